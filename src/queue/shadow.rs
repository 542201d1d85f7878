//! [`ShadowQueue`]: shadow rays from hit points toward lights, each carrying the radiance it adds
//! to its sample if nothing blocks it.

use glam::Vec3;

use super::SampleSlot;

/// One shadow ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowItem {
    /// Origin, already offset off the surface.
    pub origin: Vec3,
    /// Unit direction toward the light.
    pub direction: Vec3,
    /// Distance to the light: blockers count only for `0 < t < t_max`.
    pub t_max: f32,
    /// Direct radiance (already weighted) added to the sample when unoccluded.
    pub radiance: Vec3,
    /// Sample the radiance belongs to.
    pub slot: SampleSlot,
}

/// Shadow rays in structure-of-arrays form; slots ascend (several rows may share a slot when
/// there are several lights).
#[derive(Clone, Debug, Default)]
pub struct ShadowQueue {
    /// Origins.
    pub origin: Vec<Vec3>,
    /// Unit directions.
    pub direction: Vec<Vec3>,
    /// Distances to the light.
    pub t_max: Vec<f32>,
    /// Radiance if unoccluded.
    pub radiance: Vec<Vec3>,
    /// Sample slots, non-decreasing.
    pub slot: Vec<SampleSlot>,
    /// Whether something blocks the ray (written by the shadow stage).
    pub occluded: Vec<bool>,
}

impl ShadowQueue {
    /// Number of shadow rays.
    pub fn len(&self) -> usize {
        self.slot.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.slot.is_empty()
    }

    /// Removes all rows, keeping the allocations.
    pub fn clear(&mut self) {
        self.origin.clear();
        self.direction.clear();
        self.t_max.clear();
        self.radiance.clear();
        self.slot.clear();
        self.occluded.clear();
    }

    /// Appends one shadow ray.
    pub fn push(&mut self, r: ShadowItem) {
        debug_assert!(
            self.slot.last().is_none_or(|&s| s <= r.slot),
            "slots must not descend"
        );
        self.origin.push(r.origin);
        self.direction.push(r.direction);
        self.t_max.push(r.t_max);
        self.radiance.push(r.radiance);
        self.slot.push(r.slot);
    }

    /// Row `i` as an item.
    pub fn get(&self, i: usize) -> ShadowItem {
        ShadowItem {
            origin: self.origin[i],
            direction: self.direction[i],
            t_max: self.t_max[i],
            radiance: self.radiance[i],
            slot: self.slot[i],
        }
    }
}
