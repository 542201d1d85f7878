//! Stage `generate`: camera rays for one wave of pixels (SPEC §1).
//!
//! Reads: camera, image settings, the wave's pixel range. Rays start at the eye, which is the
//! origin of the render frame ([`crate::world::frame`]).
//! Writes: [`CameraRays`] — every column of the depth-0 `RayQueue`, one row per sample, slots in
//! order.

// Lane loops index several parallel `[_; LANES]` arrays by lane: an index is clearer than zips.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;
use rayon::prelude::*;

use crate::queue::lanes::store3;
use crate::queue::region::Region;
use crate::queue::wave::Wave;
use crate::queue::{MIN_CHUNK, RayItem, RayQueue, Resize, SampleSlot};
use crate::sampling::{Strata, uniform};
use crate::scene::{Camera, ImageSettings};
use crate::simd::{Kernel, Level, dispatch};

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

crate::kernels! {
    /// The stage's kernels, in the order the schedule calls them.
    pub(crate) const KERNELS = [generate_camera_rays(CameraRays)];
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

/// Rays per lane group of the kernel: 16, one AVX-512 register of `f32`s (two AVX2 ones).
const LANES: usize = 16;

/// `1/d` when `x / d` and `x · (1/d)` round alike for every `x`: `d` a power of two whose
/// reciprocal is a normal float (both then scale `x` by an exact power of two and round once).
/// Scene A's 512-pixel image and 8 × 8 strata divide by such: a multiply instead of a division
/// per lane, the same bits.
fn exact_reciprocal(d: f32) -> Option<f32> {
    let r = 1.0 / d;
    let power_of_two = |v: f32| v.is_normal() && v.to_bits() & 0x007f_ffff == 0;
    (power_of_two(d) && power_of_two(r)).then_some(r)
}

/// `x / d` lane by lane, as a multiply by `rcp` when it is `d`'s [`exact_reciprocal`].
#[inline(always)]
fn divide(x: [f32; LANES], d: f32, rcp: Option<f32>) -> [f32; LANES] {
    match rcp {
        Some(r) => x.map(|v| v * r),
        None => x.map(|v| v / d),
    }
}

/// The generate kernel over one chunk of slots `first..first + direction.len()`: per group of
/// `LANES` slots, the pixel and stratum of each (stepped, never divided, from the chunk's first
/// slot), then the jitter hash, the image-plane point and the normalised direction in lanes — the
/// operations of [`camera_ray`] in its order, so every ray is bit-identical to it.
struct CameraKernel<'a> {
    camera: &'a Camera,
    image: &'a ImageSettings,
    wave: &'a Wave,
    strata: &'a Strata,
    /// Column and row of each sample's stratum (`s mod k`, `s div k`), as floats.
    stratum_x: &'a [f32],
    stratum_y: &'a [f32],
    first: u32,
    direction: &'a mut [Vec3],
}

