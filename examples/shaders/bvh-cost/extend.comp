// extend (example, bvh-cost): the built-in closest-hit stage, also recording how many BVH child boxes each ray tested.
#version 460
#extension GL_GOOGLE_include_directive : require
#define TRAVERSE_COUNT_NODES
#include "stage.glsl"
#include "rng.glsl"
#include "traverse.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint cur = frame.bounce & 1u;
    if (i >= counters.queue_count[cur]) return;
    uint path = queues[cur * frame.path_capacity + i];
    vec3 o = path_get(PATH_ORIGIN, path).xyz;
    vec3 d = path_get(PATH_DIR, path).xyz;
    uint key = pcg4d(uvec4(path_pixel(path), path_sample(path), (frame.bounce << 8u) | DIM_ALPHA, frame.seed)).x;
    Hit h = trace(o, d, 0.0, 3.0e38, false, key);
    path_set(PATH_HIT, path, vec4(h.t, uintBitsToFloat(h.tri), h.uv));
    // PATH_DIR.w is unused by the built-in stages: the count rides along to shade.
    path_set(PATH_DIR, path, vec4(d, float(traverse_node_visits)));
}
