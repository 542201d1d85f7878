//! [`ShadowQueue`]: shadow rays from hit points toward lights, each carrying the radiance it adds
//! to its sample if nothing blocks it.

use glam::Vec3;

use super::SampleSlot;

crate::queue! {
    /// Shadow rays in structure-of-arrays form; slots do not descend (several rows may share a
    /// slot when there are several lights). Shade sizes the queue and writes every column but
    /// `occluded`, which the shadow stage writes in place.
    pub struct ShadowQueue {
        /// Origin, already offset off the surface.
        origin: Vec3,
        /// Unit direction toward the light.
        direction: Vec3,
        /// Distance to the light: blockers count only for `0 < t < t_max`.
        t_max: f32,
        /// Direct radiance (already weighted) added to the sample when unoccluded.
        radiance: Vec3,
        /// Sample the radiance belongs to.
        slot: SampleSlot,
        /// Whether something blocks the ray (written by the shadow stage).
        occluded: bool,
    }
    /// One shadow ray.
    pub struct ShadowItem;
}
