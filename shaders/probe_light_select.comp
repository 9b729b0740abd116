// probe_light_select: light selection at given points (select_light) and its pdf twin (light_pick_prob), for the
// light sampler the frame's flags ask for, so tests can hold the device's light BVH to its CPU twin, and an instance's
// pick within its mesh to its pdf twin.
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
    uint j, sub;
    float prob;
    bool ok = select_light(r.p, r.n, vec2(r.u, r.v), u_point, j, sub, prob);
    r.picked = ok ? j : LIGHT_NONE;
    r.sub_picked = ok ? sub : LIGHT_NONE;
    r.prob = ok ? prob : 0.0;
    r.pmf = light_pick_prob(r.entry, r.p, r.n);
    if (scene_has(FEATURE_INSTANCES) && r.sub_entry != LIGHT_NONE) {
        r.pmf *= instanced_pick_prob(load_light(r.entry).id & LIGHT_INDEX_MASK, r.sub_entry, r.p, r.n);
    }
    records[k] = r;
}
