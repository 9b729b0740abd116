// probe_env: runs environment sampling from Rust. Input record k at probe[4k..4k+4): u xy (sample mode) or a direction
// xyz (pdf mode). Output at probe[4n + 8k..]: direction xyz, pdf from sampling, pdf(direction), radiance rgb.
// frame.bounce: 0 = sample, 1 = evaluate the given direction.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "environment.glsl"

void main() {
    uint k = gl_GlobalInvocationID.x;
    uint n = frame.path_count;
    if (k >= n) return;
    vec3 x = vec3(uintBitsToFloat(probe[4u * k]), uintBitsToFloat(probe[4u * k + 1u]), uintBitsToFloat(probe[4u * k + 2u]));
    vec3 d;
    float pdf = 0.0;
    if (frame.bounce == 0u) {
        d = env_sample(x.xy, pdf);
    } else {
        d = normalize(x);
    }
    vec3 le = env_radiance(d);
    uint o = 4u * n + 8u * k;
    probe[o] = floatBitsToUint(d.x);
    probe[o + 1u] = floatBitsToUint(d.y);
    probe[o + 2u] = floatBitsToUint(d.z);
    probe[o + 3u] = floatBitsToUint(pdf);
    probe[o + 4u] = floatBitsToUint(env_pdf(d));
    probe[o + 5u] = floatBitsToUint(le.x);
    probe[o + 6u] = floatBitsToUint(le.y);
    probe[o + 7u] = floatBitsToUint(le.z);
}
