//! The light BVH's unit tests: the descent against its pmf twin, importance's zeros, and the cones' unions.
use super::bounds::cone_union;
use super::build::record;
use super::*;
use crate::constants::{LIGHT_NODE_LEAF, LIGHT_TREE_MAX_DEPTH};
use glam::Vec3;

fn lcg(state: &mut u64) -> f32 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 40) as f32 / (1u64 << 24) as f32
}

/// A field of small triangles facing every way, and point and spot lights, of widely varying power.
fn field(n: usize, seed: u64) -> Vec<(u32, LightBounds)> {
    let mut s = seed;
    (0..n)
        .map(|i| {
            let c = Vec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 10.0;
            let phi = 10f32.powf(3.0 * lcg(&mut s));
            let b = match i % 5 {
                3 => LightBounds::point(c, phi),
                4 => LightBounds::spot(c, Vec3::new(0.0, -1.0, 0.2), 0.3, 0.6, phi),
                _ => {
                    let d = Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5) * 0.4;
                    let e = Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5) * 0.4;
                    LightBounds::triangle(&[[c, c + d, c + e]], phi, i % 7 == 0).unwrap()
                }
            };
            (i as u32 * 2 + 1, b) // entries with gaps, as when the table holds infinite lights too
        })
        .collect()
}

fn receivers(seed: u64) -> Vec<(Vec3, Vec3)> {
    let mut s = seed;
    (0..12)
        .map(|k| {
            let p = Vec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 12.0 - 1.0;
            let n = Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5).normalize();
            (p, if k % 4 == 0 { Vec3::ZERO } else { n })
        })
        .collect()
}

/// The probability the descent from `node` (reached with probability `prob`) ends at a node whose children both
/// have zero importance: it then picks nothing, which is no bias (nothing below can light p).
fn lost(tree: &LightTree, node: u32, prob: f64, p: Vec3, n: Vec3) -> f64 {
    match tree.children(node) {
        None => 0.0,
        Some((c0, c1)) => match tree.first_child_prob(node, p, n) {
            None => prob,
            Some(p0) => lost(tree, c0, prob * p0 as f64, p, n) + lost(tree, c1, prob * (1.0 - p0) as f64, p, n),
        },
    }
}

// A pdf twin that walked a different path than the descent, or a trail set wrong, breaks the sum: the emitters'
// pmfs and the mass the descent loses where both children of a node are dark add to one.
#[test]
fn pmf_and_lost_mass_sum_to_one() {
    let lights = field(300, 7);
    let entries: Vec<u32> = lights.iter().map(|l| l.0).collect();
    let tree = build(lights, 700, 1.0, (0, 0));
    assert!(tree.stats.depth <= LIGHT_TREE_MAX_DEPTH);
    for (p, n) in receivers(3) {
        let sum: f64 = entries.iter().map(|&e| tree.pmf(p, n, e) as f64).sum();
        let lost = lost(&tree, tree.root(), 1.0, p, n);
        assert!((sum + lost - 1.0).abs() < 1e-4, "sum {sum} and lost {lost} at {p}");
    }
}

// Frequencies of the descent against the pmf twin (chi-square, bins with expected count 5 and more pooled);
// catches a rescaling or fresh-number slip the sum test cannot see.
#[test]
fn picks_follow_the_pmf() {
    let lights = field(200, 11);
    let entries: Vec<u32> = lights.iter().map(|l| l.0).collect();
    let tree = build(lights, 500, 1.0, (0, 0));
    let mut s = 99;
    for (p, n) in receivers(5).into_iter().take(6) {
        let draws = 200_000;
        let mut counts = std::collections::HashMap::new();
        for _ in 0..draws {
            let (u, v) = (lcg(&mut s), lcg(&mut s));
            if let Some((e, prob)) = tree.pick(p, n, u, v) {
                let twin = tree.pmf(p, n, e);
                assert!((prob - twin).abs() <= 1e-5 * twin, "pick says {prob}, pmf {twin}");
                *counts.entry(e).or_insert(0u32) += 1;
            }
        }
        let (mut chi2, mut dof, mut pooled_obs, mut pooled_exp) = (0.0f64, 0i32, 0.0f64, 0.0f64);
        for &e in &entries {
            let expected = tree.pmf(p, n, e) as f64 * draws as f64;
            let observed = *counts.get(&e).unwrap_or(&0) as f64;
            if expected == 0.0 {
                assert_eq!(observed, 0.0, "entry {e} picked with pmf 0");
            } else if expected < 5.0 {
                pooled_obs += observed;
                pooled_exp += expected;
            } else {
                chi2 += (observed - expected).powi(2) / expected;
                dof += 1;
            }
        }
        if pooled_exp > 0.0 {
            chi2 += (pooled_obs - pooled_exp).powi(2) / pooled_exp.max(1.0);
            dof += 1;
        }
        // chi-square's mean is dof with sd sqrt(2 dof); 6 sd is far past a 1e-6 tail here.
        let bound = dof as f64 + 6.0 * (2.0 * dof as f64).sqrt();
        assert!(chi2 < bound, "chi2 {chi2} over {dof} bins at {p}");
    }
}

