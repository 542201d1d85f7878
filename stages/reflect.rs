//! Stage `reflect`: mirror rays for the next depth from every hit on a reflective material.
//!
//! Reads: [`ReflectHits`] (`HitQueue.{spawn, shading, material, direction, weight, slot}`),
//! materials.
//! Writes: [`NextRays`] — the next depth's `RayQueue` (compacted, slot order), weight `weight·α`.

use glam::Vec3;

use crate::queue::compact::{compact, count_chunks};
use crate::queue::{HitQueue, MIN_CHUNK, RayItem, RayQueue, Resize, SampleSlot};
use crate::simd::{Level, Wide, WideKernel, dispatch_wide, dot3};
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
    spawn_reflection_rays_at(Level::current(), world, hits, counts, next);
}

/// [`spawn_reflection_rays`] with its kernel compiled for `level`.
fn spawn_reflection_rays_at(
    level: Level,
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
        let k = out.slot.len();
        let kernel = ReflectKernel {
            spawn: &hits.spawn[rows.clone()],
            shading: &hits.shading[rows.clone()],
            direction: &hits.direction[rows.clone()],
            weight: &hits.weight[rows.clone()],
            slot: &hits.slot[rows.clone()],
            material: &material[rows],
            alpha,
            origin: &mut out.origin[..k],
            out_direction: &mut out.direction[..k],
            t_max: &mut out.t_max[..k],
            out_weight: &mut out.weight[..k],
            out_slot: &mut out.slot[..k],
        };
        dispatch_wide(level, kernel);
    });
}

/// Most lanes of a [`Wide`] type (stack buffers are this long).
const MAX_LANES: usize = 32;

/// One chunk of hits' reflection rays, in order, into its part of the next queue: groups of
/// `V::LANES` hits that all reflect on lanes (the operations of [`reflection_ray`], in its
/// order), other rows by [`reflection_ray`] itself.
struct ReflectKernel<'a> {
    spawn: &'a [Vec3],
    shading: &'a [Vec3],
    direction: &'a [Vec3],
    weight: &'a [Vec3],
    slot: &'a [SampleSlot],
    material: &'a [u32],
    /// Each material's α, 0 where it does not reflect.
    alpha: &'a [f32],
    origin: &'a mut [Vec3],
    out_direction: &'a mut [Vec3],
    t_max: &'a mut [f32],
    out_weight: &'a mut [Vec3],
    out_slot: &'a mut [SampleSlot],
}

impl ReflectKernel<'_> {
    /// Row `i` by [`reflection_ray`] into output row `j` when it reflects; true if it did.
    #[inline(always)]
    fn row(&mut self, i: usize, j: usize) -> bool {
        let a = self.alpha[self.material[i] as usize];
        if a > 0.0 {
            let r = reflection_ray(
                (self.spawn[i], self.direction[i], self.shading[i]),
                (self.weight[i], a, self.slot[i]),
            );
            (self.origin[j], self.out_direction[j]) = (r.origin, r.direction);
            (self.t_max[j], self.out_weight[j], self.out_slot[j]) = (r.t_max, r.weight, r.slot);
        }
        a > 0.0
    }
}

