// plan: adaptive sampling's budgets, once the film holds exactly the pilot (plan_pilot() samples of every pixel). A
// pixel's budget is the samples its mean needs for a relative standard error of plan_threshold(), estimated from
// the pilot samples of its 24 nearest neighbours, never its own: its budget is then independent of its own samples, so
// the mean of the samples it takes is an unbiased estimate of the pixel (see docs/guide/aovs.md, "Adaptive sampling"). It also
// counts the budgets per bucket, and a second dispatch ranks the pixels by them (the budget buffer's order).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "film.glsl"

// A 128-bit two's-complement word group in units of 2^-scale, as a float (rounded; deterministic).
float signed128(uvec4 w, int scale) {
    bool negative = (w.w & 0x80000000u) != 0u;
    if (negative) {
        // Two's complement: invert and add one.
        w = ~w;
        uint carry = 1u;
        for (uint k = 0u; k < 4u; k++) w[k] = add_wrapping(w[k], carry, carry);
    }
    float v = 0.0;
    for (int k = 3; k >= 0; k--) v += float(w[k]) * exp2(float(32 * k - scale));
    return negative ? -v : v;
}

// Pixel q's pilot: its sample count, and per channel the sum and the sum of squares.
void pilot_of(uint q, out float n, out vec3 sum, out vec3 sum_sq) {
    if (scene_has(FEATURE_EXACT_FILM)) {
        ExactSums s = exact_load_film(q);
        n = float(s.t[6].w & ~EXACT_OVERFLOW);
        for (uint c = 0u; c < 3u; c++) {
            sum[c] = signed128(s.t[c], int(EXACT_SUM_BITS));
            // The squares' fifth word is above the fourth, 2^128 up.
            sum_sq[c] = signed128(uvec4(s.t[3u + c].xyz, 0u), int(EXACT_SQUARE_BITS)) +
                        float(s.t[3u + c].w) * exp2(float(96 - int(EXACT_SQUARE_BITS))) +
                        float(s.t[6][c]) * exp2(float(128 - int(EXACT_SQUARE_BITS)));
        }
    } else {
        vec4 s = film[q];
        n = s.w;
        sum = s.xyz;
        sum_sq = film[frame.width * frame.height + q].xyz;
    }
}

// The second dispatch (FLAG_PIXEL_ORDER): the pixel's place among the pixels by budget, from the largest. Places
// within a bucket go by arrival: which invocation later takes which pixel changes no sample (each is a function of its
// pixel and index), so the image stays the same bytes.
void rank(uint p, uint pixels) {
    uint counts = 2u * pixels, cursors = counts + ORDER_BUCKETS;
    uint b = order_bucket(budget[p]);
    uint place = 0u;
    for (uint k = b + 1u; k < ORDER_BUCKETS; k++) place += budget[counts + k];
    place += atomicAdd(budget[cursors + b], 1u);
    budget[pixels + place] = p;
}

// The neighbourhood the pilot is pooled over: 5x5 pixels but the pixel itself. Eight neighbours (3x3) predicted the
// variance too poorly: on the Cornell box relMSE x samples was 1.24x uniform's with them, 1.15x with 24.
const int R = 2;
void main() {
    uint p = gl_GlobalInvocationID.x;
    uint pixels = frame.width * frame.height;
    if (p >= pixels) return;
    if ((frame.flags & FLAG_PIXEL_ORDER) != 0u) {
        rank(p, pixels);
        return;
    }
    int x = int(p % frame.width), y = int(p / frame.width);
    // The neighbours' pilots pooled (R pixels around): pixels differing from each other raise the variance, so edges
    // get more samples.
    float n = 0.0;
    vec3 sum = vec3(0.0), sum_sq = vec3(0.0);
    for (int dy = -R; dy <= R; dy++) {
        for (int dx = -R; dx <= R; dx++) {
            int qx = x + dx, qy = y + dy;
            bool inside = qx >= 0 && qy >= 0 && qx < int(frame.width) && qy < int(frame.height);
            if ((dx != 0 || dy != 0) && inside) {
                float qn;
                vec3 qs, qq;
                pilot_of(uint(qy) * frame.width + uint(qx), qn, qs, qq);
                n += qn;
                sum += qs;
                sum_sq += qq;
            }
        }
    }
    uint pilot = plan_pilot();
    uint need = pilot;
    if (n > 1.0) {
        vec3 mean = sum / n;
        vec3 variance = max(sum_sq / n - mean * mean, vec3(0.0)) * (n / (n - 1.0));
        // The channels' average, its standard deviation bounded by the average of theirs (exact when they move
        // together).
        float sigma = (sqrt(variance.r) + sqrt(variance.g) + sqrt(variance.b)) / 3.0;
        float mu = (mean.r + mean.g + mean.b) / 3.0;
        if (sigma > 0.0) {
            // sigma / sqrt(N) <= threshold * sqrt(mu^2 + epsilon): relMSE's measure of a pixel's error.
            float samples = sigma * sigma / (plan_threshold() * plan_threshold() * (mu * mu + ADAPTIVE_EPSILON));
            // Not below the end, or not a number: the whole render.
            need = !(samples < float(plan_end())) ? plan_end() : max(pilot, uint(ceil(samples)));
        }
    }
    budget[p] = need;
    atomicMax(counters.budget_max, need);
    uint b = order_bucket(need);
    atomicAdd(budget[2u * pixels + b], 1u);
    atomicMax(budget[2u * pixels + 2u * ORDER_BUCKETS + b], need);
}
