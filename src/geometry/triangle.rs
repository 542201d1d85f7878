//! Ray/triangle intersection: the watertight test of Woop, Benthin and Wald (JCGT 2013), its
//! per-ray precomputation, a Möller–Trumbore variant for comparison, and brute-force references.
//!
//! Reads triangle vertices and one ray (origin, unnormalised direction, `t_max`); returns the hit
//! distance `t` in units of the direction's length. A hit is valid only for `0 < t < t_max`
//! (strict); degenerate triangles (zero determinant) never hit; no routine returns NaN.

use glam::Vec3;

use super::TriangleMesh;
use super::offset::gamma;
use crate::simd::Wide;

/// Which ray/triangle test the kD traversal uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TriangleTest {
    /// Woop, Benthin & Wald 2013. The default.
    Watertight,
    /// Möller–Trumbore, kept for the error report.
    MollerTrumbore,
}

/// Per-ray data of the watertight test, computed once per ray and shared by every triangle test
/// (and by kD-tree traversal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatertightRay {
    /// Ray origin.
    pub origin: Vec3,
    /// Index of the dominant direction axis (largest `|d|`), mapped to the sheared z.
    pub kz: usize,
    /// Axis mapped to the sheared x (swapped with `ky` when `d[kz] < 0` to keep the winding).
    pub kx: usize,
    /// Axis mapped to the sheared y.
    pub ky: usize,
    /// Shear `d[kx] / d[kz]`.
    pub sx: f32,
    /// Shear `d[ky] / d[kz]`.
    pub sy: f32,
    /// Scale `1 / d[kz]`.
    pub sz: f32,
}

impl WatertightRay {
    /// Precomputes the shear for a ray. Returns `None` for a direction that cannot hit anything
    /// (all components zero, non-finite, or so tiny that `1 / d[kz]` overflows).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Option<WatertightRay> {
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = if kz == 2 { 0 } else { kz + 1 };
        let mut ky = if kx == 2 { 0 } else { kx + 1 };
        let dz = dir[kz];
        if dz < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = 1.0 / dz;
        let sx = dir[kx] / dz;
        let sy = dir[ky] / dz;
        if !(sz.is_finite() && sx.is_finite() && sy.is_finite() && origin.is_finite()) {
            return None;
        }
        Some(WatertightRay {
            origin,
            kz,
            kx,
            ky,
            sx,
            sy,
            sz,
        })
    }

    /// Watertight test against triangle `(p0, p1, p2)`. Returns `t` with `0 < t < t_max`, or
    /// `None`. Both faces hit; edges shared by two triangles are hit by at least one of them.
    #[inline(always)]
    pub fn intersect(&self, p0: [f32; 3], p1: [f32; 3], p2: [f32; 3], t_max: f32) -> Option<f32> {
        let o = self.origin.to_array();
        // `min(2)` is a no-op for rays made by `new`; it lets the compiler drop the bounds
        // checks on the nine permuted reads below (the fields are public).
        let (kx, ky, kz) = (self.kx.min(2), self.ky.min(2), self.kz.min(2));
        let a = [p0[kx] - o[kx], p0[ky] - o[ky], p0[kz] - o[kz]];
        let b = [p1[kx] - o[kx], p1[ky] - o[ky], p1[kz] - o[kz]];
        let c = [p2[kx] - o[kx], p2[ky] - o[ky], p2[kz] - o[kz]];
        let ax = a[0] - self.sx * a[2];
        let ay = a[1] - self.sy * a[2];
        let bx = b[0] - self.sx * b[2];
        let by = b[1] - self.sy * b[2];
        let cx = c[0] - self.sx * c[2];
        let cy = c[1] - self.sy * c[2];
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            // Fall back to double precision on edges (the paper's exact edge test).
            let (ax, ay, bx, by, cx, cy) = (
                ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64,
            );
            u = (cx * by - cy * bx) as f32;
            v = (ax * cy - ay * cx) as f32;
            w = (bx * ay - by * ax) as f32;
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let az = self.sz * a[2];
        let bz = self.sz * b[2];
        let cz = self.sz * c[2];
        let t_scaled = u * az + v * bz + w * cz;
        let t = t_scaled / det;
        // `t` is finite here (finite inputs, det != 0), or +-inf for a tiny det; never NaN.
        if t > 0.0 && t < t_max { Some(t) } else { None }
    }

    /// The barycentric coordinates `(b0, b1, b2)` of the point where the ray meets the plane of
    /// triangle `(p0, p1, p2)`, from the same edge functions as [`WatertightRay::intersect`]
    /// (`b0 = U/det`, weight of `p0`, …). `None` for a triangle seen edge-on (`det = 0`).
    #[inline]
    pub(crate) fn barycentrics(
        &self,
        p0: [f32; 3],
        p1: [f32; 3],
        p2: [f32; 3],
    ) -> Option<[f32; 3]> {
        let o = self.origin.to_array();
        let (kx, ky, kz) = (self.kx.min(2), self.ky.min(2), self.kz.min(2));
        let shear = |p: [f32; 3]| {
            let (x, y, z) = (p[kx] - o[kx], p[ky] - o[ky], p[kz] - o[kz]);
            ((x - self.sx * z) as f64, (y - self.sy * z) as f64)
        };
        let ((ax, ay), (bx, by), (cx, cy)) = (shear(p0), shear(p1), shear(p2));
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let det = u + v + w;
        let b = [(u / det) as f32, (v / det) as f32, (w / det) as f32];
        (det != 0.0 && b.iter().all(|x| x.is_finite())).then_some(b)
    }
}

