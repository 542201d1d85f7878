//! Deterministic per-sample jitter: a counter-based hash of (seed, pixel, sample), so any thread
//! computes the same sample positions in any order.

/// A 32-bit integer hash with good avalanche (the "lowbias32" finaliser by C. Wellons).
#[inline(always)]
pub(crate) fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// A uniform float in `[0, 1)` from a hash of the three keys.
#[inline(always)]
pub fn uniform(seed: u32, a: u32, b: u32) -> f32 {
    let h = hash32(seed ^ hash32(a ^ hash32(b.wrapping_add(0x9e37_79b9))));
    // 24 high bits → exactly representable floats in [0, 1).
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Offset of sample `s` of `n` inside its pixel, in `[0, 1)²` (see [`Strata`]).
#[inline]
pub fn sample_offset(seed: u32, pixel: u32, s: u32, n: u32) -> (f32, f32) {
    Strata::new(n).offset(seed, pixel, s)
}

/// The stratification of a pixel for `n` samples, computed once per wave rather than per ray.
///
/// One sample sits at the pixel centre (SPEC §1). With `n > 1` the pixel is cut into
/// `k × m` strata (`k = ⌈√n⌉`, `m = ⌈n / k⌉`; exactly `√n × √n` when `n` is a square) and sample
/// `s` is jittered uniformly inside stratum `s`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Strata {
    /// Samples per pixel.
    pub n: u32,
    /// Columns of strata.
    pub k: u32,
    /// Rows of strata.
    pub m: u32,
}

impl Strata {
    /// The strata for `n` samples.
    pub fn new(n: u32) -> Strata {
        let (k, m) = strata(n);
        Strata { n, k, m }
    }

    /// Offset of sample `s` inside pixel `pixel`, in `[0, 1)²`.
    #[inline]
    pub fn offset(&self, seed: u32, pixel: u32, s: u32) -> (f32, f32) {
        if self.n <= 1 {
            return (0.5, 0.5);
        }
        let (sx, sy) = (s % self.k, s / self.k);
        let jx = uniform(seed, pixel, 2 * s);
        let jy = uniform(seed, pixel, 2 * s + 1);
        (
            (sx as f32 + jx) / self.k as f32,
            (sy as f32 + jy) / self.m as f32,
        )
    }
}

/// Strata counts `(columns, rows)` for `n` samples.
pub(crate) fn strata(n: u32) -> (u32, u32) {
    let k = (n as f64).sqrt().ceil() as u32;
    let k = k.max(1);
    (k, n.div_ceil(k))
}

/// A seeded sequential generator (splitmix64) for tests, tools and benchmarks: the one place
/// random numbers come from outside the renderer's counter-based [`uniform`] jitter.
#[derive(Clone, Debug)]
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (by remainder; 0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }

    /// Uniform in [-1, 1).
    pub fn signed(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// Uniform in [0, 1), as f32.
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in `[lo, hi)`, as f32.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_counts_use_square_strata() {
        assert_eq!(strata(64), (8, 8));
        assert_eq!(strata(4), (2, 2));
        assert_eq!(strata(5), (3, 2));
    }

    #[test]
    fn each_sample_lies_in_its_own_stratum() {
        for s in 0..64 {
            let (x, y) = sample_offset(7, 123, s, 64);
            assert_eq!((x * 8.0) as u32, s % 8);
            assert_eq!((y * 8.0) as u32, s / 8);
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
        }
    }

    #[test]
    fn one_sample_is_the_pixel_centre() {
        assert_eq!(sample_offset(1, 5, 0, 1), (0.5, 0.5));
    }

    #[test]
    fn seeds_change_the_jitter() {
        assert_ne!(sample_offset(1, 5, 3, 16), sample_offset(2, 5, 3, 16));
    }
}
