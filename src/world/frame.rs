//! The render frame: world coordinates translated so the eye is the origin, then rounded to f32.
//!
//! Scenes and OBJ files are read in f64 ([`crate::scene`], [`crate::mesh::ObjMesh`]); everything
//! the kernels trace — lights, planes, spheres, mesh vertices, tree files' boxes and splits — is
//! `p − eye` computed in f64 and rounded once to f32. Precision then follows the distance from the
//! camera, not from the world's origin: a scene moved by 10⁶ renders as it does at the origin
//! (pbrt-v4's default `CameraWorld` rendering space works the same way).

use glam::{DVec3, Vec3};

pub use crate::geometry::frame::RenderFrame;
use crate::mesh::ObjMesh;
use crate::scene;

/// A sphere in the render frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius (> 0).
    pub radius: f32,
    /// Material index.
    pub material: u32,
}

/// An infinite plane in the render frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// The plane's point nearest the frame origin (the eye): small where precision matters.
    pub point: Vec3,
    /// Unit normal.
    pub normal: Vec3,
    /// Material index.
    pub material: u32,
}

/// A light in the render frame (SPEC §14). [`Light::toward`] and `Light::attenuation` are the
/// one definition of where it lights from and how strongly; the shade stage's scalar and lane
/// paths both use them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Position (point and spot lights; zero for a directional light, which has none).
    pub position: Vec3,
    /// Intensity per channel.
    pub intensity: Vec3,
    /// Point, directional or spot.
    pub emission: Emission,
    /// The contribution at distance `r` is multiplied by `1 / r²`.
    pub inverse_square: bool,
}

/// How a render-frame light emits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Emission {
    /// Every way from its position.
    Point,
    /// Along one direction everywhere: `l` is `to_light` at every point, at infinite distance.
    Directional {
        /// The unit vector toward the light, `−normalize(direction)` (in f64, rounded).
        to_light: Vec3,
    },
    /// A cone from its position about `axis`: full within the half angle `inner`, none beyond
    /// `outer`, smoothstep in the angle between.
    Spot {
        /// Unit axis, the way the spot points (in f64, rounded).
        axis: Vec3,
        /// `cos(inner)`, rounded: at or above it, full intensity.
        cos_inner: f32,
        /// `cos(outer)`, rounded: at or below it, none.
        cos_outer: f32,
        /// Inner half angle `(θ − φ) / 2` in radians.
        inner: f64,
        /// Outer half angle `θ / 2` in radians.
        outer: f64,
    },
}

impl Light {
    /// A point light at `position` without falloff (SPEC §2's light).
    pub fn point(position: Vec3, intensity: Vec3) -> Light {
        Light {
            position,
            intensity,
            emission: Emission::Point,
            inverse_square: false,
        }
    }

    /// The unit vector `l` from `p` toward the light and the distance to it (∞ for a
    /// directional light), or `None` where the light gives nothing: a point or spot light at `p`
    /// itself or at a non-finite distance.
    #[inline]
    pub fn toward(&self, p: Vec3) -> Option<(Vec3, f32)> {
        if let Emission::Directional { to_light } = self.emission {
            return Some((to_light, f32::INFINITY));
        }
        let to_light = self.position - p;
        let dist = to_light.length();
        if !(dist > 0.0 && dist.is_finite()) {
            return None;
        }
        Some((to_light / dist, dist))
    }

    /// The light's unit direction `l` from `p` for the geometric side test (zero at the light
    /// itself): `l` of a directional light, else `normalize_or_zero(position − p)`.
    #[inline]
    pub(crate) fn side_direction(&self, p: Vec3) -> Vec3 {
        match self.emission {
            Emission::Directional { to_light } => to_light,
            _ => (self.position - p).normalize_or_zero(),
        }
    }

    /// Whether [`Light::attenuation`] can be anything but 1 (a spot light or `1/r²` falloff).
    #[inline]
    pub(crate) fn attenuates(&self) -> bool {
        self.inverse_square || matches!(self.emission, Emission::Spot { .. })
    }

