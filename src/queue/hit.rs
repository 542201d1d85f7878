//! [`HitQueue`] (the rays that hit) and [`PrimId`] (which primitive a ray hit).

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::SampleSlot;

/// Which primitive a ray hit: spheres first, then planes, then triangles, numbered consecutively
/// (see `crate::world::World::prim_kind`). [`PrimId::NONE`] is a miss.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Pod, Zeroable)]
pub struct PrimId(pub u32);

/// A miss.
impl Default for PrimId {
    fn default() -> Self {
        PrimId::NONE
    }
}

impl PrimId {
    /// No hit.
    pub const NONE: PrimId = PrimId(u32::MAX);

    /// True when this is a hit.
    pub fn is_hit(self) -> bool {
        self != Self::NONE
    }
}

crate::queue! {
    /// The rays that hit something, with their hits; compacted in slot order.
    ///
    /// Intersect sizes the queue and fills the ray and hit columns; shade fills `point`,
    /// `normal`, `material`, `spawn`, `shading` and `emitted` in place; reflect reads `spawn`,
    /// `shading`, `material` with the ray columns.
    pub struct HitQueue {
        /// Ray origin.
        origin: Vec3,
        /// Unit ray direction.
        direction: Vec3,
        /// Path weight.
        weight: Vec3,
        /// Sample slot (ascending).
        slot: SampleSlot,
        /// Hit parameter.
        t: f32,
        /// Hit primitive.
        prim: PrimId,
        /// Hit point (written by shade).
        point: Vec3,
        /// Unit normal facing the incoming ray (written by shade).
        normal: Vec3,
        /// Material index (written by shade).
        material: u32,
        /// Origin for rays leaving the hit, offset off the surface (written by shade).
        spawn: Vec3,
        /// Unit shading normal on the facing side (written by shade): the facing normal, or an
        /// interpolated vertex normal.
        shading: Vec3,
        /// Radiance the hit adds to its sample at once (written by shade).
        emitted: Vec3,
    }
    /// One row of a [`HitQueue`].
    pub struct HitItem;
}
