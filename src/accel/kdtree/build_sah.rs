//! Surface-area-heuristic builder in O(N log N) (Wald & Havran 2006, "On building fast kd-trees
//! for ray tracing, and on doing that in O(N log N)").
//!
//! Each node carries its triangles' bounds clipped to the node box and, per axis, the split
//! events (end / planar / start) sorted once at the root and kept sorted by filtering and merging
//! on the way down; nodes of at most [`SMALL`] triangles keep no events: they count, on SIMD
//! lanes, the triangles left, right and in each candidate plane (the counts and costs the sweep
//! has there, so the same split; [`split_lanes`]) and bound straddling triangles by box
//! intersection rather than exact clipping. A sweep per axis finds the cheapest plane; empty space gets a bonus; a node
//! becomes a leaf when splitting costs more than intersecting all its triangles, or at the depth
//! cap `8 + 1.3·log2 N` (pbrt); a node below the root of at most [`LEAF_MAX`] triangles is a
//! leaf without a search.
//!
//! Classification follows the paper: a triangle whose (clipped) extent only touches the plane
//! goes to the one side it lies on, and a triangle lying IN the plane goes to the side that makes
//! the split cheaper. `validate()` checks exactly this contract (positive-area overlap).
//!
//! Events are packed in one `u64` each (`ordered position bits << 32 | kind << 30 | triangle`),
//! so sorting and merging compare plain integers. Output nodes are written directly in
//! depth-first order; subtrees built in parallel (`rayon::join`) are appended with their indices
//! shifted, so the result does not depend on the thread count.

use super::node::KdNode;
use super::overlap::{Aabb, clip_bounds};
use super::{COST_INTERSECT, COST_TRAVERSAL, MAX_BUILD_DEPTH, split_box, tri_verts};
use crate::mesh::TriangleMesh;
use crate::simd::{Level, Wide, WideKernel, dispatch_wide};

/// Cost factor applied when one side of a split is empty (20 % empty-space bonus).
pub(crate) const EMPTY_FACTOR: f32 = 0.8;
/// Smallest empty slab (as a fraction of the node's extent on the split axis) that earns the
/// bonus, so that thin slivers of empty space are not cut off for nothing.
pub(crate) const EMPTY_MIN_FRACTION: f32 = 0.02;
/// Nodes with more triangles than this build their children in parallel.
const PARALLEL_MIN: usize = 4096;
/// Nodes with at most this many triangles are built by [`node_small`]: splits are found by
/// counting on lanes ([`split_lanes`]) instead of sweeping events, and children's triangles live
/// in one reused scratch arena, so a small subtree makes no heap allocation of its own.
pub(crate) const SMALL: usize = 48;

/// Nodes below the root of at most this many triangles become leaves without a split search (a
/// mesh that small is still searched at the root, so its tree cuts off empty space). Measured on
/// Sibenik (callgrind, 1 thread): the build takes 17 % fewer instructions than searching every
/// node (1.28 G against 1.54 G), and tracing the `sibenik-shadows` frame with the tree 0.7 % more
/// (679 M against 674 M); 3 gives 8 % and -0.4 %, 8 gives 27 % and +3.1 %.
pub(crate) const LEAF_MAX: usize = 5;

/// The builder's own constants, for [`super::builder_settings`].
pub(crate) const SETTINGS: &str = "empty 0.8/0.02 small 48 leaf 5 exact-sweep";

const END: u64 = 0;
const PLANAR: u64 = 1;
const START: u64 = 2;

/// Maps an `f32` to a `u32` with the same order (`-0.0` must be normalised to `+0.0` first).
#[inline]
fn ord(f: f32) -> u32 {
    let b = f.to_bits();
    if b >> 31 == 1 { !b } else { b | 0x8000_0000 }
}

/// Inverse of [`ord`].
#[inline]
fn unord(u: u32) -> f32 {
    f32::from_bits(if u >> 31 == 1 { u & 0x7fff_ffff } else { !u })
}

#[inline]
fn event(pos: f32, kind: u64, tri: u32) -> u64 {
    ((ord(pos) as u64) << 32) | (kind << 30) | tri as u64
}

/// Pushes the events of one triangle's bounds on `axis`.
#[inline]
fn push_events(out: &mut Vec<u64>, b: &Aabb, axis: usize, tri: u32) {
    let (lo, hi) = (b.0[axis], b.1[axis]);
    if lo == hi {
        out.push(event(lo, PLANAR, tri));
    } else {
        out.push(event(lo, START, tri));
        out.push(event(hi, END, tri));
    }
}

/// `-0.0` becomes `+0.0`, so equal positions have equal event keys.
#[inline]
fn norm(b: Aabb) -> Aabb {
    (b.0.map(|x| x + 0.0), b.1.map(|x| x + 0.0))
}

