//! `validate()`: structural and geometric checks of a kD tree against its mesh.
//!
//! Checks that every node and child index is in range, that the tree is a proper pre-order tree
//! within the depth limit, that children partition the parent's box at the split (the split lies
//! inside the parent's box, closed), that every triangle index is in range, and that every
//! non-degenerate triangle meeting a leaf's box with positive area ([`tri_box_overlap_area`]) is
//! listed in that leaf — except that a triangle lying IN a split plane need only be listed on one
//! side of it (the side whose subtree lists it; the other side is then not checked for it).
//! Every point of every triangle thus lies in the closed box of a leaf listing it, which is what
//! traversal needs. Degenerate triangles are never hit, so they need not be listed.

use std::path::Path;

use super::overlap::{Aabb, tri_box_overlap, tri_box_overlap_area};
use super::{KdTree, MAX_DEPTH, TreeError, exact_root, split_box, tri_verts};
use crate::mesh::TriangleMesh;

/// A problem [`KdTree::validate`] found, and the node (pre-order index) it is at, if any.
struct Invalid {
    node: Option<usize>,
    message: String,
}

impl Invalid {
    fn at(node: usize, message: String) -> Invalid {
        Invalid {
            node: Some(node),
            message,
        }
    }

    fn whole(message: String) -> Invalid {
        Invalid {
            node: None,
            message,
        }
    }
}

impl KdTree {
    /// Checks the tree against `mesh`; the error names the first problem found (and, for a tree
    /// read from a file, the file's line of the node at fault).
    pub fn validate(&self, mesh: &TriangleMesh) -> Result<(), String> {
        self.validate_nodes(mesh)
            .map_err(|e| match self.line_of(e.node) {
                Some(line) => format!("line {line}: {}", e.message),
                None => e.message,
            })
    }

    /// [`KdTree::validate`] for the tree read from the file `path`: the error is
    /// [`TreeError::Invalid`], naming the file and the line of the node at fault.
    pub(crate) fn validate_file(&self, mesh: &TriangleMesh, path: &Path) -> Result<(), TreeError> {
        self.validate_nodes(mesh).map_err(|e| TreeError::Invalid {
            path: path.to_path_buf(),
            line: self.line_of(e.node),
            message: e.message,
        })
    }

    /// The file line of pre-order node `node`, for trees read from text.
    fn line_of(&self, node: Option<usize>) -> Option<usize> {
        node.and_then(|i| self.lines.get(i)).map(|&l| l as usize)
    }

    fn validate_nodes(&self, mesh: &TriangleMesh) -> Result<(), Invalid> {
        if self.triangle_count != mesh.len() {
            return Err(Invalid::whole(format!(
                "tree built for {} triangles, mesh has {}",
                self.triangle_count,
                mesh.len()
            )));
        }
        if self.nodes.is_empty() {
            return Err(Invalid::whole("tree has no nodes".to_string()));
        }
        if let Some(&t) = self.tri_indices.iter().find(|&&t| t as usize >= mesh.len()) {
            return Err(Invalid::whole(format!(
                "triangle index {t} out of range ({})",
                mesh.len()
            )));
        }
        let root = exact_root(self, mesh);
        // The vertices of every triangle side by side: the descent reads them for every node.
        let verts: Vec<[[f32; 3]; 3]> =
            (0..mesh.len() as u32).map(|k| tri_verts(mesh, k)).collect();
        let candidates: Vec<u32> = (0..mesh.len() as u32)
            .filter(|&k| {
                let v = &verts[k as usize];
                !mesh.is_degenerate(k as usize)
                    && (strictly_inside(v, &root) || tri_box_overlap_area(v, &root))
            })
            .collect();
        let mut seen = 0usize;
        self.check(&verts, 0, root, candidates, 0, &mut seen)?;
        if seen != self.nodes.len() {
            return Err(Invalid::whole(format!(
                "{} nodes, only {} reachable from the root",
                self.nodes.len(),
                seen
            )));
        }
        Ok(())
    }

