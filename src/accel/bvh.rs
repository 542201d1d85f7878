//! Bounding-volume hierarchy over boxes: the accelerator of many analytic primitives (spheres;
//! see `world::sphere_bvh` for the queries and why a BVH rather than the mesh's kD tree).
//!
//! Reads one box per item; writes [`Bvh`]: 32-byte nodes in depth-first pre-order (an inner
//! node's first child is the next node, its second child is stored in it) and the item indices
//! of all leaves, leaf after leaf. Built top-down with a binned surface-area heuristic over the
//! box centres (16 bins per axis, Wald 2007), sequentially, so the tree depends on nothing but
//! the boxes. Every item sits in exactly one leaf. Traversal ([`Bvh::visit`]) is front-to-back
//! by the ray's direction on each node's split axis, with a fixed stack (no allocation per ray)
//! and a conservative slab test (see [`SlabRay`]).

/// Axis-aligned box `[lo, hi]` (closed) in `f32`.
pub type Aabb = ([f32; 3], [f32; 3]);

/// Deepest node the builder makes (the root is at depth 0); deeper items share one leaf. The
/// traversal stack holds one entry per level.
pub const MAX_DEPTH: usize = 48;
/// Items per leaf above which the builder always splits (when the centres can be split).
pub const MAX_LEAF: usize = 4;
/// SAH cost of one node visit, in units of one item test.
const COST_TRAVERSAL: f32 = 0.5;
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

/// Union of two boxes.
#[inline]
fn join(a: &Aabb, b: &Aabb) -> Aabb {
    let mut r = *a;
    for k in 0..3 {
        r.0[k] = r.0[k].min(b.0[k]);
        r.1[k] = r.1[k].max(b.1[k]);
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
        let centres: Vec<[f32; 3]> = boxes
            .iter()
            .map(|b| [0, 1, 2].map(|k| 0.5 * b.0[k] + 0.5 * b.1[k]))
            .collect();
        let mut items: Vec<u32> = (0..boxes.len() as u32).collect();
        let mut b = Builder {
            boxes,
            centres: &centres,
            nodes: Vec::with_capacity(2 * boxes.len() / MAX_LEAF + 1),
        };
        b.node(&mut items, 0, 0);
        Bvh {
            nodes: b.nodes,
            items,
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

    /// Visits, front to back, every leaf whose box the ray may meet within `0 ..= limit`
    /// (conservatively: see [`SlabRay`]), calling `leaf(items, &mut limit)` with the leaf's
    /// range of [`Bvh::items`]; `leaf` may lower `limit` and returns true to stop. Returns true
    /// when a leaf stopped the walk.
    #[inline(always)]
    pub fn visit<const WIDE: bool>(
        &self,
        ray: &SlabRay,
        mut limit: f32,
        mut leaf: impl FnMut(std::ops::Range<usize>, &mut f32) -> bool,
    ) -> bool {
        let mut stack = [0u32; MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut i = 0usize;
        loop {
            let n = &self.nodes[i];
            if ray.meets::<WIDE>(n, limit) {
                if !n.is_leaf() {
                    // Near child first: the first child holds the lower side of the split axis.
                    let (near, far) = if ray.neg[n.axis()] {
                        (n.offset as usize, i + 1)
                    } else {
                        (i + 1, n.offset as usize)
                    };
                    stack[sp] = far as u32;
                    sp += 1;
                    i = near;
                    continue;
                }
                let start = n.offset as usize;
                if leaf(start..start + n.count(), &mut limit) {
                    return true;
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            i = stack[sp] as usize;
        }
    }
}

struct Builder<'a> {
    boxes: &'a [Aabb],
    centres: &'a [[f32; 3]],
    nodes: Vec<BvhNode>,
}

impl Builder<'_> {
    /// Builds the subtree over `items` (which sit at `first..` of the final item list) at
    /// `depth`, reordering `items` in place into leaf order; returns its node index.
    fn node(&mut self, items: &mut [u32], first: usize, depth: usize) -> usize {
        let here = self.nodes.len();
        let bounds = items
            .iter()
            .fold(EMPTY, |b, &i| join(&b, &self.boxes[i as usize]));
        self.nodes.push(BvhNode {
            lo: bounds.0,
            hi: bounds.1,
            offset: first as u32,
            meta: 3 | (items.len() as u32) << 2,
        });
        if items.len() <= 1 || depth >= MAX_DEPTH {
            return here;
        }
        let Some((axis, mid)) = self.split(items, &bounds) else {
            return here;
        };
        let (left, right) = items.split_at_mut(mid);
        self.node(left, first, depth + 1);
        let second = self.node(right, first + mid, depth + 1);
        let n = &mut self.nodes[here];
        n.offset = second as u32;
        n.meta = axis as u32;
        here
    }

    /// The binned-SAH split of `items` (box `bounds`): reorders `items` so the first `mid` go
    /// left and returns `(axis, mid)`, or `None` when a leaf is cheaper (only for at most
    /// [`MAX_LEAF`] items). Centres that cannot be binned apart (all equal) are split in half by
    /// position in the list when there are too many for a leaf.
    fn split(&self, items: &mut [u32], bounds: &Aabb) -> Option<(usize, usize)> {
        let n = items.len();
        let cb = items.iter().fold(EMPTY, |b, &i| {
            let c = self.centres[i as usize];
            join(&b, &(c, c))
        });
        let bin_of = |axis: usize, i: u32| -> usize {
            let (lo, hi) = (cb.0[axis], cb.1[axis]);
            let x = (self.centres[i as usize][axis] - lo) / (hi - lo) * BINS as f32;
            // NaN (infinite boxes) and the top edge land in a valid bin.
            (x as usize).min(BINS - 1)
        };
        let mut best: Option<(f32, usize, usize)> = None;
        for axis in 0..3 {
            if !(cb.1[axis] > cb.0[axis]) {
                continue;
            }
            let mut count = [0usize; BINS];
            let mut bin_box = [EMPTY; BINS];
            for &i in items.iter() {
                let b = bin_of(axis, i);
                count[b] += 1;
                bin_box[b] = join(&bin_box[b], &self.boxes[i as usize]);
            }
            // Right-to-left sweep: cost of everything right of each boundary.
            let mut right_cost = [0.0f32; BINS];
            let (mut acc, mut m) = (EMPTY, 0usize);
            for b in (1..BINS).rev() {
                acc = join(&acc, &bin_box[b]);
                m += count[b];
                right_cost[b] = half_area(&acc) * m as f32;
            }
            let (mut acc, mut m) = (EMPTY, 0usize);
            for b in 1..BINS {
                acc = join(&acc, &bin_box[b - 1]);
                m += count[b - 1];
                if m == 0 || m == n {
                    continue;
                }
                let cost = half_area(&acc) * m as f32 + right_cost[b];
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, b));
                }
            }
        }
        let area = half_area(bounds);
        match best {
            Some((cost, axis, b)) => {
                let split_cost = COST_TRAVERSAL + cost / area;
                // A flat or empty box (NaN cost) splits when it must.
                if n <= MAX_LEAF && !(split_cost < n as f32) {
                    return None;
                }
                Some((axis, partition(items, |i| bin_of(axis, i) < b)))
            }
            None if n > MAX_LEAF => Some((0, n / 2)),
            None => None,
        }
    }
}