/// [`WatertightRay::intersect`] on `V` lanes (one ray per lane, sharing the axis permutation):
/// the one lane form of the watertight test, used by every batched kD traversal (4-ray packets,
/// frusta, light-rooted bundles). The same operations in the same order (no fused
/// multiply-add), so a lane's `t` is the scalar test's, bit for bit; a lane with a zero edge
/// function (`u`, `v` or `w`), where the scalar test falls back to `f64`, is reported in
/// [`LaneHits::edge`] for the caller to retest with the scalar test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WatertightLanes<V: Wide> {
    /// The origins on the permuted axes `kx`, `ky`, `kz`.
    pub(crate) o: [V; 3],
    /// Shear `sx` per lane.
    pub(crate) sx: V,
    /// Shear `sy` per lane.
    pub(crate) sy: V,
    /// Scale `sz` per lane.
    pub(crate) sz: V,
}

/// What [`WatertightLanes::hit`] found.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LaneHits<V> {
    /// Live lanes, off every edge, that hit with `0 < t < t_max`.
    pub(crate) hit: u32,
    /// Live lanes with a zero edge function: the scalar test decides them.
    pub(crate) edge: u32,
    /// Each lane's `t` (meaningful in the `hit` lanes).
    pub(crate) t: V,
}

impl<V: Wide> WatertightLanes<V> {
    /// The lanes of `live` (bit `k` = lane `k`) that hit the triangle whose vertices, permuted
    /// to `[p[kx], p[ky], p[kz]]`, are `a`, `b`, `c`, lane `k` with `0 < t < t_max[k]`. The
    /// distance is computed only when some live lane is inside the triangle.
    #[inline(always)]
    pub(crate) fn hit(
        &self,
        a: &[f32; 3],
        b: &[f32; 3],
        c: &[f32; 3],
        live: u32,
        t_max: V,
    ) -> LaneHits<V> {
        let zero = V::splat(0.0);
        let [ox, oy, oz] = self.o;
        let (sx, sy) = (self.sx, self.sy);
        // (No closures: a closure is not compiled with the dispatcher's target features, so the
        // lane operations inside it would not be inlined.)
        let (a0, a1, a2) = (
            V::splat(a[0]).sub(ox),
            V::splat(a[1]).sub(oy),
            V::splat(a[2]).sub(oz),
        );
        let (b0, b1, b2) = (
            V::splat(b[0]).sub(ox),
            V::splat(b[1]).sub(oy),
            V::splat(b[2]).sub(oz),
        );
        let (c0, c1, c2) = (
            V::splat(c[0]).sub(ox),
            V::splat(c[1]).sub(oy),
            V::splat(c[2]).sub(oz),
        );
        let ax = a0.sub(sx.mul(a2));
        let ay = a1.sub(sy.mul(a2));
        let bx = b0.sub(sx.mul(b2));
        let by = b1.sub(sy.mul(b2));
        let cx = c0.sub(sx.mul(c2));
        let cy = c1.sub(sy.mul(c2));
        let u = cx.mul(by).sub(cy.mul(bx));
        let v = ax.mul(cy).sub(ay.mul(cx));
        let w = bx.mul(ay).sub(by.mul(ax));
        let on_edge = V::or(V::or(V::eq(u, zero), V::eq(v, zero)), V::eq(w, zero));
        let neg = V::or(V::or(V::lt(u, zero), V::lt(v, zero)), V::lt(w, zero));
        let pos = V::or(V::or(V::gt(u, zero), V::gt(v, zero)), V::gt(w, zero));
        let edge = V::bits(on_edge) & live;
        let inside = !V::bits(V::and(neg, pos)) & live & !edge;
        if inside == 0 {
            return LaneHits {
                hit: 0,
                edge,
                t: zero,
            };
        }
        let det = u.add(v).add(w);
        let az = self.sz.mul(a2);
        let bz = self.sz.mul(b2);
        let cz = self.sz.mul(c2);
        let t = u.mul(az).add(v.mul(bz)).add(w.mul(cz)).div(det);
        let ok = V::bits(V::and(V::gt(t, zero), V::lt(t, t_max))) & !V::bits(V::eq(det, zero));
        LaneHits {
            hit: ok & inside,
            edge,
            t,
        }
    }
}

