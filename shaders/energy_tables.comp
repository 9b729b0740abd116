// energy_tables: the GGX lobe's directional albedo per (cos theta, roughness) cell, from the BSDF's own sampling and
// Smith terms, for energy compensation and layering (sheen_table fills the sheen's grid). Run once per device at start-up; the host adds the averages.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "bsdf.glsl"

void main() {
    uint cell = gl_GlobalInvocationID.x;
    if (cell >= ENERGY_RES * ENERGY_RES) return;
    uint i = cell % ENERGY_RES; // cos theta index
    uint j = cell / ENERGY_RES; // roughness index
    // Cells sit on the grid points the lookup interpolates between; cos theta 0 is taken just above the horizon.
    float mu = max(float(i) / float(ENERGY_RES - 1u), 1e-3);
    float roughness = float(j) / float(ENERGY_RES - 1u);
    float alpha = max(roughness * roughness, DELTA_ALPHA);
    float a2 = alpha * alpha;
    vec3 wo = vec3(sqrt(1.0 - mu * mu), 0.0, mu);
    float e1 = 0.0;
    float e2 = 0.0;
    for (uint k = 0u; k < ENERGY_SAMPLES; ++k) {
        vec2 u = vec2((float(k) + 0.5) / float(ENERGY_SAMPLES), radical_inverse(k));
        vec3 h = sample_ggx_vndf(wo, vec2(alpha), u);
        vec3 wi = reflect(-wo, h);
        if (wi.z <= 0.0) continue;
        // f cos / pdf for visible-normal sampling is G2 / G1(wo).
        float lo = smith_lambda(a2, wo);
        float g = (1.0 + lo) / (1.0 + lo + smith_lambda(a2, wi));
        e1 += g;
        e2 += g * schlick_weight(dot(wo, h));
    }
    energy[cell] = e1 / float(ENERGY_SAMPLES);
    energy[ENERGY_RES * ENERGY_RES + cell] = e2 / float(ENERGY_SAMPLES);
}
