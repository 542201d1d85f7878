//! Images are byte-identical whatever the thread count, the wave size, or the run.

use wavefront::RenderOptions;
use wavefront::Scene;
use wavefront::scene::builtin::spheres;
use wavefront_kit::testkit::*;

/// Scene A with 4 samples per pixel and 3 reflections: jitter, several depths, long queues.
fn spheres_4spp_depth3() -> Scene {
    let mut s = spheres();
    s.image.samples = 4;
    s.render.max_depth = 3;
    s
}

fn first_difference(a: &[u8], b: &[u8]) -> Option<usize> {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).position(|(x, y)| x != y).map(|i| i / 3)
}

fn assert_same_on_1_2_and_4_threads(scene: &Scene) {
    let one = in_pool(1, || render_png_bytes(scene));
    for threads in [2, 4] {
        let many = in_pool(threads, || render_png_bytes(scene));
        assert!(
            one == many,
            "{} on {threads} threads differs from 1 thread, first at pixel {:?}",
            scene.name,
            first_difference(&one, &many)
        );
    }
}

#[test]
fn scene_a_is_identical_on_1_2_and_4_threads() {
    assert_same_on_1_2_and_4_threads(&spheres());
}

#[test]
fn scene_a_at_4_spp_depth_3_is_identical_on_1_2_and_4_threads() {
    assert_same_on_1_2_and_4_threads(&spheres_4spp_depth3());
}

#[test]
fn a_small_wave_size_gives_the_same_image() {
    for scene in [spheres(), spheres_4spp_depth3()] {
        let default = render_png_bytes(&scene);
        let options = RenderOptions {
            wave_samples: 1000,
            ..RenderOptions::default()
        };
        let small = render_png_bytes_with(&scene, options);
        assert!(
            default == small,
            "{} with 1000-sample waves differs, first at pixel {:?}",
            scene.name,
            first_difference(&default, &small)
        );
    }
}

#[test]
fn rendering_twice_gives_the_same_image() {
    let scene = spheres_4spp_depth3();
    let a = render_png_bytes(&scene);
    let b = render_png_bytes(&scene);
    assert!(
        a == b,
        "second render differs, first at pixel {:?}",
        first_difference(&a, &b)
    );
}

#[test]
fn a_pixel_range_renders_exactly_the_full_images_pixels_there() {
    let scene = spheres_4spp_depth3();
    let full = render_png_bytes(&scene);
    // A range that starts and ends inside waves of 1000 samples (250 pixels).
    let range = 100_123..131_077;
    let options = RenderOptions {
        wave_samples: 1000,
        pixel_range: Some(range.clone()),
        ..RenderOptions::default()
    };
    let part = render_png_bytes_with(&scene, options);
    let bytes = range.start as usize * 3..range.end as usize * 3;
    assert!(
        full[bytes.clone()] == part[bytes.clone()],
        "pixels inside the range differ"
    );
    assert!(
        part[..bytes.start]
            .iter()
            .chain(&part[bytes.end..])
            .all(|&b| b == 0),
        "pixels outside the range were rendered"
    );
}
