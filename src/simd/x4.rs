//! Four `f32` lanes ([`F32x4`]) and a lane mask ([`M32x4`]) with SSE2 semantics, for the kD
//! tree's packet traversal.
//!
//! Reads and writes nothing but its arguments. Every operation is a safe method with exactly the
//! semantics of one SSE2 instruction (`minps`, `cmpltps`, ...), so a formula written once over
//! lanes gives the same bits on every lane as the same formula on scalars with the same
//! operation semantics (see the kD traversal's `interval` step). Arithmetic is plain IEEE
//! (no fused multiply-add), lane by lane.
//!
//! On `x86_64` (where SSE2 is part of the baseline, so every intrinsic is always available) the
//! types wrap `__m128`; elsewhere they are arrays with the same semantics, written out in
//! `portable` (also compiled in tests on `x86_64` and checked against the SSE2 version).
#![allow(unsafe_code)]

#[cfg(target_arch = "x86_64")]
pub(crate) use sse2::{F32x4, M32x4};

#[cfg(not(target_arch = "x86_64"))]
pub(crate) use portable::{F32x4, M32x4};

/// `min` with `minps` semantics: `a` if `a < b`, else `b` (so a NaN operand yields `b`, and
/// `min(-0.0, 0.0)` is `0.0`). [`f32::min`] differs only for a NaN operand and a zero's sign.
#[inline(always)]
pub(crate) fn min_ps(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// `max` with `maxps` semantics: `a` if `a > b`, else `b`.
#[inline(always)]
pub(crate) fn max_ps(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

#[cfg(target_arch = "x86_64")]
mod sse2 {
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

    /// Four `f32` lanes in one SSE register.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(crate) struct F32x4(__m128);

    /// A per-lane mask: all bits set (true) or clear (false) in each lane, as SSE2 comparisons
    /// produce.
    #[derive(Clone, Copy, Debug)]
    #[repr(transparent)]
    pub(crate) struct M32x4(__m128);

    impl F32x4 {
        /// All lanes `x`.
        #[inline(always)]
        pub(crate) fn splat(x: f32) -> F32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            F32x4(unsafe { _mm_set1_ps(x) })
        }

        /// Lane `k` is `a[k]`.
        #[inline(always)]
        pub(crate) fn from_array(a: &[f32; 4]) -> F32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; unaligned load of the 4 floats
            // behind a valid `&[f32; 4]`.
            F32x4(unsafe { _mm_loadu_ps(a.as_ptr()) })
        }

        /// The lanes as an array.
        #[inline(always)]
        pub(crate) fn to_array(self) -> [f32; 4] {
            let mut out = [0.0f32; 4];
            // SAFETY: SSE2 is part of the x86_64 baseline; unaligned store of 4 floats into a
            // local `[f32; 4]`.
            unsafe { _mm_storeu_ps(out.as_mut_ptr(), self.0) };
            out
        }

        /// Lane-wise `minps`: `self` where `self < o`, else `o`.
        #[inline(always)]
        pub(crate) fn min(self, o: F32x4) -> F32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            F32x4(unsafe { _mm_min_ps(self.0, o.0) })
        }

        /// Lane-wise `maxps`: `self` where `self > o`, else `o`.
        #[inline(always)]
        pub(crate) fn max(self, o: F32x4) -> F32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            F32x4(unsafe { _mm_max_ps(self.0, o.0) })
        }

        /// Lane-wise `self < o` (false for NaN).
        #[inline(always)]
        pub(crate) fn lt(self, o: F32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_cmplt_ps(self.0, o.0) })
        }

        /// Lane-wise `self <= o` (false for NaN).
        #[inline(always)]
        pub(crate) fn le(self, o: F32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_cmple_ps(self.0, o.0) })
        }

        /// Lane-wise `self > o` (false for NaN).
        #[inline(always)]
        pub(crate) fn gt(self, o: F32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_cmpgt_ps(self.0, o.0) })
        }

        /// Lane-wise `self == o` (false for NaN).
        #[inline(always)]
        pub(crate) fn eq(self, o: F32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_cmpeq_ps(self.0, o.0) })
        }

        /// Lane-wise `|self|` (clears the sign bit).
        #[inline(always)]
        pub(crate) fn abs(self) -> F32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            F32x4(unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), self.0) })
        }
    }

    macro_rules! arith {
        ($tr:ident, $f:ident, $op:ident) => {
            impl $tr for F32x4 {
                type Output = F32x4;
                /// Lane-wise IEEE operation.
                #[inline(always)]
                fn $f(self, o: F32x4) -> F32x4 {
                    // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
                    F32x4(unsafe { $op(self.0, o.0) })
                }
            }
        };
    }
    arith!(Add, add, _mm_add_ps);
    arith!(Sub, sub, _mm_sub_ps);
    arith!(Mul, mul, _mm_mul_ps);
    arith!(Div, div, _mm_div_ps);

    impl M32x4 {
        /// Lanes of `self` that are not in `o` (`self & !o`, one `andnps`).
        #[inline(always)]
        pub(crate) fn and_not(self, o: M32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_andnot_ps(o.0, self.0) })
        }

        /// No lane set.
        #[inline(always)]
        pub(crate) fn none() -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_setzero_ps() })
        }

        /// Every lane set.
        #[inline(always)]
        pub(crate) fn all() -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_castsi128_ps(_mm_set1_epi32(-1)) })
        }

        /// `a` in the lanes of `self`, `b` elsewhere, as `b ^ ((a ^ b) & self)` (the same bits
        /// as and/andnot/or; the xor form lets nested selects sharing `b` fold).
        #[inline(always)]
        pub(crate) fn select(self, a: F32x4, b: F32x4) -> F32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            F32x4(unsafe { _mm_xor_ps(b.0, _mm_and_ps(_mm_xor_ps(a.0, b.0), self.0)) })
        }

        /// Mask `a` in the lanes of `self`, `b` elsewhere (as [`M32x4::select`]).
        #[inline(always)]
        pub(crate) fn select_mask(self, a: M32x4, b: M32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_xor_ps(b.0, _mm_and_ps(_mm_xor_ps(a.0, b.0), self.0)) })
        }

        /// Bit `k` set when lane `k` is set (`movmskps`).
        #[inline(always)]
        pub(crate) fn bits(self) -> u8 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            (unsafe { _mm_movemask_ps(self.0) }) as u8
        }
    }

    impl BitAnd for M32x4 {
        type Output = M32x4;
        /// Lanes in both.
        #[inline(always)]
        fn bitand(self, o: M32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_and_ps(self.0, o.0) })
        }
    }

    impl BitOr for M32x4 {
        type Output = M32x4;
        /// Lanes in either.
        #[inline(always)]
        fn bitor(self, o: M32x4) -> M32x4 {
            // SAFETY: SSE2 is part of the x86_64 baseline; no memory access.
            M32x4(unsafe { _mm_or_ps(self.0, o.0) })
        }
    }
}

