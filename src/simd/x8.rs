//! Lane masks as bits for the kD tree's wide frusta: a `[bool; G]` (what a comparison over an
//! array of lanes gives) packed into an integer, one bit per lane, with SSE2 `movmskps` four
//! lanes at a time.
//!
//! Reads and writes nothing but its arguments. LLVM does not turn a loop of shifts and ORs over
//! booleans into a `movmskps`, and the frusta build one such mask per node step; this is the
//! one operation their safe lane code cannot express. On `x86_64` SSE2 is part of the baseline,
//! so the intrinsics are always available (inlined into an AVX2 or AVX-512 kernel they get the
//! VEX encoding); elsewhere a plain loop.
#![allow(unsafe_code)]

/// Bit `j` of the result is `m[j]` (`G` ≤ 64, a multiple of 4): sixteen lanes at a time with
/// one byte mask ([`movemask16`]), the rest four at a time.
#[inline(always)]
pub fn bits<const G: usize>(m: &[bool; G]) -> u64 {
    let mut out = 0u64;
    let wide = G / 16 * 16;
    for q in 0..G / 16 {
        let sixteen: &[bool; 16] = m[16 * q..16 * q + 16].try_into().expect("16 lanes");
        out |= (movemask16(sixteen) as u64) << (16 * q);
    }
    for q in wide / 4..G / 4 {
        let four: [i32; 4] = std::array::from_fn(|j| -(m[4 * q + j] as i32));
        out |= (movemask4(&four) as u64) << (4 * q);
    }
    out
}

/// Sixteen booleans as bits: each byte (0 or 1) shifted to its sign bit, then `pmovmskb`.
#[inline(always)]
fn movemask16(a: &[bool; 16]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_loadu_si128, _mm_movemask_epi8, _mm_slli_epi64};
        // SAFETY: SSE2 is part of the x86_64 baseline; an unaligned load of the 16 bytes behind
        // a valid `&[bool; 16]` (each byte 0 or 1, so a shift by 7 within 64-bit lanes moves
        // each byte's bit to its sign bit without crossing into the next byte).
        unsafe { _mm_movemask_epi8(_mm_slli_epi64::<7>(_mm_loadu_si128(a.as_ptr().cast()))) as u32 }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        a.iter()
            .enumerate()
            .fold(0, |b, (j, &x)| b | (u32::from(x) << j))
    }
}

/// The sign bits of four lanes.
#[inline(always)]
fn movemask4(a: &[i32; 4]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_castsi128_ps, _mm_loadu_si128, _mm_movemask_ps};
        // SAFETY: SSE2 is part of the x86_64 baseline; an unaligned load of the 16 bytes behind
        // a valid `&[i32; 4]`.
        unsafe { _mm_movemask_ps(_mm_castsi128_ps(_mm_loadu_si128(a.as_ptr().cast()))) as u32 }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        a.iter()
            .enumerate()
            .fold(0, |b, (j, &x)| b | (((x as u32) >> 31) << j))
    }
}

#[cfg(test)]
mod tests {
    use super::bits;

    #[test]
    fn bits_follow_the_lanes() {
        let mut m = [false; 16];
        for j in [0, 3, 4, 9, 15] {
            m[j] = true;
        }
        assert_eq!(bits(&m), 1 | 1 << 3 | 1 << 4 | 1 << 9 | 1 << 15);
        assert_eq!(bits(&[true; 64]), u64::MAX);
        assert_eq!(bits(&[false; 8]), 0);
        let mut m = [false; 64];
        for j in [0, 7, 8, 15, 16, 31, 33, 48, 62, 63] {
            m[j] = true;
        }
        let want = [0, 7, 8, 15, 16, 31, 33, 48, 62, 63]
            .iter()
            .fold(0u64, |b, &j| b | 1 << j);
        assert_eq!(bits(&m), want);
        let mut m = [false; 8];
        m[5] = true;
        assert_eq!(bits(&m), 1 << 5);
    }
}
