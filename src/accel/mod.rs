//! Acceleration structures: the kD tree of ray/mesh queries and the BVH of many analytic
//! primitives.

pub mod bvh;
pub mod kdtree;
