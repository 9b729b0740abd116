// generate: one camera ray per pixel of this pass, jittered inside the pixel (box filter), into ray queue 0.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "camera.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (!scene_has(FEATURE_ADAPTIVE) && i == 0u) counters.queue_count[0] = frame.path_count;
    if (i >= frame.path_count) return;
    uint pixel = path_pixel(i);
    // Adaptive sampling queues only the samples pixels take (the counters start the pass at zero). Queue order does
    // not matter: every path's result is a function of its pixel and sample, and accumulate adds in sample order.
    if (scene_has(FEATURE_ADAPTIVE) && !sample_taken(pixel, path_sample(i))) return;
    PathVertex v = start_path(pixel_xy(pixel), pixel, path_sample(i));
    path_set(PATH_ORIGIN, i, v.origin);
    path_set(PATH_DIR, i, vec4(v.dir, 0.0));
    path_set(PATH_THROUGHPUT, i, spectrum_store(v.beta));
    path_set(PATH_RADIANCE, i, spectrum_store(v.radiance));
    if (scene_has(FEATURE_MEDIA)) {
        path_set(PATH_MEDIUM, i, uintBitsToFloat(v.media));
        path_set(PATH_MEDIUM_RATIOS, i, v.media_ratios);
    }
    queues[scene_has(FEATURE_ADAPTIVE) ? atomicAdd(counters.queue_count[0], 1u) : i] = i;
}
