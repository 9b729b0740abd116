// shade: one bounce of every path that extend traced (path.glsl), its shadow ray into the shadow queue and its
// continuation into the next ray queue.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#include "stage.glsl"
#include "path.glsl"

// Appends path to a queue: one atomic per subgroup, not per invocation (lavapipe runs a subgroup's 8 atomics one
// after another; GPUs contend on the counter). Called with any subset of the subgroup active. Written with the
// subgroup operations naga can read (no subgroupElect or ballot counts), so tests/layout.rs still checks this stage.
void queue_push(uint queue, uint path) {
    uint count = subgroupAdd(1u);
    uint rank = subgroupExclusiveAdd(1u);
    uint base = 0u;
    if (rank == 0u) base = atomicAdd(counters.queue_count[queue], count);
    queues[queue * frame.path_capacity + subgroupBroadcastFirst(base) + rank] = path;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint cur = frame.bounce & 1u;
    if (i >= counters.queue_count[cur]) return;
    uint path = queues[cur * frame.path_capacity + i];
    motion_begin(path_pixel(path), path_sample(path));
    wavelengths_begin(path_pixel(path), path_sample(path));

    PathVertex v;
    v.origin = path_get(PATH_ORIGIN, path);
    vec4 dir = path_get(PATH_DIR, path);
    v.dir = dir.xyz;
    v.beta = path_get(PATH_THROUGHPUT, path);
    v.radiance = path_get(PATH_RADIANCE, path);
    ShadowRay shadow;
    uint dir_bits = floatBitsToUint(dir.w);
    v.hero_only = spectral() && (dir_bits & PATH_HERO_ONLY) != 0u;
    // The light BVH's normal at the ray's origin waits in the shadow direction's w, which connect does not read.
    v.light_normal = light_tree_on() ? path_get(PATH_SHADOW_DIR, path).w : 0.0;
    v.media = scene_has(FEATURE_MEDIA) ? floatBitsToUint(path_get(PATH_MEDIUM, path)) : uvec4(0u);
    v.media_ratios = scene_has(FEATURE_MEDIA) ? path_get(PATH_MEDIUM_RATIOS, path) : Spectrum(1.0);
    uint inst = scene_has(FEATURE_INSTANCES) ? (spectral() ? dir_bits & ~PATH_HERO_ONLY : dir_bits) : NO_INSTANCE;
    bool alive = shade_path(path_pixel(path), path_sample(path), frame.bounce, path_get(PATH_HIT, path), inst, v, shadow);

    path_set(PATH_RADIANCE, path, spectrum_store(v.radiance));
    if (shadow.wanted) {
        queue_push(QUEUE_SHADOW, path);
        path_set(PATH_SHADOW_ORIGIN, path, shadow.origin);
        path_set(PATH_SHADOW_DIR, path, vec4(shadow.dir, v.light_normal));
        path_set(PATH_SHADOW_RADIANCE, path, spectrum_store(shadow.radiance));
    }
    if (alive && !shadow.wanted && light_tree_on()) path_set(PATH_SHADOW_DIR, path, vec4(0.0, 0.0, 0.0, v.light_normal));
    if (alive) {
        path_set(PATH_ORIGIN, path, v.origin);
        path_set(PATH_DIR, path, vec4(v.dir, v.hero_only ? uintBitsToFloat(PATH_HERO_ONLY) : 0.0));
        path_set(PATH_THROUGHPUT, path, spectrum_store(v.beta));
        if (scene_has(FEATURE_MEDIA)) {
            path_set(PATH_MEDIUM, path, uintBitsToFloat(v.media));
            path_set(PATH_MEDIUM_RATIOS, path, v.media_ratios);
        }
        queue_push(1u - cur, path);
    }
    check_loop_budget();
}
