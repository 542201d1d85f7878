//! Surface-area-heuristic builder in O(N log N) (Wald & Havran 2006, "On building fast kd-trees
//! for ray tracing, and on doing that in O(N log N)").
//!
//! Each node carries its triangles' bounds clipped to the node box and, per axis, the split
//! events (end / planar / start) sorted once at the root and kept sorted by filtering and merging
//! on the way down; nodes of at most [`SMALL`] triangles regenerate and sort their events instead
//! (cheaper at that size) and bound straddling triangles by box intersection rather than exact
//! clipping. A sweep per axis finds the cheapest plane; empty space gets a bonus; a node
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

/// Cost factor applied when one side of a split is empty (20 % empty-space bonus).
pub(crate) const EMPTY_FACTOR: f32 = 0.8;
/// Smallest empty slab (as a fraction of the node's extent on the split axis) that earns the
/// bonus, so that thin slivers of empty space are not cut off for nothing.
pub(crate) const EMPTY_MIN_FRACTION: f32 = 0.02;
/// Nodes with more triangles than this build their children in parallel.
const PARALLEL_MIN: usize = 4096;
/// Nodes with at most this many triangles are built by [`node_small`]: events are regenerated
/// and sorted per node in one reused scratch buffer instead of being filtered and merged, and
/// children's triangles live on the stack, so a small subtree makes one heap allocation.
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
}

fn find_split(n: usize, events: [&[u64]; 3], bx: &Aabb) -> Option<Split> {
    let ext = [bx.1[0] - bx.0[0], bx.1[1] - bx.0[1], bx.1[2] - bx.0[2]];
    let sa = 2.0 * (ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0]);
    if sa.is_nan() || sa <= 0.0 {
        return None;
    }
    let ki = COST_INTERSECT / sa;
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

/// Scratch arrays of one small subtree ([`node_small`]): the triangles and events of the nodes on
/// the current path, each node's after its parent's (pushed before descending, truncated after).
#[derive(Default)]
pub(crate) struct SmallArena {
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
    events: Vec<u64>,
}

impl SmallArena {
    /// An arena sized for one subtree of at most [`SMALL`] triangles.
    pub(crate) fn new() -> SmallArena {
        SmallArena {
            ids: Vec::with_capacity(8 * SMALL),
            bounds: Vec::with_capacity(8 * SMALL),
            events: Vec::with_capacity(48 * SMALL),
        }
    }
}

/// Builds the subtree over at most [`SMALL`] triangles `ids` with (clipped) `bounds` in box `bx`:
/// sorts their events once, then hands each child its parent's events filtered in order, so no
/// node below sorts. Straddling triangles' bounds are intersected with the child box rather
/// than clipped exactly (measured on Sibenik, exact clipping in these small nodes costs a third
/// of the build time for a 3 % lower SAH cost); that moves only their bound on the split axis,
/// to the plane, which is the last position of the left child's events and the first of the
/// right child's, so the filtered lists stay sorted by position (all the sweep needs).
#[allow(clippy::too_many_arguments)]
pub(crate) fn node_small(
    bx: Aabb,
    ids: &[u32],
    bounds: &[Aabb],
    depth: usize,
    max_depth: usize,
    out: &mut Flat,
    arena: &mut SmallArena,
) {
    let n = ids.len();
    debug_assert!(n <= SMALL && bounds.len() == n);
    arena.ids.clear();
    arena.bounds.clear();
    arena.events.clear();
    arena.ids.extend_from_slice(ids);
    arena.bounds.extend_from_slice(bounds);
    let mut ranges = [(0usize, 0usize); 3];
    for (axis, range) in ranges.iter_mut().enumerate() {
        let start = arena.events.len();
        for (i, b) in bounds.iter().enumerate() {
            push_events(&mut arena.events, b, axis, i as u32);
        }
        arena.events[start..].sort_unstable();
        *range = (start, arena.events.len());
    }
    small(bx, 0, n, ranges, depth, max_depth, out, arena);
}