    fn check(
        &self,
        verts: &[[[f32; 3]; 3]],
        i: usize,
        bx: Aabb,
        candidates: Vec<u32>,
        depth: usize,
        seen: &mut usize,
    ) -> Result<(), Invalid> {
        if depth > MAX_DEPTH {
            return Err(Invalid::at(i, format!("node {i} deeper than {MAX_DEPTH}")));
        }
        let Some(&n) = self.nodes.get(i) else {
            return Err(Invalid::at(i, format!("node index {i} out of range")));
        };
        *seen += 1;
        if n.is_leaf() {
            let start = n.offset() as usize;
            let end = start + n.count() as usize;
            let Some(listed) = self.tri_indices.get(start..end) else {
                return Err(Invalid::at(
                    i,
                    format!("leaf {i}: triangle range {start}..{end} out of range"),
                ));
            };
            let mut sorted = Vec::new();
            let listed = if listed.len() > 16 {
                sorted.extend_from_slice(listed);
                sorted.sort_unstable();
                &sorted[..]
            } else {
                listed
            };
            let lists = |t: u32| {
                if listed.len() > 16 {
                    listed.binary_search(&t).is_ok()
                } else {
                    listed.contains(&t)
                }
            };
            for t in candidates {
                if !lists(t) {
                    return Err(Invalid::at(
                        i,
                        format!(
                            "leaf {i} (box {:?}..{:?}) misses triangle {t} which overlaps it",
                            bx.0, bx.1
                        ),
                    ));
                }
            }
            return Ok(());
        }
        let (axis, split) = (n.axis(), n.split());
        if !(split >= bx.0[axis] && split <= bx.1[axis]) {
            return Err(Invalid::at(
                i,
                format!(
                    "node {i}: split {split} on axis {axis} outside its box {:?}..{:?}",
                    bx.0, bx.1
                ),
            ));
        }
        let right = n.right() as usize;
        if right <= i + 1 || right >= self.nodes.len() {
            return Err(Invalid::at(
                i,
                format!("node {i}: right child {right} out of order or range"),
            ));
        }
        let (lb, rb) = split_box(&bx, axis, split);
        let (mut l, mut r) = (
            Vec::with_capacity(candidates.len()),
            Vec::with_capacity(candidates.len()),
        );
        for t in candidates {
            let v = verts[t as usize];
            let lo = v[0][axis].min(v[1][axis]).min(v[2][axis]);
            let hi = v[0][axis].max(v[1][axis]).max(v[2][axis]);
            // `t` meets this node's box with positive area, in a set open within its plane. A
            // triangle not lying in the split plane on one side of it meets that child the same
            // way (the set is not inside the plane) and not the other (whose open box is beyond
            // the plane): only triangles crossing the plane need the overlap test.
            if hi <= split && lo < split {
                l.push(t);
                continue;
            }
            if lo >= split && hi > split {
                r.push(t);
                continue;
            }
            let in_plane = lo == split && hi == split;
            if in_plane {
                // Lying in the split plane: required on one side, the one that lists it.
                if tri_box_overlap_area(&v, &lb) {
                    if self.lists(i + 1, &lb, t, &v, depth + 1) {
                        l.push(t);
                    } else {
                        r.push(t);
                    }
                }
                continue;
            }
            // Crossing the plane, inside the open box: it meets both children's open boxes
            // (at its vertices on either side).
            if strictly_inside(&v, &bx) {
                l.push(t);
                r.push(t);
                continue;
            }
            // Crossing the plane: it meets at least one child (the set it meets this node's
            // box in is open within its plane, which is not the split plane).
            if !tri_box_overlap_area(&v, &lb) {
                r.push(t);
                continue;
            }
            l.push(t);
            if tri_box_overlap_area(&v, &rb) {
                r.push(t);
            }
        }
        let mut seen_l = 0;
        let mut seen_r = 0;
        let (a, b) = if l.len() + r.len() > 4096 {
            rayon::join(
                || self.check(verts, i + 1, lb, l, depth + 1, &mut seen_l),
                || self.check(verts, right, rb, r, depth + 1, &mut seen_r),
            )
        } else {
            (
                self.check(verts, i + 1, lb, l, depth + 1, &mut seen_l),
                self.check(verts, right, rb, r, depth + 1, &mut seen_r),
            )
        };
        a?;
        b?;
        // In pre-order the right subtree starts right after the left one.
        if right != i + 1 + seen_l {
            return Err(Invalid::at(
                i,
                format!("node {i}: right child {right} does not follow its left subtree"),
            ));
        }
        *seen += seen_l + seen_r;
        Ok(())
    }
}

