//! Stage `generate`: camera rays for one wave of pixels (SPEC §1).
//!
//! Reads: camera, image settings, the wave's pixel range.
//! Writes: `RayQueue.{origin, direction, t_max, weight, slot}`, one row per sample, slots in order.

use glam::Vec3;
use rayon::prelude::*;

use crate::queue::{MIN_CHUNK, RayItem, RayQueue, SampleSlot};
use crate::sampling::Strata;
use crate::scene::{Camera, ImageSettings};

/// A contiguous range of pixels rendered together; its samples fill slots `0..len()`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wave {
    /// First pixel (row-major index).
    pub first_pixel: u32,
    /// Number of pixels.
    pub pixels: u32,
    /// Samples per pixel.
    pub samples: u32,
}

impl Wave {
    /// Number of samples (= primary rays) in the wave.
    pub fn len(&self) -> usize {
        self.pixels as usize * self.samples as usize
    }

    /// True when the wave holds no pixels.
    pub fn is_empty(&self) -> bool {
        self.pixels == 0
    }
}

/// The primary ray of slot `slot` in `wave`: the per-row body of the kernel. `strata` is
/// `Strata::new(wave.samples)`, computed once per wave.
#[inline]
pub fn camera_ray(
    camera: &Camera,
    image: &ImageSettings,
    wave: &Wave,
    strata: &Strata,
    slot: u32,
) -> RayItem {
    let pixel = wave.first_pixel + slot / wave.samples;
    let s = slot % wave.samples;
    let (i, j) = (pixel % image.width, pixel / image.width);
    let (dx, dy) = strata.offset(image.seed, pixel, s);
    let d = camera.direction(i as f32 + dx, j as f32 + dy, image.width, image.height);
    RayItem {
        origin: camera.eye,
        direction: d.normalize(),
        t_max: f32::INFINITY,
        weight: Vec3::ONE,
        slot: SampleSlot(slot),
    }
}

/// Fills `rays` with the wave's camera rays, one per sample, in slot order.
pub fn generate_camera_rays(
    camera: &Camera,
    image: &ImageSettings,
    wave: &Wave,
    rays: &mut RayQueue,
) {
    let n = wave.len();
    let strata = Strata::new(wave.samples);
    let rows = || (0..n as u32).into_par_iter().with_min_len(MIN_CHUNK);
    rows()
        .map(|s| camera_ray(camera, image, wave, &strata, s).direction)
        .collect_into_vec(&mut rays.direction);
    rays.origin.clear();
    rays.origin.resize(n, camera.eye);
    rays.t_max.clear();
    rays.t_max.resize(n, f32::INFINITY);
    rays.weight.clear();
    rays.weight.resize(n, Vec3::ONE);
    rows().map(SampleSlot).collect_into_vec(&mut rays.slot);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin::spheres;

    #[test]
    fn fills_every_column_for_every_sample() {
        let scene = spheres();
        let wave = Wave {
            first_pixel: 512 * 256,
            pixels: 3,
            samples: 4,
        };
        let mut q = RayQueue::default();
        generate_camera_rays(&scene.camera, &scene.image, &wave, &mut q);
        assert_eq!(q.len(), 12);
        assert_eq!(q.origin.len(), 12);
        assert_eq!(q.weight[5], Vec3::ONE);
        assert_eq!(q.slot, (0..12).map(SampleSlot).collect::<Vec<_>>());
        for d in &q.direction {
            assert!((d.length() - 1.0).abs() < 1e-6);
            assert!(d.z < 0.0, "scene A looks down -z");
        }
        assert_eq!(
            q.get(7),
            camera_ray(&scene.camera, &scene.image, &wave, &Strata::new(4), 7)
        );
    }

    #[test]
    fn one_sample_goes_through_the_pixel_centre() {
        let mut scene = spheres();
        scene.image.width = 2;
        scene.image.height = 2;
        let wave = Wave {
            first_pixel: 0,
            pixels: 4,
            samples: 1,
        };
        let r = camera_ray(&scene.camera, &scene.image, &wave, &Strata::new(1), 0);
        // Pixel (0, 0) is the top-left: us = -0.05, vs = +0.05.
        let expected = Vec3::new(-0.05, 0.05, -0.1).normalize();
        assert!((r.direction - expected).length() < 1e-7);
        let r = camera_ray(&scene.camera, &scene.image, &wave, &Strata::new(1), 3);
        assert!((r.direction - Vec3::new(0.05, -0.05, -0.1).normalize()).length() < 1e-7);
    }
}
