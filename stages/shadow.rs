//! Stage `shadow`: any-hit occlusion of every shadow ray, with early exit, then the light of the
//! unoccluded ones added to their samples.
//!
//! Reads: [`ShadowTrace`]' read columns (`ShadowQueue.{origin, direction, t_max}`); then
//! [`LitRays`] (`ShadowQueue.{slot, radiance, occluded}`).
//! Writes: `ShadowQueue.occluded` (one flag per row, in place: shade sized the queue); the samples of the unoccluded rows.

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::kdtree::KdAccel;
use crate::queue::{MIN_CHUNK, SampleSlot, Samples, ShadowQueue};
use crate::world::World;

crate::column_set! {
    /// What `intersect_occluded` reads and writes.
    pub struct ShadowTrace<'a>: ShadowQueue {
        read origin: Vec3,
        read direction: Vec3,
        read t_max: f32,
        write occluded: bool,
    }
}

crate::column_set! {
    /// What `add_unoccluded` reads.
    pub struct LitRays<'a>: read ShadowQueue { slot: SampleSlot, radiance: Vec3, occluded: bool }
}

crate::kernels! {
    /// The stage's kernels, in the order the schedule calls them.
    pub(crate) const KERNELS = [
        intersect_occluded(ShadowTrace),
        add_unoccluded(LitRays, Samples),
    ];
}

/// Whether each shadow ray is blocked by anything strictly between its origin and its light.
/// Chunks of rays go through [`World::intersect_occluded_batch`] (a mesh's shadow rays are traced
/// from their light as bundles: chunks of [`KdAccel::OCCLUDED_BATCH`] rays give them coherent
/// neighbours to bundle with).
pub fn intersect_occluded(world: &World, rays: ShadowTrace<'_>) {
    let chunk = KdAccel::OCCLUDED_BATCH.max(MIN_CHUNK);
    rays.occluded
        .par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(c, out)| {
            let r = c * chunk..c * chunk + out.len();
            world.intersect_occluded_batch(
                &rays.origin[r.clone()],
                &rays.direction[r.clone()],
                &rays.t_max[r],
                out,
            );
        });
}

/// Adds the radiance of every unoccluded shadow ray to its sample; returns how many were lit.
pub(crate) fn add_unoccluded(rays: LitRays<'_>, samples: Samples<'_>) -> usize {
    let occluded = rays.occluded;
    crate::queue::add_sorted(samples.radiance, rays.slot, rays.radiance, |i| !occluded[i]);
    occluded.iter().filter(|&&o| !o).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::queue::ShadowItem;
    use crate::scene::builtin::spheres;

    #[test]
    fn blockers_count_only_between_origin_and_light() {
        let world = World::load(&spheres()).unwrap();
        let mut q = ShadowQueue::default();
        let mut push = |o: Vec3, target: Vec3| {
            let to = target - o;
            q.push(ShadowItem {
                origin: o,
                direction: to.normalize(),
                t_max: to.length(),
                radiance: Vec3::ONE,
                slot: SampleSlot(q.len() as u32),
                occluded: false,
            });
        };
        // Under the red sphere toward a light straight above it: blocked.
        push(Vec3::new(-4.0, -1.99, -7.0), Vec3::new(-4.0, 10.0, -7.0));
        // The same, with the light between the floor and the sphere: free.
        push(Vec3::new(-4.0, -1.99, -7.0), Vec3::new(-4.0, -1.5, -7.0));
        // Open sky.
        push(Vec3::new(10.0, -1.99, 0.0), Vec3::new(10.0, 10.0, 0.0));
        intersect_occluded(&world, ShadowTrace::of(&mut q));
        assert_eq!(q.occluded(), vec![true, false, false]);
    }
}
