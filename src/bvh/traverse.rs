//! CPU traversal of the exact GPU node layout; it mirrors shaders/include/traverse.glsl line for line.
use crate::constants::{BVH_STACK_SIZE, BVH_WIDTH, MOTION_SEGMENTS, NO_HIT, NO_INSTANCE, STACK_COUNT_BITS};
use crate::layout::{BvhNode, GpuInstance, TriVerts};
use glam::{Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceHit {
    pub t: f32,
    /// Index into the reordered triangles, or NO_HIT.
    pub tri: u32,
    pub uv: Vec2,
    /// The instance record whose triangle it is, or NO_INSTANCE (a world-space triangle, or a miss).
    pub inst: u32,
}

fn v3(a: [f32; 4]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// Moller-Trumbore, identical to the GLSL: returns t in (tmin, tmax) or None.
pub fn intersect_triangle(tv: &TriVerts, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<(f32, Vec2)> {
    let (v0, e1, e2) = (v3(tv.v0), v3(tv.e1), v3(tv.e2));
    let pvec = d.cross(e2);
    let det = e1.dot(pvec);
    if det == 0.0 {
        return None;
    }
    let inv_det = 1.0 / det;
    let tvec = o - v0;
    let u = tvec.dot(pvec) * inv_det;
    // Written as two comparisons, not a range, so a NaN passes exactly as it does in the GLSL.
    #[allow(clippy::manual_range_contains)]
    if u < 0.0 || u > 1.0 {
        return None;
    }
    let qvec = tvec.cross(e1);
    let v = d.dot(qvec) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qvec) * inv_det;
    if t <= tmin || t >= tmax {
        return None;
    }
    Some((t, Vec2::new(u, v)))
}

fn safe_inverse(d: Vec3) -> Vec3 {
    let inv = |x: f32| if x != 0.0 { (1.0 / x).clamp(-1e30, 1e30) } else { 1e30 };
    Vec3::new(inv(d.x), inv(d.y), inv(d.z))
}

/// The device's min and max in the slab test, written as it writes them (traverse.glsl's sooner and later).
fn sooner(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

fn later(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Child `c`'s entry distance, if the ray enters its box within (tmin, tmax): the slab distances of grid point q are
/// base + q * step, with base = (origin - o) * inv_d and step = scale * inv_d found once per node, as traverse.glsl
/// does (the device may fuse the multiply-add, so the last bit of a distance can differ; the hits do not).
fn test_child(n: &BvhNode, c: usize, base: Vec3, step: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
    if n.kind(c) == 0 {
        return None;
    }
    let (lo, hi) = n.child_q(c);
    let t0 = base + Vec3::new(lo[0] as f32, lo[1] as f32, lo[2] as f32) * step;
    let t1 = base + Vec3::new(hi[0] as f32, hi[1] as f32, hi[2] as f32) * step;
    let near0 = t0.cmplt(t1);
    let tn = Vec3::select(near0, t0, t1);
    let tf = Vec3::select(near0, t1, t0);
    let enter = later(later(tn.x, tn.y), later(tn.z, tmin));
    let exit = sooner(sooner(tf.x, tf.y), sooner(tf.z, tmax));
    (enter <= exit).then_some(enter)
}

/// A child or stack word, first << STACK_COUNT_BITS | count, as (first, count).
fn unpack(word: u32) -> (u32, u32) {
    (word >> STACK_COUNT_BITS, word & ((1 << STACK_COUNT_BITS) - 1))
}

/// Closest hit (or any hit) through the flattened BVH, in the same visiting order as the device: each step tests
/// the next interior node and the next triangle of a pending leaf (see traverse.glsl for why).
pub fn trace(nodes: &[BvhNode], tris: &[TriVerts], ray: &Ray, any_hit: bool) -> TraceHit {
    trace_from(nodes, tris, 0, ray, any_hit)
}

/// `trace` from the BVH rooted at node `root` (a mesh's own, in a two-level layout).
pub fn trace_from(nodes: &[BvhNode], tris: &[TriVerts], root: u32, ray: &Ray, any_hit: bool) -> TraceHit {
    let mut hit = TraceHit {
        t: ray.tmax,
        tri: NO_HIT,
        uv: Vec2::ZERO,
        inst: NO_INSTANCE,
    };
    let (o, d) = (ray.origin, ray.dir);
    let inv_d = safe_inverse(d);
    // A node is (first, count), packed on the stack as first << STACK_COUNT_BITS | count, as on the device, with no
    // distance (see traverse.glsl).
    let mut stack = [0u32; BVH_STACK_SIZE as usize];
    let mut sp = 0usize;
    // Traversal starts at the root as if its parent had entered it (an empty tree's root has no children).
    let (mut first, mut count) = (root, 0u32);
    let mut has_node = true;
    // The pending leaf: triangles tri .. end - 1 are still to test.
    let (mut tri, mut end) = (0u32, 0u32);
    loop {
        if has_node && count == 0 {
            // All children, sorted near to far by the same network as the device (misses are +inf and sort last).
            let n = &nodes[first as usize];
            let base = (Vec3::from(n.grid_origin()) - o) * inv_d;
            let step = Vec3::from(n.scale()) * inv_d;
            let mut ct: [f32; BVH_WIDTH as usize] =
                std::array::from_fn(|c| test_child(n, c, base, step, ray.tmin, hit.t).unwrap_or(f32::INFINITY));
            let mut cw = n.child_entries();
            for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
                if ct[b] < ct[a] {
                    ct.swap(a, b);
                    cw.swap(a, b);
                }
            }
            for c in (1..BVH_WIDTH as usize).rev() {
                stack[sp] = cw[c];
                if ct[c] != f32::INFINITY {
                    sp += 1;
                }
            }
            (first, count) = unpack(cw[0]);
            has_node = ct[0] != f32::INFINITY;
        }
        if has_node && count > 0 && tri == end {
            (tri, end) = (first, first + count);
            has_node = false;
        }
        if !has_node && sp > 0 {
            sp -= 1;
            (first, count) = unpack(stack[sp]);
            has_node = true;
        }
        if tri < end {
            let i = tri;
            tri += 1;
            if let Some((t, uv)) = intersect_triangle(&tris[i as usize], o, d, ray.tmin, hit.t) {
                hit = TraceHit {
                    t,
                    tri: i,
                    uv,
                    inst: NO_INSTANCE,
                };
                if any_hit {
                    return hit;
                }
            }
        } else if !has_node && sp == 0 {
            return hit;
        }
    }
}

/// Every triangle tested: the reference both traversals are checked against.
pub fn brute_force(tris: &[TriVerts], ray: &Ray) -> TraceHit {
    let mut hit = TraceHit {
        t: ray.tmax,
        tri: NO_HIT,
        uv: Vec2::ZERO,
        inst: NO_INSTANCE,
    };
    for (i, tv) in tris.iter().enumerate() {
        if let Some((t, uv)) = intersect_triangle(tv, ray.origin, ray.dir, ray.tmin, hit.t) {
            hit = TraceHit {
                t,
                tri: i as u32,
                uv,
                inst: NO_INSTANCE,
            };
        }
    }
    hit
}

/// The ray in an instance's object space, as traverse.glsl's to_object: the direction left unnormalised, so
/// distances along it stay the world's.
pub fn to_object(inst: &GpuInstance, ray: &Ray) -> Ray {
    let rows = [inst.object0, inst.object1, inst.object2].map(|r| (v3(r), r[3]));
    let point = |p: Vec3| Vec3::from_array(rows.map(|(r, w)| r.dot(p) + w));
    let vector = |d: Vec3| Vec3::from_array(rows.map(|(r, _)| r.dot(d)));
    Ray {
        origin: point(ray.origin),
        dir: vector(ray.dir),
        ..*ray
    }
}

/// Instance record `i` placed at `time` (the fraction of the shutter), as layout.glsl's instance_at: a moving
/// record's keys on either side interpolated (as motion::Pose::toward when they decompose, their rows linearly when
/// they do not), and the inverse of that map, by the same cross products.
pub fn instance_at(instances: &[GpuInstance], i: u32, time: f32) -> GpuInstance {
    let mut inst = instances[i as usize];
    let first_key = inst.info[3];
    if first_key == 0 {
        return inst;
    }
    let x = time * MOTION_SEGMENTS as f32;
    let k = (x as u32).min(MOTION_SEGMENTS - 1);
    let f = x - k as f32;
    let a = instances[(first_key + k) as usize];
    let b = instances[(first_key + k + 1) as usize];
    if a.object0[3] != 0.0 {
        let pose = |r: &GpuInstance| super::motion::Pose {
            translation: v3(r.object0),
            rotation: glam::Quat::from_array(r.object1),
            scale: v3(r.object2),
        };
        let m = pose(&a).toward(&pose(&b), f).matrix();
        (inst.world0, inst.world1, inst.world2) = (m.row(0).into(), m.row(1).into(), m.row(2).into());
    } else {
        let lerp = |a: [f32; 4], b: [f32; 4]| std::array::from_fn(|j| a[j] + (b[j] - a[j]) * f);
        inst.world0 = lerp(a.world0, b.world0);
        inst.world1 = lerp(a.world1, b.world1);
        inst.world2 = lerp(a.world2, b.world2);
    }
    let r = [inst.world0, inst.world1, inst.world2].map(v3);
    let c = [r[1].cross(r[2]), r[2].cross(r[0]), r[0].cross(r[1])];
    let inv_det = 1.0 / r[0].dot(c[0]);
    let t = Vec3::new(inst.world0[3], inst.world1[3], inst.world2[3]);
    let row = |j: usize| {
        let a = Vec3::new(c[0][j], c[1][j], c[2][j]) * inv_det;
        [a.x, a.y, a.z, -a.dot(t)]
    };
    (inst.object0, inst.object1, inst.object2) = (row(0), row(1), row(2));
    inst
}

/// The two-level traversal of traverse.glsl's trace_all at `time` (the fraction of the shutter; 0 without motion):
/// the world BVH from node 0, then (unless any hit is done) the top-level BVH over `instances` (the header first),
/// each instance placed at `time` and traced from its own root in its space. World triangles are taken as `tris`
/// holds them (key 0): moving world triangles are checked against brute force in tests/motion.rs.
pub fn trace_two_level(
    nodes: &[BvhNode],
    tris: &[TriVerts],
    instances: &[GpuInstance],
    ray: &Ray,
    any_hit: bool,
    time: f32,
) -> TraceHit {
    let mut hit = trace_from(nodes, tris, 0, ray, any_hit);
    let Some(header) = instances.first() else {
        return hit;
    };
    if (any_hit && hit.tri != NO_HIT) || header.info[1] == 0 {
        return hit;
    }
    let inv_d = safe_inverse(ray.dir);
    let mut stack = vec![header.info[0] << STACK_COUNT_BITS];
    while let Some(word) = stack.pop() {
        let (first, count) = unpack(word);
        if count == 0 {
            let n = &nodes[first as usize];
            let base = (Vec3::from(n.grid_origin()) - ray.origin) * inv_d;
            let step = Vec3::from(n.scale()) * inv_d;
            let cw = n.child_entries();
            for (c, &w) in cw.iter().enumerate() {
                if w != 0 && test_child(n, c, base, step, ray.tmin, hit.t).is_some() {
                    stack.push(w);
                }
            }
            continue;
        }
        for i in first..first + count {
            let inst = instance_at(instances, i, time);
            let local = Ray {
                tmax: hit.t,
                ..to_object(&inst, ray)
            };
            let h = trace_from(nodes, tris, inst.info[0], &local, any_hit);
            if h.tri != NO_HIT {
                hit = TraceHit { inst: i, ..h };
            }
        }
        if any_hit && hit.tri != NO_HIT {
            break;
        }
    }
    hit
}