/// Flat builder output: nodes in depth-first pre-order and the leaves' triangle lists.
#[derive(Default)]
pub(crate) struct Flat {
    pub(crate) nodes: Vec<KdNode>,
    pub(crate) tris: Vec<u32>,
}

impl Flat {
    /// Appends a subtree built separately, shifting its child and triangle offsets.
    pub(crate) fn append(&mut self, sub: Flat) {
        let nb = self.nodes.len() as u32;
        let tb = self.tris.len() as u32;
        self.nodes.extend(sub.nodes.into_iter().map(|n| {
            if n.is_leaf() {
                KdNode::leaf(n.offset() + tb, n.count())
            } else {
                KdNode::inner(n.axis(), n.split(), n.right() + nb)
            }
        }));
        self.tris.extend_from_slice(&sub.tris);
    }

    /// Appends a leaf holding `ids` (sorted).
    pub(crate) fn leaf(&mut self, ids: &[u32]) {
        let start = self.tris.len();
        self.nodes
            .push(KdNode::leaf(start as u32, ids.len() as u32));
        self.tris.extend_from_slice(ids);
        self.tris[start..].sort_unstable();
    }
}

/// Triangles of one node: global ids, bounds clipped to the node box, sorted events per axis
/// (left empty for nodes of at most [`SMALL`] triangles, which make their own).
struct Work {
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
    events: [Vec<u64>; 3],
}

/// Bounds of triangle `t` (with `-0.0` normalised).
#[inline]
pub(crate) fn tri_bounds(mesh: &TriangleMesh, t: u32) -> Aabb {
    let v = tri_verts(mesh, t);
    let mut b = (v[0], v[0]);
    for p in &v[1..] {
        for (k, &c) in p.iter().enumerate() {
            b.0[k] = b.0[k].min(c);
            b.1[k] = b.1[k].max(c);
        }
    }
    norm(b)
}

/// Depth cap of a tree over `n` triangles: `8 + 1.3·log2 n` (pbrt), at most [`MAX_BUILD_DEPTH`].
pub(crate) fn max_depth(n: usize) -> usize {
    let n = n.max(1) as f32;
    ((8.0 + 1.3 * n.log2()) as usize).min(MAX_BUILD_DEPTH)
}

/// Builds the SAH tree over `tris` (non-degenerate triangle indices) in box `root` with the exact
/// sweep at every level.
pub(crate) fn build(mesh: &TriangleMesh, root: Aabb, tris: Vec<u32>) -> Flat {
    assert!(
        tris.len() < 1 << 30,
        "too many triangles for the SAH builder"
    );
    let bounds: Vec<Aabb> = tris.iter().map(|&t| tri_bounds(mesh, t)).collect();
    let max_depth = max_depth(tris.len());
    let mut out = Flat::default();
    subtree(mesh, root, tris, bounds, 0, max_depth, &mut out);
    out
}

/// Builds the exact-sweep subtree over triangles `ids` with (clipped) `bounds` in box `bx` at
/// `depth`, appending it to `out` in pre-order: sorts this node's events once, then filters and
/// merges them on the way down.
pub(crate) fn subtree(
    mesh: &TriangleMesh,
    bx: Aabb,
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
    depth: usize,
    max_depth: usize,
    out: &mut Flat,
) {
    if ids.len() <= SMALL {
        node_small(
            bx,
            &ids,
            &bounds,
            depth,
            max_depth,
            out,
            &mut SmallArena::new(),
        );
        return;
    }
    let make = |axis: usize| {
        let mut ev = Vec::with_capacity(2 * bounds.len());
        for (i, b) in bounds.iter().enumerate() {
            push_events(&mut ev, b, axis, i as u32);
        }
        ev.sort_unstable();
        ev
    };
    let (e0, (e1, e2)) = rayon::join(|| make(0), || rayon::join(|| make(1), || make(2)));
    let work = Work {
        ids,
        bounds,
        events: [e0, e1, e2],
    };
    node(mesh, bx, work, depth, max_depth, out);
}

/// Best split found by a sweep or by binning.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Split {
    /// SAH cost of the split.
    pub(crate) cost: f32,
    /// Split axis.
    pub(crate) axis: usize,
    /// Plane position on the axis.
    pub(crate) pos: f32,
    /// Triangles lying in the plane go left (else right).
    pub(crate) planar_left: bool,
}

/// The SAH cost of split planes on one axis of a node's box: the one cost formula of the exact
/// sweep and the binned builder (`build_binned`), so both builders weigh a plane alike.
#[derive(Clone, Copy, Debug)]
pub(crate) struct AxisCost {
    /// The box's extent on the axis.
    pub lo: f32,
    /// The box's extent on the axis.
    pub hi: f32,
    /// Area of the two faces perpendicular to the axis.
    cap: f32,
    /// Perimeter of those faces (area per unit of extent along the axis).
    perim: f32,
    /// `COST_INTERSECT` over the node's surface area.
    ki: f32,
    /// Smallest empty side that earns the empty-space bonus.
    min_empty: f32,
}

