//! PLACEHOLDER until the mesh module lands: triangle meshes as flat vertex and index arrays.

use std::path::{Path, PathBuf};

use glam::Vec3;

/// A triangle mesh: flat vertex and index buffers.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub vertices: Vec<[f32; 3]>,
    /// Vertex indices, three per triangle; triangle k is the k-th face of the file.
    pub indices: Vec<[u32; 3]>,
}

/// A mesh file that cannot be loaded.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be read or parsed.
    #[error("{}: {message}", file.display())]
    Load {
        /// The OBJ file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
}

impl TriangleMesh {
    /// Loads an OBJ file.
    pub fn load_obj(path: &Path) -> Result<TriangleMesh, MeshError> {
        let (models, _) = tobj::load_obj(
            path,
            &tobj::LoadOptions {
                triangulate: true,
                single_index: true,
                ..Default::default()
            },
        )
        .map_err(|e| MeshError::Load {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let mut mesh = TriangleMesh::default();
        for m in models {
            let base = mesh.vertices.len() as u32;
            mesh.vertices
                .extend(m.mesh.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
            mesh.indices.extend(
                m.mesh
                    .indices
                    .chunks_exact(3)
                    .map(|c| [c[0] + base, c[1] + base, c[2] + base]),
            );
        }
        Ok(mesh)
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// The three corners of triangle `k`.
    pub fn triangle(&self, k: usize) -> [Vec3; 3] {
        self.indices[k].map(|i| Vec3::from(self.vertices[i as usize]))
    }

    /// Unnormalised geometric normal `(b − a) × (c − a)` of triangle `k`.
    pub fn geometric_normal(&self, k: usize) -> Vec3 {
        let [a, b, c] = self.triangle(k);
        (b - a).cross(c - a)
    }
}
