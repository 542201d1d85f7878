//! Reference ("peer") ray tracers that `wavefront`'s kD-tree kernels are
//! benchmarked against. Each peer sits behind its own cargo feature.

#[cfg(feature = "embree")]
#[allow(unsafe_code)] // the FFI binding: every block carries a SAFETY comment
pub mod embree;
