//! Light-rooted shadow bundles: the occluded (any-hit) batch query for rays that end at a shared
//! point — a point light — traced *from* that point as bundles of up to 32 rays (Reshetov et al.
//! 2005; Wald's shared-origin packets), answers identical to [`KdAccel::intersect_occluded`].
//!
//! Reads a batch's origins, directions and `t_max` (any rays: the ones that do not end near a
//! shared point take the 4-ray packet path), the tree's nodes, the leaf-ordered triangles and the
//! root box; writes one occlusion bit per ray, in the batch's order.
//!
//! **Grouping.** A ray's far end `F = o + t_max·d` is compared with the batch's apexes (the far
//! ends met so far, at most [`MAX_APEXES`]); a ray within [`APEX_TOL`] of one (relative to its
//! length or to the length of the ray that set it) joins it.
//! Rays of one apex are grouped by the watertight test's axis permutation (the cube face of their
//! direction, so every lane of a bundle reads the same vertex components; `LANES` rays at a time
//! in lanes when they all share the previous ray's apex and face, else ray by ray). Runs of up
//! to [`UNIT`] consecutive rays of one group (neighbours on screen, as the queue holds them)
//! form units, sorted along a Morton curve of their first ray's direction on that face (a
//! counting sort over a grid sized to the group), then packed whole into bundles. Grouping only
//! decides which rays share work: it never changes an answer, and the output stays in the
//! batch's order.
//!
//! **Culling from the light.** A bundle's lanes share the apex `A` as origin and run along
//! `A + s·(o − A)`, `s ∈ [0, 1]`: every lane agrees on which child of a split is near (the
//! apex's side), the plane distance `split − A[axis]` is one scalar per node, and the bundle
//! descends each node once with a 32-wide (16-wide, …) interval step; a child is skipped when no
//! live lane enters it. The reversed segment is made to cover the original one: each lane's
//! world-space slack `g` is the single ray's `δ` plus the distance from `F` to `A` plus a bound
//! on the rounding of `F`, of `o − A` and of this module's own plane distances (relative slack
//! `SLACK` on `s`, as the single-ray step). So every leaf the single ray can find a hit in — one
//! within `δ` of its segment — is visited by its lane.
//!
//! **Testing in the ray's own frame.** In a leaf each triangle is tested against all live lanes
//! at once with the watertight test exactly as [`WatertightRay::intersect`] computes it for the
//! lane's *original* ray (origin `o`, direction `d`, `t_max`): the same `f32` operations in the
//! same order (Rust never fuses them), and the lanes that land on an edge (`u`, `v` or `w` zero)
//! take the scalar test itself with its `f64` fallback. A lane is occluded exactly when some
//! triangle of a leaf it visits passes that test, which — visiting every leaf the single ray
//! could hit in — is the single ray's answer (the tests below and `tests/shadow_bundles.rs`, on
//! every Sibenik shadow ray and on rays grazing its edges, check it). A bundle stops when all its
//! lanes are occluded.
//!
//! **Shadow cache.** Each light keeps the last triangle that occluded one of its lanes (Haines &
//! Greenberg); its next bundle — a neighbour along the Morton curve — tests it first against
//! every entered lane with the same exact test, and walks the tree only for the lanes it leaves
//! unoccluded (none: no walk). A lane hit by it is occluded by the single ray's definition, so
//! the cache changes work, never an answer (on Sibenik's shadow rays it answers about 8 % of the
//! lanes, two thirds of the occluded ones).
//!
//! **Lanes.** The lane code is written once over [`Wide`] ([`crate::simd`]'s `wide`: one
//! instruction per operation, each with the scalar operation's semantics) and inlined into
//! [`dispatch_wide`]'s per-level functions, two SIMD values per bundle ([`Pair`]): 32 lanes with
//! AVX-512, 16 with AVX2 and on the portable path (measured on Sibenik's shadow rays, AVX-512:
//! 32 lanes take 2.27 node steps and 0.85 triangle tests per ray against 16 lanes' 3.93 and 1.14;
//! per bundle 72 node steps against 62). No closure may touch a [`Wide`] value in the hot loop (a closure is not compiled with the
//! dispatcher's target features, so its lane operations would become calls). Every level gives
//! the same answers (`tests/shadow_bundles.rs` checks each one on Sibenik).

use glam::Vec3;

use super::KdAccel;
use super::interval::{DELTA, HI};
use super::route::{self, Loop};
use super::visit::Occluded;
use crate::accel::kdtree::MAX_DEPTH;
use crate::geometry::triangle::{WatertightLanes, WatertightRay};
use crate::simd::{Level, Pair, Wide, WideKernel, dispatch_wide};

/// Most distinct far ends (lights) one batch bundles rays toward; rays toward others take the
/// packet path.
const MAX_APEXES: usize = 16;
/// A ray joins an apex when its far end is within this fraction of its length (L∞) of it. Shadow
/// rays end `γ(3)·length` plus the light's rounding short of the light, far inside this.
const APEX_TOL: f32 = 1.0 / (1 << 16) as f32;
/// Relative bound used for every rounding this module accounts for in a lane's slack (`F`,
/// `o − A`): 2⁻²⁰, sixteen times the unit roundoff.
const ROUND: f32 = 1.0 / (1 << 20) as f32;

/// Most consecutive rays of a batch grouped and sorted as one unit.
const UNIT: usize = 4;

/// What grouping needs of one unit: consecutive bundled rays of one group.
#[derive(Clone, Copy)]
struct Prep {
    /// Index of the unit's first ray in the batch.
    ray: u32,
    /// Rays in the unit (1..=UNIT).
    len: u8,
    /// The first ray's direction components on the face's two other axes (`d[kx]`, `d[ky]`):
    /// the sort key.
    uv: [f32; 2],
}

/// Occlusion of every ray of the batch into `out` (see the module docs); the answers are those
/// of [`KdAccel::intersect_occluded`], whatever the SIMD level.
pub(super) fn occluded_batch(
    accel: &KdAccel,
    origins: &[Vec3],
    dirs: &[Vec3],
    t_max: &[f32],
    out: &mut [bool],
) {
    occluded_batch_at(
        Level::current(),
        accel,
        origins,
        dirs,
        t_max,
        out,
        &mut NoCount,
    );
}

