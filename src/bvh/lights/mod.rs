//! The light BVH: a binary tree over the finite emitters (bounds, power and normal cone per node), its GPU layout
//! (`GpuLightNode`) and the CPU twin of the device's descent and pmf (`shaders/include/light_tree.glsl`).
//!
//! Light selection descends from the root, choosing a child in proportion to its importance at the shading point:
//! power over squared distance, times the cosines left once the node's normal cone and its bounds' solid angle are
//! allowed for, at the emitter and at the receiver (the bound of pbrt-v4's `LightBounds::Importance`, after Conty
//! Estevez and Kulla 2018). The importance is a bound, so a node it calls zero cannot light the point; where it
//! misjudges, MIS with BSDF sampling still gives the right mean, since the pdf twin returns exactly the probability
//! the descent picks with.
use super::motion::{largest_turn, Pose};
use crate::constants::{LIGHT_FRESH_NUMBER_BELOW, LIGHT_NODE_LEAF, LIGHT_NODE_TWO_SIDED, LIGHT_TREE_MAX_DEPTH};
use crate::layout::GpuLightNode;
use glam::{Mat3, Vec3};
use std::f32::consts::PI;

/// What importance needs to know of an emitter or a group of them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    pub lo: Vec3,
    pub hi: Vec3,
    /// Power (W), the same estimate the power table uses.
    pub phi: f32,
    /// Every emitting normal is within acos(cos_o) of `axis`.
    pub axis: Vec3,
    pub cos_o: f32,
    /// Emission reaches at most acos(cos_e) beyond the normal (pi/2 for a surface).
    pub cos_e: f32,
    /// Emits from both faces: the cone holds for -axis too.
    pub two_sided: bool,
}

/// Angles a float error can move a cone by; the union widens by it so it stays a bound.
const CONE_SLACK: f32 = 1e-4;

impl LightBounds {
    /// A triangle (at one or more places over the shutter) emitting from its counter-clockwise face, or both.
    pub fn triangle(keys: &[[Vec3; 3]], phi: f32, two_sided: bool) -> Option<LightBounds> {
        let mut b: Option<LightBounds> = None;
        for &[a, v1, v2] in keys {
            let n = (v1 - a).cross(v2 - a);
            let n = if n.length_squared() > 0.0 {
                n.normalize()
            } else {
                Vec3::Z
            };
            let cone = LightBounds {
                lo: a.min(v1).min(v2),
                hi: a.max(v1).max(v2),
                phi,
                axis: n,
                cos_o: 1.0,
                cos_e: 0.0,
                two_sided,
            };
            b = Some(match b {
                None => cone,
                Some(prev) => LightBounds {
                    phi,
                    ..prev.union(&cone)
                },
            });
        }
        b
    }

    /// A point light: all directions.
    pub fn point(p: Vec3, phi: f32) -> LightBounds {
        LightBounds {
            lo: p,
            hi: p,
            phi,
            axis: Vec3::Z,
            cos_o: -1.0,
            cos_e: 0.0,
            two_sided: false,
        }
    }

    /// A spot light: full intensity within `inner` of `dir`, none beyond `outer`.
    pub fn spot(p: Vec3, dir: Vec3, inner: f32, outer: f32, phi: f32) -> LightBounds {
        let inner = inner.clamp(0.0, outer.max(0.0));
        LightBounds {
            lo: p,
            hi: p,
            phi,
            axis: dir.normalize_or(Vec3::Z),
            cos_o: inner.cos(),
            cos_e: (outer - inner).min(PI).cos(),
            two_sided: false,
        }
    }

