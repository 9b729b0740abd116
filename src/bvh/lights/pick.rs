//! The CPU twin of light_tree.glsl (importance, the descent and its pmf): the same f32 arithmetic in the same order.
use super::LightTree;
use crate::constants::{LIGHT_FRESH_NUMBER_BELOW, LIGHT_NODE_LEAF, LIGHT_NODE_TWO_SIDED};
use crate::layout::GpuLightNode;
use glam::Vec3;

/// cos(max(0, a - b)) from the sines and cosines of a and b.
fn cos_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// sin(max(0, a - b)).
fn sin_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

/// Largest importance, so sums of two stay finite.
const IMPORTANCE_MAX: f32 = 1e30;

/// The node's importance at p for a receiver with normal n (zero: no receiver term), as light_tree.glsl has it.
pub fn importance(node: &GpuLightNode, two_sided: bool, p: Vec3, n: Vec3) -> f32 {
    let [cx, cy, cz, radius] = node.sphere;
    let [ax, ay, az, phi] = node.cone;
    let [cos_o, sin_o, cos_e, _] = node.angles;
    let to_p = p - Vec3::new(cx, cy, cz);
    let d2_true = to_p.dot(to_p);
    let r2 = radius * radius;
    let d2 = d2_true.max(r2).max(1e-20);
    let inv_d = 1.0 / d2_true.max(1e-30).sqrt();
    let wi = to_p * inv_d;
    let mut cos_w = Vec3::new(ax, ay, az).dot(wi);
    if two_sided {
        cos_w = cos_w.abs();
    }
    let sin_w = safe_sqrt(1.0 - cos_w * cos_w);
    // The half angle the bounds' sphere spans from p: all directions from inside it.
    let inside = d2_true <= r2;
    let sin_b = if inside { 0.0 } else { radius * inv_d };
    let cos_b = if inside { -1.0 } else { safe_sqrt(1.0 - sin_b * sin_b) };
    let cos_x = cos_sub_clamped(sin_w, cos_w, sin_o, cos_o);
    let sin_x = sin_sub_clamped(sin_w, cos_w, sin_o, cos_o);
    let cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
    if cos_p <= cos_e {
        return 0.0;
    }
    let mut imp = phi * cos_p / d2;
    if n != Vec3::ZERO {
        let cos_i = wi.dot(n).abs();
        let sin_i = safe_sqrt(1.0 - cos_i * cos_i);
        imp *= cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
    }
    imp.clamp(0.0, IMPORTANCE_MAX)
}

impl LightTree {
    pub(super) fn children(&self, node: u32) -> Option<(u32, u32)> {
        let link = self.nodes[node as usize].link;
        (link[0] != LIGHT_NODE_LEAF).then_some((link[0], link[1] & !LIGHT_NODE_TWO_SIDED))
    }

    /// The probability of the first child at an interior node (0 and 0 importance: None).
    pub(super) fn first_child_prob(&self, node: u32, p: Vec3, n: Vec3) -> Option<f32> {
        let link = self.nodes[node as usize].link;
        let (c0, c1) = (link[0], link[1] & !LIGHT_NODE_TWO_SIDED);
        let i0 = importance(&self.nodes[c0 as usize], link[2] & 1 != 0, p, n);
        let i1 = importance(&self.nodes[c1 as usize], link[1] & LIGHT_NODE_TWO_SIDED != 0, p, n);
        (i0 + i1 > 0.0).then(|| i0 / (i0 + i1))
    }

    /// The descent from the root with uniforms u (and v, once u is used up): the entry picked and the probability
    /// of picking it, among the tree's emitters. None when nothing in the tree can light p.
    pub fn pick(&self, p: Vec3, n: Vec3, u: f32, v: f32) -> Option<(u32, f32)> {
        self.descend(self.root(), p, n, &mut LightWalk::new(u, v))
    }

    /// The descent from `node` (the root, or an instanced mesh's subtree's with p and n in the mesh's space),
    /// drawing on `walk`: the entry picked and the probability of picking it below `node`.
    pub fn descend(&self, mut node: u32, p: Vec3, n: Vec3, walk: &mut LightWalk) -> Option<(u32, f32)> {
        if node == 0 {
            return None;
        }
        let mut prob = 1.0f32;
        while let Some((c0, c1)) = self.children(node) {
            let p0 = self.first_child_prob(node, p, n)?;
            let u = walk.u;
            if u < p0 {
                node = c0;
                prob *= p0;
                walk.part *= p0;
                walk.u = (u / p0).min(ONE_MINUS_EPSILON);
            } else {
                node = c1;
                prob *= 1.0 - p0;
                walk.part *= 1.0 - p0;
                walk.u = ((u - p0) / (1.0 - p0)).min(ONE_MINUS_EPSILON);
            }
            if !walk.fresh && walk.part < LIGHT_FRESH_NUMBER_BELOW {
                walk.u = walk.v;
                walk.fresh = true;
            }
        }
        Some((node - 1, prob))
    }

    /// The probability `pick` returns `entry` from (p, n): the same products along the leaf's trail.
    pub fn pmf(&self, p: Vec3, n: Vec3, entry: u32) -> f32 {
        self.pmf_below(self.root(), p, n, entry)
    }

    /// The probability `descend` from `root` returns `entry`.
    pub fn pmf_below(&self, root: u32, p: Vec3, n: Vec3, entry: u32) -> f32 {
        let leaf = &self.nodes[1 + entry as usize];
        let trail = leaf.link[2] as u64 | (leaf.link[3] as u64) << 32;
        let mut node = root;
        if node == 0 {
            return 0.0;
        }
        let mut prob = 1.0f32;
        let mut d = 0;
        while let Some((c0, c1)) = self.children(node) {
            let Some(p0) = self.first_child_prob(node, p, n) else {
                return 0.0;
            };
            if trail >> d & 1 == 0 {
                node = c0;
                prob *= p0;
            } else {
                node = c1;
                prob *= 1.0 - p0;
            }
            d += 1;
        }
        if node == 1 + entry {
            prob
        } else {
            0.0
        }
    }
}

/// The random numbers of one descent, through the tree and on into an instanced mesh's subtree: u chooses, rescaled
/// at each node, until the choices made are less likely than LIGHT_FRESH_NUMBER_BELOW, where v takes over.
#[derive(Clone, Copy, Debug)]
pub struct LightWalk {
    pub u: f32,
    pub v: f32,
    pub part: f32,
    pub fresh: bool,
}

impl LightWalk {
    pub fn new(u: f32, v: f32) -> LightWalk {
        LightWalk {
            u,
            v,
            part: 1.0,
            fresh: false,
        }
    }
}

const ONE_MINUS_EPSILON: f32 = 0.99999994;
