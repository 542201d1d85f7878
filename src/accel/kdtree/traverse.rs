//! Ray traversal of the kD tree: the closest-hit and occluded (any-hit) kernels.
//!
//! Reads the tree's nodes and leaf-ordered triangle copy, and one ray (origin, unnormalised
//! direction, `t_max`). Front-to-back, stack-based (fixed array, no allocation per ray), with a
//! reciprocal direction and the triangle test's per-ray data (the watertight shear by default)
//! computed once per ray. Generic over the triangle test ([`TriangleRay`]), monomorphised.
//!
//! Robustness: slab and split-plane distances are computed as `(plane - o) * (1 / d)`. For a
//! `±0.0` component this is `±inf`, which orders the children correctly; the only NaN case
//! (`0 * inf`, origin exactly on the plane of a parallel ray) is detected and both children are
//! visited. The builders put a triangle that only touches a split plane on one side, so a hit
//! computed with rounding error may lie a hair across the plane from the leaf listing it. Each
//! side is therefore entered when the ray comes within `δ` of it (world space, per ray:
//! `DELTA ·` the L∞ distance from the origin to the farthest root corner, since rounding in
//! `p - o` scales with that distance, not with the coordinates' magnitude), plus a small relative
//! slack (`SLACK`) on `t` for the plane distances and the hit's own `t`. Measured on Sibenik,
//! both slacks together change the visited node count by well under 1 %. A node is skipped only when its (conservative) entry
//! distance is beyond the best hit: ties at leaf boundaries still find the lowest triangle index
//! among equal-`t` hits.
//!
//! Batch queries ([`KdTree::intersect_closest_batch`], [`KdTree::intersect_occluded_batch`])
//! trace groups of 4 consecutive rays with equal direction signs as a packet (Wald 2004 style,
//! per-lane active mask): one node fetch and one 4-wide SSE2 step per node for the packet
//! (scalar lanes on other architectures), and each triangle tested against the live lanes at
//! once. Every lane makes exactly its single ray's decisions (same interval formulas, same
//! visiting order, same culling; where lanes disagree on the near child of a closest-hit packet
//! each lane finishes that subtree with the single-ray loop), so results are bit-identical to
//! the single-ray queries.

use glam::Vec3;

use super::{KdTree, MAX_DEPTH, TriHit};
use crate::geometry::triangle::{MollerTrumboreRay, TriangleRay, WatertightRay};
use crate::mesh::TriangleMesh;
use crate::scene::TriangleTest;

/// Relative slack on ray-interval comparisons (plane distances and hit `t` carry a few ulps).
const SLACK: f32 = 1e-4;
const HI: f32 = 1.0 + SLACK;
/// World-space slack around split planes, relative to the coordinates' magnitude.
const DELTA: f32 = 1.0 / (1 << 18) as f32;

/// One pending far child: node index and ray interval.
#[derive(Clone, Copy, Default)]
struct Entry {
    node: u32,
    t0: f32,
    t1: f32,
}

/// Everything a traversal needs per ray.
struct Ray<T> {
    /// The triangle test's per-ray data.
    test: T,
    /// Origin; the 4th lane pads the arrays so a node's 2-bit axis field indexes them without
    /// a bounds check.
    origin: [f32; 4],
    /// `1 / dir`, cached so plane distances are one subtract and one multiply.
    inv: [f32; 4],
    /// `δ · |1 / dir|` per axis (clamped to `f32::MAX`): the world-space slack in `t` units.
    slack: [f32; 4],
}

impl<T: TriangleRay> Ray<T> {
    #[inline(always)]
    fn new(origin: Vec3, dir: Vec3, root: &([f32; 3], [f32; 3])) -> Option<Ray<T>> {
        let test = T::prepare(origin, dir)?;
        let inv = Vec3::ONE / dir;
        // Rounding in `p - o` and everything after it scales with the distance from the
        // origin to the geometry, bounded by the farthest root corner (L∞).
        let reach = (Vec3::from_array(root.0) - origin)
            .abs()
            .max((Vec3::from_array(root.1) - origin).abs())
            .max_element();
        let delta = DELTA * reach;
        Some(Ray {
            test,
            origin: origin.extend(0.0).to_array(),
            inv: inv.extend(0.0).to_array(),
            slack: (inv.abs() * delta)
                .min(Vec3::splat(f32::MAX))
                .extend(0.0)
                .to_array(),
        })
    }

    /// Clips `[0, t_max]` to the root box grown by `δ`; `None` when the ray misses it. NaN slab
    /// distances (origin on a face of a parallel ray) are ignored by `max`/`min`.
    #[inline(always)]
    fn clip(&self, bx: &([f32; 3], [f32; 3]), t_max: f32) -> Option<(f32, f32)> {
        let mut t0 = 0.0f32;
        let mut t1 = t_max;
        for a in 0..3 {
            let ta = (bx.0[a] - self.origin[a]) * self.inv[a];
            let tb = (bx.1[a] - self.origin[a]) * self.inv[a];
            let (near, far) = (ta.min(tb), ta.max(tb));
            t0 = t0.max(near - self.slack[a]);
            t1 = t1.min(far + self.slack[a]);
        }
        (t0 <= t1 * HI).then_some((t0.max(0.0), t1))
    }
}

/// What a leaf visit tells the traversal loop.
trait Visitor {
    /// Tests the leaf's entries `start..end`; returns true to stop traversal.
    fn leaf(&mut self, tree: &KdTree, tris: &[[[f32; 3]; 3]], start: usize, end: usize) -> bool;
    /// Tests one triangle (vertices, index) as `leaf` does for each of its entries, in order;
    /// returns true to stop traversal.
    fn tri(&mut self, verts: &[[f32; 3]; 3], tri: u32) -> bool;
    /// The `t_max` to test the next triangle with.
    fn limit(&self) -> f32;
    /// Takes a hit `t < limit()` on triangle `tri`; returns true to stop traversal.
    fn accept(&mut self, t: f32, tri: u32) -> bool;
    /// Current cull distance (nodes entered beyond it are skipped).
    fn cull(&self) -> f32;
    /// True when the answer does not depend on the order leaves are visited in (no culling:
    /// any-hit), so a packet may visit children in any order.
    const ORDER_FREE: bool;
}

struct Closest<'a, T> {
    ray: &'a T,
    t_max: f32,
    best: Option<TriHit>,
}

