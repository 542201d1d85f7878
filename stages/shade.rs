//! Stage `shade`: local Whitted shading at every hit (SPEC §2) and the shadow rays it needs.
//!
//! Reads: [`ShadeHits`]' read columns (`HitQueue.{origin, direction, t, prim, weight, slot}`),
//! materials, lights.
//! Writes: [`ShadeHits`]' write columns — `HitQueue.{point, normal, material, spawn}` and
//! `HitQueue.emitted` (the radiance added to the sample now, `(1 − α)·weight·(La [+ Ld + Ls when
//! shadows are off])`) — and [`ShadowRays`]: one `ShadowQueue` row per hit and light that can
//! light it, carrying `(1 − α)·weight·(Ld + Ls)`. [`add_emitted`] then adds `emitted` to the
//! samples.

use glam::Vec3;
use rayon::prelude::*;

use crate::film::SampleBuffer;
use crate::frame::Light;
use crate::geometry::offset::shadow_t_max;
use crate::queue::compact::{gather, kept_rows};
use crate::queue::{HitQueue, MIN_CHUNK, PrimId, RowIndex, SampleSlot, ShadowQueue};
use crate::scene::{Material, Scene};
use crate::world::{Surface, World};

crate::column_set! {
    /// What `shade_hits` reads and writes in the hit queue.
    pub struct ShadeHits<'a>: HitQueue {
        read origin: Vec3,
        read direction: Vec3,
        read t: f32,
        read prim: PrimId,
        read weight: Vec3,
        read slot: SampleSlot,
        write point: Vec3,
        write normal: Vec3,
        write material: u32,
        write spawn: Vec3,
        write emitted: Vec3,
    }
}

crate::column_set! {
    /// What `shade_hits` writes: the shadow rays, compacted in slot order.
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

crate::column_set! {
    /// What `add_emitted` and the shadow stage's `add_unoccluded` write: the wave's samples.
    pub struct Samples<'a>: SampleBuffer { write radiance: Vec3 }
}

/// What the shade kernel needs besides the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeSettings {
    /// Ambient intensity `Ia`.
    pub ambient: Vec3,
    /// Defer the direct terms to shadow rays.
    pub shadows: bool,
    /// Evaluate the specular term at all (false when no material has `ks > 0`).
    pub specular: bool,
}

impl ShadeSettings {
    /// The settings a scene implies.
    pub fn for_scene(scene: &Scene) -> ShadeSettings {
        ShadeSettings {
            ambient: scene.render.ambient,
            shadows: scene.needs_shadows(),
            specular: scene.needs_specular(),
        }
    }
}

/// `(Ld + Ls)·I` from one light at `p` with facing normal `n` and unit view vector `v`, and
/// `n·l`. Finite for every finite input: a zero half vector counts as `n·h = 0`, and a light at
/// `p` itself gives nothing.
#[inline]
pub fn direct_light(
    light: &Light,
    m: &Material,
    specular: bool,
    p: Vec3,
    n: Vec3,
    v: Vec3,
) -> (Vec3, f32) {
    let to_light = light.position - p;
    let dist = to_light.length();
    if !(dist > 0.0 && dist.is_finite()) {
        return (Vec3::ZERO, 0.0);
    }
    let l = to_light / dist;
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
        c += m.ks * n_dot_h.powf(m.p);
    }
    (c * light.intensity, n_dot_l)
}

