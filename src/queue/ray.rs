//! [`RayQueue`]: the rays of one depth (queue 0 = primary rays, queue k = after k reflections).

use glam::Vec3;

use super::SampleSlot;

/// One ray, as pushed into or read from a [`RayQueue`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayItem {
    /// Ray origin.
    pub origin: Vec3,
    /// Unit direction.
    pub direction: Vec3,
    /// Hits count only for `0 < t < t_max`.
    pub t_max: f32,
    /// Product of the reflectivities along the path: what this ray's radiance is worth.
    pub weight: Vec3,
    /// Sample this ray contributes to.
    pub slot: SampleSlot,
}

/// Rays in structure-of-arrays form. All columns have the same length.
#[derive(Clone, Debug, Default)]
pub struct RayQueue {
    /// Ray origins.
    pub origin: Vec<Vec3>,
    /// Unit directions.
    pub direction: Vec<Vec3>,
    /// Upper bounds of the hit parameter.
    pub t_max: Vec<f32>,
    /// Path weights.
    pub weight: Vec<Vec3>,
    /// Sample slots, ascending.
    pub slot: Vec<SampleSlot>,
}

impl RayQueue {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.slot.len()
    }

    /// True when the queue holds no rays.
    pub fn is_empty(&self) -> bool {
        self.slot.is_empty()
    }

    /// Removes all rays, keeping the allocations.
    pub fn clear(&mut self) {
        self.origin.clear();
        self.direction.clear();
        self.t_max.clear();
        self.weight.clear();
        self.slot.clear();
    }

    /// Appends one ray.
    pub fn push(&mut self, r: RayItem) {
        debug_assert!(
            self.slot.last().is_none_or(|&s| s < r.slot),
            "slots must ascend"
        );
        self.origin.push(r.origin);
        self.direction.push(r.direction);
        self.t_max.push(r.t_max);
        self.weight.push(r.weight);
        self.slot.push(r.slot);
    }

    /// Row `i` as an item.
    pub fn get(&self, i: usize) -> RayItem {
        RayItem {
            origin: self.origin[i],
            direction: self.direction[i],
            t_max: self.t_max[i],
            weight: self.weight[i],
            slot: self.slot[i],
        }
    }

    /// Bytes per row across all columns (for bandwidth figures).
    pub const ROW_BYTES: usize = 3 * 12 + 4 + 4;
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
        let cap = q.origin.capacity();
        q.clear();
        assert!(q.is_empty());
        assert_eq!(q.origin.capacity(), cap, "clear keeps the allocation");
    }
}
