// probe_bsdf: runs the BSDF's sample, eval and pdf on batches from Rust (the material comes from the materials
// buffer). One BsdfRecord per query; probe_mode() PROBE_SAMPLE samples with x as the uniforms, PROBE_EVALUATE
// evaluates at wi = x.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "bsdf.glsl"

layout(std430, set = 0, binding = BINDING_PROBE) buffer Probe { BsdfRecord records[]; };

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    BsdfRecord r = records[k];
    Bsdf b = bsdf_from_material(materials[r.material], r.front != 0u);
    bsdf_at(b, r.wo);
    BsdfSample s;
    bool ok = true;
    if (probe_mode() == PROBE_SAMPLE) {
        ok = bsdf_sample(b, r.x, s);
    } else {
        s.wi = r.x;
        s.pdf = bsdf_pdf(b, r.x);
        s.weight = Spectrum(0.0);
        s.delta = false;
    }
    records[k].wi = s.wi;
    records[k].pdf = s.pdf;
    records[k].weight = s.weight.rgb;
    records[k].flags = (s.delta ? PROBE_DELTA : 0u) | (ok ? PROBE_OK : 0u);
    records[k].eval = bsdf_eval(b, s.wi).rgb;
    records[k].pdf_wi = bsdf_pdf(b, s.wi);
    // Seen from wi: the same material readied there.
    Bsdf back = bsdf_from_material(materials[r.material], r.front != 0u);
    bsdf_at(back, s.wi);
    records[k].eval_reverse = bsdf_eval(back, r.wo).rgb;
}
