//! The analytic primitives (spheres, planes) as batch kernels over rays: 8 rays at a time in
//! lanes, compiled per SIMD [`Level`] and chosen at run time ([`crate::simd::dispatch`]).
//!
//! Each lane performs exactly the IEEE operations of the scalar tests, in the same order —
//! [`sphere::intersect_stable`] in f64 lanes on the f32 inputs, [`plane::intersect`] in f32 lanes
//! — with branches turned into selects, so every ray gets the bits [`World::intersect_closest`]
//! and [`World::intersect_occluded`] give it (tests below, at every supported level).
//!
//! [`sphere::intersect_stable`]: crate::geometry::sphere::intersect_stable
//! [`plane::intersect`]: crate::geometry::plane::intersect
//! [`World::intersect_closest`]: super::World::intersect_closest
//! [`World::intersect_occluded`]: super::World::intersect_occluded

use glam::Vec3;

use crate::frame::{Plane, Sphere};
use crate::queue::PrimId;
use crate::simd::{Kernel, Level, dispatch};

/// Rays per lane group.
pub(crate) const LANES: usize = 8;

/// A group of up to [`LANES`] rays, deinterleaved (unused lanes hold a ray that misses nothing
/// harmful: their results are never written).
#[derive(Clone, Copy)]
struct Rays8 {
    o: [[f32; LANES]; 3],
    d: [[f32; LANES]; 3],
    t_max: [f32; LANES],
}

impl Rays8 {
    #[inline(always)]
    fn load(origins: &[Vec3], dirs: &[Vec3], t_max: &[f32]) -> Rays8 {
        let mut r = Rays8 {
            o: [[0.0; LANES]; 3],
            d: [[0.0; LANES]; 3],
            t_max: [0.0; LANES],
        };
        for (l, ((o, d), t)) in origins.iter().zip(dirs).zip(t_max).enumerate() {
            for k in 0..3 {
                r.o[k][l] = o[k];
                r.d[k][l] = d[k];
            }
            r.t_max[l] = *t;
        }
        r
    }
}

/// The stable ray/sphere test of [`crate::geometry::sphere::intersect_f64`] (then rounded and
/// re-checked as `intersect_stable` does) on 8 lanes against `best` (each lane's `t_max`):
/// returns the lanes' `t` and whether each hit.
#[inline(always)]
fn sphere8(r: &Rays8, s: &Sphere, best: &[f32; LANES]) -> ([f32; LANES], [bool; LANES]) {
    let c = [s.center.x as f64, s.center.y as f64, s.center.z as f64];
    let rr = s.radius as f64 * s.radius as f64;
    let mut t_out = [0.0f32; LANES];
    let mut hit = [false; LANES];
    for l in 0..LANES {
        let (ox, oy, oz) = (r.o[0][l] as f64, r.o[1][l] as f64, r.o[2][l] as f64);
        let (dx, dy, dz) = (r.d[0][l] as f64, r.d[1][l] as f64, r.d[2][l] as f64);
        let (fx, fy, fz) = (ox - c[0], oy - c[1], oz - c[2]);
        let a = dx * dx + dy * dy + dz * dz;
        let b = fx * dx + fy * dy + fz * dz;
        let k = b / a;
        let (lx, ly, lz) = (fx - k * dx, fy - k * dy, fz - k * dz);
        let disc = a * (rr - (lx * lx + ly * ly + lz * lz));
        let cc = (fx * fx + fy * fy + fz * fz) - rr;
        let q = -b - disc.sqrt().copysign(b);
        let (t0, t1) = (cc / q, q / a);
        let le = t0 <= t1;
        let near = if le { t0 } else { t1 };
        let far = if le { t1 } else { t0 };
        let tm = best[l] as f64;
        let near_ok = near > 0.0 && near < tm;
        let far_ok = far > 0.0 && far < tm;
        let t64 = if near_ok { near } else { far };
        let t = t64 as f32;
        // `disc >= 0` is false for NaN, as the scalar test's early return.
        hit[l] = disc >= 0.0 && (near_ok || far_ok) && t > 0.0 && t < best[l];
        t_out[l] = t;
    }
    (t_out, hit)
}

/// [`crate::geometry::plane::intersect`] on 8 lanes against `best`.
#[inline(always)]
fn plane8(r: &Rays8, p: &Plane, best: &[f32; LANES]) -> ([f32; LANES], [bool; LANES]) {
    let (n, q) = (p.normal, p.point);
    let mut t_out = [0.0f32; LANES];
    let mut hit = [false; LANES];
    for l in 0..LANES {
        let denom = r.d[0][l] * n.x + r.d[1][l] * n.y + r.d[2][l] * n.z;
        let num = (q.x - r.o[0][l]) * n.x + (q.y - r.o[1][l]) * n.y + (q.z - r.o[2][l]) * n.z;
        let t = num / denom;
        t_out[l] = t;
        hit[l] = t > 0.0 && t < best[l];
    }
    (t_out, hit)
}

