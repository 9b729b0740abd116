// probe_rand: the sampler's two uniforms, as 24-bit integers, for invocation k's pixel and sample (numbered as paths
// are: pixel pixel_offset + k % pass_pixels, sample sample_index + k / pass_pixels), at bounce probe_mode() and
// dimension probe_dimension(), so tests can check stratification and uniformity.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "rng.glsl"

layout(std430, set = 0, binding = BINDING_PROBE) writeonly buffer Probe { uvec2 records[]; };

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    vec2 u = rand2(path_pixel(k), path_sample(k), probe_mode(), probe_dimension());
    records[k] = uvec2(u * 16777216.0);
}