/// [`occluded_batch`] at a chosen SIMD level, counting work into `count`.
pub(super) fn occluded_batch_at<C: Count>(
    level: Level,
    accel: &KdAccel,
    origins: &[Vec3],
    dirs: &[Vec3],
    t_max: &[f32],
    out: &mut [bool],
    count: &mut C,
) {
    let n = origins.len();
    assert!(dirs.len() == n && t_max.len() == n && out.len() == n);
    dispatch_wide(
        level,
        BatchKernel {
            accel,
            origins,
            dirs,
            t_max,
            out,
            count,
        },
    );
}

/// Work counters for measurements and tests (the default, [`NoCount`], compiles to nothing).
pub(super) trait Count {
    /// A bundle of `lanes` live lanes starts.
    fn bundle(&mut self, lanes: u32);
    /// An inner node is stepped.
    fn node(&mut self);
    /// A leaf with `tris` triangles is entered by `lanes` lanes.
    fn leaf(&mut self, tris: u32, lanes: u32);
    /// A triangle is tested against the live lanes.
    fn tri(&mut self);
    /// A ray goes through the packet path instead.
    fn fallback(&mut self, rays: u32);
    /// A bundle's `lanes` live lanes are tested against the cached occluder first, and `hit`
    /// of them are occluded by it.
    fn cached(&mut self, lanes: u32, hit: u32);
}

/// No counting.
pub(super) struct NoCount;

impl Count for NoCount {
    #[inline(always)]
    fn bundle(&mut self, _: u32) {}
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn leaf(&mut self, _: u32, _: u32) {}
    #[inline(always)]
    fn tri(&mut self) {}
    #[inline(always)]
    fn fallback(&mut self, _: u32) {}
    #[inline(always)]
    fn cached(&mut self, _: u32, _: u32) {}
}

/// Counts of the work the light-rooted bundles of [`KdAccel::intersect_occluded_batch`] did,
/// from [`KdAccel::intersect_occluded_batch_counted`] (for tests and measurements).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BundleCounts {
    /// Bundles traced.
    pub bundles: u64,
    /// Lanes in them.
    pub lanes: u64,
    /// Inner-node steps.
    pub nodes: u64,
    /// Leaves entered.
    pub leaves: u64,
    /// Sum over leaves of the lanes entering.
    pub leaf_lanes: u64,
    /// Triangle tests (each against a whole bundle).
    pub tris: u64,
    /// Rays that took the packet path.
    pub fallback: u64,
    /// Bundles tested against their light's cached occluder before traversal.
    pub cache_tests: u64,
    /// Lanes found occluded by the cached occluder (no traversal for them).
    pub cache_hits: u64,
    /// Bundles all of whose lanes the cached occluder answered.
    pub cache_done: u64,
}

impl BundleCounts {
    /// Adds `o`'s counts to these.
    pub fn add(&mut self, o: &BundleCounts) {
        self.bundles += o.bundles;
        self.lanes += o.lanes;
        self.nodes += o.nodes;
        self.leaves += o.leaves;
        self.leaf_lanes += o.leaf_lanes;
        self.tris += o.tris;
        self.fallback += o.fallback;
        self.cache_tests += o.cache_tests;
        self.cache_hits += o.cache_hits;
        self.cache_done += o.cache_done;
    }
}

impl Count for BundleCounts {
    fn bundle(&mut self, lanes: u32) {
        self.bundles += 1;
        self.lanes += lanes as u64;
    }
    fn node(&mut self) {
        self.nodes += 1;
    }
    fn leaf(&mut self, _: u32, lanes: u32) {
        self.leaves += 1;
        self.leaf_lanes += lanes as u64;
    }
    fn tri(&mut self) {
        self.tris += 1;
    }
    fn fallback(&mut self, rays: u32) {
        self.fallback += rays as u64;
    }
    fn cached(&mut self, lanes: u32, hit: u32) {
        self.cache_tests += 1;
        self.cache_hits += hit as u64;
        self.cache_done += u64::from(lanes == hit);
    }
}

/// The whole batch as one kernel for [`dispatch_wide`].
struct BatchKernel<'a, C> {
    accel: &'a KdAccel,
    origins: &'a [Vec3],
    dirs: &'a [Vec3],
    t_max: &'a [f32],
    out: &'a mut [bool],
    count: &'a mut C,
}

/// Rows of a bundle's block of lanes (see [`BatchKernel::trace`]): the original rays' origins
/// and directions per axis, and `t_max`.
const ROW_O: usize = 0;
/// See [`ROW_O`].
const ROW_D: usize = 3;
/// See [`ROW_O`].
const ROW_T_MAX: usize = 6;
/// Rows per bundle.
const ROWS: usize = 7;

/// One thread's buffers for the occluded batch, reused by its every call (allocating and
/// zeroing fresh ones per call showed as `memset` in the any-hit kernel's profile).
#[derive(Default)]
struct BatchScratch {
    /// The batch's units.
    preps: Vec<Prep>,
    /// Each unit's group.
    groups: Vec<u8>,
    /// Rays traced alone.
    fallback: Vec<u32>,
    /// The bundles.
    bundles: Vec<BundleInfo>,
    /// Each bundle's units in the sorted order.
    spans: Vec<u32>,
    /// The bundles' lane rows (see [`ROW_O`]).
    block: Vec<f32>,
    /// Each bundle lane's ray.
    lane_ray: Vec<u32>,
    /// [`sort_by_direction`]'s buffers.
    sort: SortScratch,
}

/// [`sort_by_direction`]'s buffers; `order` is its answer.
#[derive(Default)]
struct SortScratch {
    /// Units per cell, then each cell's first slot.
    counts: Vec<u32>,
    /// Each unit's cell.
    keys: Vec<u32>,
    /// The units in cell order.
    order: Vec<u32>,
}

thread_local! {
    /// Each thread's [`BatchScratch`] (taken out while a batch runs).
    static SCRATCH: std::cell::RefCell<Option<Box<BatchScratch>>> =
        const { std::cell::RefCell::new(None) };
}

