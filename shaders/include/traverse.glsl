// Closest-hit and any-hit traversal of the flattened BVH; src/bvh/traverse.rs is its CPU twin and must match it.
#ifndef TRAVERSE_GLSL
#define TRAVERSE_GLSL

#include "surface.glsl"

struct Hit {
    float t;
    uint tri;
    vec2 uv;
    uint inst; // the instance whose triangle it is (records from 1), or NO_INSTANCE for a world-space triangle
};

// Moller-Trumbore. Returns t in (tmin, tmax) or -1 (callers keep tmin >= 0); uv are the barycentrics of v1 and v2.
float intersect_triangle(uint tri, vec3 o, vec3 d, float tmin, float tmax, out vec2 uv) {
    TriVerts tv = load_tri_verts(tri);
    vec3 pvec = cross(d, tv.e2.xyz);
    float det = dot(tv.e1.xyz, pvec);
    uv = vec2(0.0);
    if (det == 0.0) return -1.0;
    float inv_det = 1.0 / det;
    vec3 tvec = o - tv.v0.xyz;
    float u = dot(tvec, pvec) * inv_det;
    if (u < 0.0 || u > 1.0) return -1.0;
    vec3 qvec = cross(tvec, tv.e1.xyz);
    float v = dot(d, qvec) * inv_det;
    if (v < 0.0 || u + v > 1.0) return -1.0;
    float t = dot(tv.e2.xyz, qvec) * inv_det;
    if (t <= tmin || t >= tmax) return -1.0;
    uv = vec2(u, v);
    return t;
}

vec3 safe_inverse(vec3 d) {
    // A zero component becomes a huge finite value, and none is larger (a component below 1e-30 is as good as 0), so
    // the slab test's step = scale * inv_d stays finite for any sane scene and 0 * inf never makes NaN there.
    const float big = 1e30;
    vec3 inv = vec3(d.x != 0.0 ? 1.0 / d.x : big, d.y != 0.0 ? 1.0 / d.y : big, d.z != 0.0 ? 1.0 / d.z : big);
    return clamp(inv, vec3(-big), vec3(big));
}

// The ray in an instance's object space: the world-to-object rows applied to the origin (a point) and the direction
// (a vector, left unnormalised, so that distances along it stay the world's).
void to_object(Instance inst, inout vec3 o, inout vec3 d) {
    o = rows_point(inst.object0, inst.object1, inst.object2, o);
    d = rows_vector(inst.object0, inst.object1, inst.object2, d);
}

// The hit's barycentrics, from the same arithmetic that found it (traversal keeps only t and the triangle), in the
// space it was found in.
Hit with_barycentrics(Hit h, vec3 o, vec3 d, float tmin) {
    if (scene_has(FEATURE_INSTANCES) && h.inst != NO_INSTANCE) to_object(instance_at(h.inst), o, d);
    if (h.tri != NO_HIT) intersect_triangle(h.tri, o, d, tmin, uintBitsToFloat(0x7F800000u), h.uv);
    return h;
}

#ifdef TRAVERSE_COUNT_NODES
// Child boxes the last trace() tested (BVH_WIDTH per node visited): a stage that defines TRAVERSE_COUNT_NODES before
// including this file can show traversal cost (see examples/shaders/bvh-cost). Off by default, so it costs nothing.
uint traverse_node_visits = 0u;
#endif

// any_hit: stop at the first intersection (shadow rays). alpha_key: the ray's hash for stochastic transparency
// (alphaMode BLEND); alpha-tested triangles the ray passes through are not hits. Alpha testing is compiled in only
// with ALPHA_TEST (the *_alpha stage variants), and decided outside the loop: inside it made traversal 4x slower on
// lavapipe even when no triangle needed it; outside, it still costs opaque scenes 40 %, hence the variant.
//
// lavapipe runs both sides of every branch under a mask, so a loop step costs a node test plus a triangle test
// whichever one a lane needs. Each step therefore does one of each: the next interior node (all its children), and
// the next triangle of a pending leaf. A leaf reached while another is pending waits as the current node. Four-wide
// nodes halve the steps of two-wide ones, and quantised child boxes keep a node to three texel reads (see docs/guide/internals.md).

