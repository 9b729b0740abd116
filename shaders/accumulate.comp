// accumulate: add each pixel's samples of this pass to its running sum and sum of squares, in sample order, so the sum
// is the same bytes however samples are grouped into passes. The exact film (FEATURE_EXACT_FILM) adds them as
// fixed-point integers instead, whose sums are the same bits in any order.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "film.glsl"
#include "spectrum.glsl"

// A path's sample as the film takes it: linear sRGB (spectrum_to_rgb at the sample's own wavelengths).
vec3 sample_rgb(uint pixel, uint path) {
    wavelengths_begin(pixel, path_sample(path));
    return spectrum_to_rgb(path_get(PATH_RADIANCE, path));
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    // A follow dispatch cut short left wrong samples: the host runs the pass again (Integrator::run).
    if (i >= frame.pass_pixels || counters.follow_cut != 0u) return;
    uint pixel = pass_pixel(i);
    uint pixels = frame.width * frame.height;
    bool fused = (frame.flags & FLAG_FUSED_SUMS) != 0u;
    uint dropped = 0u;
    if (scene_has(FEATURE_EXACT_FILM)) {
        // follow left the pass's sums in the pixel's slot; the wavefront's samples wait in their paths.
        ExactSums pass = exact_zero();
        if (fused) {
            pass = exact_load_slot(i);
        } else {
            for (uint path = i; path < frame.path_count; path += frame.pass_pixels) {
                if (sample_taken(pixel, path_sample(path))) dropped += exact_add(pass, sample_rgb(pixel, path));
            }
        }
        ExactSums sums = exact_load_film(pixel);
        exact_merge(sums, pass);
        exact_store_film(pixel, sums);
    } else if (fused) {
        // follow added the samples itself, in the same order with the same arithmetic.
        film[pixel] = path_get(PATH_RADIANCE, i);
        film[pixels + pixel] = path_get(PATH_THROUGHPUT, i);
        return;
    } else {
        vec4 sum = film[pixel];
        vec4 sum_sq = film[pixels + pixel];
        for (uint path = i; path < frame.path_count; path += frame.pass_pixels) {
            if (sample_taken(pixel, path_sample(path))) dropped += film_add(sum, sum_sq, sample_rgb(pixel, path));
        }
        film[pixel] = sum;
        film[pixels + pixel] = sum_sq;
    }
    if (dropped != 0u) atomicAdd(counters.nonfinite, dropped);
}