// issue 24: four lanes in the one lane vocabulary, so the packet loop's step is the same
// generic code as the single ray's and the frusta's.
impl super::Wide for F32x4 {
    const LANES: usize = 4;
    type Mask = M32x4;
    #[inline(always)]
    fn splat(x: f32) -> F32x4 {
        F32x4::splat(x)
    }
    #[inline(always)]
    fn load(a: &[f32]) -> F32x4 {
        F32x4::from_array(&[a[0], a[1], a[2], a[3]])
    }
    #[inline(always)]
    fn store(self, a: &mut [f32]) {
        a[..4].copy_from_slice(&self.to_array());
    }
    #[inline(always)]
    fn add(self, o: F32x4) -> F32x4 {
        self + o
    }
    #[inline(always)]
    fn sub(self, o: F32x4) -> F32x4 {
        self - o
    }
    #[inline(always)]
    fn mul(self, o: F32x4) -> F32x4 {
        self * o
    }
    #[inline(always)]
    fn div(self, o: F32x4) -> F32x4 {
        self / o
    }
    #[inline(always)]
    fn min(self, o: F32x4) -> F32x4 {
        F32x4::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: F32x4) -> F32x4 {
        F32x4::max(self, o)
    }
    #[inline(always)]
    fn abs(self) -> F32x4 {
        F32x4::abs(self)
    }
    #[inline(always)]
    fn lt(self, o: F32x4) -> M32x4 {
        F32x4::lt(self, o)
    }
    #[inline(always)]
    fn le(self, o: F32x4) -> M32x4 {
        F32x4::le(self, o)
    }
    #[inline(always)]
    fn gt(self, o: F32x4) -> M32x4 {
        F32x4::gt(self, o)
    }
    #[inline(always)]
    fn eq(self, o: F32x4) -> M32x4 {
        F32x4::eq(self, o)
    }
    #[inline(always)]
    fn and(a: M32x4, b: M32x4) -> M32x4 {
        a & b
    }
    #[inline(always)]
    fn or(a: M32x4, b: M32x4) -> M32x4 {
        a | b
    }
    #[inline(always)]
    fn select(m: M32x4, a: F32x4, b: F32x4) -> F32x4 {
        m.select(a, b)
    }
    #[inline(always)]
    fn bits(m: M32x4) -> u32 {
        m.bits() as u32
    }
    #[inline(always)]
    fn andnot(a: M32x4, b: M32x4) -> M32x4 {
        a.and_not(b)
    }
    #[inline(always)]
    fn select_mask(m: M32x4, a: M32x4, b: M32x4) -> M32x4 {
        m.select_mask(a, b)
    }
    #[inline(always)]
    fn none() -> M32x4 {
        M32x4::none()
    }
    #[inline(always)]
    fn all() -> M32x4 {
        M32x4::all()
    }
    // issue 23
    #[inline(always)]
    fn sqrt(self) -> F32x4 {
        let a = self.to_array();
        F32x4::from_array(&a.map(f32::sqrt))
    }
    #[inline(always)]
    fn load3(rows: &[f32]) -> [F32x4; 3] {
        let rows = &rows[..12];
        std::array::from_fn(|k| {
            F32x4::from_array(&[rows[k], rows[3 + k], rows[6 + k], rows[9 + k]])
        })
    }
    #[inline(always)]
    fn store3(v: [F32x4; 3], rows: &mut [f32]) {
        let rows = &mut rows[..12];
        for (k, c) in v.iter().enumerate() {
            for (l, x) in c.to_array().into_iter().enumerate() {
                rows[3 * l + k] = x;
            }
        }
    }
}
// end issue 24