    /// These bounds under an affine map (an instance's transform at each of its keys): the box's corners mapped,
    /// the cone's axis mapped as a normal. A map that is not a similarity does not keep angles, so the cone then
    /// opens to the sphere. Keys interpolated as `poses` (motion::Pose::toward) sweep the box along its arc
    /// (motion::swept_box), and a direction between two keys is within half their turn of one of them, so each
    /// key's cone opens by half the largest turn; keys interpolated as matrices move points linearly between keys.
    pub fn transformed(&self, keys: &[glam::Mat4], poses: Option<&[Pose]>, phi: f32) -> LightBounds {
        let mut out: Option<LightBounds> = None;
        for w in keys {
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for c in crate::scene::box_corners(self.lo, self.hi) {
                let q = w.transform_point3(c);
                lo = lo.min(q);
                hi = hi.max(q);
            }
            let m = Mat3::from_mat4(*w);
            let normal = m.inverse().transpose() * self.axis;
            let cos_o = if is_similarity(&m) && normal.length_squared() > 0.0 {
                self.cos_o
            } else {
                -1.0
            };
            let b = LightBounds {
                lo,
                hi,
                phi,
                axis: normal.normalize_or(Vec3::Z),
                cos_o,
                cos_e: self.cos_e,
                two_sided: self.two_sided,
            };
            out = Some(match out {
                None => b,
                Some(prev) => LightBounds { phi, ..prev.union(&b) },
            });
        }
        let (Some(mut out), Some(poses)) = (out, poses) else {
            return out.unwrap_or(*self);
        };
        (out.lo, out.hi) = super::motion::swept_box(self.lo, self.hi, poses);
        if out.cos_o > -1.0 {
            out.cos_o = (out.cos_o.clamp(-1.0, 1.0).acos() + 0.5 * largest_turn(poses))
                .min(PI)
                .cos();
        }
        out
    }

    /// Both groups: the box around both, the powers added, a cone holding both cones.
    pub fn union(&self, b: &LightBounds) -> LightBounds {
        let (axis, cos_o) = cone_union(self.axis, self.cos_o, b.axis, b.cos_o);
        LightBounds {
            lo: self.lo.min(b.lo),
            hi: self.hi.max(b.hi),
            phi: self.phi + b.phi,
            axis,
            cos_o,
            cos_e: self.cos_e.min(b.cos_e),
            two_sided: self.two_sided || b.two_sided,
        }
    }

    fn centroid(&self) -> Vec3 {
        0.5 * (self.lo + self.hi)
    }

    /// The build's measure of how much space and how many directions the group lights (pbrt-v4's M_Omega times the
    /// box's area), so that splits keep emitters of one place and one facing together.
    fn cost(&self) -> f32 {
        // One inverse cosine: a surface's theta_e is pi/2, and theta_o's sine and cosine follow from cos_o.
        let cos_o = self.cos_o.clamp(-1.0, 1.0);
        let theta_o = cos_o.acos();
        let theta_e = if self.cos_e == 0.0 {
            PI / 2.0
        } else {
            self.cos_e.clamp(-1.0, 1.0).acos()
        };
        let theta_w = (theta_o + theta_e).min(PI);
        let sin_o = (1.0 - cos_o * cos_o).max(0.0).sqrt();
        let m_omega = 2.0 * PI * (1.0 - cos_o)
            + PI / 2.0 * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o + cos_o);
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        // A flat or point-like group still has some extent, so groups of point lights are still told apart.
        let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x) + 1e-12 * (d.x + d.y + d.z);
        self.phi * m_omega * area
    }
}

/// Whether m keeps angles: its columns orthogonal and of one length.
fn is_similarity(m: &Mat3) -> bool {
    let g = m.transpose() * *m;
    let s = (g.x_axis.x + g.y_axis.y + g.z_axis.z) / 3.0;
    if s.is_nan() || s <= 0.0 || !s.is_finite() {
        return false;
    }
    let off = (g - Mat3::from_diagonal(Vec3::splat(s))).to_cols_array();
    off.iter().all(|v| v.abs() <= 1e-4 * s)
}