/// True when every vertex of `v` lies in the open box `bx`: then so does the whole triangle, and
/// a non-degenerate one meets it with positive area (what [`tri_box_overlap_area`] decides, found
/// without its 13 axes).
#[inline]
fn strictly_inside(v: &[[f32; 3]; 3], bx: &Aabb) -> bool {
    v.iter()
        .all(|p| (0..3).all(|k| p[k] > bx.0[k] && p[k] < bx.1[k]))
}

impl KdTree {
    /// True when some leaf of the subtree at `i` (box `bx`) whose closed box touches triangle
    /// `t` lists it. Malformed subtrees answer false; `check` reports them. The descent prunes by
    /// the triangle's bounds (never a box it touches) and tests the leaves listing it exactly.
    fn lists(&self, i: usize, bx: &Aabb, t: u32, v: &[[f32; 3]; 3], depth: usize) -> bool {
        let Some(&n) = self.nodes.get(i) else {
            return false;
        };
        if depth > MAX_DEPTH {
            return false;
        }
        if n.is_leaf() {
            let start = n.offset() as usize;
            let end = start + n.count() as usize;
            return self
                .tri_indices
                .get(start..end)
                .is_some_and(|l| l.contains(&t))
                && tri_box_overlap(v, bx);
        }
        let (axis, split) = (n.axis(), n.split());
        let lo = v[0][axis].min(v[1][axis]).min(v[2][axis]);
        let hi = v[0][axis].max(v[1][axis]).max(v[2][axis]);
        let (lb, rb) = split_box(bx, axis, split);
        (lo <= split && self.lists(i + 1, &lb, t, v, depth + 1))
            || (hi >= split && self.lists(n.right() as usize, &rb, t, v, depth + 1))
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::accel::kdtree::{BuildMethod, KdTree};
    use crate::mesh::TriangleMesh;

    fn mesh() -> TriangleMesh {
        TriangleMesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [3.0, 0.0, 0.0],
                [4.0, 0.0, 0.0],
                [4.0, 1.0, 1.0],
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        )
    }

    #[test]
    fn built_trees_are_valid() {
        let m = mesh();
        for method in [BuildMethod::Midpoint, BuildMethod::Sah] {
            KdTree::build(&m, method).validate(&m).expect("valid");
        }
    }

    #[test]
    fn a_leaf_missing_an_overlapping_triangle_is_reported() {
        let text =
            "inner{ 0 0 0 4 1 1 ; 1 2 0 2 }\nleaf{ 0 0 0 2 1 1 ; }\nleaf{ 2 0 0 4 1 1 ; 1 }\n";
        let tree = KdTree::read_text(text.as_bytes(), Path::new("v.kd"), 2).expect("read");
        let err = tree.validate(&mesh()).expect_err("triangle 0 missing");
        assert!(err.contains("misses triangle 0"), "{err}");
    }

    #[test]
    fn errors_of_a_tree_from_a_file_name_the_line_of_the_node() {
        // The left child is on line 3, after the right one: node 1 in pre-order, line 3.
        let text =
            "inner{ 0 0 0 4 1 1 ; 2 1 0 2 }\nleaf{ 2 0 0 4 1 1 ; 1 }\nleaf{ 0 0 0 2 1 1 ; }\n";
        let path = Path::new("v.kd");
        let tree = KdTree::read_text(text.as_bytes(), path, 2).expect("read");
        let err = tree.validate(&mesh()).expect_err("triangle 0 missing");
        assert!(
            err.starts_with("line 3: ") && err.contains("misses triangle 0"),
            "{err}"
        );
        let err = tree
            .validate_file(&mesh(), path)
            .expect_err("triangle 0 missing");
        assert!(
            err.to_string().starts_with("v.kd:3: invalid tree: "),
            "{err}"
        );
        // A problem of the whole tree names no line.
        let other = TriangleMesh::new(vec![[0.0; 3]; 3], vec![[0, 1, 2]]);
        let tree = KdTree::read_text(text.as_bytes(), path, 1).expect_err("index 1 of 1");
        assert!(tree.to_string().starts_with("v.kd:2:"), "{tree}");
        let tree =
            KdTree::read_text("leaf{ 0 0 0 1 1 1 ; 0 }\n".as_bytes(), path, 2).expect("read");
        let err = tree.validate_file(&other, path).expect_err("count");
        assert!(
            err.to_string()
                .starts_with("v.kd: invalid tree: tree built for 2"),
            "{err}"
        );
    }

