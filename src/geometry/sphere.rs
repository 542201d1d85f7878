//! Ray/sphere intersection: the numerically stable form of Haines, Günther & Akenine-Möller
//! (Ray Tracing Gems, ch. 7), and the textbook form kept for comparison.

use glam::{DVec3, Vec3};

use super::offset::gamma;

/// Nearest root `t` of `|o + t·d − c| = r` with `0 < t < t_max`, or `None`.
///
/// Stable formulation (Haines, Günther & Akenine-Möller, Ray Tracing Gems ch. 7): with
/// `f = o − c`, `a = d·d`, `b = f·d`, the discriminant is `a·(r² − |f − (b/a)·d|²)`, which keeps its
/// precision for small spheres far away, and the roots are `q = −b − sign(b)·√Δ`, `t₀ = c/q`,
/// `t₁ = q/a`, which avoids cancellation between `−b` and `√Δ`.
///
/// The arithmetic runs in f64 on the f32 inputs (all products of f32 values are exact in f64) and
/// `t` is rounded to f32 once. In f32 the perpendicular `f − (b/a)·d` of a sphere 1e3 away loses
/// ~1e-4 absolutely, which near tangency becomes tens of ulps in `t`, and `c = f·f − r²` cancels
/// catastrophically for origins next to a huge sphere; in f64 neither matters at f32 input
/// precision (`tests/stability.rs` checks ≤ 4 ulp and 1e-5 relative error). Scalar f64 costs the
/// same as scalar f32 here, and the result is still exact under power-of-two scaling.
#[inline]
pub fn intersect_stable(o: Vec3, d: Vec3, center: Vec3, radius: f32, t_max: f32) -> Option<f32> {
    let t = intersect_f64(
        o.as_dvec3(),
        d.as_dvec3(),
        center.as_dvec3(),
        radius as f64,
        t_max as f64,
    )? as f32;
    // Rounding to f32 may land on t_max (or, below 1e-45, on 0): re-check in f32.
    (t > 0.0 && t < t_max).then_some(t)
}

/// The textbook quadratic `t = (−b ± √(b² − 4ac)) / 2a` in f32: loses the near root to
/// cancellation and small far spheres to a rounded discriminant. Only for the error report.
#[inline]
pub fn intersect_naive(o: Vec3, d: Vec3, center: Vec3, radius: f32, t_max: f32) -> Option<f32> {
    let f = o - center;
    let a = d.dot(d);
    let b = 2.0 * f.dot(d);
    let c = f.dot(f) - radius * radius;
    let disc = b * b - 4.0 * a * c;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    nearest_root((-b - s) / (2.0 * a), (-b + s) / (2.0 * a), t_max)
}

/// The nearer of two roots `t0`, `t1` (in either order) with `0 < t < t_max`, or `None`: how every
/// ray/sphere test in the project picks its answer.
#[inline]
pub(crate) fn nearest_root(t0: f32, t1: f32, t_max: f32) -> Option<f32> {
    let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    if near > 0.0 && near < t_max {
        Some(near)
    } else if far > 0.0 && far < t_max {
        Some(far)
    } else {
        None
    }
}

/// The point on the sphere in the direction of `p` from the centre, its unit normal and its error
/// bound: re-projecting a hit point removes the error of `o + t·d` (PBR 4th ed. §6.8.5). The
/// centre-relative vector `v = r·(p − c)/|p − c|` is within `γ(5)·|v|` per component, and adding
/// the centre rounds once more (`γ(2)·|c + v|`, with margin).
#[inline]
pub(crate) fn reproject(p: Vec3, center: Vec3, radius: f32) -> (Vec3, Vec3, Vec3) {
    let n = (p - center).normalize();
    let v = radius * n;
    let point = center + v;
    let error = gamma(5) * v.abs() + gamma(2) * point.abs();
    (point, n, error)
}

/// The stable formulation in f64: nearest root with `0 < t < t_max`.
pub(crate) fn intersect_f64(
    o: DVec3,
    d: DVec3,
    center: DVec3,
    radius: f64,
    t_max: f64,
) -> Option<f64> {
    let f = o - center;
    let a = d.length_squared();
    let b = f.dot(d);
    let l = f - (b / a) * d;
    let disc = a * (radius * radius - l.length_squared());
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let c = f.dot(f) - radius * radius;
    let q = -b - disc.sqrt().copysign(b);
    let (t0, t1) = (c / q, q / a);
    let (near, far) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    if near > 0.0 && near < t_max {
        Some(near)
    } else if far > 0.0 && far < t_max {
        Some(far)
    } else {
        None
    }
}

#[cfg(test)]
// Test data and references may use the platform's functions; no pixel depends on them.
#[allow(clippy::disallowed_methods)]
mod tests {
    use super::*;

    #[test]
    fn hits_the_near_side_from_outside() {
        let t = intersect_stable(
            Vec3::ZERO,
            Vec3::NEG_Z,
            Vec3::new(0.0, 0.0, -5.0),
            1.0,
            f32::INFINITY,
        );
        assert_eq!(t, Some(4.0));
    }

    #[test]
    fn hits_the_far_side_from_inside() {
        let t = intersect_stable(Vec3::ZERO, Vec3::X, Vec3::ZERO, 2.0, f32::INFINITY);
        assert_eq!(t, Some(2.0));
    }

    #[test]
    fn respects_t_max_and_misses() {
        let c = Vec3::new(0.0, 0.0, -5.0);
        assert_eq!(intersect_stable(Vec3::ZERO, Vec3::NEG_Z, c, 1.0, 4.0), None);
        assert_eq!(
            intersect_stable(Vec3::ZERO, Vec3::Y, c, 1.0, f32::INFINITY),
            None
        );
        assert_eq!(
            intersect_stable(Vec3::ZERO, Vec3::Z, c, 1.0, f32::INFINITY),
            None
        );
    }

    #[test]
    fn nan_rays_miss() {
        let c = Vec3::new(0.0, 0.0, -5.0);
        assert_eq!(
            intersect_stable(Vec3::NAN, Vec3::NEG_Z, c, 1.0, f32::INFINITY),
            None
        );
        assert_eq!(
            intersect_stable(Vec3::ZERO, Vec3::NAN, c, 1.0, f32::INFINITY),
            None
        );
    }

    #[test]
    fn near_root_stays_accurate_just_above_a_huge_sphere() {
        // Origin 1e-2 above a sphere of radius 1000, looking 60° away from straight down.
        let c = Vec3::ZERO;
        let o = Vec3::new(0.0, 1000.01, 0.0);
        let d = Vec3::new(0.6f32.sin(), -0.6f32.cos(), 0.0);
        let t = intersect_stable(o, d, c, 1000.0, f32::INFINITY).unwrap() as f64;
        // Reference: the textbook quadratic in f64, independent of the code under test.
        let (od, dd) = (o.as_dvec3(), d.as_dvec3());
        let (b, cc) = (od.dot(dd), od.dot(od) - 1e6);
        let r = -b - (b * b - dd.dot(dd) * cc).sqrt();
        assert!(((t - r) / r).abs() < 1e-5, "{t} vs {r}");
        let naive = intersect_naive(o, d, c, 1000.0, f32::INFINITY).unwrap() as f64;
        assert!(
            ((naive - r) / r).abs() > 1e-5,
            "the naive form should be visibly worse here"
        );
    }
}