/// The smallest cone (axis, cos of its half angle) that holds cones a and b, widened by CONE_SLACK.
fn cone_union(a: Vec3, cos_a: f32, b: Vec3, cos_b: f32) -> (Vec3, f32) {
    // One cone inside the other, tested without inverse cosines (the build's common case): b lies within a when
    // the angle between the axes is at most theta_a - theta_b, whose cosine the sines and cosines give.
    let d = a.dot(b);
    // One of them a single direction (an emitter's normal: every union of the build's binning): no roots needed.
    if cos_b >= 1.0 && d >= cos_a {
        return (a, cos_a);
    }
    if cos_a >= 1.0 && d >= cos_b {
        return (b, cos_b);
    }
    let (sin_a, sin_b) = (
        (1.0 - cos_a * cos_a).max(0.0).sqrt(),
        (1.0 - cos_b * cos_b).max(0.0).sqrt(),
    );
    if cos_a <= -1.0 || (cos_a <= cos_b && d >= cos_a * cos_b + sin_a * sin_b) {
        return (a, cos_a);
    }
    if cos_b <= -1.0 || (cos_b <= cos_a && d >= cos_a * cos_b + sin_a * sin_b) {
        return (b, cos_b);
    }
    // A single direction's angle is 0 without an inverse cosine (both cones are one, often).
    let angle = |c: f32| if c >= 1.0 { 0.0 } else { c.clamp(-1.0, 1.0).acos() };
    let (theta_a, theta_b, theta_d) = (angle(cos_a), angle(cos_b), angle(d));
    if (theta_d + theta_b).min(PI) <= theta_a {
        return (a, cos_a);
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return (b, cos_b);
    }
    let theta_o = 0.5 * (theta_a + theta_d + theta_b) + CONE_SLACK;
    if theta_o >= PI {
        return (a, -1.0);
    }
    // Turn a towards b by the angle that puts both edges inside.
    let theta_r = theta_o - theta_a;
    let w = a.cross(b);
    if w.length_squared() < 1e-12 {
        // Axes too close to turn between (neighbouring triangles of a curved mesh): a's axis, opened to reach b's
        // edge. Opening it to the sphere here once lost half of a light bulb's picks: such a node has importance
        // where its two faces turned away have none, and a descent that reaches it picks nothing.
        let theta = theta_a.max(theta_d + theta_b) + CONE_SLACK;
        return (a, if theta >= PI { -1.0 } else { theta.cos() });
    }
    let axis = glam::Quat::from_axis_angle(w.normalize(), theta_r) * a;
    (axis.normalize(), theta_o.cos())
}

/// The tree on the host: the device's records and what `pathwave info` reports.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    /// Record 0 is the header, then a leaf per entry of the light buffer before the infinite lights' table (1 +
    /// entry; a record of zeros for an entry outside the tree), then the interior nodes, the instanced meshes'
    /// subtrees' after the tree's. See `GpuLightNode`.
    pub nodes: Vec<GpuLightNode>,
    pub stats: LightTreeStats,
}

#[derive(Clone, Debug, Default)]
pub struct LightTreeStats {
    /// Emitters in the tree (triangles, emissive instances, point and spot lights).
    pub emitters: usize,
    /// Emitters in instanced meshes' subtrees (each mesh's triangles once).
    pub instanced: usize,
    /// Interior nodes.
    pub interior: usize,
    /// Longest path from the root to a leaf, in edges.
    pub depth: u32,
    /// Longest path from an instanced mesh's subtree's root to its leaves.
    pub subtree_depth: u32,
    pub build: std::time::Duration,
}

impl LightTree {
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.nodes[..])
    }
    pub fn root(&self) -> u32 {
        self.nodes[0].link[0]
    }
    /// The probability light selection descends the tree rather than picking an infinite light.
    pub fn share(&self) -> f32 {
        self.nodes[0].sphere[0]
    }
}

struct Item {
    entry: u32,
    b: LightBounds,
    c: Vec3,
}

const BUCKETS: usize = 12;
/// Below this depth the orientation-and-area heuristic splits; past it the median does, so no leaf is deeper than
/// LIGHT_TREE_MAX_DEPTH for up to 2^(LIGHT_TREE_MAX_DEPTH - SAOH_DEPTH_LIMIT) emitters.
const SAOH_DEPTH_LIMIT: u32 = LIGHT_TREE_MAX_DEPTH - 24;

/// The tree over `emitters` (entry of the light buffer, its bounds), for a light buffer of `entries` entries.
/// `share` is the probability of descending the tree, `infinite` the infinite lights' table (first entry in the
/// light buffer, count), both stored in the header. Emitters must number below 2^24 (the caller's limit). Instanced
/// meshes' subtrees are added after it (`add_subtree`).
pub fn build(emitters: Vec<(u32, LightBounds)>, entries: u32, share: f32, infinite: (u32, u32)) -> LightTree {
    let start = std::time::Instant::now();
    let mut tree = LightTree {
        nodes: vec![GpuLightNode::default(); 1 + entries as usize],
        stats: LightTreeStats::default(),
    };
    let count = emitters.len();
    let (root, depth) = tree.grow(emitters);
    tree.nodes[0] = GpuLightNode {
        sphere: [share, 0.0, 0.0, 0.0],
        link: [root, infinite.0, infinite.1, count as u32],
        ..Default::default()
    };
    tree.stats = LightTreeStats {
        emitters: count,
        interior: tree.nodes.len() - 1 - entries as usize,
        depth,
        build: start.elapsed(),
        ..Default::default()
    };
    tree
}

