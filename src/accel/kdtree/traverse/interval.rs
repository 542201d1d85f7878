//! The node-interval step, written once: which children of an inner node a ray enters and over
//! which part of its `[t0, t1]` interval, with the `δ` and `SLACK` tolerances.
//!
//! Reads one inner node's split (axis value) and a ray's origin, reciprocal direction and slack
//! on that axis plus its current interval; writes a [`Step`]. Generic over [`Wide`], the crate's
//! one lane vocabulary: `f32` for the single-ray loop, [`F32x4`](crate::simd::F32x4) for the
//! 4-ray packet loop and 8 or 16 lanes for the frusta, so every loop makes exactly the same
//! decisions and computes the same interval bits lane by lane (the operations have the SSE
//! instructions' semantics, see [`crate::simd`]). The formula is written as its three cases
//! (the sign of the plane distance, or NaN): one lane branches on the case, several compute all
//! three and blend them per lane ([`by_sign`]).

use crate::simd::Wide;

/// Relative slack on ray-interval comparisons (plane distances and hit `t` carry a few ulps).
pub(super) const SLACK: f32 = 1e-4;
/// `1 + SLACK`: `a <= b · HI` is "`a` is not beyond `b` by more than the slack".
pub(super) const HI: f32 = 1.0 + SLACK;
/// World-space slack around split planes, relative to the distance from the ray origin to the
/// farthest root corner (the per-ray `δ`, see the module docs of `traverse`).
pub(super) const DELTA: f32 = 1.0 / (1 << 18) as f32;

/// Per lane, `pos()` where `tp > 0`, `nonpos()` where `tp <= 0` and `nan()` where `tp` is NaN.
/// One lane branches and evaluates one case (a predicted branch keeps the single-ray loop's
/// dependency chains short, measured: a branch-free scalar step is ~20 % slower); several lanes
/// evaluate all three and blend.
#[inline(always)]
fn by_sign<L: Wide>(
    tp: L,
    pos: impl FnOnce() -> Case<L>,
    nonpos: impl FnOnce() -> Case<L>,
    nan: impl FnOnce() -> Case<L>,
) -> Case<L> {
    let zero = L::splat(0.0);
    let (p, q) = (tp.gt(zero), tp.le(zero));
    if L::LANES == 1 {
        return if L::bits(p) != 0 {
            pos()
        } else if L::bits(q) != 0 {
            nonpos()
        } else {
            nan()
        };
    }
    let (a, b, c) = (pos(), nonpos(), nan());
    let f = |x: L, y: L, z: L| L::select(p, x, L::select(q, y, z));
    let m = |x, y, z| L::select_mask(p, x, L::select_mask(q, y, z));
    Case {
        near_t1: f(a.near_t1, b.near_t1, c.near_t1),
        far_t0: f(a.far_t0, b.far_t0, c.far_t0),
        far_t1: f(a.far_t1, b.far_t1, c.far_t1),
        skip_near: m(a.skip_near, b.skip_near, c.skip_near),
        far: m(a.far, b.far, c.far),
    }
}

/// One case of the step, before the normalisation of [`Step`]: the near and far intervals and
/// which children are entered.
#[derive(Clone, Copy, Debug)]
pub(super) struct Case<L: Wide> {
    /// End of the near child's interval (it starts at the node's `t0`).
    pub(super) near_t1: L,
    /// Start of the far child's interval.
    pub(super) far_t0: L,
    /// End of the far child's interval.
    pub(super) far_t1: L,
    /// The near child is not entered (the ray goes far).
    pub(super) skip_near: L::Mask,
    /// The far child is entered (if the near one is not, the ray goes far anyway).
    pub(super) far: L::Mask,
}

/// One inner-node step, oriented near/far (near = the child on the origin's side of the split).
/// The near child's interval is `[t0, near_t1]`, the far child's `[far_t0, far_t1]`; when only
/// one child is entered its interval is the one to continue with (`near_t1 == t1` then, and
/// `far_t1 == t1`), so a caller never needs the case that produced it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Step<L: Wide> {
    /// The left child (below the split) is the near one.
    pub(super) near_left: L::Mask,
    /// The near child is not entered (the others enter it).
    pub(super) skip_near: L::Mask,
    /// The far child is entered (always when the near one is not).
    pub(super) go_far: L::Mask,
    /// End of the near child's interval.
    pub(super) near_t1: L,
    /// Start of the far child's interval.
    pub(super) far_t0: L,
    /// End of the far child's interval.
    pub(super) far_t1: L,
}

