//! [`HitColumns`] (the intersect stage's per-ray answer) and [`HitQueue`] (the rays that hit).

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::SampleSlot;

/// Which primitive a ray hit: spheres first, then planes, then triangles, numbered consecutively
/// (see [`crate::world::World::prim_kind`]). [`PrimId::NONE`] is a miss.
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

/// One closest-hit answer per ray of a [`super::RayQueue`], row for row.
#[derive(Clone, Debug, Default)]
pub struct HitColumns {
    /// Hit parameter (`inf` on a miss).
    pub t: Vec<f32>,
    /// Hit primitive ([`PrimId::NONE`] on a miss).
    pub prim: Vec<PrimId>,
}

impl HitColumns {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.prim.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.prim.is_empty()
    }
}

/// The rays that hit something, with their hits; compacted in slot order.
///
/// Intersect fills the ray and hit columns; shade fills `point`, `normal`, `material`, `spawn`
/// and `emitted`; reflect reads `spawn`, `normal`, `material` with the ray columns.
#[derive(Clone, Debug, Default)]
pub struct HitQueue {
    /// Ray origins.
    pub origin: Vec<Vec3>,
    /// Unit ray directions.
    pub direction: Vec<Vec3>,
    /// Path weights.
    pub weight: Vec<Vec3>,
    /// Sample slots, ascending.
    pub slot: Vec<SampleSlot>,
    /// Hit parameters.
    pub t: Vec<f32>,
    /// Hit primitives.
    pub prim: Vec<PrimId>,
    /// Hit points (written by shade).
    pub point: Vec<Vec3>,
    /// Unit normals facing the incoming ray (written by shade).
    pub normal: Vec<Vec3>,
    /// Material indices (written by shade).
    pub material: Vec<u32>,
    /// Origins for rays leaving each hit, offset off the surface (written by shade).
    pub spawn: Vec<Vec3>,
    /// Unit shading normals on the facing side (written by shade): the facing normal, or an
    /// interpolated vertex normal.
    pub shading: Vec<Vec3>,
    /// Radiance each hit adds to its sample at once (written by shade).
    pub emitted: Vec<Vec3>,
}

impl HitQueue {
    /// Number of hits.
    pub fn len(&self) -> usize {
        self.slot.len()
    }

    /// True when no ray hit.
    pub fn is_empty(&self) -> bool {
        self.slot.is_empty()
    }

    /// Removes all rows, keeping the allocations.
    pub fn clear(&mut self) {
        self.origin.clear();
        self.direction.clear();
        self.weight.clear();
        self.slot.clear();
        self.t.clear();
        self.prim.clear();
        self.point.clear();
        self.normal.clear();
        self.material.clear();
        self.spawn.clear();
        self.shading.clear();
        self.emitted.clear();
    }
}
