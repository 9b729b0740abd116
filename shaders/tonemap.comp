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

// The curves as src/output/tone.rs defines them (its module comment names their sources); tests/tonemap.rs holds
// these to the host's. Each maps linear radiance to display-linear [0, 1].

// Narkowicz's fit of the ACES filmic curve.
vec3 aces(vec3 x) {
    return clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

// AgX's default contrast sigmoid on log-encoded [0, 1] (Wrensch's 6th-order fit).
vec3 agx_contrast(vec3 x) {
    vec3 x2 = x * x;
    vec3 x4 = x2 * x2;
    return 15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x - 0.00232;
}

// Sobotka's AgX: inset, log2 encoding about 0.18, the sigmoid, the inset's inverse, then the 2.2 power that undoes
// the curve's display encoding.
vec3 agx(vec3 c) {
    const mat3 inset = mat3(0.842479062253094, 0.0423282422610123, 0.0423756549057051,
                            0.0784335999999992, 0.878468636469772, 0.0784336,
                            0.0792237451477643, 0.0791661274605434, 0.879142973793104);
    const float min_ev = -12.47393;
    const float max_ev = 4.026069;
    vec3 ev = clamp(log2(max(inset * c, vec3(1e-12))), min_ev, max_ev);
    vec3 display = inverse(inset) * agx_contrast((ev - min_ev) / (max_ev - min_ev));
    return clamp(pow(max(display, vec3(0.0)), vec3(2.2)), 0.0, 1.0);
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
    else if (curve == TONEMAP_AGX) c = agx(c);
    vec3 e = vec3(srgb_encode(c.r), srgb_encode(c.g), srgb_encode(c.b));
    if ((tone.op & TONEMAP_BGRA) != 0u) e = e.bgr;
    pixels[p.y * tone.out_width + p.x] = packUnorm4x8(vec4(e, 1.0));
}
