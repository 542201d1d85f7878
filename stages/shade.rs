//! Stage `shade`: local Whitted shading at every hit (SPEC §2) and the shadow rays it needs.
//!
//! Reads: [`ShadeHits`]' read columns (`HitQueue.{origin, direction, t, prim, weight}`),
//! materials, lights; then [`ShadedHits`] (`HitQueue.{direction, weight, slot, point, normal,
//! material, spawn}`).
//! Writes: [`ShadeHits`]' write columns — `HitQueue.{point, normal, material, spawn}` and
//! `HitQueue.emitted` (the radiance added to the sample now, `(1 − α)·weight·(La [+ Ld + Ls when
//! shadows are off])`), which `add_emitted` adds to the samples — and [`ShadowRays`]: one
//! `ShadowQueue` row per hit and light that can light it, carrying `(1 − α)·weight·(Ld + Ls)`.
//!
//! Shadow rays are spawned one [`ShadowPass`] at a time — a block of hits × a block of lights of
//! at most a fixed number of rows — and the schedule traces each pass before spawning the next, so
//! memory is bounded however many lights there are. Each sample still receives its emitted
//! radiance first and then its lights in index order, so the image does not depend on the passes.

// Lane loops index several parallel `[_; LANES]` arrays by lane: an index is clearer than zips.
#![allow(clippy::needless_range_loop)]

use std::ops::Range;

use glam::Vec3;
use rayon::prelude::*;

use crate::arith;
use crate::geometry::offset::gamma;
use crate::geometry::offset::shadow_t_max;
use crate::queue::compact::compact;
use crate::queue::pass::{MAX_SHADOW_ROWS, ShadowPass};
use crate::queue::{HitQueue, MIN_CHUNK, PrimId, Resize, SampleSlot, Samples, ShadowQueue};
use crate::scene::{Material, ShadeSettings};
use crate::simd::{Level, Wide, WideKernel, dispatch_wide, dot3};
use crate::world::frame::{Emission, Light};
use crate::world::{Surface, SurfaceOut, World};

crate::column_set! {
    /// What `shade_hits` reads and writes in the hit queue.
    pub struct ShadeHits<'a>: HitQueue {
        read origin: Vec3,
        read direction: Vec3,
        read t: f32,
        read prim: PrimId,
        read weight: Vec3,
        write point: Vec3,
        write normal: Vec3,
        write material: u32,
        write spawn: Vec3,
        write shading: Vec3,
        write emitted: Vec3,
    }
}

crate::column_set! {
    /// What `spawn_shadow_rays` reads: the hits `shade_hits` has given their surfaces.
    pub struct ShadedHits<'a>: read HitQueue {
        direction: Vec3,
        weight: Vec3,
        slot: SampleSlot,
        point: Vec3,
        normal: Vec3,
        shading: Vec3,
        material: u32,
        spawn: Vec3,
    }
}

crate::column_set! {
    /// What `spawn_shadow_rays` writes: one pass's shadow rays, compacted in slot order.
    pub struct ShadowRays<'a>: ShadowQueue {
        write origin: Vec3,
        write direction: Vec3,
        write t_max: f32,
        write radiance: Vec3,
        write slot: SampleSlot,
    }
}

crate::column_set! {
    /// What `shade_hit_mask` reads and writes.
    pub struct MaskHits<'a>: HitQueue { read weight: Vec3, write emitted: Vec3 }
}

crate::column_set! {
    /// What `add_emitted` reads.
    pub struct EmittedHits<'a>: read HitQueue { slot: SampleSlot, emitted: Vec3 }
}

crate::kernels! {
    /// The stage's kernels, in the order the schedule calls them.
    pub(crate) const KERNELS = [
        shade_hits(ShadeHits),
        add_emitted(EmittedHits, Samples),
        spawn_shadow_rays(ShadedHits, ShadowRays),
    ];
}

crate::kernels! {
    /// The kernels of the stage's hit-mask variant, in order.
    pub const MASK_KERNELS = [shade_hit_mask(MaskHits), add_emitted(EmittedHits, Samples)];
}

/// `(Ld + Ls)·I·a` from one light at `p` with facing normal `n` and unit view vector `v`, and
/// `n·l`, where `l` and `a` are the light's direction and attenuation there ([`Light::toward`],
/// `Light::attenuation`: spot factor, falloff). Finite for every finite input: a zero half
/// vector counts as `n·h = 0`, a point or spot light at `p` itself gives nothing, and so does an
/// attenuated value that overflows.
#[inline]
pub(crate) fn direct_light(
    light: &Light,
    m: &Material,
    specular: bool,
    p: Vec3,
    n: Vec3,
    v: Vec3,
) -> (Vec3, f32) {
    let Some((l, dist)) = light.toward(p) else {
        return (Vec3::ZERO, 0.0);
    };
    let n_dot_l = n.dot(l);
    let mut c = m.kd * n_dot_l.max(0.0);
    if specular && m.has_specular() {
        let h = l + v;
        let len = h.length();
        let n_dot_h = if len > 0.0 {
            n.dot(h / len).max(0.0)
        } else {
            0.0
        };
        c += m.ks * arith::pow(n_dot_h, m.p);
    }
    let c = c * light.intensity;
    if !light.attenuates() {
        return (c, n_dot_l);
    }
    let c = c * light.attenuation(l, dist);
    (if c.is_finite() { c } else { Vec3::ZERO }, n_dot_l)
}

/// The radiance one hit emits now: `(1 − α)·weight·(La [+ Σ (Ld + Ls) over every light when
/// shadows are off])`. With shadows on, the lights' part comes through [`shadow_radiance`].
#[inline]
pub(crate) fn shade_hit(
    world: &World,
    settings: &ShadeSettings,
    (direction, weight): (Vec3, Vec3),
    surface: &Surface,
) -> Vec3 {
    let m = &world.materials()[surface.material as usize];
    let w = weight * (1.0 - m.alpha);
    let mut emitted = m.ka * settings.ambient;
    if !settings.shadows {
        let v = -direction;
        for light in world.lights() {
            emitted += direct_light(
                light,
                m,
                settings.specular,
                surface.point,
                surface.shading,
                v,
            )
            .0;
        }
    }
    w * emitted
}

