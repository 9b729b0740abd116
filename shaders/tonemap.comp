// tonemap: the film's running mean as display pixels (exposure, a tone curve, sRGB encoding), scaled to the window.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "shared_constants.glsl"

layout(local_size_x = TONEMAP_TILE, local_size_y = TONEMAP_TILE, local_size_z = 1) in;

// 32 bytes; mirrored by ToneMap in src/layout.rs. Its own block within the pipelines' shared push-constant range.
struct ToneMap {
    uint film_width;
    uint film_height;
    uint out_width;
    uint out_height;
    uint samples;
    uint op;
    float exposure;
    uint pad;
};

layout(push_constant) uniform Push { ToneMap tone; };
layout(std430, set = 0, binding = BINDING_FILM) readonly buffer Film { vec4 film[]; };
// One packed 8-bit pixel per word, row 0 at the top, ready to copy into a swapchain image.
layout(std430, set = 0, binding = BINDING_TONEMAP_OUT) writeonly buffer Pixels { uint pixels[]; };

// Narkowicz's fit of the ACES filmic curve.
vec3 aces(vec3 x) {
    return clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

// Khronos PBR Neutral: identity below the compression start, then a hue-preserving shoulder with some desaturation.
vec3 pbr_neutral(vec3 c) {
    const float start = 0.8 - 0.04;
    const float desaturation = 0.15;
    float x = min(c.r, min(c.g, c.b));
    float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
    c -= offset;
    float peak = max(c.r, max(c.g, c.b));
    if (peak < start) return c;
    const float d = 1.0 - start;
    float new_peak = 1.0 - d * d / (peak + d - start);
    c *= new_peak / peak;
    float g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
    return mix(c, vec3(new_peak), g);
}

float srgb_encode(float c) {
    c = clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= tone.out_width || p.y >= tone.out_height) return;
    // Nearest film pixel: the viewer renders at a lower resolution while the camera moves.
    uint fx = min(p.x * tone.film_width / tone.out_width, tone.film_width - 1u);
    uint fy = min(p.y * tone.film_height / tone.out_height, tone.film_height - 1u);
    vec3 c = film[fy * tone.film_width + fx].rgb / float(max(tone.samples, 1u)) * tone.exposure;
    uint curve = tone.op & 15u;
    if (curve == TONEMAP_ACES) c = aces(c);
    else if (curve == TONEMAP_NEUTRAL) c = pbr_neutral(max(c, vec3(0.0)));
    vec3 e = vec3(srgb_encode(c.r), srgb_encode(c.g), srgb_encode(c.b));
    if ((tone.op & TONEMAP_BGRA) != 0u) e = e.bgr;
    pixels[p.y * tone.out_width + p.x] = packUnorm4x8(vec4(e, 1.0));
}
