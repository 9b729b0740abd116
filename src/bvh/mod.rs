//! Binned-SAH BVH build, widened to BVH_WIDTH children per node and flattened into the GPU node layout
//! (`layout::BvhNode`), with triangles reordered to match.
pub mod lights;
pub mod motion;
mod traverse;

pub use traverse::{
    brute_force, instance_at, intersect_triangle, to_object, trace, trace_from, trace_two_level, Ray, TraceHit,
};

use crate::constants::{BVH_CHILD_INTERIOR, BVH_MAX_LEAF_TRIS, BVH_STACK_SIZE, BVH_WIDTH, STACK_COUNT_BITS};
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
    /// Node records on the device, unused child slots included.
    pub nodes: usize,
    pub leaves: usize,
    /// Depth of the binary tree the build makes before widening.
    pub depth: u32,
    /// The most entries the traversal stack can hold: what the widening must keep below BVH_STACK_SIZE.
    pub max_waiting: u32,
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

/// A node of the binary tree the SAH build makes, before widening: 32 bytes, the box with `first` in lo.w (left
/// child index, the right child follows it; or first triangle) and `count` in hi.w (0 for interior nodes).
#[derive(Clone, Copy, Debug, Default)]
struct BinaryNode {
    lo: [f32; 4],
    hi: [f32; 4],
}

impl BinaryNode {
    fn bounds(&self) -> Aabb {
        Aabb {
            lo: Vec3::new(self.lo[0], self.lo[1], self.lo[2]),
            hi: Vec3::new(self.hi[0], self.hi[1], self.hi[2]),
        }
    }
    fn is_leaf(&self) -> bool {
        self.count() > 0
    }
    fn first(&self) -> u32 {
        self.lo[3].to_bits()
    }
    fn count(&self) -> u32 {
        self.hi[3].to_bits()
    }
}

fn node(b: &Aabb, first: u32, count: u32) -> BinaryNode {
    BinaryNode {
        lo: [b.lo.x, b.lo.y, b.lo.z, f32::from_bits(first)],
        hi: [b.hi.x, b.hi.y, b.hi.z, f32::from_bits(count)],
    }
}

/// Subtrees with fewer triangles than this are built on the current thread.
const PARALLEL_MIN_TRIS: usize = 32 * 1024;

/// What every subtree build reads.
struct Inputs<'a> {
    centroids: &'a [Vec3],
    boxes: &'a [Aabb],
    root_area: f32,
    /// The most primitives a leaf may hold: BVH_MAX_LEAF_TRIS for triangles, 1 for instances (build_boxes).
    max_leaf: usize,
}

impl Inputs<'_> {
    fn bounds_of(&self, range: &[u32]) -> Aabb {
        let mut b = Aabb::EMPTY;
        range.iter().for_each(|&i| b.merge(&self.boxes[i as usize]));
        b
    }
}

/// Builds over world-space triangles. An empty input gives one empty leaf that every ray misses.
///
/// The top of the tree splits across threads; each subtree is built into its own node array and spliced in a fixed
/// order, so the result is the same bytes whatever the number of threads.
pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
    build_with_threads(triangles, std::thread::available_parallelism().map_or(1, |t| t.get()))
}

/// `build` on at most `threads` threads (the result does not depend on it; tests check that).
pub fn build_with_threads(triangles: &[[Vec3; 3]], threads: usize) -> Bvh {
    build_over(
        triangles.len(),
        |i| triangles[i].into_iter(),
        threads,
        BVH_MAX_LEAF_TRIS as usize,
    )
}

/// Builds over moving triangles: triangle i is `keys[k][i]` at key k and moves linearly between keys, so it stays
/// inside the box of all its keys' vertices, which is the box the tree holds it in. Triangles are ordered as in
/// every key (all of the same length).
pub fn build_moving(keys: &[&[[Vec3; 3]]]) -> Bvh {
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let n = keys.first().map_or(0, |k| k.len());
    build_over(
        n,
        |i| keys.iter().flat_map(move |k| k[i]),
        threads,
        BVH_MAX_LEAF_TRIS as usize,
    )
}