/// The radiance `light` adds to a hit if its shadow ray is unoccluded, `(1 − α)·weight·(Ld + Ls)`
/// with the shading normal; zero — no shadow ray — where the light is behind the surface (the
/// geometric `normal`'s side: blocked by the surface itself) or adds nothing.
#[inline]
pub(crate) fn shadow_radiance(
    light: &Light,
    m: &Material,
    specular: bool,
    (direction, weight): (Vec3, Vec3),
    (point, normal, shading): (Vec3, Vec3, Vec3),
) -> Vec3 {
    let (c, n_dot_l) = if shading == normal {
        direct_light(light, m, specular, point, normal, -direction)
    } else {
        let (c, _) = direct_light(light, m, specular, point, shading, -direction);
        (c, normal.dot(light.side_direction(point)))
    };
    if n_dot_l > 0.0 && c != Vec3::ZERO {
        weight * (1.0 - m.alpha) * c
    } else {
        Vec3::ZERO
    }
}

/// The shadow ray from `origin` (the hit's offset spawn point) to `light`: unit direction and
/// `t_max`, the distance shortened at the light by its error bound (`shadow_t_max`); for a
/// directional light `l` itself and `t_max = ∞` (unbounded: anything along it blocks).
#[inline]
pub fn shadow_ray(origin: Vec3, light: &Light) -> (Vec3, f32) {
    if let Emission::Directional { to_light } = light.emission {
        return (to_light, f32::INFINITY);
    }
    let to = light.position - origin;
    let dist = to.length();
    let dir = to / dist;
    (dir, shadow_t_max(light.position, dir, dist))
}

/// Scratch for the shadow rays' variable output, reused across passes and waves; at most one
/// pass's rows (a [`ShadowPass`]'s budget), whatever the number of lights.
#[derive(Debug, Default)]
pub(crate) struct ShadeScratch {
    /// `shadow_radiance` of every (hit, light) row of the pass, hit-major.
    radiance: Vec<Vec3>,
    /// Kept rows (non-zero radiance) of each chunk of hits.
    counts: Vec<usize>,
}

/// Shades every hit: fills its surface columns and `emitted` (one row per hit). Each chunk of
/// rows goes through `World::surface_batch` (the SIMD surface kernel) and then the emitted
/// radiance of its rows.
pub(crate) fn shade_hits(world: &World, settings: &ShadeSettings, hits: ShadeHits<'_>) {
    let (prim, origin, direction, t, weight) =
        (hits.prim, hits.origin, hits.direction, hits.t, hits.weight);
    // With shadows on, a hit emits only its ambient term: `(1 − α)` and `ka·Ia` per material,
    // once per call, then `(weight·(1 − α))·(ka·Ia)` per row.
    let ambient_terms: Vec<(f32, Vec3)> = if settings.shadows {
        let terms = world.materials().iter();
        terms
            .map(|m| (1.0 - m.alpha, m.ka * settings.ambient))
            .collect()
    } else {
        Vec::new()
    };
    (
        hits.point.par_chunks_mut(MIN_CHUNK),
        hits.normal.par_chunks_mut(MIN_CHUNK),
        hits.material.par_chunks_mut(MIN_CHUNK),
        hits.spawn.par_chunks_mut(MIN_CHUNK),
        hits.shading.par_chunks_mut(MIN_CHUNK),
        hits.emitted.par_chunks_mut(MIN_CHUNK),
    )
        .into_par_iter()
        .enumerate()
        .for_each(|(c, (point, normal, material, spawn, shading, emitted))| {
            let r = c * MIN_CHUNK..c * MIN_CHUNK + point.len();
            world.surface_batch(
                &prim[r.clone()],
                &origin[r.clone()],
                &direction[r.clone()],
                &t[r.clone()],
                SurfaceOut {
                    point: &mut *point,
                    normal: &mut *normal,
                    material: &mut *material,
                    spawn: &mut *spawn,
                    shading: &mut *shading,
                },
            );
            if settings.shadows {
                // Ambient only (the lights come through shadow rays): `shade_hit`'s operations
                // on the row's material, without building its `Surface`.
                let rows = emitted.iter_mut().zip(&*material).zip(&weight[r.clone()]);
                for ((e, &m), &w) in rows {
                    let (keep, ambient) = ambient_terms[m as usize];
                    *e = (w * keep) * ambient;
                }
                return;
            }
            for (k, e) in emitted.iter_mut().enumerate() {
                let s = Surface {
                    point: point[k],
                    normal: normal[k],
                    material: material[k],
                    spawn: spawn[k],
                    shading: shading[k],
                };
                let i = r.start + k;
                *e = shade_hit(world, settings, (direction[i], weight[i]), &s);
            }
        });
}

/// Most lanes of a [`Wide`] type the shadow-ray kernels meet (stack buffers are this long).
const MAX_LANES: usize = 32;

/// `x.max(0.0)` on lanes as x86-64 computes `f32::max(x, 0.0)`: `0 > x ? 0 : x`, and 0 for NaN
/// (what LLVM emits for `maxnum`, `maxss(0, x)` then a NaN select).
#[inline(always)]
fn max0<V: Wide>(x: V) -> V {
    let zero = V::splat(0.0);
    V::select(V::eq(x, x), zero.max(x), zero)
}

/// `x^p` lane by lane, bit for bit [`arith::pow`] (`p`: one exponent per lane): when every lane
/// has the same integer exponent (one material, as neighbouring samples mostly have)
/// square-and-multiply runs across the lanes at once, from the exponent's highest bit; other
/// lanes take [`arith::pow`] one by one. Lanes whose power is not used (no specular, facing
/// away, NaN) may hold any value.
#[inline(always)]
fn specular_power<V: Wide>(x: V, p: &[f32]) -> V {
    let p = &p[..V::LANES];
    let shared = p.iter().all(|&q| q.to_bits() == p[0].to_bits());
    match arith::integer_exponent(p[0]) {
        Some(n) if shared => {
            let mut r = V::splat(1.0);
            let mut bit = match n {
                0 => 0,
                n => 1u32 << (31 - n.leading_zeros()),
            };
            while bit != 0 {
                r = r.mul(r);
                if n & bit != 0 {
                    r = r.mul(x);
                }
                bit >>= 1;
            }
            r
        }
        _ => {
            let mut xs = [0.0f32; MAX_LANES];
            x.store(&mut xs);
            for (v, &q) in xs.iter_mut().zip(p) {
                *v = arith::pow(*v, q);
            }
            V::load(&xs)
        }
    }
}

