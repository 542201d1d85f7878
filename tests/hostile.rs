//! Regression tests for issue 21 (hostile inputs and file systems), each named after the bug it
//! guards against: no hang, no panic, no silently wrong scene, no clobbered file.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use glam::Vec3;
use wavefront::error::chain;
use wavefront::mesh::{ObjMesh, ObjRead, TriangleMesh};
use wavefront::queue::SampleSlot;
use wavefront::scene::file::{load, parse};
use wavefront::{Film, World};
use wavefront_kit::testkit::Scratch;

/// Runs `f` on its own thread; panics (fails the test) if it takes longer than `secs`: a hang
/// becomes a failure instead of a test that never ends.
fn within<R: Send + 'static>(secs: u64, what: &str, f: impl FnOnce() -> R + Send + 'static) -> R {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(secs))
        .unwrap_or_else(|_| panic!("{what}: no answer within {secs} s (a hang)"))
}

/// A minimal scene (one floor material) with `body` appended.
fn scene_text(body: &str) -> String {
    format!(
        "[camera]\neye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -1.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y = 40.0\n\n[material.floor]\nkd = [1.0, 1.0, 1.0]\n\n{body}"
    )
}

/// A one-triangle OBJ.
const TRIANGLE: &str = "v -1 -1 -3\nv 1 -1 -3\nv 0 1 -3\nf 1 2 3\n";

fn mkfifo(path: &Path) {
    let ok = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .expect("cannot run mkfifo")
        .success();
    assert!(ok, "mkfifo {} failed", path.display());
}

// Case 1.

#[test]
fn many_lights_sharing_one_sample_slot_do_not_spin_in_add_range() {
    // Every row from the midpoint on shares one slot (a 1 × 1 image lit by thousands of lights).
    let n = 20_000;
    let slot: Vec<SampleSlot> = (0..n).map(|i| SampleSlot(i.min(100) as u32)).collect();
    let value: Vec<Vec3> = (0..n).map(|_| Vec3::ONE).collect();
    let out = within(20, "add_sorted", move || {
        let mut out = vec![Vec3::ZERO; 101];
        wavefront::queue::add_sorted(&mut out, &slot, &value, |_| true);
        out
    });
    assert_eq!(out[0], Vec3::ONE);
    assert_eq!(out[100], Vec3::splat((n - 100) as f32));
    // All rows in one slot: the same answer, in row order.
    let slot = vec![SampleSlot(0); n];
    let value: Vec<Vec3> = (0..n).map(|i| Vec3::splat(i as f32)).collect();
    let serial = value.iter().fold(Vec3::ZERO, |a, &b| a + b);
    let out = within(20, "add_sorted", move || {
        let mut out = vec![Vec3::ZERO; 1];
        wavefront::queue::add_sorted(&mut out, &slot, &value, |_| true);
        out
    });
    assert_eq!(out[0], serial);
}

// Cases 2 and 14: MTL files.

/// A scene whose mesh takes its materials from `mtl`; returns the loaded scene or the error line.
fn load_mtl_scene(dir: &Scratch, mtl: &str) -> Result<wavefront::Scene, String> {
    dir.write("m.mtl", mtl);
    dir.write(
        "m.obj",
        &format!(
            "mtllib m.mtl\n{}usemtl a\nf 1 2 3\n",
            &TRIANGLE[..TRIANGLE.len() - 8]
        ),
    );
    let scene = dir.write(
        "s.toml",
        &scene_text("[[mesh]]\npath = \"m.obj\"\nmaterial = \"mtl\"\n"),
    );
    load(&scene).map_err(|e| chain(&e))
}

#[test]
fn mtl_colour_with_one_or_two_components_is_not_a_panic() {
    let dir = Scratch::new("hostile-mtl-short");
    let scene = load_mtl_scene(&dir, "newmtl a\nKd 0.5\nKa 0.25 0.5\n").expect("loads");
    let m = scene.materials.last().unwrap();
    // MTL: g and b default to r.
    assert_eq!(m.kd, Vec3::splat(0.5));
    assert_eq!(m.ka, Vec3::new(0.25, 0.5, 0.25));
}

