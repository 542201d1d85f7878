//! A seeded fuzz suite over every input parser (issue 21, item 6): scene TOML, OBJ, PLY (ASCII,
//! binary LE and BE), glTF (JSON with a data URI, and GLB), MTL, tree text, tree-cache entries,
//! (tile PNG and EXR files are fuzzed in the CLI, which reads them: `tools/cli/src/tile.rs`). Each parser gets `WAVEFRONT_FUZZ_CASES`
//! random mutations (default 10,000) of a valid file — bit flips, truncations, splices of the
//! file into itself, byte runs, and tokens such as huge, tiny and non-finite numbers — and every
//! case must end in a clean error (naming the file) or in a result that passes validation, with
//! no panic and no hang: a watchdog aborts the run, naming the case, if one case takes longer
//! than `WAVEFRONT_FUZZ_CASE_SECONDS` (default 20).
//!
//! The default run takes well under a minute on two cores (`cargo test --release --test fuzz`).
//! A longer run is one command, e.g. a million cases per parser from another seed:
//!
//! ```text
//! WAVEFRONT_FUZZ_CASES=1000000 WAVEFRONT_FUZZ_SEED=7 cargo test --release --test fuzz
//! ```
//!
//! A failing case prints its parser, seed and case number; rerun it with the same seed. The CLI's
//! arguments are fuzzed in-process in the binary's own tests (`tools/cli/src/fuzz_args.rs`:
//! `cargo test --release -p wavefront-cli --bin wavefront fuzz`, the same variables), through its
//! clap parser and the checks each command makes before any work; a process per case would be
//! too slow for 10,000 cases.

use std::path::{Path, PathBuf};

use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree};
use wavefront::error::chain;
use wavefront::mesh::{ObjMesh, ObjRead, TriangleMesh};
use wavefront_kit::fuzz::{Rng, cases, fuzz, mutate, seed};
use wavefront_kit::testkit::Scratch;

/// The error names `file`.
fn assert_names(e: &str, file: &str) {
    assert!(e.contains(file), "error does not name {file}: {e}");
}

/// A closed cube: 8 `v` lines, 12 `f` lines.
const CUBE: &str = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
f 1 2 3\nf 1 3 4\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 3 7\nf 4 7 8\nf 1 4 8\nf 1 8 5\nf 2 3 7\nf 2 7 6\n";

/// The cube with a material library, groups, texture coordinates and normals.
const CUBE_FULL: &str = "mtllib m.mtl\no cube\nv -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\n\
vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 -1\nvn 0 0 1\nusemtl a\nf 1/1/1 2/2/1 3/3/1\nf 1//1 3//1 4//1\n\
g side\nusemtl b\nf -4/-3/-2 -3/-2/-2 -2/-1/-2 -1/-1/-1\ns 1\n";

const MTL: &str = "# two materials\nnewmtl a\nKa 0.1 0.1 0.1\nKd 0.5 0.25 1\nKs 0.5\nNs 20\nillum 3\n\
\nnewmtl b\nKd 0.8\nmap_Kd tex.png\nd 1\n";

#[test]
fn fuzzed_scene_files_parse_to_valid_scenes_or_name_file_and_line() {
    let valid = include_str!("../scenes/spheres.toml");
    fuzz("scene", valid.as_bytes(), |bytes| {
        let text = String::from_utf8_lossy(bytes);
        match wavefront::scene::file::parse(&text, Path::new("fuzz.toml")) {
            Ok(scene) => {
                assert!(scene.image.width >= 1 && scene.image.height >= 1);
                assert!(scene.image.samples >= 1);
                assert!(
                    scene
                        .spheres
                        .iter()
                        .all(|s| s.radius > 0.0 && s.center.is_finite())
                );
                assert!(scene.planes.iter().all(|p| p.normal.is_normalized()));
                let n = scene.materials.len() as u32;
                assert!(scene.spheres.iter().all(|s| s.material < n));
                assert!(scene.planes.iter().all(|p| p.material < n));
                assert!(scene.materials.iter().all(|m| {
                    m.kd.min_element() >= 0.0 && m.p >= 0.0 && (0.0..=1.0).contains(&m.alpha)
                }));
            }
            Err(e) => {
                let e = e.to_string();
                assert!(e.starts_with("fuzz.toml:"), "{e}");
                let line: usize = e["fuzz.toml:".len()..]
                    .split(':')
                    .next()
                    .and_then(|l| l.parse().ok())
                    .unwrap_or_else(|| panic!("no line: {e}"));
                assert!(line >= 1 && line <= text.lines().count().max(1) + 1, "{e}");
            }
        }
    });
}