impl LightTree {
    /// A subtree over an instanced mesh's emitters in the mesh's own space (entries of its table in the light
    /// buffer), stored once however many instances place the mesh: their leaves in the tree continue into it, with
    /// the shading point taken into the mesh's space. Returns its root (a leaf's record for one emitter; 0 for none).
    pub fn add_subtree(&mut self, emitters: Vec<(u32, LightBounds)>) -> u32 {
        let start = std::time::Instant::now();
        let count = emitters.len();
        let before = self.nodes.len();
        let (root, depth) = self.grow(emitters);
        self.stats.instanced += count;
        self.stats.interior += self.nodes.len() - before;
        self.stats.subtree_depth = self.stats.subtree_depth.max(depth);
        self.stats.build += start.elapsed();
        root
    }

    /// Builds a (sub)tree over `emitters`: interior nodes appended, leaves at 1 + entry, each leaf's trail from the
    /// returned root. (root, depth); root 0 for no emitters.
    fn grow(&mut self, emitters: Vec<(u32, LightBounds)>) -> (u32, u32) {
        let count = emitters.len();
        let mut items: Vec<Item> = (emitters.into_iter())
            .map(|(entry, b)| Item {
                entry,
                c: b.centroid(),
                b,
            })
            .collect();
        if items.is_empty() {
            return (0, 0);
        }
        let mut depth = 0;
        // A binary tree over n leaves has n - 1 interior nodes, so every subtree's place is known before it is
        // built and the two halves of the top levels build on two threads.
        let first = self.nodes.len() as u32;
        self.nodes.resize(self.nodes.len() + count - 1, GpuLightNode::default());
        let (root, _) = {
            let interior = &mut self.nodes[first as usize..];
            build_range(&mut items, 0, (interior, first), &mut depth)
        };
        for it in &items {
            let sided = if it.b.two_sided { LIGHT_NODE_TWO_SIDED } else { 0 };
            self.nodes[1 + it.entry as usize] = record(&it.b, [LIGHT_NODE_LEAF, sided, 0, 0]);
        }
        set_trails(&mut self.nodes, root);
        (root, depth)
    }
}

fn record(b: &LightBounds, link: [u32; 4]) -> GpuLightNode {
    let c = b.centroid();
    let cos_o = b.cos_o.clamp(-1.0, 1.0);
    GpuLightNode {
        sphere: [c.x, c.y, c.z, (0.5 * (b.hi - b.lo)).length()],
        cone: [b.axis.x, b.axis.y, b.axis.z, b.phi],
        angles: [cos_o, (1.0 - cos_o * cos_o).max(0.0).sqrt(), b.cos_e, 0.0],
        link,
    }
}

/// Builds the subtree over `items`, returning its node and bounds.
/// Subtrees over more emitters than this build the halves of their split on two threads.
const PARALLEL_ABOVE: usize = 1 << 14;

