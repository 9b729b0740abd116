// The exact film (FEATURE_EXACT_FILM): per-pixel sums kept as fixed-point integers, so that the sums of any split of
// a pixel's samples add up to the same bits in any order. That is what lets `pathwave merge` turn parts rendered on
// many machines into the very file one render of all their samples writes; float sums depend on their order.
#ifndef FILM_GLSL
#define FILM_GLSL

// 112 bytes (EXACT_FILM_TEXELS uvec4) per pixel, in the film buffer as float bits (the film is declared vec4) and,
// between a fused pass's dispatches, in fields 0 to 6 of the pixel's row-0 path slot. Words are little-endian; carries are
// computed by hand (add_wrapping).
//   t[0..2]: the sum of channel R, G, B: 128-bit two's complement in units of 2^-EXACT_SUM_BITS.
//   t[3..5]: the low 128 bits of channel R, G, B's sum of squares, unsigned, in units of 2^-EXACT_SQUARE_BITS.
//   t[6]:    xyz the squares' fifth (top) words; w the sample count, with EXACT_OVERFLOW set once a sum overflowed.
// Every sample film_add would take fits without rounding above the units (SAMPLE_RADIANCE_MAX < 2^50, so a sum word
// gets at most bit 113 and a square at most bit 147); below them a sample is rounded to nearest, ties up, as a
// function of the sample alone, so that rounding is the same however the samples are split.
struct ExactSums {
    uvec4 t[EXACT_FILM_TEXELS];
};

ExactSums exact_zero() {
    ExactSums s;
    for (uint k = 0u; k < EXACT_FILM_TEXELS; k++) s.t[k] = uvec4(0u);
    return s;
}

// a + b; carry becomes 1 when the sum wraps. What uaddCarry does, which naga's SPIR-V reader (tests/layout.rs reads
// every stage with it) does not know.
uint add_wrapping(uint a, uint b, out uint carry) {
    uint r = a + b;
    carry = r < a ? 1u : 0u;
    return r;
}

// m * m for m below 2^24, exactly, as hi:lo (umulExtended, likewise): m = a 2^16 + b, so m^2 = a^2 2^32 + 2ab 2^16
// + b^2, with b^2 below 2^32 and 2ab below 2^25.
void square24(uint m, out uint hi, out uint lo) {
    uint a = m >> 16u;
    uint b = m & 0xffffu;
    uint cross = 2u * a * b;
    uint c;
    lo = add_wrapping(b * b, cross << 16u, c);
    hi = a * a + (cross >> 16u) + c;
}

// a + b + carry over 128 bits; carry becomes the carry out.
uvec4 add128(uvec4 a, uvec4 b, inout uint carry) {
    uvec4 r;
    uint c0, c1;
    // One of the two carries at most: a word sum that carries leaves at most 2^32 - 2, so adding 1 cannot carry too.
    r.x = add_wrapping(a.x, b.x, c0);
    r.x = add_wrapping(r.x, carry, c1);
    carry = c0 + c1;
    r.y = add_wrapping(a.y, b.y, c0);
    r.y = add_wrapping(r.y, carry, c1);
    carry = c0 + c1;
    r.z = add_wrapping(a.z, b.z, c0);
    r.z = add_wrapping(r.z, carry, c1);
    carry = c0 + c1;
    r.w = add_wrapping(a.w, b.w, c0);
    r.w = add_wrapping(r.w, carry, c1);
    carry = c0 + c1;
    return r;
}

// v (hi:lo, below 2^49) times 2^s as a 160-bit integer (four words, then top), rounded to nearest (ties up) where s
// is negative. Shifts are built from selects and shifts below 32: GLSL leaves a shift by 32 or more undefined.
uvec4 exact_place(uint lo, uint hi, int s, out uint top) {
    if (s < 0) {
        // Rounding: v < 2^49, so v + 2^(r-1) < 2^r once r > 49 and the result is 0.
        uint r = uint(min(-s, 50));
        uint c;
        uint half_lo = r <= 32u ? 1u << (r - 1u) : 0u;
        uint half_hi = r > 32u ? 1u << min(r - 33u, 31u) : 0u;
        lo = add_wrapping(lo, half_lo, c);
        hi += half_hi + c;
        if (r < 32u) {
            lo = (lo >> r) | ((hi << 1u) << (31u - r));
            hi >>= r;
        } else {
            lo = r < 50u ? hi >> (r - 32u) : 0u;
            hi = 0u;
        }
        s = 0;
    }
    uint k = uint(s) >> 5u;
    uint b = uint(s) & 31u;
    // The value's three words once shifted by b bits; (x >> 1) >> (31 - b) is x >> (32 - b), and 0 when b is 0.
    uint w0 = lo << b;
    uint w1 = (hi << b) | ((lo >> 1u) >> (31u - b));
    uint w2 = (hi >> 1u) >> (31u - b);
    uvec4 words;
    for (uint j = 0u; j < 4u; j++) {
        words[j] = j == k ? w0 : j == k + 1u ? w1 : j == k + 2u ? w2 : 0u;
    }
    top = 4u == k ? w0 : 4u == k + 1u ? w1 : 4u == k + 2u ? w2 : 0u;
    return words;
}