#[test]
fn mtl_nan_and_negative_values_are_errors_naming_file_and_line() {
    let dir = Scratch::new("hostile-mtl-values");
    for bad in [
        "Kd nan 0 0",
        "Ks nan",
        "Ns nan",
        "Kd -1 0 0",
        "Ks -5",
        "Ns -20",
        "Ka 1e39",
        "Kd x y z",
    ] {
        let e = load_mtl_scene(&dir, &format!("newmtl a\n{bad}\n"))
            .expect_err(&format!("`{bad}` accepted"));
        assert!(e.contains("m.mtl:2:"), "`{bad}`: {e}");
    }
}

// Case 16.

#[test]
fn faces_with_fewer_than_three_corners_and_vn_index_zero_are_errors() {
    let dir = Scratch::new("hostile-faces");
    let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\n";
    for (f, what) in [
        ("f 1\n", ObjRead::default()),
        ("f 1 2\n", ObjRead::default()),
        ("f 1//0 2//1 3//1\n", ObjRead::default()),
        (
            "f 1//0 2//1 3//1\n",
            ObjRead {
                normals: true,
                materials: false,
            },
        ),
    ] {
        let path = dir.write("m.obj", &format!("{v}{f}"));
        let e = ObjMesh::read_with(&path, what).expect_err(&format!("`{f}` accepted"));
        assert!(chain(&e).contains("m.obj:5:"), "`{f}`: {}", chain(&e));
        let bytes = std::fs::read(&path).unwrap();
        let e = wavefront::mesh::obj_fast::read_bytes(&path, &bytes)
            .expect_err(&format!("`{f}` accepted by the fast reader"));
        assert!(chain(&e).contains("m.obj:5:"), "`{f}`: {}", chain(&e));
    }
}

// Case 11.

#[test]
fn a_file_that_is_not_obj_is_an_error_naming_the_line_not_an_empty_mesh() {
    let dir = Scratch::new("hostile-not-obj");
    let nul = String::from_utf8(vec![0u8; 100_000]).unwrap();
    for (text, line) in [
        (nul.as_str(), 1),
        ("root:x:0:0:root:/root:/bin/bash\n", 1),
        ("# comment\nv 0 0 0\nhello world\n", 3),
        ("ply\nformat ascii 1.0\nelement vertex 3\n", 1),
    ] {
        let path = dir.write("m.obj", text);
        let e = TriangleMesh::load_obj(&path).expect_err("not an OBJ file accepted");
        let want = format!("m.obj:{line}:");
        assert!(chain(&e).contains(&want), "{}", chain(&e));
        let e = wavefront::mesh::obj_fast::read_bytes(&path, text.as_bytes())
            .expect_err("not an OBJ file accepted by the fast reader");
        assert!(chain(&e).contains(&want), "{}", chain(&e));
    }
}

#[test]
fn a_file_bad_beyond_the_first_look_is_refused_with_the_checks_error_on_every_load_path() {
    // The render looks at the first 64 KiB before reading a mesh and checks its first MiB before
    // parsing it: a bad line at about 200 KB is found by the second check, with the error
    // `ObjMesh::read` gives (file and line), with or without a tree cache.
    let dir = Scratch::new("hostile-bad-late");
    let good = TRIANGLE.repeat(200_000 / TRIANGLE.len());
    let line = good.lines().count() + 1;
    dir.write("m.obj", &format!("{good}hello world\n{TRIANGLE}"));
    let want = chain(&ObjMesh::read(&dir.join("m.obj")).expect_err("a bad OBJ file accepted"));
    assert!(want.contains(&format!("m.obj:{line}:")), "{want}");
    let scene = load(&dir.write(
        "s.toml",
        &scene_text("[[mesh]]\npath = \"m.obj\"\nmaterial = \"floor\"\n"),
    ))
    .expect("scene");
    let e = World::load(&scene).map(|_| ()).expect_err("no cache");
    assert_eq!(chain(&e), want);
    let cache = wavefront::accel::cache::TreeCache::new(dir.join("cache"));
    let e = World::load_cached(&scene, Some(&cache))
        .map(|_| ())
        .expect_err("with a cache");
    assert_eq!(chain(&e), want);
}

