//! Stage `generate`: camera rays for one wave of pixels (SPEC §1).
//!
//! Reads: camera, image settings, the wave's pixel range. Rays start at the eye, which is the
//! origin of the render frame ([`crate::frame`]).
//! Writes: [`CameraRays`] — every column of the depth-0 `RayQueue`, one row per sample, slots in
//! order.

use glam::Vec3;
use rayon::prelude::*;

use crate::queue::{MIN_CHUNK, RayItem, RayQueue, SampleSlot};
use crate::sampling::Strata;
use crate::scene::{Camera, ImageSettings};
use crate::wave::Wave;

crate::column_set! {
    /// What `generate_camera_rays` writes: the whole depth-0 ray queue.
    pub struct CameraRays<'a>: RayQueue {
        write origin: Vec3,
        write direction: Vec3,
        write t_max: f32,
        write weight: Vec3,
        write slot: SampleSlot,
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
    slot: SampleSlot,
) -> RayItem {
    let (pixel, s) = wave.pixel_of(slot);
    let (dx, dy) = strata.offset(image.seed, pixel.0, s);
    RayItem {
        origin: Vec3::ZERO, // the eye: the render frame's origin
        direction: camera.ray_direction(pixel, (dx, dy), image.width, image.height),
        t_max: f32::INFINITY,
        weight: Vec3::ONE,
        slot,
    }
}

/// Fills `out` with the wave's camera rays, one per sample, in slot order.
pub fn generate_camera_rays(
    camera: &Camera,
    image: &ImageSettings,
    wave: &Wave,
    out: CameraRays<'_>,
) {
    let n = wave.len();
    let strata = Strata::new(wave.samples);
    let rows = || (0..n as u32).into_par_iter().with_min_len(MIN_CHUNK);
    rows()
        .map(|s| camera_ray(camera, image, wave, &strata, SampleSlot(s)).direction)
        .collect_into_vec(out.direction);
    out.origin.clear();
    out.origin.resize(n, Vec3::ZERO); // the eye: the render frame's origin
    out.t_max.clear();
    out.t_max.resize(n, f32::INFINITY);
    out.weight.clear();
    out.weight.resize(n, Vec3::ONE);
    rows().map(SampleSlot).collect_into_vec(out.slot);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin::spheres;

    #[test]
    fn fills_every_column_for_every_sample() {
        let scene = spheres();
        let wave = Wave::of_image(512, 512, 512 * 256, 3, 4);
        let mut q = RayQueue::default();
        generate_camera_rays(&scene.camera, &scene.image, &wave, CameraRays::of(&mut q));
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
            camera_ray(
                &scene.camera,
                &scene.image,
                &wave,
                &Strata::new(4),
                SampleSlot(7)
            )
        );
    }

    #[test]
    fn one_sample_goes_through_the_pixel_centre() {
        let mut scene = spheres();
        scene.image.width = 2;
        scene.image.height = 2;
        let wave = Wave::of_image(2, 2, 0, 4, 1);
        let ray = |s| camera_ray(&scene.camera, &scene.image, &wave, &Strata::new(1), s);
        // Pixel (0, 0) is the top-left: us = -0.05, vs = +0.05.
        let expected = Vec3::new(-0.05, 0.05, -0.1).normalize();
        assert!((ray(SampleSlot(0)).direction - expected).length() < 1e-7);
        let expected = Vec3::new(0.05, -0.05, -0.1).normalize();
        assert!((ray(SampleSlot(3)).direction - expected).length() < 1e-7);
    }
}