/// Builds over boxes (lo, hi), e.g. instances in the world: a leaf's "triangles" are then indices into `boxes`, one
/// per leaf. An instance costs far more than a triangle to test (a moving one is placed at the ray's time, and each
/// has a BVH below it), so each is reached only by rays through its own box; leaves of several made a turning cube's
/// six faces each pay for the others' rays.
pub fn build_boxes(boxes: &[(Vec3, Vec3)]) -> Bvh {
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    build_over(boxes.len(), |i| [boxes[i].0, boxes[i].1].into_iter(), threads, 1)
}

/// The build over `n` triangles, triangle i bounded by the points `points(i)` yields.
fn build_over<I: Iterator<Item = Vec3>>(n: usize, points: impl Fn(usize) -> I, threads: usize, max_leaf: usize) -> Bvh {
    let mut boxes = Vec::with_capacity(n);
    let mut centroids = Vec::with_capacity(n);
    for i in 0..n {
        let mut b = Aabb::EMPTY;
        points(i).for_each(|v| b.grow(v));
        boxes.push(b);
        centroids.push((b.lo + b.hi) * 0.5);
    }
    let mut order: Vec<u32> = (0..n as u32).collect();
    if n == 0 {
        // A root without children: every ray misses it.
        let stats = BvhStats {
            nodes: 1,
            ..Default::default()
        };
        return Bvh {
            nodes: vec![BvhNode::default()],
            order,
            stats,
        };
    }
    let inputs = Inputs {
        centroids: &centroids,
        boxes: &boxes,
        root_area: 0.0,
        max_leaf,
    };
    let root_box = inputs.bounds_of(&order);
    let inputs = Inputs {
        root_area: root_box.area().max(f32::MIN_POSITIVE),
        ..inputs
    };
    let (binary, mut stats) = build_range(&inputs, &mut order, 0, root_box, 0, threads);
    let (nodes, order, max_waiting) = widen(&binary, &order);
    stats.max_waiting = max_waiting;
    stats.nodes = nodes.len();
    Bvh { nodes, order, stats }
}

/// Builds the subtree over `order` (the triangles at global positions start..) with its root at index 0 and child
/// indices local to the returned array. `threads` > 1 builds the two halves of a split at the same time.
fn build_range(
    inputs: &Inputs,
    order: &mut [u32],
    start: usize,
    bounds: Aabb,
    depth: u32,
    threads: usize,
) -> (Vec<BinaryNode>, BvhStats) {
    // The shape of the splice depends on the triangle count only, never on `threads`: same bytes on any machine.
    if order.len() < PARALLEL_MIN_TRIS {
        return build_sequential(inputs, order, start, bounds, depth);
    }
    let Some(mid) = choose_split(order, inputs, &bounds, depth) else {
        return build_sequential(inputs, order, start, bounds, depth);
    };
    let (lo, hi) = order.split_at_mut(mid);
    let (lb, rb) = (inputs.bounds_of(lo), inputs.bounds_of(hi));
    let ((left, ls), (right, rs)) = if threads > 1 {
        std::thread::scope(|scope| {
            let r = scope.spawn(|| build_range(inputs, hi, start + mid, rb, depth + 1, threads / 2));
            let l = build_range(inputs, lo, start, lb, depth + 1, threads - threads / 2);
            (l, r.join().expect("a BVH build thread panicked"))
        })
    } else {
        (
            build_range(inputs, lo, start, lb, depth + 1, 1),
            build_range(inputs, hi, start + mid, rb, depth + 1, 1),
        )
    };
    // [root, left root, right root, rest of left, rest of right]: children stay adjacent.
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    nodes.push(node(&bounds, 1, 0));
    let left_base = 3;
    let right_base = 3 + left.len() - 1;
    let place = |local: usize, base: usize| if local == 0 { usize::MAX } else { base + local - 1 };
    let remap = |n: &BinaryNode, base: usize| {
        let mut n = *n;
        if !n.is_leaf() {
            n.lo[3] = f32::from_bits(place(n.first() as usize, base) as u32);
        }
        n
    };
    nodes.push(remap(&left[0], left_base));
    nodes.push(remap(&right[0], right_base));
    nodes.extend(left[1..].iter().map(|n| remap(n, left_base)));
    nodes.extend(right[1..].iter().map(|n| remap(n, right_base)));
    let stats = BvhStats {
        nodes: 0,
        leaves: ls.leaves + rs.leaves,
        depth: ls.depth.max(rs.depth),
        max_leaf_tris: ls.max_leaf_tris.max(rs.max_leaf_tris),
        sah_cost: TRAVERSAL_COST * bounds.area() / inputs.root_area + ls.sah_cost + rs.sah_cost,
        ..Default::default()
    };
    (nodes, stats)
}