#[test]
fn cr_only_line_endings_keep_the_mesh() {
    let dir = Scratch::new("hostile-cr");
    let text = TRIANGLE.replace('\n', "\r");
    let path = dir.write("m.obj", &text);
    let mesh = TriangleMesh::load_obj(&path).expect("CR-only OBJ");
    assert_eq!(mesh.len(), 1);
    let fast = wavefront::mesh::obj_fast::read_bytes(&path, text.as_bytes()).expect("CR-only OBJ");
    assert_eq!(fast.indices.len(), 1);
}

/// The scene `body` in `dir`, loaded into a world; the error line if either fails.
fn load_world(dir: &Scratch, body: &str) -> Result<World, String> {
    let scene = dir.write("s.toml", &scene_text(body));
    let scene = load(&scene).map_err(|e| chain(&e))?;
    World::load(&scene).map_err(|e| chain(&e))
}

#[test]
fn a_mesh_without_triangles_is_an_error_unless_the_scene_allows_it() {
    let dir = Scratch::new("hostile-empty");
    dir.write("m.obj", "# nothing here\nv 0 0 0\n");
    let e = load_world(&dir, "[[mesh]]\npath = \"m.obj\"\nmaterial = \"floor\"\n")
        .map(|_| ())
        .expect_err("an empty mesh was accepted");
    assert!(e.contains("m.obj") && e.contains("no triangles"), "{e}");
    load_world(
        &dir,
        "[[mesh]]\npath = \"m.obj\"\nmaterial = \"floor\"\nallow_empty = true\n",
    )
    .expect("allowed empty mesh");
}

#[test]
fn obj_text_in_a_ply_or_gltf_path_or_an_unknown_extension_is_an_error_naming_the_file() {
    let dir = Scratch::new("hostile-misnamed");
    for (name, want) in [
        ("m.ply", "not a PLY file"),
        ("m.gltf", "not a valid glTF 2.0 file"),
        ("m.glb", "not a valid glTF 2.0 file"),
        ("m.stl", "unknown mesh format .stl"),
    ] {
        dir.write(name, TRIANGLE);
        let e = load_world(
            &dir,
            &format!("[[mesh]]\npath = \"{name}\"\nmaterial = \"floor\"\n"),
        )
        .err()
        .unwrap_or_else(|| panic!("{name} accepted"));
        assert!(e.contains(name) && e.contains(want), "{e}");
    }
}

// Case 12.

#[test]
fn a_tiny_or_huge_plane_normal_is_normalised_not_lost() {
    for n in ["[0.0, 1e-25, 0.0]", "[0.0, 1e-40, 0.0]", "[0.0, 1e30, 0.0]"] {
        let text = scene_text(&format!(
            "[[plane]]\npoint = [0.0, -1.0, 0.0]\nnormal = {n}\nmaterial = \"floor\"\n"
        ));
        let scene = parse(&text, Path::new("s.toml")).unwrap_or_else(|e| panic!("{n}: {e}"));
        assert_eq!(scene.planes[0].normal, Vec3::Y, "{n}");
    }
}

// Case 13.

#[test]
fn arrays_longer_than_three_are_errors() {
    for (body, line) in [
        (
            "[[sphere]]\ncenter = [-4.0, 0.0, -7.0, \"junk\", {a = 1}]\nradius = 1.0\nmaterial = \"floor\"\n",
            11,
        ),
        ("[render]\nambient = [1.0, 1.0, 1.0, 99.0]\n", 11),
        ("[render]\nambient = [1.0, 1.0]\n", 11),
    ] {
        let text = scene_text(body);
        let e = parse(&text, Path::new("s.toml"))
            .err()
            .unwrap_or_else(|| panic!("accepted:\n{body}"));
        let e = e.to_string();
        assert!(e.starts_with(&format!("s.toml:{line}:")), "{e}");
        assert!(e.contains('3'), "{e}");
    }
}

// Unclear errors.

#[test]
fn huge_numbers_in_messages_are_printed_short() {
    let text =
        scene_text("[[sphere]]\ncenter = [0.0, 0.0, -7.0]\nradius = 1e308\nmaterial = \"floor\"\n");
    let e = parse(&text, Path::new("s.toml")).expect_err("accepted");
    let e = e.to_string();
    assert!(e.contains("1e308") && e.len() < 120, "{e}");
}

