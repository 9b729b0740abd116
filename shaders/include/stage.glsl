// The preamble every compute stage starts with: shared layout, workgroup size, and the invocation's index.
#ifndef STAGE_GLSL
#define STAGE_GLSL
#extension GL_GOOGLE_include_directive : require
#ifdef RAY_QUERY
#extension GL_EXT_ray_query : require
#endif
#include "layout.glsl"
#include "scene_reads.glsl"
layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

// lavapipe (gallivm) ends every loop of an invocation, silently, once their iterations together reach 65535 (see
// follow.comp). A wavefront stage calls this last: once the budget is spent, a two-step loop whose bound the compiler
// cannot see runs fewer steps, and the invocation is counted (Counters::stage_cut), which the host reports as an
// error: an edited stage with an endless loop then fails rather than giving a wrong image. Elsewhere it costs a
// two-step loop.
void check_loop_budget() {
    uint steps = 0u;
    for (uint k = 0u; k < 2u + (frame.path_count == 0u ? 1u : 0u); k++) steps++;
    if (steps != 2u) atomicAdd(counters.stage_cut, 1u);
}
#endif
