//! One triangle against the 4 rays of a packet ([`PacketTest`]), bit-identical to each lane's
//! single-ray test: the lane watertight test ([`WatertightLanes`]) on [`F32x4`] lanes,
//! Möller–Trumbore lane by lane.
//!
//! Reads one triangle's vertices, the packet's prepared rays and per-lane `t_max`; writes the
//! mask of lanes hit and their `t`.

use super::LANES;
use super::ray::Ray;
use crate::geometry::triangle::{MollerTrumboreRay, TriangleRay, WatertightLanes, WatertightRay};
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

/// Watertight packet data: the shared axis permutation and the lanes' test
/// ([`WatertightLanes`]), or `None` when the live lanes' permutations differ (then lanes go one
/// by one).
pub(super) struct WatertightPre {
    /// Axes mapped to the sheared x, y, z (shared by the live lanes).
    k: [usize; 3],
    /// The lanes' origins on `k` and shears.
    lanes: WatertightLanes<F32x4>,
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
            lanes: WatertightLanes {
                o: [
                    lanes(&|r| r.origin[k[0]]),
                    lanes(&|r| r.origin[k[1]]),
                    lanes(&|r| r.origin[k[2]]),
                ],
                sx: lanes(&|r| r.sx),
                sy: lanes(&|r| r.sy),
                sz: lanes(&|r| r.sz),
            },
        })
    }

    /// The lane watertight test ([`WatertightLanes::hit`]) on the packet's 4 lanes; lanes on an
    /// edge (`u`, `v` or `w` zero: the double-precision fallback) are retested with the scalar
    /// code.
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
        let perm = |p: &[f32; 3]| [p[kx], p[ky], p[kz]];
        let h = pre.lanes.hit(
            &perm(p0),
            &perm(p1),
            &perm(p2),
            live as u32,
            F32x4::from_array(limits),
        );
        let mut mask = h.hit as u8;
        let mut out = h.t.to_array();
        let mut e = h.edge;
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