/// `v` in every lane, per component. (Helpers rather than closures: a closure's body, e.g.
/// through `array::map`, may stay out of line and so not be compiled for the kernel's level.)
#[inline(always)]
fn splat3<V: Wide>(v: Vec3) -> [V; 3] {
    [V::splat(v.x), V::splat(v.y), V::splat(v.z)]
}

/// Column `c`'s `rows` (exactly `V::LANES`) as x, y and z lanes.
#[inline(always)]
fn col3<V: Wide>(c: &[Vec3], rows: &Range<usize>) -> [V; 3] {
    V::load3(bytemuck::cast_slice(&c[rows.clone()]))
}

/// `V::LANES` hits of the shaded queue on lanes: what `shadow_radiance` reads.
struct HitLanes<V: Wide> {
    p: [V; 3],
    n: [V; 3],
    d: [V; 3],
    w: [V; 3],
    kd: [V; 3],
    ks: [V; 3],
    exponent: [f32; MAX_LANES],
    alpha: V,
    spec: V::Mask,
    /// Bit `l`: the shading normal of lane `l` differs from the geometric one (vertex
    /// normals): computed by the scalar `shadow_radiance` instead.
    smooth: u32,
}

impl<V: Wide> HitLanes<V> {
    /// Hits `rows` (exactly `V::LANES`).
    /// `meshes`: the world has triangles, whose shading normals may differ from the geometric
    /// ones (analytic hits' never do: their `smooth` bits are clear without reading `shading`).
    #[inline(always)]
    fn load(
        hits: &ShadedHits<'_>,
        materials: &[Material],
        specular: bool,
        meshes: bool,
        rows: Range<usize>,
    ) -> Self {
        let ids = &hits.material[rows.clone()];
        let (kd, ks, exponent, alpha, spec) = if ids.iter().all(|&m| m == ids[0]) {
            // One material in every lane (neighbouring samples mostly are): splats.
            let m = &materials[ids[0] as usize];
            let spec = f32::from(u8::from(specular && m.has_specular()));
            (
                splat3(m.kd),
                splat3(m.ks),
                [m.p; MAX_LANES],
                V::splat(m.alpha),
                V::splat(spec),
            )
        } else {
            // kd, ks, alpha and specular (1 or 0) per lane.
            let mut a = [[0.0f32; MAX_LANES]; 8];
            let mut e = [0.0f32; MAX_LANES];
            for (l, &id) in ids.iter().enumerate() {
                let m = &materials[id as usize];
                for k in 0..3 {
                    a[k][l] = m.kd[k];
                    a[3 + k][l] = m.ks[k];
                }
                (e[l], a[6][l]) = (m.p, m.alpha);
                a[7][l] = f32::from(u8::from(specular && m.has_specular()));
            }
            (
                [V::load(&a[0]), V::load(&a[1]), V::load(&a[2])],
                [V::load(&a[3]), V::load(&a[4]), V::load(&a[5])],
                e,
                V::load(&a[6]),
                V::load(&a[7]),
            )
        };
        let n = col3(hits.normal, &rows);
        let mut smooth = 0;
        if meshes {
            let s: [V; 3] = col3(hits.shading, &rows);
            let same = V::and(V::and(s[0].eq(n[0]), s[1].eq(n[1])), s[2].eq(n[2]));
            smooth = !V::bits(same) & (u32::MAX >> (32 - V::LANES));
        }
        HitLanes {
            p: col3(hits.point, &rows),
            n,
            d: col3(hits.direction, &rows),
            w: col3(hits.weight, &rows),
            kd,
            ks,
            exponent,
            alpha,
            spec: V::gt(spec, V::splat(0.5)),
            smooth,
        }
    }

    /// [`Light::toward`] from the hits, lane by lane in its operations' order: `l`, the
    /// distance, and whether the light gives anything.
    #[inline(always)]
    fn toward(&self, light: &Light) -> ([V; 3], V, V::Mask) {
        if let Emission::Directional { to_light } = light.emission {
            let all = V::le(V::splat(0.0), V::splat(1.0));
            return (splat3(to_light), V::splat(f32::INFINITY), all);
        }
        let lp: [V; 3] = splat3(light.position);
        let to = [
            lp[0].sub(self.p[0]),
            lp[1].sub(self.p[1]),
            lp[2].sub(self.p[2]),
        ];
        let dist = dot3(to, to).sqrt();
        let valid = V::and(dist.gt(V::splat(0.0)), dist.lt(V::splat(f32::INFINITY)));
        let u = [to[0].div(dist), to[1].div(dist), to[2].div(dist)];
        (u, dist, valid)
    }

