//! Look-at cameras (SPEC §10): `eye`, `look_at`, `up`, `fov_y` turned into the pinhole
//! [`Camera`] of SPEC §1, in f64.
//!
//! `w = normalize(eye − look_at)`, `u = normalize(up × w)`, `v = w × u`, `distance = 1`,
//! `t = tan(fov_y / 2)`, `b = −t`, `r = t · width / height`, `l = −r`; only the finished basis and
//! window are rounded to the camera's f32.

use glam::DVec3;

use super::Camera;

/// The smallest accepted sine of the angle between `up` and the view direction: below it, `up`
/// counts as parallel to the view and the basis is rejected rather than amplified from noise.
pub(crate) const MIN_UP_SINE: f64 = 1e-9;

/// A look-at view: where the eye is, what it looks at, which way is up, the vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookAt {
    /// Eye position.
    pub eye: DVec3,
    /// The point the camera looks at (projects to the image centre).
    pub look_at: DVec3,
    /// Up direction (need not be unit or perpendicular to the view; not parallel to it).
    pub up: DVec3,
    /// Full vertical field of view in degrees, `0 < fov_y < 180`.
    pub fov_y: f64,
}

/// Why a look-at view has no camera; each names the offending field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LookAtError {
    /// `eye` and `look_at` coincide: there is no view direction.
    #[error("look_at equals eye: there is no view direction")]
    NoViewDirection,
    /// `up` is zero or parallel to the view direction.
    #[error("up is zero or parallel to the view direction (eye − look_at)")]
    UpParallel,
    /// `fov_y` is not inside (0, 180) degrees.
    #[error("fov_y must be inside (0, 180) degrees")]
    FieldOfView,
}

impl LookAtError {
    /// The scene-file key the error is about (`look_at`, `up` or `fov_y`).
    pub fn key(&self) -> &'static str {
        match self {
            LookAtError::NoViewDirection => "look_at",
            LookAtError::UpParallel => "up",
            LookAtError::FieldOfView => "fov_y",
        }
    }
}

impl LookAt {
    /// The pinhole camera of this view for a `width × height` image, computed in f64.
    pub fn camera(&self, width: u32, height: u32) -> Result<Camera, LookAtError> {
        if !(self.fov_y > 0.0 && self.fov_y < 180.0) {
            return Err(LookAtError::FieldOfView);
        }
        let back = self.eye - self.look_at;
        let len = back.length();
        if len == 0.0 || !len.is_finite() {
            return Err(LookAtError::NoViewDirection);
        }
        let w = back / len;
        let side = self.up.cross(w);
        let up_len = self.up.length();
        let sine = side.length() / up_len; // NaN for a zero `up`
        if sine.is_nan() || sine <= MIN_UP_SINE {
            return Err(LookAtError::UpParallel);
        }
        let u = side.normalize();
        let v = w.cross(u);
        let t = crate::arith::tan(self.fov_y.to_radians() / 2.0);
        let r = t * f64::from(width) / f64::from(height);
        Ok(Camera {
            eye: self.eye,
            u: u.as_vec3(),
            v: v.as_vec3(),
            w: w.as_vec3(),
            l: -r as f32,
            r: r as f32,
            b: -t as f32,
            t: t as f32,
            d: 1.0,
        })
    }

    /// The view a fraction `s` of the way from `a` to `b`: `(1 − s)·a + s·b` for every field,
    /// in f64 (exactly `a` at `s = 0` and exactly `b` at `s = 1`).
    pub(crate) fn lerp(a: &LookAt, b: &LookAt, s: f64) -> LookAt {
        if s == 0.0 {
            return *a;
        }
        if s == 1.0 {
            return *b;
        }
        let mix = |x: DVec3, y: DVec3| x * (1.0 - s) + y * s;
        LookAt {
            eye: mix(a.eye, b.eye),
            look_at: mix(a.look_at, b.look_at),
            up: mix(a.up, b.up),
            fov_y: a.fov_y * (1.0 - s) + b.fov_y * s,
        }
    }
}

#[cfg(test)]
// Test data and references may use the platform's functions; no pixel depends on them.
#[allow(clippy::disallowed_methods)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn view() -> LookAt {
        LookAt {
            eye: DVec3::ZERO,
            look_at: DVec3::new(0.0, 0.0, -7.0),
            up: DVec3::new(0.0, 3.0, 0.0),
            fov_y: 90.0,
        }
    }

    #[test]
    fn looking_down_minus_z_gives_the_standard_basis() {
        let c = view().camera(512, 256).unwrap();
        assert_eq!((c.u, c.v, c.w), (Vec3::X, Vec3::Y, Vec3::Z));
        assert_eq!((c.b, c.t, c.d), (-1.0, 1.0, 1.0));
        assert_eq!((c.l, c.r), (-2.0, 2.0), "r = t · width / height");
        // The centre of the image looks at look_at.
        let d = c.direction(256.0, 128.0, 512, 256);
        assert_eq!(d, Vec3::new(0.0, 0.0, -1.0));
    }

    #[test]
    fn the_basis_is_orthonormal_for_an_oblique_view() {
        let v = LookAt {
            eye: DVec3::new(3.0, 2.0, 1.0),
            look_at: DVec3::new(-1.0, 0.5, -4.0),
            up: DVec3::new(0.2, 1.0, 0.1),
            fov_y: 40.0,
        };
        let c = v.camera(640, 480).unwrap();
        for (a, b) in [(c.u, c.v), (c.v, c.w), (c.u, c.w)] {
            assert!(a.dot(b).abs() < 1e-6);
        }
        assert!((c.u.cross(c.v) - c.w).length() < 1e-6, "right-handed");
        assert!(c.v.dot(Vec3::Y) > 0.0, "v points up");
        assert!((c.t - (20f32).to_radians().tan()).abs() < 1e-7);
    }

    #[test]
    fn degenerate_views_are_rejected_with_their_key() {
        let mut v = view();
        v.look_at = v.eye;
        assert_eq!(v.camera(8, 8).unwrap_err().key(), "look_at");
        let mut v = view();
        v.up = DVec3::new(0.0, 0.0, 2.0);
        assert_eq!(v.camera(8, 8).unwrap_err().key(), "up");
        v.up = DVec3::ZERO;
        assert_eq!(v.camera(8, 8).unwrap_err(), LookAtError::UpParallel);
        for fov in [0.0, 180.0, -5.0, f64::NAN] {
            let v = LookAt {
                fov_y: fov,
                ..view()
            };
            assert_eq!(v.camera(8, 8).unwrap_err().key(), "fov_y");
        }
    }

    #[test]
    fn lerp_is_exact_at_both_ends() {
        let a = view();
        let b = LookAt {
            eye: DVec3::new(0.1, 0.3, -0.7),
            look_at: DVec3::new(1.0 / 3.0, 0.0, -7.0),
            up: DVec3::new(0.1, 1.0, 0.0),
            fov_y: 33.3,
        };
        assert_eq!(LookAt::lerp(&a, &b, 0.0), a);
        assert_eq!(LookAt::lerp(&a, &b, 1.0), b);
        let mid = LookAt::lerp(&a, &b, 0.5);
        assert_eq!(mid.fov_y, (90.0 + 33.3) / 2.0);
        assert_eq!(mid.eye, DVec3::new(0.05, 0.15, -0.35));
    }
}