/// One bundle: its apex, shared axis permutation and number of rays.
#[derive(Clone, Copy)]
struct BundleInfo {
    /// Index of the apex.
    apex: u8,
    /// `(kx, ky, kz)` of every lane's watertight test.
    k: [u8; 3],
    /// Rays in the bundle (1..=LANES).
    len: u8,
}

impl<C: Count> WideKernel for BatchKernel<'_, C> {
    type Output = ();

    #[inline(always)]
    fn run<V: Wide>(self) {
        // Two SIMD values of lanes per bundle (see the module docs).
        self.trace::<Pair<V>>()
    }
}

impl<C: Count> BatchKernel<'_, C> {
    /// Groups the batch and traces its bundles of `V::LANES` lanes.
    #[inline(always)]
    fn trace<V: Wide>(self) {
        let mut scratch = SCRATCH.with_borrow_mut(Option::take).unwrap_or_default();
        self.trace_in::<V>(&mut scratch);
        SCRATCH.with_borrow_mut(|spare| *spare = Some(scratch));
    }

    /// [`BatchKernel::trace`] with this thread's reused buffers.
    #[inline(always)]
    fn trace_in<V: Wide>(self, scratch: &mut BatchScratch) {
        let BatchScratch {
            preps,
            groups,
            fallback,
            bundles,
            spans,
            block,
            lane_ray,
            sort,
        } = scratch;
        preps.clear();
        groups.clear();
        fallback.clear();
        bundles.clear();
        spans.clear();
        let BatchKernel {
            accel,
            origins,
            dirs,
            t_max,
            out,
            count,
        } = self;
        let w = V::LANES;
        let n = origins.len();
        out.fill(false);
        let mut apexes: Vec<Vec3> = Vec::with_capacity(MAX_APEXES);
        // Length of the ray whose far end set each apex.
        let mut founders: Vec<f32> = Vec::with_capacity(MAX_APEXES);
        // Units of up to `UNIT` consecutive rays of one group (neighbours in the batch are
        // usually neighbours on screen), grouped and sorted as one.
        // Group of each unit: apex · 6 + face.
        let mut bundled = 0usize;
        // The apex of the previous ray, tried first; the last ray put in a unit.
        let mut last = 0usize;
        let mut prev = usize::MAX;
        let mut next = 0;
        while next < n {
            let mut end = next + 1;
            if next + w <= n && last < apexes.len() {
                // The common case first: `w` rays in lanes, all toward the previous ray's apex
                // through one face, become whole units.
                let r = next..next + w;
                let face = uniform_face::<V>(
                    &origins[r.clone()],
                    &dirs[r.clone()],
                    &t_max[r],
                    apexes[last],
                    founders[last],
                );
                if let Some(f) = face {
                    let (kz, swap) = (f as usize / 2, f % 2 == 1);
                    let kx = (kz + 1 + usize::from(swap)) % 3;
                    let ky = (kz + 2 - usize::from(swap)) % 3;
                    for i in (next..next + w).step_by(UNIT) {
                        groups.push((last * 6) as u8 + f);
                        preps.push(Prep {
                            ray: i as u32,
                            len: UNIT as u8,
                            uv: [dirs[i][kx], dirs[i][ky]],
                        });
                    }
                    bundled += w;
                    next += w;
                    prev = next - 1;
                    continue;
                }
                end = next + w;
            }
            for i in next..end {
                let (o, d, tm) = (origins[i], dirs[i], t_max[i]);
                // What the single ray rejects before traversal: never occluded.
                if tm.is_nan() || tm <= 0.0 {
                    continue;
                }
                // The watertight test's axes (as `WatertightRay::new` picks them): the face.
                let a = d.abs();
                let kz = if a.x >= a.y && a.x >= a.z {
                    0
                } else if a.y >= a.z {
                    1
                } else {
                    2
                };
                let swap = d[kz] < 0.0;
                let far = o + d * tm;
                let length = (o - far).abs().max_element();
                let mut apex = None;
                // Far from overflow, so `o − A`, the far end and the slack are finite.
                let sane = |v: Vec3| v.is_finite() && v.abs().max_element() < 1e30;
                if sane(o) && sane(far) && sane(d * tm) && length > 0.0 {
                    // Within the tolerance of this ray's length or of the one that set the apex
                    // (a short ray toward the light ends as near it as a long one, in world units).
                    let near = |k: usize| {
                        (far - apexes[k]).abs().max_element() <= APEX_TOL * length.max(founders[k])
                    };
                    apex = if last < apexes.len() && near(last) {
                        Some(last)
                    } else {
                        (0..apexes.len()).find(|&k| near(k))
                    };
                    if apex.is_none() && apexes.len() < MAX_APEXES {
                        apexes.push(far);
                        founders.push(length);
                        apex = Some(apexes.len() - 1);
                    }
                }
                let Some(k) = apex else {
                    fallback.push(i as u32);
                    continue;
                };
                last = k;
                bundled += 1;
                let g = (k * 6 + kz * 2 + usize::from(swap)) as u8;
                if let Some(p) = preps.last_mut()
                    && groups.last() == Some(&g)
                    && prev.wrapping_add(1) == i
                    && (p.len as usize) < UNIT
                {
                    p.len += 1;
                    prev = i;
                    continue;
                }
                let kx = (kz + 1 + usize::from(swap)) % 3;
                let ky = (kz + 2 - usize::from(swap)) % 3;
                groups.push(g);
                preps.push(Prep {
                    ray: i as u32,
                    len: 1,
                    uv: [d[kx], d[ky]],
                });
                prev = i;
            }
            next = end;
        }
        if route::occluded_batch(bundled) == Loop::Packet {
            // Too few to bundle: the packet path for the whole batch.
            count.fallback(n as u32);
            accel.batch::<WatertightRay, Occluded>(origins, dirs, t_max, false, |i, o| out[i] = o);
            return;
        }
        count.fallback(fallback.len() as u32);
        for &i in fallback.iter() {
            let i = i as usize;
            out[i] = accel.intersect_occluded(origins[i], dirs[i], t_max[i]);
        }
        sort_by_direction(preps, groups, w, sort);
        let order = &sort.order;
        // Cut into bundles of whole units of one group and lay their lanes out,
        // structure-of-arrays: bundle `b`'s row `r`, lane `l` at `(b · ROWS + r) · LANES + l`
        // (lanes past a bundle's rays repeat its first ray and are masked off). Written once for
        // the batch, so each bundle's lane loads read memory written long before (no
        // store-forwarding stalls).
        // Each bundle's units: `order[spans[b]..spans[b + 1]]`.
        let mut start = 0;
        while start < order.len() {
            let g = groups[order[start] as usize];
            let mut len = preps[order[start] as usize].len as usize;
            let mut end = start + 1;
            while end < order.len() && groups[order[end] as usize] == g {
                let more = preps[order[end] as usize].len as usize;
                if len + more > w {
                    break;
                }
                len += more;
                end += 1;
            }
            let (kz, swap) = (g as usize % 6 / 2, g % 2 == 1);
            let kx = (kz + 1 + usize::from(swap)) % 3;
            let ky = (kz + 2 - usize::from(swap)) % 3;
            bundles.push(BundleInfo {
                apex: g / 6,
                k: [kx as u8, ky as u8, kz as u8],
                len: len as u8,
            });
            spans.push(start as u32);
            start = end;
        }
        spans.push(order.len() as u32);
        // (Every element is written below before it is read: grown, never cleared.)
        if block.len() < bundles.len() * ROWS * w {
            block.resize(bundles.len() * ROWS * w, 0.0);
        }
        if lane_ray.len() < bundles.len() * w {
            lane_ray.resize(bundles.len() * w, 0);
        }
        for b in 0..bundles.len() {
            // The bundle's rays, unit after unit, then its first ray again in the spare lanes.
            let ids = &mut lane_ray[b * w..(b + 1) * w];
            let mut l = 0;
            for &u in &order[spans[b] as usize..spans[b + 1] as usize] {
                let p = &preps[u as usize];
                for ray in p.ray..p.ray + p.len as u32 {
                    if l < w {
                        ids[l] = ray;
                        l += 1;
                    }
                }
            }
            let first = ids[0];
            ids[l..].fill(first);
            let rows = &mut block[b * ROWS * w..(b + 1) * ROWS * w];
            for (l, &ray) in ids.iter().enumerate() {
                let (o, d) = (origins[ray as usize], dirs[ray as usize]);
                for a in 0..3 {
                    rows[(ROW_O + a) * w + l] = o[a];
                    rows[(ROW_D + a) * w + l] = d[a];
                }
                rows[ROW_T_MAX * w + l] = t_max[ray as usize];
            }
        }
        let empty = Entry {
            t0: V::splat(0.0),
            t1: V::splat(0.0),
            node: 0,
            mask: 0,
        };
        // Pending far children: one per tree level at most.
        let mut stack = vec![empty; MAX_DEPTH + 1];
        let rays = Rays {
            origins,
            dirs,
            t_max,
        };
        // Each light's last occluder (an index into the leaf-ordered triangles; `u32::MAX`:
        // none yet), tested first by its next bundle (Haines & Greenberg's shadow cache; the
        // bundles of a light follow each other along the Morton curve, so it is usually a
        // neighbour's occluder).
        let mut cache = [u32::MAX; MAX_APEXES];
        for (b, info) in bundles.iter().enumerate() {
            let apex = apexes[info.apex as usize].to_array();
            let cache = &mut cache[info.apex as usize % MAX_APEXES];
            let rows = &block[b * ROWS * w..(b + 1) * ROWS * w];
            let lanes = &lane_ray[b * w..(b + 1) * w];
            let hit =
                accel.bundle::<V, C>(apex, info, rows, lanes, &rays, &mut stack, cache, count);
            for (l, &ray) in lanes.iter().enumerate().take(info.len as usize) {
                if hit & (1 << l) != 0 {
                    out[ray as usize] = true;
                }
            }
        }
    }
}

