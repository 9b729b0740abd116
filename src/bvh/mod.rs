//! Binned-SAH BVH build, flattened into the GPU node layout (`layout::BvhNode`), with triangles reordered to match.
mod traverse;

pub use traverse::{brute_force, intersect_triangle, trace, Ray, TraceHit};

use crate::constants::{BVH_MAX_LEAF_TRIS, BVH_STACK_SIZE};
use crate::layout::BvhNode;
use glam::Vec3;

const BINS: usize = 32;
/// Below this depth SAH decides; past it splits fall back to the median so the tree stays within the traversal stack.
const SAH_DEPTH_LIMIT: u32 = BVH_STACK_SIZE - 24;
/// Relative cost of one node visit against one triangle test.
const TRAVERSAL_COST: f32 = 1.0;

#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: Vec3,
    hi: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };
    fn grow(&mut self, p: Vec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }
    fn merge(&mut self, b: &Aabb) {
        self.lo = self.lo.min(b.lo);
        self.hi = self.hi.max(b.hi);
    }
    fn area(&self) -> f32 {
        let d = self.hi - self.lo;
        if d.min_element() < 0.0 {
            0.0
        } else {
            2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
        }
    }
}

#[derive(Clone, Debug, Default)]
pub struct BvhStats {
    pub nodes: usize,
    pub leaves: usize,
    pub depth: u32,
    pub max_leaf_tris: u32,
    /// SAH cost with node visits and triangle tests both costing 1, relative to the root's area.
    pub sah_cost: f32,
}

pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    /// `order[i]` is the original index of the triangle stored at position `i`.
    pub order: Vec<u32>,
    pub stats: BvhStats,
}

fn node(b: &Aabb, first: u32, count: u32) -> BvhNode {
    BvhNode {
        lo: [b.lo.x, b.lo.y, b.lo.z, f32::from_bits(first)],
        hi: [b.hi.x, b.hi.y, b.hi.z, f32::from_bits(count)],
    }
}

/// Builds over world-space triangles. An empty input gives one empty leaf that every ray misses.
pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
    let n = triangles.len();
    let mut boxes = Vec::with_capacity(n);
    let mut centroids = Vec::with_capacity(n);
    for t in triangles {
        let mut b = Aabb::EMPTY;
        t.iter().for_each(|v| b.grow(*v));
        boxes.push(b);
        centroids.push((b.lo + b.hi) * 0.5);
    }
    let mut order: Vec<u32> = (0..n as u32).collect();
    let mut nodes = vec![BvhNode::default()];
    let mut stats = BvhStats::default();
    if n == 0 {
        // first = 0 and count = 0 marks the empty tree; both traversals return at once.
        nodes[0] = node(&Aabb::EMPTY, 0, 0);
        stats.nodes = 1;
        return Bvh { nodes, order, stats };
    }
    let bounds_of = |range: &[u32]| {
        let mut b = Aabb::EMPTY;
        range.iter().for_each(|&i| b.merge(&boxes[i as usize]));
        b
    };
    let root_box = bounds_of(&order);
    let root_area = root_box.area().max(f32::MIN_POSITIVE);
    // (node index, start, end, depth, bounds)
    let mut work = vec![(0usize, 0usize, n, 0u32, root_box)];
    while let Some((index, start, end, depth, bounds)) = work.pop() {
        stats.depth = stats.depth.max(depth);
        let count = end - start;
        let split = if count <= 1 {
            None
        } else {
            choose_split(&mut order[start..end], &centroids, &boxes, &bounds, depth)
        };
        match split {
            None => {
                nodes[index] = node(&bounds, start as u32, count as u32);
                stats.leaves += 1;
                stats.max_leaf_tris = stats.max_leaf_tris.max(count as u32);
                stats.sah_cost += bounds.area() / root_area * count as f32;
            }
            Some(mid) => {
                let left = nodes.len();
                nodes.push(BvhNode::default());
                nodes.push(BvhNode::default());
                nodes[index] = node(&bounds, left as u32, 0);
                stats.sah_cost += TRAVERSAL_COST * bounds.area() / root_area;
                let lb = bounds_of(&order[start..start + mid]);
                let rb = bounds_of(&order[start + mid..end]);
                work.push((left + 1, start + mid, end, depth + 1, rb));
                work.push((left, start, start + mid, depth + 1, lb));
            }
        }
    }
    stats.nodes = nodes.len();
    Bvh { nodes, order, stats }
}

/// A leaf when few enough triangles remain, otherwise the halves by centroid along `axis`.
fn median_split(idx: &mut [u32], centroids: &[Vec3], axis: usize) -> Option<usize> {
    if idx.len() <= BVH_MAX_LEAF_TRIS as usize {
        return None;
    }
    let mid = idx.len() / 2;
    idx.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    Some(mid)
}

/// Partitions `idx` and returns the size of the left part, or None to make a leaf.
fn choose_split(idx: &mut [u32], centroids: &[Vec3], boxes: &[Aabb], bounds: &Aabb, depth: u32) -> Option<usize> {
    let count = idx.len();
    let mut cb = Aabb::EMPTY;
    idx.iter().for_each(|&i| cb.grow(centroids[i as usize]));
    let extent = cb.hi - cb.lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if extent[axis] <= 0.0 || depth >= SAH_DEPTH_LIMIT {
        // Coincident centroids (or too deep for SAH): halve by position so leaves stay small and depth stays bounded.
        return median_split(idx, centroids, axis);
    }
    // SAH over bins on every axis with a non-zero extent.
    let mut best = (f32::INFINITY, 0usize, 0usize);
    for ax in 0..3 {
        if extent[ax] <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / extent[ax];
        let bin_of = |i: u32| (((centroids[i as usize][ax] - cb.lo[ax]) * scale) as usize).min(BINS - 1);
        let mut bin_box = [Aabb::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        for &i in idx.iter() {
            let b = bin_of(i);
            bin_count[b] += 1;
            bin_box[b].merge(&boxes[i as usize]);
        }
        let mut right_area = [0f32; BINS];
        let mut acc = Aabb::EMPTY;
        let mut right_count = [0usize; BINS];
        let mut rc = 0;
        for b in (1..BINS).rev() {
            acc.merge(&bin_box[b]);
            rc += bin_count[b];
            right_area[b] = acc.area();
            right_count[b] = rc;
        }
        let mut left = Aabb::EMPTY;
        let mut lc = 0;
        for b in 1..BINS {
            left.merge(&bin_box[b - 1]);
            lc += bin_count[b - 1];
            if lc == 0 || right_count[b] == 0 {
                continue;
            }
            let cost = left.area() * lc as f32 + right_area[b] * right_count[b] as f32;
            if cost < best.0 {
                best = (cost, ax, b);
            }
        }
    }
    let leaf_cost = bounds.area() * count as f32;
    let split_cost = TRAVERSAL_COST * bounds.area() + best.0;
    if best.0 == f32::INFINITY || (split_cost >= leaf_cost && count <= BVH_MAX_LEAF_TRIS as usize) {
        return median_split(idx, centroids, axis);
    }
    let (_, ax, split_bin) = best;
    let scale = BINS as f32 / extent[ax];
    let mut i = 0;
    let mut j = count;
    while i < j {
        let b = (((centroids[idx[i] as usize][ax] - cb.lo[ax]) * scale) as usize).min(BINS - 1);
        if b < split_bin {
            i += 1;
        } else {
            j -= 1;
            idx.swap(i, j);
        }
    }
    Some(i)
}
