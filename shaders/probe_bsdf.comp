// probe_bsdf: runs the BSDF's sample, eval and pdf on batches from Rust (the material comes from the materials buffer).
// Input record k at probe[8k..8k+8): material index, wo xyz, then u xyz (sample mode) or wi xyz (eval mode), then 1 if
// wo is on the front (outside) of the surface, 0 if inside.
// Output record k at probe[8n + 16k..]: wi xyz, weight rgb, pdf, delta|ok<<1, eval(wo,wi) rgb, pdf(wo,wi),
// eval(wi,wo) rgb, unused. frame.bounce: 0 = sample, 1 = evaluate at the given wi.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "bsdf.glsl"

vec3 read3(uint at) {
    return vec3(uintBitsToFloat(probe[at]), uintBitsToFloat(probe[at + 1u]), uintBitsToFloat(probe[at + 2u]));
}

void write3(uint at, vec3 v) {
    probe[at] = floatBitsToUint(v.x);
    probe[at + 1u] = floatBitsToUint(v.y);
    probe[at + 2u] = floatBitsToUint(v.z);
}

void main() {
    uint k = gl_GlobalInvocationID.x;
    uint n = frame.path_count;
    if (k >= n) return;
    Bsdf b = bsdf_from_material(materials[probe[8u * k]], probe[8u * k + 7u] != 0u);
    vec3 wo = read3(8u * k + 1u);
    vec3 x = read3(8u * k + 4u);
    BsdfSample s;
    bool ok = true;
    if (frame.bounce == 0u) {
        ok = bsdf_sample(b, wo, x, s);
    } else {
        s.wi = x;
        s.pdf = bsdf_pdf(b, wo, x);
        s.weight = vec3(0.0);
        s.delta = false;
    }
    uint o = 8u * n + 16u * k;
    write3(o, s.wi);
    write3(o + 3u, s.weight);
    probe[o + 6u] = floatBitsToUint(s.pdf);
    probe[o + 7u] = (s.delta ? 1u : 0u) | (ok ? 2u : 0u);
    write3(o + 8u, bsdf_eval(b, wo, s.wi));
    probe[o + 11u] = floatBitsToUint(bsdf_pdf(b, wo, s.wi));
    write3(o + 12u, bsdf_eval(b, s.wi, wo));
}
