//! Stage `intersect`: the closest hit of every ray, then the hits compacted in order.
//!
//! Reads: [`ClosestRays`] (`RayQueue.{origin, direction, t_max}`), then [`CompactRays`] and
//! [`CompactHits`] to carry the rays that hit along.
//! Writes: [`ClosestOut`] (`HitColumns.{t, prim}`, row for row), then [`CompactOut`]
//! (`HitQueue.{origin, direction, weight, slot, t, prim}`) for the rows that hit. Misses leave the
//! pipeline (the sky is black).

use glam::Vec3;
use rayon::prelude::*;

use crate::queue::compact::{compact, count_chunks};
use crate::queue::{
    HitColumns, HitQueue, MIN_CHUNK, PrimId, RayQueue, Resize, SampleSlot, TRACE_CHUNK,
};
use crate::world::World;

crate::column_set! {
    /// What `intersect_closest` reads.
    pub struct ClosestRays<'a>: read RayQueue { origin: Vec3, direction: Vec3, t_max: f32 }
}

crate::column_set! {
    /// What `intersect_closest` writes: one answer per ray.
    pub struct ClosestOut<'a>: HitColumns { write t: f32, write prim: PrimId }
}

crate::column_set! {
    /// The ray columns `compact_hits` carries into the hit queue.
    pub struct CompactRays<'a>: read RayQueue {
        origin: Vec3,
        direction: Vec3,
        weight: Vec3,
        slot: SampleSlot,
    }
}

crate::column_set! {
    /// The answers `compact_hits` filters on and carries along.
    pub struct CompactHits<'a>: read HitColumns { t: f32, prim: PrimId }
}

crate::column_set! {
    /// What `compact_hits` writes: the rays that hit, in slot order.
    pub struct CompactOut<'a>: HitQueue {
        write origin: Vec3,
        write direction: Vec3,
        write weight: Vec3,
        write slot: SampleSlot,
        write t: f32,
        write prim: PrimId,
    }
}

crate::kernels! {
    /// The stage's kernels, in the order the schedule calls them.
    pub(crate) const KERNELS = [
        intersect_closest(ClosestRays, ClosestOut),
        compact_hits(CompactRays, CompactHits, CompactOut),
    ];
}

/// Closest hit of every ray (one row per ray). Chunks of up to [`TRACE_CHUNK`] rays go through
/// [`World::intersect_closest_batch`] (camera rays as frusta of screen tiles, others as packets
/// of consecutive, coherent rays); on several threads a mesh-only world's small queue goes in
/// one call, which spreads its frusta over the threads.
pub fn intersect_closest(world: &World, rays: ClosestRays<'_>, out: Resize<ClosestOut<'_>>) {
    let n = rays.origin.len();
    // Every row is overwritten below.
    let out = out.resize(n);
    // On one thread, whole chunks (the frusta find more coherent neighbours in them). On
    // several, a small queue (fewer than 4 chunks per thread) of a mesh-only world with the
    // watertight test goes in one call: the kD tree regroups it in chunks of the same size and
    // spreads whole frusta over the threads (measured on Sibenik's 3,951 mirror reflections, 2
    // threads: ~1.2× four 1,024-ray chunks; on 65,536 camera rays it measured no faster than 16
    // whole chunks). Other worlds: small queues in smaller chunks, so every thread gets some
    // (answers do not depend on any of it).
    let threads = rayon::current_num_threads();
    let mesh_only = world.spheres().is_empty()
        && world.planes().is_empty()
        && world.robustness().triangle == crate::scene::TriangleTest::Watertight;
    let chunk = if threads == 1 {
        TRACE_CHUNK
    } else if mesh_only && n < 4 * threads * TRACE_CHUNK {
        n.max(1)
    } else {
        TRACE_CHUNK.min((n / (4 * threads)).max(MIN_CHUNK))
    };
    out.t
        .par_chunks_mut(chunk)
        .zip(out.prim.par_chunks_mut(chunk))
        .enumerate()
        .for_each(|(c, (t, prim))| {
            let r = c * chunk..c * chunk + t.len();
            world.intersect_closest_batch(
                &rays.origin[r.clone()],
                &rays.direction[r.clone()],
                &rays.t_max[r],
                t,
                prim,
            );
        });
}