#[test]
fn a_missing_user_mesh_is_not_described_as_the_sibenik_mesh() {
    let dir = Scratch::new("hostile-missing");
    let e = load_world(
        &dir,
        "[[mesh]]\npath = \"bunnyy.obj\"\nmaterial = \"floor\"\n",
    )
    .map(|_| ())
    .expect_err("a missing mesh was accepted");
    assert!(e.contains("bunnyy.obj"), "{e}");
    assert!(!e.contains("Sibenik") && !e.contains("75,284"), "{e}");
}

#[test]
fn a_directory_as_mesh_path_says_it_is_a_directory() {
    let dir = Scratch::new("hostile-dir-mesh");
    std::fs::create_dir_all(dir.join("d.obj")).unwrap();
    for material in ["floor", "mtl"] {
        let e = load_world(
            &dir,
            &format!("[[mesh]]\npath = \"d.obj\"\nmaterial = \"{material}\"\n"),
        )
        .map(|_| ())
        .expect_err("a directory was accepted as a mesh");
        assert!(e.contains("d.obj") && e.contains("is a directory"), "{e}");
        assert!(!e.contains("scene file"), "{e}");
    }
}

// Case 4.

#[test]
fn a_fifo_as_scene_file_or_mesh_is_an_error_not_a_hang() {
    let dir = Scratch::new("hostile-fifo");
    let fifo = dir.join("f.toml");
    mkfifo(&fifo);
    let e = within(20, "scene FIFO", move || load(&fifo).map(|_| ()))
        .expect_err("a FIFO was read as a scene file");
    let e = chain(&e);
    assert!(e.contains("f.toml") && e.contains("FIFO"), "{e}");
    mkfifo(&dir.join("f.obj"));
    let scene = dir.write(
        "s.toml",
        &scene_text("[[mesh]]\npath = \"f.obj\"\nmaterial = \"floor\"\n"),
    );
    let e = within(20, "mesh FIFO", move || {
        let scene = load(&scene).map_err(|e| chain(&e))?;
        World::load(&scene).map(|_| ()).map_err(|e| chain(&e))
    })
    .expect_err("a FIFO was read as a mesh");
    assert!(e.contains("f.obj") && e.contains("FIFO"), "{e}");
}

// Case 3 (scene files).

#[test]
fn an_oversized_scene_file_is_refused_with_its_cap() {
    let dir = Scratch::new("hostile-big-scene");
    let path = dir.join("big.toml");
    let f = std::fs::File::create(&path).unwrap();
    f.set_len(64 << 20).unwrap(); // sparse: no disk used
    drop(f);
    let e = load(&path).expect_err("a 64 MiB scene file was read");
    let e = chain(&e);
    assert!(e.contains("big.toml") && e.contains("MiB"), "{e}");
}

// Cases 5, 6, 7, 9 (output files).

fn film() -> Film {
    let mut f = Film::new(2, 1);
    f.pixels[0] = Vec3::ONE;
    f
}

#[test]
fn a_planted_symlink_at_the_temporary_name_is_not_followed() {
    let dir = Scratch::new("hostile-symlink");
    let victim = dir.write("victim", "precious");
    let out = dir.join("out.ppm");
    std::os::unix::fs::symlink(&victim, dir.join("out.ppm.partial")).unwrap();
    film().save(&out, 2.2).expect("saved");
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
    assert!(std::fs::read(&out).unwrap().starts_with(b"P6"));
}

#[test]
fn an_output_path_that_is_not_a_regular_file_is_an_error_and_kept() {
    let dir = Scratch::new("hostile-fifo-out");
    let out = dir.join("out.ppm");
    mkfifo(&out);
    let e = film().save(&out, 2.2).expect_err("a FIFO was replaced");
    assert!(chain(&e).contains("out.ppm"), "{}", chain(&e));
    use std::os::unix::fs::FileTypeExt;
    assert!(
        std::fs::symlink_metadata(&out)
            .unwrap()
            .file_type()
            .is_fifo()
    );
    assert_eq!(dir.files(), vec!["out.ppm"], "a temporary file was left");
}

