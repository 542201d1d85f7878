//! End-to-end images: the wavefront renderer against the independent f64 oracle
//! (`wavefront::oracle`), and both against the assignment's reference figures.

use std::sync::OnceLock;

use wavefront::Scene;
use wavefront::scene::RenderMode;
use wavefront::scene::builtin::spheres;
use wavefront_kit::oracle::{ImageDiff, compare_rgb8};
use wavefront_kit::testkit::*;

/// Scene A with every α = 0: the assignment's "shading with shadows" image.
fn spheres_without_mirrors() -> Scene {
    let mut s = spheres();
    for m in &mut s.materials {
        m.alpha = 0.0;
    }
    s
}

/// Renders `scene` with both renderers and compares them.
fn diff_against_oracle(scene: &Scene) -> ImageDiff {
    compare_rgb8(&render_png_bytes(scene), &oracle_png_bytes(scene))
}

/// At least 99.9% of pixels within 1/255, and at least 99.99% within 3/255.
///
/// Not every pixel within 3/255: a ray that passes within f32 precision of a silhouette can hit in
/// one renderer and miss in the other. Measured cases: with 4 spp, sample 3 of pixel (64, 262)
/// passes 4e-8 inside the red sphere in f64 and misses it in f32 (15 levels); with reflections,
/// pixels (201, 477) and (310, 477) at 1 spp (49 levels), whose mirror rays pass 1.2e-5 inside the
/// green sphere from the exact floor point but 4.3e-6 outside it from the wavefront's offset
/// origin (256 ulps = 3e-5 above the floor; the oracle offsets by 1e-9·|p|).
fn close_enough(d: &ImageDiff) -> bool {
    d.over_1 * 1000 <= d.pixels && d.over_3 * 10_000 <= d.pixels
}

fn assert_close(what: &str, d: &ImageDiff) {
    println!("{what}: {d}");
    assert!(
        close_enough(d),
        "{what}: more than 0.1% of pixels off by > 1/255 or 0.01% off by > 3/255: {d}"
    );
}

