//! PLACEHOLDER until the watertight test lands: Möller–Trumbore ray/triangle intersection.

use glam::Vec3;

/// `t` of the hit with triangle `(a, b, c)` if `0 < t < t_max`.
#[inline]
pub fn intersect_moller_trumbore(
    o: Vec3,
    d: Vec3,
    [a, b, c]: [Vec3; 3],
    t_max: f32,
) -> Option<f32> {
    let e1 = b - a;
    let e2 = c - a;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0 && t < t_max).then_some(t)
}
