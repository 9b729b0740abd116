//! BVH correctness: the CPU traversal of the GPU layout and the device traversal both match a brute force.
mod common;

use glam::Vec3;
use pathwave::bvh::{self, brute_force, intersect_triangle, Ray, TraceHit};
use pathwave::constants::{NO_HIT, REGISTER_STACK};
use pathwave::layout::TriVerts;
use pathwave::render::gpu_scene;
use pathwave::scene::{Material, Mesh, Primitive, Scene};

use common::rng::Rng;

/// Ranges, points and directions from the shared test generator.
trait RngExt {
    fn range(&mut self, lo: f32, hi: f32) -> f32;
    fn vec(&mut self, lo: Vec3, hi: Vec3) -> Vec3;
    fn dir(&mut self) -> Vec3;
}

impl RngExt for Rng {
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
    fn vec(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(self.range(lo.x, hi.x), self.range(lo.y, hi.y), self.range(lo.z, hi.z))
    }
    fn dir(&mut self) -> Vec3 {
        loop {
            let v = self.vec(Vec3::splat(-1.0), Vec3::splat(1.0));
            if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }
}

/// One mesh of face-normal triangles, placed once where they are.
fn scene_of(triangles: Vec<[Vec3; 3]>) -> Scene {
    let mut scene = Scene {
        materials: vec![Material::default()],
        ..Default::default()
    };
    let primitives = vec![Primitive::from_triangles(&triangles, None, 0)];
    scene.add_mesh(
        Mesh {
            name: "soup".into(),
            primitives,
        },
        glam::Mat4::IDENTITY,
    );
    scene
}

/// n triangles with centres in [-1, 1]^3 and vertices at a random distance in `size` from them.
fn soup(rng: &mut Rng, n: usize, size: (f32, f32)) -> Vec<[Vec3; 3]> {
    (0..n)
        .map(|_| {
            let c = rng.vec(Vec3::splat(-1.0), Vec3::splat(1.0));
            let s = rng.range(size.0, size.1);
            [c + rng.dir() * s, c + rng.dir() * s, c + rng.dir() * s]
        })
        .collect()
}

/// A UV sphere over a large ground quad: shared edges, many coplanar neighbours, a long thin box.
fn sphere_and_plane() -> Vec<[Vec3; 3]> {
    let (rings, segs) = (24, 48);
    let p = |i: usize, j: usize| {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        let ph = 2.0 * std::f32::consts::PI * j as f32 / segs as f32;
        Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * 0.7 + Vec3::new(0.0, 0.8, 0.0)
    };
    let mut t = Vec::new();
    for i in 0..rings {
        for j in 0..segs {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            if i != 0 {
                t.push([a, b, d]);
            }
            if i + 1 != rings {
                t.push([b, c, d]);
            }
        }
    }
    let g = 5.0;
    t.push([Vec3::new(-g, 0.0, -g), Vec3::new(-g, 0.0, g), Vec3::new(g, 0.0, g)]);
    t.push([Vec3::new(-g, 0.0, -g), Vec3::new(g, 0.0, g), Vec3::new(g, 0.0, -g)]);
    t
}

/// 10k+ rays: a third random, a third along the axes, a third leaving a point on a triangle.
fn rays(rng: &mut Rng, tris: &[[Vec3; 3]], lo: Vec3, hi: Vec3, n: usize) -> Vec<Ray> {
    let pad = (hi - lo) * 0.2;
    let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    (0..n)
        .map(|i| match i % 3 {
            0 => Ray {
                origin: rng.vec(lo - pad, hi + pad),
                dir: rng.dir(),
                tmin: 0.0,
                tmax: f32::MAX,
            },
            1 => Ray {
                origin: rng.vec(lo - pad, hi + pad),
                dir: axes[i / 3 % 6],
                tmin: 0.0,
                tmax: f32::MAX,
            },
            _ => {
                let t = tris[(rng.next() * tris.len() as f32) as usize % tris.len()];
                let (mut u, mut v) = (rng.next(), rng.next());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                let origin = t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0]);
                Ray {
                    origin,
                    dir: rng.dir(),
                    tmin: 0.0,
                    tmax: f32::MAX,
                }
            }
        })
        .collect()
}