#[test]
fn two_writers_of_one_output_use_distinct_temporary_files() {
    let dir = Scratch::new("hostile-two-writers");
    let out = dir.join("out.ppm");
    let (a, mut fa) = wavefront::film::output::PartialFile::create(&out).unwrap();
    let (b, mut fb) = wavefront::film::output::PartialFile::create(&out).unwrap();
    use std::io::Write;
    fb.write_all(b"short").unwrap();
    fa.write_all(b"a much longer content").unwrap();
    drop((fa, fb));
    // A leftover temporary file never looks like an output.
    for name in dir.files() {
        assert!(!name.ends_with(".ppm"), "{name}");
    }
    a.commit().unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), b"a much longer content");
    b.commit().unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), b"short");
    assert_eq!(dir.files(), vec!["out.ppm"]);
}

#[test]
fn a_255_byte_output_name_can_be_written() {
    let dir = Scratch::new("hostile-long-name");
    let name = format!("{}.ppm", "x".repeat(251));
    assert_eq!(name.len(), 255);
    let out: PathBuf = dir.join(&name);
    film()
        .save(&out, 2.2)
        .unwrap_or_else(|e| panic!("{}", chain(&e)));
    assert_eq!(dir.files(), vec![name]);
}

// Case 10: `render --kdtree FILE` checks the tree as `kdtree check` does (in the frame centred
// on the mesh, where `kdtree build` builds and the file reads back exactly).

#[test]
fn a_tree_file_for_another_mesh_is_an_error_not_a_wrong_image() {
    let dir = Scratch::new("hostile-tree");
    // A 16 × 16 grid of quads (512 triangles, enough for the tree to have structure), and the
    // same faces in reverse order: the same triangle count, other triangle indices.
    let grid = |reversed: bool| {
        let n = 16;
        let mut s = String::new();
        for j in 0..=n {
            for i in 0..=n {
                s.push_str(&format!("v {} {} -5\n", i as f64 - 8.0, j as f64 - 8.0));
            }
        }
        let mut faces = vec![];
        for j in 0..n {
            for i in 0..n {
                let v = |di: usize, dj: usize| (j + dj) * (n + 1) + i + di + 1;
                faces.push(format!("f {} {} {}\n", v(0, 0), v(1, 0), v(1, 1)));
                faces.push(format!("f {} {} {}\n", v(0, 0), v(1, 1), v(0, 1)));
            }
        }
        if reversed {
            faces.reverse();
        }
        s + &faces.concat()
    };
    let a = dir.write("a.obj", &grid(false));
    dir.write("b.obj", &grid(true));
    let mesh = TriangleMesh::load_obj(&a).unwrap();
    let mut text = Vec::new();
    wavefront::accel::kdtree::KdTree::build(&mesh, wavefront::accel::kdtree::BuildMethod::Sah)
        .write_text(&mut text)
        .unwrap();
    std::fs::write(dir.join("t.kd"), &text).unwrap();
    let body = |obj: &str| {
        format!("[[mesh]]\npath = \"{obj}\"\nmaterial = \"floor\"\nkdtree = \"t.kd\"\n")
    };
    load_world(&dir, &body("a.obj")).expect("the tree of a.obj fits a.obj");
    let e = load_world(&dir, &body("b.obj"))
        .map(|_| ())
        .expect_err("a tree built for another mesh was used");
    assert!(e.contains("t.kd") && e.contains("invalid tree"), "{e}");
    // A tree whose leaves miss triangles: every leaf's first triangle index dropped.
    let text = String::from_utf8(text).unwrap();
    let holed: String = text
        .lines()
        .map(|l| match l.split_once("; ") {
            Some((head, tris)) if l.starts_with("leaf") && tris.split(' ').count() > 2 => {
                let rest: Vec<&str> = tris.split(' ').skip(1).collect();
                format!("{head}; {}\n", rest.join(" "))
            }
            _ => format!("{l}\n"),
        })
        .collect();
    assert_ne!(holed, text, "some leaf lost a triangle");
    std::fs::write(dir.join("t.kd"), holed).unwrap();
    let e = load_world(&dir, &body("a.obj"))
        .map(|_| ())
        .expect_err("a tree missing triangles was used");
    assert!(e.contains("t.kd") && e.contains("misses triangle"), "{e}");
}

// Case 9: EXR bytes.

