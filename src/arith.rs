//! Deterministic arithmetic (SPEC §2): the transcendental functions whose values reach a pixel
//! — the specular power, the output gamma, the camera's field of view — built from IEEE-754
//! basic operations (`+ − × ÷`, correctly rounded, no FMA) in an order fixed here, so a scene
//! gives the same bits on every x86-64 CPU, SIMD width and thread count. No platform `libm`:
//! glibc picks a different `powf` by CPU. The workspace's `clippy.toml` keeps `f32::powf`,
//! `f64::tan` and the like out of the core crate (`disallowed_methods`).
//!
//! Reads and writes nothing but its arguments. The f32 functions evaluate in f64 and round once,
//! so each is within one ulp of the exact value (tests check two against the f64 reference).

/// Largest exponent taken by square-and-multiply ([`integer_exponent`]).
pub(crate) const MAX_INTEGER_EXPONENT: u32 = 65_536;

/// `Some(n)` when `p` is an integer `n` in `0..=MAX_INTEGER_EXPONENT` (the specular powers of
/// scene files mostly are), else `None`.
#[inline]
pub(crate) fn integer_exponent(p: f32) -> Option<u32> {
    // The range check first: `as u32` saturates, so only in-range values round-trip.
    let in_range = (0.0..=MAX_INTEGER_EXPONENT as f32).contains(&p);
    (in_range && (p as u32) as f32 == p).then_some(p as u32)
}

/// `x^n` by square-and-multiply in f32 over the bits of `n` from the highest: `x^0 = 1`,
/// `0^n = 0` for `n > 0`. Leading zero bits square 1 into 1, so starting from any higher bit
/// gives the same bits (the lane form relies on it).
#[inline]
pub fn powi(x: f32, n: u32) -> f32 {
    let mut r = 1.0f32;
    let mut bit = match n {
        0 => 0,
        n => 1u32 << (31 - n.leading_zeros()),
    };
    while bit != 0 {
        r *= r;
        if n & bit != 0 {
            r *= x;
        }
        bit >>= 1;
    }
    r
}

/// `x^p` as SPEC §2 defines it: [`powi`] for an integer `p` in `0..=65536`, otherwise
/// `exp2(p · log2(x))` with this module's [`exp2`] and [`log2`] (`0^p = 0` for `p > 0`; a
/// negative `x` gives NaN).
#[inline]
pub(crate) fn pow(x: f32, p: f32) -> f32 {
    match integer_exponent(p) {
        Some(n) => powi(x, n),
        None => exp2(p * log2(x)),
    }
}

const SQRT_2: f64 = std::f64::consts::SQRT_2;
const LOG2_E: f64 = std::f64::consts::LOG2_E;
const LN_2: f64 = std::f64::consts::LN_2;

/// Base-2 logarithm, within one ulp: NaN below 0 (and for NaN), −∞ at ±0, +∞ at +∞.
///
/// `x = 2^e · m` with `m` in `[√2/2, √2)`; `ln m = 2·atanh(s)` with `s = (m − 1)/(m + 1)`,
/// `|s| ≤ 0.172`, summed in f64 to `s^15` (truncation below 1e-12 relative).
pub(crate) fn log2(x: f32) -> f32 {
    if x.is_nan() || x < 0.0 {
        return f32::NAN;
    }
    if x == 0.0 {
        return f32::NEG_INFINITY;
    }
    if x == f32::INFINITY {
        return x;
    }
    let (mut bits, mut e) = (x.to_bits(), 0i32);
    if bits < 0x0080_0000 {
        // Subnormal: scale by 2^23 (exact) into the normal range.
        bits = (x * 8_388_608.0).to_bits();
        e = -23;
    }
    e += (bits >> 23) as i32 - 127;
    let mut m = f64::from(f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000));
    if m > SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let mut series = 1.0 / 15.0;
    for c in [
        1.0 / 13.0,
        1.0 / 11.0,
        1.0 / 9.0,
        1.0 / 7.0,
        1.0 / 5.0,
        1.0 / 3.0,
        1.0,
    ] {
        series = series * s2 + c;
    }
    let ln_m = 2.0 * s * series;
    (f64::from(e) + ln_m * LOG2_E) as f32
}