float sooner(float a, float b) { return a < b ? a : b; }
float later(float a, float b) { return a > b ? a : b; }

// Slab test of child c: its entry distance, or +inf when the ray misses its box within (tmin, tmax) (an unused slot
// is masked by the caller). Grid point q's slab distance is base + q * step, with base = (origin - o) * inv_d and
// step = scale * inv_d found once per node: a multiply and an add per bound instead of decoding the bound, then a
// subtract and a multiply, 4.5 % faster on the Cornell box. The builder keeps every grid point a float, so this
// measures the box it checked; its rounding is of the size the decoded form's was.
float test_child(BvhNode n, uint c, vec3 base, vec3 step, float tmin, float tmax) {
    uint shift = 8u * c;
    vec3 t0 = base + vec3((n.q0.xyz >> shift) & 0xFFu) * step;
    vec3 t1 = base + vec3((uvec3(n.q0.w, n.q1.xy) >> shift) & 0xFFu) * step;
    // Selects rather than min and max: gallivm gives those NaN-aware semantics, an unordered compare and a blend each
    // besides the min or max, where a < b ? a : b is one minps. The distances are never NaN (see safe_inverse) in
    // scenes within about 1e8 units, whose grid steps keep step finite, so the result is the same: 6.5 % faster on
    // the Cornell box.
    bvec3 near0 = lessThan(t0, t1);
    vec3 tn = mix(t1, t0, near0);
    vec3 tf = mix(t0, t1, near0);
    float enter = later(later(tn.x, tn.y), later(tn.z, tmin));
    float exit = sooner(sooner(tf.x, tf.y), sooner(tf.z, tmax));
    return enter <= exit ? enter : uintBitsToFloat(0x7F800000u);
}

// Each child as a stack entry, first << STACK_COUNT_BITS | count (count 0 for an interior node), or 0 for an unused
// slot: layout.glsl's BvhNode keeps kinds and where the runs start, BvhNode::child_entries is the CPU twin.
uvec4 child_entries(BvhNode n) {
    uvec4 kind = uvec4(n.origin.w >> 24u, n.origin.w >> 27u, n.q1.z, n.q1.w) & ((1u << STACK_COUNT_BITS) - 1u);
    bvec4 interior = equal(kind, uvec4(BVH_CHILD_INTERIOR));
    uvec4 nodes = uvec4(interior);
    uvec4 tris = mix(kind, uvec4(0u), interior);
    uvec4 node = (n.q1.z >> STACK_COUNT_BITS) + uvec4(0u, nodes.x, nodes.x + nodes.y, nodes.x + nodes.y + nodes.z);
    uvec4 tri = (n.q1.w >> STACK_COUNT_BITS) + uvec4(0u, tris.x, tris.x + tris.y, tris.x + tris.y + tris.z);
    uvec4 entry = mix(tri << STACK_COUNT_BITS | tris, node << STACK_COUNT_BITS, interior);
    return mix(entry, uvec4(0u), equal(kind, uvec4(0u)));
}

// A child or stack word, first << STACK_COUNT_BITS | count, as (first, count).
void unpack(uint word, out uint first, out uint count) {
    first = word >> STACK_COUNT_BITS;
    count = word & ((1u << STACK_COUNT_BITS) - 1u);
}

// One compare-exchange of the sorting network that orders a node's children near to far.
void sort2(inout float ta, inout float tb, inout uint wa, inout uint wb) {
    bool swap = tb < ta;
    float t = ta;
    uint w = wa;
    ta = swap ? tb : ta;
    tb = swap ? t : tb;
    wa = swap ? wb : wa;
    wb = swap ? w : wb;
}

// The register stack (s0 .. s7 in trace_hit) is written out for REGISTER_STACK = 8: any other value fails to compile.
const uint register_stack_is_written_out_for_8[REGISTER_STACK == 8u ? 1 : 0] = uint[](0u);

