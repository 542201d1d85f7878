//! Acceleration structures over triangle meshes.

pub mod kdtree;