/// Scene A at depths 0–3, shadows on and off, `samples` per pixel, against the oracle; every
/// configuration is printed before any failure is reported.
fn scene_a_variants_match_the_oracle(samples: u32) {
    let mut failures = vec![];
    for depth in 0..=3 {
        for shadows in [true, false] {
            let mut s = spheres();
            s.render.max_depth = depth;
            s.render.shadows = shadows;
            s.image.samples = samples;
            let what = format!("scene A, depth {depth}, shadows {shadows}, {samples} spp");
            let d = diff_against_oracle(&s);
            println!("{what}: {d}");
            if !close_enough(&d) {
                failures.push(format!("{what}: {d}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "more than 0.1% of pixels off by > 1/255 or 0.01% off by > 3/255:\n{}",
        failures.join("\n")
    );
}

#[test]
fn scene_a_matches_the_oracle_at_every_depth_with_one_sample() {
    scene_a_variants_match_the_oracle(1);
}

#[test]
fn scene_a_matches_the_oracle_at_every_depth_with_four_samples() {
    scene_a_variants_match_the_oracle(4);
}

#[test]
fn hit_mask_matches_the_oracle() {
    let mut s = spheres();
    s.render.mode = RenderMode::HitMask;
    let d = diff_against_oracle(&s);
    println!("hit mask: {d}");
    // The mask is black or white: any difference is a pixel whose primary ray disagrees.
    assert!(
        d.over_1 * 10_000 <= d.pixels,
        "hit mask differs in more than 0.01% of pixels: {d}"
    );
}

#[test]
fn shading_with_shadows_and_no_mirrors_matches_the_oracle() {
    let s = spheres_without_mirrors();
    let d = compare_rgb8(without_mirrors(), &oracle_png_bytes(&s));
    assert_close("scene A, all α = 0", &d);
}

#[test]
fn sixty_four_samples_without_mirrors_match_the_oracle() {
    let s = antialiased_scene();
    let d = compare_rgb8(antialiased(), &oracle_png_bytes(&s));
    assert_close("scene A, all α = 0, 64 spp", &d);
}

/// Scene A with all α = 0 at 64 samples per pixel, full 512 × 512 (16.7M primary samples).
fn antialiased_scene() -> Scene {
    let mut s = spheres_without_mirrors();
    s.image.samples = 64;
    s
}

/// Wavefront renders shared by the oracle and reference-figure tests of this binary.
fn default_spheres() -> &'static [u8] {
    static IMG: OnceLock<Vec<u8>> = OnceLock::new();
    IMG.get_or_init(|| render_png_bytes(&spheres()))
}

fn without_mirrors() -> &'static [u8] {
    static IMG: OnceLock<Vec<u8>> = OnceLock::new();
    IMG.get_or_init(|| render_png_bytes(&spheres_without_mirrors()))
}

fn antialiased() -> &'static [u8] {
    static IMG: OnceLock<Vec<u8>> = OnceLock::new();
    IMG.get_or_init(|| render_png_bytes(&antialiased_scene()))
}

/// Bounds on the Sibenik renders against the assignment's figures (measured with the oracle:
/// MAE 0.452 / 0.419 levels, 0.127% / 0.114% of pixels off by > 16, without / with shadows).
const SIBENIK_MAE: f64 = 0.6;
const SIBENIK_OVER_16: f64 = 0.002;

/// The full Sibenik render against the oracle (≥ 99.9% of pixels within 1/255) and against the
/// assignment's figure. Measured: 45 / 69 pixels (without / with shadows) off by more than 1/255,
/// 43 of them on the anti-diagonal, whose rays graze the top edge of a wall (see
/// `sibenik_at_low_resolution_matches_the_oracle`), the rest on shadow boundaries and silhouettes.
fn sibenik_matches_the_oracle(shadows: bool) {
    let Some(s) = sibenik_scene(shadows) else {
        return;
    };
    let wavefront = render_png_bytes(&s);
    let d = compare_rgb8(&wavefront, &oracle_png_bytes(&s));
    println!("sibenik, shadows {shadows}: {d}");
    assert!(
        d.over_1 * 1000 <= d.pixels,
        "sibenik (shadows {shadows}): more than 0.1% of pixels off by more than 1/255: {d}"
    );
    let figure = if shadows {
        "pa4_fig2b_sibenik_shadows.png"
    } else {
        "pa4_fig2a_sibenik_noshadows.png"
    };
    check_reference(
        figure,
        "wavefront",
        &wavefront,
        SIBENIK_MAE,
        SIBENIK_OVER_16,
    );
}

#[test]
fn sibenik_without_shadows_matches_the_oracle() {
    sibenik_matches_the_oracle(false);
}

#[test]
fn sibenik_with_shadows_matches_the_oracle() {
    sibenik_matches_the_oracle(true);
}

#[test]
fn sibenik_at_low_resolution_matches_the_oracle() {
    // The same camera window at 48 × 47: cheap enough with any triangle acceleration. Not square on
    // purpose: in a square image the anti-diagonal's rays have d.y = −d.z exactly, and from the eye
    // (0, −10, 0) they graze the top edge of a wall (triangles 66371 and 66382, y = −12.83,
    // z = −2.83) — coin flips between f32 and f64.
    for shadows in [false, true] {
        let Some(mut s) = sibenik_scene(shadows) else {
            return;
        };
        s.image.width = 48;
        s.image.height = 47;
        let d = diff_against_oracle(&s);
        println!("sibenik 48 × 47, shadows {shadows}: {d}");
        assert!(
            d.over_1 * 100 <= d.pixels,
            "sibenik 48 × 47 (shadows {shadows}): more than 1% of pixels off by more than 1/255: {d}"
        );
    }
}

/// Compares `render` with reference figure `file`, printing and bounding its error figures.
fn check_reference(file: &str, who: &str, render: &[u8], max_mae: f64, max_over_16: f64) {
    let Some(dir) = reference_dir() else { return };
    let (w, h, reference) = read_rgb8(&dir.join(file));
    assert_eq!((w, h), (512, 512), "{file} is not 512 × 512");
    let e = reference_error(render, &reference);
    println!(
        "{who} vs {file}: mean absolute error {:.3} levels, {:.3}% of pixels off by > 16",
        e.mae,
        100.0 * e.over_16
    );
    assert!(
        e.mae <= max_mae && e.over_16 <= max_over_16,
        "{who} vs {file}: MAE {:.3} (bound {max_mae}), {:.3}% > 16 (bound {:.3}%)",
        e.mae,
        100.0 * e.over_16,
        100.0 * max_over_16
    );
}

// Bounds a little above the measured figures (MAE in levels, share of pixels off by > 16):
// reflections 0.351 / 0.365% (the oracle 0.351 / 0.366%), shading 0.180 / 0.042%,
// antialiasing 0.206 / 0.082% (the figure's random jitter differs from ours).

#[test]
fn scene_a_matches_the_reflections_figure() {
    check_reference(
        "pa4_fig1_reflections.png",
        "wavefront",
        default_spheres(),
        0.5,
        0.005,
    );
    check_reference(
        "pa4_fig1_reflections.png",
        "oracle",
        &oracle_png_bytes(&spheres()),
        0.5,
        0.005,
    );
}

#[test]
fn scene_a_without_mirrors_matches_the_shading_figure() {
    check_reference(
        "pa1_fig1b_shading_shadows.png",
        "wavefront",
        without_mirrors(),
        0.3,
        0.001,
    );
}

#[test]
fn scene_a_at_sixty_four_samples_matches_the_antialiasing_figure() {
    check_reference(
        "pa1_fig1c_antialiasing.png",
        "wavefront",
        antialiased(),
        0.35,
        0.0015,
    );
}

#[test]
fn oracle_matches_the_sibenik_figures() {
    let (Some(plain), Some(shadowed)) = (sibenik_scene(false), sibenik_scene(true)) else {
        return;
    };
    check_reference(
        "pa4_fig2a_sibenik_noshadows.png",
        "oracle",
        &oracle_png_bytes(&plain),
        SIBENIK_MAE,
        SIBENIK_OVER_16,
    );
    check_reference(
        "pa4_fig2b_sibenik_shadows.png",
        "oracle",
        &oracle_png_bytes(&shadowed),
        SIBENIK_MAE,
        SIBENIK_OVER_16,
    );
}
