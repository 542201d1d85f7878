//! Reference ("peer") ray tracers that `wavefront`'s kD-tree kernels are
//! benchmarked against. Each peer sits behind its own cargo feature.

#[cfg(feature = "embree")]
#[allow(unsafe_code)] // a C FFI binding: every call into Embree is `unsafe`
pub mod embree;
