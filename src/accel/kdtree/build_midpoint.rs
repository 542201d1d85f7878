//! The assignment's builder (SPEC §6): split the node box's longest axis at its midpoint; a
//! triangle goes to every child whose (closed) box it overlaps by the exact triangle/box test;
//! when either child would receive all of the node's triangles the node becomes a leaf, and a
//! depth cap guarantees termination.

use super::build_sah::Flat;
use super::node::KdNode;
use super::overlap::{Aabb, tri_box_overlap};
use super::{MAX_BUILD_DEPTH, split_box, tri_verts};
use crate::mesh::TriangleMesh;

/// Nodes with more triangles than this build their children in parallel.
const PARALLEL_MIN: usize = 2048;

/// Builds the midpoint tree over `tris` (non-degenerate triangle indices, ascending) in box
/// `root`.
pub(crate) fn build(mesh: &TriangleMesh, root: Aabb, tris: Vec<u32>) -> Flat {
    let mut out = Flat::default();
    node(mesh, root, tris, 0, &mut out);
    out
}

/// Builds the subtree over `tris` in box `bx`, appending it to `out` in pre-order.
fn node(mesh: &TriangleMesh, bx: Aabb, tris: Vec<u32>, depth: usize, out: &mut Flat) {
    let n = tris.len();
    if n == 0 || depth >= MAX_BUILD_DEPTH {
        return out.leaf(&tris);
    }
    let ext = [bx.1[0] - bx.0[0], bx.1[1] - bx.0[1], bx.1[2] - bx.0[2]];
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let split = bx.0[axis] + 0.5 * ext[axis];
    if !(split > bx.0[axis] && split < bx.1[axis]) {
        return out.leaf(&tris);
    }
    let (lb, rb) = split_box(&bx, axis, split);
    let mut left = Vec::new();
    let mut right = Vec::new();
    for &t in &tris {
        let v = tri_verts(mesh, t);
        if tri_box_overlap(&v, &lb) {
            left.push(t);
        }
        if tri_box_overlap(&v, &rb) {
            right.push(t);
        }
    }
    if left.len() == n || right.len() == n {
        return out.leaf(&tris);
    }
    drop(tris);
    let here = out.nodes.len();
    out.nodes.push(KdNode::inner(axis, split, 0));
    let mut sub = Flat::default();
    if n > PARALLEL_MIN {
        rayon::join(
            || node(mesh, lb, left, depth + 1, out),
            || node(mesh, rb, right, depth + 1, &mut sub),
        );
    } else {
        node(mesh, lb, left, depth + 1, out);
        node(mesh, rb, right, depth + 1, &mut sub);
    }
    out.nodes[here] = KdNode::inner(axis, split, out.nodes.len() as u32);
    out.append(sub);
}

#[cfg(test)]
mod tests {
    use crate::accel::kdtree::{BuildMethod, KdTree};
    use crate::mesh::TriangleMesh;

    #[test]
    fn splits_the_longest_axis_at_its_middle() {
        // Box 0..8 in x, 0..1 in y and z: the root splits x at 4.
        let mesh = TriangleMesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 1.0],
                [8.0, 0.0, 0.0],
                [7.0, 1.0, 0.0],
                [8.0, 1.0, 1.0],
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let tree = KdTree::build(&mesh, BuildMethod::Midpoint);
        let root = tree.nodes()[0];
        assert!(!root.is_leaf());
        assert_eq!((root.axis(), root.split()), (0, 4.0));
        tree.validate(&mesh).expect("valid");
    }

    #[test]
    fn node_is_a_leaf_when_one_child_gets_everything() {
        // One long triangle crossing the middle: both children would receive it.
        let mesh = TriangleMesh::new(
            vec![[0.0, 0.0, 0.0], [8.0, 0.0, 0.0], [4.0, 1.0, 0.0]],
            vec![[0, 1, 2]],
        );
        let tree = KdTree::build(&mesh, BuildMethod::Midpoint);
        assert_eq!(tree.nodes().len(), 1);
        assert_eq!(tree.leaf_triangles(0), &[0]);
    }
}
