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

// Lane loops index several parallel `[_; LANES]` arrays by lane: an index is clearer than zips.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;

use super::{SphereBvh, World};
use crate::geometry::offset::gamma;
use crate::geometry::plane;
use crate::queue::PrimId;
use crate::queue::lanes::{Lanes3, load1, load3, store3};
use crate::scene::OffsetMethod;
use crate::simd::{Kernel, Level, dispatch};
use crate::world::frame::{Plane, Sphere};

/// Rays per lane group.
pub(crate) const LANES: usize = 8;

/// A group of up to [`LANES`] rays, deinterleaved (unused lanes hold a ray that misses nothing
/// harmful: their results are never written).
#[derive(Clone, Copy)]
struct Rays8 {
    o: [[f32; LANES]; 3],
    d: [[f32; LANES]; 3],
    t_max: [f32; LANES],
    /// `1/|d|²` of each lane in f32 where `|d|²` is in `(1e-10, 1e10)`, else NaN (so
    /// [`misses8`] answers false): computed once per group, not per sphere.
    inv_a: [f32; LANES],
}

impl Rays8 {
    #[inline(always)]
    fn load(origins: &[Vec3], dirs: &[Vec3], t_max: &[f32]) -> Rays8 {
        let mut r = Rays8 {
            o: load3(origins),
            d: load3(dirs),
            t_max: [0.0; LANES],
            inv_a: [0.0; LANES],
        };
        for (l, t) in t_max.iter().take(LANES).enumerate() {
            r.t_max[l] = *t;
        }
        for l in 0..LANES {
            let a = r.d[0][l] * r.d[0][l] + r.d[1][l] * r.d[1][l] + r.d[2][l] * r.d[2][l];
            let ok = (a > 1e-10) & (a < 1e10);
            r.inv_a[l] = if ok { 1.0 / a } else { f32::NAN };
        }
        r
    }
}

/// The stable ray/sphere test of [`crate::geometry::sphere::intersect_f64`] (then rounded and
/// re-checked as `intersect_stable` does) on 8 lanes against `best` (each lane's `t_max`):
/// returns the lanes' `t` and whether each hit, or `None` when every lane's discriminant is
/// negative or NaN (every lane misses: the roots' square root and divisions are skipped).
#[inline(always)]
fn sphere8(r: &Rays8, s: &Sphere, best: &[f32; LANES]) -> Option<([f32; LANES], [bool; LANES])> {
    if misses8(r, s) {
        return None;
    }
    let c = [s.center.x as f64, s.center.y as f64, s.center.z as f64];
    let rr = s.radius as f64 * s.radius as f64;
    let mut a = [0.0f64; LANES];
    let mut b = [0.0f64; LANES];
    let mut disc = [0.0f64; LANES];
    let mut cc = [0.0f64; LANES];
    for l in 0..LANES {
        let (ox, oy, oz) = (r.o[0][l] as f64, r.o[1][l] as f64, r.o[2][l] as f64);
        let (dx, dy, dz) = (r.d[0][l] as f64, r.d[1][l] as f64, r.d[2][l] as f64);
        let (fx, fy, fz) = (ox - c[0], oy - c[1], oz - c[2]);
        a[l] = dx * dx + dy * dy + dz * dz;
        b[l] = fx * dx + fy * dy + fz * dz;
        let k = b[l] / a[l];
        let (lx, ly, lz) = (fx - k * dx, fy - k * dy, fz - k * dz);
        disc[l] = a[l] * (rr - (lx * lx + ly * ly + lz * lz));
        cc[l] = (fx * fx + fy * fy + fz * fz) - rr;
    }
    // `disc >= 0` is false for NaN, as the scalar test's early return.
    let mut any = false;
    for d in disc {
        any |= d >= 0.0;
    }
    if !any {
        return None;
    }
    let mut t_out = [0.0f32; LANES];
    let mut hit = [false; LANES];
    for l in 0..LANES {
        let q = -b[l] - disc[l].sqrt().copysign(b[l]);
        let (t0, t1) = (cc[l] / q, q / a[l]);
        let le = t0 <= t1;
        let near = if le { t0 } else { t1 };
        let far = if le { t1 } else { t0 };
        let tm = best[l] as f64;
        let near_ok = (near > 0.0) & (near < tm);
        let far_ok = (far > 0.0) & (far < tm);
        let t64 = if near_ok { near } else { far };
        let t = t64 as f32;
        hit[l] = (disc[l] >= 0.0) & (near_ok | far_ok) & (t > 0.0) & (t < best[l]);
        t_out[l] = t;
    }
    Some((t_out, hit))
}