impl AxisCost {
    /// The costs on `axis` of box `bx` (extent `ext`, `ki = COST_INTERSECT / area`); `None` when
    /// the box is flat on the axis.
    pub(crate) fn new(bx: &Aabb, ext: [f32; 3], axis: usize, ki: f32) -> Option<AxisCost> {
        let (lo, hi) = (bx.0[axis], bx.1[axis]);
        if lo >= hi {
            return None;
        }
        let d1 = ext[(axis + 1) % 3];
        let d2 = ext[(axis + 2) % 3];
        Some(AxisCost {
            lo,
            hi,
            cap: 2.0 * d1 * d2,
            perim: 2.0 * (d1 + d2),
            ki,
            min_empty: EMPTY_MIN_FRACTION * (hi - lo),
        })
    }

    /// The cost of the plane at `p` (`lo < p < hi`) with `l` triangles left and `r` right.
    #[inline]
    pub(crate) fn cost(&self, p: f32, l: usize, r: usize) -> f32 {
        let (wl, wr) = (p - self.lo, self.hi - p);
        let sl = self.cap + wl * self.perim;
        let sr = self.cap + wr * self.perim;
        let c = COST_TRAVERSAL + self.ki * (sl * l as f32 + sr * r as f32);
        if (l == 0 && wl >= self.min_empty) || (r == 0 && wr >= self.min_empty) {
            c * EMPTY_FACTOR
        } else {
            c
        }
    }

    /// [`AxisCost::cost`] of the planes at lanes `p` with `l` and `r` triangles (exact small
    /// integers) each: the same operations in the same order, so each lane has the scalar bits.
    #[inline(always)]
    pub(crate) fn cost_lanes<V: Wide>(&self, p: V, l: V, r: V) -> V {
        let (wl, wr) = (p.sub(V::splat(self.lo)), V::splat(self.hi).sub(p));
        let perim = V::splat(self.perim);
        let sl = V::splat(self.cap).add(wl.mul(perim));
        let sr = V::splat(self.cap).add(wr.mul(perim));
        let c = V::splat(COST_TRAVERSAL).add(V::splat(self.ki).mul(sl.mul(l).add(sr.mul(r))));
        let (zero, min_empty) = (V::splat(0.0), V::splat(self.min_empty));
        let bonus = V::or(
            V::and(l.eq(zero), min_empty.le(wl)),
            V::and(r.eq(zero), min_empty.le(wr)),
        );
        V::select(bonus, c.mul(V::splat(EMPTY_FACTOR)), c)
    }
}

/// [`split_lanes`] as a kernel for [`dispatch_wide`].
struct LaneSplit<'a> {
    bounds: &'a [Aabb],
    bx: &'a Aabb,
}

impl WideKernel for LaneSplit<'_> {
    type Output = Option<Split>;
    #[inline(always)]
    fn run<V: Wide>(self) -> Option<Split> {
        split_lanes::<V>(self.bounds, self.bx)
    }
}

