//! Many spheres through a BVH ([`crate::accel::bvh`]): the closest and occluded sphere queries of
//! a world with more than [`SPHERE_BVH_MIN`] spheres, with exactly the answers of testing every
//! sphere in index order.
//!
//! Reads the world's spheres (once, to build) and one ray (origin, unnormalised direction,
//! `t_max`); writes the closest sphere hit `(t, index)` or a shadow bit.
//!
//! **Why a BVH, not the mesh's kD tree.** A sphere is one bounded object with a tight box: a BVH
//! puts each in exactly one leaf (a kD tree lists every sphere in each leaf its box straddles,
//! so it tests some several times and needs a mailbox or a per-leaf range check for the closest
//! hit), builds in one binned-SAH pass over box centres (the kD builders clip triangles to
//! boxes), and its traversal needs no split-plane reasoning to stay exact: a node is skipped only
//! when the slab test proves no point of its box is nearer than the best hit. The planes stay a
//! short list tested after the spheres: they are unbounded (a plane's box is all of space, so no
//! hierarchy can skip one), and scenes have a few.
//!
//! **Why the answers are the linear loop's.** [`sphere::intersect_stable`]'s answer for one
//! sphere does not depend on the `t_max` it is given except through `t < t_max`: it computes one
//! candidate `t` per sphere and accepts it when `0 < t < t_max`. The linear loop therefore
//! returns the smallest candidate below `t_max`, and among equal ones the lowest index (a later
//! sphere must be strictly nearer). Here each candidate is computed by the same function with
//! `t_max = ∞` and accepted when `t < best`, or `t == best` from a lower index — the same
//! minimum whatever order the leaves come in — and no node holding a candidate `t ≤ best` is
//! skipped:
//!
//! - each sphere's box is `c ± (r + pad)` with `pad = 2⁻²⁰·(|c|∞ + r) + 2⁻⁴⁰·M` (`M` the largest
//!   `|c|∞ + r`): this covers the rounding of the box corners to f32 and the distance from the
//!   sphere of the point `o + t·d` at the f64 test's root, which stays within a few f64 ulps of
//!   `|o − c|` even at tangency (where `t` itself is only good to √ε along the ray, but the
//!   point stays on the tangent line, within second order of the sphere). Rays from farther
//!   than `1024·M` widen every box by `2⁻⁴⁰·|o|∞` more (the `WIDE` walk).
//! - the slab test widens each far end by `1 + 2⁻²⁰` (pbrt's `1 + 2γ(3)` and more) and nodes are
//!   cut at `best·(1 + 2⁻¹⁶)` ([`limit_for`]), which covers the candidate's rounding to f32.
//! - rays the slab test cannot be trusted with (a non-finite component, a subnormal direction
//!   component) test every sphere, as the linear loop does.
//!
//! The tests below check this against the linear loop on random sphere sets and rays, tangent
//! rays and rays from points on the spheres among them.

use glam::Vec3;

use crate::accel::bvh::{Aabb, Bvh, SlabRay, limit_for};
use crate::geometry::sphere;
use crate::world::frame::Sphere;

/// Worlds with more spheres than this trace them through a [`SphereBvh`]; up to this many are
/// tested directly, 8 rays at a time with an f32 pre-test (scene A's three among them). Measured
/// (one thread, 256² renders of `many_spheres(n)` packed in front of the camera or spread out):
/// the direct kernel is faster up to about 120 spheres packed and 250 spread out; at 17 spheres
/// the BVH took twice as long, at 512 the direct loop took 1.4–2.7 times as long.
pub const SPHERE_BVH_MIN: usize = 128;

/// Rays from farther than this many times the spheres' reach take the widened walk.
const FAR_ORIGIN: f32 = 1024.0;

/// Spheres in a BVH, with a copy of each sphere's centre and radius in leaf order.
#[derive(Clone, Debug)]
pub struct SphereBvh {
    /// The hierarchy over the spheres' padded boxes; its items are sphere indices.
    bvh: Bvh,
    /// `(centre, radius)` of `bvh.items[k]` at `k`: a leaf's spheres are one contiguous run.
    leaf: Vec<[f32; 4]>,
    /// `FAR_ORIGIN · M`: rays with `|o|∞` beyond this take the widened walk.
    reach: f32,
}

/// `|v|∞`.
#[inline(always)]
fn max_norm(v: Vec3) -> f32 {
    v.abs().max_element()
}

