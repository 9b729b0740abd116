// follow: the fused integrator. One invocation takes one pixel's samples of this pass through generate, extend, shade
// and connect in registers, starting the next sample as soon as a path ends, and adds each to the pixel's running sums
// for accumulate to store (FLAG_FUSED_SUMS). The same functions and arithmetic as the wavefront stages and accumulate,
// so the same bytes.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_vote : require
#include "stage.glsl"
#include "path.glsl"
#include "traverse.glsl"
#include "film.glsl"

// follow_first_row(): the first sample row (slots row * pass_pixels + pixel) of this dispatch; it takes the rows up to
// path_count / pass_pixels (the host sets path_count per dispatch).
void main() {
    uint i = gl_GlobalInvocationID.x;
    uint rays = 0u;
    uint shadow_rays = 0u;
    uint dropped = 0u;
    uint rows = frame.path_count / frame.pass_pixels;
    uint end = rows * frame.pass_pixels;
    uint path = i + follow_first_row() * frame.pass_pixels;
    if (i < frame.pass_pixels) {
        // Slots path, path + pass_pixels, ...: this pixel's samples in order (layout.glsl's path_pixel, path_sample).
        uint pixel = path_pixel(i);
        if (scene_has(FEATURE_ADAPTIVE)) {
            // The pixel's samples end at its budget: its rows beyond it are not taken.
            uint b = budget[pixel];
            end = min(rows, b > frame.sample_index ? b - frame.sample_index : 0u) * frame.pass_pixels;
        }
        uvec2 xy = pixel_xy(pixel);
        // The sample of slot path, path_sample(path), kept as it advances: a division is eight scalar divides here.
        uint s = path_sample(path);
        uint bounce = 0u;
        PathVertex v = start_path(xy, pixel, s);
        // The pixel's running film sums, which accumulate would add this pass's samples to (in sample order, so the
        // same bytes): kept here and stored once, not a sample at a time, since each store to a storage buffer is a
        // loop over the lanes on lavapipe. The first dispatch of a pass starts from the film, later ones from where
        // the one before left them (FLAG_FUSED_SUMS).
        // The exact film's sums (FEATURE_EXACT_FILM) are order-free, so a pass's start from zero and accumulate adds
        // them to the film.
        uint pixels = frame.width * frame.height;
        vec4 sum, sum_sq;
        ExactSums exact;
        if (scene_has(FEATURE_EXACT_FILM)) {
            exact = follow_first_row() == 0u ? exact_zero() : exact_load_slot(i);
        } else {
            sum = follow_first_row() == 0u ? film[pixel] : path_get(PATH_RADIANCE, i);
            sum_sq = follow_first_row() == 0u ? film[pixels + pixel] : path_get(PATH_THROUGHPUT, i);
        }
        // A lane whose path ends starts its next sample in the same iteration, so lanes stay busy until the last
        // samples; the wavefront gets the same by compacting its queues.
        while (path < end) {
            Hit h = trace(v.origin.xyz, v.dir, 0.0, 3.0e38, false, ray_key(pixel, s, bounce, DIM_ALPHA));
            rays++;
            ShadowRay shadow;
            bool alive = shade_path(pixel, s, bounce, vec4(h.t, uintBitsToFloat(h.tri), h.uv), h.inst, v, shadow);
            if (shadow.wanted) {
                shadow_rays++;
                uint shadow_key = ray_key(pixel, s, bounce, DIM_SHADOW_ALPHA);
                if (!occluded(shadow.origin.xyz, shadow.dir, 0.0, shadow.origin.w, shadow_key)) {
                    v.radiance += shadow.radiance;
                }
            }
            bounce++;
            if (!alive) {
                if (scene_has(FEATURE_EXACT_FILM)) {
                    dropped += exact_add(exact, spectrum_to_rgb(v.radiance));
                } else {
                    dropped += film_add(sum, sum_sq, spectrum_to_rgb(v.radiance));
                }
                path += frame.pass_pixels;
                s++;
                bounce = 0u;
                v = start_path(xy, pixel, s);
            }
        }
        if (scene_has(FEATURE_EXACT_FILM)) {
            exact_store_slot(i, exact);
        } else {
            path_set(PATH_RADIANCE, i, sum);
            path_set(PATH_THROUGHPUT, i, sum_sq);
        }
    }
    // lavapipe (gallivm) guards against endless loops by ending every loop of an invocation once their iterations
    // together reach 65535, silently. Once spent, that budget stops every loop after one step, so a two-step loop
    // with a bound the compiler cannot see that runs fewer than two steps, or a lane left with samples to do, shows
    // the loops above may have been cut. Then accumulate skips this pass and the host runs it again, fused with fewer
    // samples per dispatch or, at the fewest, as a wavefront (Integrator::run).
    uint steps = 0u;
    for (uint k = 0u; k < 2u + (frame.path_count == 0u ? 1u : 0u); k++) steps++;
    bool cut = steps != 2u || (i < frame.pass_pixels && path < end);
    if (subgroupAny(cut) && gl_SubgroupInvocationID == 0u) atomicAdd(counters.follow_cut, 1u);
    // The wavefront's tallies, one atomic per subgroup.
    uint sum_rays = subgroupAdd(rays);
    uint sum_shadow = subgroupAdd(shadow_rays);
    uint sum_dropped = subgroupAdd(dropped);
    if (gl_SubgroupInvocationID == 0u) {
        atomicAdd(counters.extension_rays, sum_rays);
        atomicAdd(counters.shadow_rays, sum_shadow);
        if (sum_dropped != 0u) atomicAdd(counters.nonfinite, sum_dropped);
    }
}