/// The hit point of a ray on triangle `(p0, p1, p2)` reconstructed from its barycentric
/// coordinates, `p = b0·p0 + b1·p1 + b2·p2`, with its error bound `γ(7)·Σ|bᵢ·pᵢ|` (PBR 4th ed.
/// §6.8.4): unlike `o + t·d`, whose error grows with the distance travelled, this point lies on the
/// triangle's plane within a few ulps of the vertices' own magnitude. Also returns the
/// barycentric coordinates (for interpolated shading normals). `None` when the ray cannot be
/// prepared or sees the triangle edge-on.
#[inline]
pub(crate) fn hit_point(origin: Vec3, dir: Vec3, tri: [Vec3; 3]) -> Option<(Vec3, Vec3, [f32; 3])> {
    let ray = WatertightRay::new(origin, dir)?;
    let b = ray.barycentrics(tri[0].into(), tri[1].into(), tri[2].into())?;
    let (q0, q1, q2) = (b[0] * tri[0], b[1] * tri[1], b[2] * tri[2]);
    let point = q0 + q1 + q2;
    let error = gamma(7) * (q0.abs() + q1.abs() + q2.abs());
    Some((point, error, b))
}

/// A ray prepared for one ray/triangle test: traversal is generic over it, so the default
/// (watertight) path is monomorphised and pays nothing for the alternative.
pub(crate) trait TriangleRay: Sized {
    /// Prepares a ray; `None` when the direction cannot hit anything.
    fn prepare(origin: Vec3, dir: Vec3) -> Option<Self>;
    /// Hit distance `t` with `0 < t < t_max` against triangle `(p0, p1, p2)`, or `None`.
    fn hit(&self, p0: [f32; 3], p1: [f32; 3], p2: [f32; 3], t_max: f32) -> Option<f32>;
}

impl TriangleRay for WatertightRay {
    #[inline(always)]
    fn prepare(origin: Vec3, dir: Vec3) -> Option<Self> {
        WatertightRay::new(origin, dir)
    }

    #[inline(always)]
    fn hit(&self, p0: [f32; 3], p1: [f32; 3], p2: [f32; 3], t_max: f32) -> Option<f32> {
        self.intersect(p0, p1, p2, t_max)
    }
}

/// A ray for the Möller–Trumbore test (see [`intersect_moller_trumbore`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MollerTrumboreRay {
    /// Ray origin.
    pub origin: Vec3,
    /// Ray direction (unnormalised).
    pub dir: Vec3,
}