    /// [`shadow_radiance`] of the hits toward `light`, lane by lane in its operations' order
    /// (the specular power as [`arith::pow`] gives it: [`specular_power`]; the attenuation from
    /// [`Light::attenuation`] itself), and a bit per lane whose value is non-zero.
    #[inline(always)]
    fn radiance(&self, light: &Light) -> ([V; 3], u32) {
        let zero = V::splat(0.0);
        let (u, dist, valid) = self.toward(light);
        let n = self.n;
        let n_dot_l = dot3(n, u);
        // The half vector with v = −d (`u + −d` is `u − d`).
        let h = [
            u[0].sub(self.d[0]),
            u[1].sub(self.d[1]),
            u[2].sub(self.d[2]),
        ];
        let len = dot3(h, h).sqrt();
        let hn = [h[0].div(len), h[1].div(len), h[2].div(len)];
        let ndh = max0(dot3(n, hn));
        let n_dot_h = V::select(len.gt(zero), ndh, zero);
        let power = specular_power(n_dot_h, &self.exponent);
        let diffuse = max0(n_dot_l);
        let mut c = [zero; 3];
        for k in 0..3 {
            let kd = self.kd[k].mul(diffuse);
            let with_spec = kd.add(self.ks[k].mul(power));
            c[k] = V::select(self.spec, with_spec, kd).mul(V::splat(light.intensity[k]));
        }
        if light.attenuates() {
            let mut us = [0.0f32; 3 * MAX_LANES];
            let (mut ds, mut scale) = ([0.0f32; MAX_LANES], [0.0f32; MAX_LANES]);
            V::store3(u, &mut us);
            dist.store(&mut ds);
            for l in 0..V::LANES {
                scale[l] = light.attenuation(Vec3::from_slice(&us[3 * l..]), ds[l]);
            }
            let scale = V::load(&scale);
            for x in &mut c {
                *x = x.mul(scale);
            }
            let inf = V::splat(f32::INFINITY);
            let finite = V::and(
                V::and(c[0].abs().lt(inf), c[1].abs().lt(inf)),
                c[2].abs().lt(inf),
            );
            for x in &mut c {
                *x = V::select(finite, *x, zero);
            }
        }
        let c_zero = V::and(V::and(c[0].eq(zero), c[1].eq(zero)), c[2].eq(zero));
        let lit = V::and(valid, n_dot_l.gt(zero));
        let keep = V::splat(1.0).sub(self.alpha);
        let mut out = [zero; 3];
        for k in 0..3 {
            let r = self.w[k].mul(keep).mul(c[k]);
            out[k] = V::select(c_zero, zero, V::select(lit, r, zero));
        }
        let o_zero = V::and(V::and(out[0].eq(zero), out[1].eq(zero)), out[2].eq(zero));
        let all = u32::MAX >> (32 - V::LANES);
        (out, !V::bits(o_zero) & all)
    }
}

/// The first pass of [`spawn_shadow_rays`] over one chunk of hits: every (hit, light) row's
/// radiance (hit-major) into `out`; returns how many are non-zero.
struct RadianceKernel<'a, 'h> {
    hits: &'a ShadedHits<'h>,
    materials: &'a [Material],
    specular: bool,
    /// The world has triangles (see [`HitLanes::load`]).
    meshes: bool,
    lights: &'a [Light],
    hits_range: Range<usize>,
    out: &'a mut [Vec3],
}

impl RadianceKernel<'_, '_> {
    /// The scalar definition for row `h` and light `li`: written to `out`, true when non-zero.
    #[inline(always)]
    fn scalar(&mut self, h: usize, li: usize) -> bool {
        let m = &self.materials[self.hits.material[h] as usize];
        let (d, w) = (self.hits.direction[h], self.hits.weight[h]);
        let surface = (
            self.hits.point[h],
            self.hits.normal[h],
            self.hits.shading[h],
        );
        let light = &self.lights[li];
        let v = shadow_radiance(light, m, self.specular, (d, w), surface);
        self.out[(h - self.hits_range.start) * self.lights.len() + li] = v;
        v != Vec3::ZERO
    }
}

impl WideKernel for RadianceKernel<'_, '_> {
    type Output = usize;
    #[inline(always)]
    fn run<V: Wide>(mut self) -> usize {
        let (lights, per_hit) = (self.lights, self.lights.len());
        let mut kept = 0;
        let Range { start, end } = self.hits_range;
        let n = V::LANES;
        let mut g = start;
        while g + n <= end {
            let rows = g..g + n;
            g += n;
            let x = HitLanes::<V>::load(
                self.hits,
                self.materials,
                self.specular,
                self.meshes,
                rows.clone(),
            );
            for (li, light) in lights.iter().enumerate() {
                let (r, nonzero) = x.radiance(light);
                if per_hit == 1 && x.smooth == 0 {
                    // One light: the group's rows are consecutive.
                    kept += nonzero.count_ones() as usize;
                    let out = &mut self.out[rows.start - start..rows.end - start];
                    V::store3(r, bytemuck::cast_slice_mut(out));
                    continue;
                }
                let mut rs = [0.0f32; 3 * MAX_LANES];
                V::store3(r, &mut rs);
                for (l, h) in rows.clone().enumerate() {
                    if (x.smooth >> l) & 1 != 0 {
                        kept += usize::from(self.scalar(h, li));
                        continue;
                    }
                    kept += ((nonzero >> l) & 1) as usize;
                    self.out[(h - start) * per_hit + li] = Vec3::from_slice(&rs[3 * l..]);
                }
            }
        }
        // The last rows (fewer than a group): the scalar definition.
        for h in g..end {
            for li in 0..per_hit {
                kept += usize::from(self.scalar(h, li));
            }
        }
        kept
    }
}

/// [`shadow_ray`] from `V::LANES` spawn points toward `light`, on [`Wide`] lanes in its
/// operations' order: directions and `t_max` (the test checks the bits against `shadow_ray`).
#[inline(always)]
fn shadow_rays_wide<V: Wide>(spawn: [V; 3], light: &Light) -> ([V; 3], V) {
    if let Emission::Directional { to_light } = light.emission {
        return (splat3(to_light), V::splat(f32::INFINITY));
    }
    let lp: [V; 3] = splat3(light.position);
    let le = splat3(gamma(1) * light.position.abs());
    let to = [
        lp[0].sub(spawn[0]),
        lp[1].sub(spawn[1]),
        lp[2].sub(spawn[2]),
    ];
    let dist = dot3(to, to).sqrt();
    let u = [to[0].div(dist), to[1].div(dist), to[2].div(dist)];
    let along = u[0]
        .abs()
        .mul(le[0])
        .add(u[1].abs().mul(le[1]))
        .add(u[2].abs().mul(le[2]));
    let t_max = dist
        .mul(V::splat(1.0 - gamma(3)))
        .sub(along)
        .max(V::splat(0.0));
    (u, t_max)
}

