//! Ray queues: structure-of-arrays columns, one file per schema.
//!
//! | queue | rows are | columns |
//! |---|---|---|
//! | [`RayQueue`] | rays to trace at one depth | `origin`, `direction`, `t_max`, `weight`, `slot` |
//! | [`HitQueue`] | rays that hit something | the ray columns, `t`, `prim`; then `point`, `normal`, `material`, `spawn` written by shade |
//! | [`ShadowQueue`] | shadow rays toward one light | `origin`, `direction`, `t_max`, `radiance`, `slot` |
//!
//! Every queue keeps its rows in ascending [`SampleSlot`] order: generation emits slots in order and
//! [`compact`] preserves order, which is what makes the film's accumulation deterministic.

pub mod compact;
pub mod hit;
pub mod ray;
pub mod shadow;

pub use hit::{HitColumns, HitQueue, PrimId};
pub use ray::{RayItem, RayQueue};
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

/// Minimum rows per rayon task in kernels: small enough to balance, large enough to amortise.
pub const MIN_CHUNK: usize = 1024;
