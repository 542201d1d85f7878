//! Wide packets of rays ("frusta"): camera rays regrouped into screen tiles and traced [`WIDE`]
//! at a time, 8 lanes per SIMD step (AVX2 and portable) or 16 (AVX-512).
//!
//! Reads the tree's nodes, the accelerator's leaf-ordered triangles and root box, and a batch of
//! rays (origin, direction, `t_max` columns); writes each ray's closest hit into the output
//! columns, row for row (the rays are regrouped for tracing, never the output).
//!
//! **Regrouping** ([`KdAccel::closest_frusta`]). Rays are keyed by their watertight test's axis
//! permutation (6 cases) and by their shear `(d[kx]/d[kz], d[ky]/d[kz])`, the ray's point on a
//! plane perpendicular to its dominant axis: for a pinhole camera, a projective image of its
//! pixel position. A grid over each permutation's shear bounds, with about [`WIDE`] rays per
//! cell, is a grid of screen tiles (an 8 × 8 pixel tile at one sample per pixel for a chunk of 8
//! image rows); a counting sort orders the rays tile by tile (queue order inside a tile) and runs
//! of [`WIDE`] consecutive rays become one frustum. Rays whose direction the watertight test
//! rejects go one by one. A batch from many origins (mirror reflections: the rays of a screen
//! tile reflected by one plane leave from a small patch of it) goes the same way while its
//! frusta's origins stay close together ([`MAX_SPREAD`](super::route::MAX_SPREAD), measured over the batch's first two
//! frusta); otherwise the caller traces it as 4-ray packets. On several threads
//! ([`KdAccel::closest_frusta_par`]) the batch is regrouped in pieces of the intersect stage's
//! chunk size (the tiles a one-thread render traces), the frusta go to the threads a few at a
//! time, their answers into a buffer in tracing order, then back to their rows.
//!
//! **Traversal** ([`KdAccel::walk_frustum`]). One node fetch per frustum; whole-frustum culling
//! through the lane mask (a node no lane enters is never fetched, a group of lanes none of which
//! is live is skipped, 8 or 16 lanes at a time); the entry point of every frustum is found once:
//! interval arithmetic over the frustum (the box of the origins, the lanes' bounds of `1/d`, `δ`
//! and interval ends) proves, node by node from the root, that every lane goes to the same one
//! child with its interval unchanged, so those nodes cost a few scalar operations for all
//! [`WIDE`] rays and no lane work. Elsewhere every lane takes exactly the single-ray step
//! ([`super::interval::step`] over the `V` lanes), visits its
//! leaves in the single ray's order and culls with its own best hit, so answers are bit-identical
//! to [`KdAccel::intersect_closest`]. Where at most [`SOLO`](super::route::SOLO) lanes are left, they go on one by
//! one through the single-ray loop from their own intervals and best hits. Lanes agree on the
//! near child (the origin's side) unless their origins lie on both sides of the plane (or on it,
//! with opposite direction signs); there each lane's children are oriented left/right and the
//! lowest live lane's near side goes first. That order changes no answer: a lane still visits
//! every leaf that starts before its best hit (culling skips only entries beyond it), so it meets
//! the leaf holding its closest hit, and it keeps the least `(t, index)` of what it tests, as the
//! single ray does. For the same reason a child that is an empty leaf is neither entered nor
//! pushed: it holds nothing to test, so skipping it changes no lane's answer.
//!
//! **Triangles**: one triangle against a group of lanes with the watertight test's operations in
//! the scalar order, lanes on an edge retested with the scalar code (its double-precision
//! fallback).

use glam::Vec3;

use super::KdAccel;
use super::interval::{DELTA, HI, step};
use super::ray::Ray;
use super::route::{self, Loop, Origins};
use super::single::Entry;
use super::visit::{Closest, Visitor};
use crate::accel::kdtree::{MAX_DEPTH, TriHit};
use crate::geometry::triangle::{WatertightLanes, WatertightRay};
use crate::simd::{Level, Wide, WideKernel, dispatch_wide, max_ps, min_ps};
use rayon::prelude::*;

/// Rays per frustum: an 8 × 8 pixel tile at one sample per pixel.
pub(super) const WIDE: usize = 64;

/// Stack entries of a frustum: one per tree level.
const STACK: usize = MAX_DEPTH + 1;

/// One pending node of a frustum: its lanes' intervals, the node and the lanes that enter it.
#[repr(C, align(64))]
#[derive(Clone, Copy)]
struct WideEntry {
    /// Start of each lane's interval inside the node.
    t0: [f32; WIDE],
    /// End of each lane's interval inside the node.
    t1: [f32; WIDE],
    /// Node index.
    node: u32,
    /// Lanes that enter the node (bit `k` = lane `k`).
    mask: u64,
    /// Lower bound of `t0` over the live lanes (interval arithmetic).
    lo: f32,
    /// Upper bound of `t1` over the live lanes.
    hi: f32,
}

impl Default for WideEntry {
    fn default() -> WideEntry {
        WideEntry {
            t0: [0.0; WIDE],
            t1: [0.0; WIDE],
            node: 0,
            mask: 0,
            lo: 0.0,
            hi: 0.0,
        }
    }
}

/// A frustum's rays, structure-of-arrays, and each lane's closest-hit state.
struct Frustum {
    /// Origins per axis and lane (the 4th axis pads for the 2-bit axis index).
    org: [[f32; WIDE]; 4],
    /// Interval-arithmetic bounds of the live lanes' origins, per axis.
    org_lo: [f32; 4],
    /// See `org_lo`.
    org_hi: [f32; 4],
    /// `1 / d` per axis and lane (4th axis pads).
    inv: [[f32; WIDE]; 4],
    /// Per-axis `δ` slack in `t` units, per lane.
    slack: [[f32; WIDE]; 4],
    /// Interval-arithmetic bounds over the live lanes, per axis: `1/d` low and high, `δ` high.
    inv_lo: [f32; 4],
    /// See `inv_lo`.
    inv_hi: [f32; 4],
    /// See `inv_lo`.
    slack_hi: [f32; 4],
    /// The watertight test's shared axis permutation (`kx`, `ky`, `kz`).
    k: [usize; 3],
    /// Shears `sx`, `sy`, `sz` per lane.
    sx: [f32; WIDE],
    /// See `sx`.
    sy: [f32; WIDE],
    /// See `sx`.
    sz: [f32; WIDE],
    /// Directions (for the single-ray fallbacks).
    dir: [Vec3; WIDE],
    /// Each lane's `t_max`.
    t_max: [f32; WIDE],
    /// Best hit distance (`∞` before any hit).
    best_t: [f32; WIDE],
    /// Best hit's triangle (`u32::MAX` before any hit).
    best_tri: [u32; WIDE],
    /// The bound the next triangle is tested with (`Closest::limit`).
    limit: [f32; WIDE],
    /// Cull distance (`Closest::cull`).
    cull: [f32; WIDE],
}

