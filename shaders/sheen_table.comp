// sheen_table: the sheen lobe's directional albedo per (cos theta, sheen roughness) cell, into the energy buffer's
// Esheen grid. Its own stage, run only once a scene has a sheen, so other scenes neither compile nor run it.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "bsdf.glsl"

void main() {
    uint cell = gl_GlobalInvocationID.x;
    if (cell >= ENERGY_RES * ENERGY_RES) return;
    uint i = cell % ENERGY_RES; // cos theta index
    uint j = cell / ENERGY_RES; // roughness index
    float mu = max(float(i) / float(ENERGY_RES - 1u), 1e-3);
    float roughness = float(j) / float(ENERGY_RES - 1u);
    vec3 wo = vec3(sqrt(1.0 - mu * mu), 0.0, mu);
    // Importance sampling of the Charlie distribution (normalised: its projected integral is 1): sin(theta_h) =
    // u^(1 / (1/alpha + 2)), then reflection. f cos / pdf reduces to (wo.h) / (h.z wo.z (1 + L(wo) + L(wi))), which
    // stays exact where the near-delta lobes of low roughness live (cosine sampling missed their grazing peak).
    float alpha = sheen_alpha(roughness);
    float es = 0.0;
    for (uint k = 0u; k < SHEEN_ENERGY_SAMPLES; ++k) {
        vec2 u = vec2((float(k) + 0.5) / float(SHEEN_ENERGY_SAMPLES), radical_inverse(k));
        float sin_h = pow(u.x, 1.0 / (1.0 / alpha + 2.0));
        float cos_h = sqrt(max(0.0, 1.0 - sin_h * sin_h));
        float phi = 2.0 * PI * u.y;
        vec3 h = vec3(sin_h * cos(phi), sin_h * sin(phi), cos_h);
        float wo_h = dot(wo, h);
        if (wo_h <= 0.0 || cos_h <= 0.0) continue;
        vec3 wi = reflect(-wo, h);
        if (wi.z <= 0.0) continue;
        es += wo_h / (cos_h * wo.z * (1.0 + sheen_lambda(wo.z, alpha) + sheen_lambda(wi.z, alpha)));
    }
    energy[2u * ENERGY_RES * ENERGY_RES + cell] = es / float(SHEEN_ENERGY_SAMPLES);
}
