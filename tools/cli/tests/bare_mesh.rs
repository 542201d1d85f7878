//! `wavefront render MESH.obj` with no scene file frames the mesh (SPEC §16).

use wavefront_kit::testkit::Scratch;

/// A cube from (1, 2, 3) to (3, 4, 5), as 12 triangles.
const CUBE: &str = "v 1 2 3\nv 3 2 3\nv 3 4 3\nv 1 4 3\nv 1 2 5\nv 3 2 5\nv 3 4 5\nv 1 4 5\n\
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 7 3\nf 4 8 7\nf 1 5 8\nf 1 8 4\n\
f 2 3 7\nf 2 7 6\n";

fn run(dir: &Scratch, args: &[&str]) -> std::process::Output {
    let mut c = dir.command(env!("CARGO_BIN_EXE_wavefront"));
    c.args(args)
        .output()
        .expect("cannot run the wavefront binary")
}

#[test]
fn a_bare_mesh_is_framed_centred_and_whole() {
    let dir = Scratch::new("bare-mesh");
    std::fs::write(dir.path().join("cube.obj"), CUBE).unwrap();
    let o = run(&dir, &["render", "cube.obj", "-o", "cube.ppm"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(dir.path().join("cube.ppm")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (512, 512));
    let lit = |x: u32, y: u32| img.get_pixel(x, y).0 != [0, 0, 0];
    // The box's centre is at the image centre, and its bounding sphere fits inside the image:
    // nothing touches the border, and the cube (whose sphere is √3 times its half-side) spans
    // well over a third of the image.
    assert!(lit(256, 256), "the centre pixel sees the cube");
    for i in 0..512 {
        for (x, y) in [(i, 0), (i, 511), (0, i), (511, i)] {
            assert!(!lit(x, y), "the border pixel ({x}, {y}) sees the cube");
        }
    }
    let row: Vec<u32> = (0..512).filter(|&x| lit(x, 256)).collect();
    let span = row.last().unwrap() - row.first().unwrap();
    assert!(span > 200, "the cube spans {span} px of the middle row");
    // Lit from the eye: every visible face is lit, nothing in the cube is black.
    assert!(row.iter().all(|&x| img.get_pixel(x, 256).0[0] > 25));
}

#[test]
fn other_mesh_formats_are_named_not_read_as_scene_files() {
    let dir = Scratch::new("bare-ply");
    std::fs::write(
        dir.path().join("bunny.ply"),
        "ply\nformat ascii 1.0\nend_header\n",
    )
    .unwrap();
    let o = run(&dir, &["render", "bunny.ply", "-o", "b.png"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bunny.ply") && err.contains("no `vertex` element"),
        "{err}"
    );
    assert!(!err.contains("TOML") && !err.contains("expected"), "{err}");
    assert!(!dir.path().join("b.png").exists());
}

#[test]
fn info_describes_a_mesh_and_a_scene() {
    let dir = Scratch::new("info");
    std::fs::write(dir.path().join("cube.obj"), CUBE).unwrap();
    let o = run(&dir, &["info", "cube.obj", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["triangles"], 12);
    let mesh = &v["meshes"][0];
    assert_eq!(
        (&mesh["vertices"], &mesh["degenerate"]),
        (&8.into(), &0.into())
    );
    assert_eq!(
        mesh["bounds"],
        serde_json::json!([[1.0, 2.0, 3.0], [3.0, 4.0, 5.0]])
    );
    assert_eq!(v["materials"][0]["faces"], 12);
    assert_eq!(v["lights"].as_array().unwrap().len(), 1);
    assert!(
        v["pipeline"]
            .as_str()
            .unwrap()
            .contains("depth 0: generate")
    );
    // The room: its 12 × 24 UV-sphere ball has 2 × 24 degenerate triangles at the poles, and
    // each wall material of room.mtl covers one quad.
    let room = wavefront_kit::testkit::project_root().join("scenes/room.toml");
    let o = run(&dir, &["info", room.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("576 triangles (48 degenerate)"), "{text}");
    assert!(
        text.contains("room.obj:red: ") && text.contains("(2 faces)"),
        "{text}"
    );
}