// A triangle that faces p and lies above p's horizon must keep a chance: zero importance there is bias for the
// light-only estimator and lost light for punctual lights. Checked by brute force over random configurations.
#[test]
fn importance_is_zero_only_where_nothing_arrives() {
    let mut s = 5;
    let mut lit = 0;
    for _ in 0..20_000 {
        let c = Vec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 4.0 - 2.0;
        let d = Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5);
        let e = Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5);
        let tri = [c, c + d, c + e];
        let b = LightBounds::triangle(&[tri], 1.0, false).unwrap();
        let node = record(&b, [LIGHT_NODE_LEAF, 0, 0, 0]);
        let p = Vec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 4.0 - 2.0;
        let n = Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5).normalize();
        let ng = d.cross(e).normalize();
        // Does any of a grid of points on the triangle face p from the front and sit off p's tangent plane?
        let arrives = (0..64).any(|k| {
            let (a, bb) = ((k % 8) as f32 / 8.0 + 0.06, (k / 8) as f32 / 8.0 + 0.06);
            if a + bb > 1.0 {
                return false;
            }
            let q = tri[0] + a * d + bb * e;
            let w = (p - q).normalize();
            ng.dot(w) > 1e-3 && w.dot(n).abs() > 1e-3
        });
        if arrives {
            lit += 1;
            assert!(
                importance(&node, false, p, n) > 0.0,
                "lit point {p} given zero importance"
            );
        }
    }
    assert!(lit > 2000);
}

// Every cone of a union holds its parts' normals, under rotations, mirrors and motion.
#[test]
fn unions_and_transforms_hold_their_parts() {
    let lights = field(64, 13);
    let mut all = lights[0].1;
    for (_, b) in &lights[1..] {
        all = all.union(b);
    }
    for (_, b) in &lights {
        assert!(all.lo.cmple(b.lo).all() && all.hi.cmpge(b.hi).all());
        if b.cos_o >= 1.0 {
            assert!(all.axis.dot(b.axis) >= all.cos_o - 1e-5);
        }
    }
    let keys = [
        glam::Mat4::from_rotation_y(0.3),
        glam::Mat4::from_scale_rotation_translation(
            Vec3::new(-2.0, 2.0, 2.0),
            glam::Quat::from_rotation_x(1.0),
            Vec3::X,
        ),
    ];
    let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let t = LightBounds::triangle(&[tri], 1.0, false)
        .unwrap()
        .transformed(&keys, None, 1.0);
    for w in keys {
        let [a, b, c] = tri.map(|v| w.transform_point3(v));
        // The device's front of a mirrored instance is the mesh's: the mapped normal, not the mapped winding.
        let n = (glam::Mat3::from_mat4(w).inverse().transpose() * Vec3::Z).normalize();
        assert!(t.axis.dot(n) >= t.cos_o - 1e-5, "{n} outside");
        for q in [a, b, c] {
            assert!(t.lo.cmple(q + 1e-5).all() && t.hi.cmpge(q - 1e-5).all());
        }
    }
    let stretched = LightBounds::triangle(&[tri], 1.0, false).unwrap().transformed(
        &[glam::Mat4::from_scale(Vec3::new(1.0, 3.0, 1.0))],
        None,
        1.0,
    );
    assert_eq!(stretched.cos_o, -1.0);
}

// Neighbouring faces of a curved mesh have axes too close to turn between: their union must stay about as narrow
// as they are (it once opened to the sphere, and a light bulb lost half of its picks to nodes whose importance
// its faces turned away do not share), and still hold both.
#[test]
fn unions_of_nearly_parallel_cones_stay_narrow() {
    for angle in [1e-7f32, 1e-6, 1e-5, 1e-4] {
        let a = Vec3::new(0.549, -0.671, 0.498).normalize();
        let b = glam::Quat::from_axis_angle(a.any_orthonormal_vector(), angle) * a;
        for (cos_a, cos_b) in [(1.0, 1.0), (0.999, 1.0), (1.0, 0.99)] {
            let (axis, cos_o) = cone_union(a, cos_a, b, cos_b);
            assert!(cos_o > 0.98, "{angle}: cos {cos_o}");
            let theta = cos_o.acos();
            for (v, c) in [(a, cos_a), (b, cos_b)] {
                let edge = axis.dot(v).clamp(-1.0, 1.0).acos() + c.clamp(-1.0, 1.0).acos();
                assert!(
                    edge <= theta + 1e-6,
                    "{angle}: a part reaches {edge}, the union {theta}"
                );
            }
        }
    }
}
