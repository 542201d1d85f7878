//! Ray traversal of the kD tree: [`KdAccel`], a tree made ready to trace against its mesh, and
//! its closest-hit and occluded (any-hit) queries, for one ray or a batch.
//!
//! Reads the tree's nodes, the accelerator's leaf-ordered triangle copy and exact root box, and
//! rays (origin, unnormalised direction, `t_max`); writes a [`TriHit`] or an occlusion bit per
//! ray. The files, by role:
//! - `ray`: per-ray data (reciprocal direction, `δ` slack, the triangle test's precomputation)
//!   and the root-box clip;
//! - `interval`: the node-interval step (near/far child intervals with `δ` and `SLACK`),
//!   written once over [`crate::simd::Wide`] lanes (`f32`, 4, 8 or 16 of them);
//! - `visit`: the closest and occluded modes (leaf visit, culling, answer);
//! - `single`: the single-ray loop; `packet`: the 4-ray packet loop and the batch driver;
//!   `hit4`: one triangle against a packet's 4 rays;
//! - `route`: the routing table (which loop a batch, or a part of it, takes);
//! - `frustum`: 64-ray frusta for closest-hit batches; `bundle`: light-rooted shadow bundles
//!   for occluded batches (both over [`crate::simd`]'s `Wide` lanes: 16 with AVX-512, 8
//!   otherwise; a bundle is two of them, 32 or 16 rays);
//! - [`crate::simd`]: the SIMD lanes and dispatch (the crate's one `unsafe` module).
//!
//! **Which loop a query takes**: the routing table, `route` (one function per decision, its
//! thresholds beside it, tested). Every loop gives the single-ray answer, bit for bit.
//!
//! Traversal is front-to-back and stack-based (fixed array, no allocation per ray), generic over
//! the query mode and the triangle test
//! ([`TriangleRay`](crate::geometry::triangle::TriangleRay); the watertight one by default),
//! monomorphised.
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
//! both slacks together change the visited node count by well under 1 %. A node is skipped only
//! when its (conservative) entry distance is beyond the best hit: ties at leaf boundaries still
//! find the lowest triangle index among equal-`t` hits.
//!
//! Batch queries: [`KdAccel::intersect_closest_batch`] regroups camera rays into screen tiles
//! and traces them as 64-ray frusta (`frustum`, 8 or 16 SIMD lanes by [`Level`]);
//! [`KdAccel::intersect_occluded_batch`], and closest-hit batches the frusta do not suit, trace
//! groups of 4 consecutive rays with equal direction signs as a packet (Wald 2004 style,
//! per-lane active mask): one node fetch and one 4-wide step per node for the packet, and each
//! triangle tested against the live lanes at once. Every lane takes its single ray's interval
//! step and culls with its own best hit; where lanes disagree on the near child, the packet
//! visits both children with their lanes, the lowest live lane's near side first. Results are
//! bit-identical to the single-ray queries (see `frustum` for why the order changes no
//! closest hit).

mod bundle;
mod frustum;
mod hit4;
mod interval;
mod packet;
mod ray;
mod route;
mod single;
mod visit;

use glam::Vec3;
use rayon::prelude::*;

use super::overlap::Aabb;
use super::{KdTree, TriHit, exact_root};
use crate::geometry::triangle::TriangleTest;
use crate::geometry::triangle::{MollerTrumboreRay, WatertightRay};
use crate::mesh::TriangleMesh;
use crate::simd::{Level, Wide, WideKernel, dispatch_wide};
pub use bundle::BundleCounts;
use visit::{Closest, Occluded};

/// Rays per packet.
const LANES: usize = route::PACKET;

