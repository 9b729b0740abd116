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

// Owen scrambling in base 2 by hashing (Laine-Karras permutation, constants from Burley 2020 and Vegdahl): a digit
// flips depending only on the digits above it. Works on bit-reversed values, so the top digit is the lowest bit here.
uint laine_karras(uint x, uint seed) {
    x ^= x * 0x3d20adeau;
    x += seed;
    x *= (seed >> 16u) | 1u;
    x ^= x * 0x05526c56u;
    x ^= x * 0x53a22864u;
    return x;
}

uint owen_scramble(uint x, uint seed) {
    return bitfieldReverse(laine_karras(bitfieldReverse(x), seed));
}

// Sobol's second dimension, bit-reversed: its generator is the Pascal matrix mod 2, so by Lucas' theorem digit m
// is the XOR of the index bits j with j a superset of m (as bit sets), a transform of five shift-mask steps instead
// of a loop over 32 direction numbers.
uint sobol_pascal_reversed(uint index) {
    index ^= (index >> 1u) & 0x55555555u;
    index ^= (index >> 2u) & 0x33333333u;
    index ^= (index >> 4u) & 0x0F0F0F0Fu;
    index ^= (index >> 8u) & 0x00FF00FFu;
    index ^= (index >> 16u) & 0x0000FFFFu;
    return index;
}

// Two uniforms in [0, 1) for one (pixel, sample, bounce, dimension) key: over a pixel's samples, the first two
// dimensions of Sobol (a (0,2)-sequence: any 2^k consecutive samples from 0 stratify the square in every 2^-a x 2^-b
// box with a + b = k), Owen-scrambled per key, the index itself Owen-scrambled too so the dimensions pair at random
// (Burley 2020, "Practical hash-based Owen scrambling"). Each point is uniform and independent across keys; within
// a pixel the samples are stratified, which is what lowers the noise at equal samples.
vec2 rand2(uint pixel, uint sample_index, uint bounce, uint dim) {
    uvec4 h = pcg4d(uvec4(pixel, (bounce << 8u) | dim, 0x9E3779B9u, frame.seed));
    uint index = owen_scramble(sample_index, h.x);
    // Sobol's first dimension is the bit-reversed index; owen_scramble works on reversed digits, so both stay there.
    uint x = bitfieldReverse(laine_karras(index, h.y));
    uint y = bitfieldReverse(laine_karras(sobol_pascal_reversed(index), h.z));
    // 24 bits so the float is exact and strictly below 1.
    return vec2(uvec2(x, y) >> 8u) * (1.0 / 16777216.0);
}

// Sets the time of sample s of pixel in the shutter (motion_time), stratified over the pixel's samples like the
// other dimensions. Every stage that traces or shades a path calls it first; it costs nothing where nothing moves.
void motion_begin(uint pixel, uint sample_index) {
    if (scene_has(FEATURE_MOTION)) motion_time = rand2(pixel, sample_index, 0u, DIM_TIME).x;
}

// A hash of (pixel, sample, bounce, dimension): a ray's key for stochastic transparency (alpha_stops in surface.glsl).
uint ray_key(uint pixel, uint sample_index, uint bounce, uint dim) {
    return pcg4d(uvec4(pixel, sample_index, (bounce << 8u) | dim, frame.seed)).x;
}

// Per-pixel rotated R2 sequence: low discrepancy over samples, decorrelated across pixels.
// Fixed point keeps it exact for any sample index.
vec2 pixel_jitter(uint pixel, uint sample_index) {
    uvec4 rot = pcg4d(uvec4(pixel, 0xFFFFFFFFu, DIM_PIXEL, frame.seed));
    uvec2 p = rot.xy + sample_index * uvec2(3242174889u, 2447445414u);
    return vec2(p >> 8u) * (1.0 / 16777216.0);
}

#endif