impl<T: TriangleRay> Visitor for Closest<'_, T> {
    #[inline(always)]
    fn leaf(&mut self, tree: &KdTree, tris: &[[[f32; 3]; 3]], start: usize, end: usize) -> bool {
        let (Some(tris), Some(ids)) = (tris.get(start..end), tree.tri_indices.get(start..end))
        else {
            return false;
        };
        for (verts, &tri) in tris.iter().zip(ids) {
            self.tri(verts, tri);
        }
        false
    }

    #[inline(always)]
    fn tri(&mut self, &[p0, p1, p2]: &[[f32; 3]; 3], tri: u32) -> bool {
        match self.ray.hit(p0, p1, p2, self.limit()) {
            Some(t) => self.accept(t, tri),
            None => false,
        }
    }

    #[inline(always)]
    fn limit(&self) -> f32 {
        // Accept equal t too, so ties can go to the lower index.
        match self.best {
            Some(b) => b.t.next_up(),
            None => self.t_max,
        }
    }

    #[inline(always)]
    fn accept(&mut self, t: f32, tri: u32) -> bool {
        if self.best.is_none_or(|b| t < b.t || tri < b.tri) {
            self.best = Some(TriHit { t, tri });
        }
        false
    }

    const ORDER_FREE: bool = false;

    #[inline(always)]
    fn cull(&self) -> f32 {
        match self.best {
            Some(b) => b.t * HI,
            None => f32::INFINITY,
        }
    }
}

struct Occluded<'a, T> {
    ray: &'a T,
    t_max: f32,
}

impl<T: TriangleRay> Visitor for Occluded<'_, T> {
    #[inline(always)]
    fn leaf(&mut self, _: &KdTree, tris: &[[[f32; 3]; 3]], start: usize, end: usize) -> bool {
        let Some(tris) = tris.get(start..end) else {
            return false;
        };
        for verts in tris {
            if self.tri(verts, 0) {
                return true;
            }
        }
        false
    }

    #[inline(always)]
    fn tri(&mut self, &[p0, p1, p2]: &[[f32; 3]; 3], _: u32) -> bool {
        self.ray.hit(p0, p1, p2, self.t_max).is_some()
    }

    #[inline(always)]
    fn limit(&self) -> f32 {
        self.t_max
    }

    #[inline(always)]
    fn accept(&mut self, _: f32, _: u32) -> bool {
        true
    }

    const ORDER_FREE: bool = true;

    #[inline(always)]
    fn cull(&self) -> f32 {
        f32::INFINITY
    }
}