/// Builds the subtree over `items` into `interior` (its `items.len() - 1` interior nodes, the first of them at node
/// index `base`, this subtree's root when it has more than one emitter; its leaves are the caller's, at 1 + entry);
/// returns its root's index and bounds.
fn build_range(
    items: &mut [Item],
    depth: u32,
    (interior, base): (&mut [GpuLightNode], u32),
    max_depth: &mut u32,
) -> (u32, LightBounds) {
    *max_depth = (*max_depth).max(depth);
    if items.len() == 1 {
        return (1 + items[0].entry, items[0].b);
    }
    let mid = split(items, depth);
    let parallel = items.len() > PARALLEL_ABOVE;
    let (this, rest) = interior
        .split_first_mut()
        .expect("a subtree of two or more emitters has an interior node");
    let (left_nodes, right_nodes) = rest.split_at_mut(mid - 1);
    let (left_items, right_items) = items.split_at_mut(mid);
    let left_base = base + 1;
    let right_base = base + mid as u32;
    let ((left, lb), (right, rb)) = if parallel {
        let mut right_depth = 0;
        let (l, r) = std::thread::scope(|scope| {
            let right =
                scope.spawn(|| build_range(right_items, depth + 1, (right_nodes, right_base), &mut right_depth));
            let l = build_range(left_items, depth + 1, (left_nodes, left_base), max_depth);
            (l, right.join().expect("the light tree's build thread does not panic"))
        });
        *max_depth = (*max_depth).max(right_depth);
        (l, r)
    } else {
        let l = build_range(left_items, depth + 1, (left_nodes, left_base), max_depth);
        let r = build_range(right_items, depth + 1, (right_nodes, right_base), max_depth);
        (l, r)
    };
    let b = lb.union(&rb);
    // Each child's two-sidedness rides in this link (the second's beside its index, the first's in bit 0 of z).
    let sided = if rb.two_sided { LIGHT_NODE_TWO_SIDED } else { 0 };
    *this = record(&b, [left, right | sided, lb.two_sided as u32, 0]);
    (base, b)
}

/// Reorders `items` into two non-empty groups and returns where the second starts: the bucket boundary of least
/// cost over three axes, or the median of the widest axis when that is no help or the tree is deep.
fn split(items: &mut [Item], depth: u32) -> usize {
    if items.len() == 2 {
        return 1;
    }
    let (mut clo, mut chi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for it in items.iter() {
        clo = clo.min(it.c);
        chi = chi.max(it.c);
    }
    let extent = chi - clo;
    let widest = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if items.len() <= BUCKETS && depth < SAOH_DEPTH_LIMIT && extent[widest] > 0.0 {
        return split_few(items, widest);
    }
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, buckets below the split)
    if depth < SAOH_DEPTH_LIMIT {
        // The widest axis of the centroids only (pbrt tries all three): binning is most of the build's time, and
        // over a million emitters this took it from 2.9 s to 1.5 s.
        for axis in [widest] {
            if extent[axis].is_nan() || extent[axis] <= 0.0 {
                continue;
            }
            let scale = BUCKETS as f32 / extent[axis];
            let bucket = |c: Vec3| (((c[axis] - clo[axis]) * scale) as usize).min(BUCKETS - 1);
            let bins = bin(items, bucket);
            // Long thin groups split across their length first (pbrt's regularisation).
            let kr = extent.max_element() / extent[axis];
            // The bounds of the buckets below each cut and above it, in one sweep each way.
            let sweep = |order: &mut dyn Iterator<Item = usize>| {
                let mut acc: Option<LightBounds> = None;
                let mut out = [None; BUCKETS];
                for k in order {
                    acc = match (acc, bins[k]) {
                        (Some(a), Some(b)) => Some(a.union(&b)),
                        (a, b) => a.or(b),
                    };
                    out[k] = acc;
                }
                out
            };
            let below = sweep(&mut (0..BUCKETS));
            let above = sweep(&mut (0..BUCKETS).rev());
            for cut in 1..BUCKETS {
                // A cut after an empty bucket splits as the one before it did.
                let (Some(_), Some(l), Some(r)) = (bins[cut - 1], below[cut - 1], above[cut]) else {
                    continue;
                };
                let cost = kr * (l.cost() + r.cost());
                if cost.is_finite() && best.is_none_or(|b| cost < b.0) {
                    best = Some((cost, axis, cut));
                }
            }
        }
    }
    if let Some((_, axis, cut)) = best {
        let (lo, scale) = (clo[axis], BUCKETS as f32 / extent[axis]);
        let mut i = 0;
        for j in 0..items.len() {
            let k = (((items[j].c[axis] - lo) * scale) as usize).min(BUCKETS - 1);
            if k < cut {
                items.swap(i, j);
                i += 1;
            }
        }
        if i > 0 && i < items.len() {
            return i;
        }
    }
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| {
        a.c[widest].total_cmp(&b.c[widest]).then(a.entry.cmp(&b.entry))
    });
    mid
}

