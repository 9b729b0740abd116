// probe_trace: runs the device traversal on rays from Rust so tests can compare it with a CPU brute force.
// probe[8k..8k+8): origin xyz, tmin, direction xyz, tmax (float bits); results at probe[8n + 4k..]: t, tri, u, v.
// frame.path_count = n rays; frame.bounce = 1 asks for any hit instead of closest hit.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "traverse.glsl"

void main() {
    uint k = gl_GlobalInvocationID.x;
    uint n = frame.path_count;
    if (k >= n) return;
    vec3 o = vec3(uintBitsToFloat(probe[8u * k]), uintBitsToFloat(probe[8u * k + 1u]), uintBitsToFloat(probe[8u * k + 2u]));
    float tmin = uintBitsToFloat(probe[8u * k + 3u]);
    vec3 d = vec3(uintBitsToFloat(probe[8u * k + 4u]), uintBitsToFloat(probe[8u * k + 5u]), uintBitsToFloat(probe[8u * k + 6u]));
    float tmax = uintBitsToFloat(probe[8u * k + 7u]);
    Hit h = trace(o, d, tmin, tmax, frame.bounce == 1u, 0u);
    uint base = 8u * n + 4u * k;
    probe[base] = floatBitsToUint(h.t);
    probe[base + 1u] = h.tri;
    probe[base + 2u] = floatBitsToUint(h.uv.x);
    probe[base + 3u] = floatBitsToUint(h.uv.y);
}
