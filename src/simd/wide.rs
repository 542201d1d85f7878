//! Wide `f32` lanes for the kD tree's light-rooted shadow bundles: 16 lanes with AVX-512, 8 with
//! AVX2, and 8 portable lanes, behind one trait ([`Wide`]) and chosen at run time by
//! [`dispatch_wide`].
//!
//! Why explicit lanes rather than loops over `[f32; 8]` for LLVM to vectorise (what
//! [`super::Kernel`] bodies usually are): the bundle step ends in lane *masks* turned into bit
//! sets and branched on, and LLVM's SLP vectoriser turned those loops into scalar
//! `ucomiss`/`setae` sequences and per-lane stores (checked in the assembly; the first bundle
//! kernel ran slower than single rays). Each operation here is one instruction.
//!
//! Reads and writes nothing but its arguments. Every operation has exactly the semantics of the
//! corresponding scalar Rust operation on each lane (`+ - * /` are IEEE, never fused; `min`/`max`
//! are `minps`/`maxps`: `a` if `a < b` (`a > b`), else `b`; comparisons are ordered, false on
//! NaN), so a formula written once over [`Wide`] gives every lane the bits the scalar formula
//! gives, whatever the width.
//!
//! Soundness: the AVX2 and AVX-512 types are private to this file, so the only way to run code
//! over them is [`dispatch_wide`], which picks them only inside [`super::dispatch`]'s functions
//! compiled for (and entered only on a CPU with) those features.
#![allow(unsafe_code)]

use super::{Kernel, Level, dispatch};

/// `f32` lanes of one width with their comparison mask.
pub(crate) trait Wide: Copy {
    /// Lanes per value (at most 32).
    const LANES: usize;
    /// Per-lane truth values.
    type Mask: Copy;
    /// All lanes `x`.
    fn splat(x: f32) -> Self;
    /// Lane `k` is `a[k]` (`a` has at least [`Wide::LANES`] elements).
    fn load(a: &[f32]) -> Self;
    /// Writes lane `k` to `a[k]` (`a` has at least [`Wide::LANES`] elements).
    #[cfg_attr(not(test), allow(dead_code))]
    fn store(self, a: &mut [f32]);
    /// `self + o`.
    fn add(self, o: Self) -> Self;
    /// `self - o`.
    fn sub(self, o: Self) -> Self;
    /// `self * o`.
    fn mul(self, o: Self) -> Self;
    /// `self / o`.
    fn div(self, o: Self) -> Self;
    /// `self` where `self < o`, else `o` (`minps`).
    fn min(self, o: Self) -> Self;
    /// `self` where `self > o`, else `o` (`maxps`).
    fn max(self, o: Self) -> Self;
    /// `|self|` (clears the sign bit).
    fn abs(self) -> Self;
    /// `self < o`.
    fn lt(self, o: Self) -> Self::Mask;
    /// `self <= o`.
    fn le(self, o: Self) -> Self::Mask;
    /// `self > o`.
    fn gt(self, o: Self) -> Self::Mask;
    /// `self == o`.
    fn eq(self, o: Self) -> Self::Mask;
    /// `a & b`.
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `a | b`.
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// `a` where `m`, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// Bit `k` set for a true lane `k`.
    fn bits(m: Self::Mask) -> u32;

