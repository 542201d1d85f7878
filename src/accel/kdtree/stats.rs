//! Tree statistics (`KdTree::stats`): node counts, depth, leaf occupancy and SAH cost.

use std::fmt;

use super::overlap::Aabb;
use super::{COST_INTERSECT, COST_TRAVERSAL, KdTree, area, exact_root, split_box};
use crate::mesh::TriangleMesh;

/// Summary statistics of a kD tree.
#[derive(Clone, Debug, PartialEq)]
pub struct KdStats {
    /// All nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Leaves without triangles.
    pub empty_leaves: usize,
    /// Deepest leaf (root = 0).
    pub max_depth: usize,
    /// Total triangle references over all leaves.
    pub references: usize,
    /// Mean triangles per non-empty leaf.
    pub mean_tris_per_leaf: f64,
    /// Largest leaf.
    pub max_tris_per_leaf: usize,
    /// SAH cost relative to the root box: `sum(inner) Ct·A/A_root + sum(leaf) Ci·n·A/A_root`.
    pub sah_cost: f64,
}

impl KdTree {
    /// Computes statistics; boxes are derived from the exact root box of `mesh`.
    pub fn stats(&self, mesh: &TriangleMesh) -> KdStats {
        let root = exact_root(self, mesh);
        let root_area = area(&root).max(f32::MIN_POSITIVE) as f64;
        let mut s = KdStats {
            nodes: self.nodes.len(),
            leaves: 0,
            empty_leaves: 0,
            max_depth: 0,
            references: 0,
            mean_tris_per_leaf: 0.0,
            max_tris_per_leaf: 0,
            sah_cost: 0.0,
        };
        let mut stack: Vec<(usize, Aabb, usize)> = vec![(0, root, 0)];
        while let Some((i, bx, depth)) = stack.pop() {
            let Some(&n) = self.nodes.get(i) else {
                continue;
            };
            let rel = area(&bx) as f64 / root_area;
            s.max_depth = s.max_depth.max(depth);
            if n.is_leaf() {
                let c = n.count() as usize;
                s.leaves += 1;
                s.references += c;
                s.empty_leaves += (c == 0) as usize;
                s.max_tris_per_leaf = s.max_tris_per_leaf.max(c);
                s.sah_cost += COST_INTERSECT as f64 * c as f64 * rel;
            } else {
                s.sah_cost += COST_TRAVERSAL as f64 * rel;
                let (l, r) = split_box(&bx, n.axis(), n.split());
                stack.push((n.right() as usize, r, depth + 1));
                stack.push((i + 1, l, depth + 1));
            }
        }
        let full = s.leaves - s.empty_leaves;
        s.mean_tris_per_leaf = if full > 0 {
            s.references as f64 / full as f64
        } else {
            0.0
        };
        s
    }
}

impl fmt::Display for KdStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "nodes {}, leaves {} ({} empty), max depth {}, triangle refs {}, \
             tris/leaf mean {:.2} (non-empty) max {}, sah cost {:.2}",
            self.nodes,
            self.leaves,
            self.empty_leaves,
            self.max_depth,
            self.references,
            self.mean_tris_per_leaf,
            self.max_tris_per_leaf,
            self.sah_cost
        )
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::accel::kdtree::KdTree;
    use crate::mesh::TriangleMesh;

    #[test]
    fn counts_nodes_leaves_depth_and_cost() {
        let mesh = TriangleMesh::new(
            vec![[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 1.0, 1.0]],
            vec![[0, 1, 2]],
        );
        let text = "inner{ 0 0 0 4 1 1 ; 1 2 0 2 }\nleaf{ 0 0 0 2 1 1 ; 0 }\ninner{ 2 0 0 4 1 1 ; 3 4 0 3 }\nleaf{ 2 0 0 3 1 1 ; 0 }\nleaf{ 3 0 0 4 1 1 ; }\n";
        let tree = KdTree::read_text(text.as_bytes(), Path::new("s.kd"), 1).expect("read");
        let s = tree.stats(&mesh);
        assert_eq!(
            (s.nodes, s.leaves, s.empty_leaves, s.max_depth),
            (5, 3, 1, 2)
        );
        assert_eq!((s.references, s.max_tris_per_leaf), (2, 1));
        assert_eq!(s.mean_tris_per_leaf, 1.0);
        // Root box area 18; inner 1.0 * (18 + 10) / 18, leaves 1.5 * (10 + 6) / 18.
        assert!(
            (s.sah_cost - (28.0 + 24.0) / 18.0).abs() < 1e-6,
            "{}",
            s.sah_cost
        );
        assert!(s.to_string().contains("nodes 5"));
    }
}