/// Margin of [`misses8`], relative to `|o − c|² + r²`: f32 rounding moves the squared distance
/// from the centre to a ray's line, `|f|² − (f·d)²/|d|²` with `f = o − c`, by at most a few tens
/// of ulps of `|f|²` (`2^-24` each; `(f·d)²/|d|² ≤ |f|²`), far below this.
const MISS_MARGIN: f32 = 1e-4;

/// A conservative f32 pre-test of [`sphere8`]: true only when every lane's line passes farther
/// from the centre than the radius by more than [`MISS_MARGIN`] — then the f64 discriminant is
/// negative in every lane and `sphere8` returns `None`, so skipping it changes no bit. The
/// squared distance is `|f|² − (f·d)² · (1/|d|²)` with the group's [`Rays8::inv_a`]: no
/// division per sphere. Any doubt (a short group's empty lanes, a tiny or huge direction — NaN
/// `inv_a` —, a tiny radius, NaN or infinity, a line near the sphere) answers false and the f64
/// test decides.
#[inline(always)]
fn misses8(r: &Rays8, s: &Sphere) -> bool {
    let rr = s.radius * s.radius;
    if !(rr > 1e-30 && rr < 1e30) {
        return false;
    }
    let c = s.center;
    let mut miss = true;
    for l in 0..LANES {
        let f = [r.o[0][l] - c.x, r.o[1][l] - c.y, r.o[2][l] - c.z];
        let d = [r.d[0][l], r.d[1][l], r.d[2][l]];
        let b = f[0] * d[0] + f[1] * d[1] + f[2] * d[2];
        let ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
        let ll = ff - b * b * r.inv_a[l];
        let margin = MISS_MARGIN * (ff + rr);
        miss &= ll - rr > margin;
    }
    miss
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
        hit[l] = (t > 0.0) & (t < best[l]);
    }
    (t_out, hit)
}

/// Closest analytic hit of every ray: `out_t`/`out_prim` as [`super::World::intersect_closest`]
/// gives them for a world of these spheres and planes only.
pub(crate) struct Closest<'a> {
    pub spheres: &'a [Sphere],
    /// The spheres' BVH: when given, each ray goes through it (then the planes) on its own.
    pub sphere_bvh: Option<&'a SphereBvh>,
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
            let Some((t, hit)) = sphere8(r, s, &best) else {
                continue;
            };
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
        if let Some(bvh) = self.sphere_bvh {
            let ns = self.spheres.len() as u32;
            for i in 0..self.origins.len() {
                let (o, d) = (self.origins[i], self.dirs[i]);
                let (mut best, mut prim) = bvh.closest(o, d, self.t_max[i]);
                for (k, p) in self.planes.iter().enumerate() {
                    if let Some(t) = plane::intersect(o, d, p.point, p.normal, best) {
                        (best, prim) = (t, ns + k as u32);
                    }
                }
                self.out_t[i] = if prim == PrimId::NONE.0 {
                    f32::INFINITY
                } else {
                    best
                };
                self.out_prim[i] = PrimId(prim);
            }
            return;
        }
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
    /// The spheres' BVH: when given, each ray goes through it (then the planes) on its own.
    pub sphere_bvh: Option<&'a SphereBvh>,
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
        if let Some(bvh) = self.sphere_bvh {
            for i in 0..self.origins.len() {
                let (o, d, t_max) = (self.origins[i], self.dirs[i], self.t_max[i]);
                self.out[i] = bvh.occluded(o, d, t_max)
                    || self
                        .planes
                        .iter()
                        .any(|p| plane::intersect(o, d, p.point, p.normal, t_max).is_some());
            }
            return;
        }
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
                let Some((_, hit)) = sphere8(&r, s, &r.t_max) else {
                    continue;
                };
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