/// The split [`find_split`] finds for the triangles with `bounds` (at most [`SMALL`]) in box
/// `bx`, found without events: the candidate planes are the bounds' faces, [`Wide::LANES`] at a
/// time, and each triangle counts itself left (`lo < p`), right (`hi > p`) and planar (`lo == hi
/// == p`) on every lane — exactly the counts the sweep has at `p` — then the lanes' costs are the
/// sweep's ([`AxisCost::cost_lanes`]). The sweep takes the first cheapest plane by axis, then
/// position; so does this (a tie goes to the lower axis, then the lower position), so the split
/// is the same.
#[inline(always)]
fn split_lanes<V: Wide>(bounds: &[Aabb], bx: &Aabb) -> Option<Split> {
    let n = bounds.len();
    debug_assert!(n <= SMALL);
    let (ext, ki) = box_costs(bx)?;
    let mut best: Option<Split> = None;
    // Candidates (padded with NaN, which is never inside the box) and one batch's costs.
    let mut cand = [f32::NAN; 2 * SMALL + 32];
    let mut costs = [0.0f32; 32];
    let one = V::splat(1.0);
    for axis in 0..3 {
        let Some(axis_cost) = AxisCost::new(bx, ext, axis, ki) else {
            continue;
        };
        // Each plane inside the box once per triangle face (a flat triangle's two faces are one;
        // the faces of bounds clipped to the box lie on it): repeats cost time, not results.
        let (mut planar, mut m) = (false, 0);
        for b in bounds {
            // `+ 0.0`: a plane at `-0.0` is the sweep's `+0.0` (its events are normalised).
            let (lo, hi) = (b.0[axis] + 0.0, b.1[axis] + 0.0);
            planar |= lo == hi;
            cand[m] = lo;
            m += (lo > axis_cost.lo && lo < axis_cost.hi) as usize;
            cand[m] = hi;
            m += (hi != lo && hi > axis_cost.lo && hi < axis_cost.hi) as usize;
        }
        cand[m..m.next_multiple_of(V::LANES)].fill(f32::NAN);
        let (box_lo, box_hi) = (V::splat(axis_cost.lo), V::splat(axis_cost.hi));
        for at in (0..m).step_by(V::LANES) {
            let p = V::load(&cand[at..]);
            let (mut l, mut r, mut pp) = (V::splat(0.0), V::splat(0.0), V::splat(0.0));
            if planar {
                for b in bounds {
                    let (lo, hi) = (V::splat(b.0[axis]), V::splat(b.1[axis]));
                    l = l.add_where(lo.lt(p), one);
                    r = r.add_where(hi.gt(p), one);
                    pp = pp.add_where(V::and(lo.eq(p), hi.eq(p)), one);
                }
            } else {
                for b in bounds {
                    l = l.add_where(V::splat(b.0[axis]).lt(p), one);
                    r = r.add_where(V::splat(b.1[axis]).gt(p), one);
                }
            }
            let inside = V::and(p.gt(box_lo), p.lt(box_hi));
            let (c, left) = if planar {
                let cl = axis_cost.cost_lanes(p, l.add(pp), r);
                let cr = axis_cost.cost_lanes(p, l, r.add(pp));
                let left = cl.le(cr);
                (V::select(left, cl, cr), V::bits(left))
            } else {
                (axis_cost.cost_lanes(p, l, r), u32::MAX)
            };
            let bound = V::splat(best.map_or(f32::INFINITY, |b| b.cost));
            let mut hits = V::bits(V::and(inside, c.le(bound)));
            if hits == 0 {
                continue;
            }
            c.store(&mut costs);
            while hits != 0 {
                let k = hits.trailing_zeros() as usize;
                hits &= hits - 1;
                let (cost, pos) = (costs[k], cand[at + k]);
                let better = best.is_none_or(|b| {
                    cost < b.cost || (cost == b.cost && b.axis == axis && pos < b.pos)
                });
                if better {
                    best = Some(Split {
                        cost,
                        axis,
                        pos,
                        planar_left: left >> k & 1 != 0,
                    });
                }
            }
        }
    }
    best
}

/// Box `bx`'s extent and `COST_INTERSECT` over its surface area, the two things every split
/// search's costs start from ([`AxisCost::new`]); `None` for an empty, flat or NaN box.
pub(crate) fn box_costs(bx: &Aabb) -> Option<([f32; 3], f32)> {
    let ext = [bx.1[0] - bx.0[0], bx.1[1] - bx.0[1], bx.1[2] - bx.0[2]];
    let sa = 2.0 * (ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0]);
    if sa.is_nan() || sa <= 0.0 {
        return None;
    }
    Some((ext, COST_INTERSECT / sa))
}

fn find_split(n: usize, events: [&[u64]; 3], bx: &Aabb) -> Option<Split> {
    let (ext, ki) = box_costs(bx)?;
    let mut best: Option<Split> = None;
    let mut best_cost = f32::INFINITY;
    for (axis, ev) in events.into_iter().enumerate() {
        let Some(axis_cost) = AxisCost::new(bx, ext, axis, ki) else {
            continue;
        };
        let (lo, hi) = (axis_cost.lo, axis_cost.hi);
        let (mut nl, mut nr) = (0usize, n);
        let len = ev.len();
        let mut i = 0;
        while i < len {
            let key = ev[i] >> 32;
            // Counted without branching on the kind (END = 0, PLANAR = 1, START = 2): the kinds
            // of neighbouring events are unpredictable.
            let (mut group, mut pp, mut ps) = (0usize, 0usize, 0usize);
            loop {
                let kind = ((ev[i] >> 30) & 3) as usize;
                group += 1;
                pp += kind & 1;
                ps += kind >> 1;
                i += 1;
                if i == len || ev[i] >> 32 != key {
                    break;
                }
            }
            let pe = group - pp - ps;
            nr -= pe + pp;
            let p = unord(key as u32);
            if p > lo && p < hi {
                let cost = |l: usize, r: usize| axis_cost.cost(p, l, r);
                let (c, planar_left) = if pp == 0 {
                    (cost(nl, nr), true)
                } else {
                    let cl = cost(nl + pp, nr);
                    let cr = cost(nl, nr + pp);
                    if cl <= cr { (cl, true) } else { (cr, false) }
                };
                if c < best_cost {
                    best_cost = c;
                    best = Some(Split {
                        cost: c,
                        axis,
                        pos: p,
                        planar_left,
                    });
                }
            }
            nl += ps + pp;
        }
    }
    best
}