/// Scratch space of a batch of frusta, allocated once per batch.
pub(super) struct FrustumScratch {
    /// The frustum being traced.
    f: Frustum,
    /// Pending far children.
    stack: [WideEntry; STACK],
    /// Step outputs (near `t1`, far `t0`, far `t1`).
    tmp: [[f32; WIDE]; 3],
    /// Per-ray sort key, then the rays in tracing order.
    key: Vec<u32>,
    /// Rays in tracing order.
    order: Vec<u32>,
    /// Each ray's shear, roughly (for the tiling only).
    shear: Vec<[f32; 2]>,
    /// Where each frustum's run of `order` starts, then the batch's length (parallel batches).
    runs: Vec<u32>,
    /// Hit distances in tracing order (parallel batches).
    buf_t: Vec<f32>,
    /// Hit triangles in tracing order (parallel batches).
    buf_tri: Vec<u32>,
}

impl FrustumScratch {
    /// Empty scratch space (on the heap: about 45 KiB).
    pub(super) fn new() -> Box<FrustumScratch> {
        Box::new(FrustumScratch {
            f: Frustum {
                org: [[0.0; WIDE]; 4],
                org_lo: [0.0; 4],
                org_hi: [0.0; 4],
                inv: [[0.0; WIDE]; 4],
                slack: [[0.0; WIDE]; 4],
                inv_lo: [0.0; 4],
                inv_hi: [0.0; 4],
                slack_hi: [0.0; 4],
                k: [0, 1, 2],
                sx: [0.0; WIDE],
                sy: [0.0; WIDE],
                sz: [0.0; WIDE],
                dir: [Vec3::ZERO; WIDE],
                t_max: [0.0; WIDE],
                best_t: [0.0; WIDE],
                best_tri: [0; WIDE],
                limit: [0.0; WIDE],
                cull: [0.0; WIDE],
            },
            stack: [WideEntry::default(); STACK],
            tmp: [[0.0; WIDE]; 3],
            key: Vec::new(),
            order: Vec::new(),
            shear: Vec::new(),
            runs: Vec::new(),
            buf_t: Vec::new(),
            buf_tri: Vec::new(),
        })
    }
}

thread_local! {
    /// Each thread's spare scratch spaces, reused by every batch and work item it traces (two
    /// at most: a batch traced on several threads holds one while its work items on the same
    /// thread use another).
    static SCRATCH: std::cell::RefCell<Vec<Box<FrustumScratch>>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// A spare scratch space of this thread (a new one if it has none). Taken out and put back
/// ([`put_scratch`]) rather than used inside `with_borrow_mut`: a closure would be compiled
/// apart from the caller, without its SIMD level.
pub(super) fn take_scratch() -> Box<FrustumScratch> {
    SCRATCH
        .with_borrow_mut(Vec::pop)
        .unwrap_or_else(FrustumScratch::new)
}

/// Gives a scratch space back to this thread's spares (see [`take_scratch`]).
pub(super) fn put_scratch(scratch: Box<FrustumScratch>) {
    SCRATCH.with_borrow_mut(|spare| {
        if spare.len() < 2 {
            spare.push(scratch);
        }
    });
}

/// Frusta per work item of a batch traced on several threads: many more items than threads, so
/// they end together, each a few tens of microseconds.
const RUNS_PER_ITEM: usize = 4;

/// Rays regrouped together when a batch is traced on several threads: the intersect stage's
/// chunk on one thread, so that the frusta are the tiles a render traces.
const PIECE: usize = crate::queue::TRACE_CHUNK;

/// Rays from which a closest-hit batch is traced on all the threads of the current rayon pool
/// ([`KdAccel::closest_frusta_par`]) when it has more than one.
pub(super) const PAR_MIN: usize = 16 * WIDE;

/// Frustum runs `runs[0]..runs[last]` of a regrouped batch traced as one [`Kernel`] (compiled
/// per SIMD level); answers go to `out_*` in tracing order, from `runs[0]`.
struct Runs<'a> {
    /// The accelerator.
    accel: &'a KdAccel,
    /// All the batch's origins.
    origins: &'a [Vec3],
    /// All the batch's directions.
    dirs: &'a [Vec3],
    /// All the batch's bounds.
    t_max: &'a [f32],
    /// Rays in tracing order.
    order: &'a [u32],
    /// Per-ray sort keys (`>> 24`: permutation).
    key: &'a [u32],
    /// Starts of the runs, then the end of the last.
    runs: &'a [u32],
    /// Hit distances out, tracing order.
    out_t: &'a mut [f32],
    /// Hit triangles out, tracing order.
    out_tri: &'a mut [u32],
}

impl WideKernel for Runs<'_> {
    type Output = ();

    #[inline(always)]
    fn run<V: Wide>(self) {
        let Runs {
            accel,
            origins,
            dirs,
            t_max,
            order,
            key,
            runs,
            out_t,
            out_tri,
        } = self;
        let mut scratch = take_scratch();
        let FrustumScratch { f, stack, tmp, .. } = &mut *scratch;
        let base = runs[0] as usize;
        for w in runs.windows(2) {
            let (i, end) = (w[0] as usize, w[1] as usize);
            let rows = &order[i..end];
            let (t, tri) = (
                &mut out_t[i - base..end - base],
                &mut out_tri[i - base..end - base],
            );
            let perm = key[rows[0] as usize] >> 24;
            if perm >= 6 {
                for (k, &r) in rows.iter().enumerate() {
                    let r = r as usize;
                    (t[k], tri[k]) = accel.single_closest(origins[r], dirs[r], t_max[r]);
                }
                continue;
            }
            let rays = Rows {
                origins,
                perm,
                dirs,
                t_max,
                rows,
            };
            accel.frustum::<V>(&rays, t, tri, true, f, stack, tmp);
        }
        put_scratch(scratch);
    }
}

/// A run of rays sharing origin `o` and watertight permutation `perm`, traced as one frustum.
struct Rows<'a> {
    /// All the batch's origins.
    origins: &'a [Vec3],
    /// Permutation: `2·kz + (d[kz] < 0)`.
    perm: u32,
    /// All the batch's directions.
    dirs: &'a [Vec3],
    /// All the batch's bounds.
    t_max: &'a [f32],
    /// The rows of this frustum (at most [`WIDE`]).
    rows: &'a [u32],
}