impl KdTree {
    /// Closest hit with `0 < t < t_max` (strict), `t` in units of `dir`'s length (`dir` need not
    /// be normalised). Equal `t` resolves to the lowest triangle index, exactly as the
    /// brute-force reference [`crate::geometry::triangle::intersect_all_closest`] does, with
    /// bit-identical `t`. Uses the watertight test.
    #[inline]
    pub fn intersect_closest(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> Option<TriHit> {
        self.closest::<WatertightRay>(mesh, origin, dir, t_max)
    }

    /// True when any triangle is hit with `0 < t < t_max`; stops at the first hit found. Uses
    /// the watertight test.
    #[inline]
    pub fn intersect_occluded(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> bool {
        self.occluded::<WatertightRay>(mesh, origin, dir, t_max)
    }

    /// [`KdTree::intersect_closest`] with a chosen triangle test (for the error report).
    pub fn intersect_closest_with(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        test: TriangleTest,
    ) -> Option<TriHit> {
        match test {
            TriangleTest::Watertight => self.closest::<WatertightRay>(mesh, origin, dir, t_max),
            TriangleTest::MollerTrumbore => {
                self.closest::<MollerTrumboreRay>(mesh, origin, dir, t_max)
            }
        }
    }

    /// [`KdTree::intersect_occluded`] with a chosen triangle test (for the error report).
    pub fn intersect_occluded_with(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        test: TriangleTest,
    ) -> bool {
        match test {
            TriangleTest::Watertight => self.occluded::<WatertightRay>(mesh, origin, dir, t_max),
            TriangleTest::MollerTrumbore => {
                self.occluded::<MollerTrumboreRay>(mesh, origin, dir, t_max)
            }
        }
    }

    #[inline(always)]
    fn closest<T: TriangleRay>(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> Option<TriHit> {
        let prep = self.prepared(mesh);
        let ray = Ray::<T>::new(origin, dir, &prep.root)?;
        let mut v = Closest {
            ray: &ray.test,
            t_max,
            best: None,
        };
        self.traverse(prep, &ray, t_max, &mut v);
        v.best
    }

    #[inline(always)]
    fn occluded<T: TriangleRay>(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> bool {
        let prep = self.prepared(mesh);
        let Some(ray) = Ray::<T>::new(origin, dir, &prep.root) else {
            return false;
        };
        let mut v = Occluded {
            ray: &ray.test,
            t_max,
        };
        self.traverse(prep, &ray, t_max, &mut v)
    }

    /// Front-to-back traversal; returns true if the visitor asked to stop.
    #[inline(always)]
    fn traverse<T: TriangleRay, V: Visitor>(
        &self,
        prep: &super::Prepared,
        ray: &Ray<T>,
        t_max: f32,
        v: &mut V,
    ) -> bool {
        if t_max.is_nan() || t_max <= 0.0 {
            return false;
        }
        let Some((t0, t1)) = ray.clip(&prep.root, t_max) else {
            return false;
        };
        self.walk(prep, ray, Entry { node: 0, t0, t1 }, v)
    }

    /// Front-to-back traversal of the subtree `start.node` over the ray interval
    /// `start.t0..start.t1`; returns true if the visitor asked to stop. A whole-tree traversal
    /// is `walk` from the root; the packet kernels also call it to finish one lane of a subtree
    /// exactly as a single ray would (a single ray processes a subtree it enters completely
    /// before popping anything pushed earlier).
    #[inline(always)]
    fn walk<T: TriangleRay, V: Visitor>(
        &self,
        prep: &super::Prepared,
        ray: &Ray<T>,
        start: Entry,
        v: &mut V,
    ) -> bool {
        let nodes = &self.nodes[..];
        let mut stack = [Entry::default(); MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut cur = start;
        loop {
            let mut e = cur;
            // Descend to a leaf.
            let leaf = loop {
                let Some(&n) = nodes.get(e.node as usize) else {
                    break None;
                };
                if n.is_leaf() {
                    break Some(n);
                }
                let axis = n.axis();
                let split = n.split();
                let oa = ray.origin[axis];
                let ia = ray.inv[axis];
                let st = ray.slack[axis];
                let left = e.node + 1;
                let right = n.right();
                let tp = (split - oa) * ia;
                let (near, far) = if oa < split || (oa == split && ia < 0.0) {
                    (left, right)
                } else {
                    (right, left)
                };
                // Parts of the ray interval on (or within δ of) each side.
                let (near_t1, far_t0, far_t1, near_used, far_used) = if tp > 0.0 {
                    let far_t0 = e.t0.max(tp - st);
                    (
                        e.t1.min(tp + st),
                        far_t0,
                        e.t1,
                        e.t0 <= (tp + st) * HI,
                        far_t0 <= e.t1 * HI,
                    )
                } else if tp <= 0.0 {
                    let far_t1 = e.t1.min(tp + st);
                    (e.t1, e.t0, far_t1, true, e.t0 <= far_t1 * HI)
                } else {
                    // NaN: a parallel ray lying in the split plane; both sides.
                    (e.t1, e.t0, e.t1, true, true)
                };
                if near_used && far_used {
                    if sp < stack.len() {
                        stack[sp] = Entry {
                            node: far,
                            t0: far_t0,
                            t1: far_t1,
                        };
                        sp += 1;
                    }
                    e.node = near;
                    e.t1 = near_t1;
                } else if near_used {
                    e.node = near;
                } else {
                    e.node = far;
                    e.t0 = far_t0;
                }
            };
            if let Some(n) = leaf {
                let start = n.offset() as usize;
                let end = start + n.count() as usize;
                if v.leaf(self, &prep.tris, start, end) {
                    return true;
                }
            }
            // Pop the next entry that can still hold a closer (or tying) hit.
            loop {
                if sp == 0 {
                    return false;
                }
                sp -= 1;
                cur = stack[sp];
                if cur.t0 <= v.cull() {
                    break;
                }
            }
        }
    }
}

/// Rays per packet.
const LANES: usize = 4;

/// One pending far child of a packet: node, the lanes that enter it and their intervals.
/// Intervals first and 16-byte aligned, so a whole-entry copy and the 4-wide loads of `t0`,
/// `t1` line up (a load straddling two smaller stores stalls store forwarding).
#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
struct PacketEntry {
    t0: [f32; LANES],
    t1: [f32; LANES],
    node: u32,
    mask: u8,
}

/// Four rays' traversal data, structure-of-arrays (`[axis][lane]`; the 4th axis pads so a
/// node's 2-bit axis field indexes without a bounds check).
struct PacketRays {
    origin: [[f32; LANES]; 4],
    inv: [[f32; LANES]; 4],
    slack: [[f32; LANES]; 4],
}

impl PacketRays {
    fn new<T>(rays: &[Ray<T>; LANES]) -> PacketRays {
        let mut p = PacketRays {
            origin: [[0.0; LANES]; 4],
            inv: [[0.0; LANES]; 4],
            slack: [[0.0; LANES]; 4],
        };
        for (k, r) in rays.iter().enumerate() {
            for a in 0..4 {
                p.origin[a][k] = r.origin[a];
                p.inv[a][k] = r.inv[a];
                p.slack[a][k] = r.slack[a];
            }
        }
        p
    }
}

/// One inner-node step for 4 lanes, oriented near/far per lane (near = the side of the
/// origin): which lanes enter each child and their intervals (near starts at the lane's `t0`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Step4 {
    near_left: u8,
    go_near: u8,
    go_far: u8,
    n_t1: [f32; LANES],
    f_t0: [f32; LANES],
    f_t1: [f32; LANES],
}

/// [`Step4`] lane by lane with exactly the single-ray formulas of [`KdTree::walk`]: when both
/// children are used, near gets `(t0, near_t1)` and far `(far_t0, far_t1)`; near only keeps
/// `(t0, t1)`; otherwise the ray goes far with `(far_t0, t1)`.
#[cfg_attr(all(target_arch = "x86_64", not(test)), allow(dead_code))]
#[inline(always)]
fn step4_scalar(
    split: f32,
    oa: &[f32; LANES],
    ia: &[f32; LANES],
    st: &[f32; LANES],
    t0s: &[f32; LANES],
    t1s: &[f32; LANES],
) -> Step4 {
    let mut s = Step4 {
        near_left: 0,
        go_near: 0,
        go_far: 0,
        n_t1: *t1s,
        f_t0: *t0s,
        f_t1: *t1s,
    };
    for k in 0..LANES {
        let (t0, t1) = (t0s[k], t1s[k]);
        let tp = (split - oa[k]) * ia[k];
        let nl = oa[k] < split || (oa[k] == split && ia[k] < 0.0);
        let (near_t1, far_t0, far_t1, near_used, far_used) = if tp > 0.0 {
            let far_t0 = t0.max(tp - st[k]);
            (
                t1.min(tp + st[k]),
                far_t0,
                t1,
                t0 <= (tp + st[k]) * HI,
                far_t0 <= t1 * HI,
            )
        } else if tp <= 0.0 {
            let far_t1 = t1.min(tp + st[k]);
            (t1, t0, far_t1, true, t0 <= far_t1 * HI)
        } else {
            (t1, t0, t1, true, true)
        };
        let both = near_used && far_used;
        (s.n_t1[k], s.f_t0[k], s.f_t1[k]) = if both {
            (near_t1, far_t0, far_t1)
        } else {
            (t1, far_t0, t1)
        };
        let bit = 1u8 << k;
        s.near_left |= if nl { bit } else { 0 };
        s.go_near |= if near_used { bit } else { 0 };
        s.go_far |= if both || !near_used { bit } else { 0 };
    }
    s
}

/// [`step4_scalar`] with SSE2 (always available on x86_64), branch-free. `minps`/`maxps`
/// differ from `f32::min`/`max` only for NaN operands and the sign of a zero result; interval
/// ends and `tp ± δ` are never NaN on the lanes where they are selected (`t0`, `t1` come from
/// non-NaN clips, `δ` is clamped, `tp` is NaN only on the lanes that take neither branch), and
/// a zero's sign never changes a comparison, so the decisions are the scalar ones. (Merged
/// forms: `far_t0` is `t0` unless `tp > 0` and `far_t1` is `t1` unless `tp <= 0`, so one
/// comparison `far_t0 <= far_t1 · HI` covers both branches of `far_used`.)
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn step4(
    split: f32,
    oa: &[f32; LANES],
    ia: &[f32; LANES],
    st: &[f32; LANES],
    t0s: &[f32; LANES],
    t1s: &[f32; LANES],
) -> Step4 {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of the x86_64 baseline; loads and stores are unaligned and on
    // 4-element arrays.
    unsafe {
        let blend =
            |m: __m128, a: __m128, b: __m128| _mm_or_ps(_mm_and_ps(m, a), _mm_andnot_ps(m, b));
        let t0 = _mm_loadu_ps(t0s.as_ptr());
        let t1 = _mm_loadu_ps(t1s.as_ptr());
        let o = _mm_loadu_ps(oa.as_ptr());
        let i = _mm_loadu_ps(ia.as_ptr());
        let s = _mm_loadu_ps(st.as_ptr());
        let sp = _mm_set1_ps(split);
        let zero = _mm_setzero_ps();
        let hi = _mm_set1_ps(HI);
        let tp = _mm_mul_ps(_mm_sub_ps(sp, o), i);
        let pos = _mm_cmpgt_ps(tp, zero);
        let nonpos = _mm_cmple_ps(tp, zero);
        let nan = _mm_cmpunord_ps(tp, tp);
        let tps = _mm_add_ps(tp, s);
        let tms = _mm_sub_ps(tp, s);
        let t1_tps = _mm_min_ps(t1, tps);
        let far_t0 = blend(pos, _mm_max_ps(t0, tms), t0);
        let far_t1 = blend(nonpos, t1_tps, t1);
        // near_used = !pos || t0 <= (tp + δ)·HI, as a mask of lanes where it fails.
        let near_unused = _mm_andnot_ps(_mm_cmple_ps(t0, _mm_mul_ps(tps, hi)), pos);
        let far_used = _mm_or_ps(_mm_cmple_ps(far_t0, _mm_mul_ps(far_t1, hi)), nan);
        // both = near_used && far_used
        let both = _mm_andnot_ps(near_unused, far_used);
        let mut out = Step4 {
            near_left: _mm_movemask_ps(_mm_or_ps(
                _mm_cmplt_ps(o, sp),
                _mm_and_ps(_mm_cmpeq_ps(o, sp), _mm_cmplt_ps(i, zero)),
            )) as u8,
            go_near: !(_mm_movemask_ps(near_unused) as u8) & 0xf,
            go_far: (_mm_movemask_ps(far_used) | _mm_movemask_ps(near_unused)) as u8,
            n_t1: [0.0; LANES],
            f_t0: [0.0; LANES],
            f_t1: [0.0; LANES],
        };
        _mm_storeu_ps(
            out.n_t1.as_mut_ptr(),
            blend(_mm_and_ps(both, pos), t1_tps, t1),
        );
        _mm_storeu_ps(out.f_t0.as_mut_ptr(), far_t0);
        _mm_storeu_ps(
            out.f_t1.as_mut_ptr(),
            blend(_mm_and_ps(both, nonpos), t1_tps, t1),
        );
        out
    }
}

/// Scalar [`step4`] on other architectures.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn step4(
    split: f32,
    oa: &[f32; LANES],
    ia: &[f32; LANES],
    st: &[f32; LANES],
    t0s: &[f32; LANES],
    t1s: &[f32; LANES],
) -> Step4 {
    step4_scalar(split, oa, ia, st, t0s, t1s)
}

/// A triangle test that can test one triangle against the 4 rays of a packet at once, with
/// results bit-identical to its single-ray test on every lane.
trait PacketTest: TriangleRay + Sized {
    /// Per-packet data (computed once per packet).
    type Pre;
    /// Prepares the packet's live lanes `live`.
    fn pre(rays: &[Ray<Self>; LANES], live: u8) -> Self::Pre;
    /// Tests `verts` against the live lanes, lane `k` with `t_max = limits[k]`: returns the
    /// mask of lanes hit and their `t`.
    fn hit4(
        pre: &Self::Pre,
        rays: &[Ray<Self>; LANES],
        live: u8,
        verts: &[[f32; 3]; 3],
        limits: &[f32; LANES],
    ) -> (u8, [f32; LANES]);
}

/// Lane by lane.
#[inline(always)]
fn hit4_scalar<T: TriangleRay>(
    rays: &[Ray<T>; LANES],
    live: u8,
    &[p0, p1, p2]: &[[f32; 3]; 3],
    limits: &[f32; LANES],
) -> (u8, [f32; LANES]) {
    let mut mask = 0u8;
    let mut ts = [0.0; LANES];
    for k in 0..LANES {
        if live & (1 << k) != 0
            && let Some(t) = rays[k].test.hit(p0, p1, p2, limits[k])
        {
            mask |= 1 << k;
            ts[k] = t;
        }
    }
    (mask, ts)
}

impl PacketTest for MollerTrumboreRay {
    type Pre = ();

    #[inline(always)]
    fn pre(_: &[Ray<Self>; LANES], _: u8) {}

    #[inline(always)]
    fn hit4(
        _: &(),
        rays: &[Ray<Self>; LANES],
        live: u8,
        verts: &[[f32; 3]; 3],
        limits: &[f32; LANES],
    ) -> (u8, [f32; LANES]) {
        hit4_scalar(rays, live, verts, limits)
    }
}

/// Watertight packet data: the shared axis permutation and the lanes' sheared-space origin and
/// shear, or `None` when the live lanes' dominant axes differ (then lanes go one by one).
#[cfg(target_arch = "x86_64")]
struct WatertightPre {
    k: [usize; 3],
    o: [std::arch::x86_64::__m128; 3],
    s: [std::arch::x86_64::__m128; 3],
}

#[cfg(target_arch = "x86_64")]
impl PacketTest for WatertightRay {
    type Pre = Option<WatertightPre>;

    #[inline(always)]
    fn pre(rays: &[Ray<Self>; LANES], live: u8) -> Option<WatertightPre> {
        use std::arch::x86_64::*;
        let first = rays[live.trailing_zeros() as usize % LANES].test;
        let k = [first.kx.min(2), first.ky.min(2), first.kz.min(2)];
        for (j, r) in rays.iter().enumerate() {
            if live & (1 << j) != 0 && (r.test.kx, r.test.ky, r.test.kz) != (k[0], k[1], k[2]) {
                return None;
            }
        }
        let lanes = |f: &dyn Fn(&WatertightRay) -> f32| {
            let a: [f32; LANES] = std::array::from_fn(|j| f(&rays[j].test));
            // SAFETY: SSE2 is part of the x86_64 baseline; unaligned load of 4 floats.
            unsafe { _mm_loadu_ps(a.as_ptr()) }
        };
        Some(WatertightPre {
            k,
            o: [
                lanes(&|r| r.origin[k[0]]),
                lanes(&|r| r.origin[k[1]]),
                lanes(&|r| r.origin[k[2]]),
            ],
            s: [lanes(&|r| r.sx), lanes(&|r| r.sy), lanes(&|r| r.sz)],
        })
    }

    /// [`WatertightRay::intersect`] on 4 lanes with the same operations in the same order
    /// (no fused multiply-add), so every lane's `t` is the scalar one; lanes on an edge
    /// (`u`, `v` or `w` zero: the double-precision fallback) are retested with the scalar code.
    #[inline(always)]
    fn hit4(
        pre: &Option<WatertightPre>,
        rays: &[Ray<Self>; LANES],
        live: u8,
        verts: &[[f32; 3]; 3],
        limits: &[f32; LANES],
    ) -> (u8, [f32; LANES]) {
        use std::arch::x86_64::*;
        let Some(pre) = pre else {
            return hit4_scalar(rays, live, verts, limits);
        };
        let [p0, p1, p2] = verts;
        let [kx, ky, kz] = pre.k;
        // SAFETY: SSE2 is part of the x86_64 baseline; unaligned loads/stores of 4 floats.
        unsafe {
            let rel = |p: &[f32; 3]| {
                (
                    _mm_sub_ps(_mm_set1_ps(p[kx]), pre.o[0]),
                    _mm_sub_ps(_mm_set1_ps(p[ky]), pre.o[1]),
                    _mm_sub_ps(_mm_set1_ps(p[kz]), pre.o[2]),
                )
            };
            let (a0, a1, a2) = rel(p0);
            let (b0, b1, b2) = rel(p1);
            let (c0, c1, c2) = rel(p2);
            let [sx, sy, sz] = pre.s;
            let ax = _mm_sub_ps(a0, _mm_mul_ps(sx, a2));
            let ay = _mm_sub_ps(a1, _mm_mul_ps(sy, a2));
            let bx = _mm_sub_ps(b0, _mm_mul_ps(sx, b2));
            let by = _mm_sub_ps(b1, _mm_mul_ps(sy, b2));
            let cx = _mm_sub_ps(c0, _mm_mul_ps(sx, c2));
            let cy = _mm_sub_ps(c1, _mm_mul_ps(sy, c2));
            let u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
            let v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
            let w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
            let zero = _mm_setzero_ps();
            let edge = _mm_or_ps(
                _mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)),
                _mm_cmpeq_ps(w, zero),
            );
            let neg = _mm_or_ps(
                _mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)),
                _mm_cmplt_ps(w, zero),
            );
            let pos = _mm_or_ps(
                _mm_or_ps(_mm_cmpgt_ps(u, zero), _mm_cmpgt_ps(v, zero)),
                _mm_cmpgt_ps(w, zero),
            );
            let det = _mm_add_ps(_mm_add_ps(u, v), w);
            let az = _mm_mul_ps(sz, a2);
            let bz = _mm_mul_ps(sz, b2);
            let cz = _mm_mul_ps(sz, c2);
            let ts = _mm_add_ps(
                _mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)),
                _mm_mul_ps(w, cz),
            );
            let t = _mm_div_ps(ts, det);
            let ok = _mm_and_ps(
                _mm_andnot_ps(_mm_and_ps(neg, pos), _mm_cmpneq_ps(det, zero)),
                _mm_and_ps(
                    _mm_cmpgt_ps(t, zero),
                    _mm_cmplt_ps(t, _mm_loadu_ps(limits.as_ptr())),
                ),
            );
            let edge = _mm_movemask_ps(edge) as u8 & live;
            let mut mask = _mm_movemask_ps(ok) as u8 & live & !edge;
            let mut out = [0.0f32; LANES];
            _mm_storeu_ps(out.as_mut_ptr(), t);
            let mut e = edge;
            while e != 0 {
                let j = e.trailing_zeros() as usize;
                e &= e - 1;
                if let Some(t) = rays[j].test.intersect(*p0, *p1, *p2, limits[j]) {
                    mask |= 1 << j;
                    out[j] = t;
                }
            }
            (mask, out)
        }
    }
}

