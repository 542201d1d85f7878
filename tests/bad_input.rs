//! Bad input never panics: random and mutated scene files give a scene or an error naming the
//! file and line; so do mutated OBJ and tree files (the CLI side is in `tools/cli/tests/cli.rs`).

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use wavefront::scene::file::parse;
use wavefront_kit::testkit::{SCENE_TOKENS, mutate_from};

const SPHERES: &str = include_str!("../scenes/spheres.toml");

/// [`mutate_from`] with the scene-file tokens.
fn mutate(text: &str, kind: u8, at: usize, len: usize, token: usize) -> String {
    mutate_from(SCENE_TOKENS, text, kind, at, len, token)
}

/// An error message must be `file:line: key: message` with a line inside the text.
fn assert_names_file_and_line(message: &str, text: &str) {
    let rest = message
        .strip_prefix("fuzz.toml:")
        .unwrap_or_else(|| panic!("error does not name the file: {message}"));
    let line: usize = rest
        .split(':')
        .next()
        .and_then(|l| l.parse().ok())
        .unwrap_or_else(|| panic!("error does not name the line: {message}"));
    let lines = text.lines().count().max(1);
    assert!(
        line >= 1 && line <= lines + 1,
        "line {line} outside the file ({lines} lines): {message}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, .. ProptestConfig::default() })]

    #[test]
    fn mutated_scene_files_parse_or_name_file_and_line(
        muts in prop::collection::vec((any::<u8>(), any::<usize>(), any::<usize>(), any::<usize>()), 1..4)
    ) {
        let mut text = SPHERES.to_owned();
        for (kind, at, len, token) in muts {
            text = mutate(&text, kind, at, len, token);
        }
        match parse(&text, Path::new("fuzz.toml")) {
            Ok(scene) => {
                // Whatever parses is valid: finite, positive radii, materials in range.
                prop_assert!(scene.spheres.iter().all(|s| s.radius > 0.0 && s.center.is_finite()));
                prop_assert!(scene.spheres.iter().all(|s| (s.material as usize) < scene.materials.len()));
                prop_assert!(scene.image.samples >= 1 && scene.image.width >= 1);
            }
            Err(e) => assert_names_file_and_line(&e.to_string(), &text),
        }
    }

    #[test]
    fn random_bytes_never_panic_the_scene_parser(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        if let Err(e) = parse(&text, Path::new("fuzz.toml")) {
            assert_names_file_and_line(&e.to_string(), &text);
        }
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("wavefront-bad-input-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A closed cube as OBJ text: 8 `v` lines, 12 `f` lines.
const CUBE_OBJ: &str = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
f 1 2 3\nf 1 3 4\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 3 7\nf 4 7 8\nf 1 4 8\nf 1 8 5\nf 2 3 7\nf 2 7 6\n";

/// Tokens for mutating OBJ and tree files.
const FILE_TOKENS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e39",
    "0",
    "-1",
    "99",
    "4294967296",
    "x",
    "",
    " ",
    "\n",
    "f 1 2",
    "f 1 2 3 4 5",
    "v 1 2",
    "f 0 1 2",
    "f -9 1 2",
    "inner{",
    "leaf{",
    "}",
    ";",
    "3",
    "-0.0",
    "1e-45",
    "#",
];

fn mutate_with(text: &str, kind: u8, at: usize, len: usize, token: usize) -> String {
    mutate_from(FILE_TOKENS, text, kind, at, len, token)
}

/// The error names the file and, where the message has a line, a line inside the file.
fn assert_names_file(message: &str, path: &Path, text: &str) {
    let p = path.display().to_string();
    assert!(
        message.contains(&p),
        "error does not name the file: {message}"
    );
    if let Some(rest) = message.strip_prefix(&format!("{p}:"))
        && let Some(line) = rest.split(':').next().and_then(|l| l.parse::<usize>().ok())
    {
        assert!(
            line >= 1 && line <= text.lines().count().max(1) + 1,
            "line {line} outside the file: {message}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, .. ProptestConfig::default() })]

    #[test]
    fn mutated_obj_files_load_or_name_file_and_line(
        muts in prop::collection::vec((any::<u8>(), any::<usize>(), any::<usize>(), any::<usize>()), 1..4)
    ) {
        let mut text = CUBE_OBJ.to_owned();
        for (kind, at, len, token) in muts {
            text = mutate_with(&text, kind, at, len, token);
        }
        let dir = temp_dir("obj");
        let path = dir.join("m.obj");
        std::fs::write(&path, &text).unwrap();
        match wavefront::mesh::TriangleMesh::load_obj(&path) {
            Ok(mesh) => {
                prop_assert!(mesh.vertices.iter().flatten().all(|c| c.is_finite()));
                prop_assert!(mesh.indices.iter().flatten().all(|&i| (i as usize) < mesh.vertices.len()));
            }
            Err(e) => assert_names_file(&e.to_string(), &path, &text),
        }
        // The fast reader takes a file only if tobj reads it to the same mesh; otherwise it
        // hands it to tobj, whose errors name file and line.
        let slow = wavefront::mesh::ObjMesh::read(&path);
        if let Some((positions, indices)) = wavefront::mesh::obj_fast::parse(text.as_bytes()) {
            let slow = slow.as_ref().expect("the fast path took a file tobj rejects");
            prop_assert_eq!(&positions, &slow.positions);
            prop_assert_eq!(&indices, &slow.indices);
        }
        match wavefront::mesh::obj_fast::read_bytes(&path, text.as_bytes()) {
            Ok(fast) => prop_assert_eq!(Some(&fast), slow.as_ref().ok()),
            Err(e) => assert_names_file(&e.to_string(), &path, &text),
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn mutated_tree_files_load_or_name_file_and_line(
        muts in prop::collection::vec((any::<u8>(), any::<usize>(), any::<usize>(), any::<usize>()), 1..4)
    ) {
        use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree};
        let dir = temp_dir("tree");
        let obj = dir.join("m.obj");
        std::fs::write(&obj, CUBE_OBJ).unwrap();
        let mesh = wavefront::mesh::TriangleMesh::load_obj(&obj).unwrap();
        let mut text = Vec::new();
        KdTree::build(&mesh, BuildMethod::Midpoint).write_text(&mut text).unwrap();
        let mut text = String::from_utf8(text).unwrap();
        for (kind, at, len, token) in muts {
            text = mutate_with(&text, kind, at, len, token);
        }
        let path = dir.join("t.kd");
        match KdTree::read_text(text.as_bytes(), &path, mesh.len()) {
            // Whatever loads can be traced without panicking, and validate() judges it.
            Ok(tree) => {
                let _ = tree.validate(&mesh);
                let tree = KdAccel::new(tree, &mesh);
                let _ = tree.intersect_closest(glam::Vec3::ZERO, glam::Vec3::X, f32::INFINITY);
            }
            Err(e) => assert_names_file(&e.to_string(), &path, &text),
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
