//! Each scene's pipeline holds exactly the stages it needs (SPEC §7), and the shipped scene file
//! of scene A is the built-in scene.

use wavefront::Pipeline;
use wavefront::Scene;
use wavefront::Stage;
use wavefront::scene::builtin::{sibenik, spheres};
use wavefront::scene::{RenderMode, file};
use wavefront_kit::testkit::*;

/// The stages of `pipeline` at each depth.
fn stages(pipeline: &Pipeline) -> Vec<Vec<Stage>> {
    pipeline.depths.iter().map(|d| d.stages.clone()).collect()
}

fn depths(pipeline: &Pipeline) -> Vec<u32> {
    pipeline.depths.iter().map(|d| d.depth).collect()
}

fn spheres_without_mirrors() -> Scene {
    let mut s = spheres();
    for m in &mut s.materials {
        m.alpha = 0.0;
    }
    s
}

#[test]
fn scene_a_reflects_at_depths_0_and_1_and_shadows_at_every_depth() {
    let p = Pipeline::for_scene(&spheres());
    assert_eq!(depths(&p), vec![0, 1, 2], "{p}");
    use Stage::*;
    assert_eq!(
        stages(&p),
        vec![
            vec![Generate, Intersect, Shade, Shadow, Reflect],
            vec![Intersect, Shade, Shadow, Reflect],
            vec![Intersect, Shade, Shadow],
        ],
        "{p}"
    );
    assert!(!p.mask);
    assert!(p.shade.specular, "the green sphere has ks > 0");
}

#[test]
fn scene_a_without_mirrors_has_no_reflect_stage_and_one_depth() {
    let p = Pipeline::for_scene(&spheres_without_mirrors());
    assert!(!p.runs(Stage::Reflect), "{p}");
    assert_eq!(depths(&p), vec![0], "{p}");
    assert!(p.runs(Stage::Shadow), "{p}");
}

#[test]
fn max_depth_zero_has_no_reflect_stage() {
    let mut s = spheres();
    s.render.max_depth = 0;
    let p = Pipeline::for_scene(&s);
    assert!(!p.runs(Stage::Reflect), "{p}");
    assert_eq!(depths(&p), vec![0], "{p}");
}

#[test]
fn shadows_off_has_no_shadow_stage() {
    let mut s = spheres();
    s.render.shadows = false;
    let p = Pipeline::for_scene(&s);
    assert!(!p.runs(Stage::Shadow), "{p}");
    assert!(!p.shade.shadows);
    assert!(p.runs(Stage::Reflect), "{p}");
}

#[test]
fn no_lights_has_no_shadow_stage() {
    let mut s = spheres();
    s.lights.clear();
    let p = Pipeline::for_scene(&s);
    assert!(!p.runs(Stage::Shadow), "{p}");
    assert!(!p.shade.specular, "no light, nothing to evaluate");
}

#[test]
fn sibenik_has_no_reflect_stage_and_one_depth() {
    let p = Pipeline::for_scene(&sibenik(false));
    assert!(!p.runs(Stage::Reflect), "{p}");
    assert!(!p.runs(Stage::Shadow), "{p}");
    assert_eq!(depths(&p), vec![0], "{p}");
    assert!(!p.shade.specular, "ks = 0");
    assert!(p.geometry.contains("kD tree"), "{}", p.geometry);
}

#[test]
fn sibenik_shadows_has_a_shadow_stage() {
    let p = Pipeline::for_scene(&sibenik(true));
    use Stage::*;
    assert_eq!(
        stages(&p),
        vec![vec![Generate, Intersect, Shade, Shadow]],
        "{p}"
    );
}

#[test]
fn mask_mode_has_no_shadow_or_reflect_stage() {
    let mut s = spheres();
    s.render.mode = RenderMode::HitMask;
    let p = Pipeline::for_scene(&s);
    assert!(p.mask);
    assert!(!p.runs(Stage::Shadow), "{p}");
    assert!(!p.runs(Stage::Reflect), "{p}");
    assert_eq!(depths(&p), vec![0], "{p}");
}

#[test]
fn no_specular_material_turns_specular_off() {
    let mut s = spheres();
    for m in &mut s.materials {
        m.ks = glam::Vec3::ZERO;
    }
    let p = Pipeline::for_scene(&s);
    assert!(!p.shade.specular, "{p}");
}

#[test]
fn spheres_need_no_kd_tree() {
    let p = Pipeline::for_scene(&spheres());
    assert!(p.geometry.contains("no kD tree"), "{}", p.geometry);
    assert!(
        !p.to_string().to_lowercase().contains("kdtree"),
        "no kdtree stage expected:\n{p}"
    );
}

fn spheres_file() -> Scene {
    let path = wavefront_kit::testkit::project_root().join("scenes/spheres.toml");
    file::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn spheres_toml_is_the_built_in_scene_a() {
    let mut from_file = spheres_file();
    let builtin = spheres();
    assert_ne!(from_file.name, "", "the file's scene has a name");
    from_file.name = builtin.name.clone();
    assert_eq!(from_file, builtin);
}

#[test]
fn spheres_toml_renders_byte_identical_to_the_built_in() {
    let a = render_png_bytes(&spheres_file());
    let b = render_png_bytes(&spheres());
    assert!(a == b, "scenes/spheres.toml renders differently");
}

/// The Markdown between `<!-- registry:begin -->` and `<!-- registry:end -->` in `text`, with a
/// line prefix (`//! ` in Rust docs) removed.
fn documented_table(text: &str, prefix: &str) -> String {
    let body: Vec<&str> = text
        .lines()
        .map(|l| l.strip_prefix(prefix).unwrap_or(l))
        .skip_while(|l| !l.contains("registry:begin"))
        .skip(1)
        .take_while(|l| !l.contains("registry:end"))
        .collect();
    body.join("\n") + "\n"
}

#[test]
fn the_column_tables_in_the_docs_are_the_registry() {
    let registry = wavefront::schedule::stage::columns_table();
    let root = wavefront_kit::testkit::project_root();
    for (file, prefix) in [("README.md", ""), ("stages/mod.rs", "//! ")] {
        let text = std::fs::read_to_string(root.join(file)).unwrap();
        assert_eq!(
            documented_table(&text, prefix),
            registry,
            "{file}'s stage/column table differs from the stage registry; paste this:\n{registry}"
        );
    }
}
