// generate: one camera ray per pixel of this pass, jittered inside the pixel (box filter), into ray queue 0.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "camera.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i == 0u) counters.queue_count[0] = frame.path_count;
    if (i >= frame.path_count) return;
    uint pixel = path_pixel(i);
    PathVertex v = start_path(pixel_xy(pixel), pixel, path_sample(i));
    path_set(PATH_ORIGIN, i, v.origin);
    path_set(PATH_DIR, i, vec4(v.dir, 0.0));
    path_set(PATH_THROUGHPUT, i, vec4(v.beta, 0.0));
    path_set(PATH_RADIANCE, i, vec4(v.radiance, 0.0));
    queues[i] = i;
}
