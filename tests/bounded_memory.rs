//! Memory bounded by the wave, not by the lights or the image: shadow rays traced in bounded
//! shade → shadow passes, and images encoded row by row as waves finish, give exactly the image
//! of an unsplit render held in memory.

use std::path::Path;

use glam::Vec3;
use wavefront::film::output::{ImageMeta, ImageStream};
use wavefront::queue::ShadowQueue;
use wavefront::scene::Light;
use wavefront::scene::builtin::spheres;
use wavefront::schedule::{Observer, Queues, StageRun};
use wavefront::{RenderOptions, Scene, Stage, Stats, World, render_into, render_observed};
use wavefront_kit::testkit::{Rng, Scratch, in_pool};

/// Scene A lit by `n` seeded random point lights above the floor.
fn scene_a_with_random_lights(n: usize) -> Scene {
    let mut scene = spheres();
    let mut rng = Rng(0x5eed_0040);
    scene.lights = (0..n)
        .map(|_| {
            Light::point(
                Vec3::new(
                    rng.range(-8.0, 8.0),
                    rng.range(-1.0, 8.0),
                    rng.range(-12.0, 2.0),
                )
                .as_dvec3(),
                Vec3::new(
                    rng.range(0.0, 0.05),
                    rng.range(0.0, 0.05),
                    rng.range(0.0, 0.05),
                ),
            )
        })
        .collect();
    scene
}

/// Watches the shade stage: its calls and the largest shadow queue it leaves.
#[derive(Default)]
struct ShadePasses {
    calls: usize,
    largest_shadow_queue: usize,
}

impl Observer for ShadePasses {
    fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
        if run.stage == Stage::Shade {
            self.calls += 1;
            self.largest_shadow_queue = self.largest_shadow_queue.max(q.shadows.len());
        }
    }
}

/// (depth, stage, rays in, rays out) of every entry: the stats without their times.
fn counts(stats: &Stats) -> Vec<(u32, Stage, u64, u64)> {
    stats
        .entries
        .iter()
        .map(|(&(depth, stage), e)| (depth, stage, e.rays_in, e.rays_out))
        .collect()
}

/// Renders with at most `shadow_rows` shadow rays per pass: 8-bit pixels, stats, shade passes.
fn render_with_budget(
    scene: &Scene,
    world: &World,
    shadow_rows: usize,
) -> (Vec<u8>, Stats, ShadePasses) {
    // The whole frame in one wave, so one pass spans all of a depth's hits.
    let options = RenderOptions {
        shadow_rows,
        wave_samples: 1 << 20,
        ..RenderOptions::default()
    };
    let mut stats = Stats::default();
    let mut passes = ShadePasses::default();
    let film = render_observed(scene, world, &options, (&mut stats, &mut passes));
    (film.to_rgb8(scene.image.gamma), stats, passes)
}

#[test]
fn forty_lights_in_tiny_passes_render_the_unsplit_image_on_1_and_2_threads() {
    let scene = scene_a_with_random_lights(40);
    let world = World::load(&scene).unwrap();
    let (whole, whole_stats, whole_passes) =
        in_pool(1, || render_with_budget(&scene, &world, usize::MAX));
    assert_eq!(whole_passes.calls, 3, "one shade call per depth");
    assert!(
        whole_passes.largest_shadow_queue > 1_000_000,
        "40 lights over ~145,000 hits: {}",
        whole_passes.largest_shadow_queue
    );
    // 1,000 rows: blocks of 1,000 hits, one light at a time. 2^18 rows: every hit, a few lights
    // at a time.
    for budget in [1_000, 1 << 18] {
        for threads in [1, 2] {
            let (image, stats, passes) =
                in_pool(threads, || render_with_budget(&scene, &world, budget));
            assert!(
                image == whole,
                "{budget}-row passes on {threads} threads change the image"
            );
            assert_eq!(
                counts(&stats),
                counts(&whole_stats),
                "{budget}-row passes: the stage statistics do not add up to the unsplit ones"
            );
            assert!(passes.calls > 40, "{} shade calls", passes.calls);
            assert!(
                passes.largest_shadow_queue <= budget,
                "a pass left {} shadow rays, over its budget of {budget}",
                passes.largest_shadow_queue
            );
        }
    }
}

#[test]
fn shadows_off_and_the_hit_mask_ignore_the_budget() {
    for (shadows, mask) in [(false, false), (true, true)] {
        let mut scene = scene_a_with_random_lights(7);
        scene.render.shadows = shadows;
        if mask {
            scene.render.mode = wavefront::scene::RenderMode::HitMask;
        }
        let world = World::load(&scene).unwrap();
        let (whole, _, _) = render_with_budget(&scene, &world, usize::MAX);
        let (tiny, _, passes) = render_with_budget(&scene, &world, 1);
        assert!(tiny == whole);
        assert_eq!(passes.largest_shadow_queue, 0);
    }
}

/// Scene A at an odd size and 2 samples per pixel, in waves of 250 pixels: rows of 97 pixels
/// end inside waves, and waves end inside rows.
fn small_scene_and_options() -> (Scene, RenderOptions) {
    let mut scene = spheres();
    scene.image.width = 97;
    scene.image.height = 61;
    scene.image.samples = 2;
    let options = RenderOptions {
        wave_samples: 500,
        ..RenderOptions::default()
    };
    (scene, options)
}