/// The near/far child intervals of the ray interval `[t0, t1]` at a split plane `split`, for a
/// ray with `origin`, reciprocal direction `inv` and slack `slack` (all on the node's axis).
///
/// The plane is crossed at `tp = (split - origin) · inv`. A side is entered when the ray comes
/// within `δ` of it (`slack = δ · |inv|`, in `t` units) and its interval is not empty up to the
/// relative `SLACK`:
/// - `tp > 0`: near is `[t0, min(t1, tp + δ)]`, entered if `t0 <= (tp + δ)·HI`; far is
///   `[max(t0, tp - δ), t1]`, entered if its start is `<= t1·HI`.
/// - `tp <= 0` (the plane is behind the origin): near is `[t0, t1]`, always entered; far is
///   `[t0, min(t1, tp + δ)]`, entered if `t0 <=` its end `·HI`.
/// - `tp` NaN (`0 · ∞`: a ray parallel to the plane, lying in it): both, with `[t0, t1]`.
///
/// When only one side is entered, its interval is `[t0, t1]` (near) or `[far_t0, t1]` (far).
/// The near side is the origin's (the left one on the plane when the direction is negative).
/// Interval ends are never NaN where they are used (`t0`, `t1` come from non-NaN root clips,
/// `δ` is clamped finite, and `tp ± δ` is NaN only where `tp` is, which takes the third case),
/// so `minps`/`maxps` give the values `f32::min`/`max` would (up to the sign of a zero, which
/// no comparison sees).
#[inline(always)]
pub(super) fn step<L: Wide>(split: L, origin: L, inv: L, slack: L, t0: L, t1: L) -> Step<L> {
    let (near_left, c) = split_case(split, origin, inv, slack, t0, t1);
    let both = L::andnot(c.far, c.skip_near);
    Step {
        near_left,
        skip_near: c.skip_near,
        go_far: L::or(c.far, c.skip_near),
        near_t1: L::select(both, c.near_t1, t1),
        far_t0: c.far_t0,
        far_t1: L::select(both, c.far_t1, t1),
    }
}

/// [`step`] before its normalisation: whether the left child is the near one, and the case's
/// intervals and entry tests. When only one side is entered, a caller continues with `[t0, t1]`
/// (near) or `[far_t0, t1]` (far), as [`step`] does; the single-ray loop takes this form and
/// branches on "both" (its branches are the normalisation). "Near not entered" is written
/// `(tp + δ)·HI < t0`, the negation of `t0 <= (tp + δ)·HI` as neither is NaN when `tp > 0`.
#[inline(always)]
pub(super) fn split_case<L: Wide>(
    split: L,
    origin: L,
    inv: L,
    slack: L,
    t0: L,
    t1: L,
) -> (L::Mask, Case<L>) {
    let zero = L::splat(0.0);
    let hi = L::splat(HI);
    let tp = split.sub(origin).mul(inv);
    let tps = tp.add(slack);
    let near_left = L::or(origin.lt(split), L::and(origin.eq(split), inv.lt(zero)));
    let case = by_sign(
        tp,
        || {
            let far_t0 = t0.max(tp.sub(slack));
            Case {
                near_t1: t1.min(tps),
                far_t0,
                far_t1: t1,
                skip_near: tps.mul(hi).lt(t0),
                far: far_t0.le(t1.mul(hi)),
            }
        },
        || {
            let far_t1 = t1.min(tps);
            Case {
                near_t1: t1,
                far_t0: t0,
                far_t1,
                skip_near: L::none(),
                far: t0.le(far_t1.mul(hi)),
            }
        },
        || Case {
            near_t1: t1,
            far_t0: t0,
            far_t1: t1,
            skip_near: L::none(),
            far: L::all(),
        },
    );
    (near_left, case)
}

#[cfg(test)]
mod tests {
    use super::{HI, step};
    use crate::simd::F32x4;