// |x| = m * 2^e exactly, m below 2^24.
void exact_float_parts(float x, out uint m, out int e) {
    uint bits = floatBitsToUint(x) & 0x7fffffffu;
    uint biased = bits >> 23u;
    m = bits & 0x7fffffu;
    if (biased != 0u) {
        m |= 0x800000u;
    } else {
        biased = 1u; // subnormal
    }
    e = int(biased) - 150;
}

// Adds channel c's sample x to s: the sum (signed) and the square, which is exact before it is placed (m * m needs
// 48 bits, square24). Returns 1 when a sum overflowed.
uint exact_add_channel(inout ExactSums s, uint c, float x) {
    uint m;
    int e;
    exact_float_parts(x, m, e);
    uint unused_top;
    uvec4 v = exact_place(m, 0u, e + int(EXACT_SUM_BITS), unused_top);
    uint carry = 1u;
    if (x < 0.0) v = add128(~v, uvec4(0u), carry); // two's complement negation
    uvec4 before = s.t[c];
    carry = 0u;
    s.t[c] = add128(before, v, carry);
    // Two's complement overflow: both operands of one sign and the result of the other.
    uint sum_overflow = ((~(before.w ^ v.w) & (before.w ^ s.t[c].w)) >> 31u);
    uint hi, lo;
    square24(m, hi, lo);
    uint top;
    uvec4 q = exact_place(lo, hi, 2 * e + int(EXACT_SQUARE_BITS), top);
    carry = 0u;
    s.t[3u + c] = add128(s.t[3u + c], q, carry);
    uint old_top = s.t[6][c];
    uint new_top;
    uint c0, c1;
    new_top = add_wrapping(old_top, top, c0);
    new_top = add_wrapping(new_top, carry, c1);
    s.t[6][c] = new_top;
    return sum_overflow | c0 | c1;
}

// Adds a sample to s as film_add adds it to the float film: one more sample, and one that is not finite or beyond
// SAMPLE_RADIANCE_MAX counts as zero. Returns 1 for such a dropped sample.
uint exact_add(inout ExactSums s, vec3 l) {
    uint dropped = 0u;
    if (any(greaterThan(floatBitsToUint(l) & 0x7fffffffu, uvec3(floatBitsToUint(SAMPLE_RADIANCE_MAX))))) {
        dropped = 1u;
        l = vec3(0.0);
    }
    uint overflow = exact_add_channel(s, 0u, l.r) | exact_add_channel(s, 1u, l.g) | exact_add_channel(s, 2u, l.b);
    uint count = (s.t[6].w & ~EXACT_OVERFLOW) + 1u;
    bool flagged = overflow != 0u || (s.t[6].w & EXACT_OVERFLOW) != 0u || count >= EXACT_OVERFLOW;
    s.t[6].w = (count & ~EXACT_OVERFLOW) | (flagged ? EXACT_OVERFLOW : 0u);
    return dropped;
}

// a += b: two pixels' sums (a film's and a pass's), with overflow kept.
void exact_merge(inout ExactSums a, ExactSums b) {
    uint overflow = 0u;
    for (uint c = 0u; c < 3u; c++) {
        uvec4 before = a.t[c];
        uint carry = 0u;
        a.t[c] = add128(before, b.t[c], carry);
        overflow |= (~(before.w ^ b.t[c].w) & (before.w ^ a.t[c].w)) >> 31u;
        carry = 0u;
        a.t[3u + c] = add128(a.t[3u + c], b.t[3u + c], carry);
        uint c0, c1;
        uint top = add_wrapping(a.t[6][c], b.t[6][c], c0);
        a.t[6][c] = add_wrapping(top, carry, c1);
        overflow |= c0 | c1;
    }
    uint count = (a.t[6].w & ~EXACT_OVERFLOW) + (b.t[6].w & ~EXACT_OVERFLOW);
    bool flagged = overflow != 0u || ((a.t[6].w | b.t[6].w) & EXACT_OVERFLOW) != 0u || count >= EXACT_OVERFLOW;
    a.t[6].w = (count & ~EXACT_OVERFLOW) | (flagged ? EXACT_OVERFLOW : 0u);
}

// The film's texels of a pixel, and a pass's sums in the pixel's row-0 path slot (read from the storage buffer, not
// through a float texel view, which may flush the words that look like subnormal floats).
ExactSums exact_load_film(uint pixel) {
    ExactSums s;
    for (uint k = 0u; k < EXACT_FILM_TEXELS; k++) s.t[k] = floatBitsToUint(film[pixel * EXACT_FILM_TEXELS + k]);
    return s;
}

void exact_store_film(uint pixel, ExactSums s) {
    for (uint k = 0u; k < EXACT_FILM_TEXELS; k++) film[pixel * EXACT_FILM_TEXELS + k] = uintBitsToFloat(s.t[k]);
}

ExactSums exact_load_slot(uint path) {
    ExactSums s;
    for (uint k = 0u; k < EXACT_FILM_TEXELS; k++) s.t[k] = floatBitsToUint(paths[k * frame.path_capacity + path]);
    return s;
}

void exact_store_slot(uint path, ExactSums s) {
    for (uint k = 0u; k < EXACT_FILM_TEXELS; k++) paths[k * frame.path_capacity + path] = uintBitsToFloat(s.t[k]);
}
#endif
