//! The film: the box filter of a wave's samples ([`crate::queue::SampleBuffer`]) into pixels
//! (`resolve_wave`), where resolved pixels go ([`PixelSink`]: an in-memory [`Film`], or an
//! image file streamed as the render goes, [`crate::film::output::ImageStream`]), and 8-bit
//! output.
//!
//! Accumulation is deterministic: every addition into a sample happens in schedule order (depth by
//! depth, shade before shadow), and within one pass each sample is written by exactly one task.

pub mod output;

use glam::Vec3;
use rayon::prelude::*;

use crate::arith;
use crate::queue::wave::Wave;
use crate::queue::{MIN_CHUNK, PixelIndex, SampleBuffer};

/// Where the schedule puts each wave's resolved pixels (linear radiance), as soon as the wave is
/// done. Waves arrive in ascending pixel order and never overlap; pixels never delivered (outside
/// a rendered pixel range) are black.
pub trait PixelSink {
    /// Takes the pixels `first .. first + pixels.len()` (row-major, row 0 at the top).
    fn put(&mut self, first: PixelIndex, pixels: &[Vec3]);

    /// False once the sink can take no more pixels (e.g. its file could not be written): the
    /// schedule then stops after the current wave, and the sink's owner reports why.
    fn accepts(&self) -> bool {
        true
    }
}

/// A finished image in linear radiance, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear radiance per pixel (mean of its samples).
    pub pixels: Vec<Vec3>,
}

