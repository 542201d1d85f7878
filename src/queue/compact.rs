//! Order-preserving parallel compaction and gathers.
//!
//! Kernels with variable output write a per-row outcome in parallel; [`kept_rows`] then lists the
//! rows to keep in their original order (rayon's indexed `collect` preserves order whatever the
//! thread count), and [`gather`] copies a column's kept rows in parallel. Atomic appends would
//! reorder rows between runs; this does not.

use rayon::prelude::*;

use super::{MIN_CHUNK, RowIndex};

/// Indices of the rows for which `keep` is true, ascending, into `out` (cleared first).
pub fn kept_rows(n: usize, keep: impl Fn(usize) -> bool + Sync, out: &mut Vec<RowIndex>) {
    out.clear();
    out.par_extend(
        (0..n as u32)
            .into_par_iter()
            .with_min_len(MIN_CHUNK)
            .filter(|&i| keep(i as usize))
            .map(RowIndex),
    );
}

/// `out[k] = column[rows[k]]` for every k, in parallel (`out` is overwritten).
pub fn gather<T: Copy + Send + Sync>(column: &[T], rows: &[RowIndex], out: &mut Vec<T>) {
    rows.par_iter()
        .with_min_len(MIN_CHUNK)
        .map(|&i| column[i.get()])
        .collect_into_vec(out);
}

/// Counts, in parallel, the rows each chunk of `chunk` rows (of `n`) keeps, into `counts` (one
/// entry per chunk, overwritten); returns the total. The first pass of an order-preserving
/// two-pass compaction: [`split_by_counts`] then hands each chunk its place in the output, so
/// every chunk writes its kept rows directly, in order, with no index list and no atomics.
pub fn count_chunks(
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

/// `out` (resized to the sum of `counts`) cut into consecutive pieces of `counts[c]` rows: chunk
/// `c`'s part of a compacted column.
pub fn split_by_counts<'a, T: Copy + Default>(
    out: &'a mut Vec<T>,
    counts: &[usize],
) -> Vec<&'a mut [T]> {
    // Every row is overwritten by its chunk: only a growing column needs filling.
    out.resize(counts.iter().sum(), T::default());
    let mut rest = out.as_mut_slice();
    let mut pieces = Vec::with_capacity(counts.len());
    for &k in counts {
        let (piece, tail) = rest.split_at_mut(k);
        pieces.push(piece);
        rest = tail;
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kept_rows_preserve_order_on_any_pool() {
        let n = 100_000;
        let keep = |i: usize| (i * 7919) % 13 < 5;
        let expected: Vec<RowIndex> = (0..n as u32)
            .filter(|&i| keep(i as usize))
            .map(RowIndex)
            .collect();
        for threads in [1, 2, 4] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut out = vec![];
            pool.install(|| kept_rows(n, keep, &mut out));
            assert_eq!(out, expected, "{threads} threads");
        }
    }

    #[test]
    fn counted_chunks_split_the_output_in_order() {
        let mut counts = vec![];
        let total = count_chunks(10, 4, |r| r.filter(|i| i % 3 == 0).count(), &mut counts);
        assert_eq!((total, counts.as_slice()), (4, &[2, 1, 1][..]));
        let mut out = vec![7u32; 1];
        let pieces = split_by_counts(&mut out, &counts);
        assert_eq!(pieces.iter().map(|p| p.len()).collect::<Vec<_>>(), counts);
        assert_eq!(out.len(), 4);
    }

    #[test]
    fn gather_copies_kept_rows() {
        let col: Vec<u32> = (0..10).map(|i| i * 10).collect();
        let mut out = vec![99; 3];
        gather(&col, &[RowIndex(1), RowIndex(4), RowIndex(9)], &mut out);
        assert_eq!(out, vec![10, 40, 90]);
        gather(&col, &[], &mut out);
        assert!(out.is_empty());
    }
}