/// Checks a loaded mesh: finite f32 coordinates, indices in range.
fn assert_valid_mesh(m: &ObjMesh) {
    assert!(
        m.positions
            .iter()
            .flatten()
            .all(|&c| (c as f32).is_finite())
    );
    let n = m.positions.len();
    assert!(m.indices.iter().flatten().all(|&i| (i as usize) < n));
}

#[test]
fn fuzzed_obj_files_load_valid_meshes_or_name_the_file() {
    let dir = Scratch::new("fuzz-obj");
    dir.write("m.mtl", MTL);
    let path = dir.join("m.obj");
    let what = ObjRead {
        normals: true,
        materials: true,
    };
    let mut n = 0u64;
    fuzz("obj", CUBE_FULL.as_bytes(), |bytes| {
        let text = String::from_utf8_lossy(bytes);
        // Every other case mutates the plain cube instead, the fast reader's kind of file.
        n += 1;
        let text = if n.is_multiple_of(2) {
            text.into_owned()
        } else {
            let mut b = CUBE.as_bytes().to_vec();
            let mut rng = Rng(n ^ seed("obj"));
            mutate(&mut rng, &mut b);
            String::from_utf8_lossy(&b).into_owned()
        };
        match ObjMesh::parse_with(&text, &path, what) {
            Ok(m) => {
                assert_valid_mesh(&m);
                assert_eq!(m.normals.len(), m.positions.len());
                assert!(m.normals.iter().flatten().all(|c| c.is_finite()));
            }
            Err(e) => assert_names(&chain(&e), "m.obj"),
        }
        if let Some((positions, indices)) = wavefront::mesh::obj_fast::parse(text.as_bytes()) {
            // The fast path takes a file only if the full reader reads it to the same mesh.
            let slow = ObjMesh::parse_with(&text, &path, ObjRead::default())
                .unwrap_or_else(|e| panic!("the fast path took a file the reader rejects: {e}"));
            assert_eq!(positions, slow.positions);
            assert_eq!(indices, slow.indices);
        }
    });
}

/// Checks a mesh read with normals and materials: [`assert_valid_mesh`], one finite normal per
/// vertex, one material per triangle.
fn assert_valid_full_mesh(m: &ObjMesh) {
    assert_valid_mesh(m);
    assert_eq!(m.normals.len(), m.positions.len());
    assert!(m.normals.iter().flatten().all(|c| c.is_finite()));
}

#[test]
fn fuzzed_ply_files_load_valid_meshes_or_name_the_file() {
    use wavefront_kit::meshes::{PlyEncoding, PolyMesh};
    let mesh = PolyMesh::bumpy(2);
    let encodings = [
        PlyEncoding::Ascii,
        PlyEncoding::LittleEndian,
        PlyEncoding::BigEndian,
    ];
    let what = ObjRead {
        normals: true,
        materials: false,
    };
    let path = PathBuf::from("fuzz.ply");
    for (k, enc) in encodings.into_iter().enumerate() {
        let name = ["ply-ascii", "ply-le", "ply-be"][k];
        let mut read = 0u64;
        fuzz(
            name,
            &mesh.ply(enc),
            |bytes| match wavefront::mesh::read_bytes(&path, bytes, what, true) {
                Ok(m) => {
                    assert_valid_full_mesh(&m);
                    read += 1;
                }
                Err(e) => {
                    let e = chain(&e);
                    assert_names(&e, "fuzz.ply");
                    assert!(!e.contains('\n'), "a multi-line error: {e}");
                }
            },
        );
        println!("{name}: {read} of {} mutations read", cases());
    }
}

#[test]
fn fuzzed_gltf_files_load_valid_meshes_or_name_the_file() {
    use wavefront_kit::meshes::PolyMesh;
    let mesh = PolyMesh::bumpy(2);
    let what = ObjRead {
        normals: true,
        materials: true,
    };
    let read = std::cell::Cell::new(0u64);
    let check =
        |path: &Path, bytes: &[u8]| match wavefront::mesh::read_bytes(path, bytes, what, true) {
            Ok(m) => {
                assert_valid_full_mesh(&m);
                assert_eq!(m.face_materials.len(), m.indices.len());
                read.set(read.get() + 1);
            }
            Err(e) => {
                let e = chain(&e);
                assert_names(&e, &path.display().to_string());
                assert!(!e.contains('\n'), "a multi-line error: {e}");
            }
        };
    let matrix = Some([
        0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.5, 0.25, -1.0, 1.0,
    ]);
    let gltf = PathBuf::from("fuzz.gltf");
    fuzz("gltf", mesh.gltf_embedded(matrix).as_bytes(), |b| {
        check(&gltf, b)
    });
    println!("gltf: {} of {} mutations read", read.replace(0), cases());
    let glb = PathBuf::from("fuzz.glb");
    fuzz("glb", &mesh.glb(matrix), |b| check(&glb, b));
    println!("glb: {} of {} mutations read", read.get(), cases());
}