// The closest (or any) hit's distance and triangle in the BVH rooted at node `root` (0: the world's); its barycentrics
// are left 0 (see trace).
Hit trace_hit(vec3 o, vec3 d, float tmin, float tmax, bool any_hit, uint alpha_key, uint root) {
    Hit hit;
    hit.t = tmax;
    hit.tri = NO_HIT;
    hit.uv = vec2(0.0);
    hit.inst = NO_INSTANCE;
    vec3 inv_d = safe_inverse(d);
    // A node is known by its (first, count) word, read when its parent tested its box: visiting an interior node
    // fetches only its own record, a leaf nothing more. A stack entry is that word alone. Keeping each entry's
    // distance too, to drop nodes beyond the closest hit when popped, cost more than it saved on lavapipe (each word
    // pushed is a per-lane scatter): without it random rays ran 4 % faster and the Cornell box's extend and connect
    // stages 5-15 %. A popped node's children are still tested against the closest hit.
    //
    // Scenes whose stack never holds more than REGISTER_STACK entries (no FEATURE_DEEP_STACK) keep it in registers
    // instead, s0 on top: a push shifts the entries down by the number pushed, a pop up by one (see constants.rs).
    uint stack[BVH_STACK_SIZE];
    uint s0 = 0u, s1 = 0u, s2 = 0u, s3 = 0u, s4 = 0u, s5 = 0u, s6 = 0u, s7 = 0u;
    uint sp = 0u;
    // Traversal starts at the root as if its parent had entered it (an empty tree's root has no children).
    uint first = root;
    uint count = 0u;
    bool has_node = true; // (first, count) is a node still to visit
    uint tri = 0u;        // the pending leaf: triangles tri .. end - 1 are still to test
    uint end = 0u;
#ifdef ALPHA_TEST
    // A candidate on an alpha-tested triangle leaves the loop, is tested here, and traversal resumes where it was.
    while (true) {
        uint pending = NO_HIT;
        float pending_t = 0.0;
        vec2 pending_uv = vec2(0.0);
#endif
    while (true) {
        if (has_node && count == 0u) {
            // All four children (BVH_WIDTH) at once, sorted near to far (misses, at +inf, sort last): the nearest is
            // visited next, the others entered wait on the stack, farthest first. Stores are unconditional (a missed
            // child is written, then overwritten) and sp moves only for hits, since branches cost their bodies anyway.
            BvhNode n = load_node(first);
            vec3 origin = uintBitsToFloat(n.origin.xyz);
            vec3 scale = uintBitsToFloat(((uvec3(n.origin.w) >> uvec3(0u, 8u, 16u)) & 0xFFu) << 23u);
            vec3 base = (origin - o) * inv_d;
            vec3 step = scale * inv_d;
            vec4 ct = vec4(test_child(n, 0u, base, step, tmin, hit.t),
                           test_child(n, 1u, base, step, tmin, hit.t),
                           test_child(n, 2u, base, step, tmin, hit.t),
                           test_child(n, 3u, base, step, tmin, hit.t));
            uvec4 cw = child_entries(n);
            // An unused slot is a miss.
            ct = mix(ct, vec4(uintBitsToFloat(0x7F800000u)), equal(cw, uvec4(0u)));
#ifdef TRAVERSE_COUNT_NODES
            traverse_node_visits += BVH_WIDTH;
#endif
            sort2(ct.x, ct.y, cw.x, cw.y);
            sort2(ct.z, ct.w, cw.z, cw.w);
            sort2(ct.x, ct.z, cw.x, cw.z);
            sort2(ct.y, ct.w, cw.y, cw.w);
            sort2(ct.y, ct.z, cw.y, cw.z);
            if (scene_has(FEATURE_DEEP_STACK)) {
                stack[sp] = cw.w;
                sp += ct.w != uintBitsToFloat(0x7F800000u) ? 1u : 0u;
                stack[sp] = cw.z;
                sp += ct.z != uintBitsToFloat(0x7F800000u) ? 1u : 0u;
                stack[sp] = cw.y;
                sp += ct.y != uintBitsToFloat(0x7F800000u) ? 1u : 0u;
            } else {
                // Entered children are a prefix of the sorted four, so y, z, w push as the top 0 to 3 entries.
                const float miss = uintBitsToFloat(0x7F800000u);
                uint k = (ct.y != miss ? 1u : 0u) + (ct.z != miss ? 1u : 0u) + (ct.w != miss ? 1u : 0u);
                s7 = k == 0u ? s7 : k == 1u ? s6 : k == 2u ? s5 : s4;
                s6 = k == 0u ? s6 : k == 1u ? s5 : k == 2u ? s4 : s3;
                s5 = k == 0u ? s5 : k == 1u ? s4 : k == 2u ? s3 : s2;
                s4 = k == 0u ? s4 : k == 1u ? s3 : k == 2u ? s2 : s1;
                s3 = k == 0u ? s3 : k == 1u ? s2 : k == 2u ? s1 : s0;
                s2 = k == 0u ? s2 : k == 1u ? s1 : k == 2u ? s0 : cw.w;
                s1 = k == 0u ? s1 : k == 1u ? s0 : cw.z;
                s0 = k == 0u ? s0 : cw.y;
                sp += k;
            }
            unpack(cw.x, first, count);
            has_node = ct.x != uintBitsToFloat(0x7F800000u);
        }
        if (has_node && count > 0u && tri == end) {
            tri = first;
            end = first + count;
            has_node = false;
        }
        if (!has_node && sp > 0u) {
            --sp;
            if (scene_has(FEATURE_DEEP_STACK)) {
                unpack(stack[sp], first, count);
            } else {
                unpack(s0, first, count);
                s0 = s1;
                s1 = s2;
                s2 = s3;
                s3 = s4;
                s4 = s5;
                s5 = s6;
                s6 = s7;
            }
            has_node = true;
        }
        if (tri < end) {
            vec2 uv;
            float t = intersect_triangle(tri, o, d, tmin, hit.t, uv);
            uint i = tri++;
#ifdef ALPHA_TEST
            if (t >= 0.0 && load_tri_verts(i).e1.w != 0.0) {
                pending = i;
                pending_t = t;
                pending_uv = uv;
                break;
            }
#endif
            // Selects, not a branch: the closest hit's barycentrics are found again once traversal ends.
            bool found = t >= 0.0;
            hit.t = found ? t : hit.t;
            hit.tri = found ? i : hit.tri;
            if (any_hit && found) break;
        } else if (!has_node && sp == 0u) {
            break;
        }
    }
#ifdef ALPHA_TEST
        if (pending == NO_HIT) break;
        if (alpha_stops(pending, pending_uv, alpha_key)) {
            hit.t = pending_t;
            hit.tri = pending;
            if (any_hit) break;
        }
    }
#endif
    return hit;
}