/// Builds the subtree for `w` in box `bx`, appending its nodes to `out` in pre-order.
fn node(mesh: &TriangleMesh, bx: Aabb, w: Work, depth: usize, max_depth: usize, out: &mut Flat) {
    let n = w.ids.len();
    if n <= SMALL {
        node_small(
            bx,
            &w.ids,
            &w.bounds,
            depth,
            max_depth,
            out,
            &mut SmallArena::new(),
        );
        return;
    }
    let split = if depth >= max_depth {
        None
    } else {
        let [e0, e1, e2] = &w.events;
        find_split(n, [e0, e1, e2], &bx).filter(|s| s.cost < COST_INTERSECT * n as f32)
    };
    let Some(split) = split else {
        out.leaf(&w.ids);
        return;
    };
    let (axis, s) = (split.axis, split.pos);
    let (lb, rb) = split_box(&bx, axis, s);
    // Classify: 1 = left only, 2 = right only, 3 = both (straddles the plane).
    let side: Vec<u8> = w.bounds.iter().map(|b| classify(b, &split)).collect();
    let large = n > PARALLEL_MIN;
    let (left, right) = if large {
        rayon::join(
            || child(mesh, &w, &side, 1, &lb),
            || child(mesh, &w, &side, 2, &rb),
        )
    } else {
        (
            child(mesh, &w, &side, 1, &lb),
            child(mesh, &w, &side, 2, &rb),
        )
    };
    drop(side);
    drop(w);
    let here = out.nodes.len();
    out.nodes.push(KdNode::inner(axis, s, 0));
    if large {
        let mut sub = Flat::default();
        rayon::join(
            || node(mesh, lb, left, depth + 1, max_depth, out),
            || node(mesh, rb, right, depth + 1, max_depth, &mut sub),
        );
        out.nodes[here] = KdNode::inner(axis, s, out.nodes.len() as u32);
        out.append(sub);
    } else {
        node(mesh, lb, left, depth + 1, max_depth, out);
        out.nodes[here] = KdNode::inner(axis, s, out.nodes.len() as u32);
        node(mesh, rb, right, depth + 1, max_depth, out);
    }
}

/// Side of each triangle for a split: 1 = left only, 2 = right only, 3 = both (straddles).
#[inline]
pub(crate) fn classify(b: &Aabb, split: &Split) -> u8 {
    let (a, c, s) = (b.0[split.axis], b.1[split.axis], split.pos);
    if a == s && c == s {
        if split.planar_left { 1 } else { 2 }
    } else if c <= s {
        1
    } else if a >= s {
        2
    } else {
        3
    }
}

/// Bounds of triangle `id` clipped to child box `cb` (conservative fallback: its old bounds
/// intersected with the box).
#[inline]
pub(crate) fn clip(mesh: &TriangleMesh, id: u32, old: &Aabb, cb: &Aabb) -> Aabb {
    norm(clip_bounds(&tri_verts(mesh, id), cb).unwrap_or_else(|| clip_to_box(old, cb)))
}

/// Bounds intersected with a box: a conservative (looser) stand-in for exact clipping.
#[inline]
fn clip_to_box(old: &Aabb, cb: &Aabb) -> Aabb {
    let mut b = *old;
    for k in 0..3 {
        b.0[k] = b.0[k].max(cb.0[k]);
        b.1[k] = b.1[k].min(cb.1[k]).max(b.0[k]);
    }
    b
}

/// Scratch arrays of one small subtree ([`node_small`]): the triangles of the nodes on the
/// current path, each node's after its parent's (pushed before descending, truncated after).
#[derive(Default)]
pub(crate) struct SmallArena {
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
}

impl SmallArena {
    /// An arena sized for one subtree of at most [`SMALL`] triangles.
    pub(crate) fn new() -> SmallArena {
        SmallArena {
            ids: Vec::with_capacity(8 * SMALL),
            bounds: Vec::with_capacity(8 * SMALL),
        }
    }
}

/// Builds the subtree over at most [`SMALL`] triangles `ids` with (clipped) `bounds` in box `bx`:
/// each node's split is found by counting on lanes ([`split_lanes`], the split the sweep finds),
/// so no node sorts events. Straddling triangles' bounds are intersected with the child box rather
/// than clipped exactly (measured on Sibenik, exact clipping in these small nodes costs a third
/// of the build time for a 3 % lower SAH cost).
pub(crate) fn node_small(
    bx: Aabb,
    ids: &[u32],
    bounds: &[Aabb],
    depth: usize,
    max_depth: usize,
    out: &mut Flat,
    arena: &mut SmallArena,
) {
    debug_assert!(ids.len() <= SMALL && bounds.len() == ids.len());
    arena.ids.clear();
    arena.bounds.clear();
    arena.ids.extend_from_slice(ids);
    arena.bounds.extend_from_slice(bounds);
    let level = Level::current();
    small(bx, 0, ids.len(), depth, max_depth, level, out, arena);
}

