//! kD tree over a [`TriangleMesh`]: the accelerator of the kD-intersect stage.
//!
//! Split like Embree/obvhs: `node` (8-byte node layout), `build_midpoint` (the assignment's
//! longest-axis midpoint rule), `build_binned` (binned SAH for the nodes of more than 1,024
//! triangles of the default SAH tree: in parallel over triangles at the top, then subtrees as
//! sequential tasks) over `build_sah` (Wald & Havran 2006, O(N log N), the exact sweep below),
//! `traverse` ([`KdAccel`]: closest and occluded queries; its SSE2 lanes are in [`crate::simd`],
//! the crate's one `unsafe` module), `text` (the SPEC §6 text
//! format), `validate` and `stats`. The builders read mesh vertices and triangle indices and
//! write a [`KdTree`] (structure only); [`KdAccel::new`] reads a tree and its mesh and writes the
//! traversal-ready copy; queries read one ray (origin, unnormalised direction, `t_max`) and
//! write a [`TriHit`] or a shadow bit.
//!
//! Tree layout: nodes in depth-first pre-order (left child = next node, right child stored in
//! the node), leaves referring to a contiguous run of a triangle-index list. Degenerate
//! triangles ([`TriangleMesh::is_degenerate`]) are left out of every tree, so they are never
//! hit. A [`KdTree`] holds no mesh data; [`KdAccel`] adds a copy of the triangle vertices in
//! leaf order, so traversal touches one contiguous array.

mod build_binned;
mod build_midpoint;
mod build_sah;
pub(crate) mod node;
mod overlap;
mod reframe;
mod stats;
mod text;
mod traverse;
mod validate;

use glam::Vec3;

use crate::mesh::TriangleMesh;
pub use node::KdNode;
use overlap::Aabb;
pub use stats::KdStats;
pub use text::TreeError;
pub use traverse::{BundleCounts, KdAccel};

/// Deepest tree the builders produce (the SAH builder also stops at `8 + 1.3·log2 N`, as pbrt).
pub(crate) const MAX_BUILD_DEPTH: usize = 40;
/// Deepest tree accepted from a file (traversal's fixed stack holds one entry per level).
pub(crate) const MAX_DEPTH: usize = 63;
/// SAH cost of one traversal step.
pub(crate) const COST_TRAVERSAL: f32 = 1.0;
/// SAH cost of one ray/triangle test.
pub(crate) const COST_INTERSECT: f32 = 1.5;

/// How to build a tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildMethod {
    /// The assignment's rule: split the longest axis at its midpoint.
    Midpoint,
    /// Surface-area heuristic (Wald & Havran 2006); the default.
    #[default]
    Sah,
}

/// Everything that decides what [`KdTree::build`] makes with `method`, as text: part of the tree
/// cache's key ([`crate::accel::cache::CacheKey`]), so changing a builder constant invalidates entries.
pub(crate) fn builder_settings(method: BuildMethod) -> String {
    match method {
        BuildMethod::Midpoint => format!("midpoint v1 depth {MAX_BUILD_DEPTH}"),
        BuildMethod::Sah => format!(
            "sah v1 depth {MAX_BUILD_DEPTH} traversal {COST_TRAVERSAL} intersect {COST_INTERSECT} {} {}",
            build_sah::SETTINGS,
            build_binned::SETTINGS
        ),
    }
}

/// Where a build's time went ([`KdTree::build_profiled`]). The parallel phases are summed over
/// threads, so on more than one thread they can add up to more than `wall_seconds`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildPhases {
    /// Listing the non-degenerate triangles and the mesh bounds (wall time).
    pub input_seconds: f64,
    /// Triangle bounds and their union (wall time).
    pub bounds_seconds: f64,
    /// Binning and partitioning the nodes built in parallel over triangles (thread time).
    pub top_seconds: f64,
    /// The sequential subtree tasks below them (thread time).
    pub task_seconds: f64,
    /// Number of sequential subtree tasks.
    pub tasks: usize,
    /// The whole build (wall time).
    pub wall_seconds: f64,
}

/// Closest hit of a ray: distance `t` (in units of the direction's length) and triangle index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter of the hit, `0 < t < t_max`.
    pub t: f32,
    /// Index of the triangle hit (its face number in the OBJ file).
    pub tri: u32,
}

/// A kD tree over a triangle mesh (structure only: it holds no vertices). See the module docs
/// for the layout; trace rays through [`KdAccel`]. Two trees are equal when their nodes, lists,
/// root boxes and triangle counts are (the file lines of a tree read from text do not count).
#[derive(Clone, Debug)]
pub struct KdTree {
    /// Nodes in depth-first pre-order; node 0 is the root.
    pub(crate) nodes: Vec<KdNode>,
    /// Triangle indices of all leaves, leaf after leaf.
    pub(crate) tri_indices: Vec<u32>,
    /// Root box: the mesh bounds for built trees, the file's root box for trees read from text.
    pub(crate) root: Aabb,
    /// Number of triangles of the mesh the tree refers to (bound on every index).
    pub(crate) triangle_count: usize,
    /// For a tree read from text, the 1-based file line of each node (pre-order), so that
    /// [`KdTree::validate`] names lines; empty for built trees.
    pub(crate) lines: Vec<u32>,
}

