//! Ray/primitive tests and the secondary-ray origin offset.

pub mod frame;
pub mod mesh;
pub(crate) mod offset;
pub(crate) mod plane;
pub mod sphere;
pub mod triangle;

pub use mesh::TriangleMesh;
