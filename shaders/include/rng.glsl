// Counter-based randomness: every number is a pure function of (seed, pixel, sample, bounce, dimension).
#ifndef RNG_GLSL
#define RNG_GLSL

// PCG-style 4D hash (Jarzynski and Olano 2020): each output word depends on all four inputs.
uvec4 pcg4d(uvec4 v) {
    v = v * 1664525u + 1013904223u;
    v.x += v.y * v.w; v.y += v.z * v.x; v.z += v.x * v.y; v.w += v.y * v.z;
    v ^= v >> 16u;
    v.x += v.y * v.w; v.y += v.z * v.x; v.z += v.x * v.y; v.w += v.y * v.z;
    return v;
}

// Two independent uniforms in [0, 1) for one (pixel, sample, bounce, dimension) key.
vec2 rand2(uint pixel, uint sample_index, uint bounce, uint dim) {
    uvec4 h = pcg4d(uvec4(pixel, sample_index, (bounce << 8u) | dim, frame.seed));
    // 24 bits so the float is exact and strictly below 1.
    return vec2(h.xy >> 8u) * (1.0 / 16777216.0);
}

// Per-pixel rotated R2 sequence: low discrepancy over samples, decorrelated across pixels.
// Fixed point keeps it exact for any sample index.
vec2 pixel_jitter(uint pixel, uint sample_index) {
    uvec4 rot = pcg4d(uvec4(pixel, 0xFFFFFFFFu, DIM_PIXEL, frame.seed));
    uvec2 p = rot.xy + sample_index * uvec2(3242174889u, 2447445414u);
    return vec2(p >> 8u) * (1.0 / 16777216.0);
}

#endif
