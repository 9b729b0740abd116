// probe_env: runs environment sampling from Rust. One EnvRecord per query: probe_mode() PROBE_SAMPLE samples
// with x.xy as the uniforms, PROBE_EVALUATE evaluates the direction x.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "environment.glsl"

layout(std430, set = 0, binding = BINDING_PROBE) buffer Probe { EnvRecord records[]; };

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    vec3 x = records[k].x;
    vec3 d;
    float pdf = 0.0;
    if (probe_mode() == PROBE_SAMPLE) {
        d = env_sample(x.xy, pdf);
    } else {
        d = normalize(x);
    }
    records[k].dir = d;
    records[k].pdf = pdf;
    records[k].pdf_dir = env_pdf(d);
    records[k].radiance = env_radiance(d);
}