    /// Triangle 0 lies in the plane x = 2 (the split below); triangle 1 is at x = 3..4.
    fn planar_mesh() -> TriangleMesh {
        TriangleMesh::new(
            vec![
                [2.0, 0.0, 0.0],
                [2.0, 1.0, 0.0],
                [2.0, 0.0, 1.0],
                [3.0, 0.0, 0.0],
                [4.0, 0.0, 0.0],
                [4.0, 1.0, 1.0],
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        )
    }

    #[test]
    fn a_triangle_in_the_split_plane_may_be_listed_on_either_side_only() {
        let m = planar_mesh();
        for text in [
            "inner{ 2 0 0 4 1 1 ; 1 2 0 2 }\nleaf{ 2 0 0 2 1 1 ; 0 }\nleaf{ 2 0 0 4 1 1 ; 1 }\n",
            "inner{ 2 0 0 4 1 1 ; 1 2 0 2.5 }\nleaf{ 2 0 0 2.5 1 1 ; 0 }\nleaf{ 2.5 0 0 4 1 1 ; 1 }\n",
            "inner{ 2 0 0 4 1 1 ; 1 2 0 2 }\nleaf{ 2 0 0 2 1 1 ; }\nleaf{ 2 0 0 4 1 1 ; 0 1 }\n",
        ] {
            let tree = KdTree::read_text(text.as_bytes(), Path::new("p.kd"), 2).expect("read");
            tree.validate(&m).expect("valid");
        }
    }

    #[test]
    fn a_triangle_in_the_split_plane_listed_on_neither_side_is_reported() {
        let text =
            "inner{ 2 0 0 4 1 1 ; 1 2 0 2 }\nleaf{ 2 0 0 2 1 1 ; }\nleaf{ 2 0 0 4 1 1 ; 1 }\n";
        let tree = KdTree::read_text(text.as_bytes(), Path::new("p.kd"), 2).expect("read");
        let err = tree
            .validate(&planar_mesh())
            .expect_err("triangle 0 missing");
        assert!(err.contains("misses triangle 0"), "{err}");
    }

    #[test]
    fn a_triangle_only_touching_a_leaf_need_not_be_listed() {
        // Triangle 0 of `mesh()` touches x = 1 only at a vertex; the right leaf omits it.
        let text =
            "inner{ 0 0 0 4 1 1 ; 1 2 0 1 }\nleaf{ 0 0 0 1 1 1 ; 0 }\nleaf{ 1 0 0 4 1 1 ; 1 }\n";
        let tree = KdTree::read_text(text.as_bytes(), Path::new("v.kd"), 2).expect("read");
        tree.validate(&mesh()).expect("valid");
    }

    #[test]
    fn a_split_outside_the_box_is_reported() {
        let text =
            "inner{ 0 0 0 4 1 1 ; 1 2 0 7 }\nleaf{ 0 0 0 2 1 1 ; 0 1 }\nleaf{ 2 0 0 4 1 1 ; }\n";
        let tree = KdTree::read_text(text.as_bytes(), Path::new("v.kd"), 2).expect("read");
        let err = tree.validate(&mesh()).expect_err("split outside");
        assert!(err.contains("outside its box"), "{err}");
    }

    #[test]
    fn a_tree_for_another_mesh_is_reported() {
        let tree = KdTree::build(&mesh(), BuildMethod::Sah);
        let other = TriangleMesh::new(vec![[0.0; 3]; 3], vec![[0, 1, 2]]);
        assert!(tree.validate(&other).is_err());
    }
}
