//! The tree cache through the command line: a warm render reads the entry and makes the same
//! image; a truncated, corrupted or stale entry is rebuilt with one warning line, never a crash
//! or another image; `kdtree build` stores but never reads; `--no-cache` touches nothing.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use wavefront_kit::testkit;

/// A scratch directory ([`testkit::Scratch`], removed on drop) to run the binary in.
struct Scratch(testkit::Scratch);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(testkit::Scratch::new(&format!("cache-{name}")))
    }

    fn path(&self) -> &Path {
        self.0.path()
    }

    fn run(&self, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_wavefront"))
            .args(args)
            .current_dir(self.0.path())
            .env("XDG_CACHE_HOME", self.0.join("xdg"))
            .output()
            .expect("cannot run the wavefront binary")
    }

    /// The cache entries in `cache/`.
    fn entries(&self) -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(self.0.join("cache"))
            .map(|d| d.map(|e| e.unwrap().path()).collect())
            .unwrap_or_default();
        v.sort();
        v
    }
}

/// A grid of `n × n` quads (two triangles each) on a bumpy surface in front of the camera.
fn grid_obj(n: usize, bump: f64) -> String {
    let mut s = String::from("# test grid\n");
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (
                i as f64 / n as f64 * 4.0 - 2.0,
                j as f64 / n as f64 * 4.0 - 2.0,
            );
            let z = -5.0 + bump * ((3.0 * x).sin() * (2.0 * y).cos());
            s.push_str(&format!("v {x} {y} {z}\n"));
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i + 1;
            s.push_str(&format!("f {} {} {} {}\n", a, a + 1, a + n + 2, a + n + 1));
        }
    }
    s
}

const SCENE: &str = r#"
[image]
width = 48
height = 48

[camera]
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -5.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0

[render]
max_depth = 0
shadows = true

[[light]]
position = [1.0, 2.0, 0.0]
intensity = [1.0, 1.0, 1.0]

[material.white]
kd = [1.0, 1.0, 1.0]

[[mesh]]
path = "grid.obj"
material = "white"
"#;

fn setup(name: &str) -> Scratch {
    let dir = Scratch::new(name);
    std::fs::write(dir.path().join("grid.obj"), grid_obj(24, 0.3)).unwrap();
    std::fs::write(dir.path().join("scene.toml"), SCENE).unwrap();
    dir
}

fn render(dir: &Scratch, out: &str, extra: &[&str]) -> (Vec<u8>, String) {
    let mut args = vec!["render", "scene.toml", "-o", out, "--quiet"];
    args.extend_from_slice(extra);
    let o = dir.run(&args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "render failed: {err}");
    assert!(!err.contains("panicked"), "{err}");
    (std::fs::read(dir.path().join(out)).unwrap(), err)
}

#[test]
fn a_warm_cache_renders_the_same_image_and_bad_entries_are_rebuilt_with_one_warning() {
    let dir = setup("warm");
    let cache = ["--cache", "cache"];
    let (none, err) = render(&dir, "none.png", &["--no-cache"]);
    assert!(err.is_empty(), "{err}");
    assert!(dir.entries().is_empty(), "--no-cache wrote an entry");
    assert!(
        !dir.path().join("xdg").exists(),
        "--no-cache used the default folder"
    );

    let (cold, err) = render(&dir, "cold.png", &cache);
    assert!(err.is_empty(), "{err}");
    let entries = dir.entries();
    assert_eq!(entries.len(), 1, "{entries:?}");
    let entry = entries[0].clone();
    assert_eq!(entry.extension().unwrap(), "wfkd");
    let good = std::fs::read(&entry).unwrap();

    let (warm, err) = render(&dir, "warm.png", &cache);
    assert!(err.is_empty(), "{err}");
    assert!(cold == none && warm == none, "images differ with the cache");
    assert_eq!(
        std::fs::read(&entry).unwrap(),
        good,
        "a hit rewrote the entry"
    );

    // Truncated, byte-flipped, emptied, replaced by garbage: one warning, rebuilt, same image.
    let mut corruptions: Vec<Vec<u8>> = vec![
        good[..good.len() / 2].to_vec(),
        good[..good.len() - 1].to_vec(),
        Vec::new(),
        b"not a cache entry".to_vec(),
    ];
    for at in [0, 9, 40, 100, good.len() / 2, good.len() - 3] {
        let mut b = good.clone();
        b[at] ^= 0x10;
        corruptions.push(b);
    }
    for (k, bad) in corruptions.iter().enumerate() {
        std::fs::write(&entry, bad).unwrap();
        let (image, err) = render(&dir, "again.png", &cache);
        let warnings: Vec<&str> = err.lines().collect();
        assert_eq!(warnings.len(), 1, "corruption {k}: {err}");
        assert!(
            warnings[0].starts_with("warning: ") && warnings[0].contains("rebuilding"),
            "corruption {k}: {err}"
        );
        assert!(image == none, "corruption {k} changed the image");
        assert_eq!(
            std::fs::read(&entry).unwrap(),
            good,
            "corruption {k} not rebuilt"
        );
    }

    // The default folder is $XDG_CACHE_HOME/wavefront.
    render(&dir, "xdg.png", &[]);
    assert!(
        dir.path()
            .join("xdg/wavefront")
            .join(entry.file_name().unwrap())
            .exists()
    );
    // No temporary files are left behind.
    assert!(
        dir.entries()
            .iter()
            .all(|p| p.extension().is_some_and(|e| e == "wfkd"))
    );
}

