//! The many-spheres benchmark scene from the command line (issue 26): the built-in
//! `many-spheres` and the scene file the kit writes of it render the same bytes, at every SIMD
//! level, and `plan` says the spheres go through a BVH while the stages are scene A's.

use wavefront::scene::builtin::{MANY_SPHERES, many_spheres};
use wavefront_kit::scene_toml::analytic_scene_toml;
use wavefront_kit::testkit::Scratch;

fn run(dir: &Scratch, simd: Option<&str>, args: &[&str]) -> std::process::Output {
    let mut c = dir.command(env!("CARGO_BIN_EXE_wavefront"));
    if let Some(level) = simd {
        c.env("WAVEFRONT_SIMD", level);
    }
    c.args(args)
        .output()
        .expect("cannot run the wavefront binary")
}

fn render(dir: &Scratch, simd: Option<&str>, scene: &str, out: &str) -> Vec<u8> {
    let o = run(dir, simd, &["render", scene, "--size", "64x64", "-o", out]);
    assert!(
        o.status.success(),
        "{scene}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::read(dir.join(out)).unwrap()
}

/// A scene file of 100,000 `[[sphere]]` tables parses (no timing here: `docs/performance.md`
/// has the figures) and renders what the built-in renders, and every SIMD level renders the
/// same image.
#[test]
fn the_built_in_and_its_scene_file_render_the_same_bytes_at_every_simd_level() {
    let dir = Scratch::new("many-spheres");
    let text = analytic_scene_toml(&many_spheres(MANY_SPHERES)).unwrap();
    assert_eq!(text.matches("[[sphere]]").count(), 100_000);
    let file = dir.write("many.toml", &text);
    let built_in = render(&dir, None, "many-spheres", "built-in.png");
    let from_file = render(&dir, None, file.to_str().unwrap(), "file.png");
    assert!(
        built_in == from_file,
        "the scene file renders another image"
    );
    for level in ["portable", "avx2", "avx512"] {
        let png = render(&dir, Some(level), "many-spheres", &format!("{level}.png"));
        assert!(
            png == built_in,
            "WAVEFRONT_SIMD={level} renders another image"
        );
    }
}

#[test]
fn plan_shows_the_bvh_and_scene_a_stages() {
    let dir = Scratch::new("many-spheres-plan");
    let plan = |scene: &str| {
        let o = run(&dir, None, &["plan", scene]);
        assert!(o.status.success());
        String::from_utf8(o.stdout).unwrap()
    };
    let many = plan("many-spheres");
    assert!(
        many.contains(
            "geometry: 100000 spheres in a BVH; 1 planes (brute force); no mesh, no kD tree"
        ),
        "{many}"
    );
    let a = plan("spheres");
    assert!(
        a.contains("geometry: 3 spheres, 1 planes (brute force); no mesh, no kD tree"),
        "{a}"
    );
    let depths = |p: &str| {
        p.lines()
            .filter(|l| l.starts_with("depth "))
            .map(str::to_owned)
            .collect::<Vec<_>>()
    };
    assert_eq!(depths(&many), depths(&a));
    assert_eq!(depths(&a).len(), 3);
}
