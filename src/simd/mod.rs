//! SIMD: the crate's one module with `unsafe` code.
//!
//! Two tools live here:
//!
//! - **Run-time dispatch** ([`dispatch`]): a kernel body, written once as plain safe Rust over
//!   fixed-size lanes (`[f32; 8]` chunks of SoA columns, or `F32x4`), is compiled once per
//!   instruction set ([`Level`]) and the best one the CPU has is chosen when the program runs —
//!   these machines change CPU between sessions (an Intel Xeon with AVX-512, an AMD EPYC with
//!   AVX2 and AVX-512). The portable path (SSE2 on `x86_64`) is always there.
//! - **Explicit lanes** (`F32x4`, `M32x4`): four `f32` lanes with exactly the semantics of
//!   SSE2 instructions, for the kD tree's packet traversal (`x4`); 8 or 16 lanes behind one
//!   trait (`Wide`, `wide`) for its frusta and light-rooted bundles.
//!
//! Determinism: every path performs the same IEEE operations in the same order on each lane —
//! Rust never contracts `a * b + c` into a fused multiply-add, and enabling the `fma` feature
//! does not change that — so a kernel gives the same bits on every [`Level`]. Tests run each
//! available level and compare.
#![allow(unsafe_code)]

mod wide;
mod x4;

pub(crate) use wide::Pair;
pub(crate) use wide::{Wide, WideKernel, dispatch_wide, dot3};
pub(crate) use x4::{F32x4, max_ps, min_ps};

use std::sync::OnceLock;

/// An instruction set a kernel is compiled for, from the most portable up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Level {
    /// The target's baseline (SSE2 on `x86_64`).
    Portable,
    /// AVX2 + FMA (256-bit lanes).
    Avx2,
    /// AVX-512 F/VL/BW/DQ on top of AVX2 (512-bit lanes).
    Avx512,
}

impl Level {
    /// Every level, in order.
    pub const ALL: [Level; 3] = [Level::Portable, Level::Avx2, Level::Avx512];

    /// The level's name as `WAVEFRONT_SIMD` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Level::Portable => "portable",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }

