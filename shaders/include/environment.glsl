// The environment light: radiance lookup, importance sampling from its 2D tables, and that sampling's pdf.
#ifndef ENVIRONMENT_GLSL
#define ENVIRONMENT_GLSL

#include "sampling.glsl"

// The map is rotated by env_rotation about +y: world direction d is read at R(-rotation) d.
vec3 env_rotate(vec3 d, float angle) {
    float c = cos(angle);
    float s = sin(angle);
    return vec3(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
}

// Map coordinates in [0, 1)^2 of a map-space direction: v = theta / pi from +y, u = 0.5 looks down -z, u grows to +x.
vec2 env_uv(vec3 d) {
    float phi = atan(d.x, -d.z);
    float theta = acos(clamp(d.y, -1.0, 1.0));
    return vec2(0.5 + phi / (2.0 * PI), theta / PI);
}

vec3 env_direction(vec2 uv) {
    float phi = 2.0 * PI * (uv.x - 0.5);
    float theta = PI * uv.y;
    return vec3(sin(theta) * sin(phi), cos(theta), -sin(theta) * cos(phi));
}

uvec2 env_texel(vec2 uv) {
    return uvec2(min(uint(uv.x * float(frame.env_width)), frame.env_width - 1u),
                 min(uint(uv.y * float(frame.env_height)), frame.env_height - 1u));
}

vec3 env_radiance(vec3 world_dir) {
    uvec2 t = env_texel(env_uv(env_rotate(world_dir, -frame.env_rotation)));
    uint i = 4u * (t.y * frame.env_width + t.x);
    return vec3(env[i], env[i + 1u], env[i + 2u]);
}

uint env_marginal_base() {
    return 4u * frame.env_width * frame.env_height;
}

uint env_row_base(uint row) {
    return env_marginal_base() + frame.env_height + 1u + row * (frame.env_width + 1u);
}

// Largest cell i in [0, n) with cdf[i] <= u: never an empty cell, since cdf[i + 1] > u.
uint env_search(uint base, uint n, float u) {
    uint lo = 0u;
    uint hi = n - 1u;
    while (lo < hi) {
        uint mid = (lo + hi + 1u) >> 1u;
        if (env[base + mid] <= u) lo = mid; else hi = mid - 1u;
    }
    return lo;
}

// Solid-angle density of env_sample at a world direction.
float env_pdf(vec3 world_dir) {
    vec3 d = env_rotate(world_dir, -frame.env_rotation);
    vec2 uv = env_uv(d);
    uvec2 t = env_texel(uv);
    // From x and z, not sqrt(1 - y^2), which is 0 in f32 right next to the poles.
    float sin_theta = length(d.xz);
    if (sin_theta <= 0.0) return 0.0;
    uint m = env_marginal_base();
    uint r = env_row_base(t.y);
    float p_row = env[m + t.y + 1u] - env[m + t.y];
    float p_col = env[r + t.x + 1u] - env[r + t.x];
    float pdf_uv = p_row * p_col * float(frame.env_width * frame.env_height);
    return pdf_uv / (2.0 * PI * PI * sin_theta);
}

// A world direction drawn in proportion to radiance times the map's sin(theta) Jacobian.
vec3 env_sample(vec2 u, out float pdf) {
    uint m = env_marginal_base();
    uint row = env_search(m, frame.env_height, u.x);
    float r0 = env[m + row];
    float dv = (u.x - r0) / max(env[m + row + 1u] - r0, 1e-30);
    uint rb = env_row_base(row);
    uint col = env_search(rb, frame.env_width, u.y);
    float c0 = env[rb + col];
    float du = (u.y - c0) / max(env[rb + col + 1u] - c0, 1e-30);
    vec2 uv = vec2((float(col) + clamp(du, 0.0, 0.999999)) / float(frame.env_width),
                   (float(row) + clamp(dv, 0.0, 0.999999)) / float(frame.env_height));
    vec3 world = env_rotate(env_direction(uv), frame.env_rotation);
    pdf = env_pdf(world);
    return world;
}

#endif
