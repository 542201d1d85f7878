//! [`RenderFrame`]: the translation from world coordinates (f64) to the render frame (f32) whose
//! origin is the eye — the one conversion every traced coordinate goes through. Where the
//! origin is put and what is converted is [`crate::world::frame`]'s business.

use glam::{DVec3, Vec3};

/// The translation from world coordinates to the render frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderFrame {
    /// The frame's origin in world coordinates (the eye).
    pub origin: DVec3,
}

impl RenderFrame {
    /// The frame of a camera whose eye is `eye` (world coordinates).
    pub fn at(eye: DVec3) -> RenderFrame {
        RenderFrame { origin: eye }
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
    pub(crate) fn world_coordinate(&self, axis: usize, x: f32) -> f64 {
        f64::from(x) + self.origin[axis]
    }
}