    /// True when this CPU can run code compiled for `self`.
    pub(crate) fn is_supported(self) -> bool {
        match self {
            Level::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => {
                Level::Avx2.is_supported()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx512bw")
                    && std::arch::is_x86_feature_detected!("avx512dq")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The levels this CPU supports, from the most portable up (what tests iterate over).
    pub fn supported() -> Vec<Level> {
        Level::ALL
            .into_iter()
            .filter(|l| l.is_supported())
            .collect()
    }

    /// The best supported level, capped by the `WAVEFRONT_SIMD` environment variable
    /// (`portable`, `avx2` or `avx512`; an unknown value is ignored) — read once per process.
    pub fn current() -> Level {
        static CURRENT: OnceLock<Level> = OnceLock::new();
        *CURRENT.get_or_init(|| {
            let cap = std::env::var("WAVEFRONT_SIMD")
                .ok()
                .and_then(|v| Level::ALL.into_iter().find(|l| l.name() == v))
                .unwrap_or(Level::Avx512);
            Level::supported()
                .into_iter()
                .filter(|l| *l <= cap)
                .max()
                .unwrap_or(Level::Portable)
        })
    }
}

/// A kernel body to compile once per [`Level`]. Implementations must mark [`Kernel::run`]
/// `#[inline(always)]`, and so must whatever it calls in its hot loop: only code inlined into the
/// dispatcher's `#[target_feature]` function is compiled for that level.
pub trait Kernel {
    /// What the kernel returns.
    type Output;
    /// The body; `level` is the level it runs at (for lane widths chosen per level).
    fn run(self, level: Level) -> Self::Output;
}

/// Runs `kernel` compiled for `level`, or for the best supported level below it.
#[inline]
pub fn dispatch<K: Kernel>(level: Level, kernel: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    {
        if level >= Level::Avx512 && Level::Avx512.is_supported() {
            // SAFETY: the CPU supports every feature `run_avx512` enables (checked just above).
            return unsafe { run_avx512(kernel) };
        }
        if level >= Level::Avx2 && Level::Avx2.is_supported() {
            // SAFETY: the CPU supports every feature `run_avx2` enables (checked just above).
            return unsafe { run_avx2(kernel) };
        }
    }
    let _ = level;
    kernel.run(Level::Portable)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run(Level::Avx2)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
unsafe fn run_avx512<K: Kernel>(kernel: K) -> K::Output {
    kernel.run(Level::Avx512)
}

/// Eight `Vec3` rows as three lane arrays: `rows[3l + k]` goes to lane `l` of component `k`
/// (pure data movement). With AVX2 on the CPU, three loads, six blends and three permutes in
/// place of 24 scalar moves (which is what the compiler made of the stride-3 loop); when
/// inlined into a kernel compiled for AVX2 or AVX-512 it stays in registers.
#[inline(always)]
pub(crate) fn deinterleave3x8(rows: &[f32; 24]) -> [[f32; 8]; 3] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { shuffle3::deinterleave(rows) };
    }
    deinterleave3x8_scalar(rows)
}

/// [`deinterleave3x8`]'s definition, one float at a time: the portable form, and what the AVX2
/// form is checked against.
#[inline(always)]
fn deinterleave3x8_scalar(rows: &[f32; 24]) -> [[f32; 8]; 3] {
    std::array::from_fn(|k| std::array::from_fn(|l| rows[3 * l + k]))
}

/// The inverse of [`deinterleave3x8`]: lane `l` of component `k` goes to `rows[3l + k]`.
#[inline(always)]
pub(crate) fn interleave3x8(lanes: &[[f32; 8]; 3], rows: &mut [f32; 24]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { shuffle3::interleave(lanes, rows) };
    }
    interleave3x8_scalar(lanes, rows);
}

/// [`interleave3x8`]'s definition, one float at a time (see [`deinterleave3x8_scalar`]).
#[inline(always)]
fn interleave3x8_scalar(lanes: &[[f32; 8]; 3], rows: &mut [f32; 24]) {
    for l in 0..8 {
        for k in 0..3 {
            rows[3 * l + k] = lanes[k][l];
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod shuffle3 {
    //! The AVX2 stride-3 shuffles. Rows `a b c` (8 floats each) hold `x y z x y z x y`,
    //! `z x y z x y z x` and `y z x y z x y z`: each component is two blends of them (lanes of
    //! `b` under mask `0x92`/`0x24`/`0x49`, of `c` likewise) and one permute into lane order.
    use std::arch::x86_64::*;

    /// Permutes taking the blended x, y and z vectors to lane order.
    const X: [i32; 8] = [0, 3, 6, 1, 4, 7, 2, 5];
    const Y: [i32; 8] = [1, 4, 7, 2, 5, 0, 3, 6];
    const Z: [i32; 8] = [2, 5, 0, 3, 6, 1, 4, 7];
    /// Permutes taking lane order to the blended layouts (the inverses of `X`, `Y`, `Z`).
    const TX: [i32; 8] = [0, 3, 6, 1, 4, 7, 2, 5];
    const TY: [i32; 8] = [5, 0, 3, 6, 1, 4, 7, 2];
    const TZ: [i32; 8] = [2, 5, 0, 3, 6, 1, 4, 7];

    /// `v`'s lanes in the order `idx`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn perm(v: __m256, idx: [i32; 8]) -> __m256 {
        let i = _mm256_setr_epi32(
            idx[0], idx[1], idx[2], idx[3], idx[4], idx[5], idx[6], idx[7],
        );
        _mm256_permutevar8x32_ps(v, i)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn deinterleave(rows: &[f32; 24]) -> [[f32; 8]; 3] {
        let p = rows.as_ptr();
        // SAFETY: `rows` holds 24 floats: three unaligned 8-float loads at 0, 8 and 16.
        let abc = unsafe {
            [
                _mm256_loadu_ps(p),
                _mm256_loadu_ps(p.add(8)),
                _mm256_loadu_ps(p.add(16)),
            ]
        };
        let mut out = [[0.0f32; 8]; 3];
        for (o, v) in out.iter_mut().zip(deinterleave_regs(abc)) {
            // SAFETY: `o` holds 8 floats (unaligned store).
            unsafe { _mm256_storeu_ps(o.as_mut_ptr(), v) };
        }
        out
    }

    /// [`deinterleave`] on registers: rows `a b c` to x, y and z.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn deinterleave_regs([a, b, c]: [__m256; 3]) -> [__m256; 3] {
        let x = perm(_mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(a, b), c), X);
        let y = perm(_mm256_blend_ps::<0x49>(_mm256_blend_ps::<0x24>(a, b), c), Y);
        let z = perm(_mm256_blend_ps::<0x92>(_mm256_blend_ps::<0x49>(a, b), c), Z);
        [x, y, z]
    }

    /// [`interleave`] on registers: x, y and z to rows `a b c`.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn interleave_regs([x, y, z]: [__m256; 3]) -> [__m256; 3] {
        let (tx, ty, tz) = (perm(x, TX), perm(y, TY), perm(z, TZ));
        let a = _mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(tx, ty), tz);
        let b = _mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(tz, tx), ty);
        let c = _mm256_blend_ps::<0x24>(_mm256_blend_ps::<0x92>(ty, tz), tx);
        [a, b, c]
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn interleave(lanes: &[[f32; 8]; 3], rows: &mut [f32; 24]) {
        // SAFETY: each component holds 8 floats (unaligned loads).
        let xyz = unsafe {
            [
                _mm256_loadu_ps(lanes[0].as_ptr()),
                _mm256_loadu_ps(lanes[1].as_ptr()),
                _mm256_loadu_ps(lanes[2].as_ptr()),
            ]
        };
        let [a, b, c] = interleave_regs(xyz);
        let p = rows.as_mut_ptr();
        // SAFETY: `rows` holds 24 floats: three unaligned 8-float stores at 0, 8 and 16.
        unsafe {
            _mm256_storeu_ps(p, a);
            _mm256_storeu_ps(p.add(8), b);
            _mm256_storeu_ps(p.add(16), c);
        }
    }
}

