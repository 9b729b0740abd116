//! The light BVH's build: splits by surface area and orientation, the nodes' records and the leaves' trails.
use super::bounds::{LightBounds, CONE_SLACK};
use super::{LightTree, LightTreeStats};
use crate::constants::{LIGHT_NODE_LEAF, LIGHT_NODE_TWO_SIDED, LIGHT_TREE_MAX_DEPTH};
use crate::layout::GpuLightNode;
use glam::Vec3;

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

pub(super) fn record(b: &LightBounds, link: [u32; 4]) -> GpuLightNode {
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
