// generate: one camera ray per pixel of this pass, jittered inside the pixel (box filter), into ray queue 0.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "camera.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i == 0u) counters.queue_count[0] = frame.path_count;
    if (i >= frame.path_count) return;
    vec3 origin, d;
    camera_ray(path_pixel(i), path_sample(i), origin, d);
    path_set(PATH_ORIGIN, i, vec4(origin, 0.0));
    path_set(PATH_DIR, i, vec4(d, 0.0));
    path_set(PATH_THROUGHPUT, i, vec4(1.0));
    path_set(PATH_RADIANCE, i, vec4(0.0));
    queues[i] = i;
}