/// One node of a small subtree: its triangles are `arena.ids/bounds[first..first + n]`, its
/// sorted events per axis `arena.events[ranges[axis]]` (indices local to the node).
#[allow(clippy::too_many_arguments)]
fn small(
    bx: Aabb,
    first: usize,
    n: usize,
    ranges: [(usize, usize); 3],
    depth: usize,
    max_depth: usize,
    out: &mut Flat,
    arena: &mut SmallArena,
) {
    let split = if n == 0 || (depth > 0 && n <= LEAF_MAX) || depth >= max_depth {
        None
    } else {
        let ev = &arena.events;
        let [a, b, c] = ranges;
        find_split(n, [&ev[a.0..a.1], &ev[b.0..b.1], &ev[c.0..c.1]], &bx)
            .filter(|s| s.cost < COST_INTERSECT * n as f32)
    };
    let Some(split) = split else {
        out.leaf(&arena.ids[first..first + n]);
        return;
    };
    let (axis, s) = (split.axis, split.pos);
    let (lb, rb) = split_box(&bx, axis, s);
    // Per triangle: its side in bits 0-1 and its index in the left and right child in bits
    // 8-15 and 16-23 (local indices fit in 6 bits), so filtering an event reads one word.
    let mut info = [0u32; SMALL];
    let (ids_mark, ev_mark) = (arena.ids.len(), arena.events.len());
    let mut counts = [0usize; 2];
    for (c, cb) in [(0usize, &lb), (1, &rb)] {
        let me = 1u8 << c;
        for (i, x) in info[..n].iter_mut().enumerate() {
            let b = arena.bounds[first + i];
            let sd = if c == 0 {
                let sd = classify(&b, &split);
                *x = sd as u32;
                sd
            } else {
                *x as u8 & 3
            };
            if sd & me != 0 {
                *x |= (counts[c] as u32) << (8 + 8 * c);
                counts[c] += 1;
                let id = arena.ids[first + i];
                arena.ids.push(id);
                arena
                    .bounds
                    .push(if sd == 3 { clip_to_box(&b, cb) } else { b });
            }
        }
    }
    let straddlers = info[..n].iter().filter(|&&x| x & 3 == 3).count();
    let at = |e: u64, l: u32| (e & !0x3fff_ffff) | l as u64;
    let mut child_ranges = [[(0usize, 0usize); 3]; 2];
    for (a, range) in ranges.iter().enumerate() {
        // Both children's lists in one pass: room for every event and the straddlers' re-made
        // ones on each side; each event is written to both, and each write position advances
        // only for kept ones (without branching on the side, which is unpredictable).
        let len = range.1 - range.0;
        let split_axis = a == axis;
        let base_l = arena.events.len();
        let base_r = base_l + len + straddlers;
        arena.events.resize(base_r + len + straddlers, 0);
        let (src, dst) = arena.events.split_at_mut(base_l);
        let src = &src[range.0..range.1];
        let (mut kl, mut kr) = (0usize, len + straddlers);
        if split_axis {
            // Straddlers start at the plane, before every other event of the right child.
            for &x in &info[..n] {
                if x & 3 == 3 {
                    dst[kr] = event(s, START, (x >> 16) & 0xff);
                    kr += 1;
                }
            }
        }
        for &e in src {
            let x = info[(e & 0x3fff_ffff) as usize];
            let kind = (e >> 30) & 3;
            let straddles = split_axis & (x & 3 == 3);
            // A straddler's end goes from the left child and its start from the right child:
            // both are re-made at the plane.
            let keep_l = (x & 1 != 0) & !(straddles & (kind == END));
            let keep_r = (x & 2 != 0) & !(straddles & (kind == START));
            dst[kl] = at(e, (x >> 8) & 0xff);
            kl += keep_l as usize;
            dst[kr] = at(e, (x >> 16) & 0xff);
            kr += keep_r as usize;
        }
        if split_axis {
            // Straddlers end at the plane, after every other event of the left child.
            for &x in &info[..n] {
                if x & 3 == 3 {
                    dst[kl] = event(s, END, (x >> 8) & 0xff);
                    kl += 1;
                }
            }
        }
        child_ranges[0][a] = (base_l, base_l + kl);
        child_ranges[1][a] = (base_r, base_l + kr);
    }
    let here = out.nodes.len();
    out.nodes.push(KdNode::inner(axis, s, 0));
    small(
        lb,
        ids_mark,
        counts[0],
        child_ranges[0],
        depth + 1,
        max_depth,
        out,
        arena,
    );
    out.nodes[here] = KdNode::inner(axis, s, out.nodes.len() as u32);
    small(
        rb,
        ids_mark + counts[0],
        counts[1],
        child_ranges[1],
        depth + 1,
        max_depth,
        out,
        arena,
    );
    arena.ids.truncate(ids_mark);
    arena.bounds.truncate(ids_mark);
    arena.events.truncate(ev_mark);
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
    use super::{ord, unord};
    use crate::accel::kdtree::{BuildMethod, KdTree};
    use crate::mesh::TriangleMesh;

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