/// One node of a small subtree: its triangles are `arena.ids/bounds[first..first + n]`; splits
/// are searched on lanes of `level`.
#[allow(clippy::too_many_arguments)]
fn small(
    bx: Aabb,
    first: usize,
    n: usize,
    depth: usize,
    max_depth: usize,
    level: Level,
    out: &mut Flat,
    arena: &mut SmallArena,
) {
    let split = if n == 0 || (depth > 0 && n <= LEAF_MAX) || depth >= max_depth {
        None
    } else {
        let bounds = &arena.bounds[first..first + n];
        dispatch_wide(level, LaneSplit { bounds, bx: &bx })
            .filter(|s| s.cost < COST_INTERSECT * n as f32)
    };
    let Some(split) = split else {
        out.leaf(&arena.ids[first..first + n]);
        return;
    };
    let (axis, s) = (split.axis, split.pos);
    let (lb, rb) = split_box(&bx, axis, s);
    // Classified once; the left child's triangles, then the right child's, after `mark`.
    let mark = arena.ids.len();
    let mut sides = [0u8; SMALL];
    let mut counts = [0usize; 2];
    for (sd, b) in sides.iter_mut().zip(&arena.bounds[first..first + n]) {
        *sd = classify(b, &split);
        counts[0] += (*sd & 1) as usize;
        counts[1] += (*sd >> 1) as usize;
    }
    let end = mark + counts[0] + counts[1];
    arena.ids.resize(end, 0);
    arena.bounds.resize(end, ([0.0; 3], [0.0; 3]));
    let mut at = [mark, mark + counts[0]];
    for (k, &sd) in sides[..n].iter().enumerate() {
        let (id, b) = (arena.ids[first + k], arena.bounds[first + k]);
        for (c, cb) in [(0usize, &lb), (1, &rb)] {
            if sd >> c & 1 != 0 {
                arena.ids[at[c]] = id;
                arena.bounds[at[c]] = if sd == 3 { clip_to_box(&b, cb) } else { b };
                at[c] += 1;
            }
        }
    }
    let here = out.nodes.len();
    out.nodes.push(KdNode::inner(axis, s, 0));
    small(lb, mark, counts[0], depth + 1, max_depth, level, out, arena);
    out.nodes[here] = KdNode::inner(axis, s, out.nodes.len() as u32);
    small(
        rb,
        mark + counts[0],
        counts[1],
        depth + 1,
        max_depth,
        level,
        out,
        arena,
    );
    arena.ids.truncate(mark);
    arena.bounds.truncate(mark);
}

/// Builds the work set of one child: triangles on side `me` only keep their events (filtered,
/// still sorted); straddling triangles are clipped to the child box and their new events are
/// sorted and merged in.
fn child(mesh: &TriangleMesh, w: &Work, side: &[u8], me: u8, cb: &Aabb) -> Work {
    let mut remap = vec![u32::MAX; w.ids.len()];
    let count = side.iter().filter(|&&s| s & me != 0).count();
    let mut ids = Vec::with_capacity(count);
    let mut bounds = Vec::with_capacity(count);
    let mut straddling = Vec::new();
    for (i, &s) in side.iter().enumerate() {
        if s & me == 0 {
            continue;
        }
        let local = ids.len() as u32;
        remap[i] = local;
        ids.push(w.ids[i]);
        if s == 3 {
            bounds.push(clip(mesh, w.ids[i], &w.bounds[i], cb));
            straddling.push(local);
        } else {
            bounds.push(w.bounds[i]);
        }
    }
    if count <= SMALL {
        // Built by `node_small`, which makes its own events.
        return Work {
            ids,
            bounds,
            events: Default::default(),
        };
    }
    let mut fresh = Vec::with_capacity(2 * straddling.len());
    let events = std::array::from_fn(|axis| {
        fresh.clear();
        for &l in &straddling {
            push_events(&mut fresh, &bounds[l as usize], axis, l);
        }
        fresh.sort_unstable();
        let old = &w.events[axis];
        let mut out = Vec::with_capacity(2 * (count - straddling.len()) + fresh.len());
        let mut f = 0;
        for &e in old {
            let i = (e & 0x3fff_ffff) as usize;
            if side[i] != me {
                continue;
            }
            let e = (e & !0x3fff_ffff) | remap[i] as u64;
            while f < fresh.len() && fresh[f] < e {
                out.push(fresh[f]);
                f += 1;
            }
            out.push(e);
        }
        out.extend_from_slice(&fresh[f..]);
        out
    });
    Work {
        ids,
        bounds,
        events,
    }
}

#[cfg(test)]
mod tests {
    use super::{
        AxisCost, COST_INTERSECT, LaneSplit, SMALL, Split, find_split, norm, ord, push_events,
        unord,
    };
    use crate::accel::kdtree::overlap::Aabb;
    use crate::accel::kdtree::{BuildMethod, KdTree};
    use crate::mesh::TriangleMesh;
    use crate::simd::{Level, Wide, WideKernel, dispatch_wide};

