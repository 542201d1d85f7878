//! Shared fixtures for the integration tests: rendering a scene to 8-bit RGB, thread pools of a
//! given size, and the external data (Sibenik mesh, reference figures) with graceful skipping.

use std::path::{Path, PathBuf};

use crate::oracle::{OracleImage, render_oracle};
use wavefront::{Film, RenderOptions, Scene, World};

/// Loads `scene`'s world and renders it with `options`.
pub fn render_film_with(scene: &Scene, options: RenderOptions) -> Film {
    let world = World::load(scene).unwrap_or_else(|e| {
        panic!(
            "cannot load {}: {}",
            scene.name,
            wavefront::error::chain(&e)
        )
    });
    wavefront::render(scene, &world, options, |_, _| {}).0
}

/// The 8-bit RGB pixels (row 0 at the top) a PNG of the wavefront render of `scene` would hold.
pub fn render_png_bytes(scene: &Scene) -> Vec<u8> {
    render_png_bytes_with(scene, RenderOptions::default())
}

/// [`render_png_bytes`] with explicit render options.
pub fn render_png_bytes_with(scene: &Scene, options: RenderOptions) -> Vec<u8> {
    render_film_with(scene, options).to_rgb8(scene.image.gamma)
}

/// Runs `f` in a fresh rayon pool of `threads` threads.
pub fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("cannot build a thread pool")
        .install(f)
}

/// The oracle's render of `scene`, its meshes read in f64 as written.
pub fn oracle_image(scene: &Scene) -> OracleImage {
    let meshes: Vec<_> = scene
        .meshes
        .iter()
        .map(|m| {
            let what = wavefront::mesh::ObjRead {
                materials: m.mtl.is_some(),
                normals: false,
            };
            wavefront::mesh::ObjMesh::read_with(&m.path, what).unwrap_or_else(|e| {
                panic!(
                    "cannot load {}: {}",
                    m.path.display(),
                    wavefront::error::chain(&e)
                )
            })
        })
        .collect();
    render_oracle(scene, &meshes)
}

/// The oracle's 8-bit RGB render of `scene`.
pub fn oracle_png_bytes(scene: &Scene) -> Vec<u8> {
    oracle_image(scene).to_rgb8(f64::from(scene.image.gamma))
}

/// The workspace root (where `Cargo.toml`, `src/` and `tests/` are), from this crate's location.
pub fn project_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Environment variable that turns a missing data file from a skip into a failure (`.ci/run`
/// sets it: CI has `../shared`).
pub const REQUIRE_DATA_ENV: &str = "WAVEFRONT_REQUIRE_DATA";

/// The Sibenik mesh path the built-in scenes use, resolved against the project root (so tests of
/// any workspace member find it): `$WAVEFRONT_SIBENIK`, else `../shared/data/sibenik/sibenik.obj`.
pub fn sibenik_mesh_path() -> PathBuf {
    wavefront::scene::builtin::sibenik_mesh_path_in(&project_root())
}

/// `Some(path)` when `path` exists. When it does not: with `WAVEFRONT_REQUIRE_DATA=1`, panics
/// naming the path (the test fails); otherwise prints why the test is skipped and returns `None`.
pub fn skip_if_missing(path: &Path, what: &str) -> Option<PathBuf> {
    if path.exists() {
        return Some(path.to_path_buf());
    }
    let required = std::env::var_os(REQUIRE_DATA_ENV).is_some_and(|v| v == "1");
    assert!(
        !required,
        "{what} not found at {} and {REQUIRE_DATA_ENV}=1: this test needs it (see SPEC §5)",
        path.display()
    );
    eprintln!(
        "SKIPPED: {what} not found at {} — this test needs it; see SPEC §5 and \
         ../shared/reference/README.md for where it belongs",
        path.display()
    );
    None
}

/// The Sibenik mesh, or `None` (with a message) when it is not installed.
pub fn sibenik_mesh() -> Option<PathBuf> {
    skip_if_missing(&sibenik_mesh_path(), "the Sibenik mesh (sibenik.obj)")
}

/// The built-in Sibenik scene (with or without shadows) with its mesh path resolved against the
/// project root, or `None` (see [`skip_if_missing`]).
pub fn sibenik_scene(shadows: bool) -> Option<Scene> {
    let path = sibenik_mesh()?;
    let mut scene = wavefront::scene::builtin::sibenik(shadows);
    scene.meshes[0].path = path;
    Some(scene)
}

/// Narrows a Sibenik scene to `size` × `size` pixels of an off-centre window where walls, floor
/// and shadow edges are all in view (cheap enough for the midpoint tree's huge leaves).
pub fn sibenik_crop(scene: &mut Scene, size: u32) {
    scene.image.width = size;
    scene.image.height = size;
    scene.camera.l = -0.06;
    scene.camera.r = -0.01;
    scene.camera.b = -0.06;
    scene.camera.t = -0.01;
}

/// The Sibenik mesh loaded, or `None` (see [`skip_if_missing`]).
pub fn sibenik_triangles() -> Option<wavefront::mesh::TriangleMesh> {
    let path = sibenik_mesh()?;
    Some(
        wavefront::mesh::TriangleMesh::load_obj(&path).unwrap_or_else(|e| {
            panic!(
                "cannot load {}: {}",
                path.display(),
                wavefront::error::chain(&e)
            )
        }),
    )
}

/// `../shared/reference` beside the project root, or `None` (see [`skip_if_missing`]).
pub fn reference_dir() -> Option<PathBuf> {
    let dir = project_root().join("../shared/reference");
    skip_if_missing(&dir, "the assignment's reference figures directory")
}

/// A reference figure as 8-bit RGB with its size.
pub fn read_rgb8(path: &Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
        .to_rgb8();
    (img.width(), img.height(), img.into_raw())
}

/// Figures of the README of `../shared/reference`: mean absolute error over all channels on the
/// 0–255 scale, and the share of pixels whose largest channel error exceeds 16 levels.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceError {
    /// Mean absolute channel error, in levels.
    pub mae: f64,
    /// Share (0–1) of pixels off by more than 16 levels in some channel.
    pub over_16: f64,
}

