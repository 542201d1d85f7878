//! Stage `reflect`: mirror rays for the next depth from every hit on a reflective material.
//!
//! Reads: [`ReflectHits`] (`HitQueue.{spawn, shading, material, direction, weight, slot}`),
//! materials.
//! Writes: [`NextRays`] — the next depth's `RayQueue` (compacted, slot order), weight `weight·α`.

use glam::Vec3;

use crate::queue::compact::{compact, count_chunks};
use crate::queue::{HitQueue, MIN_CHUNK, RayItem, RayQueue, Resize, SampleSlot};
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

crate::kernels! {
    /// The stage's kernels, in the order the schedule calls them.
    pub(crate) const KERNELS = [spawn_reflection_rays(ReflectHits, NextRays)];
}

/// The reflection of one hit about its shading normal `n`, `r = d − 2(d·n)n`, from the offset hit
/// point `spawn` (the geometric surface's), weight `weight·α`: the per-row body of
/// [`spawn_reflection_rays`].
#[inline(always)]
pub(crate) fn reflection_ray(
    (spawn, d, n): (Vec3, Vec3, Vec3),
    (weight, alpha, slot): (Vec3, f32, SampleSlot),
) -> RayItem {
    RayItem {
        origin: spawn,
        direction: d - 2.0 * d.dot(n) * n,
        t_max: f32::INFINITY,
        weight: weight * alpha,
        slot,
    }
}

/// Spawns the next depth's rays into `next` (overwritten), in slot order: a two-pass compaction
/// over chunks of hits (count each chunk's reflective hits, then each chunk writes its rays at its
/// place). `counts` is scratch.
pub(crate) fn spawn_reflection_rays(
    world: &World,
    hits: ReflectHits<'_>,
    counts: &mut Vec<usize>,
    next: Resize<NextRays<'_>>,
) {
    // Each material's α, 0 where it does not reflect: one look-up per row, no `Material` read.
    let alpha: Vec<f32> = world
        .materials()
        .iter()
        .map(|m| if m.reflects() { m.alpha } else { 0.0 })
        .collect();
    let alpha = alpha.as_slice();
    let material = hits.material;
    let n = material.len();
    count_chunks(
        n,
        MIN_CHUNK,
        |r| {
            material[r]
                .iter()
                .filter(|&&m| alpha[m as usize] > 0.0)
                .count()
        },
        counts,
    );
    compact(next, counts, |c, out| {
        let rows = c * MIN_CHUNK..(c * MIN_CHUNK + MIN_CHUNK).min(n);
        let (spawn, shading) = (&hits.spawn[rows.clone()], &hits.shading[rows.clone()]);
        let (direction, weight) = (&hits.direction[rows.clone()], &hits.weight[rows.clone()]);
        let (slot, material) = (&hits.slot[rows.clone()], &material[rows]);
        let k = out.slot.len();
        let (o_origin, o_direction) = (&mut out.origin[..k], &mut out.direction[..k]);
        let (o_t_max, o_weight) = (&mut out.t_max[..k], &mut out.weight[..k]);
        let mut j = 0;
        for i in 0..material.len() {
            let a = alpha[material[i] as usize];
            if a > 0.0 {
                let r = reflection_ray(
                    (spawn[i], direction[i], shading[i]),
                    (weight[i], a, slot[i]),
                );
                (o_origin[j], o_direction[j], o_t_max[j]) = (r.origin, r.direction, r.t_max);
                (o_weight[j], out.slot[j]) = (r.weight, r.slot);
                j += 1;
            }
        }
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
            hits.push(crate::queue::HitItem {
                origin: Vec3::ZERO,
                direction: d,
                weight: Vec3::splat(0.8),
                slot: SampleSlot(10 + s as u32),
                t: 1.0,
                prim: PrimId(0),
                point: p,
                normal: n,
                material: m,
                spawn: p + 1e-5 * n,
                shading: n,
                emitted: Vec3::ZERO,
            });
        }
        let mut next = RayQueue::default();
        spawn_reflection_rays(
            &world,
            ReflectHits::of(&hits),
            &mut vec![],
            NextRays::resizing(&mut next),
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
