// generate: one camera ray per pixel of this pass, jittered inside the pixel (box filter), into ray queue 0.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "rng.glsl"
#include "sampling.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i == 0u) counters.queue_count[0] = frame.path_count;
    if (i >= frame.path_count) return;
    uint pixel = path_pixel(i);
    uint px = pixel % frame.width;
    uint py = pixel / frame.width;
    vec2 j = pixel_jitter(pixel, path_sample(i));
    float tan_half = frame.cam_origin.w;
    float aspect = frame.cam_right.w;
    // Row 0 is the top of the image.
    float sx = (2.0 * (float(px) + j.x) / float(frame.width) - 1.0) * tan_half * aspect;
    float sy = (1.0 - 2.0 * (float(py) + j.y) / float(frame.height)) * tan_half;
    vec3 d = normalize(sx * frame.cam_right.xyz + sy * frame.cam_up.xyz + frame.cam_forward.xyz);
    vec3 origin = frame.cam_origin.xyz;
    float aperture = frame.cam_up.w;
    if (aperture > 0.0) {
        // Thin lens: every ray through the lens meets the pinhole ray on the plane of focus.
        vec3 focus = origin + d * (frame.cam_forward.w / dot(d, frame.cam_forward.xyz));
        vec2 lens = aperture * sample_concentric_disk(rand2(pixel, path_sample(i), 0u, DIM_LENS));
        origin += lens.x * frame.cam_right.xyz + lens.y * frame.cam_up.xyz;
        d = normalize(focus - origin);
    }
    path_set(PATH_ORIGIN, i, vec4(origin, 0.0));
    path_set(PATH_DIR, i, vec4(d, 0.0));
    path_set(PATH_THROUGHPUT, i, vec4(1.0));
    path_set(PATH_RADIANCE, i, vec4(0.0));
    queues[i] = i;
}