// Beyond `hit` (the world BVH's), the closest (or any) hit among the instances: the top-level BVH's leaves are
// instances (records from 1), each traced in its own object space from its own root. A plain stack walk: the TLAS is
// small next to the BVHs below it, where the time goes.
Hit trace_instances(vec3 o, vec3 d, float tmin, Hit hit, bool any_hit, uint alpha_key) {
    Instance header = instances[0];
    vec3 inv_d = safe_inverse(d);
    uint stack[BVH_STACK_SIZE];
    uint sp = 0u;
    uint first = header.info.x;
    uint count = 0u;
    bool more = header.info.y > 0u;
    while (more) {
        if (count == 0u) {
            BvhNode n = load_node(first);
            vec3 origin = uintBitsToFloat(n.origin.xyz);
            vec3 scale = uintBitsToFloat(((uvec3(n.origin.w) >> uvec3(0u, 8u, 16u)) & 0xFFu) << 23u);
            vec3 base = (origin - o) * inv_d;
            vec3 step = scale * inv_d;
            uvec4 cw = child_entries(n);
            for (uint c = 0u; c < BVH_WIDTH; ++c) {
                float t = test_child(n, c, base, step, tmin, hit.t);
                stack[sp] = cw[c];
                sp += (cw[c] != 0u && t != uintBitsToFloat(0x7F800000u)) ? 1u : 0u;
            }
        } else {
            for (uint k = 0u; k < count; ++k) {
                Instance inst = instance_at(first + k);
                vec3 oo = o, od = d;
                to_object(inst, oo, od);
                Hit h = trace_hit(oo, od, tmin, hit.t, any_hit, alpha_key, inst.info.x);
                if (h.tri != NO_HIT) {
                    hit.t = h.t;
                    hit.tri = h.tri;
                    hit.inst = first + k;
                }
            }
            if (any_hit && hit.tri != NO_HIT) break;
        }
        more = sp > 0u;
        if (more) {
            --sp;
            unpack(stack[sp], first, count);
        }
    }
    return hit;
}