/// The smallest lane of `x` (`minps` semantics; the bounds below hold no NaN).
#[inline(always)]
fn lowest<V: Wide>(x: V) -> f32 {
    let mut a = [0.0f32; 16];
    x.store(&mut a);
    a[..V::LANES]
        .iter()
        .fold(f32::INFINITY, |m, &v| min_ps(v, m))
}

/// The largest lane of `x` (see [`lowest`]).
#[inline(always)]
fn highest<V: Wide>(x: V) -> f32 {
    let mut a = [0.0f32; 16];
    x.store(&mut a);
    a[..V::LANES]
        .iter()
        .fold(f32::NEG_INFINITY, |m, &v| max_ps(v, m))
}

/// Lanes where `x` is finite (`x − x` is zero exactly there).
#[inline(always)]
fn finite<V: Wide>(x: V) -> V::Mask {
    V::eq(x.sub(x), V::splat(0.0))
}

/// `f32::min` per lane: the other operand where one is NaN, else the smaller.
#[inline(always)]
fn min_num<V: Wide>(a: V, b: V) -> V {
    V::select(V::eq(a, a), b.min(a), b)
}

/// `f32::max` per lane: the other operand where one is NaN, else the larger.
#[inline(always)]
fn max_num<V: Wide>(a: V, b: V) -> V {
    V::select(V::eq(a, a), b.max(a), b)
}

/// Bits of the lanes `k` of `mask` with `t0[k] <= cull[k]` (a NaN `t0` is dropped, as the single
/// ray drops it).
#[inline(always)]
fn not_culled<V: Wide>(t0: &[f32; WIDE], cull: &[f32; WIDE], mask: u64) -> u64 {
    let w = V::LANES;
    let mut out = 0u64;
    for g in 0..WIDE / w {
        let at = g * w;
        let gm = (mask >> at) & group_bits(w);
        if gm == 0 {
            continue;
        }
        let keep = V::le(V::load(&t0[at..]), V::load(&cull[at..]));
        out |= (V::bits(keep) as u64 & gm) << at;
    }
    out
}

/// The low `w` bits.
#[inline(always)]
const fn group_bits(w: usize) -> u64 {
    if w >= 64 { u64::MAX } else { (1u64 << w) - 1 }
}

/// What interval arithmetic tells about one inner node for a whole frustum.
enum Sided {
    /// Every live lane goes to the near child only, its interval unchanged.
    Near,
    /// Every live lane goes to the far child only, its interval unchanged.
    Far,
    /// Lanes must be stepped; `[tp_lo, tp_hi]` bounds their plane distances, or is
    /// `(-∞, +∞)` when unknown.
    Step(f32, f32),
}

/// Interval arithmetic for one inner node over a whole frustum whose lanes agree on the near
/// side: whether every live lane provably goes to one child only with its interval unchanged
/// (the step would leave `t0`, `t1` as they are). `[s_lo, s_hi]` bounds the lanes'
/// `split - origin`, `[inv_lo, inv_hi]` their `1/d`,
/// `slack_hi` their `δ`, `[lo, hi]` their `t0` and `t1`. Rounding is monotonic, so bounds
/// computed from bounds with the step's own operations bound the lanes' rounded values; live
/// lanes keep `t0 <= t1·HI` (every entry test checks it).
#[inline(always)]
fn one_sided(
    s_lo: f32,
    s_hi: f32,
    inv_lo: f32,
    inv_hi: f32,
    slack_hi: f32,
    lo: f32,
    hi: f32,
) -> Sided {
    // `tp = s · inv` over the lanes: the exact product of two intervals is extreme at corners,
    // and rounding is monotonic.
    let c = [s_lo * inv_lo, s_lo * inv_hi, s_hi * inv_lo, s_hi * inv_hi];
    if c.iter().any(|x| x.is_nan()) {
        return Sided::Step(f32::NEG_INFINITY, f32::INFINITY);
    }
    let tp_lo = c.into_iter().fold(f32::INFINITY, min_ps);
    let tp_hi = c.into_iter().fold(f32::NEG_INFINITY, max_ps);
    if tp_lo > 0.0 {
        // Every lane in the `tp > 0` case. Far not entered: `max(t0, tp - δ) > t1·HI` holds when
        // `tp - δ > t1·HI` for every lane (and then `t0 <= t1·HI < tp - δ`: near entered).
        if tp_lo - slack_hi > hi * HI {
            return Sided::Near;
        }
        // Near skipped: `(tp + δ)·HI < t0`; then `tp - δ < t0`, so the far `t0` stays `t0`.
        if (tp_hi + slack_hi) * HI < lo {
            return Sided::Far;
        }
    } else if tp_hi <= 0.0 && (tp_hi + slack_hi) * HI < lo {
        // Every lane in the `tp <= 0` case with the far side not entered:
        // `t0 > min(t1, tp + δ)·HI` holds when `t0 > (tp + δ)·HI`.
        return Sided::Near;
    }
    Sided::Step(tp_lo, tp_hi)
}

/// True when every origin has the bits of the first (camera rays; not reflections).
#[inline(always)]
fn shared_origin(origins: &[Vec3]) -> bool {
    let o = origins[0].to_array().map(f32::to_bits);
    origins.iter().all(|p| p.to_array().map(f32::to_bits) == o)
}

/// End of the run of rays that starts at `order[i]`: at most [`WIDE`] consecutive rays of
/// `order` with the same axis permutation (`key >> 24`), ray `r`'s key at `key[r − offset]`.
/// Both frusta entry points cut their runs with it.
#[inline(always)]
fn run_end(key: &[u32], order: &[u32], offset: usize, i: usize) -> usize {
    let perm = key[order[i] as usize - offset] >> 24;
    let m = order.len();
    let mut end = i + 1;
    while end < m && end < i + WIDE && key[order[end] as usize - offset] >> 24 == perm {
        end += 1;
    }
    end
}