impl SphereBvh {
    /// Builds the hierarchy over `spheres` (any number; worlds build one above
    /// [`SPHERE_BVH_MIN`]).
    pub fn new(spheres: &[Sphere]) -> SphereBvh {
        let extent = |s: &Sphere| max_norm(s.center) + s.radius;
        let m = spheres.iter().map(extent).fold(0.0f32, f32::max);
        let global = m / (1u64 << 40) as f32;
        let boxes: Vec<Aabb> = spheres
            .iter()
            .map(|s| {
                let reach = s.radius + (extent(s) / (1 << 20) as f32 + global);
                let c = s.center.to_array();
                (c.map(|v| v - reach), c.map(|v| v + reach))
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        let leaf = bvh
            .items
            .iter()
            .map(|&i| {
                let s = &spheres[i as usize];
                [s.center.x, s.center.y, s.center.z, s.radius]
            })
            .collect();
        SphereBvh {
            bvh,
            leaf,
            reach: m * FAR_ORIGIN,
        }
    }

    /// The hierarchy (for statistics and tests).
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// The slab ray for `o + t·d` and whether it takes the widened walk, or `None` when every
    /// sphere must be tested.
    #[inline(always)]
    fn ray(&self, o: Vec3, d: Vec3) -> Option<(SlabRay, bool)> {
        let far = max_norm(o);
        let wide = far > self.reach || far.is_nan();
        let widen = if wide { far / (1u64 << 40) as f32 } else { 0.0 };
        SlabRay::new(o.to_array(), d.to_array(), widen).map(|r| (r, wide))
    }

    /// Closest sphere hit with `0 < t < t_max`, ties to the lowest index: `(t, index)`, or
    /// `(t_max, u32::MAX)` when none — the state the linear loop over the spheres ends in.
    #[inline]
    pub fn closest(&self, o: Vec3, d: Vec3, t_max: f32) -> (f32, u32) {
        let mut best = t_max;
        // A tie needs a lower index than the best's: none before the first hit.
        let mut best_i = 0u32;
        let mut found = false;
        let mut test = |k: usize, best: &mut f32| {
            let [x, y, z, r] = self.leaf[k];
            if let Some(t) = sphere::intersect_stable(o, d, Vec3::new(x, y, z), r, f32::INFINITY) {
                let i = self.bvh.items[k];
                if t < *best || (t == *best && i < best_i) {
                    (*best, best_i, found) = (t, i, true);
                    return true;
                }
            }
            false
        };
        match self.ray(o, d) {
            Some((ray, wide)) => {
                let leaf = |items: std::ops::Range<usize>, limit: &mut f32| {
                    for k in items {
                        if test(k, &mut best) {
                            *limit = limit_for(best);
                        }
                    }
                    false
                };
                if wide {
                    self.bvh.visit::<true>(&ray, limit_for(t_max), leaf);
                } else {
                    self.bvh.visit::<false>(&ray, limit_for(t_max), leaf);
                }
            }
            None => {
                for k in 0..self.leaf.len() {
                    test(k, &mut best);
                }
            }
        }
        if found {
            (best, best_i)
        } else {
            (t_max, u32::MAX)
        }
    }

    /// True when some sphere is hit with `0 < t < t_max`; stops at the first found.
    #[inline]
    pub fn occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        let hits = |k: usize| {
            let [x, y, z, r] = self.leaf[k];
            sphere::intersect_stable(o, d, Vec3::new(x, y, z), r, t_max).is_some()
        };
        match self.ray(o, d) {
            Some((ray, wide)) => {
                let leaf = |mut items: std::ops::Range<usize>, _: &mut f32| items.any(hits);
                if wide {
                    self.bvh.visit::<true>(&ray, limit_for(t_max), leaf)
                } else {
                    self.bvh.visit::<false>(&ray, limit_for(t_max), leaf)
                }
            }
            None => (0..self.leaf.len()).any(hits),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The linear loop of [`crate::world::World::intersect_closest`] over spheres only.
    fn linear_closest(spheres: &[Sphere], o: Vec3, d: Vec3, t_max: f32) -> (f32, u32) {
        let mut best = t_max;
        let mut best_i = u32::MAX;
        for (i, s) in spheres.iter().enumerate() {
            if let Some(t) = sphere::intersect_stable(o, d, s.center, s.radius, best) {
                (best, best_i) = (t, i as u32);
            }
        }
        (best, best_i)
    }

    fn linear_occluded(spheres: &[Sphere], o: Vec3, d: Vec3, t_max: f32) -> bool {
        spheres
            .iter()
            .any(|s| sphere::intersect_stable(o, d, s.center, s.radius, t_max).is_some())
    }

    fn random_spheres(rng: &mut Rng, n: usize, spread: f32, radius: (f32, f32)) -> Vec<Sphere> {
        (0..n)
            .map(|i| Sphere {
                center: Vec3::new(
                    rng.range(-spread, spread),
                    rng.range(-spread, spread),
                    rng.range(-spread, spread),
                ),
                radius: rng.range(radius.0, radius.1),
                material: i as u32,
            })
            .collect()
    }

    fn unit(rng: &mut Rng) -> Vec3 {
        Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        )
        .normalize_or(Vec3::X)
    }

    /// Rays of every kind the renderer and hostile input make: from outside, from the
    /// spheres' surfaces (as their hit points, and as computed points a hair inside or outside),
    /// tangent to a sphere (at scales of the radius around 1), along axes, with zero
    /// components, unnormalised, with finite, tiny and NaN `t_max`, and non-finite or subnormal
    /// components (the linear fallback).
    fn rays(rng: &mut Rng, spheres: &[Sphere], spread: f32, n: usize) -> Vec<(Vec3, Vec3, f32)> {
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let s = &spheres[(rng.next_u64() % spheres.len() as u64) as usize];
            let far = Vec3::new(
                rng.range(-2.0 * spread, 2.0 * spread),
                rng.range(-2.0 * spread, 2.0 * spread),
                rng.range(-2.0 * spread, 2.0 * spread),
            );
            let on_surface = s.center + s.radius * unit(rng);
            let (o, d) = match i % 8 {
                0 => (far, unit(rng)),
                // Toward a sphere's centre, unnormalised.
                1 => (far, (s.center - far) * rng.range(0.01, 100.0)),
                // From a point on a sphere (outward, inward, along the surface).
                2 => (on_surface, unit(rng)),
                3 => {
                    // A hit point of the ray toward it, as the renderer computes it.
                    let d = (s.center - far).normalize();
                    let (t, _) = linear_closest(spheres, far, d, f32::INFINITY);
                    let p = if t.is_finite() {
                        far + t * d
                    } else {
                        on_surface
                    };
                    (p, unit(rng))
                }
                // Tangent (and nearly so) to a sphere.
                4 | 5 => {
                    let to_c = s.center - far;
                    let side = to_c.cross(unit(rng)).normalize_or(Vec3::Y);
                    let scale = [1.0, 1.0 - 1e-7, 1.0 + 1e-7, 0.9999, 1.0001, 1.0 + 3e-5][i % 6];
                    let target = s.center + side * s.radius * scale;
                    (far, target - far)
                }
                // Axis-aligned and zero-component directions through a centre.
                6 => {
                    let axis = (rng.next_u64() % 3) as usize;
                    let mut o = s.center;
                    o[axis] = far[axis];
                    let mut d = Vec3::ZERO;
                    d[axis] = if far[axis] > s.center[axis] {
                        -1.0
                    } else {
                        1.0
                    };
                    (o, d)
                }
                _ => match i % 64 {
                    7 => (Vec3::splat(f32::INFINITY), unit(rng)),
                    15 => (far, Vec3::NAN),
                    23 => (far, Vec3::ZERO),
                    31 => (far, Vec3::new(1e-40, 1.0, 0.0)),
                    39 => (far * 1e6, (s.center - far * 1e6).normalize()),
                    47 => (far, (s.center - far) * 1e-30),
                    _ => (far, (on_surface - far) * rng.range(0.5, 2.0)),
                },
            };
            let t_max = match i % 11 {
                0 => rng.range(0.0, spread),
                1 => 1.0,
                2 if i % 22 == 2 => f32::NAN,
                3 => 1e-6,
                _ => f32::INFINITY,
            };
            out.push((o, d, t_max));
        }
        out
    }

    fn agrees(spheres: &[Sphere], rays: &[(Vec3, Vec3, f32)]) -> usize {
        let bvh = SphereBvh::new(spheres);
        let mut hits = 0;
        for (i, &(o, d, t_max)) in rays.iter().enumerate() {
            let (t, k) = bvh.closest(o, d, t_max);
            let (lt, lk) = linear_closest(spheres, o, d, t_max);
            assert_eq!(
                (t.to_bits(), k),
                (lt.to_bits(), lk),
                "ray {i}: {o:?} {d:?} {t_max}"
            );
            assert_eq!(
                bvh.occluded(o, d, t_max),
                linear_occluded(spheres, o, d, t_max),
                "ray {i}: {o:?} {d:?} {t_max}"
            );
            hits += usize::from(lk != u32::MAX);
        }
        hits
    }

    #[test]
    fn random_sets_match_the_linear_loop_on_100k_rays() {
        let mut rng = Rng(2026);
        let mut total = 0;
        let mut hits = 0;
        for (n, spread, radius) in [
            (2000, 20.0, (0.05, 0.6)),
            (500, 5.0, (0.2, 2.0)),
            (20_000, 100.0, (0.01, 0.5)),
            (100, 1e4, (1.0, 500.0)),
            (300, 1e-3, (1e-6, 1e-4)),
        ] {
            let spheres = random_spheres(&mut rng, n, spread, radius);
            let rays = rays(&mut rng, &spheres, spread, 24_000);
            total += rays.len();
            hits += agrees(&spheres, &rays);
        }
        assert!(total >= 100_000);
        assert!(hits > total / 4, "{hits} of {total} rays hit");
    }

    /// Exact ties: duplicated spheres (same centre and radius under several indices, in
    /// scattered order) give the lowest index, as the linear loop does.
    #[test]
    fn duplicates_tie_to_the_lowest_index() {
        let mut rng = Rng(7);
        let mut spheres = random_spheres(&mut rng, 400, 10.0, (0.3, 1.0));
        for k in 0..400 {
            let s = spheres[(k * 37) % 400];
            spheres.push(s);
        }
        // Overlapping equal spheres build leaves holding duplicates and near-duplicates.
        spheres.extend(vec![spheres[3]; 40]);
        let rays = rays(&mut rng, &spheres, 10.0, 20_000);
        let bvh = SphereBvh::new(&spheres);
        let mut late = 0;
        for &(o, d, t_max) in &rays {
            let (t, k) = bvh.closest(o, d, t_max);
            let (lt, lk) = linear_closest(&spheres, o, d, t_max);
            assert_eq!((t.to_bits(), k), (lt.to_bits(), lk));
            late += usize::from(k != u32::MAX && k < 400 && spheres.len() > 400);
        }
        assert!(late > 1000, "duplicated spheres are hit ({late})");
    }

    /// A sphere of every set is hit tangentially by rays aimed at scales of its radius around
    /// 1, from near and far, and the tree agrees with the loop on each.
    #[test]
    fn tangent_rays_match_the_linear_loop() {
        let mut rng = Rng(99);
        let spheres = random_spheres(&mut rng, 5000, 30.0, (0.01, 1.0));
        let mut rays = vec![];
        for _ in 0..50_000 {
            let s = &spheres[(rng.next_u64() % spheres.len() as u64) as usize];
            let dist = [2.0, 20.0, 200.0, 2e4][(rng.next_u64() % 4) as usize];
            let o = s.center + unit(&mut rng) * s.radius * dist;
            let side = (s.center - o).cross(unit(&mut rng)).normalize_or(Vec3::Y);
            let scale =
                1.0 + rng.range(-1e-6, 1e-6) * [0.0, 1.0, 10.0][(rng.next_u64() % 3) as usize];
            rays.push((o, s.center + side * s.radius * scale - o, f32::INFINITY));
        }
        let hits = agrees(&spheres, &rays);
        assert!(hits > 10_000, "{hits}");
    }

    /// Rays grazing a sphere at its extreme point along an axis, nearly perpendicular to that
    /// axis, for small spheres far from the origin: they pass within an f32 ulp of the face of the
    /// sphere's box, so an unpadded box (its corners rounded to f32, sometimes inward) would lose
    /// some of their hits.
    #[test]
    fn rays_grazing_a_box_face_match_the_linear_loop() {
        let mut rng = Rng(31);
        let spheres: Vec<Sphere> = (0..2000)
            .map(|i| Sphere {
                center: Vec3::new(
                    rng.range(900.0, 1100.0),
                    rng.range(-1100.0, -900.0),
                    rng.range(900.0, 1100.0),
                ),
                radius: rng.range(0.001, 0.05),
                material: i,
            })
            .collect();
        let mut rays = vec![];
        for i in 0..60_000 {
            let s = &spheres[i % spheres.len()];
            let k = i % 3;
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let ulp = (s.center[k].abs() * f32::EPSILON) as f64;
            // Depth inside the extreme point: a few ulps of the centre either way.
            let depth = rng.range(-3.0, 3.0) as f64 * ulp;
            let mut u = unit(&mut rng);
            u[k] = 0.0;
            let u = u.normalize_or(if k == 0 { Vec3::Y } else { Vec3::X });
            let mut p = s.center.as_dvec3();
            p[k] += sign * (s.radius as f64 - depth);
            let o = p - u.as_dvec3() * (s.radius as f64 * rng.range(2.0, 50.0) as f64);
            let mut d = u;
            d[k] = rng.range(-1e-6, 1e-6);
            rays.push((o.as_vec3(), d, f32::INFINITY));
        }
        let hits = agrees(&spheres, &rays);
        assert!(hits > 10_000, "{hits}");
    }
}