/// The lane types as plain arrays, with the SSE2 instructions' semantics (used where SSE2 is not
/// available, and in tests as the specification the SSE2 version is checked against).
#[cfg(any(test, not(target_arch = "x86_64")))]
pub(crate) mod portable {
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

    use super::{max_ps, min_ps};

    /// Four `f32` lanes.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct F32x4(pub(crate) [f32; 4]);

    /// A per-lane mask.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub(crate) struct M32x4(pub(crate) [bool; 4]);

    impl F32x4 {
        /// All lanes `x`.
        #[inline(always)]
        pub(crate) fn splat(x: f32) -> F32x4 {
            F32x4([x; 4])
        }

        /// Lane `k` is `a[k]`.
        #[inline(always)]
        pub(crate) fn from_array(a: &[f32; 4]) -> F32x4 {
            F32x4(*a)
        }

        /// The lanes as an array.
        #[inline(always)]
        pub(crate) fn to_array(self) -> [f32; 4] {
            self.0
        }

        #[inline(always)]
        fn zip(self, o: F32x4, f: impl Fn(f32, f32) -> f32) -> F32x4 {
            F32x4(std::array::from_fn(|k| f(self.0[k], o.0[k])))
        }

        #[inline(always)]
        fn cmp(self, o: F32x4, f: impl Fn(f32, f32) -> bool) -> M32x4 {
            M32x4(std::array::from_fn(|k| f(self.0[k], o.0[k])))
        }

        /// Lane-wise `minps`: `self` where `self < o`, else `o`.
        #[inline(always)]
        pub(crate) fn min(self, o: F32x4) -> F32x4 {
            self.zip(o, min_ps)
        }

        /// Lane-wise `maxps`: `self` where `self > o`, else `o`.
        #[inline(always)]
        pub(crate) fn max(self, o: F32x4) -> F32x4 {
            self.zip(o, max_ps)
        }

        /// Lane-wise `self < o` (false for NaN).
        #[inline(always)]
        pub(crate) fn lt(self, o: F32x4) -> M32x4 {
            self.cmp(o, |a, b| a < b)
        }

        /// Lane-wise `self <= o` (false for NaN).
        #[inline(always)]
        pub(crate) fn le(self, o: F32x4) -> M32x4 {
            self.cmp(o, |a, b| a <= b)
        }

        /// Lane-wise `self > o` (false for NaN).
        #[inline(always)]
        pub(crate) fn gt(self, o: F32x4) -> M32x4 {
            self.cmp(o, |a, b| a > b)
        }

        /// Lane-wise `self == o` (false for NaN).
        #[inline(always)]
        pub(crate) fn eq(self, o: F32x4) -> M32x4 {
            self.cmp(o, |a, b| a == b)
        }

        /// Lane-wise `|self|`.
        #[inline(always)]
        pub(crate) fn abs(self) -> F32x4 {
            F32x4(self.0.map(f32::abs))
        }
    }

    macro_rules! arith {
        ($tr:ident, $f:ident, $op:tt) => {
            impl $tr for F32x4 {
                type Output = F32x4;
                /// Lane-wise IEEE operation.
                #[inline(always)]
                fn $f(self, o: F32x4) -> F32x4 {
                    self.zip(o, |a, b| a $op b)
                }
            }
        };
    }
    arith!(Add, add, +);
    arith!(Sub, sub, -);
    arith!(Mul, mul, *);
    arith!(Div, div, /);

