//! Ray queues: structure-of-arrays columns, one file per schema, each declared once with
//! [`queue!`](crate::queue!) (private columns of one length, the row API, `ROW_BYTES`, the
//! column descriptors).
//!
//! | queue | rows are | columns |
//! |---|---|---|
//! | [`RayQueue`] | rays to trace at one depth | `origin`, `direction`, `t_max`, `weight`, `slot` |
//! | [`HitColumns`] | one closest-hit answer per ray of a `RayQueue` | `t`, `prim` |
//! | [`HitQueue`] | rays that hit something | `origin`, `direction`, `weight`, `slot`, `t`, `prim` (compacted by intersect); `point`, `normal`, `material`, `spawn`, `emitted` (written by shade) |
//! | [`ShadowQueue`] | shadow rays toward the lights | `origin`, `direction`, `t_max`, `radiance`, `slot` (written by shade); `occluded` (written by shadow) |
//! | [`SampleBuffer`] | the samples of the current wave | `radiance` |
//!
//! Which stage reads and writes which column is declared once, by the kernels' column sets
//! ([`columns`]), and collected by the stage registry ([`crate::schedule::stage`]).
//!
//! Every queue keeps its rows in ascending [`SampleSlot`] order: generation emits slots in order and
//! [`compact`] (the one compaction helper of every kernel that compacts) preserves order, which is what makes the film's accumulation deterministic.

pub mod closest;
pub mod columns;
pub mod compact;
pub mod hit;
pub mod lanes;
pub mod pass;
pub mod ray;
pub mod region;
pub mod samples;
pub mod schema;
pub mod shadow;
pub mod wave;

pub use closest::{ClosestHit, HitColumns};
pub use columns::{Access, Column, ColumnAccess, ColumnSet, KernelDecl, Resize};
pub use hit::{HitItem, HitQueue, PrimId};
pub use ray::{RayItem, RayQueue};
pub use samples::{Sample, SampleBuffer, Samples, add_sorted};
pub use schema::Queue;
pub use shadow::{ShadowItem, ShadowQueue};

use bytemuck::{Pod, Zeroable};

/// Index of a sample in the current wave's sample buffer (not a pixel, not a queue row).
///
/// Sample `s` of the wave's `k`-th pixel has slot `k · samples + s`.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Pod, Zeroable)]
pub struct SampleSlot(pub u32);

/// Index of a pixel in the image, row-major from the top-left.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Pod, Zeroable)]
pub struct PixelIndex(pub u32);

/// Index of a row of a queue (not a sample, not a pixel): what compaction keeps.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Pod, Zeroable)]
pub struct RowIndex(pub u32);

impl RowIndex {
    /// The row as a slice index.
    #[inline]
    pub fn get(self) -> usize {
        self.0 as usize
    }
}

/// Minimum rows per rayon task in kernels: small enough to balance, large enough to amortise.
pub(crate) const MIN_CHUNK: usize = 1024;

/// Rays per call of the world's batch closest-hit query (the intersect stage's chunks): 8 rows of
/// a 512-pixel-wide image at one sample per pixel, so the kD tree can regroup camera rays into
/// 8 × 8 pixel tiles.
pub const TRACE_CHUNK: usize = 4 * MIN_CHUNK;
