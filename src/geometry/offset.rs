//! Moving a secondary ray's origin off the surface it leaves.
//!
//! The default is Wächter & Binder's method (Ray Tracing Gems, ch. 6): step the hit point along
//! the normal by a fixed number of ulps of each coordinate, so the offset scales with the point's
//! magnitude and no world-space epsilon is assumed; near the origin, where ulps are tiny, a small
//! float offset is used instead.

use glam::Vec3;

use crate::scene::OffsetMethod;

/// Below this magnitude a coordinate is offset in float space.
const ORIGIN: f32 = 1.0 / 32.0;
/// Float-space offset scale near the origin.
const FLOAT_SCALE: f32 = 1.0 / 65536.0;
/// Offset in ulps for points whose error is a few ulps: hits re-projected onto spheres and planes.
pub const EXACT_POINT_ULPS: f32 = 32.0;
/// Offset in ulps for points computed as `o + t·d` (Wächter & Binder's value).
pub const RAY_POINT_ULPS: f32 = 256.0;
/// The naive fixed epsilon, for the error report only.
pub const FIXED_EPSILON: f32 = 1e-4;

/// `p` moved off the surface to the side `n` points to, by `ulps` ulps of each coordinate per
/// unit of normal (the point's error bound, see [`EXACT_POINT_ULPS`] and [`RAY_POINT_ULPS`]).
/// `n` should have length about 1.
#[inline]
pub fn offset_origin(p: Vec3, n: Vec3, ulps: f32, method: OffsetMethod) -> Vec3 {
    match method {
        OffsetMethod::ScaleAware => Vec3::new(
            offset_coord(p.x, n.x, ulps),
            offset_coord(p.y, n.y, ulps),
            offset_coord(p.z, n.z, ulps),
        ),
        OffsetMethod::FixedEpsilon => p + FIXED_EPSILON * n,
    }
}

#[inline]
fn offset_coord(p: f32, n: f32, ulps: f32) -> f32 {
    if p.abs() < ORIGIN {
        return p + FLOAT_SCALE * n;
    }
    let of_i = (ulps * n) as i32;
    // Moving the bit pattern away from zero grows |p|, so the step's sign follows p's.
    let step = if p < 0.0 { -of_i } else { of_i };
    let moved = f32::from_bits((p.to_bits() as i32).wrapping_add(step) as u32);
    if moved.is_finite() { moved } else { p }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_to_the_normal_side_at_every_scale() {
        for scale in [1e-3f32, 1.0, 1e4, 1e7] {
            for n in [Vec3::X, Vec3::NEG_X, Vec3::new(0.6, -0.8, 0.0)] {
                let p = Vec3::splat(scale);
                let q = offset_origin(p, n, EXACT_POINT_ULPS, OffsetMethod::ScaleAware);
                assert!((q - p).dot(n) > 0.0, "scale {scale} n {n}");
                let p = -p;
                let q = offset_origin(p, n, EXACT_POINT_ULPS, OffsetMethod::ScaleAware);
                assert!((q - p).dot(n) > 0.0, "scale -{scale} n {n}");
            }
        }
    }

    #[test]
    fn offset_grows_with_magnitude() {
        let off = |p: f32| {
            offset_origin(
                Vec3::splat(p),
                Vec3::X,
                RAY_POINT_ULPS,
                OffsetMethod::ScaleAware,
            )
            .x - p
        };
        let (small, big) = (off(1.0), off(1e4));
        assert!(big > 1000.0 * small);
    }
}