#[test]
fn exr_bytes_are_the_same_on_every_write() {
    let dir = Scratch::new("hostile-exr");
    let mut film = Film::new(256, 256);
    for (i, p) in film.pixels.iter_mut().enumerate() {
        *p = Vec3::new(
            (i % 251) as f32 / 7.0,
            (i % 13) as f32,
            (i / 256) as f32 * 0.01,
        );
    }
    let first = dir.join("a.exr");
    film.save(&first, 2.2).unwrap();
    let first = std::fs::read(&first).unwrap();
    for k in 0..8 {
        let again = dir.join(&format!("b{k}.exr"));
        wavefront_kit::testkit::in_pool(1 + k % 3, || film.save(&again, 2.2)).unwrap();
        assert!(std::fs::read(&again).unwrap() == first, "write {k} differs");
    }
}

// Case 15.

/// A 3 × 3 scene in `dir` of one triangle facing the camera at z = -5, spanning ±`s` around the
/// view axis, lit by a point light at the eye.
fn huge_triangle_scene(dir: &Scratch, s: f64, shadows: bool) -> wavefront::Scene {
    dir.write(
        "t.obj",
        &format!(
            "v {} {} -5\nv {} {} -5\nv 0 {} -5\nf 1 2 3\n",
            -s, -s, s, -s, s
        ),
    );
    let scene = dir.write(
        "s.toml",
        &format!(
            "[image]\nwidth = 3\nheight = 3\n\n{}[render]\nshadows = {shadows}\n\n\
             [[light]]\nposition = [0.0, 0.0, 0.0]\n\n\
             [[mesh]]\npath = \"t.obj\"\nmaterial = \"floor\"\n",
            scene_text("")
        ),
    );
    load(&scene).unwrap_or_else(|e| panic!("{}", chain(&e)))
}

#[test]
fn a_huge_triangle_is_shaded_like_a_small_one() {
    // A triangle facing the camera at z = -5, spanning ±1 or ±1e18 around the view axis, lit
    // from the eye: the centre pixel sees the same point, normal and light either way. Without
    // shadow rays: their offsets at such sizes are the other half of case 15, not mended here.
    let dir = Scratch::new("hostile-huge-triangle");
    let centre = |s: f64| {
        let scene = huge_triangle_scene(&dir, s, false);
        let film = wavefront_kit::testkit::render_film_with(&scene, Default::default());
        film.pixels[4]
    };
    let small = centre(1.0);
    assert!(small.x > 0.5, "the small triangle is lit: {small}");
    // From ±1e10 the f32 square length of the normal overflowed (NaN shading: the direct light
    // was lost). Beyond ±1e12 (mesh::MAX_FRAME_COORDINATE) the mesh is refused: see below.
    for s in [1e10, 1e12] {
        assert_eq!(centre(s), small, "±{s}");
    }
}

#[test]
fn a_triangle_beyond_the_f32_triangle_test_is_an_error_not_a_black_image() {
    // At ±1e19 the f32 intersection test overflowed and the triangle rendered black (exit 0);
    // from about ±2e12 at depth its distance term can overflow too. Such a mesh is now refused,
    // naming the file and the limit, on every load path (the tree cache's and the direct one).
    let dir = Scratch::new("hostile-beyond-f32-test");
    for s in [1e13f64, 1e18, 1e19] {
        let scene = huge_triangle_scene(&dir, s, true);
        let e = World::load(&scene)
            .map(|_| ())
            .expect_err("a mesh beyond the limit");
        let msg = chain(&e);
        assert!(
            msg.contains("t.obj") && msg.contains("the f32 triangle test overflows"),
            "±{s}: {msg}"
        );
        let cache = wavefront::accel::cache::TreeCache::new(dir.join("cache"));
        let e = World::load_cached(&scene, Some(&cache))
            .map(|_| ())
            .expect_err("the cache path refuses it too");
        assert!(
            chain(&e).contains("the f32 triangle test overflows"),
            "±{s} (cache): {}",
            chain(&e)
        );
    }
}

// Issue 26: PLY and glTF meshes get the same treatment as OBJ.

/// A PLY header for `vertices` `float x y z` vertices and `faces` `uchar int` index lists.
fn ply_header(format: &str, vertices: &str, faces: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\n\
         property float y\nproperty float z\nelement face {faces}\n\
         property list uchar int vertex_indices\nend_header\n"
    )
}