/// Closest analytic hit of every ray: `out_t`/`out_prim` as [`super::World::intersect_closest`]
/// gives them for a world of these spheres and planes only.
pub(crate) struct Closest<'a> {
    pub spheres: &'a [Sphere],
    pub planes: &'a [Plane],
    pub origins: &'a [Vec3],
    pub dirs: &'a [Vec3],
    pub t_max: &'a [f32],
    pub out_t: &'a mut [f32],
    pub out_prim: &'a mut [PrimId],
}

impl Closest<'_> {
    #[inline(always)]
    fn group(&self, r: &Rays8) -> ([f32; LANES], [u32; LANES]) {
        let mut best = r.t_max;
        let mut prim = [PrimId::NONE.0; LANES];
        for (i, s) in self.spheres.iter().enumerate() {
            let (t, hit) = sphere8(r, s, &best);
            for l in 0..LANES {
                best[l] = if hit[l] { t[l] } else { best[l] };
                prim[l] = if hit[l] { i as u32 } else { prim[l] };
            }
        }
        let ns = self.spheres.len() as u32;
        for (i, p) in self.planes.iter().enumerate() {
            let (t, hit) = plane8(r, p, &best);
            for l in 0..LANES {
                best[l] = if hit[l] { t[l] } else { best[l] };
                prim[l] = if hit[l] { ns + i as u32 } else { prim[l] };
            }
        }
        for l in 0..LANES {
            best[l] = if prim[l] == PrimId::NONE.0 {
                f32::INFINITY
            } else {
                best[l]
            };
        }
        (best, prim)
    }
}

impl Kernel for Closest<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, _level: Level) {
        let n = self.origins.len();
        let mut start = 0;
        while start < n {
            let end = (start + LANES).min(n);
            let r = Rays8::load(
                &self.origins[start..end],
                &self.dirs[start..end],
                &self.t_max[start..end],
            );
            let (t, prim) = self.group(&r);
            for (l, i) in (start..end).enumerate() {
                self.out_t[i] = t[l];
                self.out_prim[i] = PrimId(prim[l]);
            }
            start = end;
        }
    }
}

/// Whether any analytic primitive blocks each ray: `out[i]` as
/// [`super::World::intersect_occluded`] gives it for a world of these spheres and planes only.
pub(crate) struct Occluded<'a> {
    pub spheres: &'a [Sphere],
    pub planes: &'a [Plane],
    pub origins: &'a [Vec3],
    pub dirs: &'a [Vec3],
    pub t_max: &'a [f32],
    pub out: &'a mut [bool],
}

impl Kernel for Occluded<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, _level: Level) {
        let n = self.origins.len();
        let mut start = 0;
        while start < n {
            let end = (start + LANES).min(n);
            let r = Rays8::load(
                &self.origins[start..end],
                &self.dirs[start..end],
                &self.t_max[start..end],
            );
            let mut any = [false; LANES];
            for s in self.spheres {
                let (_, hit) = sphere8(&r, s, &r.t_max);
                for l in 0..LANES {
                    any[l] |= hit[l];
                }
            }
            for p in self.planes {
                let (_, hit) = plane8(&r, p, &r.t_max);
                for l in 0..LANES {
                    any[l] |= hit[l];
                }
            }
            self.out[start..end].copy_from_slice(&any[..end - start]);
            start = end;
        }
    }
}

/// Runs [`Closest`] at the current SIMD level.
pub(crate) fn closest(k: Closest<'_>) {
    dispatch(Level::current(), k)
}