/// The second pass of [`spawn_shadow_rays`] over one chunk of hits: the rays of its non-zero rows,
/// in order, into its part of the shadow queue.
struct ShadowRayKernel<'a, 'h> {
    hits: &'a ShadedHits<'h>,
    lights: &'a [Light],
    hits_range: Range<usize>,
    radiance: &'a [Vec3],
    origin: &'a mut [Vec3],
    direction: &'a mut [Vec3],
    t_max: &'a mut [f32],
    out_radiance: &'a mut [Vec3],
    slot: &'a mut [SampleSlot],
}

impl WideKernel for ShadowRayKernel<'_, '_> {
    type Output = ();
    #[inline(always)]
    fn run<V: Wide>(self) {
        let per_hit = self.lights.len();
        let Range { start, end } = self.hits_range;
        let mut j = 0;
        if per_hit != 1 {
            // Several lights per hit: row by row in (hit, light) order.
            for h in start..end {
                let spawn = self.hits.spawn[h];
                for (li, light) in self.lights.iter().enumerate() {
                    let value = self.radiance[(h - start) * per_hit + li];
                    if value != Vec3::ZERO {
                        let (dir, t) = shadow_ray(spawn, light);
                        (self.origin[j], self.direction[j], self.t_max[j]) = (spawn, dir, t);
                        (self.out_radiance[j], self.slot[j]) = (value, self.hits.slot[h]);
                        j += 1;
                    }
                }
            }
            return;
        }
        let light = &self.lights[0];
        let n = V::LANES;
        let mut g = start;
        while g + n <= end {
            let rows = g..g + n;
            g += n;
            let spawn_rows = &self.hits.spawn[rows.clone()];
            let (dir, t) = shadow_rays_wide(V::load3(bytemuck::cast_slice(spawn_rows)), light);
            let values = &self.radiance[rows.start - start..rows.end - start];
            if values.iter().all(|&v| v != Vec3::ZERO) {
                // Every row kept: the group's rows go out whole.
                let out = j..j + n;
                self.origin[out.clone()].copy_from_slice(spawn_rows);
                V::store3(
                    dir,
                    bytemuck::cast_slice_mut(&mut self.direction[out.clone()]),
                );
                t.store(&mut self.t_max[out.clone()]);
                self.out_radiance[out.clone()].copy_from_slice(values);
                self.slot[out].copy_from_slice(&self.hits.slot[rows]);
                j += n;
                continue;
            }
            let mut dirs = [0.0f32; 3 * 32];
            let mut ts = [0.0f32; 32];
            V::store3(dir, &mut dirs);
            t.store(&mut ts);
            for (l, h) in rows.enumerate() {
                let value = self.radiance[h - start];
                if value != Vec3::ZERO {
                    self.origin[j] = self.hits.spawn[h];
                    self.direction[j] = Vec3::from_slice(&dirs[3 * l..]);
                    (self.t_max[j], self.out_radiance[j]) = (ts[l], value);
                    self.slot[j] = self.hits.slot[h];
                    j += 1;
                }
            }
        }
        // The last rows (fewer than a group): the scalar definition.
        for h in g..end {
            let value = self.radiance[h - start];
            if value != Vec3::ZERO {
                let spawn = self.hits.spawn[h];
                let (dir, t) = shadow_ray(spawn, light);
                (self.origin[j], self.direction[j], self.t_max[j]) = (spawn, dir, t);
                (self.out_radiance[j], self.slot[j]) = (value, self.hits.slot[h]);
                j += 1;
            }
        }
    }
}

/// Spawns the shadow rays of `pass` (`shadows` is overwritten): for every hit of the pass and
/// every light of the pass that can light it, in (hit, light) order — slot order. Two passes over
/// chunks of hits, each a [`Wide`] kernel ([`dispatch_wide`]: 16 lanes with AVX-512, else 8):
/// the first evaluates every (hit, light) row's radiance in lanes of hits and counts the
/// non-zero ones, the second writes each chunk's rays at its place in the queue. A chunk's last
/// rows (fewer than a group) and rows with vertex normals take the scalar definitions
/// (`shadow_radiance`, `shadow_ray`), which the lanes reproduce bit for bit.
pub(crate) fn spawn_shadow_rays(
    world: &World,
    settings: &ShadeSettings,
    pass: &ShadowPass,
    hits: ShadedHits<'_>,
    scratch: &mut ShadeScratch,
    shadows: Resize<ShadowRays<'_>>,
) {
    spawn_shadow_rays_at(
        Level::current(),
        world,
        settings,
        pass,
        hits,
        scratch,
        shadows,
    );
}

/// [`spawn_shadow_rays`] with its kernels compiled for `level`.
fn spawn_shadow_rays_at(
    level: Level,
    world: &World,
    settings: &ShadeSettings,
    pass: &ShadowPass,
    hits: ShadedHits<'_>,
    scratch: &mut ShadeScratch,
    shadows: Resize<ShadowRays<'_>>,
) {
    let lights = &world.lights()[pass.lights.clone()];
    let per_hit = lights.len().max(1);
    let rows = pass.rows();
    debug_assert!(rows <= MAX_SHADOW_ROWS);
    let r = pass.hits.clone();
    let chunk = (MIN_CHUNK / per_hit).max(1);
    scratch.radiance.resize(rows, Vec3::ZERO); // every row is overwritten
    let materials = world.materials();
    let meshes = world.triangles().is_some();
    let hits = &hits;
    scratch
        .radiance
        .par_chunks_mut(chunk * per_hit)
        .enumerate()
        .map(|(c, out)| {
            let first = r.start + c * chunk;
            let kernel = RadianceKernel {
                hits,
                materials,
                specular: settings.specular,
                meshes,
                lights,
                hits_range: first..first + out.len() / per_hit,
                out,
            };
            dispatch_wide(level, kernel)
        })
        .collect_into_vec(&mut scratch.counts);
    let counts = &scratch.counts;
    let radiance = &scratch.radiance;
    compact(shadows, counts, |c, out| {
        let first = r.start + c * chunk;
        let rows = &radiance[c * chunk * per_hit..((c + 1) * chunk * per_hit).min(rows)];
        let kernel = ShadowRayKernel {
            hits,
            lights,
            hits_range: first..first + rows.len() / per_hit,
            radiance: rows,
            origin: out.origin,
            direction: out.direction,
            t_max: out.t_max,
            out_radiance: out.radiance,
            slot: out.slot,
        };
        dispatch_wide(level, kernel);
    });
}

