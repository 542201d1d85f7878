//! `docs/scene-format.md` against the scene parser: every table's documented keys are exactly the
//! keys the parser accepts there.
//!
//! The parser's own list of keys comes from the parser: a scene with one unknown key injected
//! into a table is rejected with serde's "unknown field `zz`, expected one of `a`, `b`, …", which
//! names every field of that table's struct. The documented keys are the first column of the
//! tables under each heading of the page (`## \`[image]\``, `### \`camera.window\``, …).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use wavefront::scene::file::parse;

/// A valid scene using every table, with `{X}` marking where each table's injected key goes.
const SCENE: &str = r#"{top}
[image]
{image}
width = 8
height = 8

[camera]
{camera}
eye = [0.0, 0.0, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
w = [0.0, 0.0, 1.0]
window = { l = -0.1, r = 0.1, b = -0.1, t = 0.1 {camera.window} }
distance = 0.1

[render]
{render}
max_depth = 1

[[light]]
{light}
position = [-4.0, 4.0, -3.0]

[material.m]
{material.NAME}
kd = [1.0, 1.0, 1.0]

[[plane]]
{plane}
point = [0.0, -2.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "m"

[[sphere]]
{sphere}
center = [0.0, 0.0, -7.0]
radius = 1.0
material = "m"

[[mesh]]
{mesh}
path = "mesh.obj"
material = "m"
"#;

/// An orbit, for the keys of `[camera.orbit]`.
const ORBIT: &str = r#"
[camera.orbit]
{camera.orbit}
look_at = [0.0, 0.0, -7.0]
eye = [0.0, 1.0, 2.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0
frames = 4
"#;

/// A camera path, for the keys of `[[camera.key]]`.
const PATH: &str = r#"
[camera]
[[camera.key]]
{camera.key}
frame = 0
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -1.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0
"#;

const TABLES: [&str; 12] = [
    "",
    "image",
    "camera",
    "camera.window",
    "camera.key",
    "camera.orbit",
    "render",
    "light",
    "material.NAME",
    "plane",
    "sphere",
    "mesh",
];

/// The scene text with `zz = 1` injected into `table` and every other marker removed.
fn injected(table: &str) -> String {
    let template = match table {
        "camera.key" => PATH,
        "camera.orbit" => ORBIT,
        _ => SCENE,
    };
    let mut text = template.to_owned();
    for t in TABLES {
        let marker = if t.is_empty() {
            "{top}".to_owned()
        } else {
            format!("{{{t}}}")
        };
        let with = match (t == table, t) {
            (false, _) => "",
            (true, "camera.window") => ", zz = 1",
            (true, _) => "zz = 1",
        };
        text = text.replace(&marker, with);
    }
    text
}

/// The keys the parser accepts in `table`, from its error for an unknown one.
fn parser_keys(table: &str) -> BTreeSet<String> {
    let err = parse(&injected(table), Path::new("doc.toml"))
        .err()
        .unwrap_or_else(|| panic!("an unknown key in [{table}] must be rejected"))
        .to_string();
    let list = err
        .split("expected one of ")
        .nth(1)
        .or_else(|| err.split("expected ").nth(1))
        .unwrap_or_else(|| panic!("[{table}]: no key list in the parser's error: {err}"));
    // serde writes `a`, `a` or `b`, or `a`, `b`, `c`.
    list.replace(" or ", ",")
        .split(',')
        .map(|k| k.trim().trim_matches('`').to_owned())
        .filter(|k| !k.is_empty())
        .collect()
}

/// The first-column keys of the tables under each heading of the page.
fn documented_keys(page: &str) -> BTreeMap<String, BTreeSet<String>> {
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut section: Option<String> = None;
    for line in page.lines() {
        if let Some(h) = line
            .strip_prefix("## ")
            .or_else(|| line.strip_prefix("### "))
        {
            section = if h == "Top level" {
                Some(String::new())
            } else if h.starts_with('`') {
                Some(
                    h.trim_matches(|c| c == '`' || c == '[' || c == ']')
                        .to_owned(),
                )
            } else {
                None
            };
            continue;
        }
        let (Some(s), Some(row)) = (&section, line.strip_prefix("| `")) else {
            continue;
        };
        let key = row.split('`').next().unwrap_or("").to_owned();
        out.entry(s.clone()).or_default().insert(key);
    }
    out
}

#[test]
fn the_template_scene_is_valid() {
    // No table named "none": every marker removed, nothing injected.
    for text in [
        injected("none"),
        injected("camera.key"),
        injected("camera.orbit"),
    ] {
        let clean = text.replace("zz = 1", "");
        parse(&clean, Path::new("doc.toml")).expect("the template parses");
    }
}

#[test]
fn every_table_documents_exactly_the_keys_the_parser_accepts() {
    let page =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/scene-format.md"))
            .expect("docs/scene-format.md is readable");
    let documented = documented_keys(&page);
    let mut problems = vec![];
    for table in TABLES {
        let parser = parser_keys(table);
        let docs = documented.get(table).cloned().unwrap_or_default();
        let name = if table.is_empty() { "top level" } else { table };
        for k in parser.difference(&docs) {
            problems.push(format!(
                "[{name}] `{k}`: accepted by the parser, not documented"
            ));
        }
        for k in docs.difference(&parser) {
            problems.push(format!("[{name}] `{k}`: documented, unknown to the parser"));
        }
    }
    for section in documented.keys() {
        if !TABLES.contains(&section.as_str()) {
            problems.push(format!(
                "section `{section}` documents keys of no known table"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "docs/scene-format.md and the parser disagree:\n{}",
        problems.join("\n")
    );
}

#[test]
fn the_check_notices_an_undocumented_key() {
    // The same comparison on a page with one row removed must report it.
    let page =
        "## `[[sphere]]`\n| `center` | vec3 | required | c |\n| `radius` | f | required | r |\n";
    let docs = documented_keys(page);
    let missing: Vec<_> = parser_keys("sphere")
        .difference(&docs["sphere"])
        .cloned()
        .collect();
    assert_eq!(missing, ["material"]);
}
