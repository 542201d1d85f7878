//! Imports go one way (issue 22): each top-level module of the core crate may use only the
//! modules below it in [`LAYERS`], so there are no module cycles. The check reads every
//! `crate::…` path of the sources (`use` lines, grouped `use crate::{a, b::c}` imports and paths
//! written inline), leaving out comments and `#[cfg(test)]` modules (a test may reach anywhere).

use std::path::{Path, PathBuf};

/// The core crate's top-level modules, lowest first: a module uses only modules before it.
const LAYERS: &[&str] = &[
    // Basics: arithmetic, lanes, file access, sampling, the shared error types.
    "arith", "simd", "input", "sampling", "error",
    // Geometry: primitives, triangle tests, the f32 mesh and the render frame's conversion.
    "geometry", // Queues: ray rows, the region and the waves of samples.
    "queue", "region", "wave",
    // Mesh files, the acceleration structures and their cache.
    "mesh", "accel", "cache",
    // Scenes and the world traced: the scene in the render frame, then the world.
    "scene", "frame", "world",
    // The film the stages accumulate into, the stages, image files and the schedule.
    "film", "stages", "output", "schedule",
];

/// The source files of the core crate (`src/` and `stages/`), with their top-level module.
fn sources(root: &Path) -> Vec<(String, PathBuf)> {
    let mut out = vec![];
    let mut stack = vec![root.join("src"), root.join("stages")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("a source folder") {
            let path = entry.expect("a folder entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let rel = path.strip_prefix(root).expect("under the root");
                let mut parts = rel.iter().map(|p| p.to_string_lossy().into_owned());
                let first = parts.next().expect("src or stages");
                let module = if first == "stages" {
                    "stages".to_owned()
                } else {
                    let m = parts.next().expect("a file under src");
                    m.trim_end_matches(".rs").to_owned()
                };
                if module != "lib" {
                    out.push((module, path));
                }
            }
        }
    }
    out.sort();
    out
}

/// `text` without comments, string literals' contents and `#[cfg(test)]` modules.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod ") {
        Some(i) => &text[..i],
        None => text,
    };
    let mut out = String::with_capacity(text.len());
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else {
            out.push(b[i] as char);
            i += 1;
        }
    }
    out
}

/// The top-level modules `code` names through `crate::` (also `$crate::` in macros).
fn used_modules(code: &str) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let mut out = vec![];
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        let before = rest[..i].chars().next_back();
        rest = &rest[i + "crate::".len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let after = rest.trim_start();
        if let Some(group) = after.strip_prefix('{') {
            // `crate::{a::b, c, d::{e, f}}`: the names at depth 0 of the group.
            let mut depth = 0;
            let mut start = true;
            for (k, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => start = true,
                    c if start && (c.is_alphanumeric() || c == '_') => {
                        out.push(ident(&group[k..]));
                        start = false;
                    }
                    _ => {}
                }
            }
        } else {
            let name = ident(after);
            if !name.is_empty() {
                out.push(name);
            }
        }
    }
    out
}

/// Every import of a module at or above its own layer: `file: module uses other`.
fn back_edges(files: &[(String, PathBuf, String)]) -> Vec<String> {
    let layer = |m: &str| LAYERS.iter().position(|l| *l == m);
    let mut out = vec![];
    for (module, path, text) in files {
        let Some(own) = layer(module) else {
            out.push(format!(
                "{}: module `{module}` is not in LAYERS",
                path.display()
            ));
            continue;
        };
        for used in used_modules(&code_of(text)) {
            if used == *module || used == "self" {
                continue;
            }
            match layer(&used) {
                Some(l) if l < own => {}
                // Macros exported at the crate root (`crate::column_set!`).
                None if text.contains(&format!("macro_rules! {used}"))
                    || files
                        .iter()
                        .any(|(_, _, t)| t.contains(&format!("macro_rules! {used}"))) => {}
                Some(_) => out.push(format!(
                    "{}: `{module}` uses `{used}`, which is not below it",
                    path.display()
                )),
                None => out.push(format!(
                    "{}: `{module}` uses `{used}`, which is not in LAYERS",
                    path.display()
                )),
            }
        }
    }
    out.sort();
    out.dedup();
    out
}

#[test]
fn imports_go_one_way() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files: Vec<_> = sources(root)
        .into_iter()
        .map(|(m, p)| {
            let text = std::fs::read_to_string(&p).expect("a source file");
            (m, p, text)
        })
        .collect();
    assert!(files.len() > 50, "found the sources");
    let edges = back_edges(&files);
    assert!(
        edges.is_empty(),
        "imports against the layers:\n{}",
        edges.join("\n")
    );
}

#[test]
fn an_injected_back_edge_is_named() {
    let file = |m: &str, text: &str| {
        (
            m.to_owned(),
            PathBuf::from(format!("src/{m}.rs")),
            text.to_owned(),
        )
    };
    let clean = [
        file(
            "geometry",
            "use crate::simd::Level;\nuse crate::{arith, simd::F32x4};\n",
        ),
        file(
            "world",
            "// crate::schedule in a comment\nfn f() { crate::accel::g(); }\n",
        ),
    ];
    assert!(back_edges(&clean).is_empty(), "{:?}", back_edges(&clean));
    let cases = [
        (
            "geometry",
            "use crate::world::World;\n",
            "`geometry` uses `world`",
        ),
        (
            "queue",
            "use crate::{simd, stages::intersect::X};\n",
            "`queue` uses `stages`",
        ),
        (
            "accel",
            "fn f() -> crate::scene::Scene { todo!() }\n",
            "`accel` uses `scene`",
        ),
        (
            "film",
            "use crate::{\n    queue::X,\n    stages::{Y, Z},\n};\n",
            "`film` uses `stages`",
        ),
        (
            "stages",
            "use crate::schedule::Stage;\n",
            "`stages` uses `schedule`",
        ),
        (
            "simd",
            "use crate::unknown::X;\n",
            "`unknown`, which is not in LAYERS",
        ),
    ];
    for (module, text, expect) in cases {
        let edges = back_edges(&[file(module, text)]);
        assert!(
            edges.len() == 1 && edges[0].contains(expect),
            "{module}: {text:?} gave {edges:?}"
        );
    }
    // Test modules may reach anywhere.
    let tested = file(
        "geometry",
        "fn f() {}\n#[cfg(test)]\nmod tests {\n    use crate::world::World;\n}\n",
    );
    assert!(back_edges(&[tested]).is_empty());
}
