//! Parallel binned SAH for the upper levels of the SAH tree (Shevtsov, Soupikov & Kapustin 2007;
//! Wald 2007), the exact event sweep of [`super::build_sah`] below [`EXACT_MAX`] triangles.
//!
//! A node with more than [`EXACT_MAX`] triangles counts, per axis, how many triangle bounds start
//! and end in each of [`BINS`] equal bins of the node box (a rayon fold over chunks of triangles,
//! reduced by integer addition, so the counts and hence the chosen plane do not depend on the
//! thread count), evaluates the SAH (same costs and empty-space bonus as the exact sweep) at the
//! `BINS − 1` bin boundaries, and splits there. Triangles are classified exactly against the
//! chosen plane; straddling triangles are clipped to each child box (exact clipping, as the
//! exact builder does). Children are built with `rayon::join` and joined in left-right order,
//! so the tree is the same on any number of threads. When binning finds no split cheaper than
//! a leaf, the node goes to the exact sweep, which decides.
//!
//! Reads mesh vertices and triangle indices; writes nodes in depth-first pre-order ([`Flat`]).

use rayon::prelude::*;

use super::build_sah::{self, AxisCost, Flat, clip, tri_bounds};
use super::node::KdNode;
use super::overlap::Aabb;
use super::{COST_INTERSECT, split_box};
use crate::mesh::TriangleMesh;

/// Bins per axis.
pub(crate) const BINS: usize = 32;
/// Nodes with at most this many triangles are built by the exact sweep.
pub(crate) const EXACT_MAX: usize = 8192;
/// Triangles per rayon task when binning and partitioning.
const CHUNK: usize = 4096;

/// The builder's own constants, for [`super::builder_settings`].
pub(crate) const SETTINGS: &str = "binned 32 above 8192";

/// Builds the SAH tree over `tris` (non-degenerate triangle indices) in box `root`.
pub(crate) fn build(mesh: &TriangleMesh, root: Aabb, tris: Vec<u32>) -> Flat {
    assert!(
        tris.len() < 1 << 30,
        "too many triangles for the SAH builder"
    );
    let max_depth = build_sah::max_depth(tris.len());
    let bounds: Vec<Aabb> = tris
        .par_iter()
        .with_min_len(CHUNK)
        .map(|&t| tri_bounds(mesh, t))
        .collect();
    let mut out = Flat::default();
    node(mesh, root, tris, bounds, 0, max_depth, &mut out);
    out
}

/// Start and end counts per bin and axis.
#[derive(Clone)]
struct Bins {
    start: [[u32; BINS]; 3],
    end: [[u32; BINS]; 3],
}

impl Bins {
    fn zero() -> Bins {
        Bins {
            start: [[0; BINS]; 3],
            end: [[0; BINS]; 3],
        }
    }

    fn add(mut self, other: Bins) -> Bins {
        for a in 0..3 {
            for i in 0..BINS {
                self.start[a][i] += other.start[a][i];
                self.end[a][i] += other.end[a][i];
            }
        }
        self
    }
}

/// Bin of coordinate `x` on an axis starting at `lo` with `scale = BINS / extent`.
#[inline]
fn bin(x: f32, lo: f32, scale: f32) -> usize {
    (((x - lo) * scale) as isize).clamp(0, BINS as isize - 1) as usize
}

/// The best bin-boundary split: `(cost, axis, position)`.
fn find_split(bx: &Aabb, bounds: &[Aabb]) -> Option<(f32, usize, f32)> {
    let ext = [bx.1[0] - bx.0[0], bx.1[1] - bx.0[1], bx.1[2] - bx.0[2]];
    let sa = 2.0 * (ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0]);
    if sa.is_nan() || sa <= 0.0 {
        return None;
    }
    let scale = ext.map(|e| if e > 0.0 { BINS as f32 / e } else { 0.0 });
    let bins = bounds
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut b = Bins::zero();
            for t in chunk {
                for (a, &sc) in scale.iter().enumerate() {
                    b.start[a][bin(t.0[a], bx.0[a], sc)] += 1;
                    b.end[a][bin(t.1[a], bx.0[a], sc)] += 1;
                }
            }
            b
        })
        .reduce(Bins::zero, Bins::add);
    let n = bounds.len();
    let ki = COST_INTERSECT / sa;
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        let Some(axis_cost) = AxisCost::new(bx, ext, axis, ki) else {
            continue;
        };
        let (lo, hi) = (axis_cost.lo, axis_cost.hi);
        // Plane i lies between bins i-1 and i: left = bounds starting below it, right = bounds
        // ending at or above it.
        let (mut nl, mut nr) = (0usize, n);
        for i in 1..BINS {
            nl += bins.start[axis][i - 1] as usize;
            nr -= bins.end[axis][i - 1] as usize;
            let p = lo + (hi - lo) * (i as f32 / BINS as f32);
            if !(p > lo && p < hi) {
                continue;
            }
            let c = axis_cost.cost(p, nl, nr);
            if best.is_none_or(|b| c < b.0) {
                best = Some((c, axis, p));
            }
        }
    }
    best
}