/// `1/n!` for `n` = 11 down to 0: the Taylor coefficients of `e^t`, highest first (Horner).
const EXP_TAYLOR: [f64; 12] = {
    let mut c = [1.0; 12];
    let mut n = 1;
    while n < 12 {
        c[11 - n] = c[12 - n] / n as f64;
        n += 1;
    }
    c
};

/// `2^y`, within one ulp: NaN for NaN, +∞ from 128 up, 0 below −151 (and at −∞).
///
/// `y = k + f` with `k` the nearest integer and `|f| ≤ 1/2`; `e^(f·ln 2)` summed in f64 to the
/// 11th power (truncation below 1e-13 relative), scaled by `2^k` exactly, rounded once.
pub(crate) fn exp2(y: f32) -> f32 {
    if y.is_nan() {
        return y;
    }
    if y >= 128.0 {
        return f32::INFINITY;
    }
    if y < -151.0 {
        return 0.0;
    }
    let y = f64::from(y);
    // Round half away from zero by truncation (`as` truncates toward zero).
    let k = (y + if y >= 0.0 { 0.5 } else { -0.5 }) as i32;
    let t = (y - f64::from(k)) * LN_2;
    let mut series = EXP_TAYLOR[0];
    for c in &EXP_TAYLOR[1..] {
        series = series * t + c;
    }
    let scale = f64::from_bits(((k + 1023) as u64) << 52);
    (series * scale) as f32
}

/// `tan(x)` for `|x| < π/2` (a camera's half field of view), from the sine and cosine series
/// summed in f64 to the 30th power (truncation below 1e-16 relative for `|x| ≤ π/2`).
pub fn tan(x: f64) -> f64 {
    let (sin, cos) = sin_cos_series(x, 15);
    sin / cos
}

