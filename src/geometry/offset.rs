//! Moving a secondary ray's origin off the surface it leaves, by the error bound of the hit point
//! (Pharr, Jakob & Humphreys, *Physically Based Rendering* 4th ed., §6.8; Ray Tracing Gems ch. 6).
//!
//! Every hit point is computed together with a conservative per-component absolute error bound
//! (`p_error`): the exact surface point lies within `p ± p_error`. A ray leaving the surface starts
//! at `p` pushed along the geometric normal by `|n|·p_error` — far enough that no point of the
//! error box lies on the far side — and rounded one more float away, so the origin is on the
//! correct side whatever the rounding. The offset is zero only where the point is exact (a point
//! reconstructed on the plane `y = 0` keeps `y = 0` exactly, and the strict `t > 0` of the
//! intersection tests does the rest); it grows with the coordinates' magnitude only as far as the
//! computation's rounding does. No epsilon, no ulp count.
//!
//! The bounds use `γ(n) = n·u / (1 − n·u)` with `u = 2⁻²⁴` (PBR eq. 6.33).

use glam::Vec3;

/// Half the distance between 1 and the next f32: the unit roundoff `u`.
pub(crate) const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// `γ(n) = n·u / (1 − n·u)`: the relative error bound of `n` successive f32 operations.
#[inline]
pub const fn gamma(n: u32) -> f32 {
    let nu = n as f32 * MACHINE_EPSILON;
    nu / (1.0 - nu)
}

/// The naive fixed epsilon, for the error report only.
pub(crate) const FIXED_EPSILON: f32 = 1e-4;

/// The next f32 above `v` (`+inf` and NaN unchanged; `-0.0` goes to the smallest subnormal).
#[inline]
pub(crate) fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 || v.is_nan() {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    f32::from_bits(if v >= 0.0 { bits + 1 } else { bits - 1 })
}

/// The next f32 below `v` (`-inf` and NaN unchanged; `+0.0` goes to the smallest negative
/// subnormal).
#[inline]
pub(crate) fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 || v.is_nan() {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    f32::from_bits(if v > 0.0 { bits - 1 } else { bits + 1 })
}

/// `p` (with error bound `p_error`) moved off its surface to the side the unit geometric normal `n`
/// points to: by `d = |n|·p_error` along `n`, then each moved coordinate one float further away
/// from `p` (PBR 4th ed., `OffsetRayOrigin`).
#[inline]
pub(crate) fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let offset = d * n;
    let mut po = p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = next_float_up(po[i]);
        } else if offset[i] < 0.0 {
            po[i] = next_float_down(po[i]);
        }
    }
    if po.is_finite() { po } else { p }
}

/// `p` moved by the fixed [`FIXED_EPSILON`] along `n`: the naive method, kept for the error
/// report.
#[inline]
pub(crate) fn offset_fixed(p: Vec3, n: Vec3) -> Vec3 {
    p + FIXED_EPSILON * n
}

/// Far end of a shadow ray from `origin` toward a point light at `light` (exact in the render
/// frame up to its conversion from f64, `γ(1)·|light|` per component): the distance along the
/// unit direction `dir`, shortened by the light's error bound projected on the ray and by the
/// distance's own rounding (`γ(3)`), so a surface through the light never counts as a blocker.
#[inline]
pub(crate) fn shadow_t_max(light: Vec3, dir: Vec3, distance: f32) -> f32 {
    let light_error = gamma(1) * light.abs();
    (distance * (1.0 - gamma(3)) - dir.abs().dot(light_error)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_float_steps_one_ulp_through_zero() {
        assert_eq!(next_float_up(1.0), 1.0 + f32::EPSILON);
        assert_eq!(next_float_down(1.0), 1.0 - f32::EPSILON / 2.0);
        assert!(next_float_up(0.0) > 0.0 && next_float_up(-0.0) > 0.0);
        assert!(next_float_down(0.0) < 0.0 && next_float_down(-0.0) < 0.0);
        assert_eq!(next_float_down(next_float_up(-3.5)), -3.5);
        assert_eq!(next_float_up(f32::INFINITY), f32::INFINITY);
    }

    #[test]
    fn moves_to_the_normal_side_at_every_scale_even_without_error() {
        for scale in [0.0f32, 1e-3, 1.0, 1e4, 1e7] {
            for n in [Vec3::X, Vec3::NEG_X, Vec3::new(0.6, -0.8, 0.0)] {
                for error in [Vec3::ZERO, Vec3::splat(gamma(7) * scale)] {
                    let p = Vec3::splat(scale);
                    let q = offset_ray_origin(p, error, n);
                    assert!((q - p).dot(n) >= 0.0, "scale {scale} n {n}");
                    // The whole error box lies behind the new origin.
                    let d = n.abs().dot(error);
                    assert!((q - p).dot(n) >= d, "scale {scale} n {n}");
                }
            }
        }
    }

    #[test]
    fn an_exact_point_is_not_moved_and_an_inexact_one_by_its_bound() {
        let p = Vec3::new(3.0, 0.0, -2.0);
        assert_eq!(offset_ray_origin(p, Vec3::ZERO, Vec3::Y), p);
        let q = offset_ray_origin(p, Vec3::new(0.0, 1e-3, 0.0), Vec3::Y);
        assert!(q.y > 1e-3 && q.y < 1.001e-3, "{q}");
        assert_eq!((q.x, q.z), (3.0, -2.0));
    }

    #[test]
    fn shadow_rays_stop_short_of_the_light() {
        let light = Vec3::new(1e4, 2.0, 0.0);
        let dir = Vec3::X;
        let t = shadow_t_max(light, dir, 1e4);
        assert!(t < 1e4 && t > 1e4 * (1.0 - 1e-5), "{t}");
        assert_eq!(shadow_t_max(Vec3::ZERO, Vec3::X, 0.0), 0.0);
    }
}