    impl M32x4 {
        /// Lanes of `self` that are not in `o`.
        #[inline(always)]
        pub(crate) fn and_not(self, o: M32x4) -> M32x4 {
            M32x4(std::array::from_fn(|k| self.0[k] && !o.0[k]))
        }

        /// No lane set.
        #[inline(always)]
        pub(crate) fn none() -> M32x4 {
            M32x4([false; 4])
        }

        /// Every lane set.
        #[inline(always)]
        pub(crate) fn all() -> M32x4 {
            M32x4([true; 4])
        }

        /// `a` in the lanes of `self`, `b` elsewhere.
        #[inline(always)]
        pub(crate) fn select(self, a: F32x4, b: F32x4) -> F32x4 {
            F32x4(std::array::from_fn(
                |k| if self.0[k] { a.0[k] } else { b.0[k] },
            ))
        }

        /// Mask `a` in the lanes of `self`, `b` elsewhere.
        #[inline(always)]
        pub(crate) fn select_mask(self, a: M32x4, b: M32x4) -> M32x4 {
            M32x4(std::array::from_fn(
                |k| if self.0[k] { a.0[k] } else { b.0[k] },
            ))
        }

        /// Bit `k` set when lane `k` is set.
        #[inline(always)]
        pub(crate) fn bits(self) -> u8 {
            (0..4).fold(0, |m, k| m | (self.0[k] as u8) << k)
        }
    }

    impl BitAnd for M32x4 {
        type Output = M32x4;
        /// Lanes in both.
        #[inline(always)]
        fn bitand(self, o: M32x4) -> M32x4 {
            M32x4(std::array::from_fn(|k| self.0[k] && o.0[k]))
        }
    }

    impl BitOr for M32x4 {
        type Output = M32x4;
        /// Lanes in either.
        #[inline(always)]
        fn bitor(self, o: M32x4) -> M32x4 {
            M32x4(std::array::from_fn(|k| self.0[k] || o.0[k]))
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::portable as p;
    use super::{F32x4, M32x4};

    const SPECIAL: [f32; 10] = [
        0.0,
        -0.0,
        1.0,
        -1.5,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        f32::MAX,
        1e-40,
        -3.25,
    ];

    fn same(a: F32x4, b: p::F32x4) -> bool {
        a.to_array()
            .iter()
            .zip(b.to_array())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
    }

    #[test]
    fn sse2_lanes_match_the_portable_specification_bit_for_bit() {
        for (i, &x) in SPECIAL.iter().enumerate() {
            for (j, &y) in SPECIAL.iter().enumerate() {
                let xa = [x, y, SPECIAL[(i + j) % 10], SPECIAL[(i * 3 + 1) % 10]];
                let ya = [y, x, SPECIAL[(i + 2 * j) % 10], SPECIAL[(j * 7 + 3) % 10]];
                let (a, b) = (F32x4::from_array(&xa), F32x4::from_array(&ya));
                let (pa, pb) = (p::F32x4::from_array(&xa), p::F32x4::from_array(&ya));
                assert!(same(a + b, pa + pb));
                assert!(same(a - b, pa - pb));
                assert!(same(a * b, pa * pb));
                assert!(same(a / b, pa / pb));
                assert!(same(a.min(b), pa.min(pb)));
                assert!(same(a.max(b), pa.max(pb)));
                assert!(same(a.abs(), pa.abs()));
                let masks: [(M32x4, p::M32x4); 4] = [
                    (a.lt(b), pa.lt(pb)),
                    (a.le(b), pa.le(pb)),
                    (a.gt(b), pa.gt(pb)),
                    (a.eq(b), pa.eq(pb)),
                ];
                for (m, pm) in masks {
                    assert_eq!(m.bits(), pm.bits());
                    assert!(same(m.select(a, b), pm.select(pa, pb)));
                    for (n, pn) in masks {
                        assert_eq!((m & n).bits(), (pm & pn).bits());
                        for (o, po) in masks {
                            assert_eq!(m.select_mask(n, o).bits(), pm.select_mask(pn, po).bits());
                        }
                        assert_eq!((m | n).bits(), (pm | pn).bits());
                        assert_eq!(m.and_not(n).bits(), pm.and_not(pn).bits());
                    }
                }
            }
        }
        assert_eq!(F32x4::splat(2.5).to_array(), [2.5; 4]);
        assert_eq!((M32x4::none().bits(), p::M32x4::none().bits()), (0, 0));
        assert_eq!((M32x4::all().bits(), p::M32x4::all().bits()), (15, 15));
        assert_eq!(p::F32x4::splat(2.5).to_array(), [2.5; 4]);
    }
}
