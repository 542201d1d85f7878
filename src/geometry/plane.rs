//! Ray/plane intersection.

use glam::Vec3;

/// `t` where `o + t·d` meets the plane through `point` with normal `normal`, if `0 < t < t_max`.
///
/// Rays parallel to the plane (`d·n = 0`) miss; NaN inputs miss.
#[inline]
pub fn intersect(o: Vec3, d: Vec3, point: Vec3, normal: Vec3, t_max: f32) -> Option<f32> {
    let denom = d.dot(normal);
    let t = (point - o).dot(normal) / denom;
    (t > 0.0 && t < t_max).then_some(t)
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
