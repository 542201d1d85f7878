//! The routing table: which traversal loop a batch, or a part of it, takes. Every decision the
//! batch queries make about loops is one function here, with its threshold beside it; the loops
//! call them and decide nothing else. Only speed depends on them: every loop gives the
//! single-ray answer, bit for bit (`tests/variants.rs`).
//!
//! | query | rays | loop | decided by |
//! |---|---|---|---|
//! | `intersect_closest`, `intersect_occluded` | one | `single` | — |
//! | `intersect_closest_batch` | fewer than [`MIN_FRUSTA`] | `packet` per group of 4 (below) | [`closest_by_size`] |
//! | `intersect_closest_batch` | more, one shared origin (camera rays), or origins within [`MAX_SPREAD`] (mirror reflections) | `frustum` per 64-ray screen tile | [`closest_by_origins`] |
//! | `intersect_closest_batch` | more, origins spread | `packet` per group of 4 | [`closest_by_origins`] |
//! | a frustum's ray whose direction the watertight test rejects | one | `single` | `frustum::regroup` (permutation 6) |
//! | a frustum's lanes once at most [`SOLO`] are live | each | `single`, from its own interval and best hit | [`frustum_lanes`] |
//! | `intersect_occluded_batch` | at least [`MIN_BUNDLED`] ending at up to `bundle::MAX_APEXES` shared points (shadow rays to point lights) | `bundle`; the rays ending elsewhere `single` | [`occluded_batch`] |
//! | `intersect_occluded_batch` | fewer | `packet` per group of 4 | [`occluded_batch`] |
//! | a packet batch's next 4 rays | 4 left, direction signs equal (or forced: `KdAccel::packets_forced`) | `packet` | [`group`] |
//! | a packet batch's next ray | otherwise | `single` | [`group`] |

/// A traversal loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Loop {
    /// One ray (`single`).
    Single,
    /// 4 rays (`packet`).
    Packet,
    /// 64 rays of one screen tile (`frustum`).
    Frustum,
    /// 16 or 32 rays ending at one point, traced from it (`bundle`).
    Bundle,
}

/// Rays a closest-hit batch needs for frusta: two frusta's worth (fewer rays rarely fill a
/// tile).
pub(super) const MIN_FRUSTA: usize = 2 * super::frustum::WIDE;

/// Largest mean spread of a frustum's origins (L∞ extent of their box, relative to the root
/// box's largest side) for which rays from many origins stay frusta: reflections off a mirror
/// measured 0.026 on Sibenik (a screen tile's footprint on the mirror), rays reflected about
/// per-pixel normals 0.13 (a tile of similar directions gathers origins from the whole batch),
/// and frusta of those ran at 0.4× the 4-ray packets.
pub(super) const MAX_SPREAD: f32 = 1.0 / 16.0;

/// Live lanes at or below which a frustum's lanes go on one by one through the single-ray loop
/// (measured on Sibenik's mirror reflections: 1, 2 and 4 within the noise, 2 a little ahead,
/// 8 slower; about 13 % faster than never).
pub(super) const SOLO: u32 = 2;

/// Batches with fewer bundle-able rays than this go through the packet path as a whole.
pub(super) const MIN_BUNDLED: usize = 32;

/// Rays per packet.
pub(super) const PACKET: usize = 4;

/// A closest-hit batch of `n` rays, before it is regrouped: [`Loop::Frustum`] (try them: the
/// origins decide next, [`closest_by_origins`]) or [`Loop::Packet`].
#[inline(always)]
pub(super) fn closest_by_size(n: usize) -> Loop {
    if n < MIN_FRUSTA {
        Loop::Packet
    } else {
        Loop::Frustum
    }
}

/// How the origins of a closest-hit batch lie, once regrouped into frusta.
#[derive(Clone, Copy, Debug)]
pub(super) enum Origins {
    /// Every ray starts at one point.
    Shared,
    /// The batch holds at most two frusta (of valid directions): too few to measure.
    Few,
    /// The summed spread of the first two frusta's origins (see [`MAX_SPREAD`]).
    Spread(f32),
}

