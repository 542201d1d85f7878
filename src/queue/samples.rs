//! [`SampleBuffer`]: the linear radiance of every sample of the current wave, indexed by
//! [`SampleSlot`], and [`add_sorted`], the one way radiance is added to it.
//!
//! Accumulation is deterministic: every addition into a sample happens in schedule order (depth by
//! depth, shade before shadow), and within one pass each sample is written by exactly one task.

use glam::Vec3;

use super::{MIN_CHUNK, SampleSlot};

crate::queue! {
    /// Linear radiance of every sample of one wave, indexed by [`SampleSlot`].
    pub struct SampleBuffer {
        /// Radiance of the sample.
        radiance: Vec3,
    }
    /// One sample.
    pub struct Sample;
}

crate::column_set! {
    /// What the shade stage's `add_emitted` and the shadow stage's `add_unoccluded` write: the
    /// wave's samples.
    pub struct Samples<'a>: SampleBuffer { write radiance: Vec3 }
}

/// `radiance[slot[i]] += value[i]` for every row `i` with `keep(i)`.
///
/// `slot` must be non-decreasing (every queue is). Rows are split between tasks only where the
/// slot changes, so each sample is summed by one task in row order, bit-identically on any number
/// of threads.
pub fn add_sorted(
    radiance: &mut [Vec3],
    slot: &[SampleSlot],
    value: &[Vec3],
    keep: impl Fn(usize) -> bool + Sync,
) {
    debug_assert_eq!(slot.len(), value.len());
    debug_assert!(
        slot.windows(2).all(|w| w[0] <= w[1]),
        "slots must be sorted"
    );
    let Some(first) = slot.first() else { return };
    let base = first.0 as usize;
    add_range(&mut radiance[base..], base, slot, value, 0, &keep);
}

/// Adds rows `offset..offset + slot.len()` into `out`, which starts at sample `base`.
fn add_range(
    out: &mut [Vec3],
    base: usize,
    slot: &[SampleSlot],
    value: &[Vec3],
    offset: usize,
    keep: &(impl Fn(usize) -> bool + Sync),
) {
    if slot.len() <= 4 * MIN_CHUNK {
        return add_serial(out, base, slot, value, offset, keep);
    }
    // Split where the slot changes: at the middle, moved forward past rows that share the middle
    // row's slot, else backward (when every row from the middle on shares one slot). Rows of one
    // slot are never split, so where the split falls does not change any sum.
    let half = slot.len() / 2;
    let forward = (half..slot.len()).find(|&i| slot[i] != slot[i - 1]);
    let Some(mid) = forward.or_else(|| (1..half).rev().find(|&i| slot[i] != slot[i - 1])) else {
        // One slot for every row: one serial sum, in row order.
        return add_serial(out, base, slot, value, offset, keep);
    };
    let split = slot[mid].0 as usize;
    let (lo, hi) = out.split_at_mut(split - base);
    let (ls, hs) = slot.split_at(mid);
    let (lv, hv) = value.split_at(mid);
    rayon::join(
        || add_range(lo, base, ls, lv, offset, keep),
        || add_range(hi, split, hs, hv, offset + mid, keep),
    );
}

/// [`add_range`] on one task, in row order.
fn add_serial(
    out: &mut [Vec3],
    base: usize,
    slot: &[SampleSlot],
    value: &[Vec3],
    offset: usize,
    keep: &(impl Fn(usize) -> bool + Sync),
) {
    for (i, (s, v)) in slot.iter().zip(value).enumerate() {
        if keep(offset + i) {
            out[s.0 as usize - base] += *v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn add_sorted_sums_duplicates_and_respects_keep() {
        let mut b = SampleBuffer::default();
        b.reset(4);
        let slots = [SampleSlot(1), SampleSlot(1), SampleSlot(3)];
        let vals = [Vec3::ONE, Vec3::splat(2.0), Vec3::splat(5.0)];
        add_sorted(Samples::of(&mut b).radiance, &slots, &vals, |i| i != 2);
        assert_eq!(
            b.radiance(),
            vec![Vec3::ZERO, Vec3::splat(3.0), Vec3::ZERO, Vec3::ZERO]
        );
    }

    #[test]
    fn add_sorted_is_bit_identical_across_thread_counts() {
        let n = 50_000;
        let slots: Vec<SampleSlot> = (0..n).map(|i| SampleSlot(i / 3)).collect();
        let vals: Vec<Vec3> = (0..n)
            .map(|i| Vec3::splat(1.0 / (i as f32 + 1.0)))
            .collect();
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut b = SampleBuffer::default();
            b.reset(n as usize / 3 + 1);
            pool.install(|| add_sorted(Samples::of(&mut b).radiance, &slots, &vals, |_| true));
            b.radiance().to_vec()
        };
        let one = run(1);
        assert_eq!(one, run(3));
        let serial: f32 = (0..3).map(|i| vals[i].x).fold(0.0, |a, b| a + b);
        assert_eq!(one[0].x, serial);
    }
}