/// Copies the rays that hit, with their hits, into `out` in slot order: a two-pass compaction
/// over chunks of rows (count each chunk's hits, then each chunk writes its rows at its place).
/// `counts` is scratch.
pub(crate) fn compact_hits(
    rays: CompactRays<'_>,
    hits: CompactHits<'_>,
    counts: &mut Vec<usize>,
    out: Resize<CompactOut<'_>>,
) {
    let prim = hits.prim;
    count_chunks(
        prim.len(),
        MIN_CHUNK,
        |r| prim[r].iter().filter(|p| p.is_hit()).count(),
        counts,
    );
    compact(out, counts, |c, out| {
        let first = c * MIN_CHUNK;
        let rows = first..(first + MIN_CHUNK).min(prim.len());
        // The chunk's rows, cut once (no bounds check per row below).
        let (origin, direction) = (&rays.origin[rows.clone()], &rays.direction[rows.clone()]);
        let (weight, slot) = (&rays.weight[rows.clone()], &rays.slot[rows.clone()]);
        let (t, prim) = (&hits.t[rows.clone()], &prim[rows]);
        let n = out.prim.len();
        let (o_origin, o_direction) = (&mut out.origin[..n], &mut out.direction[..n]);
        let (o_weight, o_slot) = (&mut out.weight[..n], &mut out.slot[..n]);
        let o_t = &mut out.t[..n];
        let mut j = 0;
        for i in 0..prim.len() {
            if prim[i].is_hit() {
                (o_origin[j], o_direction[j]) = (origin[i], direction[i]);
                (o_weight[j], o_slot[j]) = (weight[i], slot[i]);
                (o_t[j], out.prim[j]) = (t[i], prim[i]);
                j += 1;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::queue::RayItem;
    use crate::scene::builtin::spheres;

    #[test]
    fn misses_leave_the_queue_and_hits_keep_their_order() {
        let scene = spheres();
        let world = World::load(&scene).unwrap();
        let mut rays = RayQueue::default();
        let towards = |s: u32, d: Vec3| RayItem {
            origin: Vec3::ZERO,
            direction: d.normalize(),
            t_max: f32::INFINITY,
            weight: Vec3::splat(s as f32),
            slot: SampleSlot(s),
        };
        rays.push(towards(0, Vec3::new(0.0, 0.0, -1.0))); // green sphere S2, t = 5
        rays.push(towards(1, Vec3::new(0.0, 1.0, 0.0))); // sky
        rays.push(towards(2, Vec3::new(-4.0, 0.0, -7.0))); // red sphere S1
        rays.push(towards(3, Vec3::new(0.0, -1.0, 0.0))); // floor, t = 2
        let mut hits = HitColumns::default();
        intersect_closest(
            &world,
            ClosestRays::of(&rays),
            ClosestOut::resizing(&mut hits),
        );
        assert_eq!(
            hits.prim(),
            vec![PrimId(1), PrimId::NONE, PrimId(0), PrimId(3)]
        );
        assert_eq!(hits.t()[0], 5.0);
        assert_eq!(hits.t()[1], f32::INFINITY);
        assert_eq!(hits.t()[3], 2.0);

        let mut out = HitQueue::default();
        compact_hits(
            CompactRays::of(&rays),
            CompactHits::of(&hits),
            &mut vec![],
            CompactOut::resizing(&mut out),
        );
        assert_eq!(
            out.slot(),
            vec![SampleSlot(0), SampleSlot(2), SampleSlot(3)]
        );
        assert_eq!(out.prim(), vec![PrimId(1), PrimId(0), PrimId(3)]);
        assert_eq!(out.weight()[2], Vec3::splat(3.0));
        assert_eq!(out.t()[2], 2.0);
    }

    #[test]
    fn poisoned_rays_miss_without_disturbing_others() {
        let world = World::load(&spheres()).unwrap();
        let mut rays = RayQueue::default();
        for (s, (o, d)) in [
            (Vec3::NAN, Vec3::NEG_Z),
            (Vec3::ZERO, Vec3::NEG_Z),
            (Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, -1.0)),
            (Vec3::splat(f32::INFINITY), Vec3::NEG_Z),
        ]
        .into_iter()
        .enumerate()
        {
            rays.push(RayItem {
                origin: o,
                direction: d,
                t_max: f32::INFINITY,
                weight: Vec3::ONE,
                slot: SampleSlot(s as u32),
            });
        }
        let mut hits = HitColumns::default();
        intersect_closest(
            &world,
            ClosestRays::of(&rays),
            ClosestOut::resizing(&mut hits),
        );
        assert_eq!(
            hits.prim(),
            vec![PrimId::NONE, PrimId(1), PrimId::NONE, PrimId::NONE]
        );
    }
}
