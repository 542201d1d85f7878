//! The render frame: world coordinates translated so the eye is the origin, then rounded to f32.
//!
//! Scenes and OBJ files are read in f64 ([`crate::scene`], [`crate::mesh::ObjMesh`]); everything
//! the kernels trace — lights, planes, spheres, mesh vertices, tree files' boxes and splits — is
//! `p − eye` computed in f64 and rounded once to f32. Precision then follows the distance from the
//! camera, not from the world's origin: a scene moved by 10⁶ renders as it does at the origin
//! (pbrt-v4's default `CameraWorld` rendering space works the same way).

use glam::{DVec3, Vec3};

use crate::mesh::ObjMesh;
use crate::scene;

/// The translation from world coordinates to the render frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderFrame {
    /// The frame's origin in world coordinates (the eye).
    pub origin: DVec3,
}

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

/// A point light in the render frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Position.
    pub position: Vec3,
    /// Intensity per channel.
    pub intensity: Vec3,
}

impl RenderFrame {
    /// The frame of a camera whose eye is `eye` (world coordinates).
    pub fn at(eye: DVec3) -> RenderFrame {
        RenderFrame { origin: eye }
    }

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

    /// A world point in the frame: `p − origin` in f64, rounded once to f32.
    #[inline]
    pub fn point(&self, p: DVec3) -> Vec3 {
        (p - self.origin).as_vec3()
    }

    /// A world coordinate along `axis` in the frame (for tree-file boxes and split planes).
    #[inline]
    pub fn coordinate(&self, axis: usize, x: f64) -> f32 {
        (x - self.origin[axis]) as f32
    }

    /// A frame coordinate along `axis` back in world coordinates (f64, exact).
    #[inline]
    pub fn world_coordinate(&self, axis: usize, x: f32) -> f64 {
        f64::from(x) + self.origin[axis]
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

    /// A scene light in the frame.
    pub fn light(&self, l: &scene::PointLight) -> Light {
        Light {
            position: self.point(l.position),
            intensity: l.intensity,
        }
    }
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