/// The face (`kz · 2 + swap`, as the single ray picks its axes) shared by all `V::LANES` rays
/// `o`, `d`, `t` when every one is bundle-able (the checks of the per-ray grouping) and ends
/// within the tolerance of `apex` (set by a ray of length `founder`); `None` otherwise (the
/// rays are then grouped one by one). Grouping only: it changes no answer.
#[inline(always)]
fn uniform_face<V: Wide>(
    o: &[Vec3],
    d: &[Vec3],
    t: &[f32],
    apex: Vec3,
    founder: f32,
) -> Option<u8> {
    let w = V::LANES;
    let mut rows = [[0.0f32; 32]; 7];
    for l in 0..w {
        for a in 0..3 {
            rows[a][l] = o[l][a];
            rows[3 + a][l] = d[l][a];
        }
        rows[6][l] = t[l];
    }
    let o = [V::load(&rows[0]), V::load(&rows[1]), V::load(&rows[2])];
    let d = [V::load(&rows[3]), V::load(&rows[4]), V::load(&rows[5])];
    let tm = V::load(&rows[6]);
    let (zero, big) = (V::splat(0.0), V::splat(1e30));
    // Positive `t_max`; origin, far end and `d · t_max` finite and far from overflow (a NaN
    // fails every comparison).
    let mut ok = V::gt(tm, zero);
    let mut length = zero;
    let mut dist = zero;
    for a in 0..3 {
        let dt = d[a].mul(tm);
        let far = o[a].add(dt);
        let small = V::and(V::lt(far.abs(), big), V::lt(dt.abs(), big));
        ok = V::and(ok, V::and(V::lt(o[a].abs(), big), small));
        length = length.max(o[a].sub(far).abs());
        dist = dist.max(far.sub(V::splat(apex[a])).abs());
    }
    ok = V::and(ok, V::gt(length, zero));
    let tol = V::splat(APEX_TOL).mul(length.max(V::splat(founder)));
    ok = V::and(ok, V::le(dist, tol));
    let full = if w >= 32 { u32::MAX } else { (1u32 << w) - 1 };
    if V::bits(ok) != full {
        return None;
    }
    let a = [d[0].abs(), d[1].abs(), d[2].abs()];
    let x_max = V::bits(V::and(V::le(a[1], a[0]), V::le(a[2], a[0])));
    let kz = if x_max == full {
        0
    } else if x_max != 0 {
        return None;
    } else {
        match V::bits(V::le(a[2], a[1])) {
            b if b == full => 1,
            0 => 2,
            _ => return None,
        }
    };
    let swap = match V::bits(V::lt(d[kz], zero)) {
        0 => 0,
        b if b == full => 1,
        _ => return None,
    };
    Some((kz * 2 + swap) as u8)
}