#[test]
fn bad_ply_files_are_one_line_errors_naming_the_file_and_line_or_face() {
    let dir = Scratch::new("hostile-ply");
    let ascii = |body: &str, faces: usize| {
        format!("{}{body}", ply_header("ascii", "3", &faces.to_string()))
    };
    let v = "0 0 -3\n1 0 -3\n0 1 -3\n";
    // The header is 9 lines: vertices on lines 10–12, faces from line 13.
    let cases: Vec<(String, &str)> = vec![
        (
            ascii(&format!("{v}3 0 1 2\n3 0 1 7\n"), 2),
            "line 14: face 1: vertex index 7 out of range (3 vertices)",
        ),
        (
            ascii(&format!("{v}3 0 -1 2\n"), 1),
            "line 13: face 0: vertex index -1 out of range",
        ),
        (
            ascii(&format!("{v}2 0 1\n"), 1),
            "line 13: face 0: needs at least 3 vertices, not 2",
        ),
        (
            ascii("0 0 nan\n1 0 -3\n0 1 -3\n3 0 1 2\n", 1),
            ":10: parse error: ply: in the `vertex` element",
        ),
        (
            ascii("0 0 1e39\n1 0 -3\n0 1 -3\n3 0 1 2\n", 1),
            "vertex 0: non-finite",
        ),
        (
            ascii("0 0 x\n", 1),
            ":10: parse error: ply: in the `vertex` element",
        ),
        (ascii(v, 1), "`face` element"),
        (
            "ply\nformat ascii 1.0\nend_header\n".into(),
            "no `vertex` element",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n".into(),
            "no `y` property",
        ),
        ("solid stl\n".into(), "not a PLY file"),
        (String::new(), "not a PLY file"),
        (ply_header("ascii", "4000000000", "1"), "`vertex` element"),
        (
            format!(
                "{}{}",
                ply_header("binary_little_endian", "3", "1"),
                "\u{1}\u{2}"
            ),
            "`vertex` element",
        ),
        (
            "ply\nformat binary_middle_endian 1.0\nend_header\n".into(),
            "fuzz.ply",
        ),
    ];
    for (text, want) in cases {
        let path = dir.write("fuzz.ply", &text);
        let e = within(20, want, move || ObjMesh::read(&path).map(|m| m.len()))
            .expect_err(&format!("accepted:\n{text}"));
        let e = chain(&e);
        assert!(
            e.contains("fuzz.ply") && e.contains(want),
            "want {want:?}: {e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}

#[test]
fn a_ply_without_faces_is_an_empty_mesh_error_unless_allowed() {
    let dir = Scratch::new("hostile-ply-empty");
    std::fs::write(
        dir.join("m.ply"),
        format!("{}0 0 -3\n", ply_header("ascii", "1", "0")),
    )
    .unwrap();
    let body = "[[mesh]]\npath = \"m.ply\"\nmaterial = \"floor\"\n";
    let e = load_world(&dir, body)
        .map(|_| ())
        .expect_err("an empty PLY was accepted");
    assert!(e.contains("m.ply") && e.contains("no triangles"), "{e}");
    load_world(&dir, &format!("{body}allow_empty = true\n")).expect("allow_empty");
}

/// A one-triangle glTF whose buffer is at `uri`, with `extra` JSON members at the top level and
/// `nodes` as the node list.
fn gltf_text(uri: &str, nodes: &str, byte_length: usize) -> String {
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
  "nodes": {nodes},
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
  "buffers": [{{"uri": "{uri}", "byteLength": {byte_length}}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                  "min": [-1, -1, -3], "max": [1, 1, -3]}}]}}"#
    )
}

/// The 36 bytes of the triangle (-1, -1, -3), (1, -1, -3), (0, 1, -3).
fn triangle_bin() -> Vec<u8> {
    [-1.0f32, -1.0, -3.0, 1.0, -1.0, -3.0, 0.0, 1.0, -3.0]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect()
}