#[test]
fn fuzzed_mtl_files_give_valid_materials_or_name_file_and_line() {
    let path = PathBuf::from("fuzz.mtl");
    fuzz("mtl", MTL.as_bytes(), |bytes| {
        let text = String::from_utf8_lossy(bytes);
        match wavefront::mesh::mtl::parse_library(&text, &path) {
            Ok(materials) => {
                for m in &materials {
                    for c in [m.ambient, m.diffuse, m.specular].into_iter().flatten() {
                        assert!(c.iter().all(|&x| x.is_finite() && x >= 0.0), "{m:?}");
                    }
                    assert!(m.shininess.is_none_or(|s| s.is_finite() && s >= 0.0));
                    assert!(!m.name.is_empty());
                }
            }
            Err(e) => assert!(e.to_string().starts_with("fuzz.mtl:"), "{e}"),
        }
    });
}

#[test]
fn fuzzed_tree_files_load_or_name_the_file_and_never_panic_validation() {
    let mesh = TriangleMesh::new(
        CUBE.lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let v: Vec<f32> = l.split(' ').map(|x| x.parse().unwrap()).collect();
                [v[0], v[1], v[2]]
            })
            .collect(),
        CUBE.lines()
            .filter_map(|l| l.strip_prefix("f "))
            .map(|l| {
                let v: Vec<u32> = l
                    .split(' ')
                    .map(|x| x.parse::<u32>().unwrap() - 1)
                    .collect();
                [v[0], v[1], v[2]]
            })
            .collect(),
    );
    let mut valid = Vec::new();
    KdTree::build(&mesh, BuildMethod::Sah)
        .write_text(&mut valid)
        .unwrap();
    let path = PathBuf::from("fuzz.kd");
    fuzz("tree", &valid, |bytes| {
        match KdTree::read_text(bytes, &path, mesh.len()) {
            Ok(tree) => {
                // validate() judges what loads; a tree it accepts is traced.
                if tree.validate(&mesh).is_ok() {
                    let accel = KdAccel::new(tree, &mesh);
                    let _ = accel.intersect_closest(glam::Vec3::ZERO, glam::Vec3::X, f32::INFINITY);
                }
            }
            Err(e) => assert_names(&chain(&e), "fuzz.kd"),
        }
    });
}

#[test]
fn fuzzed_cache_entries_are_read_valid_or_rejected() {
    use wavefront::accel::cache::{CacheKey, TreeCache};
    let dir = Scratch::new("fuzz-cache");
    let obj = ObjMesh::parse_with(CUBE, Path::new("cube.obj"), ObjRead::default()).unwrap();
    let mesh = obj.to_frame(glam::DVec3::ZERO).unwrap();
    let entry = wavefront::accel::cache::CachedTree {
        origin: glam::DVec3::ZERO,
        tree: KdTree::build(&mesh, BuildMethod::Sah),
        positions: obj.positions,
        indices: obj.indices,
        mesh_triangles: vec![12],
    };
    let cache = TreeCache::new(dir.join("cache"));
    let key = CacheKey::new(BuildMethod::Sah, &[CUBE.as_bytes()]);
    let path = cache.store(key, &entry).unwrap();
    let valid = std::fs::read(&path).unwrap();
    fuzz("cache", &valid, |bytes| {
        std::fs::write(&path, bytes).unwrap();
        match cache.load(key) {
            Ok(Some(e)) => {
                assert!(
                    e.indices
                        .iter()
                        .flatten()
                        .all(|&k| (k as usize) < e.positions.len())
                );
                let mesh = TriangleMesh::new(
                    e.positions.iter().map(|p| p.map(|c| c as f32)).collect(),
                    e.indices.clone(),
                );
                let _ = e.tree.validate(&mesh);
            }
            Ok(None) => panic!("an entry that is there was not found"),
            Err(e) => assert_names(&chain(&e), &path.display().to_string()),
        }
    });
}