/// The batch's columns (for the rare lanes that take the scalar triangle test).
struct Rays<'a> {
    origins: &'a [Vec3],
    dirs: &'a [Vec3],
    t_max: &'a [f32],
}

/// The order to bundle `preps` in, into `sort.order`: by group, then along a Morton curve of the
/// direction's shear (`d[kx]`, `d[ky]`) on a grid over the group's range with about `w / 8` rays
/// per cell, its cells as square as whole powers of two allow (Morton order within squares, the
/// squares in a row along the longer axis; a stable counting sort, so equal cells keep the
/// batch's order).
#[inline(always)]
fn sort_by_direction(preps: &[Prep], groups: &[u8], w: usize, sort: &mut SortScratch) {
    const GROUPS: usize = MAX_APEXES * 6;
    let mut lo = [[f32::INFINITY; 2]; GROUPS];
    let mut hi = [[f32::NEG_INFINITY; 2]; GROUPS];
    let mut size = [0usize; GROUPS];
    for (p, &g) in preps.iter().zip(groups) {
        let g = g as usize;
        size[g] += p.len as usize;
        for (k, &s) in p.uv.iter().enumerate() {
            lo[g][k] = lo[g][k].min(s);
            hi[g][k] = hi[g][k].max(s);
        }
    }
    // Grid bits per axis and first bucket of each group: about `size · 8 / w` cells, as square
    // as the group's range allows (a long, thin range would otherwise get long, thin cells, and
    // its bundles long, thin footprints).
    let mut bits = [[0u32; 2]; GROUPS];
    let mut base = [0usize; GROUPS + 1];
    for g in 0..GROUPS {
        let cells = (size[g] * 8 / w.max(1)).max(1);
        // At most 2^12 cells.
        let total = cells.next_power_of_two().trailing_zeros().min(12) as i32;
        let (sx, sy) = (hi[g][0] - lo[g][0], hi[g][1] - lo[g][1]);
        // log2 of the range's aspect ratio, whole bits (0 for an empty or degenerate range).
        let aspect = if sx > 0.0 && sy > 0.0 {
            ((sx / sy).log2().round() as i32).clamp(-total, total)
        } else if sx > 0.0 {
            total
        } else if sy > 0.0 {
            -total
        } else {
            0
        };
        let bx = ((total + aspect + 1) / 2).clamp(0, total);
        bits[g] = [bx as u32, (total - bx) as u32];
        base[g + 1] = base[g] + if size[g] > 0 { 1 << total } else { 0 };
    }
    // Cells per unit of shear, per group and axis (0 for a group of one direction).
    let mut scale = [[0.0f32; 2]; GROUPS];
    for g in 0..GROUPS {
        for k in 0..2 {
            let span = hi[g][k] - lo[g][k];
            if span > 0.0 {
                scale[g][k] = (1u32 << bits[g][k]) as f32 / span;
            }
        }
    }
    let key = |p: &Prep, g: usize| -> usize {
        let [bx, by] = bits[g];
        let cx = (((p.uv[0] - lo[g][0]) * scale[g][0]) as u32).min((1u32 << bx) - 1);
        let cy = (((p.uv[1] - lo[g][1]) * scale[g][1]) as u32).min((1u32 << by) - 1);
        // Along a Morton curve in squares of `2^m` cells, the squares in a row along the
        // longer axis.
        let m = bx.min(by);
        let low = morton2(cx & ((1 << m) - 1), cy & ((1 << m) - 1));
        let high = (cx >> m) | (cy >> m);
        base[g] + ((high << (2 * m)) | low) as usize
    };
    let SortScratch {
        counts,
        keys,
        order,
    } = sort;
    counts.clear();
    counts.resize(base[GROUPS] + 1, 0);
    keys.clear();
    keys.extend(
        preps
            .iter()
            .zip(groups)
            .map(|(p, &g)| key(p, g as usize) as u32),
    );
    for &k in keys.iter() {
        counts[k as usize + 1] += 1;
    }
    for c in 1..counts.len() {
        counts[c] += counts[c - 1];
    }
    // (Every slot is written: the counts are a permutation of `0..preps.len()`.)
    order.resize(preps.len(), 0);
    for (i, &k) in keys.iter().enumerate() {
        let slot = &mut counts[k as usize];
        order[*slot as usize] = i as u32;
        *slot += 1;
    }
}

/// Interleaves the low 16 bits of `x` and `y` (`x` in the even bits).
#[inline(always)]
fn morton2(x: u32, y: u32) -> u32 {
    let spread = |mut v: u32| {
        v &= 0xffff;
        v = (v | (v << 8)) & 0x00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333;
        (v | (v << 1)) & 0x5555_5555
    };
    spread(x) | (spread(y) << 1)
}

/// One pending far child of a bundle: its lanes' intervals, node and lane mask.
#[derive(Clone, Copy)]
struct Entry<V> {
    /// Start of each lane's interval (in `s`, the apex at 0, the ray's origin at 1).
    t0: V,
    /// End of each lane's interval.
    t1: V,
    /// Node index.
    node: u32,
    /// Lanes that enter the node.
    mask: u32,
}

/// How the lanes of a bundle move along an axis (their reversed directions' signs).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Sign {
    /// Every lane toward `+` (or along the axis's `+0`).
    Pos,
    /// Every lane toward `−`.
    Neg,
    /// Both.
    Mixed,
}