/// Renders into an [`ImageStream`] at `path`.
fn stream_render(scene: &Scene, world: &World, options: &RenderOptions, path: &Path) {
    let image = &scene.image;
    let region = options.region_of(scene);
    let mut stream = ImageStream::create(
        path,
        (region.width(), region.height()),
        image.gamma,
        &ImageMeta::default(),
    )
    .unwrap();
    render_into(scene, world, options, (), &mut stream);
    stream.finish().unwrap();
}

#[test]
fn a_streamed_render_writes_the_bytes_film_save_writes() {
    let dir = Scratch::new("stream");
    let (scene, options) = small_scene_and_options();
    let world = World::load(&scene).unwrap();
    let film = render_observed(&scene, &world, &options, ());
    let rgb = film.to_rgb8(scene.image.gamma);
    for ext in ["png", "ppm"] {
        let saved = dir.join(&format!("film.{ext}"));
        let streamed = dir.join(&format!("stream.{ext}"));
        film.save(&saved, scene.image.gamma).unwrap();
        stream_render(&scene, &world, &options, &streamed);
        let (a, b) = (
            std::fs::read(&saved).unwrap(),
            std::fs::read(&streamed).unwrap(),
        );
        assert!(a == b, "{ext}: the streamed file differs from Film::save's");
        let decoded = image::open(&streamed).unwrap().to_rgb8();
        assert_eq!(decoded.dimensions(), (97, 61));
        assert!(decoded.into_raw() == rgb, "{ext}: decoded pixels differ");
    }
    assert_eq!(
        dir.files(),
        ["film.png", "film.ppm", "stream.png", "stream.ppm"],
        "no partial files left"
    );
}

#[test]
fn a_streamed_region_writes_the_bytes_its_film_saves() {
    let dir = Scratch::new("range");
    let (scene, mut options) = small_scene_and_options();
    let region: wavefront::queue::region::Region = "13,71,5,40".parse().unwrap();
    options.region = Some(region);
    let world = World::load(&scene).unwrap();
    let film = render_observed(&scene, &world, &options, ());
    assert_eq!((film.width, film.height), (58, 35));
    film.save(&dir.join("film.png"), scene.image.gamma).unwrap();
    stream_render(&scene, &world, &options, &dir.join("stream.png"));
    assert!(
        std::fs::read(dir.join("film.png")).unwrap()
            == std::fs::read(dir.join("stream.png")).unwrap()
    );
    let rgb = image::open(dir.join("stream.png"))
        .unwrap()
        .to_rgb8()
        .into_raw();
    assert!(rgb.iter().any(|&b| b != 0), "the region shows the scene");
}

#[test]
fn png_text_chunks_come_before_the_image_data() {
    let dir = Scratch::new("text");
    let path = dir.join("tile.png");
    let meta = ImageMeta {
        text: vec![
            ("wavefront:bounds".into(), "0,3,0,2".into()),
            ("wavefront:image".into(), "3,2".into()),
        ],
    };
    let mut stream = ImageStream::create(&path, (3, 2), 2.2, &meta).unwrap();
    wavefront::film::PixelSink::put(
        &mut stream,
        wavefront::queue::PixelIndex(0),
        &[Vec3::ONE; 6],
    );
    stream.finish().unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf).unwrap();
    assert!(buf.iter().all(|&b| b == 255));
    let text: Vec<(String, String)> = reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .map(|t| (t.keyword.clone(), t.text.clone()))
        .collect();
    assert_eq!(text, meta.text);
}

#[test]
fn bad_metadata_unwritable_paths_and_unfinished_streams_leave_no_file() {
    let dir = Scratch::new("errors");
    let bad = ImageMeta {
        text: vec![(String::new(), "empty keyword".into())],
    };
    let e = ImageStream::create(&dir.join("a.png"), (4, 4), 2.2, &bad).unwrap_err();
    assert!(e.to_string().contains("a.png"), "{e}");
    let e = ImageStream::create(&dir.join("nodir/b.png"), (4, 4), 2.2, &ImageMeta::default())
        .unwrap_err();
    let line = wavefront::error::chain(&e);
    assert!(
        line.starts_with("cannot write ") && line.contains("nodir/b.png"),
        "{line}"
    );
    let e =
        ImageStream::create(&dir.join("c.jpg"), (4, 4), 2.2, &ImageMeta::default()).unwrap_err();
    assert!(e.to_string().contains(".png, .ppm or .exr"), "{e}");
    // Dropped half-way (say, by a failing render): nothing appears.
    let mut stream =
        ImageStream::create(&dir.join("d.png"), (4, 4), 2.2, &ImageMeta::default()).unwrap();
    wavefront::film::PixelSink::put(
        &mut stream,
        wavefront::queue::PixelIndex(0),
        &[Vec3::ONE; 5],
    );
    drop(stream);
    assert!(dir.files().is_empty(), "{:?}", dir.files());
}

/// Every pass's shadow rays stay in slot order, which deterministic accumulation needs.
#[test]
fn every_pass_keeps_its_shadow_rays_in_slot_order() {
    let scene = scene_a_with_random_lights(5);
    let world = World::load(&scene).unwrap();
    struct Sorted(bool);
    impl Observer for Sorted {
        fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
            if run.stage == Stage::Shade {
                let s: &ShadowQueue = q.shadows;
                self.0 &= s.slot().windows(2).all(|w| w[0] <= w[1]);
            }
        }
    }
    let mut sorted = Sorted(true);
    let options = RenderOptions {
        shadow_rows: 4_000,
        ..RenderOptions::default()
    };
    render_observed(&scene, &world, &options, &mut sorted);
    assert!(sorted.0);
}
