//! Bounding-volume hierarchy over boxes: the accelerator of many analytic primitives (spheres;
//! see `world::sphere_bvh` for the queries and why a BVH rather than the mesh's kD tree).
//!
//! Reads one box per item; writes [`Bvh`]: 32-byte nodes in depth-first pre-order (an inner
//! node's first child is the next node, its second child is stored in it) and the item indices
//! of all leaves, leaf after leaf. Built top-down with a binned surface-area heuristic over the
//! box centres (16 bins per axis, Wald 2007; the two halves of large nodes in parallel, joined
//! in pre-order), so the tree depends on nothing but the boxes, whatever the thread count.
//! Every item sits in exactly one leaf. Traversal ([`Bvh::visit`]) is front-to-back
//! by the ray's direction on each node's split axis, with a fixed stack (no allocation per ray)
//! and a conservative slab test (see [`SlabRay`]).

use std::cmp::Ordering;

/// Axis-aligned box `[lo, hi]` (closed) in `f32`.
pub type Aabb = ([f32; 3], [f32; 3]);

/// Deepest node the builder makes (the root is at depth 0); deeper items share one leaf. The
/// traversal stack holds one entry per level.
pub(crate) const MAX_DEPTH: usize = 48;
/// Items per leaf above which the builder always splits (when the centres can be split).
pub(crate) const MAX_LEAF: usize = 4;
/// SAH cost of one node visit, in units of one item test. On `many-spheres` any value from 0.5
/// (one sphere per leaf) to 3 traces at the same speed (measured, one thread); 2 makes leaves of
/// about two spheres and half the nodes of 0.5, which builds faster.
const COST_TRAVERSAL: f32 = 2.0;
/// Bins per axis of the binned SAH.
const BINS: usize = 16;

/// One node: its box and where its children or items are.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct BvhNode {
    /// Lower corner of the box of everything below.
    pub lo: [f32; 3],
    /// Inner node: index of the second child (the first is the next node). Leaf: index of the
    /// first item in [`Bvh::items`].
    pub offset: u32,
    /// Upper corner of the box.
    pub hi: [f32; 3],
    /// Inner node: the split axis (0, 1 or 2). Leaf: `3 | count << 2`.
    pub meta: u32,
}

impl BvhNode {
    /// True for a leaf.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.meta & 3 == 3
    }

    /// Number of items of a leaf.
    #[inline(always)]
    pub fn count(&self) -> usize {
        (self.meta >> 2) as usize
    }

    /// Split axis of an inner node.
    #[inline(always)]
    pub fn axis(&self) -> usize {
        (self.meta & 3) as usize
    }
}

/// A BVH: nodes in pre-order (node 0 is the root) and the leaves' item indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// Nodes in depth-first pre-order.
    pub nodes: Vec<BvhNode>,
    /// Item indices of all leaves, leaf after leaf (each item exactly once).
    pub items: Vec<u32>,
}

/// Union of two boxes (plain comparisons: NaN corners are the builder's only concern for where
/// an item goes, never for whether it is listed).
#[inline(always)]
fn join(a: &Aabb, b: &Aabb) -> Aabb {
    let mut r = *a;
    for k in 0..3 {
        r.0[k] = if b.0[k] < r.0[k] { b.0[k] } else { r.0[k] };
        r.1[k] = if b.1[k] > r.1[k] { b.1[k] } else { r.1[k] };
    }
    r
}

/// An empty box (the identity of [`join`]).
const EMPTY: Aabb = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);