/// Shades one hit: returns the radiance emitted now and, through `shadow`, each light's deferred
/// radiance and shadow ray (`None` where the light cannot contribute).
#[inline]
pub fn shade_hit(
    world: &World,
    settings: &ShadeSettings,
    (direction, weight): (Vec3, Vec3),
    surface: &Surface,
    mut shadow: impl FnMut(usize, Option<(Vec3, Vec3, f32, Vec3)>),
) -> Vec3 {
    let Surface {
        point,
        normal,
        material,
        spawn,
    } = *surface;
    let m = &world.materials()[material as usize];
    let w = weight * (1.0 - m.alpha);
    let v = -direction;
    let mut emitted = m.ka * settings.ambient;
    let origin = settings.shadows.then_some(spawn);
    for (j, light) in world.lights().iter().enumerate() {
        let (c, n_dot_l) = direct_light(light, m, settings.specular, point, normal, v);
        match origin {
            None => emitted += c,
            // A light behind the surface is blocked by the surface itself.
            Some(o) if n_dot_l > 0.0 && c != Vec3::ZERO => {
                let to = light.position - o;
                let dist = to.length();
                let dir = to / dist;
                let t_max = shadow_t_max(light.position, dir, dist);
                shadow(j, Some((o, dir, t_max, w * c)));
            }
            Some(_) => shadow(j, None),
        }
    }
    w * emitted
}

/// Scratch for the shade kernel's variable output, reused across waves.
#[derive(Debug, Default)]
pub struct ShadeScratch {
    candidates: ShadowQueue,
    rows: Vec<RowIndex>,
}

/// Shades every hit: fills its surface columns and `emitted` (one row per hit), and `shadows`
/// (compacted, slot order).
pub fn shade_hits(
    world: &World,
    settings: &ShadeSettings,
    hits: ShadeHits<'_>,
    scratch: &mut ShadeScratch,
    shadows: ShadowRays<'_>,
) {
    let n = hits.prim.len();
    hits.point.resize(n, Vec3::ZERO);
    hits.normal.resize(n, Vec3::ZERO);
    hits.material.resize(n, 0);
    hits.spawn.resize(n, Vec3::ZERO);
    (
        (
            &mut *hits.point,
            &mut *hits.normal,
            &mut *hits.material,
            &mut *hits.spawn,
        ),
        (hits.prim, hits.origin, hits.direction, hits.t),
    )
        .into_par_iter()
        .with_min_len(MIN_CHUNK)
        .for_each(|((p, nrm, m, sp), (&prim, &o, &d, &t))| {
            let s = world.surface(prim, o, d, t);
            (*p, *nrm, *m, *sp) = (s.point, s.normal, s.material, s.spawn);
        });

    let lights = world.lights().len();
    let shadowed = settings.shadows && lights > 0;
    let c = &mut scratch.candidates;
    let rows = if shadowed { n * lights } else { 0 };
    for col in [&mut c.origin, &mut c.direction, &mut c.radiance] {
        col.resize(rows, Vec3::ZERO);
    }
    c.t_max.resize(rows, 0.0);
    c.slot.clear();
    c.slot.extend(
        hits.slot
            .iter()
            .flat_map(|&s| std::iter::repeat_n(s, if shadowed { lights } else { 0 })),
    );

    let ray = (hits.direction, hits.weight);
    let surface = (&*hits.point, &*hits.normal, &*hits.material, &*hits.spawn);
    let at = |(&point, &normal, &material, &spawn): (&Vec3, &Vec3, &u32, &Vec3)| Surface {
        point,
        normal,
        material,
        spawn,
    };
    if shadowed {
        (
            (ray, surface),
            c.origin.par_chunks_mut(lights),
            c.direction.par_chunks_mut(lights),
            c.t_max.par_chunks_mut(lights),
            c.radiance.par_chunks_mut(lights),
        )
            .into_par_iter()
            .with_min_len(MIN_CHUNK / lights.max(1))
            .map(|(((&d, &w), s), o, dir, tm, rad)| {
                shade_hit(world, settings, (d, w), &at(s), |j, s| match s {
                    Some((so, sd, st, sr)) => (o[j], dir[j], tm[j], rad[j]) = (so, sd, st, sr),
                    None => rad[j] = Vec3::ZERO,
                })
            })
            .collect_into_vec(hits.emitted);
        kept_rows(rows, |i| c.radiance[i] != Vec3::ZERO, &mut scratch.rows);
        gather(&c.origin, &scratch.rows, shadows.origin);
        gather(&c.direction, &scratch.rows, shadows.direction);
        gather(&c.t_max, &scratch.rows, shadows.t_max);
        gather(&c.radiance, &scratch.rows, shadows.radiance);
        gather(&c.slot, &scratch.rows, shadows.slot);
    } else {
        (ray, surface)
            .into_par_iter()
            .with_min_len(MIN_CHUNK)
            .map(|((&d, &w), s)| shade_hit(world, settings, (d, w), &at(s), |_, _| {}))
            .collect_into_vec(hits.emitted);
        for col in [shadows.origin, shadows.direction, shadows.radiance] {
            col.clear();
        }
        shadows.t_max.clear();
        shadows.slot.clear();
    }
}

