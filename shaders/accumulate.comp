// accumulate: add each path's sample to its pixel's running sum and sum of squares (each pixel owns its slot).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= frame.path_count) return;
    uint pixel = frame.pixel_offset + i;
    uint pixels = frame.width * frame.height;
    vec3 l = path_get(PATH_RADIANCE, i).rgb;
    film[pixel] += vec4(l, 1.0);
    film[pixels + pixel] += vec4(l * l, 0.0);
}