/// A bundle's lanes: the reversed rays from the apex (for culling) and the original rays'
/// watertight data with the axes permuted by the bundle's shared `(kx, ky, kz)` (for the
/// triangle test).
struct Lanes<V: Wide> {
    /// `1 / (o − A)` per axis, clamped to ±`f32::MAX` (an axis the lane does not move along).
    inv: [V; 3],
    /// `g · |inv|` per axis (clamped to `f32::MAX`): the lane's world-space slack in `s` units.
    slack: [V; 3],
    /// `inv · HI` (clamped to ±`f32::MAX`): interval *ends* are kept multiplied by `HI`.
    inv_hi: [V; 3],
    /// `slack · HI` (clamped to `f32::MAX`).
    slack_hi: [V; 3],
    /// Lanes with `inv > 0`, per axis.
    pos: [V::Mask; 3],
    /// The same as one flag per axis.
    sign: [Sign; 3],
    /// The original rays' watertight test (origins permuted to `kx`, `ky`, `kz`, shears).
    tri: WatertightLanes<V>,
    /// Original `t_max`.
    t_max: V,
}

impl KdAccel {
    /// Traces one bundle from its block of lanes `rows` (see [`ROW_O`]); `lanes` are its
    /// lanes' rays. Tests the triangle `cache` (its light's last occluder) first, then walks the
    /// tree for the lanes it leaves unoccluded, and leaves in `cache` the last occluder found.
    /// Returns the mask of occluded lanes.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn bundle<V: Wide, C: Count>(
        &self,
        apex: [f32; 3],
        info: &BundleInfo,
        rows: &[f32],
        lanes: &[u32],
        rays: &Rays<'_>,
        stack: &mut [Entry<V>],
        cache: &mut u32,
        count: &mut C,
    ) -> u32 {
        let w = V::LANES;
        let o = [
            V::load(&rows[ROW_O * w..]),
            V::load(&rows[(ROW_O + 1) * w..]),
            V::load(&rows[(ROW_O + 2) * w..]),
        ];
        let d = [
            V::load(&rows[ROW_D * w..]),
            V::load(&rows[(ROW_D + 1) * w..]),
            V::load(&rows[(ROW_D + 2) * w..]),
        ];
        let t_max = V::load(&rows[ROW_T_MAX * w..]);
        let k = info.k.map(|x| (x as usize).min(2));
        let zero = V::splat(0.0);
        // The watertight shear, as `WatertightRay::new` computes it; a lane where it is not
        // finite can hit nothing (the single ray's `None`).
        let dz = d[k[2]];
        let sz = V::splat(1.0).div(dz);
        let sx = d[k[0]].div(dz);
        let sy = d[k[1]].div(dz);
        let valid = V::and(
            V::and(V::eq(sz.sub(sz), zero), V::eq(sx.sub(sx), zero)),
            V::eq(sy.sub(sy), zero),
        );
        // Each lane's slack (see the module docs): the single ray's δ (from its own origin),
        // the far end's distance from the apex, and the rounding of the far end, `o − A` and
        // the reach itself.
        let mut reach = zero;
        let mut off = zero;
        let mut o_max = zero;
        let mut d_max = zero;
        for a in 0..3 {
            let r0 = V::splat(self.root.0[a]).sub(o[a]).abs();
            let r1 = V::splat(self.root.1[a]).sub(o[a]).abs();
            reach = reach.max(r0.max(r1));
            let far = o[a].add(d[a].mul(t_max));
            off = off.max(far.sub(V::splat(apex[a])).abs());
            o_max = o_max.max(o[a].abs());
            d_max = d_max.max(d[a].abs());
        }
        let apex_max = apex.iter().fold(0.0f32, |m, x| m.max(x.abs()));
        let scale = o_max.add(V::splat(apex_max)).add(t_max.mul(d_max));
        let grow = V::splat(DELTA * (1.0 + ROUND))
            .mul(reach)
            .add(off)
            .add(V::splat(ROUND).mul(scale))
            .add(V::splat(f32::MIN_POSITIVE));
        let (big, small) = (V::splat(f32::MAX), V::splat(-f32::MAX));
        let mut t0 = zero;
        let mut t1 = V::splat(1.0);
        let mut inv = [zero; 3];
        let mut slack = [zero; 3];
        let mut inv_hi = [zero; 3];
        let mut slack_hi = [zero; 3];
        let hi = V::splat(HI);
        let mut pos = [V::lt(zero, zero); 3];
        let mut sign = [Sign::Mixed; 3];
        let filled = if info.len as usize >= 32 {
            u32::MAX
        } else {
            (1u32 << info.len) - 1
        };
        for a in 0..3 {
            let rev = o[a].sub(V::splat(apex[a]));
            let i = V::splat(1.0).div(rev).max(small).min(big);
            let s = grow.mul(i.abs()).min(big);
            inv[a] = i;
            slack[a] = s;
            inv_hi[a] = i.mul(hi).max(small).min(big);
            slack_hi[a] = s.mul(hi).min(big);
            pos[a] = V::gt(i, zero);
            let p = V::bits(pos[a]) & filled;
            sign[a] = if p == filled {
                Sign::Pos
            } else if p == 0 {
                Sign::Neg
            } else {
                Sign::Mixed
            };
            // Clip to the root box grown by the slack.
            let ta = V::splat(self.root.0[a] - apex[a]).mul(i);
            let tb = V::splat(self.root.1[a] - apex[a]).mul(i);
            t0 = t0.max(ta.min(tb).sub(s));
            t1 = t1.min(ta.max(tb).add(s));
        }
        // From here on a lane's interval end is kept multiplied by `HI`: "not empty up to the
        // relative slack" is then one comparison, `t0 <= t1`.
        let t1 = t1.mul(hi);
        let entered = V::and(V::le(t0, t1), valid);
        let mask = V::bits(entered) & filled;
        count.bundle(info.len as u32);
        if mask == 0 {
            return 0;
        }
        let ln = Lanes {
            inv,
            slack,
            inv_hi,
            slack_hi,
            pos,
            sign,
            tri: WatertightLanes {
                o: [o[k[0]], o[k[1]], o[k[2]]],
                sx,
                sy,
                sz,
            },
            t_max,
        };
        // The cached occluder first: a lane its exact test hits is occluded whatever the walk
        // would find (the single ray's answer is "some triangle passes the test"), and the walk
        // then carries only the others.
        let mut cached = 0;
        if let Some(tri) = self.tris.get(*cache as usize) {
            cached = tri_hits(&ln, k, tri, mask, rays, lanes);
            count.cached(mask.count_ones(), cached.count_ones());
            if cached == mask {
                return cached;
            }
        }
        let start = Entry {
            t0,
            t1,
            node: 0,
            mask: mask & !cached,
        };
        cached | self.walk_bundle(apex, k, &ln, rays, lanes, start, stack, cache, count)
    }

    /// The bundle traversal from `start` (see the module docs); returns the occluded lanes.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn walk_bundle<V: Wide, C: Count>(
        &self,
        apex: [f32; 3],
        k: [usize; 3],
        ln: &Lanes<V>,
        rays: &Rays<'_>,
        lanes: &[u32],
        start: Entry<V>,
        stack: &mut [Entry<V>],
        cache: &mut u32,
        count: &mut C,
    ) -> u32 {
        let nodes = &self.tree.nodes[..];
        // Whether node `i` is a leaf without triangles.
        let empty = |i: u32| {
            nodes
                .get(i as usize)
                .is_some_and(|c| c.is_leaf() && c.count() == 0)
        };
        let mut sp = 0usize;
        let mut alive = start.mask;
        let mut hit = 0u32;
        let mut e = start;
        loop {
            // Descend to a leaf.
            let leaf = loop {
                let Some(&n) = nodes.get(e.node as usize) else {
                    break None;
                };
                if n.is_leaf() {
                    break Some(n);
                }
                count.node();
                let axis = n.axis().min(2);
                let d = n.split() - apex[axis];
                // Each lane's part below and above the plane (within the slack): `m0..` is
                // beyond the plane's far side of the slack, `..m1` before its near side (an end,
                // so times `HI`: `(tp + slack) · HI` from the prescaled reciprocal and slack).
                let dv = V::splat(d);
                let m0 = e.t0.max(dv.mul(ln.inv[axis]).sub(ln.slack[axis]));
                let m1 = e.t1.min(dv.mul(ln.inv_hi[axis]).add(ln.slack_hi[axis]));
                let (lo0, lo1, hi0, hi1) = match ln.sign[axis] {
                    Sign::Pos => (e.t0, m1, m0, e.t1),
                    Sign::Neg => (m0, e.t1, e.t0, m1),
                    Sign::Mixed => {
                        let p = ln.pos[axis];
                        (
                            V::select(p, e.t0, m0),
                            V::select(p, m1, e.t1),
                            V::select(p, m0, e.t0),
                            V::select(p, e.t1, m1),
                        )
                    }
                };
                let lo_m = V::bits(V::le(lo0, lo1)) & e.mask;
                let hi_m = V::bits(V::le(hi0, hi1)) & e.mask;
                let below = Entry {
                    t0: lo0,
                    t1: lo1,
                    node: e.node + 1,
                    mask: lo_m,
                };
                let above = Entry {
                    t0: hi0,
                    t1: hi1,
                    node: n.right(),
                    mask: hi_m,
                };
                // The apex's side first.
                let (near, far) = if d >= 0.0 {
                    (below, above)
                } else {
                    (above, below)
                };
                if near.mask != 0 && far.mask != 0 {
                    // Where both children are entered, one that is an empty leaf (it holds
                    // nothing to test) is neither entered nor pushed: no lane's answer changes,
                    // one push and pop fewer.
                    if empty(near.node) {
                        e = far;
                    } else {
                        // (Never full: one entry per level of a tree at most `MAX_DEPTH` deep.)
                        if sp < stack.len() && !empty(far.node) {
                            stack[sp] = far;
                            sp += 1;
                        }
                        e = near;
                    }
                } else if near.mask != 0 {
                    e = near;
                } else if far.mask != 0 {
                    e = far;
                } else {
                    break None;
                }
            };
            if let Some(n) = leaf {
                let s = n.offset() as usize;
                let end = s + n.count() as usize;
                if let Some(tris) = self.tris.get(s..end) {
                    let mut live = e.mask & alive;
                    count.leaf(tris.len() as u32, live.count_ones());
                    for (j, tri) in tris.iter().enumerate() {
                        count.tri();
                        let h = tri_hits(ln, k, tri, live, rays, lanes);
                        if h != 0 {
                            *cache = (s + j) as u32;
                            hit |= h;
                            live &= !h;
                            alive &= !h;
                            if live == 0 {
                                break;
                            }
                        }
                    }
                    if alive == 0 {
                        return hit;
                    }
                }
            }
            // Pop the next entry with a live lane.
            loop {
                if sp == 0 {
                    return hit;
                }
                sp -= 1;
                e = stack[sp];
                e.mask &= alive;
                if e.mask != 0 {
                    break;
                }
            }
        }
    }
}

