//! Ray traversal of the kD tree: the closest-hit and occluded (any-hit) kernels.
//!
//! Reads the tree's nodes and leaf-ordered triangle copy, and one ray (origin, unnormalised
//! direction, `t_max`). Front-to-back, stack-based (fixed array, no allocation per ray), with a
//! reciprocal direction and the watertight test's shear computed once per ray.
//!
//! Robustness: slab and split-plane distances are computed as `(plane - o) * (1 / d)`. For a
//! `±0.0` component this is `±inf`, which orders the children correctly; the only NaN case
//! (`0 * inf`, origin exactly on the plane of a parallel ray) is detected and both children are
//! visited. Interval comparisons use a small relative slack (`SLACK`) so rounding in the plane
//! distances never drops a leaf, and a node is skipped only when its entry distance is beyond
//! the best hit by more than that slack: ties at leaf boundaries still find the lowest triangle
//! index among equal-`t` hits.

use glam::Vec3;

use super::{KdTree, MAX_DEPTH, TriHit};
use crate::geometry::triangle::WatertightRay;
use crate::mesh::TriangleMesh;

/// Relative slack on ray-interval comparisons (plane distances carry ~3 ulps of error).
const SLACK: f32 = 1e-4;
const HI: f32 = 1.0 + SLACK;
const LO: f32 = 1.0 - SLACK;

/// One pending far child: node index and ray interval.
#[derive(Clone, Copy, Default)]
struct Entry {
    node: u32,
    t0: f32,
    t1: f32,
}

/// Everything a traversal needs per ray.
struct Ray {
    woop: WatertightRay,
    origin: [f32; 3],
    inv: [f32; 3],
}

impl Ray {
    #[inline(always)]
    fn new(origin: Vec3, dir: Vec3) -> Option<Ray> {
        let woop = WatertightRay::new(origin, dir)?;
        Some(Ray {
            woop,
            origin: origin.to_array(),
            inv: (Vec3::ONE / dir).to_array(),
        })
    }

    /// Clips `[0, t_max]` to the root box; `None` when the ray misses it. NaN slab distances
    /// (origin on a face of a parallel ray) are ignored by `max`/`min`, i.e. treated as inside.
    #[inline(always)]
    fn clip(&self, bx: &([f32; 3], [f32; 3]), t_max: f32) -> Option<(f32, f32)> {
        let mut t0 = 0.0f32;
        let mut t1 = t_max;
        for a in 0..3 {
            let ta = (bx.0[a] - self.origin[a]) * self.inv[a];
            let tb = (bx.1[a] - self.origin[a]) * self.inv[a];
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        (t0 <= t1 * HI).then_some((t0, t1))
    }
}

/// What a leaf visit tells the traversal loop.
trait Visitor {
    /// Tests the leaf's entries; returns true to stop traversal.
    fn leaf(&mut self, tree: &KdTree, tris: &[[[f32; 3]; 3]], start: usize, end: usize) -> bool;
    /// Current cull distance (nodes entered beyond it are skipped).
    fn cull(&self) -> f32;
}

struct Closest<'a> {
    ray: &'a WatertightRay,
    t_max: f32,
    best: Option<TriHit>,
}

impl Visitor for Closest<'_> {
    #[inline(always)]
    fn leaf(&mut self, tree: &KdTree, tris: &[[[f32; 3]; 3]], start: usize, end: usize) -> bool {
        for (&[p0, p1, p2], &tri) in tris[start..end].iter().zip(&tree.tri_indices[start..end]) {
            // Accept equal t too, so ties can go to the lower index.
            let limit = match self.best {
                Some(b) => b.t.next_up(),
                None => self.t_max,
            };
            if let Some(t) = self.ray.intersect(p0, p1, p2, limit)
                && self.best.is_none_or(|b| t < b.t || tri < b.tri)
            {
                self.best = Some(TriHit { t, tri });
            }
        }
        false
    }

    #[inline(always)]
    fn cull(&self) -> f32 {
        match self.best {
            Some(b) => b.t * HI,
            None => f32::INFINITY,
        }
    }
}

struct Occluded<'a> {
    ray: &'a WatertightRay,
    t_max: f32,
}

impl Visitor for Occluded<'_> {
    #[inline(always)]
    fn leaf(&mut self, _: &KdTree, tris: &[[[f32; 3]; 3]], start: usize, end: usize) -> bool {
        tris[start..end]
            .iter()
            .any(|&[p0, p1, p2]| self.ray.intersect(p0, p1, p2, self.t_max).is_some())
    }

    #[inline(always)]
    fn cull(&self) -> f32 {
        f32::INFINITY
    }
}