impl KdAccel {
    /// Closest hits of a batch traced as frusta (see the module docs); `G` lanes per SIMD step.
    /// Returns false, having written nothing, when the batch is too small to be worth
    /// regrouping or its rays come from many origins too far apart ([`KdAccel::origins_of`], [`route::closest_by_origins`]).
    #[inline(always)]
    pub(super) fn closest_frusta<V: Wide>(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_tri: &mut [u32],
        scratch: &mut FrustumScratch,
    ) -> bool {
        let n = origins.len();
        if route::closest_by_size(n) != Loop::Frustum {
            return false;
        }
        let shared = shared_origin(origins);
        self.regroup(dirs, WIDE, scratch);
        let FrustumScratch {
            f,
            stack,
            tmp,
            key,
            order,
            ..
        } = scratch;
        // `order` lists the rays permutation by permutation (invalid rays last), tile by tile.
        let order = &order[..n];
        let lie = if shared {
            Origins::Shared
        } else {
            let mut i = 0;
            let runs = std::iter::from_fn(|| {
                (i < n).then(|| {
                    let end = run_end(key, order, 0, i);
                    let rows = &order[i..end];
                    i = end;
                    rows
                })
            });
            self.origins_of(origins, key, runs)
        };
        if route::closest_by_origins(lie) != Loop::Frustum {
            return false;
        }
        let mut i = 0;
        while i < n {
            let perm = key[order[i] as usize] >> 24;
            let end = run_end(key, order, 0, i);
            let rows = &order[i..end];
            if perm >= 6 {
                for &r in rows {
                    let r = r as usize;
                    (out_t[r], out_tri[r]) = self.single_closest(origins[r], dirs[r], t_max[r]);
                }
            } else {
                let rays = Rows {
                    origins,
                    perm,
                    dirs,
                    t_max,
                    rows,
                };
                self.frustum::<V>(&rays, out_t, out_tri, false, f, stack, tmp);
            }
            i = end;
        }
        true
    }