impl Kernel for CameraKernel<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, _level: Level) {
        let (cam, image, wave, strata) = (self.camera, self.image, self.wave, self.strata);
        let region = wave.region;
        let (nx, ny) = (image.width, image.height);
        let spp = wave.samples.max(1);
        // Where the chunk's first slot is: its pixel (column i, row j of the image) and sample.
        let (pixel, mut s) = wave.pixel_of(SampleSlot(self.first));
        let (mut pixel, mut i, mut j) = (pixel.0, pixel.0 % nx, pixel.0 / nx);
        let jitter = strata.n > 1;
        let (kf, mf) = (strata.k as f32, strata.m as f32);
        let (tx, ty) = (self.stratum_x, self.stratum_y);
        let (rl, tb) = (cam.r - cam.l, cam.t - cam.b);
        let (nxf, nyf) = (nx as f32, ny as f32);
        let (rcp_k, rcp_m) = (exact_reciprocal(kf), exact_reciprocal(mf));
        let (rcp_nx, rcp_ny) = (exact_reciprocal(nxf), exact_reciprocal(nyf));
        let (u, v, w) = (cam.u, cam.v, cam.w);
        let dw = cam.d * w;
        let iota: [u32; LANES] = std::array::from_fn(|l| l as u32);
        for out in self.direction.chunks_mut(LANES) {
            let mut lp = [0u32; LANES];
            let mut ls = [0u32; LANES];
            let mut li = [0.0f32; LANES];
            let mut lj = [0.0f32; LANES];
            let mut lsx = [0.0f32; LANES];
            let mut lsy = [0.0f32; LANES];
            let full = out.len() == LANES;
            if full && s as usize + LANES <= spp as usize {
                // The group's 8 slots are samples s..s+8 of one pixel.
                let k = s as usize;
                (lp, li, lj) = ([pixel; LANES], [i as f32; LANES], [j as f32; LANES]);
                ls = iota.map(|l| s + l);
                lsx.copy_from_slice(&tx[k..k + LANES]);
                lsy.copy_from_slice(&ty[k..k + LANES]);
                s += LANES as u32;
                if s == spp {
                    s = 0;
                    next_pixel((&mut i, &mut j, &mut pixel), region, nx);
                }
            } else if full && spp == 1 && i as usize + LANES <= region.x1 as usize {
                // One sample per pixel, the group's 8 pixels on one row of the region.
                lp = iota.map(|l| pixel + l);
                li = iota.map(|l| (i + l) as f32);
                lj = [j as f32; LANES];
                (lsx, lsy) = ([tx[0]; LANES], [ty[0]; LANES]);
                (i, pixel) = (i + LANES as u32, pixel + LANES as u32);
                if i == region.x1 {
                    (i, j) = (region.x0, j + 1);
                    pixel = j * nx + i;
                }
            } else {
                for l in 0..out.len() {
                    (lp[l], ls[l], li[l], lj[l]) = (pixel, s, i as f32, j as f32);
                    (lsx[l], lsy[l]) = (tx[s as usize], ty[s as usize]);
                    // The next slot: the next sample, or the next pixel of the region (row-major).
                    s += 1;
                    if s == spp {
                        s = 0;
                        next_pixel((&mut i, &mut j, &mut pixel), region, nx);
                    }
                }
            }
            // The jitter first, then the image-plane point and direction: two straight lane
            // loops the compiler turns into vector code (one loop with the branch inside stayed
            // scalar: a `vsqrtss` and two `vdivss` per ray).
            let (mut dx, mut dy) = ([0.5f32; LANES], [0.5f32; LANES]);
            if jitter {
                let (mut sx, mut sy) = ([0.0f32; LANES], [0.0f32; LANES]);
                for l in 0..LANES {
                    let jx = uniform(image.seed, lp[l], 2 * ls[l]);
                    let jy = uniform(image.seed, lp[l], 2 * ls[l] + 1);
                    (sx[l], sy[l]) = (lsx[l] + jx, lsy[l] + jy);
                }
                (dx, dy) = (divide(sx, kf, rcp_k), divide(sy, mf, rcp_m));
            }
            let mut xs = [0.0f32; LANES];
            let mut ys = [0.0f32; LANES];
            for l in 0..LANES {
                (xs[l], ys[l]) = (rl * (li[l] + dx[l]), tb * (lj[l] + dy[l]));
            }
            let (xs, ys) = (divide(xs, nxf, rcp_nx), divide(ys, nyf, rcp_ny));
            let mut d = [[0.0f32; LANES]; 3];
            for l in 0..LANES {
                let us = cam.l + xs[l];
                let vs = cam.t - ys[l];
                let px = us * u.x + vs * v.x - dw.x;
                let py = us * u.y + vs * v.y - dw.y;
                let pz = us * u.z + vs * v.z - dw.z;
                let rcp = 1.0 / (px * px + py * py + pz * pz).sqrt();
                (d[0][l], d[1][l], d[2][l]) = (px * rcp, py * rcp, pz * rcp);
            }
            store3(&d, out);
        }
    }
}

/// Moves the region cursor `(i, j)` and its image index `pixel` to the next pixel of `region`,
/// row-major (`nx` pixels an image row).
#[inline(always)]
fn next_pixel((i, j, pixel): (&mut u32, &mut u32, &mut u32), region: Region, nx: u32) {
    if *i + 1 < region.x1 {
        (*i, *pixel) = (*i + 1, *pixel + 1);
    } else {
        (*i, *j) = (region.x0, *j + 1);
        *pixel = *j * nx + *i;
    }
}

/// Fills `out` with the wave's camera rays, one per sample, in slot order. The directions come
/// from a SIMD kernel ([`crate::simd::dispatch`]) per chunk of slots, bit-identical to
/// [`camera_ray`]; the other columns are constants and the slot number.
pub(crate) fn generate_camera_rays(
    camera: &Camera,
    image: &ImageSettings,
    wave: &Wave,
    out: Resize<CameraRays<'_>>,
) {
    generate_at(Level::current(), camera, image, wave, out);
}

