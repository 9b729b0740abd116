// extend: closest hit for every ray in the current queue.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "rng.glsl"
#include "traverse.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint cur = frame.bounce & 1u;
    if (i >= counters.queue_count[cur]) return;
    uint path = queues[cur * frame.path_capacity + i];
    motion_begin(path_pixel(path), path_sample(path));
    vec3 o = path_get(PATH_ORIGIN, path).xyz;
    vec4 dir = path_get(PATH_DIR, path);
    vec3 d = dir.xyz;
    uint key = ray_key(path_pixel(path), path_sample(path), frame.bounce, DIM_ALPHA);
    Hit h = trace(o, d, 0.0, 3.0e38, false, key);
    path_set(PATH_HIT, path, vec4(h.t, uintBitsToFloat(h.tri), h.uv));
    // The instance rides in the direction's w, which shade reads with the direction.
    // So does a spectral path's PATH_HERO_ONLY, which shade set there and which must survive.
    uint hero = scene_has(FEATURE_SPECTRAL) ? floatBitsToUint(dir.w) & PATH_HERO_ONLY : 0u;
    if (scene_has(FEATURE_INSTANCES)) path_set(PATH_DIR, path, vec4(d, uintBitsToFloat(h.inst | hero)));
    check_loop_budget();
}