/// Is `h` an acceptable closest hit given the reference `r`? Differences are allowed only where rounding
/// legitimately decides: equal distances (shared edges), hits on an edge, or a hit at the ray's own origin.
fn agrees(tris: &[TriVerts], ray: &Ray, h: &TraceHit, r: &TraceHit) -> Result<bool, String> {
    let tol = |t: f32| 1e-4 * (1.0 + t.abs());
    if h.tri == r.tri && (h.tri == NO_HIT || (h.t - r.t).abs() <= tol(r.t)) {
        return Ok(false);
    }
    let near_edge = |h: &TraceHit| {
        let w = 1.0 - h.uv.x - h.uv.y;
        h.uv.x.min(h.uv.y).min(w) < 1e-4
    };
    let self_hit = |h: &TraceHit| h.tri != NO_HIT && h.t < 1e-4;
    let ambiguous = match (h.tri == NO_HIT, r.tri == NO_HIT) {
        (false, false) => (h.t - r.t).abs() <= tol(r.t) || self_hit(h) || self_hit(r) || near_edge(h) || near_edge(r),
        (true, false) => near_edge(r) || self_hit(r),
        (false, true) => near_edge(h) || self_hit(h),
        (true, true) => unreachable!(),
    };
    if !ambiguous {
        // Describe it fully: what the device says against what the reference says.
        let check =
            (h.tri != NO_HIT).then(|| intersect_triangle(&tris[h.tri as usize], ray.origin, ray.dir, -1.0, f32::MAX));
        return Err(format!(
            "ray {ray:?}: got {h:?}, reference {r:?}; the got-triangle re-tested on the CPU: {check:?}"
        ));
    }
    Ok(true)
}

fn check_mesh(name: &str, triangles: Vec<[Vec3; 3]>, seed: u64) {
    check_mesh_with(name, triangles, seed, 12_000);
}

fn check_mesh_with(name: &str, triangles: Vec<[Vec3; 3]>, seed: u64, ray_count: usize) {
    let mut rng = Rng(seed);
    let scene = scene_of(triangles);
    let packed = gpu_scene::pack(&scene);
    let soup = scene.flatten();
    assert_wide_tree_is_sound(&packed.bvh, soup.positions());
    let (lo, hi) = scene.bounds();
    let rays = rays(&mut rng, soup.positions(), lo, hi, ray_count);
    let reference: Vec<TraceHit> = rays.iter().map(|r| brute_force(&packed.tri_verts, r)).collect();

    // The CPU traversal of the exact GPU layout does the same arithmetic as the brute force: the distance must
    // match bit for bit (the triangle may differ only on an exact tie, where both are right).
    for (ray, r) in rays.iter().zip(&reference) {
        let h = bvh::trace(&packed.bvh.nodes, &packed.tri_verts, ray, false);
        assert!(h.t == r.t, "{name}: CPU BVH {h:?} vs brute force {r:?} for {ray:?}");
        assert_eq!(
            h.tri == NO_HIT,
            r.tri == NO_HIT,
            "{name}: CPU BVH hit/miss differs for {ray:?}"
        );
    }

    let mut renderer = pathwave::Renderer::with_validation(&scene, &Default::default(), common::validation()).unwrap();
    // Both ways of reading the BVH on the device: texel buffers (where supported) and storage buffers.
    for reads in [pathwave::BvhReads::Texel, pathwave::BvhReads::Storage] {
        if let Err(e) = renderer.set_bvh_reads(reads) {
            // lavapipe (the CI device) supports both; elsewhere a device may lack texel buffers this large.
            assert!(!renderer.context().device_name().contains("llvmpipe"), "{name}: {e}");
            eprintln!("note: {name}: {reads:?} BVH reads are not tested here: {e}");
            continue;
        }
        let device = renderer.probe_trace(&rays, false).unwrap();
        let mut ambiguous = 0;
        let mut hits = 0;
        for ((ray, h), r) in rays.iter().zip(&device).zip(&reference) {
            hits += (r.tri != NO_HIT) as usize;
            match agrees(&packed.tri_verts, ray, h, r) {
                Ok(a) => ambiguous += a as usize,
                Err(e) => panic!("{name} ({reads:?}): device closest hit disagrees with brute force: {e}"),
            }
        }
        eprintln!(
            "{name} ({reads:?}): {} triangles, {} rays, {hits} hits, {ambiguous} decided by rounding",
            soup.len(),
            rays.len()
        );
        assert!(
            hits > rays.len() / 4,
            "{name} ({reads:?}): too few rays hit anything for the test to mean much"
        );
        assert!(
            ambiguous * 200 < rays.len(),
            "{name} ({reads:?}): {ambiguous} rounding-decided rays is more than 0.5 %"
        );

        // Any-hit (shadow rays) with finite lengths: occluded or not must match the brute force.
        let shadow: Vec<Ray> = rays
            .iter()
            .map(|r| Ray {
                tmax: rng.range(0.05, 3.0),
                ..*r
            })
            .collect();
        let any = renderer.probe_trace(&shadow, true).unwrap();
        let mut occluded = 0;
        for (ray, h) in shadow.iter().zip(&any) {
            let r = brute_force(&packed.tri_verts, ray);
            occluded += (r.tri != NO_HIT) as usize;
            if (h.tri == NO_HIT) != (r.tri == NO_HIT) {
                let edge = |x: &TraceHit| {
                    x.tri != NO_HIT
                        && (x.t < 1e-4
                            || (ray.tmax - x.t) < 1e-4 * ray.tmax
                            || x.uv.min_element() < 1e-4
                            || 1.0 - x.uv.x - x.uv.y < 1e-4)
                };
                assert!(
                    edge(h) || edge(&r),
                    "{name} ({reads:?}): any-hit {h:?} vs brute force {r:?} for {ray:?}"
                );
            }
            if h.tri != NO_HIT {
                assert!(
                    h.t > ray.tmin && h.t < ray.tmax,
                    "{name} ({reads:?}): any-hit outside the ray's interval: {h:?}"
                );
            }
        }
        assert!(
            occluded > 0 && occluded < shadow.len(),
            "{name} ({reads:?}): shadow rays must be a mix of occluded and free"
        );
    }
}

