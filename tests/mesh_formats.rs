//! Meshes from PLY and glTF files (SPEC §15): every encoding reads the same triangles as the OBJ of
//! the same faces; a glTF node transform is applied (the render is checked against the f64 oracle
//! of an OBJ holding the transformed triangles); `material = "gltf"` maps PBR factors to
//! Blinn-Phong by the SPEC's formulas; `from = "gltf"` takes the file's camera; formats that do
//! not fit a key are errors; MTL keys and scene materials that are not used are warnings.

use std::path::Path;

use glam::{DMat4, DVec3};
use wavefront::World;
use wavefront::mesh::{ObjMesh, ObjRead};
use wavefront::scene::{Falloff, LightKind};
use wavefront_kit::meshes::{PlyEncoding, PolyMesh};
use wavefront_kit::oracle::compare_rgb8;
use wavefront_kit::testkit::{Scratch, oracle_png_bytes, render_png_bytes};

/// The corners of every triangle, in order.
fn corners(m: &ObjMesh) -> Vec<[[f64; 3]; 3]> {
    m.indices
        .iter()
        .map(|t| t.map(|i| m.positions[i as usize]))
        .collect()
}

const WHAT: [ObjRead; 2] = [
    ObjRead {
        normals: false,
        materials: false,
    },
    ObjRead {
        normals: true,
        materials: false,
    },
];

#[test]
fn every_ply_encoding_reads_the_triangles_of_the_obj() {
    let dir = Scratch::new("ply-read");
    let mesh = PolyMesh::bumpy(6);
    let obj = dir.write("m.obj", &mesh.obj());
    for enc in [
        PlyEncoding::Ascii,
        PlyEncoding::LittleEndian,
        PlyEncoding::BigEndian,
    ] {
        let ply = dir.join("m.ply");
        std::fs::write(&ply, mesh.ply(enc)).unwrap();
        for what in WHAT {
            let a = ObjMesh::read_with(&obj, what).unwrap();
            let b = ObjMesh::read_with(&ply, what).unwrap();
            assert_eq!(a.len(), mesh.triangles().len());
            assert_eq!(corners(&a), corners(&b), "{enc:?}");
            if what.normals {
                let n = |m: &ObjMesh| -> Vec<[f64; 3]> {
                    m.indices
                        .iter()
                        .flat_map(|t| t.map(|i| m.normals[i as usize]))
                        .collect()
                };
                assert_eq!(n(&a), n(&b), "{enc:?} normals");
            }
        }
    }
}

#[test]
fn every_gltf_form_reads_the_triangles_of_the_obj() {
    let dir = Scratch::new("gltf-read");
    let mesh = PolyMesh::bumpy(5);
    let obj = ObjMesh::read(&dir.write("m.obj", &mesh.obj())).unwrap();
    let embedded = dir.write("e.gltf", &mesh.gltf_embedded(None));
    let external = mesh.gltf_files(dir.path(), "x", None);
    let glb = dir.join("b.glb");
    std::fs::write(&glb, mesh.glb(None)).unwrap();
    for path in [embedded, external, glb] {
        let m = ObjMesh::read(&path).unwrap();
        assert_eq!(corners(&m), corners(&obj), "{}", path.display());
    }
}

/// A column-major glTF matrix: a rotation by atan(4/3) about (1, 2, 2)/3, a non-uniform scale and
/// a translation.
fn transform() -> [f64; 16] {
    // cos θ = 0.6, sin θ = 0.8: the half-angle's cosine is √0.8, its sine √0.2.
    let axis = DVec3::new(1.0, 2.0, 2.0) / 3.0 * 0.2f64.sqrt();
    let r = DMat4::from_quat(glam::DQuat::from_xyzw(
        axis.x,
        axis.y,
        axis.z,
        0.8f64.sqrt(),
    ));
    let m = DMat4::from_translation(DVec3::new(0.25, -1.5, 0.75))
        * r
        * DMat4::from_scale(DVec3::new(1.5, 2.0, 1.25));
    // As the file holds it: f32 values.
    m.to_cols_array().map(|x| f64::from(x as f32))
}

fn scene_text(mesh: &str, material: &str) -> String {
    format!(
        "[image]\nwidth = 160\nheight = 120\n\n[camera]\neye = [3.5, 2.5, 4.0]\n\
         look_at = [0.25, -1.2, 0.75]\nup = [0.0, 1.0, 0.0]\nfov_y = 45.0\n\n\
         [render]\nshadows = true\nambient = [1.0, 1.0, 1.0]\n\n\
         [[light]]\nposition = [4.0, 6.0, 3.0]\nintensity = [0.8, 0.8, 0.8]\n\n\
         [material.m]\nka = [0.05, 0.05, 0.05]\nkd = [0.7, 0.5, 0.3]\nks = [0.4, 0.4, 0.4]\n\
         p = 20.0\n\n[[mesh]]\npath = \"{mesh}\"\nmaterial = \"{material}\"\n"
    )
}