    /// [`KdAccel::closest_frusta`] on the threads of the current rayon pool: the whole batch
    /// regrouped once, its frusta traced in parallel (whole frusta, [`RUNS_PER_ITEM`] per work
    /// item) into a buffer in tracing order, then copied to their rows. Same answers and same
    /// return value as the one-thread version.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn closest_frusta_par(
        &self,
        level: Level,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_tri: &mut [u32],
        scratch: &mut FrustumScratch,
    ) -> bool {
        let n = origins.len();
        if route::closest_by_size(n) != Loop::Frustum {
            return false;
        }
        let shared = shared_origin(origins);
        let FrustumScratch {
            key,
            order,
            runs,
            buf_t,
            buf_tri,
            ..
        } = scratch;
        // Regrouped piece by piece, in parallel: the tiles of a render's trace chunks, cut into
        // runs exactly as `closest_frusta` cuts them.
        // (Every entry of `key`, `order` and `buf_*` is written below: resized, not cleared.)
        key.resize(n, 0);
        order.resize(n, 0);
        let piece_runs: Vec<Vec<u32>> = key
            .par_chunks_mut(PIECE)
            .zip(order.par_chunks_mut(PIECE))
            .enumerate()
            .map(|(c, (key, order))| {
                let first = c * PIECE;
                let m = key.len();
                let mut s = take_scratch();
                self.regroup(&dirs[first..first + m], WIDE, &mut s);
                key.copy_from_slice(&s.key);
                for (o, &r) in order.iter_mut().zip(&s.order) {
                    *o = first as u32 + r;
                }
                put_scratch(s);
                let mut runs = Vec::with_capacity(m.div_ceil(WIDE) + 6);
                let mut i = 0;
                while i < m {
                    runs.push((first + i) as u32);
                    i = run_end(key, order, first, i);
                }
                runs
            })
            .collect();
        let (key, order) = (&key[..], &order[..]);
        runs.clear();
        for r in &piece_runs {
            runs.extend_from_slice(r);
        }
        runs.push(n as u32);
        let runs = &runs[..];
        buf_t.resize(n, 0.0);
        buf_tri.resize(n, 0);
        let kernel = |runs: &[u32], out_t: &mut [f32], out_tri: &mut [u32]| {
            let k = Runs {
                accel: self,
                origins,
                dirs,
                t_max,
                order,
                key,
                runs,
                out_t,
                out_tri,
            };
            dispatch_wide(level, k)
        };
        // Rays from many origins: the first two frusta decide, as in `closest_frusta`.
        let rows_of = runs
            .windows(2)
            .map(|w| &order[w[0] as usize..w[1] as usize]);
        let lie = if shared {
            Origins::Shared
        } else {
            self.origins_of(origins, key, rows_of)
        };
        if route::closest_by_origins(lie) != Loop::Frustum {
            return false;
        }
        let mut items = Vec::new();
        let (mut rest_t, mut rest_tri) = (&mut buf_t[..], &mut buf_tri[..]);
        for a in (0..runs.len() - 1).step_by(RUNS_PER_ITEM) {
            let b = (a + RUNS_PER_ITEM).min(runs.len() - 1);
            let len = (runs[b] - runs[a]) as usize;
            let (t, tail_t) = std::mem::take(&mut rest_t).split_at_mut(len);
            let (tri, tail_tri) = std::mem::take(&mut rest_tri).split_at_mut(len);
            (rest_t, rest_tri) = (tail_t, tail_tri);
            items.push((a, b, t, tri));
        }
        items.into_par_iter().for_each(|(a, b, t, tri)| {
            kernel(&runs[a..=b], t, tri);
        });
        // Each piece's answers back to its own rows.
        out_t
            .par_chunks_mut(PIECE)
            .zip(out_tri.par_chunks_mut(PIECE))
            .enumerate()
            .for_each(|(c, (out_t, out_tri))| {
                let r = c * PIECE..c * PIECE + out_t.len();
                let found = buf_t[r.clone()].iter().zip(&buf_tri[r.clone()]);
                for (&row, (&t, &tri)) in order[r.clone()].iter().zip(found) {
                    let row = row as usize - r.start;
                    (out_t[row], out_tri[row]) = (t, tri);
                }
            });
        true
    }

    /// How the origins of a batch from many origins lie, for the routing table
    /// ([`route::closest_by_origins`]; both entry points ask before tracing): the summed spread
    /// of its first two frusta's origins (`runs`: the rays of each run in tracing order; runs of
    /// rays the watertight test rejects do not count), or [`Origins::Few`] when no more runs
    /// follow them.
    fn origins_of<'r>(
        &self,
        origins: &[Vec3],
        key: &[u32],
        mut runs: impl Iterator<Item = &'r [u32]>,
    ) -> Origins {
        let (mut frusta, mut spread) = (0, 0.0);
        while frusta < 2 {
            let Some(rows) = runs.next() else {
                return Origins::Few;
            };
            if key[rows[0] as usize] >> 24 < 6 {
                frusta += 1;
                spread += self.origin_spread(origins, rows);
            }
        }
        if runs.next().is_some() {
            Origins::Spread(spread)
        } else {
            Origins::Few
        }
    }

    /// The spread of the finite origins of the rays `rows` ([`MAX_SPREAD`](super::route::MAX_SPREAD)): the L∞ extent of
    /// their box relative to the root box's largest side.
    fn origin_spread(&self, origins: &[Vec3], rows: &[u32]) -> f32 {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &r in rows {
            let o = origins[r as usize];
            if o.is_finite() {
                (lo, hi) = (lo.min(o), hi.max(o));
            }
        }
        let (rlo, rhi) = (self.root.0, self.root.1);
        let side = (0..3).map(|a| rhi[a] - rlo[a]).fold(0.0, f32::max);
        (hi - lo).max(Vec3::ZERO).max_element() / side
    }

    /// One ray through the single-ray loop, as the output columns store it.
    #[inline(always)]
    fn single_closest(&self, o: Vec3, d: Vec3, t_max: f32) -> (f32, u32) {
        self.intersect_closest(o, d, t_max)
            .map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri))
    }

    /// Keys every ray by (watertight permutation, shear cell, about `per` rays per cell) and
    /// counting-sorts them into `scratch.order`; `scratch.key[i] >> 24` is ray `i`'s
    /// permutation (6: a direction the watertight test rejects, or close to it: such rays go one
    /// by one).
    fn regroup(&self, dirs: &[Vec3], per: usize, scratch: &mut FrustumScratch) {
        let n = dirs.len();
        let key = &mut scratch.key;
        let shear = &mut scratch.shear;
        // Every entry of `key`, `shear` and `order` is written below: resized, not cleared
        // (a batch of the usual size reuses them as they are).
        key.resize(n, 0);
        shear.resize(n, [0.0; 2]);
        // The permutation exactly as `WatertightRay::new` chooses it, and the shear (up to
        // rounding: it only places the ray in a tile), branch-free so that it vectorises.
        for ((d, k), sh) in dirs.iter().zip(key.iter_mut()).zip(shear.iter_mut()) {
            let a = d.abs();
            let x_max = a.x >= a.y && a.x >= a.z;
            let y_max = a.y >= a.z;
            let (kz, dz, dx, dy) = if x_max {
                (0, d.x, d.y, d.z)
            } else if y_max {
                (1, d.y, d.z, d.x)
            } else {
                (2, d.z, d.x, d.y)
            };
            let r = 1.0 / dz;
            let (u, v) = (dx * r, dy * r);
            let ok = r.is_finite() && u.is_finite() && v.is_finite();
            let perm = if ok { 2 * kz + u32::from(dz < 0.0) } else { 6 };
            *k = perm << 24;
            *sh = [u, v];
        }
        let mut count = [0usize; 7];
        let mut lo = [[f32::INFINITY; 2]; 6];
        let mut hi = [[f32::NEG_INFINITY; 2]; 6];
        for (k, sh) in key.iter().zip(shear.iter()) {
            let p = (*k >> 24) as usize;
            count[p] += 1;
            if p < 6 {
                lo[p] = [lo[p][0].min(sh[0]), lo[p][1].min(sh[1])];
                hi[p] = [hi[p][0].max(sh[0]), hi[p][1].max(sh[1])];
            }
        }
        // A grid of about `count / per` cells per permutation, shaped like its shear bounds.
        let mut grid = [(1u32, 1u32, 0.0f32, 0.0f32); 6];
        let mut base = [0u32; 8];
        for p in 0..6 {
            let cells = count[p].div_ceil(per).max(1) as f32;
            let (rx, ry) = (hi[p][0] - lo[p][0], hi[p][1] - lo[p][1]);
            let aspect = if ry > 0.0 && rx > 0.0 { rx / ry } else { 1.0 };
            let gx = if ry > 0.0 {
                (cells * aspect).sqrt().round().clamp(1.0, cells)
            } else {
                cells
            };
            let gy = (cells / gx).ceil().max(1.0);
            let gx = if rx > 0.0 { gx } else { 1.0 };
            let gy = if ry > 0.0 { gy } else { 1.0 };
            let sx = if rx > 0.0 { gx / rx } else { 0.0 };
            let sy = if ry > 0.0 { gy / ry } else { 0.0 };
            grid[p] = (gx as u32, gy as u32, sx, sy);
            base[p + 1] = base[p] + gx as u32 * gy as u32;
        }
        base[7] = base[6] + 1;
        // Cell of every ray, then a counting sort on the global cell index.
        let mut hist = vec![0u32; base[7] as usize + 1];
        for (k, sh) in key.iter_mut().zip(shear.iter()) {
            let p = (*k >> 24) as usize;
            let cell = if p < 6 {
                let (gx, gy, sx, sy) = grid[p];
                let cx = (((sh[0] - lo[p][0]) * sx) as u32).min(gx - 1);
                let cy = (((sh[1] - lo[p][1]) * sy) as u32).min(gy - 1);
                base[p] + cy * gx + cx
            } else {
                base[6]
            };
            *k |= cell;
            hist[cell as usize + 1] += 1;
        }
        for c in 1..hist.len() {
            hist[c] += hist[c - 1];
        }
        let order = &mut scratch.order;
        order.resize(n, 0);
        for (i, k) in key.iter().enumerate() {
            let cell = (k & 0xff_ffff) as usize;
            order[hist[cell] as usize] = i as u32;
            hist[cell] += 1;
        }
    }

    /// Traces the rays `rays.rows` (at most [`WIDE`], one permutation) as one frustum, `V` lanes
    /// per SIMD step. The per-lane setup is `Ray::new` and `Ray::clip` written over the lanes
    /// (the same operations; `f32::min`/`max`, which ignore a NaN operand, as [`min_num`] and
    /// [`max_num`]). Answers go to `out_*[row]`, or with `local` to `out_*[lane]` (tracing
    /// order).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn frustum<V: Wide>(
        &self,
        rays: &Rows<'_>,
        out_t: &mut [f32],
        out_tri: &mut [u32],
        local: bool,
        f: &mut Frustum,
        stack: &mut [WideEntry; STACK],
        tmp: &mut [[f32; WIDE]; 3],
    ) {
        let mut entry = WideEntry::default();
        let mut d = [[1.0f32; WIDE]; 3];
        for (lane, &r) in rays.rows.iter().enumerate() {
            let r = r as usize;
            let dir = rays.dirs[r];
            let o = rays.origins[r];
            (f.org[0][lane], f.org[1][lane], f.org[2][lane]) = (o.x, o.y, o.z);
            f.dir[lane] = dir;
            (d[0][lane], d[1][lane], d[2][lane]) = (dir.x, dir.y, dir.z);
            f.t_max[lane] = rays.t_max[r];
        }
        for lane in rays.rows.len()..WIDE {
            f.t_max[lane] = f32::NAN;
        }
        // The permutation `WatertightRay::new` chooses for every ray of the run.
        let kz = rays.perm as usize / 2;
        let kx = if kz == 2 { 0 } else { kz + 1 };
        let ky = if kx == 2 { 0 } else { kx + 1 };
        let axes = if rays.perm % 2 == 1 {
            [ky, kx, kz]
        } else {
            [kx, ky, kz]
        };
        let [kx, ky, _] = axes;
        f.best_t = [f32::INFINITY; WIDE];
        f.best_tri = [u32::MAX; WIDE];
        f.cull = [f32::INFINITY; WIDE];
        f.limit = f.t_max;
        let w = V::LANES;
        let (zero, inf, ninf) = (
            V::splat(0.0),
            V::splat(f32::INFINITY),
            V::splat(f32::NEG_INFINITY),
        );
        // (No closures over lanes: a closure is not compiled with the kernel's target features.)
        let (r0, r1) = (self.root.0, self.root.1);
        let root = [
            [V::splat(r0[0]), V::splat(r0[1]), V::splat(r0[2])],
            [V::splat(r1[0]), V::splat(r1[1]), V::splat(r1[2])],
        ];
        // Interval-arithmetic bounds over the live lanes (the neutral value elsewhere).
        let mut org_lo = [inf; 3];
        let mut org_hi = [ninf; 3];
        let mut inv_lo = [inf; 3];
        let mut inv_hi = [ninf; 3];
        let mut slack_hi = [ninf; 3];
        let (mut lo, mut hi) = (inf, ninf);
        let mut mask = 0u64;
        for g in 0..WIDE / w {
            let at = g * w;
            let o = [
                V::load(&f.org[0][at..]),
                V::load(&f.org[1][at..]),
                V::load(&f.org[2][at..]),
            ];
            let dv = [
                V::load(&d[0][at..]),
                V::load(&d[1][at..]),
                V::load(&d[2][at..]),
            ];
            let tm = V::load(&f.t_max[at..]);
            let origin_ok = V::and(V::and(finite(o[0]), finite(o[1])), finite(o[2]));
            // `Ray::new`'s `δ`: the L∞ distance to the farthest root corner.
            let mut reach = ninf;
            for a in 0..3 {
                let r = root[0][a].sub(o[a]).abs().max(root[1][a].sub(o[a]).abs());
                reach = reach.max(r);
            }
            let delta = V::splat(DELTA).mul(reach);
            // `WatertightRay::new`'s shear and its test for a direction it rejects.
            let dz = dv[kz];
            let sz = V::splat(1.0).div(dz);
            let sx = dv[kx].div(dz);
            let sy = dv[ky].div(dz);
            let test_ok = V::and(
                V::and(V::and(finite(sz), finite(sx)), finite(sy)),
                origin_ok,
            );
            sx.store(&mut f.sx[at..]);
            sy.store(&mut f.sy[at..]);
            sz.store(&mut f.sz[at..]);
            let mut t0 = zero;
            let mut t1 = tm;
            let mut inv = [zero; 3];
            let mut slack = [zero; 3];
            for a in 0..3 {
                inv[a] = V::splat(1.0).div(dv[a]);
                slack[a] = inv[a].abs().mul(delta).min(V::splat(f32::MAX));
                inv[a].store(&mut f.inv[a][at..]);
                slack[a].store(&mut f.slack[a][at..]);
                let ta = root[0][a].sub(o[a]).mul(inv[a]);
                let tb = root[1][a].sub(o[a]).mul(inv[a]);
                // As `Ray::clip`: a NaN distance leaves the axis unbounded.
                let ok = V::and(V::eq(ta, ta), V::eq(tb, tb));
                let near = V::select(ok, min_num(ta, tb), ninf);
                let far = V::select(ok, max_num(ta, tb), inf);
                t0 = max_num(t0, near.sub(slack[a]));
                t1 = min_num(t1, far.add(slack[a]));
            }
            // A bad `t_max` (NaN, `<= 0`) or a ray missing the root box: no hit.
            let live = V::and(
                V::and(test_ok, V::gt(tm, zero)),
                V::le(t0, t1.mul(V::splat(HI))),
            );
            mask |= (V::bits(live) as u64) << at;
            // Lanes that are not live hold the neutral interval of the bounds.
            let e0 = V::select(live, t0.max(zero), inf);
            let e1 = V::select(live, t1, ninf);
            e0.store(&mut entry.t0[at..]);
            e1.store(&mut entry.t1[at..]);
            lo = e0.min(lo);
            hi = e1.max(hi);
            for a in 0..3 {
                org_lo[a] = V::select(live, o[a], inf).min(org_lo[a]);
                org_hi[a] = V::select(live, o[a], ninf).max(org_hi[a]);
                inv_lo[a] = V::select(live, inv[a], inf).min(inv_lo[a]);
                inv_hi[a] = V::select(live, inv[a], ninf).max(inv_hi[a]);
                slack_hi[a] = V::select(live, slack[a], ninf).max(slack_hi[a]);
            }
        }
        entry.mask = mask;
        for (lane, &r) in rays.rows.iter().enumerate() {
            if mask >> lane & 1 == 0 {
                let at = if local { lane } else { r as usize };
                (out_t[at], out_tri[at]) = (f32::INFINITY, u32::MAX);
            }
        }
        if entry.mask == 0 {
            return;
        }
        f.k = axes.map(|x| x.min(2));
        for a in 0..3 {
            f.org_lo[a] = lowest(org_lo[a]);
            f.org_hi[a] = highest(org_hi[a]);
            f.inv_lo[a] = lowest(inv_lo[a]);
            f.inv_hi[a] = highest(inv_hi[a]);
            f.slack_hi[a] = highest(slack_hi[a]);
        }
        entry.lo = lowest(lo);
        entry.hi = highest(hi);
        let lanes = entry.mask;
        self.walk_frustum::<V>(f, entry, stack, tmp);
        for (lane, &r) in rays.rows.iter().enumerate() {
            if lanes >> lane & 1 != 0 {
                let at = if local { lane } else { r as usize };
                (out_t[at], out_tri[at]) = (f.best_t[lane], f.best_tri[lane]);
            }
        }
    }

    /// Front-to-back traversal of a frustum from `start` (see the module docs); each lane's
    /// answer is left in `f.best_t`, `f.best_tri`.
    #[inline(always)]
    fn walk_frustum<V: Wide>(
        &self,
        f: &mut Frustum,
        start: WideEntry,
        stack: &mut [WideEntry; STACK],
        tmp: &mut [[f32; WIDE]; 3],
    ) {
        let nodes = &self.tree.nodes[..];
        // Whether node `i` is a leaf without triangles (see the child steps below).
        let empty = |i: u32| {
            nodes
                .get(i as usize)
                .is_some_and(|c| c.is_leaf() && c.count() == 0)
        };
        let w = V::LANES;
        let mut sp = 0usize;
        let mut e = start;
        loop {
            // Descend to a leaf.
            let leaf = loop {
                // Few lanes left: on one by one (the frustum's per-node work no longer pays).
                if route::frustum_lanes(e.mask.count_ones()) == Loop::Single {
                    self.solo_lanes(f, &e);
                    break None;
                }
                let Some(&n) = nodes.get(e.node as usize) else {
                    break None;
                };
                if n.is_leaf() {
                    break Some(n);
                }
                let axis = n.axis();
                let split = n.split();
                let (left, right) = (e.node + 1, n.right());
                let m = e.mask;
                // The near side is the origin's (on the plane: the direction's sign).
                let near_left = if f.org_hi[axis] < split {
                    m
                } else if f.org_lo[axis] > split {
                    0
                } else {
                    let mut nl = 0u64;
                    let s = V::splat(split);
                    for g in 0..WIDE / w {
                        let at = g * w;
                        if (m >> at) & group_bits(w) == 0 {
                            continue;
                        }
                        let o = V::load(&f.org[axis][at..]);
                        let inv = V::load(&f.inv[axis][at..]);
                        let on = V::and(V::eq(o, s), V::lt(inv, V::splat(0.0)));
                        nl |= (V::bits(V::or(V::lt(o, s), on)) as u64) << at;
                    }
                    nl & m
                };
                let uniform = near_left == m || near_left == 0;
                let (near, far) = if near_left == m {
                    (left, right)
                } else {
                    (right, left)
                };
                // `split - o` over the lanes (monotonic in `o`).
                let (s_lo, s_hi) = (split - f.org_hi[axis], split - f.org_lo[axis]);
                let (tp_lo, tp_hi) = if uniform {
                    match one_sided(
                        s_lo,
                        s_hi,
                        f.inv_lo[axis],
                        f.inv_hi[axis],
                        f.slack_hi[axis],
                        e.lo,
                        e.hi,
                    ) {
                        // The whole frustum one way, intervals unchanged: no lane work.
                        Sided::Near => {
                            e.node = near;
                            continue;
                        }
                        Sided::Far => {
                            e.node = far;
                            continue;
                        }
                        Sided::Step(lo, hi) => (lo, hi),
                    }
                } else {
                    (f32::NEG_INFINITY, f32::INFINITY)
                };
                // Bounds of the children's intervals by interval arithmetic (no lane pass):
                // where every lane has `tp > 0`, the near `t1 <= tp + δ` and the far
                // `t0 >= tp - δ`.
                let all_pos = tp_lo > 0.0;
                let near_hi = if all_pos {
                    min_ps(e.hi, tp_hi + f.slack_hi[axis])
                } else {
                    e.hi
                };
                let far_lo = if all_pos {
                    max_ps(e.lo, tp_lo - f.slack_hi[axis])
                } else {
                    e.lo
                };
                let (mut go_near, mut go_far) = (0u64, 0u64);
                let [near_t1, far_t0, far_t1] = tmp;
                for g in 0..WIDE / w {
                    let at = g * w;
                    if (m >> at) & group_bits(w) == 0 {
                        continue;
                    }
                    let s = step::<V>(
                        V::splat(split),
                        V::load(&f.org[axis][at..]),
                        V::load(&f.inv[axis][at..]),
                        V::load(&f.slack[axis][at..]),
                        V::load(&e.t0[at..]),
                        V::load(&e.t1[at..]),
                    );
                    s.near_t1.store(&mut near_t1[at..]);
                    s.far_t0.store(&mut far_t0[at..]);
                    s.far_t1.store(&mut far_t1[at..]);
                    go_near |= (!V::bits(s.skip_near) as u64 & group_bits(w)) << at;
                    go_far |= (V::bits(s.go_far) as u64) << at;
                }
                go_near &= m;
                go_far &= m;
                if !uniform {
                    // Lanes on both sides of the plane: each lane's children as left/right,
                    // the lowest live lane's near side first. The order changes no answer: a
                    // lane still visits every leaf that starts before its best hit (culling
                    // only skips entries beyond it), so it meets the leaf holding its closest
                    // hit, and keeps the least `(t, index)` of what it tests, as the single
                    // ray does.
                    let nl = near_left;
                    let left_mask = (nl & go_near) | (!nl & go_far);
                    let right_mask = (nl & go_far) | (!nl & go_near);
                    let left_first = nl & (m & m.wrapping_neg()) != 0;
                    let (first_mask, second_mask, second_node) = if left_first {
                        (left_mask, right_mask, right)
                    } else {
                        (right_mask, left_mask, left)
                    };
                    let first_node = if left_first { left } else { right };
                    // Lanes whose near side goes first keep (t0, near t1) in `e` and push the
                    // far interval; the others the other way round.
                    let flip = if left_first { !nl } else { nl };
                    // (An empty second child is not pushed: see `empty` below.)
                    if second_mask != 0 && sp < stack.len() && !empty(second_node) {
                        let top = &mut stack[sp];
                        for k in 0..WIDE {
                            let f_k = flip >> k & 1 != 0;
                            top.t0[k] = if f_k { e.t0[k] } else { far_t0[k] };
                            top.t1[k] = if f_k { near_t1[k] } else { far_t1[k] };
                        }
                        top.node = second_node;
                        top.mask = second_mask;
                        top.lo = e.lo;
                        top.hi = e.hi;
                        sp += 1;
                    }
                    for k in 0..WIDE {
                        let f_k = flip >> k & 1 != 0;
                        e.t0[k] = if f_k { far_t0[k] } else { e.t0[k] };
                        e.t1[k] = if f_k { far_t1[k] } else { near_t1[k] };
                    }
                    e.node = first_node;
                    e.mask = first_mask;
                    if first_mask == 0 {
                        break None;
                    }
                    continue;
                }
                // An empty leaf holds nothing to test: a child that is one is not entered
                // (the lanes' answers are the same, one push and pop fewer).
                if go_near != 0 && go_far != 0 && empty(near) {
                    // On to the far child (without the pop's cull test: a lane may enter a
                    // node it would have culled, which changes no answer, as above).
                    e.node = far;
                    e.mask = go_far;
                    e.t0 = *far_t0;
                    e.t1 = *far_t1;
                    e.lo = far_lo;
                } else if go_near != 0 && go_far != 0 && empty(far) {
                    e.node = near;
                    e.mask = go_near;
                    e.t1 = *near_t1;
                    e.hi = near_hi;
                } else if go_near != 0 && go_far != 0 {
                    if sp < stack.len() {
                        let top = &mut stack[sp];
                        top.node = far;
                        top.mask = go_far;
                        top.t0 = *far_t0;
                        top.t1 = *far_t1;
                        top.lo = far_lo;
                        top.hi = e.hi;
                        sp += 1;
                    }
                    e.node = near;
                    e.mask = go_near;
                    e.t1 = *near_t1;
                    e.hi = near_hi;
                } else if go_near != 0 {
                    // Every lane near only: its interval is unchanged.
                    e.node = near;
                    e.mask = go_near;
                    e.hi = near_hi;
                } else {
                    // Every lane far only: the interval starts at the far `t0`.
                    e.node = far;
                    e.mask = go_far;
                    e.t0 = *far_t0;
                    e.lo = far_lo;
                }
                if e.mask == 0 {
                    break None;
                }
            };
            if let Some(n) = leaf {
                self.leaf_frustum::<V>(f, n.offset() as usize, n.count() as usize, e.mask);
            }
            // Pop the next entry with a lane that can still hold a closer (or tying) hit.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let top = &stack[sp];
                let m = not_culled::<V>(&top.t0, &f.cull, top.mask);
                if m != 0 {
                    e = *top;
                    e.mask = m;
                    break;
                }
            }
        }
    }

    /// The lanes of `e` traced on through its subtree one by one with the single-ray loop
    /// (from the lane's own interval, with its best hit so far), their answers written back.
    /// Same steps, tests and culling as the lane would take, so the same answers.
    #[inline(always)]
    fn solo_lanes(&self, f: &mut Frustum, e: &WideEntry) {
        let mut m = e.mask;
        while m != 0 {
            let k = m.trailing_zeros() as usize;
            m &= m - 1;
            let origin = Vec3::new(f.org[0][k], f.org[1][k], f.org[2][k]);
            let Some(ray) = Ray::<WatertightRay>::new(origin, f.dir[k], &self.root) else {
                continue;
            };
            let best = (f.best_tri[k] != u32::MAX).then_some(TriHit {
                t: f.best_t[k],
                tri: f.best_tri[k],
            });
            let mut v = Closest::resume(f.t_max[k], best);
            let start = Entry {
                node: e.node,
                t0: e.t0[k],
                t1: e.t1[k],
            };
            self.walk(&ray, start, &mut v);
            if let Some(h) = v.finish(false) {
                (f.best_t[k], f.best_tri[k]) = (h.t, h.tri);
                f.limit[k] = v.limit();
                f.cull[k] = v.cull();
            }
        }
    }

    /// Tests the leaf entries `start..start + count` against the lanes of `mask`, triangle by
    /// triangle in leaf order (as each single ray does), updating each lane's best hit.
    #[inline(always)]
    fn leaf_frustum<V: Wide>(&self, f: &mut Frustum, start: usize, count: usize, mask: u64) {
        let (Some(tris), Some(ids)) = (
            self.tris.get(start..start + count),
            self.tree.tri_indices.get(start..start + count),
        ) else {
            return;
        };
        let [kx, ky, kz] = f.k;
        for (p, &id) in tris.iter().zip(ids) {
            let perm = |v: &[f32; 3]| [v[kx], v[ky], v[kz]];
            let (a, b, c) = (perm(&p[0]), perm(&p[1]), perm(&p[2]));
            let w = V::LANES;
            for g in 0..WIDE / w {
                let at = g * w;
                let gm = ((mask >> at) & group_bits(w)) as u32;
                if gm == 0 {
                    continue;
                }
                let edge = hit_lanes::<V>(f, at, gm, &a, &b, &c, id) & gm;
                if edge != 0 {
                    self.edge_lanes(f, at, edge as u64, p, id);
                }
            }
        }
    }

    /// Lanes `base + j` for the bits `j` of `edge` (a `u`, `v` or `w` of zero) retested with the
    /// scalar watertight test (its double-precision edge fallback).
    #[cold]
    fn edge_lanes(&self, f: &mut Frustum, base: usize, mut edge: u64, p: &[[f32; 3]; 3], id: u32) {
        let [kx, ky, kz] = f.k;
        while edge != 0 {
            let k = base + edge.trailing_zeros() as usize;
            edge &= edge - 1;
            let ray = WatertightRay {
                origin: Vec3::new(f.org[0][k], f.org[1][k], f.org[2][k]),
                kx,
                ky,
                kz,
                sx: f.sx[k],
                sy: f.sy[k],
                sz: f.sz[k],
            };
            if let Some(t) = ray.intersect(p[0], p[1], p[2], f.limit[k])
                && (t < f.best_t[k] || id < f.best_tri[k])
            {
                (f.best_t[k], f.best_tri[k]) = (t, id);
                f.limit[k] = t.next_up();
                f.cull[k] = t * HI;
            }
        }
    }
}