/// The most entries the mesh's traversal stack can hold: up to REGISTER_STACK, traversal keeps them in registers
/// (FEATURE_DEEP_STACK cleared), past it in memory.
fn stack_bound(triangles: &[[Vec3; 3]]) -> u32 {
    gpu_scene::pack(&scene_of(triangles.to_vec())).bvh.stats.max_waiting
}

#[test]
fn random_triangle_soup() {
    let mut rng = Rng(1);
    let tris = soup(&mut rng, 3000, (0.02, 0.3));
    assert!(
        stack_bound(&tris) > REGISTER_STACK,
        "this test is for the stack in memory"
    );
    check_mesh("soup", tris, 2);
}

#[test]
fn small_soup_with_the_stack_in_registers() {
    let mut rng = Rng(5);
    // Large, overlapping triangles, so enough of the rays hit one.
    let tris = soup(&mut rng, 24, (0.8, 1.2));
    assert!(
        stack_bound(&tris) <= REGISTER_STACK,
        "this test is for the stack in registers"
    );
    check_mesh("small soup", tris, 6);
}

/// 80k triangles: enough for the build to split across threads and splice subtrees (past 32k triangles).
#[test]
fn large_soup_built_in_parallel() {
    let mut rng = Rng(11);
    let tris = soup(&mut rng, 80_000, (0.005, 0.05));
    let one = bvh::build_with_threads(&tris, 1);
    let four = bvh::build_with_threads(&tris, 4);
    assert!(
        one.nodes == four.nodes && one.order == four.order,
        "the layout depends on the thread count"
    );
    check_mesh_with("large soup", tris, 12, 2_000);
}

#[test]
fn sphere_over_plane() {
    check_mesh("sphere", sphere_and_plane(), 3);
}

/// Child boxes are quantised relative to their parent on a power-of-two grid: a 2-centimetre object 1 km from the
/// origin (its smallest nodes span a few hundred float steps of their position) and a 500-kilometre one exercise the
/// grid's exponent at both ends, and the rounding outwards in float arithmetic. The mesh is turned off the axes so no test
/// ray lies in its plane, where a box test and a triangle test legitimately disagree.
#[test]
fn quantised_boxes_hold_at_extreme_scales() {
    let turn = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, 0.2);
    let mesh = |scale: f32, at: Vec3| -> Vec<[Vec3; 3]> {
        sphere_and_plane()
            .into_iter()
            .map(|t| t.map(|v| turn * v * scale + at))
            .collect()
    };
    check_mesh_with("far and small", mesh(1e-2, Vec3::new(1.0e3, -0.7e3, 0.4e3)), 21, 2_000);
    check_mesh_with("huge", mesh(2.5e5, Vec3::ZERO), 22, 2_000);
}

#[test]
fn cornell_box() {
    let scene = pathwave::scene::load(&common::scenes_dir().join("cornell-box.gltf"), None).unwrap();
    let triangles = scene.flatten().positions().to_vec();
    assert!(
        stack_bound(&triangles) <= REGISTER_STACK,
        "the bench's Cornell box traces with the stack in registers"
    );
    check_mesh("cornell", triangles, 4);
}

