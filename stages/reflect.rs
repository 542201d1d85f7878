//! Stage `reflect`: mirror rays for the next depth from every hit on a reflective material.
//!
//! Reads: [`ReflectHits`] (`HitQueue.{spawn, shading, material, direction, weight, slot}`),
//! materials.
//! Writes: [`NextRays`] — the next depth's `RayQueue` (compacted, slot order), weight `weight·α`.

use glam::Vec3;
use rayon::prelude::*;

use crate::queue::compact::kept_rows;
use crate::queue::{HitQueue, MIN_CHUNK, RayItem, RayQueue, RowIndex, SampleSlot};
use crate::world::World;

crate::column_set! {
    /// What `spawn_reflection_rays` reads.
    pub struct ReflectHits<'a>: read HitQueue {
        spawn: Vec3,
        shading: Vec3,
        material: u32,
        direction: Vec3,
        weight: Vec3,
        slot: SampleSlot,
    }
}

crate::column_set! {
    /// What `spawn_reflection_rays` writes: the whole next-depth ray queue.
    pub struct NextRays<'a>: RayQueue {
        write origin: Vec3,
        write direction: Vec3,
        write t_max: f32,
        write weight: Vec3,
        write slot: SampleSlot,
    }
}

/// The reflection of hit row `i` about its shading normal, `r = d − 2(d·n)n`, from the offset hit
/// point (the geometric surface's), weight `weight·α`.
#[inline]
pub fn reflection_ray(world: &World, hits: &ReflectHits<'_>, i: usize) -> RayItem {
    let (d, n) = (hits.direction[i], hits.shading[i]);
    let alpha = world.materials()[hits.material[i] as usize].alpha;
    RayItem {
        origin: hits.spawn[i],
        direction: d - 2.0 * d.dot(n) * n,
        t_max: f32::INFINITY,
        weight: hits.weight[i] * alpha,
        slot: hits.slot[i],
    }
}

/// Spawns the next depth's rays into `next` (overwritten); `rows` is scratch.
pub fn spawn_reflection_rays(
    world: &World,
    hits: ReflectHits<'_>,
    rows: &mut Vec<RowIndex>,
    next: NextRays<'_>,
) {
    let materials = world.materials();
    let reflects = |i: usize| materials[hits.material[i] as usize].reflects();
    kept_rows(hits.slot.len(), reflects, rows);
    let n = rows.len();
    for col in [&mut *next.origin, &mut *next.direction, &mut *next.weight] {
        col.clear();
        col.resize(n, Vec3::ZERO);
    }
    next.t_max.clear();
    next.t_max.resize(n, f32::INFINITY);
    next.slot.clear();
    next.slot.resize(n, SampleSlot::default());
    (
        &mut *next.origin,
        &mut *next.direction,
        &mut *next.weight,
        &mut *next.slot,
        rows.as_slice(),
    )
        .into_par_iter()
        .with_min_len(MIN_CHUNK)
        .for_each(|(o, d, w, s, &i)| {
            let r = reflection_ray(world, &hits, i.get());
            (*o, *d, *w, *s) = (r.origin, r.direction, r.weight, r.slot);
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::queue::PrimId;
    use crate::scene::builtin::spheres;

    #[test]
    fn only_reflective_hits_spawn_rays_with_alpha_weight() {
        let world = World::load(&spheres()).unwrap();
        let mut hits = HitQueue::default();
        // Row 0: red sphere (α = 0); row 1: floor (α = 0.5) hit at 45°.
        for (s, (p, n, m, d)) in [
            (Vec3::new(-4.0, 0.0, -6.0), Vec3::Z, 1u32, Vec3::NEG_Z),
            (
                Vec3::new(0.0, -2.0, -2.0),
                Vec3::Y,
                0,
                Vec3::new(0.0, -1.0, -1.0).normalize(),
            ),
        ]
        .into_iter()
        .enumerate()
        {
            hits.origin.push(Vec3::ZERO);
            hits.direction.push(d);
            hits.weight.push(Vec3::splat(0.8));
            hits.slot.push(SampleSlot(10 + s as u32));
            hits.t.push(1.0);
            hits.prim.push(PrimId(0));
            hits.point.push(p);
            hits.spawn.push(p + 1e-5 * n);
            hits.normal.push(n);
            hits.shading.push(n);
            hits.material.push(m);
        }
        let mut next = RayQueue::default();
        spawn_reflection_rays(
            &world,
            ReflectHits::of(&hits),
            &mut vec![],
            NextRays::of(&mut next),
        );
        assert_eq!(next.len(), 1);
        let r = next.get(0);
        assert_eq!(r.slot, SampleSlot(11));
        assert_eq!(r.weight, Vec3::splat(0.4));
        assert!((r.direction - Vec3::new(0.0, 1.0, -1.0).normalize()).length() < 1e-6);
        assert_eq!(
            r.origin,
            Vec3::new(0.0, -2.0 + 1e-5, -2.0),
            "rays leave from the spawn column"
        );
    }
}
