//! [`TriangleMesh`]: the f32 triangles of the render frame, as flat `Pod` arrays — what the kD
//! tree is built over and the triangle tests read. Mesh files become one through
//! [`crate::mesh::ObjMesh::to_frame`].

use glam::{DVec3, Vec3};

/// An indexed triangle mesh stored as flat, `Pod` arrays (castable with `bytemuck`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub vertices: Vec<[f32; 3]>,
    /// Vertex indices of each triangle; triangle `k` is the `k`-th face of the source file.
    pub indices: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// Builds a mesh from vertex and index arrays (no validation beyond debug assertions).
    pub fn new(vertices: Vec<[f32; 3]>, indices: Vec<[u32; 3]>) -> TriangleMesh {
        debug_assert!(
            indices
                .iter()
                .flatten()
                .all(|&i| (i as usize) < vertices.len())
        );
        TriangleMesh { vertices, indices }
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// True when the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// The three vertices of triangle `k`. Panics if `k` is out of range.
    #[inline]
    pub fn triangle(&self, k: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[k];
        [
            Vec3::from_array(self.vertices[a as usize]),
            Vec3::from_array(self.vertices[b as usize]),
            Vec3::from_array(self.vertices[c as usize]),
        ]
    }

    /// Geometric normal of triangle `k`: the UNNORMALISED cross product `(b - a) × (c - a)`
    /// (its length is twice the area; zero for degenerate triangles).
    pub(crate) fn geometric_normal(&self, k: usize) -> Vec3 {
        let [a, b, c] = self.triangle(k);
        (b - a).cross(c - a)
    }

    /// Unit geometric normal of triangle `k`. When the f32 cross product's square length is a
    /// normal number it is normalised in f32 (the bits every valid scene had); when it underflows
    /// or overflows (a tiny triangle, or one spanning ±1e19) the cross product is taken in f64 and
    /// scaled by its largest component before normalising, so a huge triangle's normal does not
    /// overflow to NaN.
    #[inline]
    pub(crate) fn unit_normal(&self, k: usize) -> Vec3 {
        let n = self.geometric_normal(k);
        let l2 = n.length_squared();
        if l2.is_normal() && l2.is_finite() {
            return n.normalize();
        }
        let [a, b, c] = self.triangle(k).map(|v| v.as_dvec3());
        let n = (b - a).cross(c - a);
        (n / n.abs().max_element()).normalize().as_vec3()
    }

    /// True when triangle `k` has zero area: its edge cross product, computed in `f64` from the
    /// `f32` coordinates, is exactly zero. Degenerate triangles keep their index but are never
    /// hit (the kD tree leaves them out and the brute-force reference skips them).
    pub fn is_degenerate(&self, k: usize) -> bool {
        let [a, b, c] = self.triangle(k).map(|v| v.as_dvec3());
        (b - a).cross(c - a) == DVec3::ZERO
    }

    /// Axis-aligned bounds `(min, max)` of all vertices; `(0, 0)` for a mesh without vertices.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        if self.vertices.is_empty() {
            return (Vec3::ZERO, Vec3::ZERO);
        }
        self.vertices.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), v| {
                let v = Vec3::from_array(*v);
                (lo.min(v), hi.max(v))
            },
        )
    }
}