impl Film {
    /// A black film.
    pub fn new(width: u32, height: u32) -> Film {
        Film {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    /// 8-bit RGB: `round(255 · clamp(L, 0, 1)^(1/gamma))` per channel (SPEC §2).
    pub fn to_rgb8(&self, gamma: f32) -> Vec<u8> {
        let inv = 1.0 / gamma;
        let mut rgb = vec![0; 3 * self.pixels.len()];
        rgb.par_chunks_mut(3 * MIN_CHUNK)
            .zip(self.pixels.par_chunks(MIN_CHUNK))
            .for_each(|(out, px)| encode_rgb8(px, inv, out));
        rgb
    }
}

/// A film takes every wave's pixels into the whole image.
impl PixelSink for Film {
    fn put(&mut self, first: PixelIndex, pixels: &[Vec3]) {
        let first = first.0 as usize;
        self.pixels[first..first + pixels.len()].copy_from_slice(pixels);
    }
}

/// Averages each pixel's samples in `buffer` (slots as `wave` maps them) into `out`, one entry per
/// pixel of the wave (overwritten): the box filter, in a fixed order.
pub(crate) fn resolve_wave(buffer: &SampleBuffer, wave: &Wave, out: &mut Vec<Vec3>) {
    let samples = wave.samples.max(1) as usize;
    let inv = 1.0 / samples as f32;
    buffer.radiance()[..wave.len()]
        .par_chunks_exact(samples)
        .with_min_len(MIN_CHUNK)
        .map(|s| s.iter().fold(Vec3::ZERO, |a, &b| a + b) * inv)
        .collect_into_vec(out);
}

/// Encodes one linear channel value to 8 bits through the `GammaTable` of `inv_gamma` (kept
/// per thread for the last gamma used): `round(255 · c^(1/γ))` with the project's own power
/// (SPEC §2: the same bits on every CPU); NaN becomes 0.
#[inline]
pub fn encode(c: f32, inv_gamma: f32) -> u8 {
    with_table(inv_gamma, |t| t.encode(c))
}

/// Encodes linear RGB `pixels` to 8-bit RGB in `out` (three bytes per pixel), as [`encode`]
/// does each channel, looking the table up once for the whole slice.
pub(crate) fn encode_rgb8(pixels: &[Vec3], inv_gamma: f32, out: &mut [u8]) {
    debug_assert_eq!(out.len(), 3 * pixels.len());
    with_table(inv_gamma, |t| {
        for (rgb, p) in out.chunks_exact_mut(3).zip(pixels) {
            rgb[0] = t.encode(p.x);
            rgb[1] = t.encode(p.y);
            rgb[2] = t.encode(p.z);
        }
    });
}

/// Runs `f` with this thread's [`GammaTable`] of `inv_gamma` (built when the gamma changes).
fn with_table<R>(inv_gamma: f32, f: impl FnOnce(&GammaTable) -> R) -> R {
    thread_local! {
        static TABLE: std::cell::RefCell<GammaTable> = std::cell::RefCell::new(GammaTable::new(1.0 / 2.2));
    }
    TABLE.with_borrow_mut(|t| {
        if t.inv_gamma.to_bits() != inv_gamma.to_bits() {
            *t = GammaTable::new(inv_gamma);
        }
        f(t)
    })
}

/// The 8-bit output levels of one gamma as 255 thresholds (SPEC §2 allows a table whose entries
/// a deterministic routine defines). Level `k` starts at the smallest f32 `c` in `[0, 1]` with
/// `round(255 · c^(1/γ)) ≥ k`, `arith::pow` being the power ([`gamma_level`]), found by
/// bisection over the bit patterns; a value's level is the number of thresholds at or below it.
/// That is [`gamma_level`] itself wherever it does not decrease (everywhere, as far as tested)
/// for the cost of a table look-up instead of an `exp2` and a `log2` per channel.
///
/// The look-up: the value's bit pattern shifted right by `BUCKET_SHIFT` names a bucket (its
/// exponent and top mantissa bits), whose entry is the level at the bucket's first value; the
/// thresholds inside the bucket (rarely more than one) are then stepped over. The count is the
/// same as a search over all 255 thresholds (tested on every threshold's neighbours and on
/// every bucket's edges).
#[derive(Clone, Debug)]
pub(crate) struct GammaTable {
    /// `1/γ`, the exponent the table encodes.
    pub inv_gamma: f32,
    /// `start[k − 1]`: the first value of level `k`, increasing.
    start: [f32; 255],
    /// `bucket[b]`: the level of the smallest non-negative f32 whose bits shifted right by
    /// `BUCKET_SHIFT` are `b`, for every bucket up to and including 1.0's.
    bucket: Box<[u8]>,
}

/// Bits dropped from an f32 pattern to name its [`GammaTable`] bucket: buckets span a relative
/// width of 2^-7, under one level at the top of any gamma up to 1.
const BUCKET_SHIFT: u32 = 16;

/// `round(255 · c^inv_gamma)` for `c` in `[0, 1]`: the definition [`GammaTable`] tabulates.
#[inline]
pub(crate) fn gamma_level(c: f32, inv_gamma: f32) -> u8 {
    (255.0 * arith::pow(c, inv_gamma)).round() as u8
}

/// Half the width, in units in the last place, of the bracket [`threshold`] first tries around
/// its estimate: the estimate's own error is a few ulps.
const BRACKET: u32 = 32;

/// The first value of level `k` (1..=255) of `inv_gamma`: the bisection over the bit patterns
/// of `[0, 1]` for the smallest `c` with [`gamma_level`]`(c) ≥ k`, with the bracket first
/// narrowed to `BRACKET` ulps either side of the estimate `((k − ½)/255)^γ` when that bracket
/// holds the change of level (checked: the level below `k` at its low end, at least `k` at its
/// high end), else the whole of `[0, 1]`. Where the level does not decrease (everywhere, as far
/// as tested) both brackets hold the same single change, so the narrowing changes no threshold
/// (`bracketed_thresholds_are_the_full_bisections`); it turns 30 steps into 9 or 10.
fn threshold(k: u8, inv_gamma: f32) -> f32 {
    let one = 1.0f32.to_bits();
    let reaches = |b: u32| gamma_level(f32::from_bits(b), inv_gamma) >= k;
    // Invariant: level(lo) < k ≤ level(hi); level(0) = 0 and level(1) = 255.
    let (mut lo, mut hi) = (0u32, one);
    let estimate = arith::pow((f32::from(k) - 0.5) / 255.0, 1.0 / inv_gamma);
    if estimate > 0.0 && estimate < 1.0 {
        let e = estimate.to_bits();
        let (l, h) = (e.saturating_sub(BRACKET), (e + BRACKET).min(one));
        if !reaches(l) && reaches(h) {
            (lo, hi) = (l, h);
        }
    }
    bisect(lo, hi, reaches)
}

/// The smallest bit pattern in `(lo, hi]` where `reaches` holds, given that it does not hold at
/// `lo` and holds at `hi` (a bisection: the first change when there are several).
fn bisect(mut lo: u32, mut hi: u32, reaches: impl Fn(u32) -> bool) -> f32 {
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if reaches(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    f32::from_bits(hi)
}

impl GammaTable {
    /// The table of `inv_gamma` (255 bracketed bisections, [`threshold`], then one pass over
    /// the buckets).
    pub fn new(inv_gamma: f32) -> GammaTable {
        let one = 1.0f32.to_bits();
        let start: [f32; 255] = std::array::from_fn(|i| threshold(i as u8 + 1, inv_gamma));
        // One merge pass: the level only grows with the bucket's first value.
        let mut level = 0usize;
        let bucket = (0..=one >> BUCKET_SHIFT)
            .map(|b| {
                let first = f32::from_bits(b << BUCKET_SHIFT);
                while level < start.len() && start[level] <= first {
                    level += 1;
                }
                level as u8
            })
            .collect();
        GammaTable {
            inv_gamma,
            start,
            bucket,
        }
    }

    /// The 8-bit level of linear value `c` (clamped to `[0, 1]`; NaN becomes 0).
    #[inline]
    pub fn encode(&self, c: f32) -> u8 {
        // NaN, negative values and both zeros are level 0; 1 and above are level 255.
        if c.is_nan() || c <= 0.0 {
            return 0;
        }
        if c >= 1.0 {
            return 255;
        }
        let mut level = usize::from(self.bucket[(c.to_bits() >> BUCKET_SHIFT) as usize]);
        while level < self.start.len() && self.start[level] <= c {
            level += 1;
        }
        level as u8
    }

    /// [`GammaTable::encode`] by a binary search over all the thresholds: the definition the
    /// bucketed look-up is checked against.
    #[cfg(test)]
    fn encode_by_search(&self, c: f32) -> u8 {
        if c.is_nan() {
            return 0;
        }
        // `!(t > c)` counts thresholds at or below c (all 255 for c ≥ 1, none for c ≤ 0).
        self.start.partition_point(|&t| t <= c) as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gamma_table_gives_the_levels_of_its_definition() {
        for gamma in [2.2f32, 1.8, 1.0] {
            let inv = 1.0 / gamma;
            let table = GammaTable::new(inv);
            let mut s = 0x2545_f491u32;
            let seeded = (0..50_000).map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                // Uniform in [0, 1], and spread over the small values' exponents too.
                let u = (s >> 8) as f32 / (1u32 << 24) as f32;
                if s & 1 == 0 { u } else { u * u * u * u }
            });
            // Every threshold and its neighbours below and above: where the levels change.
            let edges = table.start.iter().flat_map(|t| {
                let b = t.to_bits();
                [b - 1, b, b + 1].map(f32::from_bits)
            });
            for c in seeded.chain(edges).chain([0.0, 1.0, 1e-30, 0.999_999_9]) {
                assert_eq!(
                    table.encode(c),
                    gamma_level(c, inv),
                    "level of {c} at gamma {gamma}"
                );
            }
        }
    }

    /// The full bisection over `[0, 1]`: what [`threshold`]'s bracket must not change.
    fn full_bisection(k: u8, inv_gamma: f32) -> f32 {
        bisect(0, 1.0f32.to_bits(), |b| {
            gamma_level(f32::from_bits(b), inv_gamma) >= k
        })
    }

    #[test]
    fn bracketed_thresholds_are_the_full_bisections() {
        let mut narrowed = 0;
        for gamma in [2.2f32, 1.8, 1.0, 2.4, 0.5, 4.0, 1.0 / 0.45, 3.0, 8.0] {
            let inv = 1.0 / gamma;
            let table = GammaTable::new(inv);
            for (i, &t) in table.start.iter().enumerate() {
                let k = i as u8 + 1;
                assert_eq!(
                    t.to_bits(),
                    full_bisection(k, inv).to_bits(),
                    "level {k} at gamma {gamma}"
                );
                // The threshold is where the level changes: below k just under it, k or more
                // at it and just above it.
                assert!(gamma_level(t.next_down(), inv) < k, "{k} at gamma {gamma}");
                assert!(gamma_level(t, inv) >= k, "{k} at gamma {gamma}");
                assert!(gamma_level(t.next_up(), inv) >= k, "{k} at gamma {gamma}");
                // The narrow bracket held the change (else the table cost the full 30 steps).
                let e = arith::pow((f32::from(k) - 0.5) / 255.0, gamma).to_bits();
                if t.to_bits().abs_diff(e) <= BRACKET {
                    narrowed += 1;
                }
            }
        }
        assert_eq!(narrowed, 9 * 255, "thresholds found in the narrow bracket");
    }

    #[test]
    fn the_bucketed_look_up_counts_the_thresholds_as_a_search_does() {
        for gamma in [2.2f32, 1.8, 1.0, 0.5, 4.0] {
            let table = GammaTable::new(1.0 / gamma);
            // Every threshold's neighbours, every bucket's first and last values, and the
            // values outside [0, 1].
            let thresholds = table.start.iter().flat_map(|t| {
                let b = t.to_bits();
                (b - 2..=b + 2).map(f32::from_bits)
            });
            let buckets = (0..=1.0f32.to_bits() >> BUCKET_SHIFT).flat_map(|b| {
                let first = b << BUCKET_SHIFT;
                [first, first + 1, first + (1 << BUCKET_SHIFT) - 1].map(f32::from_bits)
            });
            let outside = [
                -0.0,
                -1.0,
                1.0,
                1.5,
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::NAN,
            ];
            for c in thresholds.chain(buckets).chain(outside) {
                assert_eq!(
                    table.encode(c),
                    table.encode_by_search(c),
                    "level of {c:e} at gamma {gamma}"
                );
            }
        }
    }

    #[test]
    fn encode_rgb8_encodes_each_channel() {
        let pixels = [Vec3::new(0.0, 0.5, 1.0), Vec3::new(-1.0, f32::NAN, 0.25)];
        let mut out = [7u8; 6];
        encode_rgb8(&pixels, 1.0 / 2.2, &mut out);
        let each: Vec<u8> = pixels
            .iter()
            .flat_map(|p| p.to_array().map(|c| encode(c, 1.0 / 2.2)))
            .collect();
        assert_eq!(out.as_slice(), each.as_slice());
    }

    #[test]
    fn encode_applies_gamma_after_clamping() {
        assert_eq!(encode(0.0, 1.0 / 2.2), 0);
        assert_eq!(encode(1.0, 1.0 / 2.2), 255);
        assert_eq!(encode(7.0, 1.0 / 2.2), 255);
        assert_eq!(encode(-1.0, 1.0 / 2.2), 0);
        assert_eq!(encode(f32::NAN, 1.0 / 2.2), 0);
        assert_eq!(
            encode(0.5, 1.0 / 2.2),
            (255.0 * arith::exp2(-1.0 / 2.2)).round() as u8
        );
    }

    #[test]
    fn resolve_averages_each_pixels_samples() {
        let mut b = SampleBuffer::default();
        b.reset(4);
        crate::queue::Samples::of(&mut b)
            .radiance
            .copy_from_slice(&[Vec3::ONE, Vec3::ZERO, Vec3::splat(0.5), Vec3::splat(0.5)]);
        let mut f = Film::new(2, 2);
        let wave = Wave::of_image(2, 2, 2, 2, 2);
        let mut pixels = vec![];
        resolve_wave(&b, &wave, &mut pixels);
        f.put(crate::queue::PixelIndex(wave.first), &pixels);
        assert_eq!(
            f.pixels,
            vec![Vec3::ZERO, Vec3::ZERO, Vec3::splat(0.5), Vec3::splat(0.5)]
        );
    }

    #[test]
    fn unknown_extension_is_refused_and_nothing_is_written() {
        let dir = std::env::temp_dir().join(format!("wf-film-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.jpg");
        let e = Film::new(1, 1).save(&p, 2.2).unwrap_err();
        assert!(e.to_string().contains(".png, .ppm or .exr"));
        assert!(!p.exists());
        let p = dir.join("x.ppm");
        Film::new(2, 1).save(&p, 2.2).unwrap();
        assert!(std::fs::read(&p).unwrap().starts_with(b"P6"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
