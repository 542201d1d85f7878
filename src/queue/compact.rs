//! Order-preserving parallel compaction: the one helper of every kernel with variable output
//! (`compact_hits`, `spawn_reflection_rays`, `spawn_shadow_rays`).
//!
//! A two-pass compaction over chunks of input rows: first each chunk's kept rows are counted in
//! parallel (`count_chunks`, or a kernel's own first pass), then [`compact`] sizes the output
//! queue to the total and hands each chunk its consecutive piece of every output column, so every
//! chunk writes its kept rows directly, in order, with no index list and no atomics. Rows keep
//! their input order whatever the thread count (atomic appends would reorder them between runs).

use rayon::prelude::*;

use super::{ColumnSet, Resize};

/// Counts, in parallel, the rows each chunk of `chunk` rows (of `n`) keeps, into `counts` (one
/// entry per chunk, overwritten); returns the total. The first pass of [`compact`].
pub(crate) fn count_chunks(
    n: usize,
    chunk: usize,
    count: impl Fn(std::ops::Range<usize>) -> usize + Sync,
    counts: &mut Vec<usize>,
) -> usize {
    let chunk = chunk.max(1);
    (0..n.div_ceil(chunk))
        .into_par_iter()
        .map(|c| count(c * chunk..(c * chunk + chunk).min(n)))
        .collect_into_vec(counts);
    counts.iter().sum()
}

/// The second pass: sizes `out`'s queue to the sum of `counts` and runs `write(c, piece)` in
/// parallel for every chunk `c`, where `piece` is rows `counts[..c].sum()..` (`counts[c]` of
/// them) of every column of the set: chunk `c`'s part of the compacted queue, which `write`
/// fills completely.
pub fn compact<S>(out: Resize<S>, counts: &[usize], write: impl Fn(usize, S) + Sync)
where
    S: ColumnSet + Send,
{
    let mut rest = out.resize(counts.iter().sum());
    let mut pieces = Vec::with_capacity(counts.len());
    for &k in counts {
        let (piece, tail) = rest.split_at(k);
        pieces.push(piece);
        rest = tail;
    }
    pieces
        .into_par_iter()
        .enumerate()
        .for_each(|(c, piece)| write(c, piece));
}

// The test queues use only part of what the macros generate.
#[cfg(test)]
#[allow(dead_code)]
mod tests {
    use super::*;
    use crate::queue::Queue;

    crate::queue! {
        /// A test queue.
        pub struct Kept {
            /// Input row index.
            row: u32,
            /// Twice it.
            twice: u64,
        }
        /// A row.
        pub struct KeptRow;
    }

    crate::column_set! {
        /// Both columns, written.
        pub struct KeptOut<'a>: Kept { write row: u32, write twice: u64 }
    }

    /// The kept rows of `n` by two-pass compaction in chunks of 1,000.
    fn compacted(n: usize, keep: impl Fn(usize) -> bool + Sync, out: &mut Kept) {
        let mut counts = vec![];
        count_chunks(n, 1000, |r| r.filter(|&i| keep(i)).count(), &mut counts);
        compact(KeptOut::resizing(out), &counts, |c, piece| {
            let mut j = 0;
            for i in c * 1000..(c * 1000 + 1000).min(n) {
                if keep(i) {
                    (piece.row[j], piece.twice[j]) = (i as u32, 2 * i as u64);
                    j += 1;
                }
            }
            assert_eq!(j, piece.row.len(), "each chunk fills its piece");
        });
    }

    #[test]
    fn compaction_preserves_order_on_any_pool() {
        let n = 100_000;
        let keep = |i: usize| (i * 7919) % 13 < 5;
        let expected: Vec<u32> = (0..n as u32).filter(|&i| keep(i as usize)).collect();
        for threads in [1, 2, 4] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            // A queue longer than the output first: compaction sizes it down, one length.
            let mut out = Kept::default();
            out.resize(n + 7);
            pool.install(|| compacted(n, keep, &mut out));
            assert_eq!(out.row(), expected, "{threads} threads");
            assert_eq!(out.column_lens(), vec![expected.len(); 2]);
            assert!(
                out.twice()
                    .iter()
                    .zip(out.row())
                    .all(|(&t, &r)| t == 2 * r as u64)
            );
        }
    }

    #[test]
    fn counted_chunks_split_the_output_in_order() {
        let mut counts = vec![];
        let total = count_chunks(10, 4, |r| r.filter(|i| i % 3 == 0).count(), &mut counts);
        assert_eq!((total, counts.as_slice()), (4, &[2, 1, 1][..]));
        let mut out = Kept::default();
        let mut lens = std::sync::Mutex::new(vec![0; 3]);
        compact(KeptOut::resizing(&mut out), &counts, |c, piece| {
            lens.lock().unwrap()[c] = piece.row.len();
        });
        assert_eq!(*lens.get_mut().unwrap(), counts);
        assert_eq!(out.len(), 4);
    }
}
