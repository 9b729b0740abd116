// aniso_table: the stretched GGX lobe's directional albedo (E1, and E2 weighted by Schlick's (1 - cos)^5) per (cos
// theta, azimuth, roughness along, roughness across) cell, into the energy buffer after the isotropic tables. Its own
// stage, run only once a scene has an anisotropic material, so other scenes neither compile nor run it.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "bsdf.glsl"

void main() {
    uint cell = gl_GlobalInvocationID.x;
    if (cell >= ANISO_CELLS) return;
    uint i = cell % ANISO_RES_MU;
    uint p = (cell / ANISO_RES_MU) % ANISO_RES_PHI;
    uint jx = (cell / (ANISO_RES_MU * ANISO_RES_PHI)) % ANISO_RES_ROUGH;
    uint jy = cell / (ANISO_RES_MU * ANISO_RES_PHI * ANISO_RES_ROUGH);
    // Grid points the lookup interpolates between, as energy_tables places them.
    float mu = max(float(i) / float(ANISO_RES_MU - 1u), 1e-3);
    float phi = 0.5 * PI * float(p) / float(ANISO_RES_PHI - 1u);
    float rx = float(jx) / float(ANISO_RES_ROUGH - 1u);
    float ry = float(jy) / float(ANISO_RES_ROUGH - 1u);
    vec2 alpha = vec2(max(rx * rx, ANISO_MIN_ALPHA), max(ry * ry, ANISO_MIN_ALPHA));
    float s = sqrt(1.0 - mu * mu);
    vec3 wo = vec3(s * cos(phi), s * sin(phi), mu);
    float e1 = 0.0;
    float e2 = 0.0;
    for (uint k = 0u; k < ANISO_ENERGY_SAMPLES; ++k) {
        vec2 u = vec2((float(k) + 0.5) / float(ANISO_ENERGY_SAMPLES), radical_inverse(k));
        vec3 h = sample_ggx_vndf(wo, alpha, u);
        vec3 wi = reflect(-wo, h);
        if (wi.z <= 0.0) continue;
        // f cos / pdf for visible-normal sampling is G2 / G1(wo).
        float lo = stretched_lambda(alpha, wo);
        e1 += (1.0 + lo) / (1.0 + lo + stretched_lambda(alpha, wi));
        e2 += (1.0 + lo) / (1.0 + lo + stretched_lambda(alpha, wi)) * schlick_weight(dot(wo, h));
    }
    energy[ENERGY_TABLE_FLOATS + cell] = e1 / float(ANISO_ENERGY_SAMPLES);
    energy[ENERGY_TABLE_FLOATS + ANISO_CELLS + cell] = e2 / float(ANISO_ENERGY_SAMPLES);
}
