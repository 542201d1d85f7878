//! PLACEHOLDER until the kD tree lands: a brute-force stand-in with the kD tree's API.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::geometry::triangle::intersect_moller_trumbore;
use crate::mesh::TriangleMesh;

/// How to build a tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildMethod {
    /// The assignment's midpoint rule.
    Midpoint,
    /// Surface area heuristic.
    Sah,
}

/// A triangle hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter.
    pub t: f32,
    /// Triangle index.
    pub tri: u32,
}

/// A tree file that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum TreeError {
    /// Anything.
    #[error("{}:{line}: {message}", file.display())]
    Parse {
        /// File.
        file: PathBuf,
        /// Line.
        line: usize,
        /// Message.
        message: String,
    },
}

/// Tree statistics.
#[derive(Clone, Debug, Default)]
pub struct KdStats {
    /// Nodes.
    pub nodes: usize,
}

impl std::fmt::Display for KdStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "nodes {}", self.nodes)
    }
}

/// Placeholder tree.
#[derive(Clone, Debug, PartialEq)]
pub struct KdTree {
    n: usize,
}

impl KdTree {
    /// Builds.
    pub fn build(mesh: &TriangleMesh, _method: BuildMethod) -> KdTree {
        KdTree { n: mesh.len() }
    }
    /// Closest hit.
    pub fn intersect_closest(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> Option<TriHit> {
        let mut best: Option<TriHit> = None;
        let mut tm = t_max;
        for k in 0..self.n {
            if let Some(t) = intersect_moller_trumbore(origin, dir, mesh.triangle(k), tm) {
                tm = t;
                best = Some(TriHit { t, tri: k as u32 });
            }
        }
        best
    }
    /// Any hit.
    pub fn intersect_occluded(
        &self,
        mesh: &TriangleMesh,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
    ) -> bool {
        (0..self.n)
            .any(|k| intersect_moller_trumbore(origin, dir, mesh.triangle(k), t_max).is_some())
    }
    /// Validates.
    pub fn validate(&self, _mesh: &TriangleMesh) -> Result<(), String> {
        Ok(())
    }
    /// Stats.
    pub fn stats(&self, _mesh: &TriangleMesh) -> KdStats {
        KdStats { nodes: 1 }
    }
    /// Reads.
    pub fn read_text(
        _reader: impl BufRead,
        source: &Path,
        triangle_count: usize,
    ) -> Result<KdTree, TreeError> {
        let _ = source;
        Ok(KdTree { n: triangle_count })
    }
    /// Loads.
    pub fn load_text(path: &Path, triangle_count: usize) -> Result<KdTree, TreeError> {
        let f = std::fs::File::open(path).map_err(|e| TreeError::Parse {
            file: path.into(),
            line: 0,
            message: e.to_string(),
        })?;
        Self::read_text(std::io::BufReader::new(f), path, triangle_count)
    }
    /// Writes.
    pub fn write_text(&self, _w: impl Write) -> std::io::Result<()> {
        Ok(())
    }
}