    /// The factor the light's contribution is multiplied by toward unit `l` at distance `dist`
    /// (as [`Light::toward`] gives them): the spot factor (1 inside the inner cone, 0 outside
    /// the outer, `smoothstep` of the angle from the axis between) times `1 / dist²` with
    /// inverse-square falloff. 1 for a point light without falloff.
    #[inline]
    pub(crate) fn attenuation(&self, l: Vec3, dist: f32) -> f32 {
        let mut s = 1.0f32;
        if let Emission::Spot {
            axis,
            cos_inner,
            cos_outer,
            inner,
            outer,
        } = self.emission
        {
            let cos = -l.dot(axis);
            s = if cos >= cos_inner {
                1.0
            } else if cos <= cos_outer || cos.is_nan() {
                0.0
            } else {
                let angle = crate::arith::acos(f64::from(cos));
                let t = ((outer - angle) / (outer - inner)).clamp(0.0, 1.0);
                (t * t * (3.0 - 2.0 * t)) as f32
            };
        }
        if self.inverse_square {
            s /= dist * dist;
        }
        s
    }
}

/// The render frame of meshes and of the scene's primitives.
impl RenderFrame {
    /// The frame centred on a mesh's bounding box (f64): where a mesh on its own — `kdtree build`
    /// — is built with the most precision.
    pub fn centered_on(mesh: &ObjMesh) -> RenderFrame {
        let (lo, hi) = mesh.bounds();
        let origin = if lo.is_finite() && hi.is_finite() {
            (lo + hi) / 2.0
        } else {
            DVec3::ZERO
        };
        RenderFrame { origin }
    }

    /// A scene sphere in the frame.
    pub fn sphere(&self, s: &scene::Sphere) -> Sphere {
        Sphere {
            center: self.point(s.center),
            radius: s.radius,
            material: s.material,
        }
    }

    /// A scene plane in the frame, through its point nearest the eye (computed in f64).
    pub fn plane(&self, p: &scene::Plane) -> Plane {
        let n = p.normal.as_dvec3();
        let nearest = self.origin - (self.origin - p.point).dot(n) / n.length_squared() * n;
        Plane {
            point: self.point(nearest),
            normal: p.normal,
            material: p.material,
        }
    }

    /// A scene light in the frame: positions as [`RenderFrame::point`], directions normalised
    /// and cone angles' cosines computed in f64, then rounded.
    pub fn light(&self, l: &scene::Light) -> Light {
        let inverse_square = l.falloff == scene::Falloff::InverseSquare;
        let (position, emission) = match l.kind {
            scene::LightKind::Point { position } => (self.point(position), Emission::Point),
            scene::LightKind::Directional { direction } => {
                let to_light = (-unit(direction)).as_vec3();
                (Vec3::ZERO, Emission::Directional { to_light })
            }
            scene::LightKind::Spot {
                position,
                direction,
                cone,
                penumbra,
            } => {
                // Half angles in turns (a full turn is 360°), for `sin_cos_turns`.
                let (outer, inner) = (cone / 720.0, (cone - penumbra) / 720.0);
                let turn = std::f64::consts::TAU;
                let emission = Emission::Spot {
                    axis: unit(direction).as_vec3(),
                    cos_inner: crate::arith::sin_cos_turns(inner).1 as f32,
                    cos_outer: crate::arith::sin_cos_turns(outer).1 as f32,
                    inner: inner * turn,
                    outer: outer * turn,
                };
                (self.point(position), emission)
            }
        };
        Light {
            position,
            intensity: l.intensity,
            emission,
            inverse_square,
        }
    }
}

/// `d / |d|` in f64 for any non-zero finite `d`, scaled by its largest component first so a tiny
/// or huge vector neither underflows nor overflows.
fn unit(d: DVec3) -> DVec3 {
    (d / d.abs().max_element()).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_points_near_the_eye_keep_full_precision() {
        let frame = RenderFrame::at(DVec3::new(1e6, 1e6, 1e6));
        let p = DVec3::new(1e6 + 0.125, 1e6 - 4.0, 1e6 - 7.0);
        assert_eq!(frame.point(p), Vec3::new(0.125, -4.0, -7.0));
        assert_eq!(
            frame.world_coordinate(0, frame.coordinate(0, 1e6 + 0.5)),
            1e6 + 0.5
        );
    }

    #[test]
    fn planes_pass_through_their_point_nearest_the_eye() {
        let frame = RenderFrame::at(DVec3::new(3.0, 5.0, -1.0));
        let plane = scene::Plane {
            point: DVec3::new(100.0, -2.0, 50.0),
            normal: Vec3::Y,
            material: 0,
        };
        let p = frame.plane(&plane);
        assert_eq!(p.point, Vec3::new(0.0, -7.0, 0.0));
    }
}
