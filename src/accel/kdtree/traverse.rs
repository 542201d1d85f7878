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
        for (&[p0, p1, p2], &tri) in tris.iter().zip(ids) {
            // Accept equal t too, so ties can go to the lower index.
            let limit = match self.best {
                Some(b) => b.t.next_up(),
                None => self.t_max,
            };
            if let Some(t) = self.ray.hit(p0, p1, p2, limit)
                && self.best.is_none_or(|b| t < b.t || tri < b.tri)
            {
                self.best = Some(TriHit { t, tri });
            }
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
        for &[p0, p1, p2] in tris {
            if self.ray.hit(p0, p1, p2, self.t_max).is_some() {
                return true;
            }
        }
        false
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
#[derive(Clone, Copy, Default)]
struct PacketEntry {
    node: u32,
    mask: u8,
    t0: [f32; LANES],
    t1: [f32; LANES],
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
    fn closest_batch<T: TriangleRay>(
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
                let hits = self.closest_packet::<T>(mesh, &origins[r.clone()], &dirs[r.clone()], &t_max[r]);
                for (k, h) in hits.into_iter().enumerate() {
                    (out_t[i + k], out_tri[i + k]) = h.map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri));
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
    fn occluded_batch<T: TriangleRay>(
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
                let occ = self.occluded_packet::<T>(mesh, &origins[r.clone()], &dirs[r.clone()], &t_max[r]);
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
    fn closest_packet<T: TriangleRay>(
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
    fn occluded_packet<T: TriangleRay>(
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
    fn walk_packet<T: TriangleRay, V: Visitor>(
        &self,
        prep: &super::Prepared,
        rays: &[Ray<T>; LANES],
        start: PacketEntry,
        v: &mut [V; LANES],
    ) -> u8 {
        let p = PacketRays::new(rays);
        let nodes = &self.nodes[..];
        let mut stack = [PacketEntry::default(); MAX_DEPTH + 1];
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
                let (oa, ia, st) = (&p.origin[axis], &p.inv[axis], &p.slack[axis]);
                let mut near_left = 0u8;
                let mut go_left = 0u8;
                let mut go_right = 0u8;
                let mut l = (e.t0, e.t1);
                let mut r = (e.t0, e.t1);
                for k in 0..LANES {
                    let (t0, t1) = (e.t0[k], e.t1[k]);
                    let tp = (split - oa[k]) * ia[k];
                    let nl = oa[k] < split || (oa[k] == split && ia[k] < 0.0);
                    // Exactly the single-ray step (see `walk`).
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
                    // Single ray: both -> near (t0, near_t1) then far (far_t0, far_t1);
                    // near only -> (t0, t1); otherwise far -> (far_t0, t1).
                    let (nt, ft) = if both {
                        ((t0, near_t1), (far_t0, far_t1))
                    } else {
                        ((t0, t1), (far_t0, t1))
                    };
                    let go_near = near_used;
                    let go_far = both || !near_used;
                    let bit = 1u8 << k;
                    if nl {
                        near_left |= bit;
                        (l.0[k], l.1[k], r.0[k], r.1[k]) = (nt.0, nt.1, ft.0, ft.1);
                        go_left |= if go_near { bit } else { 0 };
                        go_right |= if go_far { bit } else { 0 };
                    } else {
                        (r.0[k], r.1[k], l.0[k], l.1[k]) = (nt.0, nt.1, ft.0, ft.1);
                        go_right |= if go_near { bit } else { 0 };
                        go_left |= if go_far { bit } else { 0 };
                    }
                }
                let m = e.mask;
                let (near_left, go_left, go_right) = (near_left & m, go_left & m, go_right & m);
                let left_first = if V::ORDER_FREE {
                    near_left & (m & m.wrapping_neg()) != 0
                } else if near_left == m || near_left == 0 {
                    near_left != 0
                } else {
                    // Lanes disagree on the near child: each finishes this subtree alone.
                    break None.or_else(|| {
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
                        None
                    });
                };
                let left = PacketEntry {
                    node: e.node + 1,
                    mask: go_left,
                    t0: l.0,
                    t1: l.1,
                };
                let right = PacketEntry {
                    node: n.right(),
                    mask: go_right,
                    t0: r.0,
                    t1: r.1,
                };
                let (near, far) = if left_first { (left, right) } else { (right, left) };
                if near.mask != 0 && far.mask != 0 {
                    if sp < stack.len() {
                        stack[sp] = far;
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
                for k in 0..LANES {
                    if e.mask & (1 << k) != 0 && v[k].leaf(self, &prep.tris, start, end) {
                        done |= 1 << k;
                    }
                }
            }
            // Pop the next entry with a lane that can still hold a closer (or tying) hit.
            loop {
                if sp == 0 {
                    return done;
                }
                sp -= 1;
                cur = stack[sp];
                let mut m = cur.mask & !done;
                for k in 0..LANES {
                    if !(cur.t0[k] <= v[k].cull()) {
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
}