/// Lane by lane on other architectures.
#[cfg(not(target_arch = "x86_64"))]
impl PacketTest for WatertightRay {
    type Pre = ();

    #[inline(always)]
    fn pre(_: &[Ray<Self>; LANES], _: u8) {}

    #[inline(always)]
    fn hit4(
        _: &(),
        rays: &[Ray<Self>; LANES],
        live: u8,
        verts: &[[f32; 3]; 3],
        limits: &[f32; LANES],
    ) -> (u8, [f32; LANES]) {
        hit4_scalar(rays, live, verts, limits)
    }
}

/// True when the four directions have the same sign in every component (sign bits, so
/// `-0.0` counts as negative): the packet is coherent enough to be worth tracing together.
/// Only a performance heuristic; results never depend on it.
#[inline(always)]
fn same_signs(dirs: &[Vec3]) -> bool {
    let bits = |d: &Vec3| {
        (d.x.is_sign_negative() as u8)
            | (d.y.is_sign_negative() as u8) << 1
            | (d.z.is_sign_negative() as u8) << 2
    };
    let b0 = bits(&dirs[0]);
    dirs[1..].iter().all(|d| bits(d) == b0)
}

impl KdTree {
    /// [`KdTree::intersect_closest`] for many rays: `out_t[i]`, `out_tri[i]` receive ray `i`'s
    /// hit, or `f32::INFINITY` and `u32::MAX` on a miss. Groups of 4 consecutive rays whose
    /// directions agree in sign are traced as a packet; results are bit-identical to the
    /// single-ray query (each lane makes exactly the single ray's decisions, see
    /// [`KdTree::closest_packet`]). Panics if the slices' lengths differ.
    pub fn intersect_closest_batch(
        &self,
        mesh: &TriangleMesh,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_tri: &mut [u32],
    ) {
        self.closest_batch::<WatertightRay>(mesh, origins, dirs, t_max, out_t, out_tri, false);
    }