impl WideKernel for ReflectKernel<'_> {
    type Output = ();
    #[inline(always)]
    fn run<V: Wide>(mut self) {
        let n = V::LANES;
        let rows = self.material.len();
        let (mut i, mut j) = (0, 0);
        while i + n <= rows {
            let mut a = [0.0f32; MAX_LANES];
            let mut all = true;
            for (al, &m) in a.iter_mut().zip(&self.material[i..i + n]) {
                *al = self.alpha[m as usize];
                all &= *al > 0.0;
            }
            if !all {
                for r in i..i + n {
                    j += usize::from(self.row(r, j));
                }
                i += n;
                continue;
            }
            let d = V::load3(bytemuck::cast_slice(&self.direction[i..i + n]));
            let s = V::load3(bytemuck::cast_slice(&self.shading[i..i + n]));
            let w = V::load3(bytemuck::cast_slice(&self.weight[i..i + n]));
            // `d − 2(d·n)n` and `weight·α` as `reflection_ray` computes them.
            let dot = dot3(d, s);
            let k = V::splat(2.0).mul(dot);
            let r = [
                d[0].sub(k.mul(s[0])),
                d[1].sub(k.mul(s[1])),
                d[2].sub(k.mul(s[2])),
            ];
            let av = V::load(&a);
            let wa = [w[0].mul(av), w[1].mul(av), w[2].mul(av)];
            let out = j..j + n;
            self.origin[out.clone()].copy_from_slice(&self.spawn[i..i + n]);
            V::store3(
                r,
                bytemuck::cast_slice_mut(&mut self.out_direction[out.clone()]),
            );
            V::splat(f32::INFINITY).store(&mut self.t_max[out.clone()]);
            V::store3(
                wa,
                bytemuck::cast_slice_mut(&mut self.out_weight[out.clone()]),
            );
            self.out_slot[out].copy_from_slice(&self.slot[i..i + n]);
            (i, j) = (i + n, j + n);
        }
        while i < rows {
            j += usize::from(self.row(i, j));
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::queue::PrimId;
    use crate::scene::builtin::spheres;

    /// Many hits, runs of reflective and mixed materials: every level's rays are
    /// `reflection_ray`'s, bit for bit, in slot order.
    #[test]
    fn lane_reflections_are_the_scalar_ones_bit_for_bit() {
        let world = World::load(&spheres()).unwrap();
        let alpha: Vec<f32> = world
            .materials()
            .iter()
            .map(|m| if m.reflects() { m.alpha } else { 0.0 })
            .collect();
        let reflective = (0..alpha.len() as u32)
            .find(|&m| alpha[m as usize] > 0.0)
            .unwrap();
        let mut rng = crate::sampling::Rng(9);
        let mut hits = HitQueue::default();
        for s in 0..3001u32 {
            // Runs of 40 reflective hits, then mixed ones.
            let m = if (s / 40) % 2 == 0 {
                reflective
            } else {
                s % alpha.len() as u32
            };
            let v = |rng: &mut crate::sampling::Rng| {
                Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                )
            };
            hits.push(crate::queue::HitItem {
                origin: Vec3::ZERO,
                direction: v(&mut rng).normalize(),
                weight: v(&mut rng).abs(),
                slot: SampleSlot(s),
                t: 1.0,
                prim: PrimId(0),
                point: v(&mut rng),
                normal: Vec3::Y,
                material: m,
                spawn: v(&mut rng) * 3.0,
                shading: v(&mut rng).normalize(),
                emitted: Vec3::ZERO,
            });
        }
        let h = hits.columns();
        let want: Vec<RayItem> = (0..hits.len())
            .filter(|&i| alpha[h.material[i] as usize] > 0.0)
            .map(|i| {
                let a = alpha[h.material[i] as usize];
                reflection_ray(
                    (h.spawn[i], h.direction[i], h.shading[i]),
                    (h.weight[i], a, h.slot[i]),
                )
            })
            .collect();
        assert!(want.len() > 1000);
        let bits = |r: &RayItem| {
            let v = |v: Vec3| v.to_array().map(f32::to_bits);
            (
                v(r.origin),
                v(r.direction),
                r.t_max.to_bits(),
                v(r.weight),
                r.slot,
            )
        };
        for level in crate::simd::Level::supported() {
            let mut next = RayQueue::default();
            spawn_reflection_rays_at(
                level,
                &world,
                ReflectHits::of(&hits),
                &mut vec![],
                NextRays::resizing(&mut next),
            );
            assert_eq!(next.len(), want.len(), "{level:?}");
            for (i, w) in want.iter().enumerate() {
                assert_eq!(bits(&next.get(i)), bits(w), "{level:?} row {i}");
            }
        }
    }

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
