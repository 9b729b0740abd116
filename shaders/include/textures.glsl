// Texture lookups from the texel buffer: wrap modes, nearest or bilinear filtering within a mip level, trilinear
// between levels, sRGB decoded before filtering.
#ifndef TEXTURES_GLSL
#define TEXTURES_GLSL

// texture_sample's footprint for a lookup at level 0 alone.
const float NO_FOOTPRINT = -1.0e30;
const vec2 NO_LOD = vec2(NO_FOOTPRINT, 0.0);

float srgb_to_linear(float c) {
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

// Brings a texture coordinate into one period of its wrap mode first, so huge uvs cannot overflow the texel indices.
float wrap_coord(float u, uint mode) {
    if (!(abs(u) < 1e30)) return 0.0; // NaN or infinite
    if (mode == WRAP_CLAMP) return clamp(u, 0.0, 1.0);
    if (mode == WRAP_MIRROR) return u - 2.0 * floor(u * 0.5); // [0, 2); the index folds the second half back
    return u - floor(u);
}

// A texel index one step outside [0, n) (bilinear filtering's neighbours) brought back inside. Indices come from
// coordinates wrap_coord brought into one period, so they lie in [-1, n] ([-1, 2n] mirrored): a compare and an add
// do what an integer remainder would, which lavapipe runs as eight scalar divides, four lookups of two each.
int wrap_index(int i, int n, uint mode) {
    if (mode == WRAP_CLAMP) return clamp(i, 0, n - 1);
    if (mode == WRAP_MIRROR) {
        int m = i < 0 ? i + 2 * n : (i >= 2 * n ? i - 2 * n : i);
        return m >= n ? 2 * n - 1 - m : m;
    }
    return i < 0 ? i + n : (i >= n ? i - n : i);
}

vec4 fetch_texel(uint offset, uint width, int x, int y, bool srgb) {
    vec4 c = unpackUnorm4x8(load_image_texel(offset + uint(y) * width + uint(x)));
    if (srgb) c.rgb = vec3(srgb_to_linear(c.r), srgb_to_linear(c.g), srgb_to_linear(c.b));
    return c;
}

// One level of a texture, at st: uv already wrapped into one period, times the level's size in texels.
vec4 sample_level(uint offset, uint width, uint height, vec2 st, uint ws, uint wt, bool nearest, bool srgb) {
    int w = int(width);
    int h = int(height);
    if (nearest) {
        ivec2 p = ivec2(floor(st));
        return fetch_texel(offset, width, wrap_index(p.x, w, ws), wrap_index(p.y, h, wt), srgb);
    }
    // Texel centres sit at half-integers.
    vec2 x = st - 0.5;
    vec2 x0 = floor(x);
    vec2 f = x - x0;
    ivec2 p = ivec2(x0);
    int xa = wrap_index(p.x, w, ws);
    int xb = wrap_index(p.x + 1, w, ws);
    int ya = wrap_index(p.y, h, wt);
    int yb = wrap_index(p.y + 1, h, wt);
    vec4 top = mix(fetch_texel(offset, width, xa, ya, srgb), fetch_texel(offset, width, xb, ya, srgb), f.x);
    vec4 bottom = mix(fetch_texel(offset, width, xa, yb, srgb), fetch_texel(offset, width, xb, yb, srgb), f.x);
    return mix(top, bottom, f.y);
}

// Level k's size: halved k times, rounding up, at least one texel (mipmaps.rs's level_size).
uvec2 level_size(TextureInfo t, uint k) {
    return max((uvec2(t.width, t.height) + ((1u << k) - 1u)) >> k, uvec2(1u));
}

// The texture at uv (glTF: (0, 0) is the image's top-left corner). srgb: colour channels are sRGB-encoded.
// lod.x: log2 of the side of the hit's footprint in uv units (texture_footprint and sample_slot), NO_FOOTPRINT for
// level 0 alone; lod.y: a uniform number in [0, 1) that picks between the two mip levels around the footprint's
// size with trilinear filtering's weights (stochastic texture filtering, Pharr et al. 2024): trilinear in
// expectation at the cost of one bilinear lookup, which matters on lavapipe, where every lane runs both of a
// branch's sides. Where the footprint spans less than a texel this is level 0's lookup without mipmaps, to the bit.
vec4 texture_sample(uint index, vec2 uv, bool srgb, vec2 lod) {
    TextureInfo t = textures[index];
    uint ws = t.flags & 3u;
    uint wt = (t.flags >> TEXTURE_WRAP_T_SHIFT) & 3u;
    vec2 wrapped = vec2(wrap_coord(uv.x, ws), wrap_coord(uv.y, wt));
    uint offset = t.offset;
    uvec2 n = uvec2(t.width, t.height);
    if (scene_has(FEATURE_TEXTURE_LOD)) {
        uint levels = (t.flags >> TEXTURE_LEVELS_SHIFT) & TEXTURE_LEVELS_MASK;
        float lambda = min(lod.x + 0.5 * log2(float(t.width) * float(t.height)), float(levels));
        uint k = 0u;
        if (lambda > 0.0) {
            k = uint(lambda);
            if (lod.y < lambda - float(k)) k++;
        }
        for (uint i = 0u; i < k; i++) {
            offset += n.x * n.y;
            n = level_size(t, i + 1u);
        }
    }
    return sample_level(offset, n.x, n.y, wrapped * vec2(n), ws, wt, (t.flags & TEXTURE_NEAREST) != 0u, srgb);
}

#endif