/// The bounds of the emitters in each bucket. A bucket's cone is around the mean of its emitters' axes, as wide as
/// its farthest emitter needs: one pass sums the axes, another finds the widest, with no inverse cosines, where a
/// union per emitter (which turns its cone whenever an emitter falls outside) was a third of the build's time.
fn bin(items: &[Item], bucket: impl Fn(Vec3) -> usize) -> [Option<LightBounds>; BUCKETS] {
    let mut bins: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
    for it in items {
        let k = bucket(it.c);
        let b = &it.b;
        bins[k] = Some(match bins[k] {
            None => LightBounds { cos_o: 1.0, ..*b },
            Some(a) => LightBounds {
                lo: a.lo.min(b.lo),
                hi: a.hi.max(b.hi),
                phi: a.phi + b.phi,
                axis: a.axis + b.axis,
                cos_o: 1.0,
                cos_e: a.cos_e.min(b.cos_e),
                two_sided: a.two_sided || b.two_sided,
            },
        });
    }
    for b in bins.iter_mut().flatten() {
        match b.axis.try_normalize() {
            Some(axis) => b.axis = axis,
            None => (b.axis, b.cos_o) = (Vec3::Z, -1.0),
        }
    }
    for it in items {
        let b = bins[bucket(it.c)].as_mut().expect("every emitter's bucket holds it");
        let (d, c) = (b.axis.dot(it.b.axis), it.b.cos_o);
        // cos of the angle between the axes plus the emitter's own spread, or -1 past pi.
        let reach = if c >= 1.0 {
            d
        } else if c <= -1.0 || d <= -c {
            -1.0
        } else {
            d * c - (1.0 - d * d).max(0.0).sqrt() * (1.0 - c * c).max(0.0).sqrt()
        };
        b.cos_o = b.cos_o.min(reach);
    }
    // Widened by CONE_SLACK for the float error of the axis and the cosines.
    let (sin_s, cos_s) = CONE_SLACK.sin_cos();
    for b in bins.iter_mut().flatten() {
        let c = b.cos_o;
        b.cos_o = if c <= -1.0 {
            -1.0
        } else {
            (c * cos_s - (1.0 - c * c).max(0.0).sqrt() * sin_s).max(-1.0)
        };
    }
    bins
}

/// The split of a few emitters (no more than BUCKETS, as nine in ten of a tree's interior nodes are): in centroid
/// order along `axis`, the cut between two of them of least cost. Every cut is tried, where buckets would mostly be
/// empty; the sweeps over twelve buckets were most of the build's time.
fn split_few(items: &mut [Item], axis: usize) -> usize {
    let n = items.len();
    items.sort_unstable_by(|a, b| a.c[axis].total_cmp(&b.c[axis]).then(a.entry.cmp(&b.entry)));
    let mut below = [items[0].b; BUCKETS];
    for i in 1..n {
        below[i] = below[i - 1].union(&items[i].b);
    }
    let mut above = items[n - 1].b;
    let mut best = (f32::INFINITY, n / 2);
    for cut in (1..n).rev() {
        if cut < n - 1 {
            above = above.union(&items[cut].b);
        }
        let cost = below[cut - 1].cost() + above.cost();
        if cost < best.0 {
            best = (cost, cut);
        }
    }
    best.1
}

/// Each leaf's trail: bit d set when the path from the root turns to the second child at depth d.
fn set_trails(nodes: &mut [GpuLightNode], root: u32) {
    let mut stack = vec![(root, 0u64, 0u32)];
    while let Some((n, trail, d)) = stack.pop() {
        let link = nodes[n as usize].link;
        if link[0] == LIGHT_NODE_LEAF {
            nodes[n as usize].link[2] = trail as u32;
            nodes[n as usize].link[3] = (trail >> 32) as u32;
            continue;
        }
        stack.push((link[0], trail, d + 1));
        stack.push((link[1] & !LIGHT_NODE_TWO_SIDED, trail | 1u64 << d, d + 1));
    }
}

// --- The CPU twin of light_tree.glsl: the same f32 arithmetic in the same order. ---

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
    fn children(&self, node: u32) -> Option<(u32, u32)> {
        let link = self.nodes[node as usize].link;
        (link[0] != LIGHT_NODE_LEAF).then_some((link[0], link[1] & !LIGHT_NODE_TWO_SIDED))
    }

    /// The probability of the first child at an interior node (0 and 0 importance: None).
    fn first_child_prob(&self, node: u32, p: Vec3, n: Vec3) -> Option<f32> {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
