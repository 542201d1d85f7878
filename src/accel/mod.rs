//! Acceleration structures: the kD tree of ray/mesh queries, its cache of built trees, and the
//! BVH of many analytic primitives.

pub(crate) mod bvh;
pub mod cache;
pub mod kdtree;
