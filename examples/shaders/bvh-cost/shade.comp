// shade (example, bvh-cost): false colour of the BVH child boxes each camera ray tested (four per node visited), blue
// (few) to green to red (BVH_COST_SCALE or more). Paths end here, so the image is the cost of the first bounce.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"

const float BVH_COST_SCALE = 128.0;

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint cur = frame.bounce & 1u;
    if (i >= counters.queue_count[cur]) return;
    uint path = queues[cur * frame.path_capacity + i];
    float t = clamp(path_get(PATH_DIR, path).w / BVH_COST_SCALE, 0.0, 1.0);
    vec3 c = t < 0.5 ? mix(vec3(0.0, 0.0, 1.0), vec3(0.0, 1.0, 0.0), 2.0 * t)
                     : mix(vec3(0.0, 1.0, 0.0), vec3(1.0, 0.0, 0.0), 2.0 * t - 1.0);
    path_set(PATH_RADIANCE, path, vec4(c, 0.0));
}
