//! Reference ("peer") ray tracers that `wavefront`'s kD-tree kernels are
//! benchmarked against. Each peer sits behind its own cargo feature.

#[cfg(feature = "embree")]
pub mod embree;