    /// Many small triangles in one corner of a large, otherwise empty box.
    fn corner_mesh() -> TriangleMesh {
        let mut v = vec![
            [0.0, 0.0, 0.0],
            [100.0, 100.0, 100.0],
            [100.0, 100.0, 100.0],
        ];
        let mut idx = vec![[0, 1, 2]]; // degenerate: only sets the bounds
        for i in 0..64 {
            let x = (i % 8) as f32;
            let y = (i / 8) as f32;
            let b = v.len() as u32;
            v.extend([[x, y, 1.0], [x + 0.9, y, 1.0], [x, y + 0.9, 1.5]]);
            idx.push([b, b + 1, b + 2]);
        }
        TriangleMesh::new(v, idx)
    }

    #[test]
    fn a_node_of_at_most_leaf_max_triangles_is_a_leaf() {
        // The corner cluster's first LEAF_MAX triangles (disjoint, in a row) in the large box:
        // the root is searched and cuts off the empty space; the node left holding them is a
        // leaf, where a search would separate them.
        let full = corner_mesh();
        let holds_all = |n: usize| {
            let mesh = TriangleMesh::new(full.vertices.clone(), full.indices[..=n].to_vec());
            let tree = KdTree::build(&mesh, BuildMethod::Sah);
            tree.validate(&mesh).expect("valid");
            assert!(!tree.nodes()[0].is_leaf(), "{n}: the root is searched");
            let all: Vec<u32> = (1..=n as u32).collect();
            (0..tree.nodes().len()).any(|i| tree.leaf_triangles(i) == all)
        };
        assert!(holds_all(super::LEAF_MAX));
        // One triangle more and the node is searched, and split.
        assert!(!holds_all(super::LEAF_MAX + 1));
    }

    #[test]
    fn ordered_bits_keep_float_order() {
        let xs = [
            f32::NEG_INFINITY,
            -3.5,
            -1e-30,
            0.0,
            1e-30,
            2.0,
            f32::INFINITY,
        ];
        for w in xs.windows(2) {
            assert!(ord(w[0]) < ord(w[1]), "{w:?}");
        }
        for x in xs {
            assert_eq!(unord(ord(x)).to_bits(), x.to_bits());
        }
    }

    #[test]
    fn cuts_off_empty_space_first() {
        let mesh = corner_mesh();
        let tree = KdTree::build(&mesh, BuildMethod::Sah);
        tree.validate(&mesh).expect("valid");
        let root = tree.nodes()[0];
        assert!(!root.is_leaf());
        // The first plane bounds the cluster (x, y < 8; z in [1, 1.5]).
        assert!(root.split() <= 8.0, "split at {}", root.split());
        let s = tree.stats(&mesh);
        assert!(s.leaves > 8 && s.max_tris_per_leaf < 16, "{s}");
        // The degenerate triangle is in no leaf.
        assert!((0..tree.nodes().len()).all(|i| !tree.leaf_triangles(i).contains(&0)));
    }

    #[test]
    fn triangles_touching_or_lying_in_the_plane_go_to_one_side() {
        // Two stacked layers of axis-aligned squares at z = 0 and z = 1 with a gap between
        // them; each square is two triangles. The planes at z = 0 and z = 1 hold planar
        // triangles, which must not be duplicated.
        let mut v = Vec::new();
        let mut idx = Vec::new();
        for layer in 0..2 {
            for i in 0..16 {
                let (x, y, z) = ((i % 4) as f32 * 2.0, (i / 4) as f32 * 2.0, layer as f32);
                let b = v.len() as u32;
                v.extend([
                    [x, y, z],
                    [x + 1.0, y, z],
                    [x + 1.0, y + 1.0, z],
                    [x, y + 1.0, z],
                ]);
                idx.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
            }
        }
        let mesh = TriangleMesh::new(v, idx);
        let tree = KdTree::build(&mesh, BuildMethod::Sah);
        tree.validate(&mesh).expect("valid");
        let s = tree.stats(&mesh);
        assert!(s.references <= mesh.len() + mesh.len() / 4, "{s}");
    }

    /// A small generator of test values (xorshift).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }

