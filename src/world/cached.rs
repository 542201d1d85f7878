//! Loading a world's triangles through the tree cache ([`crate::cache`]): the mesh files (OBJ,
//! PLY, glTF: [`crate::mesh::read_bytes`]) are read and hashed once, with their format and any
//! external glTF buffers ([`crate::mesh::cache_sources`]); on a hit the merged mesh and tree come from the cache entry, on a miss they
//! are parsed ([`crate::mesh::obj_fast`]) and built, and the entry is written for the next run.
//!
//! Either way the tree is built in the frame centred on the merged mesh (as `kdtree build` and
//! tree files do) and moved to the camera's frame with [`KdTree::reframed`], so a render with a
//! cold cache, a warm cache or no cache traces the same tree.

use std::time::Instant;

use super::LoadError;
use super::{
    SetupTimes, Triangles, World, check_mesh_path, check_not_empty, load_triangles, tree_source,
};
use crate::accel::kdtree::{BuildMethod, KdAccel, KdTree};
use crate::cache::{CacheKey, CachedTree, TreeCache};
use crate::frame::RenderFrame;
use crate::mesh::{MeshError, ObjMesh, TriangleMesh};
use crate::scene::{Normals, Scene, TreeSource};

/// Bytes of an OBJ file [`crate::mesh::check_file`] checks before the file is read whole.
const OBJ_PREFIX: u64 = 1 << 20;

/// What the cache did for one load.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum CacheStatus {
    /// No cache was given, or the scene has no mesh, or its tree comes from a tree file.
    #[default]
    Unused,
    /// The entry was read.
    Hit,
    /// There was no entry: the tree was built and stored.
    Stored,
}

/// How a world was set up: times, what the cache did, and warnings to show (one line each: an
/// invalid entry that was rebuilt, an entry that could not be written).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Setup {
    /// Load and tree times.
    pub times: SetupTimes,
    /// What the cache did.
    pub cache: CacheStatus,
    /// One line per problem the load recovered from.
    pub warnings: Vec<String>,
}

impl World {
    /// [`World::load_timed`] through a tree cache (`None`: build without one). A corrupt,
    /// truncated or stale entry is rebuilt and overwritten, with a warning in [`Setup`].
    ///
    /// The warnings start with the scene's own ([`crate::scene::mtl::load_warnings`]: MTL keys
    /// and glTF textures not used, scene materials no primitive uses).
    pub fn load_cached(
        scene: &Scene,
        cache: Option<&TreeCache>,
    ) -> Result<(World, Setup), LoadError> {
        let (world, mut setup) = World::load_cached_quietly(scene, cache)?;
        let mut warnings = crate::scene::mtl::load_warnings(scene);
        warnings.append(&mut setup.warnings);
        setup.warnings = warnings;
        Ok((world, setup))
    }