/// Runs [`Occluded`] at the current SIMD level.
pub(crate) fn occluded(k: Occluded<'_>) {
    dispatch(Level::current(), k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;
    use crate::scene::builtin::spheres;
    use crate::world::World;

    /// Rays from scene A's eye, from points on and near its surfaces, and poisoned ones.
    fn rays(n: usize) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        let mut rng = Rng(17);
        let mut o = vec![];
        let mut d = vec![];
        let mut t = vec![];
        for i in 0..n {
            let origin = match i % 5 {
                0 => Vec3::ZERO,
                1 => Vec3::new(rng.range(-6.0, 6.0), -2.0, rng.range(-12.0, 0.0)),
                2 => Vec3::new(-4.0, 0.0, -7.0) + Vec3::new(0.0, 1.0 + 1e-6, 0.0),
                3 => Vec3::new(rng.range(-9.0, 9.0), rng.range(-3.0, 5.0), -20.0),
                _ => Vec3::new(0.0, 0.0, -5.0 + rng.range(0.99, 1.01)),
            };
            let dir = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            let dir = match i % 97 {
                0 => Vec3::NAN,
                1 => Vec3::ZERO,
                2 => Vec3::new(1.0, 0.0, 0.0),
                _ => dir.normalize_or(Vec3::NEG_Z),
            };
            o.push(if i % 89 == 0 { Vec3::INFINITY } else { origin });
            d.push(dir);
            t.push(match i % 3 {
                0 => f32::INFINITY,
                1 => rng.range(0.0, 12.0),
                _ => 5.0,
            });
        }
        (o, d, t)
    }

    #[test]
    fn closest_and_occluded_match_the_scalar_tests_bit_for_bit_at_every_level() {
        let world = World::load(&spheres()).unwrap();
        let (o, d, t) = rays(10_007);
        for level in Level::supported() {
            let mut out_t = vec![0.0; o.len()];
            let mut out_prim = vec![PrimId(7); o.len()];
            dispatch(
                level,
                Closest {
                    spheres: world.spheres(),
                    planes: world.planes(),
                    origins: &o,
                    dirs: &d,
                    t_max: &t,
                    out_t: &mut out_t,
                    out_prim: &mut out_prim,
                },
            );
            let mut occ = vec![false; o.len()];
            dispatch(
                level,
                Occluded {
                    spheres: world.spheres(),
                    planes: world.planes(),
                    origins: &o,
                    dirs: &d,
                    t_max: &t,
                    out: &mut occ,
                },
            );
            for i in 0..o.len() {
                let (st, sp) = world.intersect_closest(o[i], d[i], t[i]);
                assert_eq!(
                    (out_t[i].to_bits(), out_prim[i]),
                    (st.to_bits(), sp),
                    "{level:?} ray {i}"
                );
                assert_eq!(
                    occ[i],
                    world.intersect_occluded(o[i], d[i], t[i]),
                    "{level:?} ray {i}"
                );
            }
        }
    }

    /// Scene A plus a soup of triangles around its spheres, a triangle coinciding with the floor
    /// (ties) and one through the green sphere: the mixed world's batch queries against the
    /// scalar ones, row for row.
    #[test]
    fn a_mixed_world_batches_like_the_scalar_queries() {
        use crate::accel::kdtree::BuildMethod;
        use crate::mesh::TriangleMesh;
        let scene = spheres();
        let mut rng = Rng(5);
        let mut vertices = vec![];
        let mut indices = vec![];
        for k in 0..300u32 {
            let c = Vec3::new(
                rng.range(-8.0, 8.0),
                rng.range(-2.0, 4.0),
                rng.range(-14.0, -2.0),
            );
            for _ in 0..3 {
                let v = c + Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                );
                vertices.push(v.to_array());
            }
            indices.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        let b = vertices.len() as u32;
        vertices.extend([[-20.0, -2.0, 5.0], [20.0, -2.0, 5.0], [0.0, -2.0, -40.0]]);
        vertices.extend([[-2.0, 0.0, -5.0], [2.0, 0.0, -5.0], [0.0, 2.0, -5.0]]);
        indices.extend([[b, b + 1, b + 2], [b + 3, b + 4, b + 5]]);
        let world = World::with_mesh(
            &scene,
            &TriangleMesh::new(vertices, indices),
            BuildMethod::Sah,
        );
        let (o, d, t) = rays(20_011);
        let mut out_t = vec![0.0; o.len()];
        let mut out_prim = vec![PrimId(7); o.len()];
        world.intersect_closest_batch(&o, &d, &t, &mut out_t, &mut out_prim);
        let mut occ = vec![false; o.len()];
        world.intersect_occluded_batch(&o, &d, &t, &mut occ);
        let mut triangles = 0;
        for i in 0..o.len() {
            let (st, sp) = world.intersect_closest(o[i], d[i], t[i]);
            assert_eq!(
                (out_t[i].to_bits(), out_prim[i]),
                (st.to_bits(), sp),
                "ray {i}"
            );
            assert_eq!(
                occ[i],
                world.intersect_occluded(o[i], d[i], t[i]),
                "ray {i}"
            );
            triangles += usize::from(sp.is_hit() && sp.0 >= 4);
        }
        assert!(triangles > 1000, "the mesh is hit ({triangles} rays)");
    }
}