/// A [`KdTree`] made ready to trace against the mesh it was built over: the tree, its
/// triangles' vertices copied in leaf order and the exact root box. Built once, explicitly, by
/// [`KdAccel::new`]; the queries read only this (they take no mesh).
#[derive(Clone, Debug)]
pub struct KdAccel {
    /// The tree (structure only).
    tree: KdTree,
    /// Vertices of `tree.tri_indices[i]` at index `i`: leaf order, so a leaf's triangles are
    /// one contiguous run and traversal touches one array (a copy of the mesh's data, kept for
    /// cache locality).
    tris: Vec<[[f32; 3]; 3]>,
    /// Root box used by traversal: the mesh bounds joined with the tree's stored root box (a
    /// tree read from text has a rounded root box).
    root: Aabb,
}

impl KdAccel {
    /// Rays per [`KdAccel::intersect_occluded_batch`] call that let its light-rooted bundles find
    /// coherent neighbours (measured on Sibenik: 4,096 traces ~15 % faster than 1,024; the
    /// answers do not depend on it).
    pub const OCCLUDED_BATCH: usize = 4096;

    /// Prepares `tree` for traversal against `mesh`, the mesh it indexes: copies the vertices
    /// of every leaf entry in leaf order and computes the exact root box. (Indices out of range
    /// of `mesh`, which `KdTree::validate` reports, become a degenerate triangle at the origin,
    /// which is never hit.)
    pub fn new(tree: KdTree, mesh: &TriangleMesh) -> KdAccel {
        let tris = tree
            .tri_indices
            .par_iter()
            .with_min_len(1 << 14)
            .map(|&k| {
                let idx = mesh.indices.get(k as usize).copied().unwrap_or([0; 3]);
                idx.map(|i| mesh.vertices.get(i as usize).copied().unwrap_or([0.0; 3]))
            })
            .collect();
        let root = exact_root(&tree, mesh);
        KdAccel { tree, tris, root }
    }

    /// The tree (for its structural API: nodes, stats, writing it out).
    pub fn tree(&self) -> &KdTree {
        &self.tree
    }