/// Moves the items for which `left` holds to the front, keeping each side's order; returns how
/// many there are.
fn partition(items: &mut [u32], left: impl Fn(u32) -> bool) -> usize {
    let (l, r): (Vec<u32>, Vec<u32>) = items.iter().partition(|&&i| left(i));
    let mid = l.len();
    items[..mid].copy_from_slice(&l);
    items[mid..].copy_from_slice(&r);
    mid
}

/// Relative widening of a slab's far end: covers the three roundings of `(b − o)·(1/d)` (pbrt's
/// `1 + 2γ(3)`, PBR 4th ed. §6.8.2) with room to spare.
const FAR_SCALE: f32 = 1.0 + 1.0 / (1 << 20) as f32;
/// Absolute widening of a slab's far end, in units of `t`: covers products that underflow.
const FAR_ABS: f32 = 1e-30;

/// The query limit for a best `t` so far: `best` widened by 2⁻¹⁶ relative and [`FAR_ABS`], so a
/// node holding a hit at `t ≤ best` is never cut by rounding (the slab test's three roundings,
/// `t`'s own rounding to f32). Infinity and NaN stay.
#[inline(always)]
pub fn limit_for(best: f32) -> f32 {
    best * (1.0 + 1.0 / (1 << 16) as f32) + FAR_ABS
}

/// A ray as the slab test reads it, with its cached reciprocal direction.
///
/// The test is conservative: for a finite ray whose direction components are zero or normal
/// floats, if the exact ray meets a node's box at some `t` in `0 ..= T` then the node is visited
/// whenever `limit ≥ T·(1 + 2⁻²⁰)`. NaN slab ends (an origin on a slab of a zero direction
/// component) are ignored, as are overflows to infinity, which only ever widen the interval.
#[derive(Clone, Copy, Debug)]
pub struct SlabRay {
    /// Origin.
    pub o: [f32; 3],
    /// `1/d` per component (±∞ for zero components).
    pub inv: [f32; 3],
    /// True where `inv` is negative: that axis's upper child is nearer.
    pub neg: [bool; 3],
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
        Some(SlabRay {
            o,
            inv,
            neg: inv.map(|v| v < 0.0),
            widen,
        })
    }

    /// True when the ray may meet the node's box within `0 ..= limit` (see [`SlabRay`]).
    #[inline(always)]
    pub fn meets<const WIDE: bool>(&self, n: &BvhNode, limit: f32) -> bool {
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
        t0 <= t1
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
    fn the_build_depends_only_on_the_boxes() {
        let boxes = random_boxes(3000, 4);
        assert_eq!(Bvh::build(&boxes), Bvh::build(&boxes));
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
            if (rng.next_u64() as u32) % 8 == 0 {
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
