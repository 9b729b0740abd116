// probe_light_select: light selection at given points (select_light) and its pdf twin (light_pick_prob), for the
// light sampler the frame's flags ask for, so tests can hold the device's light BVH to its CPU twin.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "lights.glsl"

layout(std430, set = 0, binding = BINDING_PROBE) buffer Probe { LightSelectRecord records[]; };

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    LightSelectRecord r = records[k];
    vec2 u_point = vec2(r.u, 0.5);
    uint j;
    float prob;
    bool ok = select_light(r.p, r.n, vec2(r.u, r.v), u_point, j, prob);
    r.picked = ok ? j : LIGHT_NONE;
    r.prob = ok ? prob : 0.0;
    r.pmf = light_pick_prob(r.entry, r.p, r.n);
    records[k] = r;
}