    /// The step as first written for the single-ray loop (branches on the sign of `tp`,
    /// `f32::min`/`max`): the specification the branch-free [`step`] must reproduce.
    /// Returns `(near_left, go_near, go_far, near_t1, far_t0, far_t1)` in the same convention.
    fn reference(split: f32, oa: f32, ia: f32, st: f32, t0: f32, t1: f32) -> [f32; 6] {
        let tp = (split - oa) * ia;
        let nl = oa < split || (oa == split && ia < 0.0);
        let (near_t1, far_t0, far_t1, near_used, far_used) = if tp > 0.0 {
            let far_t0 = t0.max(tp - st);
            (
                t1.min(tp + st),
                far_t0,
                t1,
                t0 <= (tp + st) * HI,
                far_t0 <= t1 * HI,
            )
        } else if tp <= 0.0 {
            let far_t1 = t1.min(tp + st);
            (t1, t0, far_t1, true, t0 <= far_t1 * HI)
        } else {
            (t1, t0, t1, true, true)
        };
        let both = near_used && far_used;
        let (n1, f0, f1) = if both {
            (near_t1, far_t0, far_t1)
        } else {
            (t1, far_t0, t1)
        };
        let b = |x: bool| x as u8 as f32;
        [b(nl), b(near_used), b(both || !near_used), n1, f0, f1]
    }

    fn scalar(split: f32, oa: f32, ia: f32, st: f32, t0: f32, t1: f32) -> [f32; 6] {
        let s = step::<f32>(split, oa, ia, st, t0, t1);
        let b = |x: bool| x as u8 as f32;
        [
            b(s.near_left),
            b(!s.skip_near),
            b(s.go_far),
            s.near_t1,
            s.far_t0,
            s.far_t1,
        ]
    }

    /// Small deterministic generator.
    /// The crate's seeded generator ([`crate::sampling::Rng`]) with this test's draws.
    struct Draws(crate::sampling::Rng);
    impl Draws {
        fn next(&mut self) -> u32 {
            (self.0.next_u64() >> 33) as u32
        }
        fn coord(&mut self) -> f32 {
            (self.next() as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
        }
    }

    #[test]
    fn scalar_and_four_lane_steps_match_the_reference_formula() {
        let mut rng = Draws(crate::sampling::Rng(0xabc));
        let special = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            1e-30,
        ];
        let pick = |rng: &mut Draws| {
            if rng.next().is_multiple_of(4) {
                special[(rng.next() % special.len() as u32) as usize]
            } else {
                rng.coord() * 3.0
            }
        };
        for _ in 0..200_000 {
            let split = pick(&mut rng);
            let lane = |rng: &mut Draws| {
                let o = if rng.next().is_multiple_of(4) {
                    split
                } else {
                    pick(rng)
                };
                let t0 = pick(rng).abs();
                let t1 = if rng.next().is_multiple_of(8) {
                    t0 * 0.5
                } else {
                    t0 + pick(rng).abs()
                };
                [o, pick(rng), pick(rng).abs().min(f32::MAX), t0, t1]
            };
            let l: [[f32; 5]; 4] = std::array::from_fn(|_| lane(&mut rng));
            let col = |j: usize| F32x4::from_array(&l.map(|x| x[j]));
            let v = step::<F32x4>(F32x4::splat(split), col(0), col(1), col(2), col(3), col(4));
            let (nt1, ft0, ft1) = (
                v.near_t1.to_array(),
                v.far_t0.to_array(),
                v.far_t1.to_array(),
            );
            for (k, &[o, i, st, t0, t1]) in l.iter().enumerate() {
                let want = reference(split, o, i, st, t0, t1);
                let got = scalar(split, o, i, st, t0, t1);
                // Decisions equal; interval ends equal as numbers (a zero's sign may differ
                // from the reference's; it never changes a comparison).
                assert_eq!(got, want, "{split} {:?}", l[k]);
                let bit = |m: u8| (m >> k & 1) as f32;
                let lane = [
                    bit(v.near_left.bits()),
                    bit(!v.skip_near.bits()),
                    bit(v.go_far.bits()),
                    nt1[k],
                    ft0[k],
                    ft1[k],
                ];
                // The packet lane is the single ray's step, bit for bit.
                assert_eq!(
                    lane.map(f32::to_bits),
                    got.map(f32::to_bits),
                    "{split} {:?}",
                    l[k]
                );
            }
        }
    }

    #[test]
    fn a_ray_in_the_split_plane_enters_both_children() {
        let s = step::<f32>(0.0, 0.0, f32::INFINITY, 0.0, 0.0, 5.0);
        assert!(!s.skip_near && s.go_far);
        assert_eq!((s.near_t1, s.far_t0, s.far_t1), (5.0, 0.0, 5.0));
        // A plane behind the origin: only the near side.
        let s = step::<f32>(-1.0, 0.0, 1.0, 0.0, 0.0, 5.0);
        assert!(!s.skip_near && !s.go_far && !s.near_left);
    }
}