#[test]
fn a_gltf_node_transform_renders_within_the_oracles_tolerance_of_the_obj() {
    let dir = Scratch::new("gltf-transform");
    let mesh = PolyMesh::bumpy(12);
    let m = DMat4::from_cols_array(&transform());
    mesh.gltf_files(dir.path(), "t", Some(transform()));
    // The OBJ of the same triangles in world coordinates, transformed here in f64.
    let mut text = String::new();
    for p in &mesh.positions {
        let w = m.transform_point3(DVec3::from_array(p.map(f64::from)));
        text.push_str(&format!("v {:?} {:?} {:?}\n", w.x, w.y, w.z));
    }
    for t in mesh.triangles() {
        text.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    dir.write("t.obj", &text);
    // The glTF reader's positions: the transform's f64 result, rounded once to f32.
    let g = ObjMesh::read(&dir.join("t.gltf")).unwrap();
    let o = ObjMesh::read(&dir.join("t.obj")).unwrap();
    for (a, b) in corners(&g).iter().zip(corners(&o)) {
        for (p, q) in a.iter().zip(b) {
            for (x, y) in p.iter().zip(q) {
                assert_eq!(*x, f64::from(y as f32), "{p:?} vs {q:?}");
            }
        }
    }
    let gltf =
        wavefront::scene::file::parse(&scene_text("t.gltf", "m"), &dir.join("g.toml")).unwrap();
    let obj =
        wavefront::scene::file::parse(&scene_text("t.obj", "m"), &dir.join("o.toml")).unwrap();
    let d = compare_rgb8(&render_png_bytes(&gltf), &oracle_png_bytes(&obj));
    println!("glTF render vs the OBJ's oracle: {d}");
    // tests/oracle.rs's tolerance: 99.9% of pixels within 1/255, 99.99% within 3/255.
    assert!(
        d.over_1 * 1000 <= d.pixels && d.over_3 * 10_000 <= d.pixels,
        "{d}"
    );
    // And the image is not empty: the mesh covers a good share of it.
    let rgb = render_png_bytes(&gltf);
    let lit = rgb.chunks_exact(3).filter(|p| p != &[0, 0, 0]).count();
    assert!(lit > 160 * 120 / 10, "{lit} lit pixels");
}

#[test]
fn gltf_materials_map_to_blinn_phong_and_textures_are_a_warning() {
    let dir = Scratch::new("gltf-material");
    let mesh = PolyMesh::bumpy(3);
    // baseColorFactor (0.8, 0.6, 0.4), metallic 0, roughness 0.5 (PolyMesh's material), and a
    // second, metallic one with a texture.
    let text = mesh.gltf_embedded(None).replace(
        r#""materials": ["#,
        r#""materials": [{"name": "gold", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.75, 0.25, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.25, "baseColorTexture": {"index": 0}}}, "#,
    );
    // The primitive uses material 1 ("paint") now that "gold" is material 0.
    let text = text
        .replace(r#""material": 0"#, r#""material": 1"#)
        .replace(
            r#""buffers""#,
            r#""textures": [{"source": 0}], "images": [{"uri": "gold.png"}], "buffers""#,
        );
    dir.write("m.gltf", &text);
    let scene =
        wavefront::scene::file::parse(&scene_text("m.gltf", "gltf"), &dir.join("s.toml")).unwrap();
    let by_name = |n: &str| {
        scene
            .materials
            .iter()
            .find(|m| m.name.ends_with(n))
            .unwrap_or_else(|| panic!("no material {n}"))
            .clone()
    };
    // Non-metallic: kd = base, ks = 0.04, p = 2 / 0.5⁴ − 2 = 30, α = 0.
    let paint = by_name(":paint");
    assert_eq!(paint.kd, glam::Vec3::new(0.8, 0.6, 0.4));
    assert_eq!(paint.ks, glam::Vec3::splat(0.04));
    assert_eq!(paint.p, 30.0);
    assert_eq!(paint.alpha, 0.0);
    assert_eq!(paint.ka, glam::Vec3::ZERO);
    // Metallic: kd = 0, ks = base, p = 2 / 0.25⁴ − 2 = 510, α = 1 · (1 − 0.25).
    let gold = by_name(":gold");
    assert_eq!(gold.kd, glam::Vec3::ZERO);
    assert_eq!(gold.ks, glam::Vec3::new(1.0, 0.75, 0.25));
    assert_eq!(gold.p, 510.0);
    assert_eq!(gold.alpha, 0.75);
    // Only "paint" is used: no reflect stage.
    assert!(!scene.needs_reflections());
    let (_, setup) = World::load_cached(&scene, None).unwrap();
    let textures: Vec<&String> = setup
        .warnings
        .iter()
        .filter(|w| w.contains("textures are ignored"))
        .collect();
    assert_eq!(textures.len(), 1, "{:?}", setup.warnings);
    assert!(textures[0].contains("baseColorTexture of material \"gold\""));
    // The scene's own material `m` is unused beside material = "gltf": a warning.
    assert!(
        setup
            .warnings
            .iter()
            .any(|w| w.contains("material `m` is not used")),
        "{:?}",
        setup.warnings
    );
}

/// `gltf` (one scene of node 0, the mesh) with a second scene node: `tail` is that node's JSON
/// object, then the `]` closing the node list and any top-level keys to add after it.
fn with_node(gltf: String, tail: &str) -> String {
    gltf.replace(
        r#""scenes": [{"nodes": [0]}]"#,
        r#""scenes": [{"nodes": [0, 2]}]"#,
    )
    .replace(r#"{"mesh": 0}]"#, &format!(r#"{{"mesh": 0}}, {tail}"#))
}

#[test]
fn the_camera_can_come_from_the_gltf_file() {
    let dir = Scratch::new("gltf-camera");
    let mesh = PolyMesh::bumpy(3);
    // A camera node at (1, 2, 10) turned 90° about +y (its −z axis looks along −x), yfov 0.5 rad.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let text = with_node(
        mesh.gltf_embedded(None),
        &format!(
            r#"{{"camera": 0, "translation": [1.0, 2.0, 10.0], "rotation": [0.0, {s}, 0.0, {s}]}}], "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.5, "znear": 0.1}}}}]"#
        ),
    );
    dir.write("c.gltf", &text);
    let toml = scene_text("c.gltf", "m").replace(
        "eye = [3.5, 2.5, 4.0]\nlook_at = [0.25, -1.2, 0.75]\nup = [0.0, 1.0, 0.0]\nfov_y = 45.0\n",
        "from = \"gltf\"\n",
    );
    let scene = wavefront::scene::file::parse(&toml, &dir.join("s.toml")).unwrap();
    let c = &scene.camera;
    assert!(
        (c.eye - DVec3::new(1.0, 2.0, 10.0)).length() < 1e-6,
        "{:?}",
        c.eye
    );
    // w points back from the view direction (−x): +x.
    assert!((c.w - glam::Vec3::X).length() < 1e-6, "{:?}", c.w);
    assert!((c.v - glam::Vec3::Y).length() < 1e-6, "{:?}", c.v);
    // t = tan(yfov / 2) = tan(0.25) at distance 1.
    assert!(
        (f64::from(c.t) - 0.255_341_921_221_036_3).abs() < 1e-6,
        "{}",
        c.t
    );
    // Any other camera key beside it is an error naming it.
    let toml2 = toml.replace("from = \"gltf\"\n", "from = \"gltf\"\nfov_y = 30.0\n");
    let e = wavefront::scene::file::parse(&toml2, &dir.join("s.toml")).unwrap_err();
    assert!(e.to_string().contains("camera.fov_y"), "{e}");
}

#[test]
fn formats_that_do_not_fit_a_key_are_errors_naming_the_file() {
    let dir = Scratch::new("format-keys");
    let mesh = PolyMesh::bumpy(2);
    std::fs::write(dir.join("m.ply"), mesh.ply(PlyEncoding::Ascii)).unwrap();
    dir.write("m.obj", &mesh.obj());
    dir.write("m.stl", "solid x\n");
    let cases = [
        ("m.ply", "mtl", "m.ply is a PLY file"),
        ("m.ply", "gltf", "m.ply is a PLY file"),
        ("m.obj", "gltf", "m.obj is an OBJ file"),
        ("m.stl", "m", "unknown mesh format .stl"),
    ];
    for (mesh, material, expect) in cases {
        let e = wavefront::scene::file::parse(&scene_text(mesh, material), &dir.join("s.toml"))
            .unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains(expect), "{mesh} {material}: {msg}");
        assert!(msg.contains("s.toml:"), "{msg}");
        assert!(!msg.contains('\n'), "{msg}");
    }
}

#[test]
fn unused_mtl_keys_are_one_warning_each_with_their_line() {
    let dir = Scratch::new("mtl-warnings");
    dir.write(
        "m.mtl",
        "newmtl a\nKd 0.5 0.5 0.5\nmap_Kd a.png\nd 0.5\nNi 1.5\nKe 1 1 1\nillum 2\n\
         newmtl b\nmap_Kd b.png\nd 1\nKs 0.2\n",
    );
    dir.write(
        "m.obj",
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\nusemtl b\nf 1 3 2\n",
    );
    let scene =
        wavefront::scene::file::parse(&scene_text("m.obj", "mtl"), &dir.join("s.toml")).unwrap();
    let (_, setup) = World::load_cached(&scene, None).unwrap();
    let mtl = Path::new(&dir.join("m.mtl")).display().to_string();
    let keys: Vec<&String> = setup
        .warnings
        .iter()
        .filter(|w| w.contains("MTL key"))
        .collect();
    let expected = [("map_Kd", 3), ("d", 4), ("Ni", 5), ("Ke", 6)];
    assert_eq!(keys.len(), expected.len(), "{keys:?}");
    for ((key, line), w) in expected.iter().zip(&keys) {
        assert!(
            w.starts_with(&format!("{mtl}:{line}: MTL key `{key}` is not used")),
            "{w}"
        );
    }
    // Used keys (Kd, Ks, illum, newmtl) are not warned about.
    assert!(
        !setup
            .warnings
            .iter()
            .any(|w| w.contains("`Kd`") || w.contains("`illum`"))
    );
}

#[test]
fn gltf_lights_become_spec_14_lights_with_inverse_square_falloff() {
    let dir = Scratch::new("gltf-lights");
    let mesh = PolyMesh::bumpy(3);
    let with_light = |kind: &str| {
        with_node(
            mesh.gltf_embedded(None),
            &format!(
                r#"{{"translation": [1.5, 3.0, -2.0], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}],
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{kind}]}}}}"#
            ),
        )
    };
    let toml =
        scene_text("p.gltf", "m").replace("[render]\n", "[render]\nlights_from = \"gltf\"\n");
    let parse = |kind: &str| {
        dir.write("p.gltf", &with_light(kind));
        wavefront::scene::file::parse(&toml, &dir.join("s.toml"))
    };
    let at = DVec3::new(1.5, 3.0, -2.0);
    // The scene's own light first, then the file's; a light shines along its node's -Z.
    let scene = parse(r#"{"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 2.0}"#).unwrap();
    assert_eq!(scene.lights.len(), 2);
    assert_eq!(scene.lights[1].kind, LightKind::Point { position: at });
    assert_eq!(scene.lights[1].intensity, glam::Vec3::new(2.0, 1.0, 0.5));
    assert_eq!(scene.lights[1].falloff, Falloff::InverseSquare);
    let spot =
        parse(r#"{"type": "spot", "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.5}}"#)
            .unwrap();
    let LightKind::Spot {
        position,
        direction,
        cone,
        penumbra,
    } = spot.lights[1].kind
    else {
        panic!("not a spot: {:?}", spot.lights[1]);
    };
    assert_eq!((position, direction), (at, DVec3::NEG_Z));
    // Full angle 2 · outer; full intensity inside 2 · inner = cone − penumbra.
    assert!((cone - 2.0 * 0.5f64.to_degrees()).abs() < 1e-9, "{cone}");
    assert!(
        (cone - penumbra - 2.0 * 0.25f64.to_degrees()).abs() < 1e-9,
        "{penumbra}"
    );
    assert_eq!(spot.lights[1].falloff, Falloff::InverseSquare);
    let sun = parse(r#"{"type": "directional", "intensity": 3.0}"#).unwrap();
    assert_eq!(
        sun.lights[1].kind,
        LightKind::Directional {
            direction: DVec3::NEG_Z
        }
    );
    assert_eq!(sun.lights[1].falloff, Falloff::None);
    assert_eq!(sun.lights[1].intensity, glam::Vec3::splat(3.0));
    for (kind, problem) in [
        (
            r#"{"type": "spot", "spot": {"innerConeAngle": 0.5, "outerConeAngle": 0.5}}"#,
            "spot cone angles",
        ),
        (
            r#"{"type": "spot", "spot": {"outerConeAngle": 1.5707963267948966}}"#,
            "spot cone angles",
        ),
        (
            r#"{"type": "point", "intensity": -1.0}"#,
            "must be finite and ≥ 0",
        ),
    ] {
        let msg = parse(kind).unwrap_err().to_string();
        assert!(
            msg.contains("render.lights_from") && msg.contains(problem),
            "{kind}: {msg}"
        );
    }
}