/// The output columns of `World::surface_batch`, one row per hit (a chunk of the hit queue).
pub struct SurfaceOut<'a> {
    /// [`Surface::point`](super::Surface::point) of each row.
    pub point: &'a mut [Vec3],
    /// [`Surface::normal`](super::Surface::normal) of each row.
    pub normal: &'a mut [Vec3],
    /// [`Surface::material`](super::Surface::material) of each row.
    pub material: &'a mut [u32],
    /// [`Surface::spawn`](super::Surface::spawn) of each row.
    pub spawn: &'a mut [Vec3],
    /// [`Surface::shading`](super::Surface::shading) of each row.
    pub shading: &'a mut [Vec3],
}

/// One analytic primitive as the surface kernel reads it: a sphere (`centre`, `radius`) or a
/// plane (`point` in `centre`, `normal`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct PrimEntry {
    sphere: bool,
    centre: [f32; 3],
    radius: f32,
    normal: [f32; 3],
    material: u32,
}

/// [`World::surface`] of 8 analytic hits in lanes (see [`World::surface_batch`]).
struct Surfaces<'a, 'b> {
    prims: &'a [PrimEntry],
    prim: &'a [PrimId],
    origins: &'a [Vec3],
    dirs: &'a [Vec3],
    t: &'a [f32],
    out: SurfaceOut<'b>,
}

/// `next_float_up` / `next_float_down` of [`crate::geometry::offset`], chosen by the sign of
/// `offset` (unchanged for a zero offset), as `offset_ray_origin` applies them per component.
#[inline(always)]
fn nudge(v: f32, offset: f32) -> f32 {
    let up = offset > 0.0;
    let down = offset < 0.0;
    // Infinities in the direction of the step and NaN stay.
    let stay = v.is_nan() | (up & (v == f32::INFINITY)) | (down & (v == f32::NEG_INFINITY));
    // Both zeros step from +0.0 up and from -0.0 down.
    let z = if up { 0.0f32 } else { -0.0f32 };
    let w = if v == 0.0 { z } else { v };
    let bits = w.to_bits();
    // Away from zero: up from +0.0 or a positive, down from -0.0 or a negative.
    let away = if up { w >= 0.0 } else { w <= 0.0 };
    let moved = if away {
        bits.wrapping_add(1)
    } else {
        bits.wrapping_sub(1)
    };
    if stay | !(up | down) {
        v
    } else {
        f32::from_bits(moved)
    }
}

