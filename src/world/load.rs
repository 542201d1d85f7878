//! The one load path from a scene to its triangles ([`World::load_cached`]): every mesh file
//! (OBJ, PLY, glTF: [`crate::mesh::read_bytes`]) is checked and read as bytes, which with its
//! format tag and external glTF buffers ([`crate::mesh::cache_sources`]) make the tree cache's
//! key ([`crate::accel::cache`]); on a hit the merged mesh and tree come from the entry, on a miss
//! the files are parsed, merged and built — or a tree file is checked and read — and the entry is
//! written for the next run. MTL materials and vertex normals are read in the same parse.
//!
//! A built tree is built in the frame centred on the merged mesh (as `kdtree build` builds it,
//! through [`centred_entry`]) and moved to the camera's frame with [`KdTree::into_reframed`], so
//! a render with a cold cache, a warm cache or no cache traces the same tree.

use std::time::Instant;

use super::LoadError;
use super::{SetupTimes, Triangles, World, check_mesh_path, check_not_empty, tree_source};
use crate::accel::cache::{CacheKey, CachedTree, TreeCache};
use crate::accel::kdtree::{BuildMethod, BuildPhases, KdAccel, KdTree};
use crate::mesh::{MeshError, NO_MATERIAL, ObjMesh, ObjRead, TriangleMesh};
use crate::scene::{Normals, Scene, TreeSource};
use crate::world::frame::RenderFrame;

/// Bytes of an OBJ file [`crate::mesh::check_file`] checks before the file is read whole: a
/// file that is not OBJ from the start (binary, NULs) fails at once in bounded memory.
const OBJ_QUICK: u64 = 64 << 10;
/// Bytes of an OBJ file checked before it is parsed ([`check_mesh_bytes`]; a tree-cache hit,
/// whose entry was made from bytes that passed, skips it). Checking the whole first MiB before
/// reading made a warm-cache render's load 8–36 ms; 64 KiB, 2.4–3.4 ms (Sibenik, warm page cache).
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
    /// `World::load_timed` through a tree cache (`None`: build without one). A corrupt,
    /// truncated or stale entry is rebuilt and overwritten, with a warning in [`Setup`].
    ///
    /// The warnings start with the scene's own (`crate::scene::mtl::load_warnings`: MTL keys
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

    /// [`World::load_cached`] without the scene's own warnings: the one load path of every
    /// scene with meshes (any format, with or without MTL materials and vertex normals, any tree
    /// source, with or without a cache).
    ///
    /// 1. Every mesh file is checked and read as bytes (hashed with its sources for the cache).
    /// 2. A built tree (SAH or midpoint) is looked up in the cache: a hit brings the merged
    ///    mesh and tree, and the files are parsed only if MTL materials or vertex normals need
    ///    more than positions and faces.
    /// 3. Otherwise the files are parsed and merged; the tree is built in the frame centred on
    ///    the merged mesh and stored, or a tree file is checked ([`super::check_tree_file`]).
    /// 4. Mesh and tree move to the camera's frame ([`triangles_in`]).
    fn load_cached_quietly(
        scene: &Scene,
        cache: Option<&TreeCache>,
    ) -> Result<(World, Setup), LoadError> {
        let frame = RenderFrame::at(scene.camera.eye);
        if scene.meshes.is_empty() {
            return Ok((World::analytic(scene, frame, None), Setup::default()));
        }
        let source = tree_source(scene)?;
        let start = Instant::now();
        let mut files = Vec::with_capacity(scene.meshes.len());
        // Besides each file's bytes: what else its key is made of (format tags, glTF buffers).
        let mut extra = Vec::with_capacity(scene.meshes.len());
        for m in &scene.meshes {
            check_mesh_path(scene, m)?;
            let (bytes, sources) = read_mesh_file(&m.path, cache.is_some())?;
            files.push(bytes);
            extra.push(sources);
        }
        let mut setup = Setup::default();
        let method = match &source {
            TreeSource::Sah => Some(BuildMethod::Sah),
            TreeSource::Midpoint => Some(BuildMethod::Midpoint),
            TreeSource::File(_) => None,
        };
        let key = cache
            .zip(method)
            .map(|(c, method)| (c, cache_key(method, &files, &extra)));
        let load_seconds = start.elapsed().as_secs_f64();
        let tree_start = Instant::now();
        let mut cached = None;
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
        // Parsed when there is no entry, or when faces need more than positions (MTL materials,
        // vertex normals): the merged mesh, each mesh's triangle count and what else was read.
        let rich = scene
            .meshes
            .iter()
            .any(|m| m.mtl.is_some() || m.normals == Normals::Vertex);
        let parse_start = Instant::now();
        let mut parsed = match (&cached, rich) {
            (Some(_), false) => None,
            _ => {
                for (m, bytes) in scene.meshes.iter().zip(&files) {
                    check_mesh_bytes(&m.path, bytes)?;
                }
                Some(parse(scene, &files)?)
            }
        };
        drop(files);
        let parse_seconds = parse_start.elapsed().as_secs_f64();
        let entry = match (cached, &mut parsed) {
            (Some(e), _) => e,
            (None, Some(parsed)) => {
                let entry = match (&source, method) {
                    (TreeSource::File(path), _) => tree_file_entry(path, parsed, &frame)?,
                    (_, Some(method)) => build_entry(parsed, method)?,
                    (_, None) => unreachable!("a tree source without a file is built"),
                };
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
            (None, None) => unreachable!("a world without a cache entry parses its meshes"),
        };
        let triangles = triangles_in(scene, entry, parsed.as_ref(), &frame)?;
        setup.times.load_seconds = load_seconds + parse_seconds;
        setup.times.tree_seconds = tree_start.elapsed().as_secs_f64() - parse_seconds;
        Ok((World::analytic(scene, frame, Some(triangles)), setup))
    }
}

