//! Ray/plane intersection.

use glam::Vec3;

use super::offset::gamma;

/// `t` where `o + t·d` meets the plane through `point` with normal `normal`, if `0 < t < t_max`.
///
/// Rays parallel to the plane (`d·n = 0`) miss; NaN inputs miss.
#[inline]
pub fn intersect(o: Vec3, d: Vec3, point: Vec3, normal: Vec3, t_max: f32) -> Option<f32> {
    let denom = d.dot(normal);
    let t = (point - o).dot(normal) / denom;
    (t > 0.0 && t < t_max).then_some(t)
}

/// `p` projected onto the plane through `point` with unit normal `normal`, and the projection's
/// error bound: `s = (p − q)·n` is within `γ(4)·Σ|(p − q)ᵢ nᵢ|`, and `p − s·n` rounds twice more
/// per component (PBR 4th ed. §6.8 style bounds).
#[inline]
pub(crate) fn reproject(p: Vec3, point: Vec3, normal: Vec3) -> (Vec3, Vec3) {
    let a = p - point;
    let s = a.dot(normal);
    let projected = p - s * normal;
    let s_error = gamma(4) * (a * normal).abs().element_sum();
    let error = normal.abs() * s_error + gamma(2) * (projected.abs() + (s * normal).abs());
    (projected, error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_from_either_side_and_misses_parallel() {
        let p = Vec3::new(0.0, -2.0, 0.0);
        assert_eq!(
            intersect(Vec3::ZERO, Vec3::NEG_Y, p, Vec3::Y, f32::INFINITY),
            Some(2.0)
        );
        assert_eq!(
            intersect(
                Vec3::new(0.0, -4.0, 0.0),
                Vec3::Y,
                p,
                Vec3::Y,
                f32::INFINITY
            ),
            Some(2.0)
        );
        assert_eq!(
            intersect(Vec3::ZERO, Vec3::X, p, Vec3::Y, f32::INFINITY),
            None
        );
        assert_eq!(
            intersect(Vec3::ZERO, Vec3::Y, p, Vec3::Y, f32::INFINITY),
            None
        );
        assert_eq!(intersect(Vec3::ZERO, Vec3::NEG_Y, p, Vec3::Y, 2.0), None);
    }
}