/// The lanes of `live` whose original ray hits triangle `tri` with `0 < t < t_max`: the lane
/// watertight test ([`WatertightLanes::hit`]); a lane on an edge takes the scalar test (its
/// `f64` fallback).
#[inline(always)]
fn tri_hits<V: Wide>(
    ln: &Lanes<V>,
    k: [usize; 3],
    tri: &[[f32; 3]; 3],
    live: u32,
    rays: &Rays<'_>,
    lanes: &[u32],
) -> u32 {
    let [p0, p1, p2] = tri;
    let (kx, ky, kz) = (k[0], k[1], k[2]);
    let a = [p0[kx], p0[ky], p0[kz]];
    let b = [p1[kx], p1[ky], p1[kz]];
    let c = [p2[kx], p2[ky], p2[kz]];
    let h = ln.tri.hit(&a, &b, &c, live, ln.t_max);
    let mut hits = h.hit;
    let mut z = h.edge;
    while z != 0 {
        let l = z.trailing_zeros() as usize;
        z &= z - 1;
        let r = lanes[l] as usize;
        let hit = WatertightRay::new(rays.origins[r], rays.dirs[r])
            .and_then(|ray| ray.intersect(*p0, *p1, *p2, rays.t_max[r]));
        if hit.is_some() {
            hits |= 1 << l;
        }
    }
    hits
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::BundleCounts;
    use crate::accel::kdtree::{BuildMethod, KdAccel, KdTree};
    use crate::geometry::triangle::WatertightRay;
    use crate::mesh::TriangleMesh;
    use crate::sampling::Rng;
    use crate::simd::Level;

    /// Uniform in `[-1, 1)³`.
    fn vec(rng: &mut Rng) -> Vec3 {
        Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        )
    }

    /// Random triangles with some lying in axis planes through the lights' coordinates, so split
    /// planes pass through the apexes.
    fn soup(rng: &mut Rng, lights: &[Vec3]) -> TriangleMesh {
        let (mut v, mut idx) = (vec![], vec![]);
        for k in 0..3000u32 {
            let c = vec(rng) * 4.0;
            let mut tri = [c, c + vec(rng) * 0.5, c + vec(rng) * 0.5];
            if k % 5 == 0 {
                let axis = (k / 5 % 3) as usize;
                let plane = lights[k as usize % lights.len()][axis];
                for p in &mut tri {
                    p[axis] = plane;
                }
            }
            v.extend(tri.map(|p| p.to_array()));
            idx.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        TriangleMesh::new(v, idx)
    }

    #[test]
    fn bundles_match_single_rays_with_several_lights_and_bad_rays() {
        let mut rng = Rng(0xb0d1e5);
        let lights = [
            Vec3::new(0.3, 1.7, -0.2),
            Vec3::new(-2.0, 0.5, 1.0),
            Vec3::new(0.0, 0.0, 0.0),
        ];
        let mesh = soup(&mut rng, &lights);
        for method in [BuildMethod::Sah, BuildMethod::Midpoint] {
            let tree = KdAccel::new(KdTree::build(&mesh, method), &mesh);
            let (mut o, mut d, mut tm) = (vec![], vec![], vec![]);
            for i in 0..20_000 {
                // Shadow rays as the shade stage makes them, hit-major over the lights, with
                // a few of every kind of bad ray and rays ending nowhere in particular.
                let origin = vec(&mut rng) * 5.0;
                let light = lights[i % lights.len()];
                let to = light - origin;
                let (mut dir, mut t) = (to.normalize(), to.length() * (1.0 - 1e-6));
                match i % 97 {
                    0 => t = f32::NAN,
                    1 => t = 0.0,
                    2 => dir = Vec3::ZERO,
                    3 => dir = Vec3::new(f32::NAN, 0.0, 1.0),
                    4 => dir = vec(&mut rng),
                    5 => dir[i / 97 % 3] = 0.0,
                    _ => {}
                }
                o.push(origin);
                d.push(dir);
                tm.push(t);
            }
            let want: Vec<bool> = (0..o.len())
                .map(|i| tree.intersect_occluded(o[i], d[i], tm[i]))
                .collect();
            let occluded = want.iter().filter(|&&x| x).count();
            assert!(occluded > o.len() / 10 && occluded < o.len() * 9 / 10);
            for level in Level::supported() {
                for chunk in [4096, 1000, 37, 5] {
                    let mut got = vec![false; o.len()];
                    let mut total = BundleCounts::default();
                    for (c, out) in got.chunks_mut(chunk).enumerate() {
                        let r = c * chunk..c * chunk + out.len();
                        let counts = tree.intersect_occluded_batch_counted(
                            level,
                            &o[r.clone()],
                            &d[r.clone()],
                            &tm[r],
                            out,
                        );
                        total.bundles += counts.bundles;
                        total.fallback += counts.fallback;
                    }
                    for i in 0..o.len() {
                        assert_eq!(
                            got[i], want[i],
                            "{level:?} {method:?} chunk {chunk} ray {i}"
                        );
                    }
                    if chunk >= 1000 {
                        assert!(total.bundles > 0, "{level:?}: no bundles");
                        // Only the rays that end nowhere in particular go through packets.
                        assert!(total.fallback < o.len() as u64 * 6 / 100, "{total:?}");
                    } else if chunk == 5 {
                        assert_eq!(total.bundles, 0, "too few rays to bundle");
                    }
                }
            }
        }
    }

    #[test]
    fn a_blocker_at_the_light_and_one_at_the_origin_are_told_apart() {
        // A unit quad in the plane x = 0 (two triangles).
        let mesh = TriangleMesh::new(
            vec![
                [0.0, -1.0, -1.0],
                [0.0, 1.0, -1.0],
                [0.0, 1.0, 1.0],
                [0.0, -1.0, 1.0],
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let tree = KdAccel::new(KdTree::build(&mesh, BuildMethod::Sah), &mesh);
        let mut rows = vec![];
        for k in 0..64 {
            let y = (k as f32 / 32.0 - 1.0) * 0.9;
            // Through the quad toward a light beyond it; a light just short of it; from the
            // quad's own plane (t = 0 is not a hit); toward a light on the quad's plane.
            for (origin, light) in [
                (Vec3::new(-1.0, y, 0.2), Vec3::new(2.0, 0.1, 0.0)),
                (Vec3::new(-1.0, y, 0.2), Vec3::new(-1e-3, 0.1, 0.0)),
                (Vec3::new(0.0, y, 0.2), Vec3::new(2.0, 0.1, 0.0)),
                (Vec3::new(-1.0, y, 0.2), Vec3::new(0.0, 0.1, 0.0)),
            ] {
                let to = light - origin;
                rows.push((origin, to.normalize(), to.length()));
            }
        }
        let (o, d, t): (Vec<_>, Vec<_>, Vec<_>) = rows.into_iter().fold(
            (vec![], vec![], vec![]),
            |(mut o, mut d, mut t), (a, b, c)| {
                o.push(a);
                d.push(b);
                t.push(c);
                (o, d, t)
            },
        );
        for level in Level::supported() {
            let mut got = vec![false; o.len()];
            tree.intersect_occluded_batch_counted(level, &o, &d, &t, &mut got);
            for i in 0..o.len() {
                let want = tree.intersect_occluded(o[i], d[i], t[i]);
                assert_eq!(got[i], want, "{level:?} ray {i}");
                let single = WatertightRay::new(o[i], d[i]).is_some();
                assert!(single);
            }
            assert!(
                got.iter().step_by(4).all(|&x| x),
                "through the quad: blocked"
            );
            assert!(
                !got.iter().skip(1).step_by(4).any(|&x| x),
                "short of it: free"
            );
        }
    }
}
