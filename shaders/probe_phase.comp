// probe_phase: runs Henyey-Greenstein's sampling and evaluation (media.glsl) from Rust. One PhaseRecord per query:
// probe_mode() PROBE_SAMPLE samples about d_in with x.xy as the uniforms, PROBE_EVALUATE evaluates at direction x.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "media.glsl"

layout(std430, set = 0, binding = BINDING_PROBE) buffer Probe { PhaseRecord records[]; };

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    PhaseRecord r = records[k];
    vec3 d_in = normalize(r.d_in);
    vec3 wi = probe_mode() == PROBE_SAMPLE ? hg_sample(d_in, r.g, r.x.xy) : normalize(r.x);
    records[k].wi = wi;
    records[k].pdf = hg_phase(dot(d_in, wi), r.g);
}