impl Surfaces<'_, '_> {
    /// Rows `start..end` (at most [`LANES`]): gathered into lanes, computed branch-free, stored.
    #[inline(always)]
    fn group(&mut self, start: usize, end: usize) {
        let last = self.prims.len() - 1;
        let (g2, g4, g5) = (gamma(2), gamma(4), gamma(5));
        let o: Lanes3 = load3(&self.origins[start..end]);
        let d: Lanes3 = load3(&self.dirs[start..end]);
        let t = load1(&self.t[start..end], 0.0);
        let mut c = [[0.0f32; LANES]; 3];
        let mut nn = [[0.0f32; LANES]; 3];
        let mut radius = [0.0f32; LANES];
        let mut sphere = [false; LANES];
        let mut material = [0u32; LANES];
        let ids = &self.prim[start..end];
        if ids.len() == LANES && ids.iter().all(|&p| p == ids[0]) {
            // One primitive in every lane (neighbouring samples mostly are): splats, which the
            // lane loop below reads back as vectors without store-forwarding stalls.
            let e = &self.prims[(ids[0].0 as usize).min(last)];
            c = e.centre.map(|v| [v; LANES]);
            nn = e.normal.map(|v| [v; LANES]);
            (radius, sphere, material) =
                ([e.radius; LANES], [e.sphere; LANES], [e.material; LANES]);
        } else {
            for (l, i) in (start..end).enumerate() {
                let e = &self.prims[(self.prim[i].0 as usize).min(last)];
                for k in 0..3 {
                    c[k][l] = e.centre[k];
                    nn[k][l] = e.normal[k];
                }
                (radius[l], sphere[l], material[l]) = (e.radius, e.sphere, e.material);
            }
        }
        let mut point = [[0.0f32; LANES]; 3];
        let mut normal = [[0.0f32; LANES]; 3];
        let mut spawn = [[0.0f32; LANES]; 3];
        for l in 0..LANES {
            let p = [0, 1, 2].map(|k| o[k][l] + t[l] * d[k][l]);
            // Sphere: re-projected through the centre.
            let a = [0, 1, 2].map(|k| p[k] - c[k][l]);
            let len = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            let rcp = 1.0 / len;
            let sn = a.map(|x| x * rcp);
            let v = sn.map(|x| radius[l] * x);
            let sp = [0, 1, 2].map(|k| c[k][l] + v[k]);
            // Plane: projected along its normal.
            let n = [nn[0][l], nn[1][l], nn[2][l]];
            let s = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
            let pp = [0, 1, 2].map(|k| p[k] - s * n[k]);
            let s_error = g4 * ((a[0] * n[0]).abs() + (a[1] * n[1]).abs() + (a[2] * n[2]).abs());
            let mut pt = [0.0f32; 3];
            let mut geo = [0.0f32; 3];
            let mut err = [0.0f32; 3];
            for k in 0..3 {
                let sphere_err = g5 * v[k].abs() + g2 * sp[k].abs();
                let plane_err = n[k].abs() * s_error + g2 * (pp[k].abs() + (s * n[k]).abs());
                pt[k] = if sphere[l] { sp[k] } else { pp[k] };
                geo[k] = if sphere[l] { sn[k] } else { n[k] };
                err[k] = if sphere[l] { sphere_err } else { plane_err };
            }
            let flip = geo[0] * d[0][l] + geo[1] * d[1][l] + geo[2] * d[2][l] > 0.0;
            let nf = geo.map(|g| if flip { -g } else { g });
            let dd = nf[0].abs() * err[0] + nf[1].abs() * err[1] + nf[2].abs() * err[2];
            let po = [0, 1, 2].map(|k| {
                let offset = dd * nf[k];
                nudge(pt[k] + offset, offset)
            });
            let finite = po[0].is_finite() & po[1].is_finite() & po[2].is_finite();
            for k in 0..3 {
                point[k][l] = pt[k];
                normal[k][l] = nf[k];
                spawn[k][l] = if finite { po[k] } else { pt[k] };
            }
        }
        store3(&point, &mut self.out.point[start..end]);
        store3(&normal, &mut self.out.normal[start..end]);
        store3(&normal, &mut self.out.shading[start..end]);
        store3(&spawn, &mut self.out.spawn[start..end]);
        self.out.material[start..end].copy_from_slice(&material[..end - start]);
    }
}

impl Kernel for Surfaces<'_, '_> {
    type Output = ();
    #[inline(always)]
    fn run(mut self, _level: Level) {
        let n = self.prim.len();
        let mut start = 0;
        while start < n {
            let end = (start + LANES).min(n);
            self.group(start, end);
            start = end;
        }
    }
}

/// Analytic primitives up to this many are copied into a table on the stack per surface batch;
/// worlds with more keep theirs ([`World::prim_table`](super::World)).
pub(super) const SMALL_TABLE: usize = 16;