/// One triangle (vertices `a`, `b`, `c` in the permuted axes) against the `V` lanes from `at`
/// whose bits are in `live`: the lane watertight test ([`WatertightLanes::hit`]), each hit taken
/// as `Closest::accept` would. Returns the bits of the lanes on an edge (`u`, `v` or `w` zero),
/// which the caller retests.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn hit_lanes<V: Wide>(
    f: &mut Frustum,
    at: usize,
    live: u32,
    a: &[f32; 3],
    b: &[f32; 3],
    c: &[f32; 3],
    id: u32,
) -> u32 {
    let [kx, ky, kz] = f.k;
    let lanes = WatertightLanes {
        o: [
            V::load(&f.org[kx][at..]),
            V::load(&f.org[ky][at..]),
            V::load(&f.org[kz][at..]),
        ],
        sx: V::load(&f.sx[at..]),
        sy: V::load(&f.sy[at..]),
        sz: V::load(&f.sz[at..]),
    };
    let h = lanes.hit(a, b, c, live, V::load(&f.limit[at..]));
    if h.hit != 0 {
        // A hit is better when it is closer, or (at equal `t`) of a lower index.
        let closer = V::bits(V::lt(h.t, V::load(&f.best_t[at..])));
        let mut ts = [0.0f32; 16];
        h.t.store(&mut ts);
        let mut m = h.hit;
        while m != 0 {
            let j = m.trailing_zeros() as usize;
            m &= m - 1;
            let k = at + j;
            if closer >> j & 1 != 0 || id < f.best_tri[k] {
                let t = ts[j];
                (f.best_t[k], f.best_tri[k]) = (t, id);
                // `t` is positive and finite here: its successor is the next bit pattern.
                f.limit[k] = f32::from_bits(t.to_bits() + 1);
                f.cull[k] = t * HI;
            }
        }
    }
    h.edge
}