/// `(sin 2πx, cos 2πx)` for any finite `x` (an orbit's turn): `x` is reduced exactly to an
/// eighth of a turn around a multiple of a quarter, the series are summed there to the 19th and
/// 18th powers (truncation below 1e-19), and the quarter is applied by symmetry, so quarter
/// turns are exact (`(1, 0)` at `x = 0.25`).
pub(crate) fn sin_cos_turns(x: f64) -> (f64, f64) {
    let r = x - x.round(); // exact, in [-0.5, 0.5]
    let q = (r * 4.0).round(); // quarter turns, -2..=2
    let y = r - q * 0.25; // exact, in [-1/8, 1/8]
    let (sin, cos) = sin_cos_series(y * std::f64::consts::TAU, 9);
    match (q as i64).rem_euclid(4) {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

/// `acos(x)` in radians for `x` in `[−1, 1]` (outside: clamped; NaN gives NaN), within a few
/// ulps of the exact value: `π/2 − asin(x)` for `|x| ≤ 1/2`, `2·asin(√((1 − x)/2))` above and
/// `π − 2·asin(√((1 + x)/2))` below, so the series' argument never exceeds 1/2 (a spot light's
/// angle from its axis, SPEC §14).
pub fn acos(x: f64) -> f64 {
    let x = x.clamp(-1.0, 1.0);
    if x > 0.5 {
        2.0 * asin_series(((1.0 - x) * 0.5).sqrt())
    } else if x < -0.5 {
        std::f64::consts::PI - 2.0 * asin_series(((1.0 + x) * 0.5).sqrt())
    } else {
        std::f64::consts::FRAC_PI_2 - asin_series(x)
    }
}

/// `asin x` for `|x| ≤ 1/2` from its series `Σ tₙ·x^(2n+1)/(2n + 1)`, `t₀ = 1`,
/// `tₙ = tₙ₋₁·(2n − 1)/(2n)`, summed from the smallest term to `n = 27` (truncation below
/// 1e-18 relative at `|x| = 1/2`).
fn asin_series(x: f64) -> f64 {
    const TERMS: usize = 28;
    let x2 = x * x;
    let mut terms = [0.0f64; TERMS];
    let (mut t, mut power) = (1.0f64, x);
    for (n, term) in terms.iter_mut().enumerate() {
        if n > 0 {
            let n = n as f64;
            t = t * (2.0 * n - 1.0) / (2.0 * n);
            power *= x2;
        }
        *term = t * power / (2.0 * n as f64 + 1.0);
    }
    terms.iter().rev().sum()
}

/// `(sin x, cos x)` from their Taylor series to the powers `2·terms + 1` and `2·terms`, in
/// Horner form: `sin x = x·(1 − x²/(2·3)·(1 − x²/(4·5)·(…)))`,
/// `cos x = 1 − x²/(1·2)·(1 − x²/(3·4)·(…))`.
fn sin_cos_series(x: f64, terms: u32) -> (f64, f64) {
    let x2 = x * x;
    let (mut sin, mut cos) = (1.0, 1.0);
    for n in (1..=terms).rev() {
        let n = f64::from(n);
        sin = 1.0 - x2 / ((2.0 * n) * (2.0 * n + 1.0)) * sin;
        cos = 1.0 - x2 / ((2.0 * n - 1.0) * (2.0 * n)) * cos;
    }
    (x * sin, cos)
}

#[cfg(test)]
// The platform's f64 functions are the reference the project's own are checked against.
#[allow(clippy::disallowed_methods)]
mod tests {
    use super::*;

    /// Distance in ulps between two finite f32 of the same sign.
    fn ulps(a: f32, b: f32) -> u32 {
        assert_eq!(a.is_sign_negative(), b.is_sign_negative(), "{a} vs {b}");
        a.to_bits().abs_diff(b.to_bits())
    }

    /// Seeded values spread over `lo..hi`.
    fn spread(lo: f32, hi: f32, n: usize) -> impl Iterator<Item = f32> {
        let mut s = 0x9e37_79b9u32;
        (0..n).map(move |_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            lo + (hi - lo) * (s >> 8) as f32 / (1u32 << 24) as f32
        })
    }

    #[test]
    fn acos_is_within_a_few_ulps_of_the_platform_one() {
        for i in 0..=20_000 {
            let x = -1.0 + f64::from(i) / 10_000.0;
            let (a, b) = (acos(x), x.acos());
            assert!(
                (a - b).abs() <= 4.0 * f64::EPSILON * b.max(1e-300),
                "acos({x}): {a} vs {b}"
            );
        }
        assert_eq!(acos(1.0), 0.0);
        assert_eq!(acos(2.0), 0.0);
        assert_eq!(acos(-1.0), std::f64::consts::PI);
        assert!(acos(f64::NAN).is_nan());
    }

    #[test]
    fn log2_is_within_one_ulp_of_the_f64_reference() {
        let values = spread(1e-6, 4.0, 20_000)
            .chain(spread(0.99, 1.01, 5_000))
            .chain([f32::MIN_POSITIVE, 1e-40, f32::MAX, 0.5, 2.0, 3.0]);
        for x in values {
            let want = f64::from(x).log2() as f32;
            let got = log2(x);
            if want == 0.0 {
                assert_eq!(got, 0.0, "log2({x})");
            } else {
                assert!(ulps(got, want) <= 1, "log2({x}) = {got}, want {want}");
            }
        }
        assert_eq!(log2(1.0), 0.0);
        assert_eq!(log2(8.0), 3.0);
        assert_eq!(log2(0.0), f32::NEG_INFINITY);
        assert_eq!(log2(f32::INFINITY), f32::INFINITY);
        assert!(log2(-1.0).is_nan() && log2(f32::NAN).is_nan());
    }

    #[test]
    fn exp2_is_within_one_ulp_of_the_f64_reference() {
        let values = spread(-149.0, 127.9, 20_000).chain(spread(-1.0, 1.0, 5_000));
        for y in values {
            let want = f64::from(y).exp2() as f32;
            let got = exp2(y);
            assert!(ulps(got, want) <= 1, "exp2({y}) = {got}, want {want}");
        }
        assert_eq!(exp2(0.0), 1.0);
        assert_eq!(exp2(10.0), 1024.0);
        assert_eq!(exp2(-3.0), 0.125);
        assert_eq!(exp2(128.0), f32::INFINITY);
        assert_eq!(exp2(f32::NEG_INFINITY), 0.0);
        assert!(exp2(f32::NAN).is_nan());
    }

    #[test]
    fn integer_powers_multiply_over_the_bits_from_the_highest() {
        // x^13, 13 = 0b1101: ((x²·x)²)²·x, each product rounded in f32.
        let x = 0.937_f32;
        let x3 = (x * x) * x;
        let x6 = x3 * x3;
        let want = (x6 * x6) * x;
        assert_eq!(powi(x, 13).to_bits(), want.to_bits());
        assert_eq!(powi(f32::NAN, 0), 1.0);
        assert_eq!(powi(0.0, 7), 0.0);
        assert_eq!(powi(2.0, 16), 65536.0);
        assert_eq!(pow(0.5, 1.0), 0.5);
        for (x, n) in [(0.99f32, 32u32), (0.5, 65_536), (0.999, 1000)] {
            let want = f64::from(x).powi(n as i32);
            let got = f64::from(powi(x, n));
            // Rounding errors compound: each squaring doubles the relative error so far.
            assert!(
                (got - want).abs() <= want * 1.2e-7 * f64::from(n),
                "{x}^{n}"
            );
        }
    }

    #[test]
    fn other_exponents_go_through_exp2_and_log2() {
        assert_eq!(integer_exponent(32.0), Some(32));
        assert_eq!(integer_exponent(65_536.0), Some(65_536));
        assert_eq!(integer_exponent(65_537.0), None);
        assert_eq!(integer_exponent(2.5), None);
        assert_eq!(integer_exponent(-2.0), None);
        assert_eq!(integer_exponent(f32::NAN), None);
        let inv_gamma = 1.0 / 2.2f32;
        assert_eq!(
            pow(0.5, inv_gamma).to_bits(),
            exp2(inv_gamma * log2(0.5)).to_bits()
        );
        assert_eq!(pow(0.0, inv_gamma), 0.0);
        assert_eq!(pow(1.0, inv_gamma), 1.0);
        for x in spread(0.0, 1.0, 2000) {
            let want = f64::from(x).powf(f64::from(inv_gamma));
            // log2's rounding, scaled by |p · log2 x| ≤ 11, dominates.
            assert!(
                (f64::from(pow(x, inv_gamma)) - want).abs() <= want * 4e-6,
                "{x}"
            );
        }
    }

    #[test]
    fn tan_matches_the_reference_over_camera_angles() {
        for deg in 1..180 {
            let x = f64::from(deg).to_radians() / 2.0;
            let (got, want) = (tan(x), x.tan());
            // Near 90° the cosine is small and its absolute error counts more.
            assert!(
                (got - want).abs() <= want * 1e-12,
                "tan({x}) = {got}, want {want}"
            );
            if deg <= 160 {
                assert!(((got as f32).to_bits()).abs_diff((want as f32).to_bits()) <= 1);
            }
        }
    }

    #[test]
    fn sine_and_cosine_of_turns_match_the_library_and_are_exact_on_quarters() {
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turns(-0.25), (-1.0, 0.0));
        assert_eq!(sin_cos_turns(0.5).1, -1.0);
        assert_eq!(sin_cos_turns(3.0), (0.0, 1.0));
        for i in -2000..=2000 {
            let x = i as f64 / 997.0;
            let (s, c) = sin_cos_turns(x);
            let a = x * std::f64::consts::TAU;
            assert!((s - a.sin()).abs() < 4e-16 * (1.0 + a.abs()), "sin at {x}");
            assert!((c - a.cos()).abs() < 4e-16 * (1.0 + a.abs()), "cos at {x}");
        }
    }
}