#[test]
fn bad_gltf_files_are_one_line_errors_naming_the_file() {
    let dir = Scratch::new("hostile-gltf");
    std::fs::write(dir.join("t.bin"), triangle_bin()).unwrap();
    std::fs::write(dir.join("short.bin"), &triangle_bin()[..20]).unwrap();
    mkfifo(&dir.join("fifo.bin"));
    let one = r#"[{"mesh": 0}]"#;
    // The valid file reads, so each case below fails for its own reason.
    let path = dir.write("ok.gltf", &gltf_text("t.bin", one, 36));
    assert_eq!(ObjMesh::read(&path).expect("the valid file").len(), 1);
    let cases = [
        (gltf_text("missing.bin", one, 36), "buffer 0: cannot read"),
        (gltf_text("fifo.bin", one, 36), "is a FIFO"),
        (
            gltf_text("short.bin", one, 36),
            "buffer 0 holds 20 bytes, less than its byteLength 36",
        ),
        (
            gltf_text("t.bin", one, 36).replace(
                r#""byteLength": 36}]"#,
                r#""byteLength": 36, "byteOffset": 8}]"#,
            ),
            "reaches past the end of buffer 0",
        ),
        (
            gltf_text("t.bin", one, 36).replace(r#""count": 3"#, r#""count": 4"#),
            "accessor 0: 4 elements reach past the end of bufferView 0",
        ),
        (
            gltf_text("t.bin", one, 36)
                .replace(r#""componentType": 5126"#, r#""componentType": 5121"#),
            "accessor 0 (POSITION): must be float VEC3",
        ),
        (
            gltf_text("t.bin", r#"[{"mesh": 0, "children": [0]}]"#, 36),
            "node 0 is reached twice",
        ),
        (
            gltf_text(
                "t.bin",
                r#"[{"mesh": 0, "children": [1]}, {"children": [0]}]"#,
                36,
            ),
            "is reached twice",
        ),
        (
            gltf_text("t.bin", one, 36).replace(r#""POSITION": 0"#, r#""POSITION": 5"#),
            "names accessor 5, of 1",
        ),
        (
            gltf_text("data:application/octet-stream;base64,@@@@", one, 36),
            "bad base64",
        ),
        (
            gltf_text("https://example.com/t.bin", one, 36),
            "only local files",
        ),
        (
            gltf_text("t.bin", one, 36).replace(r#""version": "2.0""#, r#""version": 2"#),
            "not a valid glTF 2.0 file",
        ),
        ("{".into(), "not a valid glTF 2.0 file"),
        ("glTF\u{2}\0\0\0".into(), "not a valid glTF 2.0 file"),
    ];
    for (text, want) in cases {
        let path = dir.write("bad.gltf", &text);
        let e = within(20, want, move || ObjMesh::read(&path).map(|m| m.len()))
            .expect_err(&format!("accepted:\n{text}"));
        let e = chain(&e);
        assert!(
            e.contains("bad.gltf") && e.contains(want),
            "want {want:?}: {e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}

#[test]
fn a_ply_put_in_for_an_mtl_bound_obj_takes_the_fallback_not_a_panic() {
    let dir = Scratch::new("hostile-mesh-swap");
    dir.write("m.mtl", "newmtl a\nKd 0.5 0.5 0.5\n");
    dir.write("m.obj", &format!("mtllib m.mtl\nusemtl a\n{TRIANGLE}"));
    std::fs::write(
        dir.join("m.ply"),
        format!(
            "{}-1 -1 -3\n1 -1 -3\n0 1 -3\n3 0 1 2\n",
            ply_header("ascii", "3", "1")
        ),
    )
    .unwrap();
    let body = "[[mesh]]\npath = \"m.obj\"\nmaterial = \"mtl\"\nfallback_material = \"floor\"\n";
    let path = dir.write("s.toml", &scene_text(body));
    let mut scene = load(&path).unwrap_or_else(|e| panic!("{}", chain(&e)));
    // What `--mesh m.ply` does: the path changes, the MTL binding stays.
    scene.meshes[0].path = dir.join("m.ply");
    scene.image.width = 8;
    scene.image.height = 8;
    let world = World::load(&scene).unwrap_or_else(|e| panic!("{}", chain(&e)));
    let t = world.triangles().expect("the triangle");
    assert_eq!(
        t.material(0),
        scene.meshes[0].mtl.as_ref().unwrap().fallback.unwrap()
    );
}
