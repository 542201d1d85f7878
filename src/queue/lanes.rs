//! `Vec3` rows in and out of lanes: 8 rows of a `Vec3` column as x, y and z arrays (what the
//! SIMD kernels compute on), and back.
//!
//! A full group of 8 rows is 24 contiguous `f32`s, read (or written) as one fixed-size array, so
//! the compiler turns the deinterleave into vector loads and shuffles rather than 24 scalar
//! stores into a stack array re-read as vectors (which stalls on store forwarding); a shorter
//! tail goes row by row. Pure data movement: the values are the rows' bits.

// Lane loops index several parallel `[_; LANES]` arrays by lane: an index is clearer than zips.
#![allow(clippy::needless_range_loop)]

use glam::Vec3;

/// Rows per lane group.
pub(crate) const LANES: usize = 8;

/// x, y and z of up to [`LANES`] rows, lane `l` holding row `l`.
pub(crate) type Lanes3 = [[f32; LANES]; 3];

/// The rows (at most `N`, [`LANES`] by default) in lanes; lanes past `rows.len()` are zero.
#[inline(always)]
pub(crate) fn load3<const N: usize>(rows: &[Vec3]) -> [[f32; N]; 3] {
    let mut x = [[0.0; N]; 3];
    if N == 8
        && let Ok(full) = <&[Vec3; 8]>::try_from(rows)
    {
        let lanes = crate::simd::deinterleave3x8(bytemuck::cast_ref(full));
        for k in 0..3 {
            x[k].copy_from_slice(&lanes[k][..N.min(8)]);
        }
    } else if let Ok(full) = <&[Vec3; N]>::try_from(rows) {
        let flat: &[f32] = bytemuck::cast_slice(full);
        let flat = &flat[..3 * N];
        for l in 0..N {
            for k in 0..3 {
                x[k][l] = flat[3 * l + k];
            }
        }
    } else {
        for (l, v) in rows.iter().take(N).enumerate() {
            for k in 0..3 {
                x[k][l] = v[k];
            }
        }
    }
    x
}

/// Writes the first `rows.len()` lanes (at most `N`, [`LANES`] by default) to `rows`.
#[inline(always)]
pub(crate) fn store3<const N: usize>(x: &[[f32; N]; 3], rows: &mut [Vec3]) {
    if N == 8
        && let Ok(full) = <&mut [Vec3; 8]>::try_from(&mut *rows)
    {
        let lanes: [[f32; 8]; 3] = std::array::from_fn(|k| std::array::from_fn(|l| x[k][l]));
        crate::simd::interleave3x8(&lanes, bytemuck::cast_mut(full));
    } else if let Ok(full) = <&mut [Vec3; N]>::try_from(&mut *rows) {
        let flat: &mut [f32] = bytemuck::cast_slice_mut(full);
        let flat = &mut flat[..3 * N];
        for l in 0..N {
            for k in 0..3 {
                flat[3 * l + k] = x[k][l];
            }
        }
    } else {
        for (l, v) in rows.iter_mut().take(N).enumerate() {
            *v = Vec3::new(x[0][l], x[1][l], x[2][l]);
        }
    }
}

/// Values of a scalar column (at most [`LANES`] rows) in lanes; lanes past `rows.len()` hold
/// `fill`.
#[inline(always)]
pub(crate) fn load1<T: Copy>(rows: &[T], fill: T) -> [T; LANES] {
    if let Ok(full) = <&[T; LANES]>::try_from(rows) {
        *full
    } else {
        let mut x = [fill; LANES];
        for (l, v) in rows.iter().take(LANES).enumerate() {
            x[l] = *v;
        }
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_through_lanes_full_and_partial() {
        for n in 0..=LANES {
            let rows: Vec<Vec3> = (0..n)
                .map(|i| Vec3::new(i as f32, -(i as f32) - 0.5, 100.0 + i as f32))
                .collect();
            let x: Lanes3 = load3(&rows);
            for l in 0..LANES {
                let want = rows.get(l).copied().unwrap_or(Vec3::ZERO);
                assert_eq!(
                    [x[0][l], x[1][l], x[2][l]],
                    want.to_array(),
                    "n {n} lane {l}"
                );
            }
            let ids: Vec<u32> = (0..n as u32).collect();
            let l1 = load1(&ids, 99);
            for l in 0..LANES {
                assert_eq!(l1[l], if l < n { l as u32 } else { 99 });
            }
            let mut back = vec![Vec3::splat(7.0); n];
            store3(&x, &mut back);
            assert_eq!(back, rows);
        }
        // 16 lanes, full and partial.
        for n in [16, 11] {
            let rows: Vec<Vec3> = (0..n)
                .map(|i| Vec3::new(i as f32, 2.0, -(i as f32)))
                .collect();
            let x: [[f32; 16]; 3] = load3(&rows);
            assert_eq!(
                (x[0][n - 1], x[2][n - 1]),
                ((n - 1) as f32, -((n - 1) as f32))
            );
            let mut back = vec![Vec3::ZERO; n];
            store3(&x, &mut back);
            assert_eq!(back, rows);
        }
    }
}