/// The bytes of the mesh file `path` (checked before: [`super::check_mesh_file`]), after a look
/// at its first 64 KiB as it streams — a file that is not OBJ from the start (binary, NULs)
/// fails at once in bounded memory — and, when `keyed`, what else its cache key is made of
/// (`crate::mesh::cache_sources`). Check the bytes with [`check_mesh_bytes`] before parsing them.
pub fn read_mesh_file(
    path: &std::path::Path,
    keyed: bool,
) -> Result<(Vec<u8>, Vec<Vec<u8>>), MeshError> {
    crate::mesh::check_file(path, Some(OBJ_QUICK))?;
    let bytes = crate::accel::cache::read_parallel(path).map_err(|source| MeshError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let sources = if keyed {
        crate::mesh::cache_sources(path, &bytes)?
    } else {
        vec![]
    };
    Ok((bytes, sources))
}

/// Checks the first MiB of the mesh file `path` read as `bytes` ([`read_mesh_file`]) as
/// `mesh::check_file` checks it: a file bad beyond the first 64 KiB is rejected before it
/// is parsed, with the error the check names (file, line) rather than the parser's.
pub fn check_mesh_bytes(path: &std::path::Path, bytes: &[u8]) -> Result<(), MeshError> {
    crate::mesh::check_bytes(path, bytes, Some(OBJ_PREFIX))
}

/// The cache key of meshes `files` (their bytes) with their other sources `extra`
/// ([`read_mesh_file`]), built with `method`: a format tag first, then the bytes, then any
/// external buffers, mesh after mesh.
pub fn cache_key(method: BuildMethod, files: &[Vec<u8>], extra: &[Vec<Vec<u8>>]) -> CacheKey {
    let mut slices: Vec<&[u8]> = Vec::with_capacity(files.len());
    for (f, e) in files.iter().zip(extra) {
        slices.extend(e.first().map(Vec::as_slice));
        slices.push(f);
        slices.extend(e.iter().skip(1).map(Vec::as_slice));
    }
    CacheKey::new(method, &slices)
}

/// The scene's meshes parsed and merged (meshes one after another, in scene order).
struct Parsed {
    /// Every mesh's positions (world coordinates) and faces (taken by a build, [`build_entry`]).
    merged: ObjMesh,
    /// Triangles of each mesh.
    counts: Vec<u64>,
    /// Material of each run of triangles: `(first triangle, scene material)`.
    material_ranges: Vec<(u32, u32)>,
    /// Shading normal of each vertex (zero where its mesh shades with geometric normals); empty
    /// when no mesh uses vertex normals.
    vertex_normals: Vec<[f32; 3]>,
}

/// Parses every mesh (its bytes `files`) with what its `[[mesh]]` asks for and merges them.
fn parse(scene: &Scene, files: &[Vec<u8>]) -> Result<Parsed, LoadError> {
    let mut merged = ObjMesh {
        path: scene.meshes[0].path.clone(),
        ..ObjMesh::default()
    };
    let mut counts = Vec::with_capacity(files.len());
    let mut material_ranges: Vec<(u32, u32)> = Vec::with_capacity(files.len());
    let smooth = scene.meshes.iter().any(|m| m.normals == Normals::Vertex);
    let mut vertex_normals = vec![];
    for (m, bytes) in scene.meshes.iter().zip(files) {
        let what = ObjRead {
            normals: m.normals == Normals::Vertex,
            materials: m.mtl.is_some(),
        };
        let obj = crate::mesh::read_bytes(&m.path, bytes, what, true)?;
        check_not_empty(m, &obj)?;
        let first = merged.indices.len() as u32;
        let mut push = |material: u32, at: u32| {
            if material_ranges
                .last()
                .is_none_or(|&(_, last)| last != material)
            {
                material_ranges.push((at, material));
            }
        };
        match &m.mtl {
            None => push(m.material, first),
            Some(binding) => {
                let fallback = binding.fallback.unwrap_or(m.material);
                // A file without per-face materials (a PLY put in by `--mesh`): the fallback.
                if obj.face_materials.len() != obj.len() {
                    push(fallback, first);
                }
                for (k, &f) in obj.face_materials.iter().enumerate() {
                    let material = if f == NO_MATERIAL {
                        fallback
                    } else {
                        binding.first + f
                    };
                    push(material, first + k as u32);
                }
            }
        }
        if smooth {
            if what.normals {
                vertex_normals.extend(obj.normals_f32());
            } else {
                vertex_normals.resize(vertex_normals.len() + obj.positions.len(), [0.0; 3]);
            }
        }
        let base = merged.positions.len() as u32;
        merged.positions.extend_from_slice(&obj.positions);
        merged
            .indices
            .extend(obj.indices.iter().map(|t| t.map(|i| i + base)));
        counts.push(obj.indices.len() as u64);
    }
    Ok(Parsed {
        merged,
        counts,
        material_ranges,
        vertex_normals,
    })
}

/// The tree file `path` for the parsed mesh, checked as `kdtree check` checks it
/// ([`super::check_tree_file`]), then read into `frame` (where it is traced).
fn tree_file_entry(
    path: &std::path::Path,
    parsed: &Parsed,
    frame: &RenderFrame,
) -> Result<CachedTree, LoadError> {
    let (positions, indices) = (&parsed.merged.positions, &parsed.merged.indices);
    super::check_tree_file(path, positions, indices)?;
    Ok(CachedTree {
        origin: frame.origin,
        positions: positions.clone(),
        indices: indices.clone(),
        mesh_triangles: parsed.counts.clone(),
        tree: KdTree::load_text_in(path, indices.len(), frame)?,
    })
}

/// Builds the tree over the parsed, merged mesh (taken from `parsed`, which keeps its materials
/// and normals) in the frame centred on it.
fn build_entry(parsed: &mut Parsed, method: BuildMethod) -> Result<CachedTree, MeshError> {
    let merged = std::mem::take(&mut parsed.merged);
    let (entry, _, _) = centred_entry(merged, parsed.counts.clone(), method)?;
    Ok(entry)
}

/// The cache entry of `mesh` (merged meshes of `mesh_triangles` triangles each): its tree built
/// with `method` in the frame centred on it — what a render's cache miss builds and what
/// `kdtree build` writes and stores — with the mesh in that frame and the build's phases.
pub fn centred_entry(
    mesh: ObjMesh,
    mesh_triangles: Vec<u64>,
    method: BuildMethod,
) -> Result<(CachedTree, TriangleMesh, BuildPhases), MeshError> {
    let centred = RenderFrame::centered_on(&mesh);
    let framed = mesh.to_frame(centred.origin)?;
    let (tree, phases) = KdTree::build_profiled(&framed, method);
    let entry = CachedTree {
        origin: centred.origin,
        positions: mesh.positions,
        indices: mesh.indices,
        mesh_triangles,
        tree,
    };
    Ok((entry, framed, phases))
}

/// The entry's mesh and tree in `frame`, with the scene's materials: per mesh, or as `parsed`
/// found them (MTL materials, vertex normals).
fn triangles_in(
    scene: &Scene,
    entry: CachedTree,
    parsed: Option<&Parsed>,
    frame: &RenderFrame,
) -> Result<Triangles, LoadError> {
    let vertices =
        crate::mesh::frame_vertices(&scene.meshes[0].path, &entry.positions, frame.origin)?;
    let mesh = TriangleMesh::new(vertices, entry.indices);
    let (material_ranges, vertex_normals) = match parsed {
        Some(p) => (p.material_ranges.clone(), p.vertex_normals.clone()),
        None => {
            let mut first = 0u64;
            let ranges = scene
                .meshes
                .iter()
                .zip(&entry.mesh_triangles)
                .map(|(m, &n)| {
                    let range = (first as u32, m.material);
                    first += n;
                    range
                })
                .collect();
            (ranges, vec![])
        }
    };
    // A built tree moves to the camera's frame; a tree file was read there already.
    let tree = entry
        .tree
        .into_reframed(&RenderFrame::at(entry.origin), frame);
    let tree = KdAccel::new(tree, &mesh);
    Ok(Triangles {
        mesh,
        world_positions: entry.positions,
        vertex_normals,
        material_ranges,
        tree,
        source: scene.meshes[0].kdtree.clone(),
    })
}