        /// One of `steps` grid values in `[lo, lo + steps / 4)`: coarse, so faces coincide and
        /// costs tie.
        fn grid(&mut self, lo: f32, steps: u64) -> f32 {
            lo + (self.next() % steps) as f32 * 0.25
        }
    }

    /// Bounds of `n` triangles in the box `[-1, 3]³`, many flat (planar events), many sharing
    /// faces, some touching the box faces or lying in them; one of them (`-0.0`) on a grid value.
    fn small_node(rng: &mut Rng, n: usize) -> (Aabb, Vec<Aabb>) {
        let bx = ([-1.0; 3], [3.0; 3]);
        let bounds = (0..n)
            .map(|_| {
                let mut b = ([0.0; 3], [0.0; 3]);
                for k in 0..3 {
                    let (a, c) = (rng.grid(-1.0, 17), rng.grid(-1.0, 17));
                    let flat = rng.next().is_multiple_of(4);
                    b.0[k] = a.min(c);
                    b.1[k] = if flat { b.0[k] } else { a.max(c) };
                    if b.0[k] == 0.0 && rng.next().is_multiple_of(2) {
                        b.0[k] = -0.0;
                    }
                }
                b
            })
            .collect();
        (bx, bounds)
    }

    #[test]
    fn counting_planes_finds_the_split_the_event_sweep_finds_on_every_width() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut planar_right = 0;
        for round in 0..3000 {
            let n = 1 + round % SMALL;
            let (bx, bounds) = small_node(&mut rng, n);
            let events: [Vec<u64>; 3] = std::array::from_fn(|axis| {
                let mut ev = Vec::new();
                for (i, b) in bounds.iter().enumerate() {
                    push_events(&mut ev, &norm(*b), axis, i as u32);
                }
                ev.sort_unstable();
                ev
            });
            let [e0, e1, e2] = &events;
            let want = find_split(n, [e0, e1, e2], &bx);
            planar_right += want.is_some_and(|s| !s.planar_left) as usize;
            for level in Level::supported() {
                let got = dispatch_wide(
                    level,
                    LaneSplit {
                        bounds: &bounds,
                        bx: &bx,
                    },
                );
                let key = |s: Option<Split>| {
                    s.map(|s| (s.cost.to_bits(), s.axis, s.pos.to_bits(), s.planar_left))
                };
                assert_eq!(key(got), key(want), "{level:?}, round {round}: {bounds:?}");
            }
        }
        // The planar triangles' side was decided both ways.
        assert!(planar_right > 10, "{planar_right}");
    }

    /// [`AxisCost::cost_lanes`] of the planes `p` with counts `l`, `r` (one batch of lanes).
    struct Costs<'a> {
        cost: AxisCost,
        p: &'a [f32],
        l: &'a [f32],
        r: &'a [f32],
    }

    impl WideKernel for Costs<'_> {
        type Output = Vec<f32>;
        #[inline(always)]
        fn run<V: Wide>(self) -> Vec<f32> {
            let mut out = vec![0.0; V::LANES];
            let (p, l, r) = (V::load(self.p), V::load(self.l), V::load(self.r));
            self.cost.cost_lanes(p, l, r).store(&mut out);
            out
        }
    }

    #[test]
    fn plane_costs_on_lanes_have_the_scalar_bits() {
        let mut rng = Rng(12345);
        let mut bonuses = 0;
        for _ in 0..500 {
            let lo = rng.grid(-4.0, 9);
            let hi = lo + 0.25 + rng.grid(0.0, 40);
            let bx = ([lo, -1.0, 0.5], [hi, 2.0 + rng.grid(0.0, 5), 0.75]);
            let ext = [0, 1, 2].map(|k| bx.1[k] - bx.0[k]);
            let sa = 2.0 * (ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0]);
            let cost = AxisCost::new(&bx, ext, 0, COST_INTERSECT / sa).expect("not flat");
            // Planes all over the box, near its faces too (inside the empty-space minimum).
            let p: Vec<f32> = (0..16)
                .map(|k| match k % 4 {
                    0 => lo + (hi - lo) * 0.01,
                    1 => hi - (hi - lo) * 0.01,
                    _ => lo + (hi - lo) * (rng.next() % 1000) as f32 / 1000.0,
                })
                .collect();
            let l: Vec<f32> = (0..16).map(|_| (rng.next() % 5) as f32).collect();
            let r: Vec<f32> = (0..16).map(|_| (rng.next() % 5) as f32).collect();
            for level in Level::supported() {
                let got = dispatch_wide(
                    level,
                    Costs {
                        cost,
                        p: &p,
                        l: &l,
                        r: &r,
                    },
                );
                for (k, g) in got.iter().enumerate() {
                    let want = cost.cost(p[k], l[k] as usize, r[k] as usize);
                    assert_eq!(g.to_bits(), want.to_bits(), "{level:?} lane {k}");
                    let plain = cost.cost(p[k], 1, 1);
                    bonuses += (l[k] == 0.0 || r[k] == 0.0) as usize * (want < plain) as usize;
                }
            }
        }
        assert!(
            bonuses > 100,
            "the empty-space bonus was taken {bonuses} times"
        );
    }

    #[test]
    fn build_of_a_small_mesh_is_deterministic_across_thread_counts() {
        let mesh = corner_mesh();
        let a = KdTree::build(&mesh, BuildMethod::Sah);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool");
        let b = pool.install(|| KdTree::build(&mesh, BuildMethod::Sah));
        assert_eq!(a, b);
    }
}