    /// Closest hit with `0 < t < t_max` (strict), `t` in units of `dir`'s length (`dir` need not
    /// be normalised). Equal `t` resolves to the lowest triangle index, exactly as the
    /// brute-force reference [`crate::geometry::triangle::intersect_all_closest`] does, with
    /// bit-identical `t`. Uses the watertight test.
    #[inline]
    pub fn intersect_closest(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<TriHit> {
        self.query::<WatertightRay, Closest>(origin, dir, t_max)
    }

    /// True when any triangle is hit with `0 < t < t_max`; stops at the first hit found. Uses
    /// the watertight test.
    #[inline]
    pub fn intersect_occluded(&self, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
        self.query::<WatertightRay, Occluded>(origin, dir, t_max)
    }

    /// [`KdAccel::intersect_closest`] with a chosen triangle test (for the error report).
    pub(crate) fn intersect_closest_with(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        test: TriangleTest,
    ) -> Option<TriHit> {
        self.query_with::<Closest>(origin, dir, t_max, test)
    }

    /// [`KdAccel::intersect_occluded`] with a chosen triangle test (for the error report).
    pub(crate) fn intersect_occluded_with(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        test: TriangleTest,
    ) -> bool {
        self.query_with::<Occluded>(origin, dir, t_max, test)
    }

    /// [`KdAccel::intersect_closest`] for many rays: `out_t[i]`, `out_tri[i]` receive ray `i`'s
    /// hit, or `f32::INFINITY` and `u32::MAX` on a miss; any `t_max` per ray, any directions.
    /// The batch is regrouped into screen tiles and traced as 64-ray frusta (camera rays; rays
    /// from many origins while they stay coherent enough), else in groups of 4 consecutive rays
    /// whose directions agree in sign as packets. Compiled for the best SIMD level of the CPU
    /// ([`Level::current`]). Results are bit-identical to the single-ray query whatever the path
    /// and level (each lane makes exactly the single ray's decisions, see the module docs).
    /// Inside a rayon pool of several threads, a batch of 1,024 rays or more is regrouped in
    /// pieces of [`TRACE_CHUNK`](crate::queue::TRACE_CHUNK) rays and its frusta are
    /// traced on all the pool's threads. Panics if the slices' lengths differ.
    pub fn intersect_closest_batch(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_tri: &mut [u32],
    ) {
        self.intersect_closest_batch_at(Level::current(), origins, dirs, t_max, out_t, out_tri);
    }

    /// [`KdAccel::intersect_closest_batch`] compiled for `level` (or the best supported level
    /// below it): for tests and benchmarks comparing levels. Same answers at every level.
    pub fn intersect_closest_batch_at(
        &self,
        level: Level,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_tri: &mut [u32],
    ) {
        let n = origins.len();
        assert!(dirs.len() == n && t_max.len() == n && out_t.len() == n && out_tri.len() == n);
        dispatch_wide(
            level,
            ClosestBatch {
                level,
                accel: self,
                origins,
                dirs,
                t_max,
                out_t,
                out_tri,
            },
        );
    }

    /// [`KdAccel::intersect_occluded`] for many rays into `out`, identical to it ray for ray.
    /// Rays whose far ends (`o + t_max·d`) meet at a shared point — shadow rays toward a point
    /// light — are traced from that point as light-rooted bundles of 16 or 32 rays (`bundle`:
    /// culling from the light, each triangle tested in the ray's own frame); any others as
    /// 4-ray packets (see [`KdAccel::intersect_closest_batch`]). Batches of about
    /// [`KdAccel::OCCLUDED_BATCH`] rays bundle best. Panics if the lengths differ.
    pub fn intersect_occluded_batch(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
    ) {
        assert!(out.len() == origins.len());
        bundle::occluded_batch(self, origins, dirs, t_max, out);
    }

    /// [`KdAccel::intersect_occluded_batch`] with its light-rooted bundles traced at SIMD level
    /// `level` (or the best supported one below it), counting their work: for tests (every
    /// level gives the same answers) and measurements.
    pub fn intersect_occluded_batch_counted(
        &self,
        level: Level,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
    ) -> BundleCounts {
        let mut counts = BundleCounts::default();
        bundle::occluded_batch_at(level, self, origins, dirs, t_max, out, &mut counts);
        counts
    }

    /// Every ray through the 4-ray packet loop in groups of 4 consecutive rays, whatever their
    /// direction signs (the routing table's `group` decision overridden; a batch query sends
    /// such groups elsewhere): closest hits into `out_t`,
    /// `out_tri` (as [`KdAccel::intersect_closest_batch`]) and occlusion into `out_occ`. For
    /// tests checking the packet loop against single rays; not part of the API. Panics if the
    /// lengths differ.
    #[doc(hidden)]
    pub fn packets_forced(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_tri: &mut [u32],
        out_occ: &mut [bool],
    ) {
        let n = origins.len();
        assert!(out_t.len() == n && out_tri.len() == n && out_occ.len() == n);
        self.batch::<WatertightRay, Closest>(origins, dirs, t_max, true, |i, h| {
            (out_t[i], out_tri[i]) = h.map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri));
        });
        self.batch::<WatertightRay, Occluded>(origins, dirs, t_max, true, |i, o| out_occ[i] = o);
    }

    /// [`KdAccel::intersect_occluded`] for many rays through the 4-ray packet loop, as the
    /// routing table sends an occluded batch with too few rays toward shared points (groups of
    /// 4 with equal direction signs as packets, others one by one): for benchmarks comparing the
    /// variants; not part of the API. Panics if the lengths differ.
    #[doc(hidden)]
    pub fn occluded_packets(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
    ) {
        assert!(out.len() == origins.len());
        self.batch::<WatertightRay, Occluded>(origins, dirs, t_max, false, |i, o| out[i] = o);
    }

    /// One ray's query `V` with the triangle test chosen at run time.
    #[inline]
    fn query_with<V: visit::Visitor>(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        test: TriangleTest,
    ) -> V::Out {
        match test {
            TriangleTest::Watertight => self.query::<WatertightRay, V>(origin, dir, t_max),
            TriangleTest::MollerTrumbore => self.query::<MollerTrumboreRay, V>(origin, dir, t_max),
        }
    }
}