/// The hit/miss mask variant of shade: every hit emits its weight (white for primary rays).
pub(crate) fn shade_hit_mask(hits: MaskHits<'_>) {
    hits.emitted.copy_from_slice(hits.weight);
}

/// Adds each hit's `emitted` radiance to its sample (in slot order: deterministic).
pub(crate) fn add_emitted(hits: EmittedHits<'_>, samples: Samples<'_>) {
    crate::queue::add_sorted(samples.radiance, hits.slot, hits.emitted, |_| true);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::queue::{PrimId, SampleSlot};
    use crate::scene::builtin::spheres;

    /// A hit queue with one primary hit on each object of scene A.
    fn scene_a_hits(world: &World) -> HitQueue {
        let mut q = HitQueue::default();
        let dirs = [
            Vec3::new(0.0, 0.0, -1.0), // S2 (green), t = 5
            Vec3::new(0.0, -1.0, 0.0), // floor, t = 2
            Vec3::new(4.0, 0.0, -7.0), // S3 (blue)
        ];
        for (s, d) in dirs.into_iter().enumerate() {
            let d = d.normalize();
            let (t, prim) = world.intersect_closest(Vec3::ZERO, d, f32::INFINITY);
            q.push(crate::queue::HitItem {
                origin: Vec3::ZERO,
                direction: d,
                weight: Vec3::ONE,
                slot: SampleSlot(s as u32),
                t,
                prim,
                point: Vec3::ZERO,
                normal: Vec3::ZERO,
                material: 0,
                spawn: Vec3::ZERO,
                shading: Vec3::ZERO,
                emitted: Vec3::ZERO,
            });
        }
        assert_eq!(q.prim(), vec![PrimId(1), PrimId(3), PrimId(2)]);
        q
    }

    /// `shade_hits`, then the shadow rays of every hit and light in one pass (when shadows are on).
    fn shade_in_one_pass(
        world: &World,
        settings: &ShadeSettings,
        hits: &mut HitQueue,
        shadows: &mut ShadowQueue,
    ) {
        shade_hits(world, settings, ShadeHits::of(hits));
        if settings.shadows {
            let pass = ShadowPass {
                hits: 0..hits.len(),
                lights: 0..world.lights().len(),
            };
            spawn_shadow_rays(
                world,
                settings,
                &pass,
                ShadedHits::of(hits),
                &mut ShadeScratch::default(),
                ShadowRays::resizing(shadows),
            );
        }
    }

    #[test]
    fn without_shadows_everything_is_emitted_at_once() {
        let mut scene = spheres();
        scene.render.shadows = false;
        let world = World::load(&scene).unwrap();
        let settings = ShadeSettings::for_scene(&scene);
        let mut hits = scene_a_hits(&world);
        let mut shadows = ShadowQueue::default();
        shade_in_one_pass(&world, &settings, &mut hits, &mut shadows);
        let emitted = hits.emitted();
        assert!(shadows.is_empty());
        assert_eq!(emitted.len(), 3);
        // Green sphere facing the camera at (0, 0, -5), normal +z; light at (-4, 4, -3).
        let l = (Vec3::new(-4.0, 4.0, -3.0) - Vec3::new(0.0, 0.0, -5.0)).normalize();
        let h = (l + Vec3::Z).normalize();
        let expected = Vec3::new(0.0, 0.2, 0.0)
            + Vec3::new(0.0, 0.5, 0.0) * l.z
            + Vec3::splat(0.5) * arith::powi(h.z, 32);
        assert!(
            (emitted[0] - expected).abs().max_element() < 1e-6,
            "{} vs {expected}",
            emitted[0]
        );
        assert_eq!(hits.normal()[0], Vec3::Z);
        assert_eq!(hits.material(), vec![2, 0, 3]);
        // The floor reflects half: (1 − 0.5)·(0.2 + n·l).
        let p = Vec3::new(0.0, -2.0, 0.0);
        let l = (Vec3::new(-4.0, 4.0, -3.0) - p).normalize();
        assert!((emitted[1].x - 0.5 * (0.2 + l.y)).abs() < 1e-6);
    }

    #[test]
    fn with_shadows_direct_light_moves_to_shadow_rays() {
        let scene = spheres();
        let world = World::load(&scene).unwrap();
        let settings = ShadeSettings::for_scene(&scene);
        let mut hits = scene_a_hits(&world);
        let mut shadows = ShadowQueue::default();
        shade_in_one_pass(&world, &settings, &mut hits, &mut shadows);
        let emitted = hits.emitted();
        assert_eq!(emitted[0], Vec3::new(0.0, 0.2, 0.0), "ambient only");
        assert_eq!(emitted[1], Vec3::splat(0.1), "(1 − α)·ka");
        assert_eq!(shadows.len(), 3, "every hit here faces the light");
        assert_eq!(
            shadows.slot(),
            vec![SampleSlot(0), SampleSlot(1), SampleSlot(2)]
        );
        let s = shadows.get(1);
        let to_light = Vec3::new(-4.0, 4.0, -3.0) - s.origin;
        assert!((s.direction - to_light.normalize()).length() < 1e-6);
        assert!((s.t_max - to_light.length()).abs() < 1e-5);
        assert!(
            s.origin.y > -2.0,
            "origin moved off the floor toward the light"
        );
        assert!((s.radiance.x - 0.5 * to_light.normalize().y).abs() < 1e-6);
    }

    #[test]
    fn a_light_behind_the_surface_sends_no_shadow_ray() {
        let mut scene = spheres();
        scene.lights[0].kind = crate::scene::LightKind::Point {
            position: glam::DVec3::new(0.0, -10.0, 0.0), // below the floor
        };
        let world = World::load(&scene).unwrap();
        let settings = ShadeSettings::for_scene(&scene);
        let mut hits = scene_a_hits(&world);
        let mut shadows = ShadowQueue::default();
        shade_in_one_pass(&world, &settings, &mut hits, &mut shadows);
        assert!(
            shadows.slot().iter().all(|&s| s != SampleSlot(1)),
            "floor hit is lit from behind"
        );
    }

    #[test]
    fn degenerate_light_geometry_stays_finite() {
        let m = Material {
            name: "m".into(),
            ka: Vec3::ZERO,
            kd: Vec3::ONE,
            ks: Vec3::ONE,
            p: 0.0,
            alpha: 0.0,
        };
        let light = Light::point(Vec3::new(0.0, 0.0, 1.0), Vec3::ONE);
        // Grazing: n·l = 0.
        let (c, _) = direct_light(&light, &m, true, Vec3::ZERO, Vec3::X, Vec3::Z);
        assert!(c.is_finite());
        // Light exactly opposite the viewer: zero-length half vector; p = 0.
        let (c, _) = direct_light(&light, &m, true, Vec3::ZERO, Vec3::Z, Vec3::NEG_Z);
        assert!(c.is_finite());
        assert_eq!(c, Vec3::splat(2.0), "kd·(n·l = 1) + ks·0^0, n·h taken as 0");
        // Light at the hit point.
        let (c, _) = direct_light(&light, &m, true, light.position, Vec3::Z, Vec3::Z);
        assert_eq!(c, Vec3::ZERO);
        // With inverse-square falloff: at the point, nothing; so near that 1/r² overflows the
        // value, nothing rather than ∞ (which a mirror's 1 − α = 0 would make NaN).
        let near = Light {
            inverse_square: true,
            ..light
        };
        let (c, _) = direct_light(&near, &m, true, near.position, Vec3::Z, Vec3::Z);
        assert_eq!(c, Vec3::ZERO);
        let p = near.position - Vec3::new(0.0, 0.0, 1e-30);
        let (c, _) = direct_light(&near, &m, true, p, Vec3::Z, Vec3::Z);
        assert_eq!(c, Vec3::ZERO);
        let p = near.position - Vec3::new(0.0, 0.0, 0.5);
        let (c, _) = direct_light(&near, &m, false, p, Vec3::Z, Vec3::Z);
        assert_eq!(c, Vec3::splat(4.0), "kd·(n·l = 1)/0.5²");
    }

    #[test]
    fn shadow_rays_split_into_passes_are_the_unsplit_rays() {
        let mut scene = spheres();
        scene.lights = (0..5)
            .map(|i| {
                crate::scene::Light::point(
                    glam::DVec3::new(-4.0 + 2.0 * i as f64, 4.0, -3.0 + i as f64),
                    Vec3::splat(0.3),
                )
            })
            .collect();
        let world = World::load(&scene).unwrap();
        let settings = ShadeSettings::for_scene(&scene);
        let mut hits = scene_a_hits(&world);
        let mut whole = ShadowQueue::default();
        shade_in_one_pass(&world, &settings, &mut hits, &mut whole);
        assert!(whole.len() > 5);
        let mut joined = ShadowQueue::default();
        let mut rows = vec![];
        for pass in crate::schedule::shadow_passes(hits.len(), world.lights().len(), 4) {
            let mut part = ShadowQueue::default();
            spawn_shadow_rays(
                &world,
                &settings,
                &pass,
                ShadedHits::of(&hits),
                &mut ShadeScratch::default(),
                ShadowRays::resizing(&mut part),
            );
            rows.extend((0..part.len()).map(|i| part.get(i)));
        }
        rows.sort_by_key(|r| r.slot); // stable: each hit's lights stay in order
        for r in rows {
            joined.push(r);
        }
        assert_eq!(joined.slot(), whole.slot());
        assert_eq!(joined.origin(), whole.origin());
        assert_eq!(joined.direction(), whole.direction());
        assert_eq!(joined.t_max(), whole.t_max());
        assert_eq!(joined.radiance(), whole.radiance());
    }

    /// Light sets for the kernel test: scene A's light; three point lights; and each SPEC §14
    /// kind — inverse-square, directional, spots with and without penumbra, pointed so their
    /// cones' edges cross the hits — alone and all together.
    fn light_sets() -> Vec<Vec<crate::scene::Light>> {
        use crate::scene::{Falloff, Light, LightKind};
        use glam::DVec3;
        let first = spheres().lights[0].clone();
        let moved = |k: f64| {
            let mut l = first.clone();
            l.kind = LightKind::Point {
                position: first.position().unwrap() + DVec3::new(3.0 * k, -1.0, 2.0),
            };
            l
        };
        let inverse_square = Light {
            falloff: Falloff::InverseSquare,
            intensity: Vec3::splat(20.0),
            ..moved(0.5)
        };
        let directional = Light {
            kind: LightKind::Directional {
                direction: DVec3::new(0.3, -1.0, -0.4),
            },
            ..first.clone()
        };
        let spot = |penumbra: f64, falloff: Falloff| Light {
            kind: LightKind::Spot {
                position: DVec3::new(-1.0, 5.0, -4.0),
                direction: DVec3::new(-0.5, -1.0, -0.8),
                cone: 50.0,
                penumbra,
            },
            intensity: Vec3::new(1.0, 0.7, 0.4),
            falloff,
        };
        let kinds = vec![
            inverse_square,
            directional,
            spot(20.0, Falloff::None),
            spot(0.0, Falloff::InverseSquare),
            spot(50.0, Falloff::None),
        ];
        let mut sets = vec![
            vec![first.clone()],
            vec![first.clone(), moved(1.0), moved(2.0)],
        ];
        sets.extend(kinds.iter().map(|l| vec![l.clone()]));
        sets.push(kinds);
        sets
    }

    /// The shadow-ray kernels at every SIMD level against the scalar `shadow_radiance` and
    /// `shadow_ray`, row for row, for every [`light_sets`] set (and shadow passes split).
    #[test]
    fn shadow_ray_kernels_match_the_scalar_functions_bit_for_bit() {
        use crate::queue::RayQueue;
        use crate::sampling::Rng;
        use crate::stages::intersect::{
            ClosestOut, ClosestRays, CompactHits, CompactOut, CompactRays, compact_hits,
            intersect_closest,
        };
        for set in light_sets() {
            let lights = set.len();
            let mut scene = spheres();
            scene.lights = set;
            let world = World::load(&scene).unwrap();
            let settings = ShadeSettings::for_scene(&scene);
            let mut rng = Rng(3);
            let mut rays = RayQueue::default();
            let mut d = Vec3::NEG_Z;
            for s in 0..5000u32 {
                // Half the rays random, half in runs of 16 equal rays: groups of 8 hits with one
                // material, all lit (the kernels' whole-group paths), and mixed groups.
                if s < 2500 || s % 16 == 0 {
                    d = Vec3::new(rng.range(-0.8, 0.8), rng.range(-0.8, 0.3), -1.0);
                }
                rays.push(crate::queue::RayItem {
                    origin: Vec3::ZERO,
                    direction: d.normalize(),
                    t_max: f32::INFINITY,
                    weight: Vec3::splat(rng.range(0.1, 1.0)),
                    slot: SampleSlot(s),
                });
            }
            let mut closest = crate::queue::HitColumns::default();
            intersect_closest(
                &world,
                ClosestRays::of(&rays),
                ClosestOut::resizing(&mut closest),
            );
            let mut hits = HitQueue::default();
            compact_hits(
                CompactRays::of(&rays),
                CompactHits::of(&closest),
                &mut vec![],
                CompactOut::resizing(&mut hits),
            );
            shade_hits(&world, &settings, ShadeHits::of(&mut hits));
            let mut expected = vec![];
            let hits_q = &hits;
            let hits = hits_q.columns();
            for h in 0..hits_q.len() {
                let m = &world.materials()[hits.material[h] as usize];
                for light in world.lights() {
                    let v = shadow_radiance(
                        light,
                        m,
                        settings.specular,
                        (hits.direction[h], hits.weight[h]),
                        (hits.point[h], hits.normal[h], hits.shading[h]),
                    );
                    if v != Vec3::ZERO {
                        let (d, t) = shadow_ray(hits.spawn[h], light);
                        expected.push((hits.spawn[h], d, t, v, hits.slot[h]));
                    }
                }
            }
            assert!(!expected.is_empty(), "{lights} lights: no lit row");
            // The spots' cones cross the hits: some rows in a penumbra (0 < factor < 1).
            let partial = (0..hits_q.len())
                .filter(|&h| {
                    world.lights().iter().any(|l| {
                        let soft = matches!(l.emission, Emission::Spot { inner, outer, .. } if inner < outer);
                        let a = l.toward(hits.point[h]).map(|(u, d)| l.attenuation(u, d));
                        soft && !l.inverse_square && a.is_some_and(|a| a > 0.0 && a < 1.0)
                    })
                })
                .count();
            let soft_spots = world.lights().iter().any(|l| {
                matches!(l.emission, Emission::Spot { inner, outer, .. } if inner < outer)
                    && !l.inverse_square
            });
            assert_eq!(soft_spots, partial > 0, "{partial} hits in a penumbra");
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            for level in Level::supported() {
                for budget in [usize::MAX, 1000] {
                    let mut got = vec![];
                    let passes = crate::schedule::shadow_passes(hits_q.len(), lights, budget);
                    let mut all: Vec<_> = passes.collect();
                    // Passes run light block by light block; order rows as (hit, light).
                    all.sort_by_key(|p| p.lights.start);
                    for pass in all {
                        let mut q = ShadowQueue::default();
                        spawn_shadow_rays_at(
                            level,
                            &world,
                            &settings,
                            &pass,
                            ShadedHits::of(hits_q),
                            &mut ShadeScratch::default(),
                            ShadowRays::resizing(&mut q),
                        );
                        for i in 0..q.len() {
                            let r = q.get(i);
                            let row = (r.origin, r.direction, r.t_max, r.radiance);
                            got.push((row, r.slot, pass.lights.start));
                        }
                    }
                    got.sort_by_key(|&(_, slot, light)| (slot, light));
                    assert_eq!(got.len(), expected.len(), "{level:?}, {lights} lights");
                    for (g, e) in got.iter().zip(&expected) {
                        let ((o, d, t, v), slot, _) = *g;
                        assert_eq!(slot, e.4);
                        assert_eq!((bits(o), bits(d)), (bits(e.0), bits(e.1)), "{level:?}");
                        assert_eq!(
                            (t.to_bits(), bits(v)),
                            (e.2.to_bits(), bits(e.3)),
                            "{level:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn lane_specular_powers_are_the_scalar_ones_bit_for_bit() {
        /// [`specular_power`] of `x` and `p` at one width.
        struct Powers<'a>(&'a [f32], &'a [f32]);
        impl WideKernel for Powers<'_> {
            type Output = Vec<f32>;
            #[inline(always)]
            fn run<V: Wide>(self) -> Vec<f32> {
                let mut out = vec![0.0; V::LANES];
                specular_power(V::load(self.0), self.1).store(&mut out);
                out
            }
        }
        let x: [f32; MAX_LANES] = std::array::from_fn(|l| 0.05 + 0.06 * l as f32);
        for p in [
            [32.0; MAX_LANES],
            [0.0; MAX_LANES],
            [1.0; MAX_LANES],
            [65_536.0; MAX_LANES],
            [2.5; MAX_LANES],
            std::array::from_fn(|l| [8.0, 32.0, 1.5, 100.0][l % 4]),
        ] {
            for level in Level::supported() {
                let lanes = dispatch_wide(level, Powers(&x, &p));
                assert!(lanes.len() >= 8);
                for l in 0..lanes.len() {
                    let want = arith::pow(x[l], p[l]);
                    assert_eq!(lanes[l].to_bits(), want.to_bits(), "{}^{}", x[l], p[l]);
                }
            }
        }
    }
}
