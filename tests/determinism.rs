//! Images are byte-identical whatever the thread count, the wave size, or the run.

use wavefront::RenderOptions;
use wavefront::Scene;
use wavefront::queue::region::Region;
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

/// The full render's pixels inside `region` (8-bit RGB rows), to compare with a region render.
fn crop(full: &[u8], width: u32, region: Region) -> Vec<u8> {
    let (w, x0, x1) = (width as usize, region.x0 as usize, region.x1 as usize);
    (region.y0 as usize..region.y1 as usize)
        .flat_map(|j| full[(j * w + x0) * 3..(j * w + x1) * 3].iter().copied())
        .collect()
}

#[test]
fn a_region_renders_exactly_the_full_images_pixels_there() {
    let scene = spheres_4spp_depth3();
    let full = render_png_bytes(&scene);
    // Rectangles whose rows start and end inside waves of 1000 samples (250 pixels), a band of
    // whole rows, and a single pixel.
    for bounds in [
        "100,357,195,256",
        "0,512,170,341",
        "511,512,0,1",
        "3,4,500,512",
    ] {
        let region: Region = bounds.parse().unwrap();
        let options = RenderOptions {
            wave_samples: 1000,
            region: Some(region),
            ..RenderOptions::default()
        };
        let film = render_film_with(&scene, options);
        assert_eq!((film.width, film.height), (region.width(), region.height()));
        let part = film.to_rgb8(scene.image.gamma);
        let expected = crop(&full, scene.image.width, region);
        assert!(
            part == expected,
            "region {bounds} differs from the full render, first at pixel {:?}",
            first_difference(&part, &expected)
        );
    }
}
