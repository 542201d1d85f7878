//! [`HitColumns`]: the intersect stage's per-ray answer, row for row with a [`super::RayQueue`].

use super::PrimId;

crate::queue! {
    /// One closest-hit answer per ray of a [`super::RayQueue`], row for row.
    pub struct HitColumns {
        /// Hit parameter (`inf` on a miss).
        t: f32,
        /// Hit primitive ([`PrimId::NONE`] on a miss).
        prim: PrimId,
    }
    /// One answer.
    pub struct ClosestHit;
}