/// Half the surface area of a box (zero for an empty or flat one).
#[inline]
fn half_area(b: &Aabb) -> f32 {
    let d = [0, 1, 2].map(|k| (b.1[k] - b.0[k]).max(0.0));
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

impl Bvh {
    /// Builds a BVH over `boxes` (item `i` has box `boxes[i]`). An empty input gives one empty
    /// leaf.
    pub fn build(boxes: &[Aabb]) -> Bvh {
        let mut prims: Vec<Prim> = boxes
            .iter()
            .enumerate()
            .map(|(i, b)| Prim {
                bounds: *b,
                centre: [0, 1, 2].map(|k| 0.5 * b.0[k] + 0.5 * b.1[k]),
                index: i as u32,
            })
            .collect();
        let nodes = subtree(&mut prims, 0, 0);
        Bvh {
            nodes,
            items: prims.iter().map(|p| p.index).collect(),
        }
    }

    /// Depth of the deepest leaf (0 for a single leaf).
    pub fn depth(&self) -> usize {
        fn walk(nodes: &[BvhNode], i: usize) -> usize {
            let n = &nodes[i];
            if n.is_leaf() {
                0
            } else {
                1 + walk(nodes, i + 1).max(walk(nodes, n.offset as usize))
            }
        }
        walk(&self.nodes, 0)
    }

    /// Visits, nearest first, every leaf whose box the ray may meet within `0 ..= limit`
    /// (conservatively: see [`SlabRay`]), calling `leaf(items, &mut limit)` with the leaf's
    /// range of [`Bvh::items`]; `leaf` may lower `limit` and returns true to stop. Returns true
    /// when a leaf stopped the walk.
    ///
    /// Both children of an inner node are tested together: the nearer (by entry `t`) is
    /// visited, the farther pushed with its entry `t` and skipped when popped beyond the limit
    /// by then.
    #[inline(always)]
    pub(crate) fn visit<const WIDE: bool>(
        &self,
        ray: &SlabRay,
        mut limit: f32,
        mut leaf: impl FnMut(std::ops::Range<usize>, &mut f32) -> bool,
    ) -> bool {
        // NaN marks a miss (and `t <= limit` is false for it below).
        if ray.entry::<WIDE>(&self.nodes[0], limit).is_nan() {
            return false;
        }
        let mut stack = [(0u32, 0.0f32); MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut i = 0usize;
        loop {
            let n = &self.nodes[i];
            if n.is_leaf() {
                let start = n.offset as usize;
                if leaf(start..start + n.count(), &mut limit) {
                    return true;
                }
            } else {
                let (a, b) = (i + 1, n.offset as usize);
                let ta = ray.entry::<WIDE>(&self.nodes[a], limit);
                let tb = ray.entry::<WIDE>(&self.nodes[b], limit);
                let (hit_a, hit_b) = (ta <= limit, tb <= limit);
                if hit_a && hit_b {
                    let (near, far, t_far) = if ta <= tb { (a, b, tb) } else { (b, a, ta) };
                    stack[sp] = (far as u32, t_far);
                    sp += 1;
                    i = near;
                    continue;
                }
                if hit_a || hit_b {
                    i = if hit_a { a } else { b };
                    continue;
                }
            }
            loop {
                if sp == 0 {
                    return false;
                }
                sp -= 1;
                let (j, t) = stack[sp];
                if t <= limit {
                    i = j as usize;
                    break;
                }
            }
        }
    }
}

/// One item as the builder moves it: its box, its box's centre and its index (kept together so
/// that partitioning moves contiguous rows).
#[derive(Clone, Copy)]
struct Prim {
    bounds: Aabb,
    centre: [f32; 3],
    index: u32,
}

/// Nodes above this many items build their two subtrees in parallel (rayon), each into its own
/// node list, joined in pre-order afterwards: the tree is the same on any number of threads.
const PARALLEL_MIN: usize = 4096;

/// The subtree over `prims` (which sit at `first..` of the final item list) at `depth`, its
/// nodes in pre-order with child indices relative to its root (node 0); reorders `prims` into
/// leaf order.
fn subtree(prims: &mut [Prim], first: usize, depth: usize) -> Vec<BvhNode> {
    if prims.len() < PARALLEL_MIN {
        let mut b = Builder {
            nodes: Vec::with_capacity(prims.len()),
        };
        b.node(prims, first, depth);
        return b.nodes;
    }
    let (root, split) = node_and_split(prims, first, depth);
    let Some((axis, mid)) = split else {
        return vec![root];
    };
    let (left, right) = prims.split_at_mut(mid);
    let (l, r) = rayon::join(
        || subtree(left, first, depth + 1),
        || subtree(right, first + mid, depth + 1),
    );
    let mut nodes = Vec::with_capacity(1 + l.len() + r.len());
    nodes.push(BvhNode {
        offset: 1 + l.len() as u32,
        meta: axis as u32,
        ..root
    });
    for (part, shift) in [(l.as_slice(), 1), (r.as_slice(), 1 + l.len() as u32)] {
        nodes.extend(part.iter().map(|n| {
            let mut n = *n;
            if !n.is_leaf() {
                n.offset += shift;
            }
            n
        }));
    }
    nodes
}

/// The leaf node over `prims` (at `first..` of the item list) and how to split it, if it is to
/// be split (see [`split`]).
fn node_and_split(
    prims: &mut [Prim],
    first: usize,
    depth: usize,
) -> (BvhNode, Option<(usize, usize)>) {
    let (mut bounds, mut centres) = (EMPTY, EMPTY);
    for p in prims.iter() {
        bounds = join(&bounds, &p.bounds);
        centres = join(&centres, &(p.centre, p.centre));
    }
    let leaf = BvhNode {
        lo: bounds.0,
        hi: bounds.1,
        offset: first as u32,
        meta: 3 | (prims.len() as u32) << 2,
    };
    if prims.len() <= 1 || depth >= MAX_DEPTH {
        return (leaf, None);
    }
    (leaf, split(prims, &bounds, &centres))
}

/// The sequential builder: appends nodes in pre-order.
struct Builder {
    nodes: Vec<BvhNode>,
}

impl Builder {
    /// Builds the subtree over `prims` (which sit at `first..` of the final item list) at
    /// `depth`, reordering `prims` in place into leaf order; returns its node index.
    fn node(&mut self, prims: &mut [Prim], first: usize, depth: usize) -> usize {
        let here = self.nodes.len();
        let (leaf, split) = node_and_split(prims, first, depth);
        self.nodes.push(leaf);
        let Some((axis, mid)) = split else {
            return here;
        };
        let (left, right) = prims.split_at_mut(mid);
        self.node(left, first, depth + 1);
        let second = self.node(right, first + mid, depth + 1);
        let n = &mut self.nodes[here];
        n.offset = second as u32;
        n.meta = axis as u32;
        here
    }
}

/// The binned-SAH split of `prims` (box `bounds`, centres within `centres`): reorders `prims`
/// so the first `mid` go left and returns `(axis, mid)`, or `None` when a leaf is cheaper (only
/// for at most [`MAX_LEAF`] items). Centres that cannot be binned apart (all equal) are split in
/// half by position when there are too many for a leaf.
fn split(prims: &mut [Prim], bounds: &Aabb, centres: &Aabb) -> Option<(usize, usize)> {
    let n = prims.len();
    // As many bins as items for small nodes (at least 2).
    let bins = BINS.min(n);
    let scale = [0, 1, 2].map(|k| bins as f32 / (centres.1[k] - centres.0[k]));
    let bin_of = |axis: usize, p: &Prim| -> usize {
        let x = (p.centre[axis] - centres.0[axis]) * scale[axis];
        // NaN (infinite boxes) and the top edge land in a valid bin.
        (x as usize).min(bins - 1)
    };
    let mut count = [[0u32; BINS]; 3];
    let mut bin_box = [[EMPTY; BINS]; 3];
    for p in prims.iter() {
        for axis in 0..3 {
            let b = bin_of(axis, p);
            count[axis][b] += 1;
            bin_box[axis][b] = join(&bin_box[axis][b], &p.bounds);
        }
    }
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        // Only axes along which the centres spread (NaN extents are skipped too).
        if centres.1[axis].partial_cmp(&centres.0[axis]) != Some(Ordering::Greater) {
            continue;
        }
        let (count, bin_box) = (&count[axis], &bin_box[axis]);
        // Right-to-left sweep: cost of everything right of each boundary.
        let mut right_cost = [0.0f32; BINS];
        let (mut acc, mut m) = (EMPTY, 0u32);
        for b in (1..bins).rev() {
            acc = join(&acc, &bin_box[b]);
            m += count[b];
            right_cost[b] = half_area(&acc) * m as f32;
        }
        let (mut acc, mut m) = (EMPTY, 0u32);
        for b in 1..bins {
            acc = join(&acc, &bin_box[b - 1]);
            m += count[b - 1];
            if m == 0 || m as usize == n {
                continue;
            }
            let cost = half_area(&acc) * m as f32 + right_cost[b];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    match best {
        Some((cost, axis, b)) => {
            let split_cost = COST_TRAVERSAL + cost / half_area(bounds);
            // A flat or empty box (NaN cost) splits when it must.
            if n <= MAX_LEAF && split_cost.partial_cmp(&(n as f32)) != Some(Ordering::Less) {
                return None;
            }
            Some((axis, partition(prims, |p| bin_of(axis, p) < b)))
        }
        None if n > MAX_LEAF => Some((0, n / 2)),
        None => None,
    }
}

/// Moves the items for which `left` holds to the front (Hoare's two-pointer partition); returns
/// how many there are.
fn partition(prims: &mut [Prim], left: impl Fn(&Prim) -> bool) -> usize {
    let (mut i, mut j) = (0, prims.len());
    loop {
        while i < j && left(&prims[i]) {
            i += 1;
        }
        while i < j && !left(&prims[j - 1]) {
            j -= 1;
        }
        if i >= j {
            return i;
        }
        prims.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
}

/// Relative widening of a slab's far end: covers the three roundings of `(b − o)·(1/d)` (pbrt's
/// `1 + 2γ(3)`, PBR 4th ed. §6.8.2) with room to spare.
const FAR_SCALE: f32 = 1.0 + 1.0 / (1 << 20) as f32;
/// Absolute widening of a slab's far end, in units of `t`: covers products that underflow.
const FAR_ABS: f32 = 1e-30;

/// The query limit for a best `t` so far: `best` widened by 2⁻¹⁶ relative and by 10⁻³⁰, so a
/// node holding a hit at `t ≤ best` is never cut by rounding (the slab test's three roundings,
/// `t`'s own rounding to f32). Infinity and NaN stay.
#[inline(always)]
pub(crate) fn limit_for(best: f32) -> f32 {
    best * (1.0 + 1.0 / (1 << 16) as f32) + FAR_ABS
}

/// A ray as the slab test reads it, with its cached reciprocal direction.
///
/// The test is conservative: for a finite ray whose direction components are zero or normal
/// floats, if the exact ray meets a node's box at some `t` in `0 ..= T` then the node is visited
/// whenever `limit ≥ T·(1 + 2⁻²⁰)`. NaN slab ends (an origin on a slab of a zero direction
/// component) are ignored, as are overflows to infinity, which only ever widen the interval.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabRay {
    /// Origin.
    pub o: [f32; 3],
    /// `1/d` per component (±∞ for zero components).
    pub inv: [f32; 3],
    /// Per-axis widening of the slab interval in units of `t` (`WIDE` queries only): `e·|1/d|`
    /// for a box widening `e`.
    pub widen: [f32; 3],
}

impl SlabRay {
    /// The ray `o + t·d` with every box widened by `widen_by` on every side (used with
    /// `WIDE = true`; pass 0 otherwise), or `None` when the slab test cannot be trusted for it:
    /// a non-finite component, or a direction component that is subnormal (its reciprocal
    /// overflows although the ray moves).
    #[inline(always)]
    pub fn new(o: [f32; 3], d: [f32; 3], widen_by: f32) -> Option<SlabRay> {
        let finite = o.iter().chain(&d).all(|v| v.is_finite());
        let normal = d.iter().all(|&v| v == 0.0 || v.abs() >= f32::MIN_POSITIVE);
        if !(finite && normal) {
            return None;
        }
        let inv = d.map(|v| 1.0 / v);
        let widen = inv.map(|v| {
            if widen_by > 0.0 {
                2.0 * widen_by * v.abs()
            } else {
                0.0
            }
        });
        Some(SlabRay { o, inv, widen })
    }

    /// True when the ray may meet the node's box within `0 ..= limit` (see [`SlabRay`]).
    #[cfg(test)]
    fn meets<const WIDE: bool>(&self, n: &BvhNode, limit: f32) -> bool {
        self.entry::<WIDE>(n, limit) <= limit
    }

    /// Where the ray may enter the node's box (at least 0, at most `limit`), or NaN when it
    /// cannot meet it within `0 ..= limit` (see [`SlabRay`]).
    #[inline(always)]
    pub fn entry<const WIDE: bool>(&self, n: &BvhNode, limit: f32) -> f32 {
        let mut t0 = 0.0f32;
        let mut t1 = limit;
        for k in 0..3 {
            let a = (n.lo[k] - self.o[k]) * self.inv[k];
            let b = (n.hi[k] - self.o[k]) * self.inv[k];
            let (mut near, mut far) = if a <= b { (a, b) } else { (b, a) };
            if WIDE {
                near -= self.widen[k];
                far += self.widen[k];
            }
            let far = far * FAR_SCALE + FAR_ABS;
            // Comparisons with NaN are false: a NaN end is ignored.
            t0 = if near > t0 { near } else { t0 };
            t1 = if far < t1 { far } else { t1 };
        }
        if t0 <= t1 { t0 } else { f32::NAN }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = Rng(seed);
        (0..n)
            .map(|_| {
                let c = [0, 1, 2].map(|_| rng.range(-10.0, 10.0));
                let r = rng.range(0.0, 0.5);
                (c.map(|v| v - r), c.map(|v| v + r))
            })
            .collect()
    }

    /// Every item in exactly one leaf; every node's box holds its children's (and leaves their
    /// items'); pre-order layout; depth within the limit.
    fn check(bvh: &Bvh, boxes: &[Aabb]) {
        let mut seen = vec![0; boxes.len()];
        for &i in &bvh.items {
            seen[i as usize] += 1;
        }
        assert!(seen.iter().all(|&s| s == 1), "each item once");
        let inside = |a: &Aabb, b: &BvhNode| (0..3).all(|k| a.0[k] >= b.lo[k] && a.1[k] <= b.hi[k]);
        for (i, n) in bvh.nodes.iter().enumerate() {
            if n.is_leaf() {
                let s = n.offset as usize;
                for &item in &bvh.items[s..s + n.count()] {
                    assert!(inside(&boxes[item as usize], n));
                }
            } else {
                assert!(n.offset as usize > i + 1 && (n.offset as usize) < bvh.nodes.len());
                for c in [i + 1, n.offset as usize] {
                    let child = &bvh.nodes[c];
                    assert!(inside(&(child.lo, child.hi), n));
                }
            }
        }
        assert!(bvh.depth() <= MAX_DEPTH);
    }

    #[test]
    fn random_boxes_build_a_valid_tree_with_small_leaves() {
        let boxes = random_boxes(5000, 3);
        let bvh = Bvh::build(&boxes);
        check(&bvh, &boxes);
        let leaves: Vec<_> = bvh.nodes.iter().filter(|n| n.is_leaf()).collect();
        assert!(leaves.iter().all(|n| n.count() <= MAX_LEAF));
        assert!(bvh.depth() < 30, "depth {}", bvh.depth());
    }

    #[test]
    fn equal_boxes_and_empty_input_still_build() {
        let boxes = vec![([0.0; 3], [1.0; 3]); 1000];
        let bvh = Bvh::build(&boxes);
        check(&bvh, &boxes);
        let bvh = Bvh::build(&[]);
        assert_eq!(bvh.nodes.len(), 1);
        assert!(bvh.nodes[0].is_leaf() && bvh.nodes[0].count() == 0);
        // Flat boxes (zero area) and one huge box among small ones.
        let mut boxes = random_boxes(300, 9);
        for b in &mut boxes[..100] {
            b.1[1] = b.0[1];
        }
        boxes.push(([-1e30; 3], [1e30; 3]));
        check(&Bvh::build(&boxes), &boxes);
    }

    #[test]
    fn the_build_depends_only_on_the_boxes_not_the_threads() {
        let boxes = random_boxes(6 * PARALLEL_MIN, 4);
        let on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| Bvh::build(&boxes))
        };
        let one = on(1);
        check(&one, &boxes);
        assert_eq!(one, on(3));
        assert_eq!(one, Bvh::build(&boxes));
    }

    /// The slab test against the exact answer, in f64, on rays grazing box faces and edges:
    /// whenever the exact ray meets the box within `0..=T`, `meets(limit_for(T))` is true.
    #[test]
    fn the_slab_test_never_misses_a_box_the_ray_meets() {
        let mut rng = Rng(11);
        let mut checked = 0;
        for _ in 0..200_000 {
            let lo = [0, 1, 2].map(|_| rng.range(-5.0, 5.0));
            let hi = [0, 1, 2].map(|k| lo[k] + rng.range(0.0, 3.0));
            let n = BvhNode {
                lo,
                hi,
                offset: 0,
                meta: 3,
            };
            let o = [0, 1, 2].map(|_| rng.range(-20.0, 20.0));
            // Aim at a point on the box's surface (a face, often an edge or a corner).
            let mut p = [0, 1, 2].map(|k| rng.range(lo[k], hi[k]));
            for k in 0..3 {
                match ((rng.next_u64() as u32) % 4) as usize {
                    0 => p[k] = lo[k],
                    1 => p[k] = hi[k],
                    _ => {}
                }
            }
            let mut d = [0, 1, 2].map(|k| p[k] - o[k]);
            if rng.next_u64().is_multiple_of(8) {
                d[((rng.next_u64() as u32) % 3) as usize] = 0.0;
            }
            let Some(ray) = SlabRay::new(o, d, 0.0) else {
                continue;
            };
            // Exact entry and exit in f64.
            let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
            for k in 0..3 {
                let (o, d, lo, hi) = (o[k] as f64, d[k] as f64, lo[k] as f64, hi[k] as f64);
                if d == 0.0 {
                    if o < lo || o > hi {
                        t1 = -1.0;
                    }
                    continue;
                }
                let (a, b) = ((lo - o) / d, (hi - o) / d);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
            if t0 <= t1 {
                checked += 1;
                let limit = limit_for(t0 as f32);
                assert!(ray.meets::<false>(&n, limit), "{o:?} {d:?} {lo:?} {hi:?}");
                assert!(ray.meets::<true>(&n, limit), "{o:?} {d:?} {lo:?} {hi:?}");
            }
        }
        assert!(checked > 50_000, "{checked}");
    }
}