#[cfg(test)]
// Test data and references may use the platform's functions; no pixel depends on them.
#[allow(clippy::disallowed_methods)]
mod tests {
    use super::*;

    /// A small kernel: `a * b + c` over lanes of 8, the shape of the crate's kernels.
    struct Madd<'a> {
        a: &'a [f32],
        b: &'a [f32],
        c: &'a [f32],
        out: &'a mut Vec<f32>,
    }

    impl Kernel for Madd<'_> {
        type Output = Level;
        #[inline(always)]
        fn run(self, level: Level) -> Level {
            self.out.clear();
            self.out.extend(
                self.a
                    .iter()
                    .zip(self.b)
                    .zip(self.c)
                    .map(|((a, b), c)| a * b + c),
            );
            level
        }
    }

    #[test]
    fn every_supported_level_runs_and_gives_the_same_bits() {
        let n = 1003;
        let a: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin() * 1e3).collect();
        let b: Vec<f32> = (0..n).map(|i| (i as f32 * 0.11).cos() / 7.0).collect();
        let c: Vec<f32> = (0..n).map(|i| 1.0 / (i as f32 + 0.5)).collect();
        let mut reference = vec![];
        dispatch(
            Level::Portable,
            Madd {
                a: &a,
                b: &b,
                c: &c,
                out: &mut reference,
            },
        );
        for level in Level::supported() {
            let mut out = vec![];
            let ran = dispatch(
                level,
                Madd {
                    a: &a,
                    b: &b,
                    c: &c,
                    out: &mut out,
                },
            );
            assert_eq!(ran, level);
            let same = out
                .iter()
                .zip(&reference)
                .all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(same, "{level:?} differs from the portable path");
        }
    }

    #[test]
    fn stride_three_shuffles_move_every_float_to_its_lane_and_back() {
        let rows: [f32; 24] = std::array::from_fn(|i| i as f32 + 0.5);
        // The scalar definition, then the form this CPU runs (AVX2's shuffles where it has
        // them) against it.
        let lanes = deinterleave3x8_scalar(&rows);
        for l in 0..8 {
            for k in 0..3 {
                assert_eq!(lanes[k][l], rows[3 * l + k], "lane {l} component {k}");
            }
        }
        let mut back = [0.0; 24];
        interleave3x8_scalar(&lanes, &mut back);
        assert_eq!(back, rows);
        assert_eq!(deinterleave3x8(&rows), lanes);
        let mut back = [0.0; 24];
        interleave3x8(&lanes, &mut back);
        assert_eq!(back, rows);
    }

    #[test]
    fn current_is_supported_and_portable_always_is() {
        assert!(Level::Portable.is_supported());
        assert!(Level::current().is_supported());
        assert_eq!(Level::supported()[0], Level::Portable);
    }
}
