// probe_rand: the sampler's two uniforms, as 24-bit integers, for invocation k's pixel and sample (numbered as paths
// are: pixel pixel_offset + k % pass_pixels, sample sample_index + k / pass_pixels), at bounce frame.bounce and
// dimension frame.max_depth, so tests can check stratification and uniformity.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "rng.glsl"

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    vec2 u = rand2(path_pixel(k), path_sample(k), frame.bounce, frame.max_depth);
    probe[2u * k] = uint(u.x * 16777216.0);
    probe[2u * k + 1u] = uint(u.y * 16777216.0);
}