    /// [`World::load_cached`] without the scene's own warnings.
    fn load_cached_quietly(
        scene: &Scene,
        cache: Option<&TreeCache>,
    ) -> Result<(World, Setup), LoadError> {
        let frame = RenderFrame::at(scene.camera.eye);
        if scene.meshes.is_empty() {
            return Ok((World::analytic(scene, frame, None), Setup::default()));
        }
        let source = tree_source(scene)?;
        // Tree files, MTL materials and vertex normals take the full (tobj) path, uncached.
        let uncached = scene
            .meshes
            .iter()
            .any(|m| m.mtl.is_some() || m.normals == Normals::Vertex);
        let method = match source {
            TreeSource::Sah if !uncached => BuildMethod::Sah,
            TreeSource::Midpoint if !uncached => BuildMethod::Midpoint,
            _ => {
                let (t, times) = load_triangles(scene, &frame)?;
                let setup = Setup {
                    times,
                    ..Setup::default()
                };
                return Ok((World::analytic(scene, frame, Some(t)), setup));
            }
        };
        let start = Instant::now();
        let mut files = Vec::with_capacity(scene.meshes.len());
        // Besides each file's bytes: what else its key is made of (format tags, glTF buffers).
        let mut extra = Vec::with_capacity(scene.meshes.len());
        for m in &scene.meshes {
            check_mesh_path(scene, m)?;
            // A look at the first MiB as it streams before the file is read whole: a file that
            // is not OBJ from the start (binary, NULs) fails at once in bounded memory.
            crate::mesh::check_file(&m.path, Some(OBJ_PREFIX))?;
            let bytes = crate::cache::read_parallel(&m.path).map_err(|source| MeshError::Read {
                path: m.path.clone(),
                source,
            })?;
            if cache.is_some() {
                extra.push(crate::mesh::cache_sources(&m.path, &bytes)?);
            }
            files.push(bytes);
        }
        let mut setup = Setup::default();
        let mut cached = None;
        let key = cache.map(|c| {
            let mut slices: Vec<&[u8]> = Vec::with_capacity(files.len());
            for (f, e) in files.iter().zip(&extra) {
                slices.extend(e.first().map(Vec::as_slice));
                slices.push(f);
                slices.extend(e.iter().skip(1).map(Vec::as_slice));
            }
            (c, CacheKey::new(method, &slices))
        });
        let load_seconds = start.elapsed().as_secs_f64();
        let tree_start = Instant::now();
        if let Some((c, key)) = key {
            match c.load(key) {
                Ok(Some(e)) if e.mesh_triangles.len() == scene.meshes.len() => {
                    setup.cache = CacheStatus::Hit;
                    cached = Some(e);
                }
                Ok(Some(_)) => setup.warnings.push(format!(
                    "cache entry {} is for another set of meshes; rebuilding it",
                    c.path_of(key).display()
                )),
                Ok(None) => {}
                Err(e) => setup
                    .warnings
                    .push(format!("{}; rebuilding it", crate::error::chain(&e))),
            }
        }
        let mut parse_seconds = 0.0;
        let entry = match cached {
            Some(e) => e,
            None => {
                let parse_start = Instant::now();
                let merged = merge(scene, &files)?;
                drop(files);
                parse_seconds = parse_start.elapsed().as_secs_f64();
                let entry = build_entry(merged, method)?;
                if let Some((c, key)) = key {
                    match c.store(key, &entry) {
                        Ok(_) => setup.cache = CacheStatus::Stored,
                        Err(e) => setup.warnings.push(format!(
                            "cannot write cache entry {}: {e}",
                            c.path_of(key).display()
                        )),
                    }
                }
                entry
            }
        };
        let triangles = triangles_in(scene, entry, &frame)?;
        setup.times.load_seconds = load_seconds + parse_seconds;
        setup.times.tree_seconds = tree_start.elapsed().as_secs_f64() - parse_seconds;
        Ok((World::analytic(scene, frame, Some(triangles)), setup))
    }
}

/// Parses every mesh and merges them (meshes one after another), with each mesh's triangle
/// count.
fn merge(scene: &Scene, files: &[Vec<u8>]) -> Result<(ObjMesh, Vec<u64>), LoadError> {
    let mut merged = ObjMesh {
        path: scene.meshes[0].path.clone(),
        ..ObjMesh::default()
    };
    let mut counts = Vec::with_capacity(files.len());
    for (m, bytes) in scene.meshes.iter().zip(files) {
        let obj = crate::mesh::obj_fast::read_bytes(&m.path, bytes)?;
        check_not_empty(m, &obj)?;
        let base = merged.positions.len() as u32;
        merged.positions.extend_from_slice(&obj.positions);
        merged
            .indices
            .extend(obj.indices.iter().map(|t| t.map(|i| i + base)));
        counts.push(obj.indices.len() as u64);
    }
    Ok((merged, counts))
}

/// Builds the tree over a merged mesh in the frame centred on it.
pub fn build_entry(
    (mesh, mesh_triangles): (ObjMesh, Vec<u64>),
    method: BuildMethod,
) -> Result<CachedTree, MeshError> {
    let centred = RenderFrame::centered_on(&mesh);
    let tree = KdTree::build(&mesh.to_frame(centred.origin)?, method);
    Ok(CachedTree {
        origin: centred.origin,
        positions: mesh.positions,
        indices: mesh.indices,
        mesh_triangles,
        tree,
    })
}

/// The entry's mesh and tree in `frame`, with the scene's materials.
fn triangles_in(
    scene: &Scene,
    entry: CachedTree,
    frame: &RenderFrame,
) -> Result<Triangles, LoadError> {
    let vertices =
        crate::mesh::frame_vertices(&scene.meshes[0].path, &entry.positions, frame.origin)?;
    let mesh = TriangleMesh::new(vertices, entry.indices);
    let mut first = 0u64;
    let material_ranges = scene
        .meshes
        .iter()
        .zip(&entry.mesh_triangles)
        .map(|(m, &n)| {
            let range = (first as u32, m.material);
            first += n;
            range
        })
        .collect();
    let tree = entry
        .tree
        .into_reframed(&RenderFrame::at(entry.origin), frame);
    let tree = KdAccel::new(tree, &mesh);
    Ok(Triangles {
        mesh,
        world_positions: entry.positions,
        vertex_normals: vec![],
        material_ranges,
        tree,
        source: scene.meshes[0].kdtree.clone(),
    })
}
