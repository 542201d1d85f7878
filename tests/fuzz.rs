//! A seeded fuzz suite over every input parser (issue 21, item 6): scene TOML, OBJ, PLY (ASCII,
//! binary LE and BE), glTF (JSON with a data URI, and GLB), MTL, tree text, tree-cache entries,
//! and tile PNG / EXR files. Each parser gets `WAVEFRONT_FUZZ_CASES`
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
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree};
use wavefront::error::chain;
use wavefront::mesh::{ObjMesh, ObjRead, TriangleMesh};
use wavefront_kit::testkit::Scratch;

/// Cases per parser (`WAVEFRONT_FUZZ_CASES`, default 10,000).
fn cases() -> u64 {
    std::env::var("WAVEFRONT_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000)
}

/// The seed (`WAVEFRONT_FUZZ_SEED`, default 21); each parser mixes in its own name.
fn seed(parser: &str) -> u64 {
    let base: u64 = std::env::var("WAVEFRONT_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(21);
    parser.bytes().fold(base ^ 0x9e37_79b9_7f4a_7c15, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

/// splitmix64: a small, seeded, portable generator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Tokens inserted or written over bytes: numbers at and past the edges, and words of every
/// format.
const TOKENS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e39",
    "1e-45",
    "1e-400",
    "-0",
    "0",
    "-1",
    "4294967296",
    "18446744073709551616",
    "-9223372036854775808",
    "3.4028236e38",
    "1e",
    ".",
    "=",
    "[",
    "]",
    "{",
    "}",
    "\"",
    ",",
    "#",
    "\n",
    "\r",
    "\0",
    " ",
    "\\",
    "/",
    "//",
    "f",
    "v",
    "vn",
    "vt",
    "f 1",
    "f 1 2",
    "f 0 1 2",
    "f -9 1 2",
    "newmtl",
    "Kd",
    "Ns",
    "illum 99",
    "inner",
    "leaf",
    "[[sphere]]",
    "[[mesh]]",
    "[image]",
    "width = 0",
    "radius = -1",
    "\u{1F600}",
];

/// One random mutation of `bytes`.
fn mutate(rng: &mut Rng, bytes: &mut Vec<u8>) {
    let len = bytes.len();
    let at = rng.below(len + 1);
    match rng.below(7) {
        // Flip 1 to 8 bits.
        0 if len > 0 => {
            for _ in 0..=rng.below(8) {
                let i = rng.below(len);
                bytes[i] ^= 1 << rng.below(8);
            }
        }
        // Truncate.
        1 => bytes.truncate(at),
        // Splice: a piece of the file copied over another place.
        2 if len > 0 => {
            let from = rng.below(len);
            let n = rng.below(64).min(len - from);
            let piece = bytes[from..from + n].to_vec();
            let end = (at + rng.below(64)).min(len);
            bytes.splice(at..end, piece);
        }
        // A token replaces a short range.
        3 => {
            let end = (at + rng.below(12)).min(len);
            let t = TOKENS[rng.below(TOKENS.len())].as_bytes().to_vec();
            bytes.splice(at..end, t);
        }
        // A token is inserted.
        4 => {
            let t = TOKENS[rng.below(TOKENS.len())].as_bytes().to_vec();
            bytes.splice(at..at, t);
        }
        // A run of one random byte.
        5 => {
            let b = rng.next() as u8;
            let n = 1 + rng.below(32);
            bytes.splice(at..at, std::iter::repeat_n(b, n));
        }
        // A range deleted.
        _ => {
            let end = (at + rng.below(32)).min(len);
            bytes.drain(at..end);
        }
    }
}

/// A watchdog for one parser's loop: if a case runs longer than the limit, it prints the case
/// and aborts the test process (a hang is a failure, not a test that never ends).
struct Watchdog {
    /// Milliseconds since `start` at which the current case began.
    began: Arc<AtomicU64>,
    /// The current case number.
    case: Arc<AtomicU64>,
    done: Arc<AtomicBool>,
    start: Instant,
}

impl Watchdog {
    fn new(parser: &'static str) -> Watchdog {
        let limit: u64 = std::env::var("WAVEFRONT_FUZZ_CASE_SECONDS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(20);
        let w = Watchdog {
            began: Arc::new(AtomicU64::new(0)),
            case: Arc::new(AtomicU64::new(0)),
            done: Arc::new(AtomicBool::new(false)),
            start: Instant::now(),
        };
        let (began, case, done, start) = (w.began.clone(), w.case.clone(), w.done.clone(), w.start);
        std::thread::spawn(move || {
            while !done.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(200));
                let now = start.elapsed().as_millis() as u64;
                if now.saturating_sub(began.load(Ordering::Relaxed)) > limit * 1000 {
                    eprintln!(
                        "fuzz {parser}: case {} (seed {}) still running after {limit} s: a hang",
                        case.load(Ordering::Relaxed),
                        seed(parser)
                    );
                    std::process::abort();
                }
            }
        });
        w
    }

    fn case(&self, i: u64) {
        self.case.store(i, Ordering::Relaxed);
        self.began
            .store(self.start.elapsed().as_millis() as u64, Ordering::Relaxed);
    }
}

impl Drop for Watchdog {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Relaxed);
    }
}