    /// [`KdTree::intersect_occluded`] for many rays into `out` (same packet grouping and
    /// guarantees as [`KdTree::intersect_closest_batch`]). Panics if the lengths differ.
    pub fn intersect_occluded_batch(
        &self,
        mesh: &TriangleMesh,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
    ) {
        self.occluded_batch::<WatertightRay>(mesh, origins, dirs, t_max, out, false);
    }

    /// Batch closest-hit; `force` traces every full group of 4 as a packet (tests).
    #[allow(clippy::too_many_arguments)]
    fn closest_batch<T: PacketTest>(
        &self,
        mesh: &TriangleMesh,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_tri: &mut [u32],
        force: bool,
    ) {
        let n = origins.len();
        assert!(dirs.len() == n && t_max.len() == n && out_t.len() == n && out_tri.len() == n);
        let mut i = 0;
        while i < n {
            if i + LANES <= n && (force || same_signs(&dirs[i..i + LANES])) {
                let r = i..i + LANES;
                let hits = self.closest_packet::<T>(
                    mesh,
                    &origins[r.clone()],
                    &dirs[r.clone()],
                    &t_max[r],
                );
                for (k, h) in hits.into_iter().enumerate() {
                    (out_t[i + k], out_tri[i + k]) =
                        h.map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri));
                }
                i += LANES;
            } else {
                let h = self.closest::<T>(mesh, origins[i], dirs[i], t_max[i]);
                (out_t[i], out_tri[i]) = h.map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri));
                i += 1;
            }
        }
    }

    /// Batch any-hit; `force` traces every full group of 4 as a packet (tests).
    fn occluded_batch<T: PacketTest>(
        &self,
        mesh: &TriangleMesh,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
        force: bool,
    ) {
        let n = origins.len();
        assert!(dirs.len() == n && t_max.len() == n && out.len() == n);
        let mut i = 0;
        while i < n {
            if i + LANES <= n && (force || same_signs(&dirs[i..i + LANES])) {
                let r = i..i + LANES;
                let occ = self.occluded_packet::<T>(
                    mesh,
                    &origins[r.clone()],
                    &dirs[r.clone()],
                    &t_max[r],
                );
                out[i..i + LANES].copy_from_slice(&occ);
                i += LANES;
            } else {
                out[i] = self.occluded::<T>(mesh, origins[i], dirs[i], t_max[i]);
                i += 1;
            }
        }
    }

    /// Per-lane setup shared by both packet queries: prepared rays (a dummy for lanes that
    /// cannot hit), and the root intervals with the mask of live lanes.
    #[inline(always)]
    fn packet_setup<T: TriangleRay>(
        prep: &super::Prepared,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
    ) -> Option<([Ray<T>; LANES], PacketEntry)> {
        let mut entry = PacketEntry::default();
        let rays: [Ray<T>; LANES] = std::array::from_fn(|k| {
            let live = if t_max[k].is_nan() || t_max[k] <= 0.0 {
                None
            } else {
                Ray::<T>::new(origins[k], dirs[k], &prep.root)
            };
            match live.and_then(|r| r.clip(&prep.root, t_max[k]).map(|c| (r, c))) {
                Some((r, (t0, t1))) => {
                    entry.mask |= 1 << k;
                    entry.t0[k] = t0;
                    entry.t1[k] = t1;
                    r
                }
                None => Ray::<T>::new(Vec3::ZERO, Vec3::X, &prep.root).expect("dummy ray"),
            }
        });
        (entry.mask != 0).then_some((rays, entry))
    }

    /// Closest hits of 4 rays traced together. Each lane computes its child intervals with the
    /// single-ray formulas; while all live lanes agree on the near child (always, for rays
    /// sharing an origin) every lane visits its leaves in the single ray's order and culls
    /// with the same best hit, so results are identical. Where lanes disagree, each lane
    /// finishes that subtree alone with the single-ray loop (a single ray also completes a
    /// subtree before popping what it pushed earlier), which keeps them identical too.
    #[inline(never)]
    fn closest_packet<T: PacketTest>(
        &self,
        mesh: &TriangleMesh,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
    ) -> [Option<TriHit>; LANES] {
        let prep = self.prepared(mesh);
        let Some((rays, entry)) = Self::packet_setup::<T>(prep, origins, dirs, t_max) else {
            return [None; LANES];
        };
        let mut v: [Closest<'_, T>; LANES] = std::array::from_fn(|k| Closest {
            ray: &rays[k].test,
            t_max: t_max[k],
            best: None,
        });
        self.walk_packet(prep, &rays, entry, &mut v);
        v.map(|c| c.best)
    }

    /// Occlusion of 4 rays traced together (any visiting order gives the single ray's answer:
    /// there is no culling, and each lane's intervals follow the single-ray formulas).
    #[inline(never)]
    fn occluded_packet<T: PacketTest>(
        &self,
        mesh: &TriangleMesh,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
    ) -> [bool; LANES] {
        let prep = self.prepared(mesh);
        let Some((rays, entry)) = Self::packet_setup::<T>(prep, origins, dirs, t_max) else {
            return [false; LANES];
        };
        let mut v: [Occluded<'_, T>; LANES] = std::array::from_fn(|k| Occluded {
            ray: &rays[k].test,
            t_max: t_max[k],
        });
        let done = self.walk_packet(prep, &rays, entry, &mut v);
        std::array::from_fn(|k| done & (1 << k) != 0)
    }

    /// Packet traversal; returns the mask of lanes whose visitor asked to stop.
    #[inline(always)]
    fn walk_packet<T: PacketTest, V: Visitor>(
        &self,
        prep: &super::Prepared,
        rays: &[Ray<T>; LANES],
        start: PacketEntry,
        v: &mut [V; LANES],
    ) -> u8 {
        let p = PacketRays::new(rays);
        let pre = T::pre(rays, start.mask);
        let nodes = &self.nodes[..];
        // Not zeroed: entries are written before they are read (`sp` counts them), and
        // zeroing 3 KiB per packet is a measurable share of a packet's work.
        let mut stack = [std::mem::MaybeUninit::<PacketEntry>::uninit(); MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut done = 0u8;
        let mut cur = start;
        loop {
            let mut e = cur;
            // Descend to a leaf (or to a subtree the lanes finish alone).
            let leaf = loop {
                let Some(&n) = nodes.get(e.node as usize) else {
                    break None;
                };
                if n.is_leaf() {
                    break Some(n);
                }
                let axis = n.axis();
                let split = n.split();
                let st = step4(
                    split,
                    &p.origin[axis],
                    &p.inv[axis],
                    &p.slack[axis],
                    &e.t0,
                    &e.t1,
                );
                let m = e.mask;
                let near_left = st.near_left & m;
                let (go_near, go_far) = (st.go_near & m, st.go_far & m);
                let (near, far) = if near_left == m || near_left == 0 {
                    // All lanes agree on the near child.
                    let (nn, fn_) = if near_left != 0 {
                        (e.node + 1, n.right())
                    } else {
                        (n.right(), e.node + 1)
                    };
                    (
                        PacketEntry {
                            node: nn,
                            mask: go_near,
                            t0: e.t0,
                            t1: st.n_t1,
                        },
                        PacketEntry {
                            node: fn_,
                            mask: go_far,
                            t0: st.f_t0,
                            t1: st.f_t1,
                        },
                    )
                } else if V::ORDER_FREE {
                    // Orient each lane's children as left/right; visit the lowest live lane's
                    // near side first (the order does not change any-hit answers).
                    let mut left = PacketEntry {
                        node: e.node + 1,
                        mask: (near_left & go_near) | (!near_left & go_far & m),
                        ..e
                    };
                    let mut right = PacketEntry {
                        node: n.right(),
                        mask: (near_left & go_far) | (!near_left & go_near & m),
                        ..e
                    };
                    for k in 0..LANES {
                        let (lt, rt) = if near_left & (1 << k) != 0 {
                            (&mut left, &mut right)
                        } else {
                            (&mut right, &mut left)
                        };
                        lt.t1[k] = st.n_t1[k];
                        (rt.t0[k], rt.t1[k]) = (st.f_t0[k], st.f_t1[k]);
                    }
                    if near_left & (m & m.wrapping_neg()) != 0 {
                        (left, right)
                    } else {
                        (right, left)
                    }
                } else {
                    // Lanes disagree on the near child: each finishes this subtree alone.
                    for k in 0..LANES {
                        if m & (1 << k) != 0 {
                            let one = Entry {
                                node: e.node,
                                t0: e.t0[k],
                                t1: e.t1[k],
                            };
                            if self.walk(prep, &rays[k], one, &mut v[k]) {
                                done |= 1 << k;
                            }
                        }
                    }
                    break None;
                };
                if near.mask != 0 && far.mask != 0 {
                    if sp < stack.len() {
                        stack[sp] = std::mem::MaybeUninit::new(far);
                        sp += 1;
                    }
                    e = near;
                } else if near.mask != 0 {
                    e = near;
                } else {
                    e = far;
                }
                if e.mask == 0 {
                    break None;
                }
            };
            if let Some(n) = leaf {
                let start = n.offset() as usize;
                let end = start + n.count() as usize;
                // Triangle by triangle, each live lane in turn: every lane still sees the
                // leaf's triangles in order, as its single ray would, and each triangle's
                // vertices are loaded once for the packet.
                if let (Some(ts), Some(ids)) =
                    (prep.tris.get(start..end), self.tri_indices.get(start..end))
                {
                    let mut live = e.mask & !done;
                    // A lane's limit changes only when it accepts a hit.
                    let mut limits: [f32; LANES] = std::array::from_fn(|k| v[k].limit());
                    for (t, &id) in ts.iter().zip(ids) {
                        let (mut hits, ts) = T::hit4(&pre, rays, live, t, &limits);
                        while hits != 0 {
                            let k = hits.trailing_zeros() as usize;
                            hits &= hits - 1;
                            if v[k].accept(ts[k], id) {
                                live &= !(1 << k);
                                done |= 1 << k;
                            }
                            limits[k] = v[k].limit();
                        }
                        if live == 0 {
                            break;
                        }
                    }
                }
            }
            // Pop the next entry with a lane that can still hold a closer (or tying) hit.
            loop {
                if sp == 0 {
                    return done;
                }
                sp -= 1;
                // SAFETY: entries below `sp` were all written by the push above.
                cur = unsafe { stack[sp].assume_init() };
                let mut m = cur.mask & !done;
                for (k, vk) in v.iter().enumerate() {
                    // As the single ray: a NaN entry distance is skipped too.
                    let keep = cur.t0[k] <= vk.cull();
                    if !keep {
                        m &= !(1 << k);
                    }
                }
                cur.mask = m;
                if m != 0 {
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::Vec3;

    use crate::accel::kdtree::{BuildMethod, KdTree, TriHit};
    use crate::geometry::triangle::WatertightRay;
    use crate::mesh::TriangleMesh;

    /// Triangles 0 and 1 are identical and lie in the plane x = 0.
    fn twin_mesh() -> TriangleMesh {
        TriangleMesh::new(
            vec![
                [0.0, -1.0, -1.0],
                [0.0, 1.0, -1.0],
                [0.0, 0.0, 1.0],
                [-1.0, -1.0, -1.0],
                [1.0, 1.0, 1.0],
                [1.0, 1.0, 1.0],
            ],
            vec![[0, 1, 2], [0, 1, 2], [3, 4, 5]],
        )
    }

    #[test]
    fn tie_at_a_leaf_boundary_returns_the_lowest_index() {
        // Hand-made tree: the near leaf (x <= 0) lists only triangle 1, the far leaf only 0.
        let text = "inner{ -1 -1 -1 1 1 1 ; 1 2 0 0 }\nleaf{ -1 -1 -1 0 1 1 ; 1 }\nleaf{ 0 -1 -1 1 1 1 ; 0 }\n";
        let mesh = twin_mesh();
        let tree = KdTree::read_text(text.as_bytes(), Path::new("tie.kd"), 3).expect("read");
        let h = tree.intersect_closest(&mesh, Vec3::new(-1.0, 0.0, 0.0), Vec3::X, f32::INFINITY);
        assert_eq!(h, Some(TriHit { t: 1.0, tri: 0 }));
        let h = tree.intersect_closest(
            &mesh,
            Vec3::new(1.0, 0.0, 0.0),
            -Vec3::X * 4.0,
            f32::INFINITY,
        );
        assert_eq!(h, Some(TriHit { t: 0.25, tri: 0 }));
    }

    #[test]
    fn axis_parallel_rays_with_signed_zeros_and_origins_on_planes() {
        let mesh = twin_mesh();
        for method in [BuildMethod::Midpoint, BuildMethod::Sah] {
            let tree = KdTree::build(&mesh, method);
            for zero in [0.0f32, -0.0] {
                let d = Vec3::new(1.0, zero, zero);
                let h = tree.intersect_closest(&mesh, Vec3::new(-1.0, 0.0, 0.0), d, f32::INFINITY);
                assert_eq!(h, Some(TriHit { t: 1.0, tri: 0 }));
                // Origin on the plane of the triangles: t = 0 is not a hit.
                let h = tree.intersect_closest(&mesh, Vec3::new(0.0, 0.1, 0.1), d, f32::INFINITY);
                assert_eq!(h, None);
                // Parallel ray lying in the plane x = 0 (and on the box face y = -1).
                let p = Vec3::new(zero, zero, 1.0);
                assert_eq!(
                    tree.intersect_closest(&mesh, Vec3::new(0.0, -1.0, -5.0), p, f32::INFINITY),
                    None
                );
                assert!(!tree.intersect_occluded(
                    &mesh,
                    Vec3::new(0.0, -1.0, -5.0),
                    p,
                    f32::INFINITY
                ));
            }
        }
    }

    #[test]
    fn moller_trumbore_traversal_matches_its_brute_force() {
        use crate::geometry::triangle::intersect_moller_trumbore;
        use crate::scene::TriangleTest;
        let mesh = twin_mesh();
        let tree = KdTree::build(&mesh, BuildMethod::Sah);
        for (o, d) in [
            (Vec3::new(-1.0, 0.1, 0.2), Vec3::X),
            (Vec3::new(1.0, -0.2, 0.1), -Vec3::X * 3.0),
            (Vec3::new(-1.0, 5.0, 0.0), Vec3::X),
        ] {
            let mut want: Option<TriHit> = None;
            for k in 0..mesh.len() {
                let limit = want.map_or(f32::INFINITY, |w| w.t);
                if let Some(t) = intersect_moller_trumbore(o, d, mesh.triangle(k), limit) {
                    want = Some(TriHit { t, tri: k as u32 });
                }
            }
            let got = tree.intersect_closest_with(
                &mesh,
                o,
                d,
                f32::INFINITY,
                TriangleTest::MollerTrumbore,
            );
            assert_eq!(got, want);
            let occ = tree.intersect_occluded_with(
                &mesh,
                o,
                d,
                f32::INFINITY,
                TriangleTest::MollerTrumbore,
            );
            assert_eq!(occ, want.is_some());
            let w =
                tree.intersect_closest_with(&mesh, o, d, f32::INFINITY, TriangleTest::Watertight);
            assert_eq!(w, tree.intersect_closest(&mesh, o, d, f32::INFINITY));
        }
    }

    #[test]
    fn bad_rays_never_hit() {
        let mesh = twin_mesh();
        let tree = KdTree::build(&mesh, BuildMethod::Sah);
        let o = Vec3::new(-1.0, 0.0, 0.0);
        for (d, t_max) in [
            (Vec3::ZERO, f32::INFINITY),
            (Vec3::X, 0.0),
            (Vec3::X, -1.0),
            (Vec3::X, f32::NAN),
            (Vec3::NAN, 5.0),
        ] {
            assert_eq!(tree.intersect_closest(&mesh, o, d, t_max), None);
            assert!(!tree.intersect_occluded(&mesh, o, d, t_max));
        }
    }
    /// Small deterministic generator for the batch tests.
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> u32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 33) as u32
        }
        /// Uniform in [-1, 1), or (1 time in 8) a value on a coarse grid, ±0 included.
        fn coord(&mut self) -> f32 {
            if self.next().is_multiple_of(8) {
                [0.0, -0.0, 0.5, -0.5, 1.0, -1.0][(self.next() % 6) as usize]
            } else {
                (self.next() as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
            }
        }
        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.coord(), self.coord(), self.coord())
        }
    }

    /// Random soup with duplicated triangles (ties) and triangles on grid planes.
    fn soup(rng: &mut Lcg, n: usize) -> TriangleMesh {
        let mut v = vec![];
        let mut idx = vec![];
        for k in 0..n {
            let c = rng.vec() * 4.0;
            let (a, b) = (rng.vec() * 0.6, rng.vec() * 0.6);
            let mut tri = [c, c + a, c + b];
            if k % 7 == 0 {
                // Axis-aligned triangle on a grid plane.
                let ax = (rng.next() % 3) as usize;
                let plane = (rng.next() % 5) as f32 - 2.0;
                for p in &mut tri {
                    p[ax] = plane;
                }
            }
            let base = v.len() as u32;
            v.extend(tri.map(|p| p.to_array()));
            idx.push([base, base + 1, base + 2]);
            if k % 11 == 0 {
                idx.push([base, base + 1, base + 2]);
                idx.push([base + 2, base + 1, base]);
            }
        }
        TriangleMesh::new(v, idx)
    }

    #[test]
    fn batch_and_packets_match_single_rays_bit_for_bit() {
        let mut rng = Lcg(0x5eed);
        let mesh = soup(&mut rng, 1500);
        for method in [BuildMethod::Sah, BuildMethod::Midpoint] {
            let tree = KdTree::build(&mesh, method);
            let (mut o, mut d, mut tm) = (vec![], vec![], vec![]);
            for g in 0..3000 {
                // Groups of 4: shared origin (camera-like), shared target (shadow-like), or
                // independent rays; directions of mixed signs with ±0 components.
                let shared_o = rng.vec() * 6.0;
                let target = rng.vec() * 3.0;
                for lane in 0..4 {
                    let (org, mut dir) = match g % 3 {
                        0 => (shared_o, rng.vec() * 0.2 + Vec3::new(0.3, -0.7, 0.5)),
                        1 => {
                            let org = rng.vec() * 5.0;
                            (org, target - org)
                        }
                        _ => (rng.vec() * 6.0, rng.vec()),
                    };
                    if rng.next().is_multiple_of(13) {
                        dir[(rng.next() % 3) as usize] = if lane % 2 == 0 { 0.0 } else { -0.0 };
                    }
                    let mut org = org;
                    let t = match rng.next() % 16 {
                        0 => f32::NAN,
                        1 => 0.0,
                        2 => {
                            dir = Vec3::NAN;
                            f32::INFINITY
                        }
                        3 => {
                            org.y = f32::NAN;
                            f32::INFINITY
                        }
                        4 => {
                            dir = Vec3::ZERO;
                            f32::INFINITY
                        }
                        5..=9 => 0.5 + (rng.next() % 100) as f32 * 0.02,
                        _ => f32::INFINITY,
                    };
                    o.push(org);
                    d.push(dir);
                    tm.push(t);
                }
            }
            // Odd length: the tail goes through the single-ray path.
            o.pop();
            d.pop();
            tm.pop();
            let n = o.len();
            for force in [false, true] {
                let (mut bt, mut btri, mut occ) = (vec![0.0; n], vec![0; n], vec![false; n]);
                tree.closest_batch::<WatertightRay>(&mesh, &o, &d, &tm, &mut bt, &mut btri, force);
                tree.occluded_batch::<WatertightRay>(&mesh, &o, &d, &tm, &mut occ, force);
                let mut hits = 0;
                for i in 0..n {
                    let want = tree.intersect_closest(&mesh, o[i], d[i], tm[i]);
                    let got = (btri[i] != u32::MAX).then_some((bt[i].to_bits(), btri[i]));
                    assert_eq!(got, want.map(|h| (h.t.to_bits(), h.tri)), "closest ray {i}");
                    if want.is_none() {
                        assert_eq!(bt[i], f32::INFINITY);
                    }
                    hits += want.is_some() as usize;
                    let want = tree.intersect_occluded(&mesh, o[i], d[i], tm[i]);
                    assert_eq!(occ[i], want, "occluded ray {i}");
                }
                assert!(
                    hits > n / 8,
                    "too few hits ({hits} of {n}) to be a useful test"
                );
            }
        }
    }

    #[test]
    fn packet_ties_at_a_leaf_boundary_return_the_lowest_index() {
        let text = "inner{ -1 -1 -1 1 1 1 ; 1 2 0 0 }\nleaf{ -1 -1 -1 0 1 1 ; 1 }\nleaf{ 0 -1 -1 1 1 1 ; 0 }\n";
        let mesh = twin_mesh();
        let tree = KdTree::read_text(text.as_bytes(), Path::new("tie.kd"), 3).expect("read");
        let o = [
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(-1.0, 0.1, 0.0),
            Vec3::new(-1.0, 0.0, 0.1),
        ];
        let d = [Vec3::X, -Vec3::X * 4.0, Vec3::X, Vec3::X];
        let tm = [f32::INFINITY; 4];
        let (mut t, mut tri) = ([0.0; 4], [0; 4]);
        tree.closest_batch::<WatertightRay>(&mesh, &o, &d, &tm, &mut t, &mut tri, true);
        assert_eq!((t, tri), ([1.0, 0.25, 1.0, 1.0], [0; 4]));
    }
    #[test]
    fn simd_node_step_matches_the_scalar_step() {
        use super::{step4, step4_scalar};
        let mut rng = Lcg(0xabc);
        let special = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            1e-30,
        ];
        let pick = |rng: &mut Lcg| {
            if rng.next().is_multiple_of(4) {
                special[(rng.next() % special.len() as u32) as usize]
            } else {
                rng.coord() * 3.0
            }
        };
        for _ in 0..200_000 {
            let split = pick(&mut rng);
            let lane = |rng: &mut Lcg| {
                let o = if rng.next().is_multiple_of(4) {
                    split
                } else {
                    pick(rng)
                };
                let t0 = pick(rng).abs();
                let t1 = if rng.next().is_multiple_of(8) {
                    t0 * 0.5
                } else {
                    t0 + pick(rng).abs()
                };
                (o, pick(rng), pick(rng).abs().min(f32::MAX), t0, t1)
            };
            let l: [(f32, f32, f32, f32, f32); 4] = std::array::from_fn(|_| lane(&mut rng));
            let (o, i, st, t0, t1) = (
                l.map(|x| x.0),
                l.map(|x| x.1),
                l.map(|x| x.2),
                l.map(|x| x.3),
                l.map(|x| x.4),
            );
            let a = step4(split, &o, &i, &st, &t0, &t1);
            let b = step4_scalar(split, &o, &i, &st, &t0, &t1);
            assert_eq!(
                (a.near_left, a.go_near, a.go_far),
                (b.near_left, b.go_near, b.go_far),
                "{split} {l:?}"
            );
            // Interval ends compare equal (a zero's sign may differ; it never matters).
            assert_eq!(
                (a.n_t1, a.f_t0, a.f_t1),
                (b.n_t1, b.f_t0, b.f_t1),
                "{split} {l:?}"
            );
        }
    }
}
