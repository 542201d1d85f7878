//! The pinhole camera of SPEC §1: eye, basis `u v w`, image window `l r b t` at distance `d`.

use glam::{DVec3, Vec3};

use crate::queue::PixelIndex;

/// A pinhole camera looking along `-w`.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Eye position `e` (world coordinates, f64 as read): the origin of the render frame.
    pub eye: DVec3,
    /// Right vector `u`.
    pub u: Vec3,
    /// Up vector `v`.
    pub v: Vec3,
    /// Backward vector `w` (the camera looks along `-w`).
    pub w: Vec3,
    /// Window left edge `l`.
    pub l: f32,
    /// Window right edge `r`.
    pub r: f32,
    /// Window bottom edge `b`.
    pub b: f32,
    /// Window top edge `t`.
    pub t: f32,
    /// Distance `d` from the eye to the window.
    pub d: f32,
}

impl Camera {
    /// Unnormalised direction through the image-plane point `(x, y)` given in pixel units from the
    /// top-left corner of a `nx × ny` image: `x = i + 0.5`, `y = j + 0.5` is pixel `(i, j)`'s centre.
    ///
    /// `us = l + (r − l)·x/nx`, `vs = t − (t − b)·y/ny`, `dir = us·u + vs·v − d·w` (SPEC §1).
    #[inline]
    pub fn direction(&self, x: f32, y: f32, nx: u32, ny: u32) -> Vec3 {
        let us = self.l + (self.r - self.l) * x / nx as f32;
        let vs = self.t - (self.t - self.b) * y / ny as f32;
        us * self.u + vs * self.v - self.d * self.w
    }

    /// Unit direction of the ray through `offset` (in `[0, 1)²`, from the pixel's top-left
    /// corner) inside pixel `pixel` of a `nx × ny` image. Every camera ray the project traces —
    /// the generate stage's, the benchmarks' and the peers' — comes from here.
    #[inline]
    pub(crate) fn ray_direction(
        &self,
        pixel: PixelIndex,
        offset: (f32, f32),
        nx: u32,
        ny: u32,
    ) -> Vec3 {
        let (i, j) = (pixel.0 % nx, pixel.0 / nx);
        self.direction(i as f32 + offset.0, j as f32 + offset.1, nx, ny)
            .normalize()
    }

    /// The unit directions of the rays through every pixel centre of a `nx × ny` image, row-major
    /// from the top-left (what a 1-sample render traces first).
    pub fn pixel_centre_directions(&self, nx: u32, ny: u32) -> Vec<Vec3> {
        (0..nx * ny)
            .map(|p| self.ray_direction(PixelIndex(p), (0.5, 0.5), nx, ny))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_pixel_looks_along_minus_w() {
        let cam = Camera {
            eye: DVec3::ZERO,
            u: Vec3::X,
            v: Vec3::Y,
            w: Vec3::Z,
            l: -0.1,
            r: 0.1,
            b: -0.1,
            t: 0.1,
            d: 0.1,
        };
        // The exact centre of a 2×2 image is the corner shared by its four pixels.
        let d = cam.direction(1.0, 1.0, 2, 2);
        assert_eq!(d, Vec3::new(0.0, 0.0, -0.1));
        // Row 0 is the top: its rays point up.
        assert!(cam.direction(0.5, 0.5, 2, 2).y > 0.0);
        assert!(cam.direction(0.5, 0.5, 2, 2).x < 0.0);
    }
}