impl KdTree {
    /// Closest hit with `0 < t < t_max` (strict), `t` in units of `dir`'s length (`dir` need not
    /// be normalised). Equal `t` resolves to the lowest triangle index, exactly as the
    /// brute-force reference [`crate::geometry::triangle::intersect_all_closest`] does, with
    /// bit-identical `t`.
    pub fn intersect_closest(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> Option<TriHit> {
        let ray = Ray::new(origin, dir)?;
        let mut v = Closest {
            ray: &ray.woop,
            t_max,
            best: None,
        };
        self.traverse(mesh, &ray, t_max, &mut v);
        v.best
    }

    /// True when any triangle is hit with `0 < t < t_max`; stops at the first hit found.
    pub fn intersect_occluded(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> bool {
        let Some(ray) = Ray::new(origin, dir) else {
            return false;
        };
        let mut v = Occluded {
            ray: &ray.woop,
            t_max,
        };
        self.traverse(mesh, &ray, t_max, &mut v)
    }

    /// Front-to-back traversal; returns true if the visitor asked to stop.
    #[inline(always)]
    fn traverse<V: Visitor>(&self, mesh: &TriangleMesh, ray: &Ray, t_max: f32, v: &mut V) -> bool {
        if t_max.is_nan() || t_max <= 0.0 {
            return false;
        }
        let prep = self.prepared(mesh);
        let Some((t0, t1)) = ray.clip(&prep.root, t_max) else {
            return false;
        };
        let nodes = &self.nodes[..];
        let mut stack = [Entry::default(); MAX_DEPTH + 1];
        let mut sp = 0usize;
        let mut cur = Entry { node: 0, t0, t1 };
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
                let split = n.split();
                let oa = ray.origin[axis];
                let ia = ray.inv[axis];
                let left = e.node + 1;
                let right = n.right();
                let tp = (split - oa) * ia;
                if tp.is_nan() {
                    // Parallel ray lying in the split plane: both sides.
                    if sp < stack.len() {
                        stack[sp] = Entry { node: right, ..e };
                        sp += 1;
                    }
                    e.node = left;
                    continue;
                }
                let below = oa < split || (oa == split && ia < 0.0);
                let (near, far) = if below { (left, right) } else { (right, left) };
                if tp > e.t1 * HI || tp <= 0.0 {
                    e.node = near;
                } else if tp < e.t0 * LO {
                    e.node = far;
                } else {
                    if sp < stack.len() {
                        stack[sp] = Entry {
                            node: far,
                            t0: tp,
                            t1: e.t1,
                        };
                        sp += 1;
                    }
                    e.node = near;
                    e.t1 = tp;
                }
            };
            if let Some(n) = leaf {
                let start = n.offset() as usize;
                let end = start + n.count() as usize;
                if v.leaf(self, &prep.tris, start, end) {
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

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::Vec3;

    use crate::accel::kdtree::{BuildMethod, KdTree, TriHit};
    use crate::mesh::TriangleMesh;

    /// Triangles 0 and 1 are identical and lie in the plane x = 0.
    fn twin_mesh() -> TriangleMesh {
        TriangleMesh::new(
            vec![
                [0.0, -1.0, -1.0],
                [0.0, 1.0, -1.0],
                [0.0, 0.0, 1.0],
                [-1.0, -1.0, -1.0],
                [1.0, 1.0, 1.0],
                [1.0, 1.0, 1.0],
            ],
            vec![[0, 1, 2], [0, 1, 2], [3, 4, 5]],
        )
    }

    #[test]
    fn tie_at_a_leaf_boundary_returns_the_lowest_index() {
        // Hand-made tree: the near leaf (x <= 0) lists only triangle 1, the far leaf only 0.
        let text = "inner{ -1 -1 -1 1 1 1 ; 1 2 0 0 }\nleaf{ -1 -1 -1 0 1 1 ; 1 }\nleaf{ 0 -1 -1 1 1 1 ; 0 }\n";
        let mesh = twin_mesh();
        let tree = KdTree::read_text(text.as_bytes(), Path::new("tie.kd"), 3).expect("read");
        let h = tree.intersect_closest(&mesh, Vec3::new(-1.0, 0.0, 0.0), Vec3::X, f32::INFINITY);
        assert_eq!(h, Some(TriHit { t: 1.0, tri: 0 }));
        let h = tree.intersect_closest(
            &mesh,
            Vec3::new(1.0, 0.0, 0.0),
            -Vec3::X * 4.0,
            f32::INFINITY,
        );
        assert_eq!(h, Some(TriHit { t: 0.25, tri: 0 }));
    }

    #[test]
    fn axis_parallel_rays_with_signed_zeros_and_origins_on_planes() {
        let mesh = twin_mesh();
        for method in [BuildMethod::Midpoint, BuildMethod::Sah] {
            let tree = KdTree::build(&mesh, method);
            for zero in [0.0f32, -0.0] {
                let d = Vec3::new(1.0, zero, zero);
                let h = tree.intersect_closest(&mesh, Vec3::new(-1.0, 0.0, 0.0), d, f32::INFINITY);
                assert_eq!(h, Some(TriHit { t: 1.0, tri: 0 }));
                // Origin on the plane of the triangles: t = 0 is not a hit.
                let h = tree.intersect_closest(&mesh, Vec3::new(0.0, 0.1, 0.1), d, f32::INFINITY);
                assert_eq!(h, None);
                // Parallel ray lying in the plane x = 0 (and on the box face y = -1).
                let p = Vec3::new(zero, zero, 1.0);
                assert_eq!(
                    tree.intersect_closest(&mesh, Vec3::new(0.0, -1.0, -5.0), p, f32::INFINITY),
                    None
                );
                assert!(!tree.intersect_occluded(
                    &mesh,
                    Vec3::new(0.0, -1.0, -5.0),
                    p,
                    f32::INFINITY
                ));
            }
        }
    }

    #[test]
    fn bad_rays_never_hit() {
        let mesh = twin_mesh();
        let tree = KdTree::build(&mesh, BuildMethod::Sah);
        let o = Vec3::new(-1.0, 0.0, 0.0);
        for (d, t_max) in [
            (Vec3::ZERO, f32::INFINITY),
            (Vec3::X, 0.0),
            (Vec3::X, -1.0),
            (Vec3::X, f32::NAN),
            (Vec3::NAN, 5.0),
        ] {
            assert_eq!(tree.intersect_closest(&mesh, o, d, t_max), None);
            assert!(!tree.intersect_occluded(&mesh, o, d, t_max));
        }
    }
}