impl PartialEq for KdTree {
    fn eq(&self, other: &KdTree) -> bool {
        self.nodes == other.nodes
            && self.tri_indices == other.tri_indices
            && self.root == other.root
            && self.triangle_count == other.triangle_count
    }
}

impl KdTree {
    /// Builds a tree over `mesh` (rayon splits the upper levels across threads; the result does
    /// not depend on the thread count).
    pub fn build(mesh: &TriangleMesh, method: BuildMethod) -> KdTree {
        KdTree::build_profiled(mesh, method).0
    }

    /// [`KdTree::build`], also returning where the build's time went (for the SAH builder;
    /// the midpoint builder reports its whole time as `wall_seconds` only).
    pub fn build_profiled(mesh: &TriangleMesh, method: BuildMethod) -> (KdTree, BuildPhases) {
        let start = std::time::Instant::now();
        let (root, tris) = build_input(mesh);
        let input_seconds = start.elapsed().as_secs_f64();
        let (flat, mut phases) = match method {
            BuildMethod::Midpoint => (
                build_midpoint::build(mesh, root, tris),
                BuildPhases::default(),
            ),
            BuildMethod::Sah => build_binned::build(mesh, root, tris),
        };
        phases.input_seconds = input_seconds;
        phases.wall_seconds = start.elapsed().as_secs_f64();
        (KdTree::from_flat(flat, root, mesh), phases)
    }

    /// The SAH tree with the exact event sweep at every level (Wald & Havran 2006), no binning:
    /// the reference [`BuildMethod::Sah`]'s binned upper levels are measured against.
    pub fn build_sah_exact(mesh: &TriangleMesh) -> KdTree {
        let (root, tris) = build_input(mesh);
        KdTree::from_flat(build_sah::build(mesh, root, tris), root, mesh)
    }

    /// A builder's output over `mesh` as a tree with root box `root`.
    fn from_flat(flat: build_sah::Flat, root: Aabb, mesh: &TriangleMesh) -> KdTree {
        KdTree {
            nodes: flat.nodes,
            tri_indices: flat.tris,
            root,
            triangle_count: mesh.len(),
            lines: Vec::new(),
        }
    }

    /// Root box `(min, max)`: the mesh bounds for built trees; for trees read from text, the
    /// file's root box (traversal and `validate` join it with the exact mesh bounds).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (Vec3::from_array(self.root.0), Vec3::from_array(self.root.1))
    }

    /// The nodes in pre-order (node 0 is the root).
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// Triangle indices of the leaf `node` (empty for inner nodes).
    pub(crate) fn leaf_triangles(&self, node: usize) -> &[u32] {
        let n = self.nodes[node];
        if !n.is_leaf() {
            return &[];
        }
        let start = n.offset() as usize;
        &self.tri_indices[start..start + n.count() as usize]
    }
}

/// What every builder starts from: the mesh's bounds as the root box, and its non-degenerate
/// triangles in ascending order (degenerate ones are never hit, so no tree holds them).
fn build_input(mesh: &TriangleMesh) -> (Aabb, Vec<u32>) {
    let (lo, hi) = mesh.bounds();
    let tris = (0..mesh.len())
        .filter(|&k| !mesh.is_degenerate(k))
        .map(|k| k as u32)
        .collect();
    ((lo.to_array(), hi.to_array()), tris)
}

/// Root box used for traversal and validation: the stored root box joined with the mesh bounds.
pub(crate) fn exact_root(tree: &KdTree, mesh: &TriangleMesh) -> Aabb {
    let (lo, hi) = mesh.bounds();
    let mut r = tree.root;
    for k in 0..3 {
        r.0[k] = r.0[k].min(lo[k]);
        r.1[k] = r.1[k].max(hi[k]);
    }
    r
}

/// The two children boxes of `bx` split on `axis` at `split`.
#[inline]
pub(crate) fn split_box(bx: &Aabb, axis: usize, split: f32) -> (Aabb, Aabb) {
    let mut l = *bx;
    let mut r = *bx;
    l.1[axis] = split;
    r.0[axis] = split;
    (l, r)
}

/// Surface area of a box.
#[inline]
pub(crate) fn area(bx: &Aabb) -> f32 {
    let d = [bx.1[0] - bx.0[0], bx.1[1] - bx.0[1], bx.1[2] - bx.0[2]];
    2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
}

/// Vertices of triangle `k` as arrays.
#[inline]
pub(crate) fn tri_verts(mesh: &TriangleMesh, k: u32) -> [[f32; 3]; 3] {
    mesh.indices[k as usize].map(|i| mesh.vertices[i as usize])
}
