// connect: trace each queued shadow ray (any hit) and add its light when nothing blocks it.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "rng.glsl"
#include "traverse.glsl"
#include "spectrum.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= counters.queue_count[QUEUE_SHADOW]) return;
    uint path = queues[QUEUE_SHADOW * frame.path_capacity + i];
    motion_begin(path_pixel(path), path_sample(path));
    vec4 o = path_get(PATH_SHADOW_ORIGIN, path);
    vec3 d = path_get(PATH_SHADOW_DIR, path).xyz;
    uint key = ray_key(path_pixel(path), path_sample(path), frame.bounce, DIM_SHADOW_ALPHA);
    if (!occluded(o.xyz, d, 0.0, o.w, key)) {
        vec4 l = path_get(PATH_RADIANCE, path);
        vec4 shadow = path_get(PATH_SHADOW_RADIANCE, path);
        path_set(PATH_RADIANCE, path, spectral() ? l + shadow : vec4(l.rgb + shadow.rgb, l.w));
    }
    check_loop_budget();
}
