//! Meshes in other formats (SPEC §15) render from the command line: a PLY file (ASCII, binary
//! little- and big-endian) renders byte-identically to the OBJ of the same faces, through a scene
//! file (with and without the tree cache) and bare (`wavefront render mesh.ply`); `info` reads
//! every format.

use wavefront_kit::meshes::{PlyEncoding, PolyMesh};
use wavefront_kit::testkit::Scratch;

fn run(dir: &Scratch, args: &[&str]) -> std::process::Output {
    dir.command(env!("CARGO_BIN_EXE_wavefront"))
        .args(args)
        .output()
        .expect("cannot run the wavefront binary")
}

fn ok(o: &std::process::Output) {
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A scene of `mesh` framed automatically, with a specular material, shadows and two lights.
fn scene(mesh: &str, normals: &str) -> String {
    format!(
        "[image]\nwidth = 120\nheight = 90\n\n[camera]\nframe = \"auto\"\n\n\
         [[light]]\nposition = [3.0, 4.0, 2.0]\nintensity = [0.8, 0.8, 0.8]\n\n\
         [[light]]\nposition = [-2.0, 1.0, 3.0]\nintensity = [0.3, 0.3, 0.4]\n\n\
         [material.m]\nka = [0.05, 0.05, 0.05]\nkd = [0.7, 0.5, 0.3]\nks = [0.4, 0.4, 0.4]\n\
         p = 30.0\n\n[[mesh]]\npath = \"{mesh}\"\nmaterial = \"m\"\nnormals = \"{normals}\"\n"
    )
}

#[test]
fn ply_renders_byte_identically_to_the_obj_of_the_same_faces() {
    let dir = Scratch::new("ply-equals-obj");

    let mesh = PolyMesh::bumpy(9);
    std::fs::write(dir.join("m.obj"), mesh.obj()).unwrap();
    let plys = [
        ("a.ply", PlyEncoding::Ascii),
        ("le.ply", PlyEncoding::LittleEndian),
        ("be.ply", PlyEncoding::BigEndian),
    ];
    for (name, enc) in plys {
        std::fs::write(dir.join(name), mesh.ply(enc)).unwrap();
    }
    for normals in ["geometric", "vertex"] {
        dir.write("obj.toml", &scene("m.obj", normals));
        ok(&run(
            &dir,
            &["render", "obj.toml", "-o", "obj.png", "--no-cache"],
        ));
        let reference = std::fs::read(dir.join("obj.png")).unwrap();
        for (name, _) in plys {
            dir.write("ply.toml", &scene(name, normals));
            // Twice through the tree cache (stored, then read) and once without it.
            for (cache, status) in [
                (&["--stats"][..], "cache: Stored"),
                (&["--stats"][..], "cache: Hit"),
                (&["--no-cache"][..], ""),
            ] {
                let mut args = vec!["render", "ply.toml", "-o", "ply.png"];
                args.extend(cache);
                let o = run(&dir, &args);
                ok(&o);
                let out = String::from_utf8_lossy(&o.stdout);
                // Vertex normals take the uncached path (as for OBJ).
                let status = if normals == "vertex" { "" } else { status };
                assert!(out.contains(status), "{name}: {out}");
                let bytes = std::fs::read(dir.join("ply.png")).unwrap();
                assert!(
                    bytes == reference,
                    "{name} ({normals} normals, {cache:?}) differs from the OBJ render"
                );
            }
        }
    }
    // Bare: `wavefront render mesh.ply` frames it as `render mesh.obj` does.
    ok(&run(
        &dir,
        &["render", "m.obj", "-o", "bare-obj.png", "--size", "64x48"],
    ));
    ok(&run(
        &dir,
        &["render", "be.ply", "-o", "bare-ply.png", "--size", "64x48"],
    ));
    assert_eq!(
        std::fs::read(dir.join("bare-obj.png")).unwrap(),
        std::fs::read(dir.join("bare-ply.png")).unwrap(),
        "bare PLY render differs from the bare OBJ render"
    );
    // The same image is not a blank one.

    let img = image::open(dir.join("bare-ply.png")).unwrap().to_rgb8();
    assert!(img.pixels().filter(|p| p.0 != [0, 0, 0]).count() > 150);
}

#[test]
fn info_reads_ply_and_gltf() {
    let dir = Scratch::new("info-formats");
    let mesh = PolyMesh::bumpy(4);
    let triangles = mesh.triangles().len();
    std::fs::write(dir.join("m.ply"), mesh.ply(PlyEncoding::LittleEndian)).unwrap();
    std::fs::write(dir.join("m.glb"), mesh.glb(None)).unwrap();
    mesh.gltf_files(dir.path(), "ext", None);
    for f in ["m.ply", "m.glb", "ext.gltf"] {
        let o = run(&dir, &["info", f, "--json"]);
        ok(&o);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            out.contains(&format!("\"triangles\":{triangles}")),
            "{f}: {out}"
        );
    }
}

#[test]
fn the_tree_cache_key_follows_a_gltf_files_external_buffer() {
    let dir = Scratch::new("gltf-cache");
    let mesh = PolyMesh::bumpy(6);
    mesh.gltf_files(dir.path(), "m", None);
    dir.write("s.toml", &scene("m.gltf", "geometric"));
    let render = |out: &str| {
        let o = run(&dir, &["render", "s.toml", "-o", out, "--stats"]);
        ok(&o);
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    assert!(render("a.png").contains("cache: Stored"));
    assert!(render("b.png").contains("cache: Hit"));
    // The same .gltf over another .bin (the mesh moved): a new entry, a new image.
    let mut moved = mesh.clone();
    for p in &mut moved.positions {
        p[1] += 0.25;
    }
    moved.gltf_files(dir.path(), "moved", None);
    std::fs::copy(dir.join("moved.bin"), dir.join("m.bin")).unwrap();
    let out = render("c.png");
    assert!(out.contains("cache: Stored"), "{out}");
    let same =
        std::fs::read(dir.join("a.png")).unwrap() == std::fs::read(dir.join("c.png")).unwrap();
    assert!(!same, "the moved mesh rendered as the old one");
    // And the moved render is the one an uncached run makes.
    ok(&run(
        &dir,
        &["render", "s.toml", "-o", "d.png", "--no-cache"],
    ));
    assert_eq!(
        std::fs::read(dir.join("c.png")).unwrap(),
        std::fs::read(dir.join("d.png")).unwrap()
    );
}

/// Regression (session 8): `kdtree build` keyed a PLY's entry by its bytes alone while a render
/// keys it by format tag and bytes (the same bytes read as another format are another mesh), so
/// a render never hit what `kdtree build` stored. Both now take the key from one function.
#[test]
fn a_ply_tree_from_kdtree_build_is_the_entry_a_render_hits() {
    let dir = Scratch::new("ply-kdtree-cache");
    let mesh = PolyMesh::bumpy(9);
    std::fs::write(dir.join("m.ply"), mesh.ply(PlyEncoding::LittleEndian)).unwrap();
    dir.write("ply.toml", &scene("m.ply", "geometric"));
    ok(&run(
        &dir,
        &["kdtree", "build", "m.ply", "-o", "m.kd", "--cache", "cache"],
    ));
    let o = run(
        &dir,
        &[
            "render", "ply.toml", "-o", "p.png", "--cache", "cache", "--stats",
        ],
    );
    ok(&o);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("cache: Hit"), "{stdout}");
}
