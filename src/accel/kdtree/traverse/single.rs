//! Single-ray traversal: front-to-back, with a fixed stack of pending far children (no
//! allocation per ray), generic over the query mode ([`Visitor`]) and the triangle test.
//!
//! Reads the tree's nodes, the accelerator's leaf-ordered triangles and exact root box, and one
//! [`Ray`]; writes the visitor's state (best hit or occlusion).

use glam::Vec3;

use super::KdAccel;
use super::interval::split_case;
use super::ray::Ray;
use super::visit::Visitor;
use crate::accel::kdtree::MAX_DEPTH;
use crate::geometry::triangle::TriangleRay;

/// One pending far child: node index and ray interval.
#[derive(Clone, Copy, Default)]
pub(super) struct Entry {
    /// Node index.
    pub(super) node: u32,
    /// Start of the ray interval inside the node.
    pub(super) t0: f32,
    /// End of the ray interval inside the node.
    pub(super) t1: f32,
}

impl KdAccel {
    /// The query `V` for one ray with triangle test `T`: a ray that cannot hit anything (bad
    /// `t_max`, rejected direction, misses the root box) gets the answer of a visitor that saw
    /// nothing.
    #[inline(always)]
    pub(super) fn query<T: TriangleRay, V: Visitor>(
        &self,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> V::Out {
        let mut v = V::new(t_max);
        if t_max.is_nan() || t_max <= 0.0 {
            return v.finish(false);
        }
        let Some(ray) = Ray::<T>::new(origin, dir, &self.root) else {
            return v.finish(false);
        };
        let stopped = match ray.clip(&self.root, t_max) {
            Some((t0, t1)) => self.walk(&ray, Entry { node: 0, t0, t1 }, &mut v),
            None => false,
        };
        v.finish(stopped)
    }

    /// Front-to-back traversal of the subtree `start.node` over the ray interval
    /// `start.t0..start.t1`; returns true if the visitor asked to stop. A whole-tree traversal
    /// is `walk` from the root.
    #[inline(always)]
    pub(super) fn walk<T: TriangleRay, V: Visitor>(
        &self,
        ray: &Ray<T>,
        start: Entry,
        v: &mut V,
    ) -> bool {
        let nodes = &self.tree.nodes[..];
        let mut stack = [Entry::default(); MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut cur = start;
        loop {
            let mut e = cur;
            // Descend to a leaf.
            let leaf = loop {
                let Some(&n) = nodes.get(e.node as usize) else {
                    break None;
                };
                if n.is_leaf() {
                    break Some(n);
                }
                let axis = n.axis();
                let (near_left, c) = split_case(
                    n.split(),
                    ray.origin[axis],
                    ray.inv[axis],
                    ray.slack[axis],
                    e.t0,
                    e.t1,
                );
                let (left, right) = (e.node + 1, n.right());
                let (near, far) = if near_left {
                    (left, right)
                } else {
                    (right, left)
                };
                if c.far && !c.skip_near {
                    if sp < stack.len() {
                        stack[sp] = Entry {
                            node: far,
                            t0: c.far_t0,
                            t1: c.far_t1,
                        };
                        sp += 1;
                    }
                    e.node = near;
                    e.t1 = c.near_t1;
                } else if !c.skip_near {
                    e.node = near;
                } else {
                    e.node = far;
                    e.t0 = c.far_t0;
                }
            };
            if let Some(n) = leaf {
                let start = n.offset() as usize;
                let end = start + n.count() as usize;
                if v.leaf(&ray.test, &self.tris, &self.tree.tri_indices, start, end) {
                    return true;
                }
            }
            // Pop the next entry that can still hold a closer (or tying) hit.
            loop {
                if sp == 0 {
                    return false;
                }
                sp -= 1;
                cur = stack[sp];
                if cur.t0 <= v.cull() {
                    break;
                }
            }
        }
    }
}
