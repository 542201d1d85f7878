//! Per-ray traversal data ([`Ray`]) and the clip of a ray to the root box.
//!
//! Reads one ray (origin, unnormalised direction) and the accelerator's exact root box; writes
//! the triangle test's per-ray data, the reciprocal direction and the per-axis `δ` slack, once
//! per ray, for the single-ray and packet loops alike.

use glam::Vec3;

use super::interval::{DELTA, HI};
use crate::accel::kdtree::overlap::Aabb;
use crate::geometry::triangle::TriangleRay;

/// Everything a traversal needs per ray.
pub(super) struct Ray<T> {
    /// The triangle test's per-ray data.
    pub(super) test: T,
    /// Origin; the 4th lane pads the arrays so a node's 2-bit axis field indexes them without
    /// a bounds check.
    pub(super) origin: [f32; 4],
    /// `1 / dir`, cached so plane distances are one subtract and one multiply.
    pub(super) inv: [f32; 4],
    /// `δ · |1 / dir|` per axis (clamped to `f32::MAX`): the world-space slack in `t` units.
    pub(super) slack: [f32; 4],
}

impl<T: TriangleRay> Ray<T> {
    /// Prepares a ray against the root box `root`; `None` when the triangle test rejects the
    /// direction (it can hit nothing).
    #[inline(always)]
    pub(super) fn new(origin: Vec3, dir: Vec3, root: &Aabb) -> Option<Ray<T>> {
        let test = T::prepare(origin, dir)?;
        let inv = Vec3::ONE / dir;
        // Rounding in `p - o` and everything after it scales with the distance from the
        // origin to the geometry, bounded by the farthest root corner (L∞).
        let reach = (Vec3::from_array(root.0) - origin)
            .abs()
            .max((Vec3::from_array(root.1) - origin).abs())
            .max_element();
        let delta = DELTA * reach;
        Some(Ray {
            test,
            origin: origin.extend(0.0).to_array(),
            inv: inv.extend(0.0).to_array(),
            slack: (inv.abs() * delta)
                .min(Vec3::splat(f32::MAX))
                .extend(0.0)
                .to_array(),
        })
    }

    /// Clips `[0, t_max]` to the root box grown by `δ`; `None` when the ray misses it. A NaN
    /// slab distance (the origin on a face of a parallel ray) leaves that axis unbounded (taking
    /// the other face's distance, as `min`/`max` would, dropped a ray lying in the box's face).
    #[inline(always)]
    pub(super) fn clip(&self, bx: &Aabb, t_max: f32) -> Option<(f32, f32)> {
        let mut t0 = 0.0f32;
        let mut t1 = t_max;
        for a in 0..3 {
            let ta = (bx.0[a] - self.origin[a]) * self.inv[a];
            let tb = (bx.1[a] - self.origin[a]) * self.inv[a];
            // A NaN distance (`0 · ∞`): a parallel ray lying in a face's plane, inside the
            // closed slab along its whole line.
            let (near, far) = if ta.is_nan() || tb.is_nan() {
                (f32::NEG_INFINITY, f32::INFINITY)
            } else {
                (ta.min(tb), ta.max(tb))
            };
            t0 = t0.max(near - self.slack[a]);
            t1 = t1.min(far + self.slack[a]);
        }
        (t0 <= t1 * HI).then_some((t0.max(0.0), t1))
    }
}