/// The closest-hit batch as a [`WideKernel`]: compiled once per SIMD level.
struct ClosestBatch<'a> {
    /// The level it is compiled for (for the parallel path's own dispatch).
    level: Level,
    /// The accelerator.
    accel: &'a KdAccel,
    /// Ray origins.
    origins: &'a [Vec3],
    /// Ray directions.
    dirs: &'a [Vec3],
    /// Per-ray bounds.
    t_max: &'a [f32],
    /// Hit distances out.
    out_t: &'a mut [f32],
    /// Hit triangles out.
    out_tri: &'a mut [u32],
}

impl WideKernel for ClosestBatch<'_> {
    type Output = ();

    #[inline(always)]
    fn run<V: Wide>(self) {
        let ClosestBatch {
            level,
            accel,
            origins,
            dirs,
            t_max,
            out_t,
            out_tri,
        } = self;
        let mut scratch = frustum::take_scratch();
        let wide = if origins.len() >= frustum::PAR_MIN && rayon::current_num_threads() > 1 {
            accel.closest_frusta_par(level, origins, dirs, t_max, out_t, out_tri, &mut scratch)
        } else {
            accel.closest_frusta::<V>(origins, dirs, t_max, out_t, out_tri, &mut scratch)
        };
        frustum::put_scratch(scratch);
        if !wide {
            accel.batch::<WatertightRay, Closest>(origins, dirs, t_max, false, |i, h| {
                (out_t[i], out_tri[i]) = h.map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri));
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::Vec3;

    use super::KdAccel;
    use super::visit::{Closest, Occluded};
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
        let tree = KdAccel::new(tree, &mesh);
        let h = tree.intersect_closest(Vec3::new(-1.0, 0.0, 0.0), Vec3::X, f32::INFINITY);
        assert_eq!(h, Some(TriHit { t: 1.0, tri: 0 }));
        let h = tree.intersect_closest(Vec3::new(1.0, 0.0, 0.0), -Vec3::X * 4.0, f32::INFINITY);
        assert_eq!(h, Some(TriHit { t: 0.25, tri: 0 }));
    }

    #[test]
    fn axis_parallel_rays_with_signed_zeros_and_origins_on_planes() {
        let mesh = twin_mesh();
        for method in [BuildMethod::Midpoint, BuildMethod::Sah] {
            let tree = KdAccel::new(KdTree::build(&mesh, method), &mesh);
            for zero in [0.0f32, -0.0] {
                let d = Vec3::new(1.0, zero, zero);
                let h = tree.intersect_closest(Vec3::new(-1.0, 0.0, 0.0), d, f32::INFINITY);
                assert_eq!(h, Some(TriHit { t: 1.0, tri: 0 }));
                // Origin on the plane of the triangles: t = 0 is not a hit.
                let h = tree.intersect_closest(Vec3::new(0.0, 0.1, 0.1), d, f32::INFINITY);
                assert_eq!(h, None);
                // Parallel ray lying in the plane x = 0 (and on the box face y = -1).
                let p = Vec3::new(zero, zero, 1.0);
                assert_eq!(
                    tree.intersect_closest(Vec3::new(0.0, -1.0, -5.0), p, f32::INFINITY),
                    None
                );
                assert!(!tree.intersect_occluded(Vec3::new(0.0, -1.0, -5.0), p, f32::INFINITY));
            }
        }
    }

    #[test]
    fn moller_trumbore_traversal_matches_its_brute_force() {
        use crate::geometry::triangle::TriangleTest;
        use crate::geometry::triangle::intersect_moller_trumbore;
        let mesh = twin_mesh();
        let tree = KdAccel::new(KdTree::build(&mesh, BuildMethod::Sah), &mesh);
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
            let got =
                tree.intersect_closest_with(o, d, f32::INFINITY, TriangleTest::MollerTrumbore);
            assert_eq!(got, want);
            let occ =
                tree.intersect_occluded_with(o, d, f32::INFINITY, TriangleTest::MollerTrumbore);
            assert_eq!(occ, want.is_some());
            let w = tree.intersect_closest_with(o, d, f32::INFINITY, TriangleTest::Watertight);
            assert_eq!(w, tree.intersect_closest(o, d, f32::INFINITY));
        }
    }

    #[test]
    fn bad_rays_never_hit() {
        let mesh = twin_mesh();
        let tree = KdAccel::new(KdTree::build(&mesh, BuildMethod::Sah), &mesh);
        let o = Vec3::new(-1.0, 0.0, 0.0);
        for (d, t_max) in [
            (Vec3::ZERO, f32::INFINITY),
            (Vec3::X, 0.0),
            (Vec3::X, -1.0),
            (Vec3::X, f32::NAN),
            (Vec3::NAN, 5.0),
        ] {
            assert_eq!(tree.intersect_closest(o, d, t_max), None);
            assert!(!tree.intersect_occluded(o, d, t_max));
        }
    }
    /// Small deterministic generator for the batch tests.
    /// The crate's seeded generator ([`crate::sampling::Rng`]) with this test's draws.
    struct Draws(crate::sampling::Rng);
    impl Draws {
        fn next(&mut self) -> u32 {
            (self.0.next_u64() >> 33) as u32
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
    fn soup(rng: &mut Draws, n: usize) -> TriangleMesh {
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
        let mut rng = Draws(crate::sampling::Rng(0x5eed));
        let mesh = soup(&mut rng, 1500);
        for method in [BuildMethod::Sah, BuildMethod::Midpoint] {
            let tree = KdAccel::new(KdTree::build(&mesh, method), &mesh);
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
                tree.batch::<WatertightRay, Closest>(&o, &d, &tm, force, |i, h| {
                    (bt[i], btri[i]) = h.map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri));
                });
                tree.batch::<WatertightRay, Occluded>(&o, &d, &tm, force, |i, x| occ[i] = x);
                // The batch entry: frusta of the regrouped rays (incoherent origins and
                // directions here), at every SIMD level.
                let mut levels = vec![];
                for level in crate::simd::Level::supported() {
                    let (mut lt, mut ltri) = (vec![0.0; n], vec![0; n]);
                    tree.intersect_closest_batch_at(level, &o, &d, &tm, &mut lt, &mut ltri);
                    levels.push((level, lt, ltri));
                }
                let mut hits = 0;
                for i in 0..n {
                    let want = tree.intersect_closest(o[i], d[i], tm[i]);
                    let got = (btri[i] != u32::MAX).then_some((bt[i].to_bits(), btri[i]));
                    assert_eq!(got, want.map(|h| (h.t.to_bits(), h.tri)), "closest ray {i}");
                    for (level, lt, ltri) in &levels {
                        let got = (ltri[i] != u32::MAX).then_some((lt[i].to_bits(), ltri[i]));
                        let want = want.map(|h| (h.t.to_bits(), h.tri));
                        assert_eq!(got, want, "closest ray {i}, batch at {level:?}");
                    }
                    if want.is_none() {
                        assert_eq!(bt[i], f32::INFINITY);
                    }
                    hits += want.is_some() as usize;
                    let want = tree.intersect_occluded(o[i], d[i], tm[i]);
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
        let tree = KdAccel::new(tree, &mesh);
        let o = [
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(-1.0, 0.1, 0.0),
            Vec3::new(-1.0, 0.0, 0.1),
        ];
        let d = [Vec3::X, -Vec3::X * 4.0, Vec3::X, Vec3::X];
        let tm = [f32::INFINITY; 4];
        let (mut t, mut tri) = ([0.0; 4], [0; 4]);
        tree.batch::<WatertightRay, Closest>(&o, &d, &tm, true, |i, h| {
            (t[i], tri[i]) = h.map_or((f32::INFINITY, u32::MAX), |h| (h.t, h.tri));
        });
        assert_eq!((t, tri), ([1.0, 0.25, 1.0, 1.0], [0; 4]));
    }
}