#ifdef RAY_QUERY
// The same hits through the device's own acceleration structures (src/render/accel.rs): instance 0 of the top level
// holds the world's triangles, instance i > 0 is instance record i; an instance's custom index is its mesh's first
// triangle, so a hit's triangle is that plus the primitive index. Triangles of alpha-tested materials are the only
// candidates the query hands back (their geometry is not opaque); the rest are committed by the device.
layout(set = 0, binding = BINDING_TLAS) uniform accelerationStructureEXT tlas;

Hit trace_all(vec3 o, vec3 d, float tmin, float tmax, bool any_hit, uint alpha_key) {
    rayQueryEXT q;
    uint flags = any_hit ? gl_RayFlagsTerminateOnFirstHitEXT : gl_RayFlagsNoneEXT;
    rayQueryInitializeEXT(q, tlas, flags, 0xFFu, o, tmin, d, tmax);
    while (rayQueryProceedEXT(q)) {
        uint tri = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(q, false)) +
                   uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, false));
#ifdef ALPHA_TEST
        vec2 uv = rayQueryGetIntersectionBarycentricsEXT(q, false);
        if (load_tri_verts(tri).e1.w == 0.0 || alpha_stops(tri, uv, alpha_key)) rayQueryConfirmIntersectionEXT(q);
#else
        rayQueryConfirmIntersectionEXT(q);
#endif
    }
    Hit h;
    h.t = tmax;
    h.tri = NO_HIT;
    h.uv = vec2(0.0);
    h.inst = NO_INSTANCE;
    if (rayQueryGetIntersectionTypeEXT(q, true) == gl_RayQueryCommittedIntersectionTriangleEXT) {
        h.t = rayQueryGetIntersectionTEXT(q, true);
        h.tri = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(q, true)) +
                uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, true));
        h.uv = rayQueryGetIntersectionBarycentricsEXT(q, true);
        uint id = uint(rayQueryGetIntersectionInstanceIdEXT(q, true));
        h.inst = id == 0u ? NO_INSTANCE : id;
    }
    return h;
}

// The query gives the barycentrics of its own arithmetic: they are kept rather than found again.
Hit trace(vec3 o, vec3 d, float tmin, float tmax, bool any_hit, uint alpha_key) {
    return trace_all(o, d, tmin, tmax, any_hit, alpha_key);
}
#else
// The closest (or any) hit in the world BVH and then, where the scene has them, among the instances.
Hit trace_all(vec3 o, vec3 d, float tmin, float tmax, bool any_hit, uint alpha_key) {
#ifdef TRAVERSE_COUNT_NODES
    traverse_node_visits = 0u;
#endif
    Hit h = trace_hit(o, d, tmin, tmax, any_hit, alpha_key, 0u);
    if (scene_has(FEATURE_INSTANCES) && !(any_hit && h.tri != NO_HIT)) {
        h = trace_instances(o, d, tmin, h, any_hit, alpha_key);
    }
    return h;
}

// The hit with its barycentrics, found again from the same arithmetic (traversal keeps only t and the triangle).
Hit trace(vec3 o, vec3 d, float tmin, float tmax, bool any_hit, uint alpha_key) {
    return with_barycentrics(trace_all(o, d, tmin, tmax, any_hit, alpha_key), o, d, tmin);
}
#endif

// Whether anything blocks the segment: a shadow ray, which skips the barycentrics' triangle test.
bool occluded(vec3 o, vec3 d, float tmin, float tmax, uint alpha_key) {
    return trace_all(o, d, tmin, tmax, true, alpha_key).tri != NO_HIT;
}

#endif
