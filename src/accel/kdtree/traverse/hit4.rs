//! One triangle against the 4 rays of a packet ([`PacketTest`]), bit-identical to each lane's
//! single-ray test: the watertight test on [`F32x4`] lanes, Möller–Trumbore lane by lane.
//!
//! Reads one triangle's vertices, the packet's prepared rays and per-lane `t_max`; writes the
//! mask of lanes hit and their `t`.

use super::LANES;
use super::ray::Ray;
use crate::geometry::triangle::{MollerTrumboreRay, TriangleRay, WatertightRay};
use crate::simd::F32x4;

/// A triangle test that can test one triangle against the 4 rays of a packet at once, with
/// results bit-identical to its single-ray test on every lane.
pub(super) trait PacketTest: TriangleRay + Sized {
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

/// Lane by lane with the single-ray test.
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

/// Watertight packet data: the shared axis permutation and the lanes' origin and shear in the
/// permuted axes, or `None` when the live lanes' permutations differ (then lanes go one by one).
pub(super) struct WatertightPre {
    /// Axes mapped to the sheared x, y, z (shared by the live lanes).
    k: [usize; 3],
    /// Origin components on `k[0]`, `k[1]`, `k[2]`, per lane.
    o: [F32x4; 3],
    /// Shear `sx`, `sy`, `sz`, per lane.
    s: [F32x4; 3],
}

impl PacketTest for WatertightRay {
    type Pre = Option<WatertightPre>;

    #[inline(always)]
    fn pre(rays: &[Ray<Self>; LANES], live: u8) -> Option<WatertightPre> {
        let first = rays[live.trailing_zeros() as usize % LANES].test;
        let k = [first.kx.min(2), first.ky.min(2), first.kz.min(2)];
        for (j, r) in rays.iter().enumerate() {
            if live & (1 << j) != 0 && (r.test.kx, r.test.ky, r.test.kz) != (k[0], k[1], k[2]) {
                return None;
            }
        }
        let lanes = |f: &dyn Fn(&WatertightRay) -> f32| {
            F32x4::from_array(&std::array::from_fn(|j| f(&rays[j].test)))
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
        let Some(pre) = pre else {
            return hit4_scalar(rays, live, verts, limits);
        };
        let [p0, p1, p2] = verts;
        let [kx, ky, kz] = pre.k;
        let rel = |p: &[f32; 3]| {
            (
                F32x4::splat(p[kx]) - pre.o[0],
                F32x4::splat(p[ky]) - pre.o[1],
                F32x4::splat(p[kz]) - pre.o[2],
            )
        };
        let (a0, a1, a2) = rel(p0);
        let (b0, b1, b2) = rel(p1);
        let (c0, c1, c2) = rel(p2);
        let [sx, sy, sz] = pre.s;
        let ax = a0 - sx * a2;
        let ay = a1 - sy * a2;
        let bx = b0 - sx * b2;
        let by = b1 - sy * b2;
        let cx = c0 - sx * c2;
        let cy = c1 - sy * c2;
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = F32x4::splat(0.0);
        let edge = u.eq(zero) | v.eq(zero) | w.eq(zero);
        let neg = u.lt(zero) | v.lt(zero) | w.lt(zero);
        let pos = u.gt(zero) | v.gt(zero) | w.gt(zero);
        let det = u + v + w;
        let az = sz * a2;
        let bz = sz * b2;
        let cz = sz * c2;
        let t = (u * az + v * bz + w * cz) / det;
        let ok = det.ne(zero).and_not(neg & pos) & (t.gt(zero) & t.lt(F32x4::from_array(limits)));
        let edge = edge.bits() & live;
        let mut mask = ok.bits() & live & !edge;
        let mut out = t.to_array();
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
