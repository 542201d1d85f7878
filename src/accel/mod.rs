//! Acceleration structures for ray/mesh queries.

pub mod kdtree;