/// Runs `check` on `cases()` mutations (1 to 4 each) of `valid`, reporting the case of a panic.
fn fuzz(parser: &'static str, valid: &[u8], mut check: impl FnMut(&[u8])) {
    let mut rng = Rng(seed(parser));
    let watchdog = Watchdog::new(parser);
    for i in 0..cases() {
        watchdog.case(i);
        let mut bytes = valid.to_vec();
        for _ in 0..=rng.below(4) {
            mutate(&mut rng, &mut bytes);
        }
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| check(&bytes)));
        if result.is_err() {
            panic!(
                "fuzz {parser}: case {i} (seed {}) panicked on {:?}",
                seed(parser),
                String::from_utf8_lossy(&bytes)
            );
        }
    }
}

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
    use wavefront::cache::{CacheKey, TreeCache};
    let dir = Scratch::new("fuzz-cache");
    let obj = ObjMesh::parse_with(CUBE, Path::new("cube.obj"), ObjRead::default()).unwrap();
    let mesh = obj.to_frame(glam::DVec3::ZERO).unwrap();
    let entry = wavefront::cache::CachedTree {
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

/// A 4 × 2 tile of a 4 × 4 image, written as `name`.
fn tile_bytes(dir: &Scratch, name: &str) -> (PathBuf, Vec<u8>) {
    use wavefront::tile::TileInfo;
    let info = TileInfo {
        bounds: wavefront::region::Region {
            x0: 0,
            x1: 4,
            y0: 0,
            y1: 2,
        },
        image: (4, 4),
        fingerprint: wavefront::tile::Fingerprint("0123456789abcdef".into()),
    };
    let path = dir.join(name);
    if name.ends_with(".exr") {
        let mut film = wavefront::Film::new(4, 2);
        film.pixels[3] = glam::Vec3::ONE;
        wavefront::tile::write_tile_exr(&path, &info, &film).unwrap();
    } else {
        let rgb: Vec<u8> = (0..4 * 2 * 3).map(|i| i as u8 * 9).collect();
        wavefront::tile::write_tile(&path, &info, &rgb).unwrap();
    }
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes)
}

fn fuzz_tiles(name: &'static str) {
    let dir = Scratch::new(&format!("fuzz-{name}"));
    let (path, valid) = tile_bytes(&dir, name);
    fuzz(name, &valid, |bytes| {
        std::fs::write(&path, bytes).unwrap();
        match wavefront::tile::read_tile(&path) {
            Ok(tile) => {
                let b = tile.info.bounds;
                assert!(b.x0 < b.x1 && b.y0 < b.y1);
                assert!(b.x1 <= tile.info.image.0 && b.y1 <= tile.info.image.1);
            }
            Err(e) => assert_names(&chain(&e), name),
        }
    });
}

#[test]
fn fuzzed_png_tiles_are_read_valid_or_rejected() {
    fuzz_tiles("tile.png");
}

#[test]
fn fuzzed_exr_tiles_are_read_valid_or_rejected() {
    fuzz_tiles("tile.exr");
}
