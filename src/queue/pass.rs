//! [`ShadowPass`]: the block of hit rows × lights one shade → shadow pass covers. The schedule
//! lays the passes out (`schedule::passes`); the shade kernels spawn a pass's shadow rays.

use std::ops::Range;

/// Upper bound on a pass's rows: row indices of a pass are `u32` ([`RowIndex`](crate::queue::RowIndex)).
pub(crate) const MAX_SHADOW_ROWS: usize = u32::MAX as usize;

/// One shade → shadow pass of a depth: the shadow rays of hits `hits` (rows of the hit queue)
/// toward lights `lights` (indices into the world's lights), at most `hits.len() × lights.len()`
/// rows. The first pass of a depth also shades the surfaces and adds the emitted radiance.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ShadowPass {
    /// Rows of the hit queue.
    pub hits: Range<usize>,
    /// Indices of the lights.
    pub lights: Range<usize>,
}

impl ShadowPass {
    /// True for the depth's first pass: the one that shades surfaces and emits.
    pub(crate) fn is_first(&self) -> bool {
        self.hits.start == 0 && self.lights.start == 0
    }

    /// Candidate shadow rays of the pass (`hits × lights`; the schedule's passes keep it within
    /// their budget, so it never overflows).
    pub fn rows(&self) -> usize {
        self.hits.len() * self.lights.len()
    }
}
