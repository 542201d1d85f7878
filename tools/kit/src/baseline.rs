//! The recursive baseline the wavefront is measured against: a plain single-ray Whitted tracer in
//! f32, one pixel at a time, threads over rows — what a C tracer with `-O3` does.
//!
//! It shares the render frame (the [`World`]'s lights, spheres, planes and materials), the camera
//! formula, the sample positions and the per-light shading function with the wavefront, so the two
//! images agree to within rounding; everything about *how* rays are traced is its own: a
//! recursive `trace`, the textbook-stable f32 ray/sphere test, no queues, no compaction, no
//! allocation per ray. Meshes go through the kD tree's single-ray queries. Used by
//! `wavefront bench` and the criterion benches to print the wavefront's time as a ratio to it.

use glam::Vec3;
use rayon::prelude::*;

use wavefront::Film;
use wavefront::frame::{Plane, Sphere};
use wavefront::geometry::offset::{offset_ray_origin, shadow_t_max};
use wavefront::geometry::{plane, sphere};
use wavefront::queue::{PixelIndex, PrimId};
use wavefront::sampling::Strata;
use wavefront::scene::{RenderMode, Scene};
use wavefront::stages::shade::direct_light;
use wavefront::world::World;

/// Nearest root of `|o + t·d − c| = r` with `0 < t < t_max`, in f32 (`d` unit): the geometric
/// form with the stable root pair (Ray Tracing Gems ch. 7).
#[inline]
fn hit_sphere(o: Vec3, d: Vec3, s: &Sphere, t_max: f32) -> Option<f32> {
    let f = o - s.center;
    let b = f.dot(d);
    let l = f - b * d;
    let disc = s.radius * s.radius - l.length_squared();
    if disc < 0.0 {
        return None;
    }
    let c = f.length_squared() - s.radius * s.radius;
    let q = -b - disc.sqrt().copysign(b);
    sphere::nearest_root(c / q, q, t_max)
}

#[inline]
fn hit_plane(o: Vec3, d: Vec3, p: &Plane, t_max: f32) -> Option<f32> {
    plane::intersect(o, d, p.point, p.normal, t_max)
}

/// A recursive tracer over a world.
struct Tracer<'a> {
    scene: &'a Scene,
    world: &'a World,
    /// Evaluate the specular term at all.
    specular: bool,
}

/// The closest hit: distance, primitive kind and index.
#[derive(Clone, Copy)]
enum Hit {
    Sphere(usize),
    Plane(usize),
    Triangle(PrimId),
}

impl Tracer<'_> {
    fn closest(&self, o: Vec3, d: Vec3) -> Option<(f32, Hit)> {
        let mut best: Option<(f32, Hit)> = None;
        let mut t_max = f32::INFINITY;
        for (i, s) in self.world.spheres().iter().enumerate() {
            if let Some(t) = hit_sphere(o, d, s, t_max) {
                (t_max, best) = (t, Some((t, Hit::Sphere(i))));
            }
        }
        for (i, p) in self.world.planes().iter().enumerate() {
            if let Some(t) = hit_plane(o, d, p, t_max) {
                (t_max, best) = (t, Some((t, Hit::Plane(i))));
            }
        }
        if self.world.triangles().is_some() {
            let (t, prim) = self.world.intersect_closest(o, d, t_max);
            if prim.is_hit() && t < t_max {
                best = Some((t, Hit::Triangle(prim)));
            }
        }
        best
    }

    fn occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        self.world
            .spheres()
            .iter()
            .any(|s| hit_sphere(o, d, s, t_max).is_some())
            || self
                .world
                .planes()
                .iter()
                .any(|p| hit_plane(o, d, p, t_max).is_some())
            || (self.world.triangles().is_some() && self.world.intersect_occluded(o, d, t_max))
    }

    /// Radiance along `o + t·d` reflected `depth` times so far.
    fn trace(&self, o: Vec3, d: Vec3, depth: u32) -> Vec3 {
        let Some((t, hit)) = self.closest(o, d) else {
            return Vec3::ZERO;
        };
        if self.scene.render.mode == RenderMode::HitMask {
            return Vec3::ONE;
        }
        let p = o + t * d;
        let facing = |n: Vec3| if n.dot(d) > 0.0 { -n } else { n };
        let (point, n, spawn, material) = match hit {
            Hit::Sphere(i) => {
                let s = &self.world.spheres()[i];
                let (point, n, error) = sphere::reproject(p, s.center, s.radius);
                let n = facing(n);
                (point, n, offset_ray_origin(point, error, n), s.material)
            }
            Hit::Plane(i) => {
                let pl = &self.world.planes()[i];
                let (point, error) = plane::reproject(p, pl.point, pl.normal);
                let n = facing(pl.normal);
                (point, n, offset_ray_origin(point, error, n), pl.material)
            }
            Hit::Triangle(prim) => {
                let s = self.world.surface(prim, o, d, t);
                (s.point, s.normal, s.spawn, s.material)
            }
        };
        let m = &self.world.materials()[material as usize];
        let render = &self.scene.render;
        let specular = self.specular;
        let mut local = m.ka * render.ambient;
        for light in self.world.lights() {
            let (c, n_dot_l) = direct_light(light, m, specular, point, n, -d);
            if !render.shadows {
                local += c;
            } else if n_dot_l > 0.0 && c != Vec3::ZERO {
                let to = light.position - spawn;
                let dist = to.length();
                let dir = to / dist;
                if !self.occluded(spawn, dir, shadow_t_max(light.position, dir, dist)) {
                    local += c;
                }
            }
        }
        let mut radiance = (1.0 - m.alpha) * local;
        if m.reflects() && depth < render.max_depth {
            let r = d - 2.0 * d.dot(n) * n;
            radiance += m.alpha * self.trace(spawn, r, depth + 1);
        }
        radiance
    }
}

/// Renders `scene` with the recursive baseline on the current rayon pool (rows in parallel).
pub fn render_recursive(scene: &Scene, world: &World) -> Film {
    let image = &scene.image;
    let (w, h) = (image.width, image.height);
    let spp = image.samples.max(1);
    let strata = Strata::new(spp);
    let tracer = Tracer {
        scene,
        world,
        specular: scene.needs_specular(),
    };
    let mut film = Film::new(w, h);
    film.pixels
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(j, row)| {
            for (i, px) in row.iter_mut().enumerate() {
                let pixel = PixelIndex(j as u32 * w + i as u32);
                let mut sum = Vec3::ZERO;
                for s in 0..spp {
                    let offset = strata.offset(image.seed, pixel.0, s);
                    let d = scene.camera.ray_direction(pixel, offset, w, h);
                    sum += tracer.trace(Vec3::ZERO, d, 0);
                }
                *px = sum / spp as f32;
            }
        });
    film
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oracle::compare_rgb8;
    use wavefront::scene::builtin::spheres;
    use wavefront::{RenderOptions, render};

    #[test]
    fn the_baseline_renders_scene_a_like_the_wavefront() {
        let mut scene = spheres();
        scene.image.width = 128;
        scene.image.height = 128;
        scene.image.samples = 4;
        let world = World::load(&scene).unwrap();
        let ours = render(&scene, &world, RenderOptions::default(), |_, _| {}).0;
        let base = render_recursive(&scene, &world);
        let d = compare_rgb8(&ours.to_rgb8(2.2), &base.to_rgb8(2.2));
        // Same math, traced differently: all but silhouette pixels within 1/255.
        assert!(d.over_1 * 200 <= d.pixels, "{d}");
    }
}
