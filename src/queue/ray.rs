//! [`RayQueue`]: the rays of one depth (queue 0 = primary rays, queue k = after k reflections).

use glam::Vec3;

use super::SampleSlot;

crate::queue! {
    /// Rays in structure-of-arrays form; slots ascend.
    pub struct RayQueue {
        /// Ray origin.
        origin: Vec3,
        /// Unit direction.
        direction: Vec3,
        /// Hits count only for `0 < t < t_max`.
        t_max: f32,
        /// Product of the reflectivities along the path: what this ray's radiance is worth.
        weight: Vec3,
        /// Sample this ray contributes to.
        slot: SampleSlot,
    }
    /// One ray, as pushed into or read from a [`RayQueue`].
    pub struct RayItem;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(s: u32) -> RayItem {
        RayItem {
            origin: Vec3::splat(s as f32),
            direction: Vec3::X,
            t_max: f32::INFINITY,
            weight: Vec3::ONE,
            slot: SampleSlot(s),
        }
    }

    #[test]
    fn push_get_and_clear_round_trip() {
        let mut q = RayQueue::default();
        q.push(ray(1));
        q.push(ray(4));
        assert_eq!(q.len(), 2);
        assert_eq!(q.get(1), ray(4));
        assert_eq!(RayQueue::ROW_BYTES, 3 * 12 + 4 + 4);
        let cap = q.capacity();
        q.clear();
        assert!(q.is_empty());
        assert_eq!(q.capacity(), cap, "clear keeps the allocation");
    }
}
