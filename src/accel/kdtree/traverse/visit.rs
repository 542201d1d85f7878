//! The two query modes, closest hit and occluded (any hit), as [`Visitor`]s: what a leaf visit
//! does with its triangles and how far the traversal may still cull. The node-stepping loops
//! (`single`, `packet`) are generic over the visitor and monomorphised for each mode.
//!
//! Reads the leaf-ordered triangle vertices and indices of one leaf; writes the visitor's
//! answer (a [`TriHit`] or an occlusion bit).

use super::interval::HI;
use crate::accel::kdtree::TriHit;
use crate::geometry::triangle::TriangleRay;

/// What a leaf visit tells the traversal loop, and the query's answer.
pub(super) trait Visitor {
    /// The query's answer for one ray.
    type Out: Copy;
    /// A visitor for a ray with parameter bound `t_max` that has seen nothing yet.
    fn new(t_max: f32) -> Self;
    /// Tests `ray` against the leaf entries `start..end` of `tris` (vertices in leaf order)
    /// and `ids` (their triangle indices), in order; returns true to stop traversal.
    fn leaf<T: TriangleRay>(
        &mut self,
        ray: &T,
        tris: &[[[f32; 3]; 3]],
        ids: &[u32],
        start: usize,
        end: usize,
    ) -> bool;
    /// The `t_max` to test the next triangle with.
    fn limit(&self) -> f32;
    /// Takes a hit `t < limit()` on triangle `tri`; returns true to stop traversal.
    fn accept(&mut self, t: f32, tri: u32) -> bool;
    /// Current cull distance (nodes entered beyond it are skipped).
    fn cull(&self) -> f32;
    /// The answer, given whether the visitor asked to stop the traversal.
    fn finish(&self, stopped: bool) -> Self::Out;
}

/// Closest hit: keeps the best hit, accepts equal `t` when the index is lower, culls nodes that
/// start beyond the best hit (with the relative slack).
pub(super) struct Closest {
    /// The ray's parameter bound.
    t_max: f32,
    /// Best hit so far.
    best: Option<TriHit>,
}

impl Closest {
    /// A visitor for a ray with bound `t_max` that has already found `best` (a traversal
    /// carried on by another loop).
    #[inline(always)]
    pub(super) fn resume(t_max: f32, best: Option<TriHit>) -> Closest {
        Closest { t_max, best }
    }
}

impl Visitor for Closest {
    type Out = Option<TriHit>;

    #[inline(always)]
    fn new(t_max: f32) -> Closest {
        Closest { t_max, best: None }
    }

    #[inline(always)]
    fn leaf<T: TriangleRay>(
        &mut self,
        ray: &T,
        tris: &[[[f32; 3]; 3]],
        ids: &[u32],
        start: usize,
        end: usize,
    ) -> bool {
        let (Some(tris), Some(ids)) = (tris.get(start..end), ids.get(start..end)) else {
            return false;
        };
        for (&[p0, p1, p2], &tri) in tris.iter().zip(ids) {
            if let Some(t) = ray.hit(p0, p1, p2, self.limit()) {
                self.accept(t, tri);
            }
        }
        false
    }

    #[inline(always)]
    fn limit(&self) -> f32 {
        // Accept equal t too, so ties can go to the lower index.
        match self.best {
            Some(b) => b.t.next_up(),
            None => self.t_max,
        }
    }

    #[inline(always)]
    fn accept(&mut self, t: f32, tri: u32) -> bool {
        if self.best.is_none_or(|b| t < b.t || tri < b.tri) {
            self.best = Some(TriHit { t, tri });
        }
        false
    }

    #[inline(always)]
    fn cull(&self) -> f32 {
        match self.best {
            Some(b) => b.t * HI,
            None => f32::INFINITY,
        }
    }

    #[inline(always)]
    fn finish(&self, _: bool) -> Option<TriHit> {
        self.best
    }
}

/// Occluded: stops at the first hit found (so "stopped" is the answer); never culls.
pub(super) struct Occluded {
    /// The ray's parameter bound (every triangle is tested against it).
    t_max: f32,
}

impl Visitor for Occluded {
    type Out = bool;

    #[inline(always)]
    fn new(t_max: f32) -> Occluded {
        Occluded { t_max }
    }

    #[inline(always)]
    fn leaf<T: TriangleRay>(
        &mut self,
        ray: &T,
        tris: &[[[f32; 3]; 3]],
        _: &[u32],
        start: usize,
        end: usize,
    ) -> bool {
        let Some(tris) = tris.get(start..end) else {
            return false;
        };
        tris.iter()
            .any(|&[p0, p1, p2]| ray.hit(p0, p1, p2, self.t_max).is_some())
    }

    #[inline(always)]
    fn limit(&self) -> f32 {
        self.t_max
    }

    #[inline(always)]
    fn accept(&mut self, _: f32, _: u32) -> bool {
        true
    }

    #[inline(always)]
    fn cull(&self) -> f32 {
        f32::INFINITY
    }

    #[inline(always)]
    fn finish(&self, stopped: bool) -> bool {
        stopped
    }
}