impl TriangleRay for MollerTrumboreRay {
    #[inline(always)]
    fn prepare(origin: Vec3, dir: Vec3) -> Option<Self> {
        (origin.is_finite() && dir.is_finite() && dir != Vec3::ZERO)
            .then_some(MollerTrumboreRay { origin, dir })
    }

    #[inline(always)]
    fn hit(&self, p0: [f32; 3], p1: [f32; 3], p2: [f32; 3], t_max: f32) -> Option<f32> {
        intersect_moller_trumbore(
            self.origin,
            self.dir,
            [p0.into(), p1.into(), p2.into()],
            t_max,
        )
    }
}

/// Watertight intersection of one ray with one triangle (convenience wrapper; traversal should
/// reuse a [`WatertightRay`]); the tests' form.
#[cfg(test)]
fn intersect_watertight(origin: Vec3, dir: Vec3, tri: [Vec3; 3], t_max: f32) -> Option<f32> {
    WatertightRay::new(origin, dir)?.intersect(
        tri[0].to_array(),
        tri[1].to_array(),
        tri[2].to_array(),
        t_max,
    )
}

/// Möller–Trumbore intersection (not watertight; kept only to compare against the default
/// test). Same conventions: `0 < t < t_max`, zero determinant never hits, never NaN.
#[inline]
pub(crate) fn intersect_moller_trumbore(
    origin: Vec3,
    dir: Vec3,
    tri: [Vec3; 3],
    t_max: f32,
) -> Option<f32> {
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - tri[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let t = e2.dot(q) * inv;
    if t > 0.0 && t < t_max { Some(t) } else { None }
}

/// Brute-force reference: closest hit `(t, triangle)` over every non-degenerate triangle of the
/// mesh with the watertight test; equal `t` resolves to the lowest triangle index.
pub fn intersect_all_closest(
    mesh: &TriangleMesh,
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
) -> Option<(f32, u32)> {
    let ray = WatertightRay::new(origin, dir)?;
    let mut best: Option<(f32, u32)> = None;
    let mut limit = t_max;
    for (k, idx) in mesh.indices.iter().enumerate() {
        let [p0, p1, p2] = idx.map(|i| mesh.vertices[i as usize]);
        if let Some(t) = ray.intersect(p0, p1, p2, limit) {
            if mesh.is_degenerate(k) {
                continue;
            }
            // Strictly closer only: ascending k keeps the lowest index among equal t.
            best = Some((t, k as u32));
            limit = t;
        }
    }
    best
}

/// Brute-force reference: is any non-degenerate triangle hit with `0 < t < t_max`?
pub fn intersect_all_occluded(mesh: &TriangleMesh, origin: Vec3, dir: Vec3, t_max: f32) -> bool {
    let Some(ray) = WatertightRay::new(origin, dir) else {
        return false;
    };
    mesh.indices.iter().enumerate().any(|(k, idx)| {
        let [p0, p1, p2] = idx.map(|i| mesh.vertices[i as usize]);
        ray.intersect(p0, p1, p2, t_max).is_some() && !mesh.is_degenerate(k)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: [Vec3; 3] = [
        Vec3::new(-1.0, -1.0, 2.0),
        Vec3::new(1.0, -1.0, 2.0),
        Vec3::new(0.0, 1.0, 2.0),
    ];

    #[test]
    fn hits_front_and_back_faces_with_unnormalised_direction() {
        let t = intersect_watertight(Vec3::ZERO, Vec3::new(0.0, 0.0, 4.0), TRI, f32::INFINITY);
        assert_eq!(t, Some(0.5));
        let t = intersect_watertight(
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::new(0.0, 0.0, -1.0),
            TRI,
            f32::INFINITY,
        );
        assert_eq!(t, Some(3.0));
    }

    #[test]
    fn t_max_and_zero_are_exclusive() {
        assert_eq!(intersect_watertight(Vec3::ZERO, Vec3::Z, TRI, 2.0), None);
        assert_eq!(
            intersect_watertight(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, TRI, 9.0),
            None
        );
        assert!(intersect_watertight(Vec3::ZERO, Vec3::Z, TRI, 2.0001).is_some());
    }

    #[test]
    fn degenerate_and_parallel_never_hit() {
        let flat = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(2.0, 0.0, 2.0),
        ];
        let o = Vec3::new(0.5, -1.0, 0.5);
        assert_eq!(intersect_watertight(o, Vec3::Y, flat, f32::INFINITY), None);
        assert_eq!(
            intersect_moller_trumbore(o, Vec3::Y, flat, f32::INFINITY),
            None
        );
        // Ray lying in the triangle's plane.
        let o = Vec3::new(-5.0, 0.0, 2.0);
        assert_eq!(intersect_watertight(o, Vec3::X, TRI, f32::INFINITY), None);
        // Zero direction.
        assert_eq!(
            intersect_watertight(Vec3::ZERO, Vec3::ZERO, TRI, f32::INFINITY),
            None
        );
    }

    #[test]
    fn shared_edge_is_hit_by_exactly_one_or_both_never_neither() {
        let a = Vec3::new(0.0, -1.0, 1.0);
        let b = Vec3::new(0.0, 1.0, 1.0);
        let left = [a, b, Vec3::new(-1.0, 0.0, 1.0)];
        let right = [b, a, Vec3::new(1.0, 0.0, 1.0)];
        for i in 0..1000 {
            let y = -0.9 + 1.8 * (i as f32 / 1000.0);
            let o = Vec3::new(0.0, y, 0.0);
            let d = Vec3::new(0.0, 0.0137, 1.0);
            let hl = intersect_watertight(o, d, left, f32::INFINITY);
            let hr = intersect_watertight(o, d, right, f32::INFINITY);
            assert!(
                hl.is_some() || hr.is_some(),
                "ray {i} leaked through the edge"
            );
        }
    }

    #[test]
    fn moller_trumbore_agrees_away_from_edges() {
        let d = Vec3::new(0.1, 0.2, 1.0);
        let w = intersect_watertight(Vec3::ZERO, d, TRI, f32::INFINITY).expect("hit");
        let m = intersect_moller_trumbore(Vec3::ZERO, d, TRI, f32::INFINITY).expect("hit");
        assert!((w - m).abs() < 1e-6);
    }

    #[test]
    fn brute_force_prefers_lowest_index_on_ties() {
        let v: Vec<[f32; 3]> = TRI.iter().map(|p| p.to_array()).collect();
        let mesh = TriangleMesh::new(v, vec![[0, 1, 2], [2, 1, 0], [0, 1, 2]]);
        let hit = intersect_all_closest(&mesh, Vec3::ZERO, Vec3::Z, f32::INFINITY);
        assert_eq!(hit, Some((2.0, 0)));
        assert!(intersect_all_occluded(&mesh, Vec3::ZERO, Vec3::Z, 2.5));
        assert!(!intersect_all_occluded(&mesh, Vec3::ZERO, Vec3::Z, 2.0));
    }

    /// [`WatertightLanes::hit`] at `V`'s width against [`WatertightRay::intersect`] on every
    /// lane: random triangles and rays, and rays aimed exactly at vertices and edge midpoints of
    /// grid triangles (zero edge functions), at `t_max` equal to the hit distance, behind the
    /// origin and on degenerate triangles. Returns (lanes compared, hits, edge lanes).
    fn lanes_against_scalar<V: Wide>() -> [usize; 3] {
        let mut rng = crate::sampling::Rng(0x1a9e5 + V::LANES as u64);
        let mut unit = move || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        let (mut compared, mut hits, mut edges) = (0, 0, 0);
        let n = V::LANES;
        for trial in 0..20_000 {
            let grid = trial % 2 == 0;
            let mut coord = |lo: f32, hi: f32| {
                let x = lo + (hi - lo) * unit();
                if grid { (x * 4.0).round() / 4.0 } else { x }
            };
            let flip = if trial % 4 < 2 { 1.0 } else { -1.0 };
            let mut tri = [[0.0f32; 3]; 3];
            for p in &mut tri {
                *p = [coord(-1.0, 1.0), coord(-1.0, 1.0), flip * coord(2.0, 4.0)];
            }
            if trial % 97 == 0 {
                tri[2] = tri[1]; // degenerate
            }
            let mut rays = vec![];
            let mut limits = vec![];
            for lane in 0..n {
                let o = [coord(-1.0, 1.0), coord(-1.0, 1.0), flip * coord(-1.0, 0.0)];
                let (u, v) = (coord(0.0, 1.0), coord(0.0, 1.0));
                let w = match (lane + trial / 2) % 4 {
                    0 => [1.0, 0.0, 0.0],
                    1 => [0.5, 0.5, 0.0],
                    2 => [0.0, 0.5, 0.5],
                    _ => [u * 0.5, v * 0.5, 1.0 - u * 0.5 - v * 0.5],
                };
                let target: [f32; 3] =
                    std::array::from_fn(|k| w[0] * tri[0][k] + w[1] * tri[1][k] + w[2] * tri[2][k]);
                let sign = if trial % 13 == 0 { -1.0 } else { 1.0 };
                let d = Vec3::from(target) - Vec3::from(o);
                limits.push([f32::INFINITY, 1.0, 0.5, 2.0][(trial + lane) % 4]);
                rays.push(WatertightRay::new(Vec3::from(o), d * sign));
            }
            let Some(first) = rays[0] else { continue };
            let k = [first.kx, first.ky, first.kz];
            let mut live = 0u32;
            for (lane, r) in rays.iter().enumerate() {
                if r.is_some_and(|r| [r.kx, r.ky, r.kz] == k) {
                    live |= 1 << lane;
                }
            }
            let col = |f: &dyn Fn(&WatertightRay) -> f32| {
                let v: Vec<f32> = rays.iter().map(|r| r.map_or(0.0, |r| f(&r))).collect();
                V::load(&v)
            };
            let lanes = WatertightLanes {
                o: [
                    col(&|r| r.origin[k[0]]),
                    col(&|r| r.origin[k[1]]),
                    col(&|r| r.origin[k[2]]),
                ],
                sx: col(&|r| r.sx),
                sy: col(&|r| r.sy),
                sz: col(&|r| r.sz),
            };
            let perm = |p: &[f32; 3]| [p[k[0]], p[k[1]], p[k[2]]];
            let h = lanes.hit(
                &perm(&tri[0]),
                &perm(&tri[1]),
                &perm(&tri[2]),
                live,
                V::load(&limits),
            );
            assert_eq!(h.hit & !live, 0);
            assert_eq!(h.edge & !live, 0);
            assert_eq!(h.hit & h.edge, 0);
            let mut ts = vec![0.0f32; n];
            h.t.store(&mut ts);
            for lane in 0..n {
                if live >> lane & 1 == 0 {
                    continue;
                }
                compared += 1;
                if h.edge >> lane & 1 != 0 {
                    edges += 1;
                    continue;
                }
                let want = rays[lane]
                    .unwrap()
                    .intersect(tri[0], tri[1], tri[2], limits[lane]);
                let got = (h.hit >> lane & 1 != 0).then_some(ts[lane]);
                assert_eq!(
                    got.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "{} lanes, trial {trial}, lane {lane}",
                    V::LANES
                );
                hits += want.is_some() as usize;
            }
        }
        [compared, hits, edges]
    }

    /// [`lanes_against_scalar`] at every SIMD level's width.
    struct LanesKernel;

    impl crate::simd::WideKernel for LanesKernel {
        type Output = [usize; 3];
        #[inline(always)]
        fn run<V: Wide>(self) -> [usize; 3] {
            lanes_against_scalar::<V>()
        }
    }

    #[test]
    fn lane_test_matches_the_scalar_test_bit_for_bit() {
        let mut results = vec![
            lanes_against_scalar::<f32>(),
            lanes_against_scalar::<crate::simd::F32x4>(),
        ];
        for level in crate::simd::Level::supported() {
            results.push(crate::simd::dispatch_wide(level, LanesKernel));
        }
        for [compared, hits, edges] in results {
            // Enough of each kind to be a test: hits, misses, and lanes on edges.
            assert!(
                hits > compared / 10 && hits < compared * 9 / 10,
                "{hits} of {compared}"
            );
            assert!(edges > compared / 50, "{edges} edge lanes of {compared}");
        }
    }
}
