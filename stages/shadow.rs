//! Stage `shadow`: any-hit occlusion of every shadow ray, with early exit.
//!
//! Reads: `ShadowQueue.{origin, direction, t_max}`.
//! Writes: `occluded` (one flag per row). The schedule then adds `ShadowQueue.radiance` of the
//! unoccluded rows to their samples.

use rayon::prelude::*;

use crate::queue::{MIN_CHUNK, ShadowQueue};
use crate::world::World;

/// Whether each shadow ray is blocked by anything strictly between its origin and its light.
/// Chunks of rays go through [`World::intersect_occluded_batch`] (packets of consecutive rays).
pub fn intersect_occluded(world: &World, shadows: &ShadowQueue, occluded: &mut Vec<bool>) {
    let n = shadows.len();
    occluded.clear();
    occluded.resize(n, false);
    occluded
        .par_chunks_mut(MIN_CHUNK)
        .enumerate()
        .for_each(|(c, out)| {
            let r = c * MIN_CHUNK..c * MIN_CHUNK + out.len();
            world.intersect_occluded_batch(
                &shadows.origin[r.clone()],
                &shadows.direction[r.clone()],
                &shadows.t_max[r],
                out,
            );
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::queue::{SampleSlot, ShadowItem};
    use crate::scene::builtin::spheres;
    use glam::Vec3;

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
            });
        };
        // Under the red sphere toward a light straight above it: blocked.
        push(Vec3::new(-4.0, -1.99, -7.0), Vec3::new(-4.0, 10.0, -7.0));
        // The same, with the light between the floor and the sphere: free.
        push(Vec3::new(-4.0, -1.99, -7.0), Vec3::new(-4.0, -1.5, -7.0));
        // Open sky.
        push(Vec3::new(10.0, -1.99, 0.0), Vec3::new(10.0, 10.0, 0.0));
        let mut occluded = vec![];
        intersect_occluded(&world, &q, &mut occluded);
        assert_eq!(occluded, vec![true, false, false]);
    }
}