    // issue 24: the mask operations the kD traversal's interval step needs, so the step is
    // written once over `Wide` for one lane (`f32`), four (`F32x4`) and the wide types.
    /// `a & !b`.
    fn andnot(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Mask `a` where `m`, else `b`.
    fn select_mask(m: Self::Mask, a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// No lane set.
    fn none() -> Self::Mask;
    /// Every lane set.
    fn all() -> Self::Mask;
    // end issue 24
    // issue 23: square roots and stride-3 (`Vec3` row) columns.
    /// `√self` (IEEE, correctly rounded: `f32::sqrt`).
    fn sqrt(self) -> Self;
    /// Lane `l` of component `k` is `rows[3l + k]`: [`Wide::LANES`] `Vec3` rows as x, y and z
    /// (`rows` has at least `3 ·` [`Wide::LANES`] elements).
    fn load3(rows: &[f32]) -> [Self; 3];
    /// The inverse of [`Wide::load3`]: lane `l` of component `k` to `rows[3l + k]`.
    fn store3(v: [Self; 3], rows: &mut [f32]);
    // issue 25: lane counting for the kD builder's small nodes.
    /// `self + x` where `m`, else `self + 0.0` (`self` but for `-0.0`): counts kept as exact
    /// small integers in `f32` lanes.
    #[inline(always)]
    fn add_where(self, m: Self::Mask, x: Self) -> Self {
        self.add(Self::select(m, x, Self::splat(0.0)))
    }
}

/// A kernel generic over the lane type: [`dispatch_wide`] runs it with the widest [`Wide`] the
/// level allows. Implementations must mark [`WideKernel::run`] and everything in its hot loop
/// `#[inline(always)]` (see [`Kernel`]).
pub(crate) trait WideKernel {
    /// What the kernel returns.
    type Output;
    /// The body over lanes `V`.
    fn run<V: Wide>(self) -> Self::Output;
}

/// `a · b` on lanes, as glam's `Vec3::dot` evaluates it (`(x·x′ + y·y′) + z·z′`, so each lane
/// has the scalar dot's bits).
#[inline(always)]
pub(crate) fn dot3<V: Wide>(a: [V; 3], b: [V; 3]) -> V {
    a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]))
}

/// Runs `kernel` with 16 AVX-512 lanes, 8 AVX2 lanes or 8 portable lanes: the best `level` (or
/// the best supported level below it) allows.
#[inline]
pub(crate) fn dispatch_wide<K: WideKernel>(level: Level, kernel: K) -> K::Output {
    dispatch(level, ByLevel(kernel))
}

/// The [`Kernel`] that maps a level to its lanes (private: only [`dispatch`] calls its `run`,
/// with a level the CPU supports).
struct ByLevel<K>(K);

impl<K: WideKernel> Kernel for ByLevel<K> {
    type Output = K::Output;

    #[inline(always)]
    fn run(self, level: Level) -> K::Output {
        match level {
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => self.0.run::<x86::F32x16>(),
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => self.0.run::<x86::F32x8>(),
            _ => self.0.run::<Portable8>(),
        }
    }
}

/// Two [`Wide`] values side by side as one of twice the lanes (at most 32: the mask bits fit a
/// `u32`): lanes `0..V::LANES` in the first, the rest in the second. Each operation is the
/// operation of `V` on both halves, so it has the same per-lane semantics.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pair<V>(V, V);