/// Side of a triangle's bounds for the plane `s` on `axis`: 1 = left, 2 = right, 3 = both.
/// Bounds lying in the plane go left.
#[inline]
fn classify(b: &Aabb, axis: usize, s: f32) -> u8 {
    let (a, c) = (b.0[axis], b.1[axis]);
    if c <= s {
        1
    } else if a >= s {
        2
    } else {
        3
    }
}

/// The triangles of one child: those on side `me`, straddlers clipped to `cb` (chunks filtered
/// in parallel, concatenated in order).
fn child(
    mesh: &TriangleMesh,
    ids: &[u32],
    bounds: &[Aabb],
    side: &[u8],
    me: u8,
    cb: &Aabb,
) -> (Vec<u32>, Vec<Aabb>) {
    let part = |start: usize| {
        let end = (start + CHUNK).min(ids.len());
        let mut out_ids = Vec::with_capacity(end - start);
        let mut out_bounds = Vec::with_capacity(end - start);
        for i in start..end {
            let s = side[i];
            if s & me != 0 {
                out_ids.push(ids[i]);
                out_bounds.push(if s == 3 {
                    clip(mesh, ids[i], &bounds[i], cb)
                } else {
                    bounds[i]
                });
            }
        }
        (out_ids, out_bounds)
    };
    if ids.len() <= CHUNK {
        return part(0);
    }
    let parts: Vec<(Vec<u32>, Vec<Aabb>)> = (0..ids.len().div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| part(c * CHUNK))
        .collect();
    let total = parts.iter().map(|p| p.0.len()).sum();
    let (mut out_ids, mut out_bounds) = (Vec::with_capacity(total), Vec::with_capacity(total));
    for (i, b) in parts {
        out_ids.extend_from_slice(&i);
        out_bounds.extend_from_slice(&b);
    }
    (out_ids, out_bounds)
}

/// Builds the subtree over `ids` (with clipped `bounds`) in box `bx`, appending it to `out`.
fn node(
    mesh: &TriangleMesh,
    bx: Aabb,
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
    depth: usize,
    max_depth: usize,
    out: &mut Flat,
) {
    let n = ids.len();
    let split = if n <= EXACT_MAX || depth >= max_depth {
        None
    } else {
        find_split(&bx, &bounds).filter(|s| s.0 < COST_INTERSECT * n as f32)
    };
    let Some((_, axis, s)) = split else {
        build_sah::subtree(mesh, bx, ids, bounds, depth, max_depth, out);
        return;
    };
    let (lb, rb) = split_box(&bx, axis, s);
    let side: Vec<u8> = bounds
        .par_iter()
        .with_min_len(CHUNK)
        .map(|b| classify(b, axis, s))
        .collect();
    let ((lids, lbounds), (rids, rbounds)) = rayon::join(
        || child(mesh, &ids, &bounds, &side, 1, &lb),
        || child(mesh, &ids, &bounds, &side, 2, &rb),
    );
    drop((ids, bounds, side));
    let here = out.nodes.len();
    out.nodes.push(KdNode::inner(axis, s, 0));
    let mut sub = Flat::default();
    rayon::join(
        || node(mesh, lb, lids, lbounds, depth + 1, max_depth, out),
        || node(mesh, rb, rids, rbounds, depth + 1, max_depth, &mut sub),
    );
    out.nodes[here] = KdNode::inner(axis, s, out.nodes.len() as u32);
    out.append(sub);
}
