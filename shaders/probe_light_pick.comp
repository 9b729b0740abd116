// probe_light_pick: the light shade would pick for sample k's first bounce, so tests can check frequencies against power.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "rng.glsl"
#include "lights.glsl"

layout(std430, set = 0, binding = BINDING_PROBE) writeonly buffer Probe { uint records[]; };

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    records[k] = pick_light(rand2(k, frame.sample_index, 0u, DIM_LIGHT).x);
}