impl<V: Wide> Wide for Pair<V> {
    const LANES: usize = 2 * V::LANES;
    type Mask = (V::Mask, V::Mask);
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Pair(V::splat(x), V::splat(x))
    }
    #[inline(always)]
    fn load(a: &[f32]) -> Self {
        Pair(V::load(a), V::load(&a[V::LANES..]))
    }
    #[inline(always)]
    fn store(self, a: &mut [f32]) {
        self.0.store(a);
        self.1.store(&mut a[V::LANES..]);
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Pair(self.0.add(o.0), self.1.add(o.1))
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Pair(self.0.sub(o.0), self.1.sub(o.1))
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Pair(self.0.mul(o.0), self.1.mul(o.1))
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        Pair(self.0.div(o.0), self.1.div(o.1))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        Pair(self.0.min(o.0), self.1.min(o.1))
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Pair(self.0.max(o.0), self.1.max(o.1))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Pair(self.0.abs(), self.1.abs())
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self::Mask {
        (self.0.lt(o.0), self.1.lt(o.1))
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self::Mask {
        (self.0.le(o.0), self.1.le(o.1))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self::Mask {
        (self.0.gt(o.0), self.1.gt(o.1))
    }
    #[inline(always)]
    fn eq(self, o: Self) -> Self::Mask {
        (self.0.eq(o.0), self.1.eq(o.1))
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        (V::and(a.0, b.0), V::and(a.1, b.1))
    }
    #[inline(always)]
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        (V::or(a.0, b.0), V::or(a.1, b.1))
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        Pair(V::select(m.0, a.0, b.0), V::select(m.1, a.1, b.1))
    }
    #[inline(always)]
    fn bits(m: Self::Mask) -> u32 {
        V::bits(m.0) | V::bits(m.1) << V::LANES
    }
    // issue 24
    #[inline(always)]
    fn andnot(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        (V::andnot(a.0, b.0), V::andnot(a.1, b.1))
    }
    #[inline(always)]
    fn select_mask(m: Self::Mask, a: Self::Mask, b: Self::Mask) -> Self::Mask {
        (V::select_mask(m.0, a.0, b.0), V::select_mask(m.1, a.1, b.1))
    }
    #[inline(always)]
    fn none() -> Self::Mask {
        (V::none(), V::none())
    }
    #[inline(always)]
    fn all() -> Self::Mask {
        (V::all(), V::all())
    }
    // issue 23
    #[inline(always)]
    fn sqrt(self) -> Self {
        Pair(self.0.sqrt(), self.1.sqrt())
    }
    #[inline(always)]
    fn load3(rows: &[f32]) -> [Self; 3] {
        let (a, b) = (V::load3(rows), V::load3(&rows[3 * V::LANES..]));
        [Pair(a[0], b[0]), Pair(a[1], b[1]), Pair(a[2], b[2])]
    }
    #[inline(always)]
    fn store3(v: [Self; 3], rows: &mut [f32]) {
        V::store3([v[0].0, v[1].0, v[2].0], rows);
        V::store3([v[0].1, v[1].1, v[2].1], &mut rows[3 * V::LANES..]);
    }
}

/// Eight lanes in an array, each operation a scalar loop (the portable path).
#[derive(Clone, Copy, Debug)]
struct Portable8([f32; 8]);

impl Portable8 {
    #[inline(always)]
    fn map(self, o: Portable8, f: impl Fn(f32, f32) -> f32) -> Portable8 {
        Portable8(std::array::from_fn(|k| f(self.0[k], o.0[k])))
    }

    #[inline(always)]
    fn test(self, o: Portable8, f: impl Fn(f32, f32) -> bool) -> u32 {
        let mut m = 0;
        for k in 0..8 {
            m |= (f(self.0[k], o.0[k]) as u32) << k;
        }
        m
    }
}

impl Wide for Portable8 {
    const LANES: usize = 8;
    type Mask = u32;
    #[inline(always)]
    fn splat(x: f32) -> Portable8 {
        Portable8([x; 8])
    }
    #[inline(always)]
    fn load(a: &[f32]) -> Portable8 {
        Portable8(std::array::from_fn(|k| a[k]))
    }
    #[inline(always)]
    fn store(self, a: &mut [f32]) {
        a[..8].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn add(self, o: Portable8) -> Portable8 {
        self.map(o, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, o: Portable8) -> Portable8 {
        self.map(o, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, o: Portable8) -> Portable8 {
        self.map(o, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, o: Portable8) -> Portable8 {
        self.map(o, |a, b| a / b)
    }
    #[inline(always)]
    fn min(self, o: Portable8) -> Portable8 {
        self.map(o, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn max(self, o: Portable8) -> Portable8 {
        self.map(o, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn abs(self) -> Portable8 {
        Portable8(self.0.map(f32::abs))
    }
    #[inline(always)]
    fn lt(self, o: Portable8) -> u32 {
        self.test(o, |a, b| a < b)
    }
    #[inline(always)]
    fn le(self, o: Portable8) -> u32 {
        self.test(o, |a, b| a <= b)
    }
    #[inline(always)]
    fn gt(self, o: Portable8) -> u32 {
        self.test(o, |a, b| a > b)
    }
    #[inline(always)]
    fn eq(self, o: Portable8) -> u32 {
        self.test(o, |a, b| a == b)
    }
    #[inline(always)]
    fn and(a: u32, b: u32) -> u32 {
        a & b
    }
    #[inline(always)]
    fn or(a: u32, b: u32) -> u32 {
        a | b
    }
    #[inline(always)]
    fn select(m: u32, a: Portable8, b: Portable8) -> Portable8 {
        Portable8(std::array::from_fn(|k| {
            if m & (1 << k) != 0 { a.0[k] } else { b.0[k] }
        }))
    }
    #[inline(always)]
    fn bits(m: u32) -> u32 {
        m
    }
    // issue 24
    #[inline(always)]
    fn andnot(a: u32, b: u32) -> u32 {
        a & !b
    }
    #[inline(always)]
    fn select_mask(m: u32, a: u32, b: u32) -> u32 {
        (a & m) | (b & !m)
    }
    #[inline(always)]
    fn none() -> u32 {
        0
    }
    #[inline(always)]
    fn all() -> u32 {
        0xff
    }
    // issue 23
    #[inline(always)]
    fn sqrt(self) -> Portable8 {
        Portable8(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn load3(rows: &[f32]) -> [Portable8; 3] {
        let rows = &rows[..24];
        std::array::from_fn(|k| Portable8(std::array::from_fn(|l| rows[3 * l + k])))
    }
    #[inline(always)]
    fn store3(v: [Portable8; 3], rows: &mut [f32]) {
        let rows = &mut rows[..24];
        for l in 0..8 {
            for k in 0..3 {
                rows[3 * l + k] = v[k].0[l];
            }
        }
    }
}

// issue 24: one lane, so the single-ray loop's interval step is the lanes' formula.
/// One lane: the plain scalar operations (`min`/`max` with `minps`/`maxps` semantics, see
/// [`super::min_ps`]); the mask is a `bool`.
impl Wide for f32 {
    const LANES: usize = 1;
    type Mask = bool;
    #[inline(always)]
    fn splat(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn load(a: &[f32]) -> f32 {
        a[0]
    }
    #[inline(always)]
    fn store(self, a: &mut [f32]) {
        a[0] = self;
    }
    #[inline(always)]
    fn add(self, o: f32) -> f32 {
        self + o
    }
    #[inline(always)]
    fn sub(self, o: f32) -> f32 {
        self - o
    }
    #[inline(always)]
    fn mul(self, o: f32) -> f32 {
        self * o
    }
    #[inline(always)]
    fn div(self, o: f32) -> f32 {
        self / o
    }
    #[inline(always)]
    fn min(self, o: f32) -> f32 {
        super::min_ps(self, o)
    }
    #[inline(always)]
    fn max(self, o: f32) -> f32 {
        super::max_ps(self, o)
    }
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
    #[inline(always)]
    fn lt(self, o: f32) -> bool {
        self < o
    }
    #[inline(always)]
    fn le(self, o: f32) -> bool {
        self <= o
    }
    #[inline(always)]
    fn gt(self, o: f32) -> bool {
        self > o
    }
    #[inline(always)]
    fn eq(self, o: f32) -> bool {
        self == o
    }
    #[inline(always)]
    fn and(a: bool, b: bool) -> bool {
        a & b
    }
    #[inline(always)]
    fn or(a: bool, b: bool) -> bool {
        a | b
    }
    #[inline(always)]
    fn select(m: bool, a: f32, b: f32) -> f32 {
        if m { a } else { b }
    }
    #[inline(always)]
    fn bits(m: bool) -> u32 {
        m as u32
    }
    #[inline(always)]
    fn andnot(a: bool, b: bool) -> bool {
        a & !b
    }
    #[inline(always)]
    fn select_mask(m: bool, a: bool, b: bool) -> bool {
        if m { a } else { b }
    }
    #[inline(always)]
    fn none() -> bool {
        false
    }
    #[inline(always)]
    fn all() -> bool {
        true
    }
    // issue 23
    #[inline(always)]
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn load3(rows: &[f32]) -> [f32; 3] {
        [rows[0], rows[1], rows[2]]
    }
    #[inline(always)]
    fn store3(v: [f32; 3], rows: &mut [f32]) {
        rows[..3].copy_from_slice(&v);
    }
}
// end issue 24

#[cfg(target_arch = "x86_64")]
mod x86 {
    //! The AVX2 and AVX-512 lanes. Every `unsafe` block below calls an intrinsic of the
    //! feature its type is for; the types are reachable only through `dispatch_wide`, inside
    //! functions compiled for those features and entered only after the CPU was checked (see
    //! the module docs), which is the one condition the intrinsics need. Loads and stores check
    //! the slice length first.
    use std::arch::x86_64::*;

    use super::Wide;

    /// Eight lanes in one AVX register.
    #[derive(Clone, Copy, Debug)]
    pub(super) struct F32x8(__m256);

    impl Wide for F32x8 {
        const LANES: usize = 8;
        type Mask = __m256;
        #[inline(always)]
        fn splat(x: f32) -> F32x8 {
            // SAFETY: AVX2 is available (module docs); no memory access.
            F32x8(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn load(a: &[f32]) -> F32x8 {
            let a = &a[..8];
            // SAFETY: AVX2 is available; `a` holds 8 floats (unaligned load).
            F32x8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn store(self, a: &mut [f32]) {
            let a = &mut a[..8];
            // SAFETY: AVX2 is available; `a` holds 8 floats (unaligned store).
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn add(self, o: F32x8) -> F32x8 {
            // SAFETY: AVX2 is available; no memory access.
            F32x8(unsafe { _mm256_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn sub(self, o: F32x8) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul(self, o: F32x8) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn div(self, o: F32x8) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn min(self, o: F32x8) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: F32x8) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn lt(self, o: F32x8) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn le(self, o: F32x8) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn gt(self, o: F32x8) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn eq(self, o: F32x8) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn and(a: __m256, b: __m256) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_and_ps(a, b) }
        }
        #[inline(always)]
        fn or(a: __m256, b: __m256) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_or_ps(a, b) }
        }
        #[inline(always)]
        fn select(m: __m256, a: F32x8, b: F32x8) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_blendv_ps(b.0, a.0, m) })
        }
        #[inline(always)]
        fn bits(m: __m256) -> u32 {
            // SAFETY: as `add`.
            unsafe { _mm256_movemask_ps(m) as u32 }
        }
        // issue 24
        #[inline(always)]
        fn andnot(a: __m256, b: __m256) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_andnot_ps(b, a) }
        }
        #[inline(always)]
        fn select_mask(m: __m256, a: __m256, b: __m256) -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_blendv_ps(b, a, m) }
        }
        #[inline(always)]
        fn none() -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_setzero_ps() }
        }
        #[inline(always)]
        fn all() -> __m256 {
            // SAFETY: as `add`.
            unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(-1)) }
        }
        // issue 23
        #[inline(always)]
        fn sqrt(self) -> F32x8 {
            // SAFETY: as `add`.
            F32x8(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn load3(rows: &[f32]) -> [F32x8; 3] {
            let rows = &rows[..24];
            let p = rows.as_ptr();
            // SAFETY: AVX2 is available; `rows` holds 24 floats: three unaligned 8-float loads
            // at 0, 8 and 16, then register shuffles.
            unsafe {
                let abc = [
                    _mm256_loadu_ps(p),
                    _mm256_loadu_ps(p.add(8)),
                    _mm256_loadu_ps(p.add(16)),
                ];
                let [x, y, z] = super::super::shuffle3::deinterleave_regs(abc);
                [F32x8(x), F32x8(y), F32x8(z)]
            }
        }
        #[inline(always)]
        fn store3(v: [F32x8; 3], rows: &mut [f32]) {
            let rows = &mut rows[..24];
            let p = rows.as_mut_ptr();
            // SAFETY: AVX2 is available; register shuffles, then three unaligned 8-float
            // stores at 0, 8 and 16 of the 24 floats `rows` holds.
            unsafe {
                let abc = super::super::shuffle3::interleave_regs([v[0].0, v[1].0, v[2].0]);
                _mm256_storeu_ps(p, abc[0]);
                _mm256_storeu_ps(p.add(8), abc[1]);
                _mm256_storeu_ps(p.add(16), abc[2]);
            }
        }
    }

    /// Sixteen lanes in one AVX-512 register.
    #[derive(Clone, Copy, Debug)]
    pub(super) struct F32x16(__m512);

    impl Wide for F32x16 {
        const LANES: usize = 16;
        type Mask = __mmask16;
        #[inline(always)]
        fn splat(x: f32) -> F32x16 {
            // SAFETY: AVX-512F is available (module docs); no memory access.
            F32x16(unsafe { _mm512_set1_ps(x) })
        }
        #[inline(always)]
        fn load(a: &[f32]) -> F32x16 {
            let a = &a[..16];
            // SAFETY: AVX-512F is available; `a` holds 16 floats (unaligned load).
            F32x16(unsafe { _mm512_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn store(self, a: &mut [f32]) {
            let a = &mut a[..16];
            // SAFETY: AVX-512F is available; `a` holds 16 floats (unaligned store).
            unsafe { _mm512_storeu_ps(a.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn add(self, o: F32x16) -> F32x16 {
            // SAFETY: AVX-512F is available; no memory access.
            F32x16(unsafe { _mm512_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn sub(self, o: F32x16) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul(self, o: F32x16) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn div(self, o: F32x16) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn min(self, o: F32x16) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: F32x16) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_abs_ps(self.0) })
        }
        #[inline(always)]
        fn lt(self, o: F32x16) -> __mmask16 {
            // SAFETY: as `add`.
            unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn le(self, o: F32x16) -> __mmask16 {
            // SAFETY: as `add`.
            unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn gt(self, o: F32x16) -> __mmask16 {
            // SAFETY: as `add`.
            unsafe { _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn eq(self, o: F32x16) -> __mmask16 {
            // SAFETY: as `add`.
            unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        fn and(a: __mmask16, b: __mmask16) -> __mmask16 {
            a & b
        }
        #[inline(always)]
        fn or(a: __mmask16, b: __mmask16) -> __mmask16 {
            a | b
        }
        #[inline(always)]
        fn select(m: __mmask16, a: F32x16, b: F32x16) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_mask_blend_ps(m, b.0, a.0) })
        }
        #[inline(always)]
        fn bits(m: __mmask16) -> u32 {
            m as u32
        }
        // issue 24
        #[inline(always)]
        fn andnot(a: __mmask16, b: __mmask16) -> __mmask16 {
            a & !b
        }
        #[inline(always)]
        fn select_mask(m: __mmask16, a: __mmask16, b: __mmask16) -> __mmask16 {
            (a & m) | (b & !m)
        }
        #[inline(always)]
        fn none() -> __mmask16 {
            0
        }
        #[inline(always)]
        fn all() -> __mmask16 {
            0xffff
        }
        // issue 23
        #[inline(always)]
        fn sqrt(self) -> F32x16 {
            // SAFETY: as `add`.
            F32x16(unsafe { _mm512_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn load3(rows: &[f32]) -> [F32x16; 3] {
            let rows = &rows[..48];
            let p = rows.as_ptr();
            // SAFETY: AVX-512F is available; `rows` holds 48 floats: three unaligned 16-float
            // loads at 0, 16 and 32, then two-source permutes ([`GATHER3`]).
            unsafe {
                let (a, b, c) = (
                    _mm512_loadu_ps(p),
                    _mm512_loadu_ps(p.add(16)),
                    _mm512_loadu_ps(p.add(32)),
                );
                let mut out = [F32x16(a); 3];
                for (o, [ab, abc]) in out.iter_mut().zip(&GATHER3) {
                    let ab = _mm512_loadu_si512(ab.as_ptr().cast());
                    let abc = _mm512_loadu_si512(abc.as_ptr().cast());
                    *o = F32x16(_mm512_permutex2var_ps(
                        _mm512_permutex2var_ps(a, ab, b),
                        abc,
                        c,
                    ));
                }
                out
            }
        }
        #[inline(always)]
        fn store3(v: [F32x16; 3], rows: &mut [f32]) {
            let rows = &mut rows[..48];
            let p = rows.as_mut_ptr();
            // SAFETY: AVX-512F is available; two-source permutes ([`SCATTER3`]), then three
            // unaligned 16-float stores at 0, 16 and 32 of the 48 floats `rows` holds.
            unsafe {
                for (o, [xy, xyz]) in SCATTER3.iter().enumerate() {
                    let xy = _mm512_loadu_si512(xy.as_ptr().cast());
                    let xyz = _mm512_loadu_si512(xyz.as_ptr().cast());
                    let r = _mm512_permutex2var_ps(
                        _mm512_permutex2var_ps(v[0].0, xy, v[1].0),
                        xyz,
                        v[2].0,
                    );
                    _mm512_storeu_ps(p.add(16 * o), r);
                }
            }
        }
    }

    /// [`F32x16::load3`]'s permute indices, per component `k`: lane `l` wants row float
    /// `e = 3l + k` of the 48 (`a` 0–15, `b` 16–31, `c` 32–47). The first permute of `a`
    /// and `b` puts `e` in lane `l` when `e < 32`; the second keeps those lanes and takes the
    /// others from `c` (index `16 + e − 32`).
    const GATHER3: [[[i32; 16]; 2]; 3] = {
        let mut t = [[[0; 16]; 2]; 3];
        let mut k = 0;
        while k < 3 {
            let mut l = 0;
            while l < 16 {
                let e = 3 * l + k;
                if e < 32 {
                    t[k][0][l] = e as i32;
                    t[k][1][l] = l as i32;
                } else {
                    t[k][1][l] = (16 + e - 32) as i32;
                }
                l += 1;
            }
            k += 1;
        }
        t
    };

    /// [`F32x16::store3`]'s permute indices, per output vector `o`: its float `p` is row float
    /// `e = 16·o + p`, lane `e / 3` of component `e % 3`. The first permute of x and y puts the
    /// x and y floats in place; the second keeps them and takes z's from z (index `16 + l`).
    const SCATTER3: [[[i32; 16]; 2]; 3] = {
        let mut t = [[[0; 16]; 2]; 3];
        let mut o = 0;
        while o < 3 {
            let mut p = 0;
            while p < 16 {
                let e = 16 * o + p;
                let (l, k) = (e / 3, e % 3);
                t[o][0][p] = if k == 1 { 16 + l as i32 } else { l as i32 };
                t[o][1][p] = if k == 2 { 16 + l as i32 } else { p as i32 };
                p += 1;
            }
            o += 1;
        }
        t
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every operation of every supported width against the scalar operations, on values with
    /// NaN, infinities, signed zeros and ties.
    struct Check;

    impl WideKernel for Check {
        type Output = usize;
        #[inline(always)]
        fn run<V: Wide>(self) -> usize {
            let special = [
                0.0f32,
                -0.0,
                1.0,
                -1.0,
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                1e-30,
                3.5,
                -2.25,
                f32::MAX,
                f32::MIN_POSITIVE,
                7.0,
                1.0,
                -0.0,
                2.0,
            ];
            let n = V::LANES;
            for shift in 0..special.len() {
                // (Lanes past 16, of a `Pair`, get other pairs of values than the first 16.)
                let a: Vec<f32> = (0..n)
                    .map(|k| special[(k + shift + k / 16 * 5) % 16])
                    .collect();
                let b: Vec<f32> = (0..n)
                    .map(|k| special[(3 * k + 1 + k / 16 * 7) % 16])
                    .collect();
                let (va, vb) = (V::load(&a), V::load(&b));
                let mut out = vec![0.0; n];
                let check = |v: V, f: &dyn Fn(f32, f32) -> f32, out: &mut Vec<f32>| {
                    v.store(out);
                    for k in 0..n {
                        let want = f(a[k], b[k]);
                        assert!(
                            out[k].to_bits() == want.to_bits() || out[k].is_nan() && want.is_nan(),
                            "lane {k}: {} vs {want} for {} and {}",
                            out[k],
                            a[k],
                            b[k]
                        );
                    }
                };
                check(va.add(vb), &|x, y| x + y, &mut out);
                check(va.sub(vb), &|x, y| x - y, &mut out);
                check(va.mul(vb), &|x, y| x * y, &mut out);
                check(va.div(vb), &|x, y| x / y, &mut out);
                check(va.min(vb), &|x, y| if x < y { x } else { y }, &mut out);
                check(va.max(vb), &|x, y| if x > y { x } else { y }, &mut out);
                check(va.abs(), &|x, _| x.abs(), &mut out);
                let lt = V::lt(va, vb);
                check(
                    V::select(lt, va, vb),
                    &|x, y| if x < y { x } else { y },
                    &mut out,
                );
                let mask = |f: &dyn Fn(f32, f32) -> bool| {
                    (0..n).fold(0u32, |m, k| m | (f(a[k], b[k]) as u32) << k)
                };
                assert_eq!(V::bits(V::lt(va, vb)), mask(&|x, y| x < y));
                assert_eq!(V::bits(V::le(va, vb)), mask(&|x, y| x <= y));
                assert_eq!(V::bits(V::gt(va, vb)), mask(&|x, y| x > y));
                assert_eq!(V::bits(V::eq(va, vb)), mask(&|x, y| x == y));
                assert_eq!(
                    V::bits(V::and(V::lt(va, vb), V::eq(va, va))),
                    mask(&|x, y| x < y && !x.is_nan())
                );
                assert_eq!(
                    V::bits(V::or(V::lt(va, vb), V::gt(va, vb))),
                    mask(&|x, y| x.partial_cmp(&y).is_some_and(|o| o.is_ne()))
                );
                check(V::splat(a[0]), &|_, _| a[0], &mut out);
                // issue 24: the mask operations.
                let (lt, gt, eq) = (V::lt(va, vb), V::gt(va, vb), V::eq(va, vb));
                assert_eq!(V::bits(V::andnot(lt, eq)), mask(&|x, y| x < y && x != y));
                assert_eq!(
                    V::bits(V::select_mask(lt, eq, gt)),
                    mask(&|x, y| if x < y { x == y } else { x > y })
                );
                assert_eq!(V::bits(V::none()), 0);
                assert_eq!(V::bits(V::all()), mask(&|_, _| true));
                assert_eq!(
                    V::bits(V::andnot(V::all(), lt)),
                    mask(&|x, y| x >= y || x.is_nan() || y.is_nan())
                );
                // issue 23
                check(va.sqrt(), &|x, _| x.sqrt(), &mut out);
            }
            // issue 23: stride-3 rows to x, y, z lanes and back, every float distinct.
            let rows: Vec<f32> = (0..3 * n).map(|e| e as f32 + 0.5).collect();
            let xyz = V::load3(&rows);
            for (k, v) in xyz.iter().enumerate() {
                let mut out = vec![0.0; n];
                v.store(&mut out);
                let want: Vec<f32> = (0..n).map(|l| rows[3 * l + k]).collect();
                assert_eq!(out, want, "component {k} of {n} lanes");
            }
            let mut back = vec![-1.0; 3 * n + 1];
            V::store3(xyz, &mut back);
            assert_eq!(&back[..3 * n], rows.as_slice(), "rows of {n} lanes");
            assert_eq!(back[3 * n], -1.0, "wrote past {n} rows");
            n
        }
    }

    #[test]
    fn every_width_computes_the_scalar_bits() {
        for level in Level::supported() {
            let lanes = dispatch_wide(level, Check);
            let want = match level {
                Level::Avx512 => 16,
                _ => 8,
            };
            assert_eq!(lanes, want, "{level:?}");
        }
    }

    // issue 24
    #[test]
    fn one_and_four_lanes_compute_the_scalar_bits() {
        assert_eq!(Check.run::<f32>(), 1);
        assert_eq!(Check.run::<super::super::F32x4>(), 4);
    }

    /// [`Check`] over [`Pair`]s of the level's lanes.
    struct PairCheck;

    impl WideKernel for PairCheck {
        type Output = usize;
        #[inline(always)]
        fn run<V: Wide>(self) -> usize {
            Check.run::<Pair<V>>()
        }
    }

    #[test]
    fn pairs_compute_the_scalar_bits_at_twice_the_width() {
        for level in Level::supported() {
            let lanes = dispatch_wide(level, PairCheck);
            let want = match level {
                Level::Avx512 => 32,
                _ => 16,
            };
            assert_eq!(lanes, want, "{level:?}");
        }
    }
}