/// The hit/miss mask variant of shade: every hit emits its weight (white for primary rays).
pub fn shade_hit_mask(hits: MaskHits<'_>) {
    hits.emitted.clear();
    hits.emitted.extend_from_slice(hits.weight);
}

/// Adds each hit's `emitted` radiance to its sample (in slot order: deterministic).
pub fn add_emitted(hits: EmittedHits<'_>, samples: Samples<'_>) {
    crate::film::add_sorted(samples.radiance, hits.slot, hits.emitted, |_| true);
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
            q.origin.push(Vec3::ZERO);
            q.direction.push(d);
            q.weight.push(Vec3::ONE);
            q.slot.push(SampleSlot(s as u32));
            q.t.push(t);
            q.prim.push(prim);
        }
        assert_eq!(q.prim, vec![PrimId(1), PrimId(3), PrimId(2)]);
        q
    }

    #[test]
    fn without_shadows_everything_is_emitted_at_once() {
        let mut scene = spheres();
        scene.render.shadows = false;
        let world = World::load(&scene).unwrap();
        let settings = ShadeSettings::for_scene(&scene);
        let mut hits = scene_a_hits(&world);
        let mut shadows = ShadowQueue::default();
        shade_hits(
            &world,
            &settings,
            ShadeHits::of(&mut hits),
            &mut ShadeScratch::default(),
            ShadowRays::of(&mut shadows),
        );
        let emitted = &hits.emitted;
        assert!(shadows.is_empty());
        assert_eq!(emitted.len(), 3);
        // Green sphere facing the camera at (0, 0, -5), normal +z; light at (-4, 4, -3).
        let l = (Vec3::new(-4.0, 4.0, -3.0) - Vec3::new(0.0, 0.0, -5.0)).normalize();
        let h = (l + Vec3::Z).normalize();
        let expected = Vec3::new(0.0, 0.2, 0.0)
            + Vec3::new(0.0, 0.5, 0.0) * l.z
            + Vec3::splat(0.5) * h.z.powf(32.0);
        assert!(
            (emitted[0] - expected).abs().max_element() < 1e-6,
            "{} vs {expected}",
            emitted[0]
        );
        assert_eq!(hits.normal[0], Vec3::Z);
        assert_eq!(hits.material, vec![2, 0, 3]);
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
        shade_hits(
            &world,
            &settings,
            ShadeHits::of(&mut hits),
            &mut ShadeScratch::default(),
            ShadowRays::of(&mut shadows),
        );
        let emitted = &hits.emitted;
        assert_eq!(emitted[0], Vec3::new(0.0, 0.2, 0.0), "ambient only");
        assert_eq!(emitted[1], Vec3::splat(0.1), "(1 − α)·ka");
        assert_eq!(shadows.len(), 3, "every hit here faces the light");
        assert_eq!(
            shadows.slot,
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
        scene.lights[0].position = glam::DVec3::new(0.0, -10.0, 0.0); // below the floor
        let world = World::load(&scene).unwrap();
        let settings = ShadeSettings::for_scene(&scene);
        let mut hits = scene_a_hits(&world);
        let mut shadows = ShadowQueue::default();
        shade_hits(
            &world,
            &settings,
            ShadeHits::of(&mut hits),
            &mut ShadeScratch::default(),
            ShadowRays::of(&mut shadows),
        );
        assert!(
            shadows.slot.iter().all(|&s| s != SampleSlot(1)),
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
        let light = Light {
            position: Vec3::new(0.0, 0.0, 1.0),
            intensity: Vec3::ONE,
        };
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
    }
}
