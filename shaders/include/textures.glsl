// Texture lookups from the texel buffer: wrap modes, nearest or bilinear filtering, sRGB decoded before filtering.
#ifndef TEXTURES_GLSL
#define TEXTURES_GLSL

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

// A texel index one step outside [0, n) (bilinear filtering's neighbours) brought back inside.
int wrap_index(int i, int n, uint mode) {
    if (mode == WRAP_CLAMP) return clamp(i, 0, n - 1);
    if (mode == WRAP_MIRROR) {
        int m = ((i % (2 * n)) + 2 * n) % (2 * n);
        return m >= n ? 2 * n - 1 - m : m;
    }
    return ((i % n) + n) % n;
}

vec4 fetch_texel(TextureInfo t, int x, int y, bool srgb) {
    vec4 c = unpackUnorm4x8(load_image_texel(t.offset + uint(y) * t.width + uint(x)));
    if (srgb) c.rgb = vec3(srgb_to_linear(c.r), srgb_to_linear(c.g), srgb_to_linear(c.b));
    return c;
}

// The texture at uv (glTF: (0, 0) is the image's top-left corner). srgb: colour channels are sRGB-encoded.
vec4 texture_sample(uint index, vec2 uv, bool srgb) {
    TextureInfo t = textures[index];
    uint ws = t.flags & 3u;
    uint wt = (t.flags >> TEXTURE_WRAP_T_SHIFT) & 3u;
    int w = int(t.width);
    int h = int(t.height);
    vec2 st = vec2(wrap_coord(uv.x, ws), wrap_coord(uv.y, wt)) * vec2(t.width, t.height);
    if ((t.flags & TEXTURE_NEAREST) != 0u) {
        ivec2 p = ivec2(floor(st));
        return fetch_texel(t, wrap_index(p.x, w, ws), wrap_index(p.y, h, wt), srgb);
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
    vec4 top = mix(fetch_texel(t, xa, ya, srgb), fetch_texel(t, xb, ya, srgb), f.x);
    vec4 bottom = mix(fetch_texel(t, xa, yb, srgb), fetch_texel(t, xb, yb, srgb), f.x);
    return mix(top, bottom, f.y);
}

#endif
