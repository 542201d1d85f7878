//! Ray/primitive tests and the secondary-ray origin offset.

pub mod offset;
pub mod plane;
pub mod sphere;
pub mod triangle;