fn build_sequential(
    inputs: &Inputs,
    order: &mut [u32],
    start: usize,
    bounds: Aabb,
    depth0: u32,
) -> (Vec<BinaryNode>, BvhStats) {
    let mut nodes = vec![BinaryNode::default()];
    let mut stats = BvhStats::default();
    let root_area = inputs.root_area;
    // (node index, start, end, depth, bounds), positions local to `order`
    let mut work = vec![(0usize, 0usize, order.len(), depth0, bounds)];
    while let Some((index, s, e, depth, bounds)) = work.pop() {
        stats.depth = stats.depth.max(depth);
        let count = e - s;
        let split = if count <= 1 {
            None
        } else {
            choose_split(&mut order[s..e], inputs, &bounds, depth)
        };
        match split {
            None => {
                nodes[index] = node(&bounds, (start + s) as u32, count as u32);
                stats.leaves += 1;
                stats.max_leaf_tris = stats.max_leaf_tris.max(count as u32);
                stats.sah_cost += bounds.area() / root_area * count as f32;
            }
            Some(mid) => {
                let left = nodes.len();
                nodes.push(BinaryNode::default());
                nodes.push(BinaryNode::default());
                nodes[index] = node(&bounds, left as u32, 0);
                stats.sah_cost += TRAVERSAL_COST * bounds.area() / root_area;
                let lb = inputs.bounds_of(&order[s..s + mid]);
                let rb = inputs.bounds_of(&order[s + mid..e]);
                work.push((left + 1, s + mid, e, depth + 1, rb));
                work.push((left, s, s + mid, depth + 1, lb));
            }
        }
    }
    (nodes, stats)
}

/// A leaf when few enough triangles remain, otherwise the halves by centroid along `axis`.
fn median_split(idx: &mut [u32], centroids: &[Vec3], axis: usize, max_leaf: usize) -> Option<usize> {
    if idx.len() <= max_leaf {
        return None;
    }
    let mid = idx.len() / 2;
    idx.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    Some(mid)
}