/// Compares a render against a reference figure (both 8-bit RGB of the same size).
pub fn reference_error(render: &[u8], reference: &[u8]) -> ReferenceError {
    assert_eq!(render.len(), reference.len(), "images of different sizes");
    let total: u64 = render
        .iter()
        .zip(reference)
        .map(|(a, b)| u64::from(a.abs_diff(*b)))
        .sum();
    let pixels = render.len() / 3;
    let over = render
        .chunks_exact(3)
        .zip(reference.chunks_exact(3))
        .filter(|(a, b)| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 16))
        .count();
    ReferenceError {
        mae: total as f64 / render.len().max(1) as f64,
        over_16: over as f64 / pixels.max(1) as f64,
    }
}

pub use wavefront::sampling::Rng;

/// Replacement tokens that stress the parser and the validation.
pub const SCENE_TOKENS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e309",
    "-1.0",
    "0",
    "0.0",
    "\"x\"",
    "[]",
    "[1.0]",
    "[1.0, 2.0, 3.0, 4.0]",
    "{}",
    "true",
    "=",
    "[",
    "]",
    "[[sphere]]",
    "[material.red]",
    "radius = -2.0",
    "alpha = 2.0",
    "material = \"none\"",
    "samples = 0",
    "max_depth = 100000",
    "width = 0",
    "\u{0}",
    "é",
    "#",
    "\"",
    "4294967296",
    "-9223372036854775808",
];

/// A mutation of `text`: replace a byte range with one of `tokens`, delete a range, insert a
/// token, or duplicate a line.
pub fn mutate_from(
    tokens: &[&str],
    text: &str,
    kind: u8,
    at: usize,
    len: usize,
    token: usize,
) -> String {
    let mut t = text.to_owned();
    let mut at = at % (t.len() + 1);
    while !t.is_char_boundary(at) {
        at -= 1;
    }
    let mut end = (at + len % 16).min(t.len());
    while !t.is_char_boundary(end) {
        end -= 1;
    }
    let tok = tokens[token % tokens.len()];
    match kind % 4 {
        0 => t.replace_range(at..end, tok),
        1 => t.replace_range(at..end, ""),
        2 => t.insert_str(at, tok),
        _ => {
            let line_start = t[..at].rfind('\n').map_or(0, |i| i + 1);
            let line_end = t[at..].find('\n').map_or(t.len(), |i| at + i);
            let line = t[line_start..line_end].to_owned();
            t.insert_str(line_end, &format!("\n{line}"));
        }
    }
    t
}

/// Scene A (`scenes/spheres.toml`) at `width × height` with its camera replaced by a two-key
/// look-at path: frame 0 at the origin looking down −z, frame 3 at (2, 1, 1) with `up` tilted by
/// `tilt` in x — the render-farm tests' frame range.
pub fn spheres_camera_path_toml(tilt: f64, (width, height): (u32, u32)) -> String {
    let spheres = std::fs::read_to_string(project_root().join("scenes/spheres.toml"))
        .expect("scenes/spheres.toml is readable");
    let camera = "[camera]
eye = [0.0, 0.0, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
w = [0.0, 0.0, 1.0]
window = { l = -0.1, r = 0.1, b = -0.1, t = 0.1 }
distance = 0.1";
    assert!(spheres.contains(camera), "scenes/spheres.toml changed");
    let path = format!(
        "[[camera.key]]
frame = 0
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -7.0]
up = [0.0, 1.0, 0.0]
fov_y = 90.0

[[camera.key]]
frame = 3
eye = [2.0, 1.0, 1.0]
look_at = [0.0, -0.5, -7.0]
up = [{tilt:?}, 1.0, 0.0]
fov_y = 60.0"
    );
    spheres.replace(camera, &path).replace(
        "width = 512\nheight = 512",
        &format!("width = {width}\nheight = {height}"),
    )
}

/// A fresh scratch directory under the system's temporary folder, removed on drop.
#[derive(Debug)]
pub struct Scratch(PathBuf);

impl Scratch {
    /// An empty directory named after the test (`name`) and this process.
    pub fn new(name: &str) -> Scratch {
        let dir =
            std::env::temp_dir().join(format!("wavefront-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("cannot create a scratch directory");
        Scratch(dir)
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.0
    }

    /// `program` to run in this directory, keeping tree-cache entries in it (`XDG_CACHE_HOME` is
    /// its `cache/`) and ignoring the caller's `$WAVEFRONT_SIBENIK`.
    pub fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> std::process::Command {
        let mut c = std::process::Command::new(program);
        c.current_dir(&self.0)
            .env_remove("WAVEFRONT_SIBENIK")
            .env("XDG_CACHE_HOME", self.0.join("cache"));
        c
    }

    /// `file` inside the directory.
    pub fn join(&self, file: &str) -> PathBuf {
        self.0.join(file)
    }

    /// Writes `text` to `file` inside the directory and returns its path.
    pub fn write(&self, file: &str, text: &str) -> PathBuf {
        let p = self.join(file);
        std::fs::write(&p, text).unwrap_or_else(|e| panic!("cannot write {}: {e}", p.display()));
        p
    }

    /// Names of the files in the directory, sorted.
    pub fn files(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(&self.0)
            .expect("the scratch directory is readable")
            .map(|e| {
                e.expect("a directory entry")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        names.sort();
        names
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