/// A closest-hit batch of enough rays ([`closest_by_size`]) whose origins lie as `origins`:
/// [`Loop::Frustum`] unless the first two frusta's origins spread more than [`MAX_SPREAD`] on
/// average, then [`Loop::Packet`].
#[inline(always)]
pub(super) fn closest_by_origins(origins: Origins) -> Loop {
    match origins {
        Origins::Spread(sum) if sum > 2.0 * MAX_SPREAD => Loop::Packet,
        _ => Loop::Frustum,
    }
}

/// A frustum (descending to a leaf) with `live` live lanes: [`Loop::Single`] for each of them
/// when at most [`SOLO`] are left, else [`Loop::Frustum`].
#[inline(always)]
pub(super) fn frustum_lanes(live: u32) -> Loop {
    if live <= SOLO {
        Loop::Single
    } else {
        Loop::Frustum
    }
}

/// An occluded batch with `bundled` rays ending at shared points: [`Loop::Bundle`] from
/// [`MIN_BUNDLED`] on, else [`Loop::Packet`] for the whole batch.
#[inline(always)]
pub(super) fn occluded_batch(bundled: usize) -> Loop {
    if bundled < MIN_BUNDLED {
        Loop::Packet
    } else {
        Loop::Bundle
    }
}

/// A packet batch's next rays, `left` of them, the next [`PACKET`] with equal direction signs
/// or not (`same_signs`), `forced` to packets (tests): [`Loop::Packet`] for the next
/// [`PACKET`] rays, or [`Loop::Single`] for the next one.
#[inline(always)]
pub(super) fn group(left: usize, same_signs: impl FnOnce() -> bool, forced: bool) -> Loop {
    if left >= PACKET && (forced || same_signs()) {
        Loop::Packet
    } else {
        Loop::Single
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_routes_each_batch_as_documented() {
        // Closest-hit batches: size first, then the origins.
        assert_eq!(closest_by_size(0), Loop::Packet);
        assert_eq!(closest_by_size(MIN_FRUSTA - 1), Loop::Packet);
        assert_eq!(closest_by_size(MIN_FRUSTA), Loop::Frustum);
        assert_eq!(MIN_FRUSTA, 128);
        assert_eq!(closest_by_origins(Origins::Shared), Loop::Frustum);
        assert_eq!(closest_by_origins(Origins::Few), Loop::Frustum);
        // Mirror reflections (0.026 per frustum) stay frusta; per-pixel-normal
        // reflections (0.13) go to packets.
        assert_eq!(closest_by_origins(Origins::Spread(0.052)), Loop::Frustum);
        assert_eq!(
            closest_by_origins(Origins::Spread(2.0 * MAX_SPREAD)),
            Loop::Frustum
        );
        assert_eq!(closest_by_origins(Origins::Spread(0.26)), Loop::Packet);
        // A frustum's last lanes.
        assert_eq!(frustum_lanes(0), Loop::Single);
        assert_eq!(frustum_lanes(SOLO), Loop::Single);
        assert_eq!(frustum_lanes(SOLO + 1), Loop::Frustum);
        // Occluded batches.
        assert_eq!(occluded_batch(MIN_BUNDLED - 1), Loop::Packet);
        assert_eq!(occluded_batch(MIN_BUNDLED), Loop::Bundle);
        // Packet groups: 4 left with equal signs, or forced; the signs are not looked at when
        // forced or too few are left.
        assert_eq!(group(4, || true, false), Loop::Packet);
        assert_eq!(group(9, || false, false), Loop::Single);
        assert_eq!(group(4, || unreachable!(), true), Loop::Packet);
        assert_eq!(group(3, || unreachable!(), true), Loop::Single);
    }
}