/// Partitions `idx` and returns the size of the left part, or None to make a leaf.
fn choose_split(idx: &mut [u32], inputs: &Inputs, bounds: &Aabb, depth: u32) -> Option<usize> {
    let (centroids, boxes) = (inputs.centroids, inputs.boxes);
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
        return median_split(idx, centroids, axis, inputs.max_leaf);
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
    if best.0 == f32::INFINITY || (split_cost >= leaf_cost && count <= inputs.max_leaf) {
        return median_split(idx, centroids, axis, inputs.max_leaf);
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

/// Collapses the binary tree into BVH_WIDTH-wide nodes: each node adopts grandchildren in place of its largest
/// interior children (by surface area, as they are the likeliest to be entered) until it has BVH_WIDTH.
///
/// Traversal pushes every entered child but the nearest, so a node `pushes` deep in the tree can leave that many
/// entries waiting. A child is opened only while `pushes + children - 1 + height(child) < BVH_STACK_SIZE` holds for
/// every child: a binary split always keeps it (height drops by one, pushes grow by one), so the stack bound the
/// binary build guarantees carries over.
///
/// A node's interior children get consecutive indices and its leaves' triangles consecutive positions, in slot order,
/// so the node stores where each run starts (`BvhNode::child_entries`). Returns the nodes, the triangle order that
/// makes (original indices, as `order` holds them for the binary tree's positions) and the stack bound.
fn widen(binary: &[BinaryNode], order: &[u32]) -> (Vec<BvhNode>, Vec<u32>, u32) {
    let height = heights(binary);
    let mut out = Vec::with_capacity(binary.len() / 2 + 1);
    out.push(BvhNode::default());
    if binary[0].is_leaf() {
        // A tree of one leaf: the root holds it as its only child, triangles from position 0.
        out[0] = quantise(&binary[0], &[&binary[0]]);
        out[0].set_kind(0, binary[0].count());
        return (out, order.to_vec(), 0);
    }
    let mut placed = Vec::with_capacity(order.len());
    let mut max_waiting = 0;
    // (binary node, the wide node made from it, entries waiting on the stack when traversal reaches it)
    let mut work = vec![(0usize, 0usize, 0u32)];
    while let Some((b, wide, pushes)) = work.pop() {
        let (slots, n) = open_children(binary, &height, b, pushes);
        let waiting = pushes + n as u32 - 1;
        max_waiting = max_waiting.max(waiting);
        let first_node = out.len() as u32;
        let first_tri = placed.len() as u32;
        let mut children = [&binary[0]; W];
        let mut kinds = [0u32; W];
        for (k, &c) in slots[..n].iter().enumerate() {
            kinds[k] = if binary[c].is_leaf() {
                let (first, count) = (binary[c].first() as usize, binary[c].count());
                placed.extend_from_slice(&order[first..first + count as usize]);
                count
            } else {
                out.push(BvhNode::default());
                work.push((c, out.len() - 1, waiting));
                BVH_CHILD_INTERIOR
            };
            children[k] = &binary[c];
        }
        let mut node = quantise(&binary[b], &children[..n]);
        for (k, &kind) in kinds[..n].iter().enumerate() {
            node.set_kind(k, kind);
        }
        node.q1[2] |= first_node << STACK_COUNT_BITS;
        node.q1[3] |= first_tri << STACK_COUNT_BITS;
        out[wide] = node;
    }
    // Every triangle sits in exactly one leaf, and every leaf under exactly one node.
    debug_assert_eq!(placed.len(), order.len());
    (out, placed, max_waiting)
}

/// Children per wide node, as an array length.
const W: usize = BVH_WIDTH as usize;

/// Each binary node's height: 0 for a leaf, one more than its taller child's otherwise.
fn heights(binary: &[BinaryNode]) -> Vec<u32> {
    // Children always follow their parent in the binary array, so one backward sweep finds every height.
    let mut height = vec![0u32; binary.len()];
    for i in (0..binary.len()).rev() {
        if !binary[i].is_leaf() {
            let l = binary[i].first() as usize;
            height[i] = 1 + height[l].max(height[l + 1]);
        }
    }
    height
}

/// The binary nodes the wide node made from binary node `b` holds (slots, how many): `b`'s two children, then
/// grandchildren in place of its largest interior children while every child stays within the stack bound, with
/// `pushes` entries waiting when traversal reaches the node.
fn open_children(binary: &[BinaryNode], height: &[u32], b: usize, pushes: u32) -> ([usize; W], usize) {
    let l = binary[b].first() as usize;
    let mut slots = [l, l + 1, 0, 0];
    let mut n = 2;
    while n < W {
        // The largest interior child whose opening keeps every child within the stack bound.
        let mut best: Option<(usize, f32)> = None;
        for k in 0..n {
            let c = slots[k];
            if binary[c].is_leaf() {
                continue;
            }
            let g = binary[c].first() as usize;
            let tallest = (0..n)
                .filter(|&j| j != k)
                .map(|j| height[slots[j]])
                .chain([height[g], height[g + 1]])
                .max()
                .unwrap_or(0);
            let a = binary[c].bounds().area();
            if pushes + n as u32 + tallest < BVH_STACK_SIZE && best.is_none_or(|(_, ba)| a > ba) {
                best = Some((k, a));
            }
        }
        let Some((k, _)) = best else { break };
        let g = binary[slots[k]].first() as usize;
        (slots[k], slots[n]) = (g, g + 1);
        n += 1;
    }
    (slots, n)
}

/// One wide node: each child's box rounded outwards onto a grid of 255 steps per axis spanning `parent`, so the box
/// traversal decodes (`BvhNode::child_box`, the same arithmetic as the device) holds the child's true box.
fn quantise(parent: &BinaryNode, children: &[&BinaryNode]) -> BvhNode {
    let mut n = BvhNode::default();
    let mut exps = [0u32; 3];
    for (a, exp) in exps.iter_mut().enumerate() {
        let (lo, hi) = (parent.lo[a] as f64, parent.hi[a] as f64);
        // The smallest step whose grid reaches the parent's far side, kept a normal power of two, with two more
        // conditions that make every grid point a float, so origin + q * step is exact and the distances traversal
        // finds as base + q * step (traverse.glsl) belong to the very box checked here: the origin is a multiple of
        // the step (at or below the parent's near side), and the step no finer than the spacing of floats at the
        // grid's largest magnitude. Only nodes narrower than 255 float steps of their position get coarser.
        let extent = (hi - lo).max(f32::MIN_POSITIVE as f64);
        let mut e = ((extent / 255.0).log2().floor() as i32 + 127).clamp(1, 254);
        let origin = loop {
            let step = 2f64.powi(e - 127);
            let origin = (lo / step).floor() * step;
            let far = origin.abs().max((origin + 255.0 * step).abs());
            // The biased exponent of the float spacing at `far` (f64 exponent rebased to f32's, less 23 bits).
            let spacing = ((far.to_bits() >> 52) & 0x7FF) as i32 - 1023 + 127 - 23;
            if e >= 254 || (origin + 255.0 * step >= hi && e >= spacing) {
                break origin as f32;
            }
            e += 1;
        };
        n.origin[a] = origin.to_bits();
        *exp = e as u32;
    }
    n.origin[3] = exps[0] | exps[1] << 8 | exps[2] << 16;
    let scale = n.scale();
    // The grid points exactly as traversal decodes them (the grid is set; children are filled in below).
    let grid = n;
    let decode = |a: usize, q: u32| grid.bound(a, q);
    for (c, child) in children.iter().enumerate() {
        let mut q = [0u32; 6];
        for a in 0..3 {
            // lo: the largest grid point at or below the child's; hi: the smallest at or above.
            let mut lo = (((child.lo[a] - decode(a, 0)) / scale[a]).floor().max(0.0) as u32).min(255);
            while lo > 0 && decode(a, lo) > child.lo[a] {
                lo -= 1;
            }
            while lo < 255 && decode(a, lo + 1) <= child.lo[a] {
                lo += 1;
            }
            let mut hi = (((child.hi[a] - decode(a, 0)) / scale[a]).ceil().max(0.0) as u32).min(255);
            while hi < 255 && decode(a, hi) < child.hi[a] {
                hi += 1;
            }
            while hi > 0 && decode(a, hi - 1) >= child.hi[a] {
                hi -= 1;
            }
            (q[a], q[3 + a]) = (lo, hi);
        }
        let shift = 8 * c;
        n.q0[0] |= q[0] << shift;
        n.q0[1] |= q[1] << shift;
        n.q0[2] |= q[2] << shift;
        n.q0[3] |= q[3] << shift;
        n.q1[0] |= q[4] << shift;
        n.q1[1] |= q[5] << shift;
    }
    n
}