#[test]
fn empty_scene_misses_everything() {
    let b = bvh::build(&[]);
    let ray = Ray {
        origin: Vec3::ZERO,
        dir: Vec3::X,
        tmin: 0.0,
        tmax: f32::MAX,
    };
    assert_eq!(bvh::trace(&b.nodes, &[], &ray, false).tri, NO_HIT);
}

#[test]
fn build_respects_leaf_size_and_stack_depth() {
    let mut rng = Rng(9);
    // Many coincident triangles force the median fallback.
    let mut tris = soup(&mut rng, 2000, (0.02, 0.3));
    tris.extend(std::iter::repeat_n([Vec3::ZERO, Vec3::X, Vec3::Y], 500));
    let b = bvh::build(&tris);
    assert!(b.stats.max_leaf_tris <= pathwave::constants::BVH_MAX_LEAF_TRIS);
    assert!(b.stats.depth < pathwave::constants::BVH_STACK_SIZE);
    assert!(
        b.stats.max_waiting < pathwave::constants::BVH_STACK_SIZE,
        "traversal could push past the stack: {} entries",
        b.stats.max_waiting
    );
    assert_wide_tree_is_sound(&b, &tris);
    let mut seen = b.order.clone();
    seen.sort();
    assert_eq!(
        seen,
        (0..tris.len() as u32).collect::<Vec<_>>(),
        "the order must be a permutation"
    );
}

/// Walks the wide tree: every node's used child slots come first and there are at least two (one for a tree that is a
/// single leaf), each child's decoded (quantised) box holds every triangle beneath it, and the leaves cover every
/// triangle exactly once.
fn assert_wide_tree_is_sound(b: &bvh::Bvh, tris: &[[Vec3; 3]]) {
    use pathwave::constants::{BVH_WIDTH, STACK_COUNT_BITS};
    let mut covered = vec![0u32; tris.len()];
    // Returns the bounds of the triangles under the child entry, checking each level on the way up.
    fn walk(b: &bvh::Bvh, tris: &[[Vec3; 3]], entry: u32, covered: &mut [u32]) -> (Vec3, Vec3) {
        let (first, count) = (entry >> STACK_COUNT_BITS, entry & ((1 << STACK_COUNT_BITS) - 1));
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        if count > 0 {
            for i in first..first + count {
                covered[i as usize] += 1;
                for v in tris[b.order[i as usize] as usize] {
                    (lo, hi) = (lo.min(v), hi.max(v));
                }
            }
            return (lo, hi);
        }
        let n = b.nodes[first as usize];
        let entries = n.child_entries();
        let used = entries.iter().take_while(|&&w| w != 0).count();
        assert!(
            entries[used..].iter().all(|&w| w == 0),
            "node {first}: a used child after an unused slot"
        );
        assert!(used >= 2 || first == 0, "node {first}: fewer than two children");
        for (c, &entry) in entries.iter().enumerate().take(used) {
            assert!(
                entry >> STACK_COUNT_BITS > first || entry & 7 > 0,
                "node {first}: a cycle"
            );
            let (clo, chi) = walk(b, tris, entry, covered);
            let (qlo, qhi) = n.child_box(c).expect("a used slot has a box");
            // Traversal measures grid points as base + q * step, the unrounded origin + q * scale: the builder keeps
            // every grid point a float, so that is the box checked below.
            let (lo_q, hi_q) = n.child_q(c);
            for a in 0..3 {
                for q in [lo_q[a], hi_q[a]] {
                    let exact = n.grid_origin()[a] as f64 + q as f64 * n.scale()[a] as f64;
                    assert_eq!(
                        n.bound(a, q) as f64,
                        exact,
                        "node {first} child {c}: grid point {q} is not a float"
                    );
                }
            }
            assert!(
                (0..3).all(|k| qlo[k] <= clo[k] && qhi[k] >= chi[k]),
                "node {first} child {c}: decoded box {qlo:?}..{qhi:?} does not hold {clo:?}..{chi:?}"
            );
            (lo, hi) = (lo.min(clo), hi.max(chi));
        }
        assert!(used <= BVH_WIDTH as usize);
        (lo, hi)
    }
    walk(b, tris, 0, &mut covered);
    assert!(
        covered.iter().all(|&c| c == 1),
        "every triangle sits in exactly one leaf"
    );
}