/// [`generate_camera_rays`] with the kernel compiled for `level`.
fn generate_at(
    level: Level,
    camera: &Camera,
    image: &ImageSettings,
    wave: &Wave,
    out: Resize<CameraRays<'_>>,
) {
    let n = wave.len();
    let strata = Strata::new(wave.samples);
    let k = strata.k.max(1);
    let (stratum_x, stratum_y): (Vec<f32>, Vec<f32>) = (0..wave.samples.max(1))
        .map(|s| ((s % k) as f32, (s / k) as f32))
        .unzip();
    // The kernel writes every row of every column (only rows the queue did not have yet were
    // initialised by the resize).
    let out = out.resize(n);
    out.direction
        .par_chunks_mut(MIN_CHUNK)
        .enumerate()
        .for_each(|(c, direction)| {
            let kernel = CameraKernel {
                camera,
                image,
                wave,
                strata: &strata,
                stratum_x: &stratum_x,
                stratum_y: &stratum_y,
                first: (c * MIN_CHUNK) as u32,
                direction,
            };
            dispatch(level, kernel);
        });
    // Constant columns, overwritten in place.
    fill_f32(bytemuck::cast_slice_mut(out.origin), 0.0); // the eye: the render frame's origin
    fill_f32(out.t_max, f32::INFINITY);
    fill_f32(bytemuck::cast_slice_mut(out.weight), 1.0);
    let slots: &mut [u32] = bytemuck::cast_slice_mut(out.slot);
    let mut groups = slots.chunks_exact_mut(16);
    let iota: [u32; 16] = std::array::from_fn(|l| l as u32);
    let mut first = 0;
    for g in &mut groups {
        g.copy_from_slice(&iota.map(|l| first + l));
        first += 16;
    }
    for (l, s) in groups.into_remainder().iter_mut().enumerate() {
        *s = first + l as u32;
    }
}

/// Sets every element of `column` to `value` in blocks of 16 (vector stores; a plain `fill`
/// of a float stayed one scalar store per element).
fn fill_f32(column: &mut [f32], value: f32) {
    let mut blocks = column.chunks_exact_mut(16);
    for b in &mut blocks {
        b.copy_from_slice(&[value; 16]);
    }
    blocks.into_remainder().fill(value);
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
        generate_camera_rays(
            &scene.camera,
            &scene.image,
            &wave,
            CameraRays::resizing(&mut q),
        );
        assert_eq!(q.len(), 12);
        assert_eq!(q.origin().len(), 12);
        assert_eq!(q.weight()[5], Vec3::ONE);
        assert_eq!(q.slot(), (0..12).map(SampleSlot).collect::<Vec<_>>());
        for d in q.direction() {
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
    fn exact_reciprocals_divide_like_the_division() {
        assert_eq!(exact_reciprocal(3.0), None);
        assert_eq!(
            exact_reciprocal(f32::from_bits(254 << 23)),
            None,
            "1/d is subnormal"
        );
        for d in [1.0f32, 8.0, 512.0, 0.25] {
            let r = exact_reciprocal(d).unwrap();
            for x in [1.0f32, 0.7, 511.99997, 1e-38, 3.0e-39, f32::MAX] {
                assert_eq!((x * r).to_bits(), (x / d).to_bits(), "{x} / {d}");
            }
        }
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

    #[test]
    fn the_kernel_gives_camera_ray_bit_for_bit_at_every_level() {
        use crate::queue::region::Region;
        let scene = spheres();
        let image = &scene.image;
        let region = Region {
            x0: 3,
            x1: 20,
            y0: 7,
            y1: 30,
        };
        let waves = [
            Wave::of_image(512, 512, 512 * 100 + 7, 300, 5),
            Wave::of_image(512, 512, 1000, 1500, 1),
            Wave::of_image(512, 512, 0, 40, 64),
            Wave {
                region,
                image_width: 512,
                first: 5,
                pixels: 200,
                samples: 3,
            },
        ];
        for wave in waves {
            let strata = Strata::new(wave.samples);
            for level in Level::supported() {
                let mut q = RayQueue::default();
                generate_at(
                    level,
                    &scene.camera,
                    image,
                    &wave,
                    CameraRays::resizing(&mut q),
                );
                assert_eq!(q.len(), wave.len());
                for (s, d) in q.direction().iter().enumerate() {
                    let r = camera_ray(&scene.camera, image, &wave, &strata, SampleSlot(s as u32));
                    let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                    assert_eq!(
                        bits(*d),
                        bits(r.direction),
                        "{level:?} slot {s} of {wave:?}"
                    );
                }
            }
        }
    }
}