#[test]
fn a_changed_obj_gets_its_own_entry_and_its_own_image() {
    let dir = setup("changed");
    let cache = ["--cache", "cache"];
    let (before, _) = render(&dir, "before.png", &cache);
    std::fs::write(dir.path().join("grid.obj"), grid_obj(24, 0.6)).unwrap();
    let (after, err) = render(&dir, "after.png", &cache);
    assert!(err.is_empty(), "{err}");
    assert_eq!(
        dir.entries().len(),
        2,
        "a changed OBJ must not hit the old entry"
    );
    let (reference, _) = render(&dir, "reference.png", &["--no-cache"]);
    assert!(after == reference && after != before);
}

#[test]
fn kdtree_build_stores_an_entry_a_render_then_hits_and_prints_json() {
    let dir = setup("kdtree");
    let o = dir.run(&[
        "kdtree",
        "build",
        "grid.obj",
        "-o",
        "grid.kd",
        "--threads",
        "2",
        "--json",
        "--cache",
        "cache",
    ]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = out.trim();
    assert_eq!(out.lines().count(), 1, "{out}");
    assert!(line.starts_with('{') && line.ends_with('}'), "{line}");
    for key in [
        "\"triangles\":1152",
        "\"threads\":2",
        "\"load_seconds\":",
        "\"build_seconds\":",
    ] {
        assert!(line.contains(key), "{key} missing in {line}");
    }
    let entries = dir.entries();
    assert_eq!(entries.len(), 1);
    // A render hits the entry kdtree build stored (it would rebuild and rewrite a bad one).
    std::fs::write(&entries[0], b"").unwrap();
    let o = dir.run(&[
        "kdtree", "build", "grid.obj", "-o", "grid.kd", "--cache", "cache",
    ]);
    assert!(o.status.success());
    assert!(o.stderr.is_empty(), "kdtree build must not read the cache");
    let (_, err) = render(&dir, "hit.png", &["--cache", "cache", "--stats"]);
    assert!(err.is_empty(), "{err}");
    let o = dir.run(&[
        "render",
        "scene.toml",
        "-o",
        "s.png",
        "--cache",
        "cache",
        "--stats",
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("cache: Hit"));
    let o = dir.run(&[
        "kdtree",
        "build",
        "grid.obj",
        "-o",
        "g.kd",
        "--threads",
        "0",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--threads"));
}

#[test]
fn kdtree_build_streams_a_complete_tree_file_or_none() {
    let dir = setup("stream");
    let o = dir.run(&["kdtree", "build", "grid.obj", "-o", "grid.kd", "--no-cache"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The streamed file is a whole tree: rendering through it gives the built-in SAH tree's image.
    let (from_file, err) = render(&dir, "file.png", &["--kdtree", "grid.kd", "--no-cache"]);
    assert!(err.is_empty(), "{err}");
    let (built, _) = render(&dir, "built.png", &["--kdtree", "sah", "--no-cache"]);
    assert!(from_file == built, "the tree file renders another image");
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!names.iter().any(|n| n.ends_with(".partial")), "{names:?}");
    // An output that cannot be written: one line naming it, a failure, and no file.
    let o = dir.run(&[
        "kdtree",
        "build",
        "grid.obj",
        "-o",
        "missing/grid.kd",
        "--no-cache",
    ]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success());
    assert!(
        err.contains("missing/grid.kd") && !err.contains("panicked"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!dir.path().join("missing").exists());
}