/// Spheres, then planes, as the surface kernel reads them (primitive id order).
pub(super) fn prim_entries<'a>(
    spheres: &'a [Sphere],
    planes: &'a [Plane],
) -> impl Iterator<Item = PrimEntry> + 'a {
    let spheres = spheres.iter().map(|s| PrimEntry {
        sphere: true,
        centre: s.center.to_array(),
        radius: s.radius,
        normal: [0.0; 3],
        material: s.material,
    });
    let planes = planes.iter().map(|p| PrimEntry {
        sphere: false,
        centre: p.point.to_array(),
        radius: 0.0,
        normal: p.normal.to_array(),
        material: p.material,
    });
    spheres.chain(planes)
}

impl World {
    /// [`World::surface`] of every row, bit-identical to it: `out`'s columns receive row `i`'s
    /// surface. Sphere and plane hits go through one branch-free kernel compiled per SIMD level
    /// (both re-projections evaluated, the primitive's chosen by a select); triangle hits, and
    /// worlds with the fixed-epsilon offset, call [`World::surface`] row by row.
    /// Panics if the slices' lengths differ.
    pub(crate) fn surface_batch(
        &self,
        prim: &[PrimId],
        origins: &[Vec3],
        dirs: &[Vec3],
        t: &[f32],
        out: SurfaceOut<'_>,
    ) {
        let n = prim.len();
        assert!(origins.len() == n && dirs.len() == n && t.len() == n);
        assert!(out.point.len() == n && out.normal.len() == n && out.material.len() == n);
        assert!(out.spawn.len() == n && out.shading.len() == n);
        let analytic = self.spheres.len() + self.planes.len();
        if analytic == 0 || self.robustness.offset != OffsetMethod::ErrorBound {
            for i in 0..n {
                let s = self.surface(prim[i], origins[i], dirs[i], t[i]);
                (out.point[i], out.normal[i], out.material[i]) = (s.point, s.normal, s.material);
                (out.spawn[i], out.shading[i]) = (s.spawn, s.shading);
            }
            return;
        }
        let mut prims = [PrimEntry::default(); SMALL_TABLE];
        let prims: &[PrimEntry] = if analytic <= prims.len() {
            for (slot, e) in prims
                .iter_mut()
                .zip(prim_entries(&self.spheres, &self.planes))
            {
                *slot = e;
            }
            &prims[..analytic]
        } else {
            &self.prim_table
        };
        let triangles = self.triangles.is_some();
        let SurfaceOut {
            point,
            normal,
            material,
            spawn,
            shading,
        } = out;
        dispatch(
            Level::current(),
            Surfaces {
                prims,
                prim,
                origins,
                dirs,
                t,
                out: SurfaceOut {
                    point: &mut *point,
                    normal: &mut *normal,
                    material: &mut *material,
                    spawn: &mut *spawn,
                    shading: &mut *shading,
                },
            },
        );
        if triangles {
            for i in 0..n {
                if prim[i].0 as usize >= analytic {
                    let s = self.surface(prim[i], origins[i], dirs[i], t[i]);
                    (point[i], normal[i], material[i]) = (s.point, s.normal, s.material);
                    (spawn[i], shading[i]) = (s.spawn, s.shading);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sphere;
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
        batches_match_scalar(&world, &o, &d, &t);
    }

    /// Rays grazing each sphere of scene A, 8 per group aimed at the same relative distance
    /// from the centre (1 ± 1e-7 … 1e-2 radii, the pre-test's margin among them).
    fn grazing_rays() -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
        let world = World::load(&spheres()).unwrap();
        let mut rng = Rng(5);
        let (mut o, mut d, mut t) = (vec![], vec![], vec![]);
        let scales = [
            0.99,
            0.9999,
            0.999_999,
            1.0,
            1.000_000_1,
            1.000_001,
            1.000_01,
            1.000_03,
            1.000_05,
            1.0001,
            1.0002,
            1.0005,
            1.001,
            1.01,
        ];
        // Origins near the scene, then far from it (`|o − c|²` large against `r²`).
        for (s, far) in world.spheres().iter().flat_map(|s| [(s, 1.0), (s, 300.0)]) {
            for scale in scales {
                for _ in 0..16 {
                    let origin = far
                        * Vec3::new(
                            rng.range(-10.0, 10.0),
                            rng.range(-1.0, 6.0),
                            rng.range(-15.0, 2.0),
                        );
                    let to_c = s.center - origin;
                    let side = to_c
                        .cross(Vec3::new(rng.range(-1.0, 1.0), 1.0, rng.range(-1.0, 1.0)))
                        .normalize();
                    let target = s.center + side * s.radius * scale;
                    o.push(origin);
                    d.push((target - origin).normalize());
                    t.push(f32::INFINITY);
                }
            }
        }
        (o, d, t)
    }

    #[test]
    fn grazing_rays_match_the_scalar_tests_and_the_pre_test_skips_only_misses() {
        let world = World::load(&spheres()).unwrap();
        let (o, d, t) = grazing_rays();
        batches_match_scalar(&world, &o, &d, &t);
        let mut skipped = 0;
        for g in (0..o.len()).step_by(LANES) {
            let r = Rays8::load(&o[g..g + LANES], &d[g..g + LANES], &t[g..g + LANES]);
            for s in world.spheres() {
                if misses8(&r, s) {
                    skipped += 1;
                    for i in g..g + LANES {
                        let hit = sphere::intersect_stable(o[i], d[i], s.center, s.radius, t[i]);
                        assert_eq!(hit, None, "ray {i} skipped but hits {s:?}");
                    }
                }
            }
        }
        // Groups aimed well outside (and far from the other spheres) are skipped.
        assert!(skipped > 0);
    }

    /// Runs [`Closest`] and [`Occluded`] over the rays at every supported level and checks each
    /// ray against the scalar queries, bit for bit.
    fn batches_match_scalar(world: &World, o: &[Vec3], d: &[Vec3], t: &[f32]) {
        for level in Level::supported() {
            let mut out_t = vec![0.0; o.len()];
            let mut out_prim = vec![PrimId(7); o.len()];
            dispatch(
                level,
                Closest {
                    spheres: world.spheres(),
                    sphere_bvh: None,
                    planes: world.planes(),
                    origins: o,
                    dirs: d,
                    t_max: t,
                    out_t: &mut out_t,
                    out_prim: &mut out_prim,
                },
            );
            let mut occ = vec![false; o.len()];
            dispatch(
                level,
                Occluded {
                    spheres: world.spheres(),
                    sphere_bvh: None,
                    planes: world.planes(),
                    origins: o,
                    dirs: d,
                    t_max: t,
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
        let world = mixed_world(&spheres());
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

    /// `scene` plus a soup of 300 triangles around scene A's spheres, a triangle coinciding with
    /// the floor (ties) and one through the green sphere.
    fn mixed_world(scene: &crate::scene::Scene) -> World {
        use crate::accel::kdtree::BuildMethod;
        use crate::mesh::TriangleMesh;
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
        World::with_mesh(
            scene,
            &TriangleMesh::new(vertices, indices),
            BuildMethod::Sah,
        )
    }

    /// Many spheres (through their BVH) over the floor, alone and with a mesh: the batch
    /// kernels at every level and the scalar queries give the answers of the direct loop over
    /// every sphere ([`World::with_direct_spheres`]), bit for bit, and the surfaces (through the
    /// world's primitive table) are the scalar ones.
    #[test]
    fn many_spheres_batch_like_the_direct_loop_at_every_level() {
        let scene = crate::scene::builtin::many_spheres(3000);
        let (mut o, mut d, mut t) = rays(20_011);
        // And rays into the cloud: from the eye and from points on the spheres, toward other
        // spheres (near their silhouettes too), as camera, reflection and shadow rays go.
        let world = World::load(&scene).unwrap();
        let mut rng = Rng(8);
        let s = world.spheres();
        for i in 0..20_000 {
            let a = &s[(rng.next_u64() % 3000) as usize];
            let b = &s[(rng.next_u64() % 3000) as usize];
            let dir = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            let from = if i % 2 == 0 {
                Vec3::ZERO
            } else {
                a.center + a.radius * dir.normalize_or(Vec3::Y)
            };
            let to = b.center + b.radius * rng.range(0.0, 1.1) * dir.normalize_or(Vec3::X);
            o.push(from);
            d.push(to - from);
            t.push(if i % 3 == 0 { 1.0 } else { f32::INFINITY });
        }
        for mesh in [false, true] {
            let load = || {
                if mesh {
                    mixed_world(&scene)
                } else {
                    World::load(&scene).unwrap()
                }
            };
            let world = load();
            assert!(world.sphere_bvh().is_some() && world.prim_table.len() == 3001);
            let direct = load().with_direct_spheres();
            let mut kinds = [0; 3];
            for i in 0..o.len() {
                let (dt, dp) = direct.intersect_closest(o[i], d[i], t[i]);
                let (st, sp) = world.intersect_closest(o[i], d[i], t[i]);
                assert_eq!(
                    (st.to_bits(), sp),
                    (dt.to_bits(), dp),
                    "mesh {mesh} ray {i}"
                );
                let occ = direct.intersect_occluded(o[i], d[i], t[i]);
                assert_eq!(world.intersect_occluded(o[i], d[i], t[i]), occ, "ray {i}");
                if sp.is_hit() {
                    // Sphere, plane (id 3000) or triangle.
                    kinds[usize::from(sp.0 >= 3000) + usize::from(sp.0 > 3000)] += 1;
                }
            }
            assert!(kinds[0] > 1000 && kinds[1] > 100, "{kinds:?}");
            assert!(!mesh || kinds[2] > 100, "{kinds:?}");
            for level in Level::supported() {
                let mut out_t = vec![0.0; o.len()];
                let mut out_prim = vec![PrimId(7); o.len()];
                let mut occ = vec![false; o.len()];
                if mesh {
                    world.intersect_closest_batch(&o, &d, &t, &mut out_t, &mut out_prim);
                    world.intersect_occluded_batch(&o, &d, &t, &mut occ);
                } else {
                    dispatch(
                        level,
                        Closest {
                            spheres: world.spheres(),
                            sphere_bvh: world.sphere_bvh(),
                            planes: world.planes(),
                            origins: &o,
                            dirs: &d,
                            t_max: &t,
                            out_t: &mut out_t,
                            out_prim: &mut out_prim,
                        },
                    );
                    dispatch(
                        level,
                        Occluded {
                            spheres: world.spheres(),
                            sphere_bvh: world.sphere_bvh(),
                            planes: world.planes(),
                            origins: &o,
                            dirs: &d,
                            t_max: &t,
                            out: &mut occ,
                        },
                    );
                }
                for i in 0..o.len() {
                    let (dt, dp) = direct.intersect_closest(o[i], d[i], t[i]);
                    assert_eq!(
                        (out_t[i].to_bits(), out_prim[i]),
                        (dt.to_bits(), dp),
                        "{level:?} mesh {mesh} ray {i}"
                    );
                    let blocked = direct.intersect_occluded(o[i], d[i], t[i]);
                    assert_eq!(occ[i], blocked, "{level:?} mesh {mesh} ray {i}");
                }
            }
            // Surfaces of the hits, through the world's table, against the scalar surface.
            let mut hit_t = vec![0.0; o.len()];
            let mut prim = vec![PrimId::NONE; o.len()];
            world.intersect_closest_batch(&o, &d, &t, &mut hit_t, &mut prim);
            let rows: Vec<usize> = (0..o.len()).filter(|&i| prim[i].is_hit()).collect();
            let pick = |c: &[Vec3]| rows.iter().map(|&i| c[i]).collect::<Vec<_>>();
            let (ro, rd) = (pick(&o), pick(&d));
            let rt: Vec<f32> = rows.iter().map(|&i| hit_t[i]).collect();
            let rp: Vec<PrimId> = rows.iter().map(|&i| prim[i]).collect();
            let n = rows.len();
            let mut cols = [vec![Vec3::NAN; n], vec![Vec3::NAN; n], vec![Vec3::NAN; n]];
            let mut shading = vec![Vec3::NAN; n];
            let mut material = vec![9; n];
            let [point, normal, spawn] = &mut cols;
            world.surface_batch(
                &rp,
                &ro,
                &rd,
                &rt,
                SurfaceOut {
                    point,
                    normal,
                    material: &mut material,
                    spawn,
                    shading: &mut shading,
                },
            );
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            for i in 0..n {
                let s = world.surface(rp[i], ro[i], rd[i], rt[i]);
                assert_eq!(bits(cols[0][i]), bits(s.point), "row {i}");
                assert_eq!(bits(cols[1][i]), bits(s.normal), "row {i}");
                assert_eq!(material[i], s.material, "row {i}");
                assert_eq!(bits(cols[2][i]), bits(s.spawn), "row {i}");
                assert_eq!(bits(shading[i]), bits(s.shading), "row {i}");
            }
        }
    }

    #[test]
    fn nudge_is_next_float_up_and_down() {
        use crate::geometry::offset::{next_float_down, next_float_up};
        let values = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MAX,
            -f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            3.5e-3,
            -7.25e5,
        ];
        for v in values {
            assert_eq!(nudge(v, 1.0).to_bits(), next_float_up(v).to_bits(), "{v}");
            assert_eq!(
                nudge(v, -1.0).to_bits(),
                next_float_down(v).to_bits(),
                "{v}"
            );
            assert_eq!(nudge(v, 0.0).to_bits(), v.to_bits(), "{v}");
        }
    }

    #[test]
    fn surfaces_match_the_scalar_surface_bit_for_bit_at_every_level() {
        let world = World::load(&spheres()).unwrap();
        let (o, d, t) = rays(10_007);
        let mut hit_t = vec![0.0; o.len()];
        let mut prim = vec![PrimId::NONE; o.len()];
        world.intersect_closest_batch(&o, &d, &t, &mut hit_t, &mut prim);
        let mut rows: Vec<usize> = (0..o.len()).filter(|&i| prim[i].is_hit()).collect();
        // Half the rows in primitive order: most groups of 8 then share one primitive (the
        // splatted entry), the rest mix them.
        let half = rows.len() / 2;
        rows[half..].sort_by_key(|&i| prim[i]);
        let pick = |c: &[Vec3]| rows.iter().map(|&i| c[i]).collect::<Vec<_>>();
        let (o, d) = (pick(&o), pick(&d));
        let t: Vec<f32> = rows.iter().map(|&i| hit_t[i]).collect();
        let prim: Vec<PrimId> = rows.iter().map(|&i| prim[i]).collect();
        assert!(rows.len() > 3000);
        let n = rows.len();
        for level in Level::supported() {
            let mut cols = (
                vec![Vec3::NAN; n],
                vec![Vec3::NAN; n],
                vec![9; n],
                vec![Vec3::NAN; n],
            );
            let mut shading = vec![Vec3::NAN; n];
            dispatch(
                level,
                Surfaces {
                    prims: &prim_entries(world.spheres(), world.planes()).collect::<Vec<_>>(),
                    prim: &prim,
                    origins: &o,
                    dirs: &d,
                    t: &t,
                    out: SurfaceOut {
                        point: &mut cols.0,
                        normal: &mut cols.1,
                        material: &mut cols.2,
                        spawn: &mut cols.3,
                        shading: &mut shading,
                    },
                },
            );
            for i in 0..n {
                let s = world.surface(prim[i], o[i], d[i], t[i]);
                let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(cols.0[i]), bits(s.point), "{level:?} row {i}");
                assert_eq!(bits(cols.1[i]), bits(s.normal), "{level:?} row {i}");
                assert_eq!(cols.2[i], s.material, "{level:?} row {i}");
                assert_eq!(bits(cols.3[i]), bits(s.spawn), "{level:?} row {i}");
                assert_eq!(bits(shading[i]), bits(s.shading), "{level:?} row {i}");
            }
        }
    }
}
