//! EXR streamed in block rows (issue 21, SPEC §13): a streamed render writes the bytes
//! [`wavefront::Film::save`] writes from the whole film, for any thread count and wave size, and
//! holds a few block rows of the image, not the image. Memory is the process's peak resident
//! size (`VmHWM`, reset through `/proc/self/clear_refs`; the file has one test, so nothing else
//! runs beside it).

use std::path::Path;

use wavefront::film::output::{ImageMeta, ImageStream, read_exr};
use wavefront::scene::builtin::spheres;
use wavefront::{RenderOptions, Scene, World, render_into, render_observed};
use wavefront_kit::testkit::{Scratch, in_pool};

/// A field of `/proc/self/status` in bytes (`VmRSS`, `VmHWM`).
fn status_bytes(field: &str) -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let line = status
        .lines()
        .find(|l| l.starts_with(field))
        .unwrap_or_else(|| panic!("no {field}"));
    let kib: u64 = line
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .expect("a number of kB");
    kib * 1024
}

fn stream_render(scene: &Scene, world: &World, options: &RenderOptions, path: &Path) {
    let image = &scene.image;
    let mut stream = ImageStream::create(
        path,
        (image.width, image.height),
        image.gamma,
        &ImageMeta::default(),
    )
    .unwrap();
    render_into(scene, world, options, (), &mut stream);
    stream.finish().unwrap();
}

#[test]
fn an_exr_is_streamed_in_block_rows_with_the_bytes_of_the_whole_film() {
    let dir = Scratch::new("exr-stream");
    // Sizes that are not multiples of the 64-pixel tiles, so the last block row and column are
    // partial.
    let mut scene = spheres();
    scene.image.width = 203;
    scene.image.height = 141;
    scene.image.samples = 2;
    let world = World::load(&scene).unwrap();
    let film = render_observed(&scene, &world, &RenderOptions::default(), ());
    let saved = dir.join("film.exr");
    film.save(&saved, scene.image.gamma).unwrap();
    let saved = std::fs::read(&saved).unwrap();
    for (threads, wave_samples) in [(1, 1 << 16), (2, 1000), (3, 4096), (2, 1)] {
        let path = dir.join(&format!("s{threads}-{wave_samples}.exr"));
        let options = RenderOptions {
            wave_samples,
            ..RenderOptions::default()
        };
        in_pool(threads, || stream_render(&scene, &world, &options, &path));
        let streamed = std::fs::read(&path).unwrap();
        assert!(
            streamed == saved,
            "{threads} thread(s), waves of {wave_samples}: the streamed EXR differs from Film::save's"
        );
    }
    // And the file holds the film's linear pixels (read back by the exr crate).
    let back = read_exr(&dir.join("s1-65536.exr")).unwrap();
    assert_eq!(back.size, (203, 141));
    assert!(back.pixels.iter().zip(&film.pixels).all(|(a, b)| a == b));

    // Memory: a 4096 × 2048 image, one sample, waves of 4096 samples. The whole film alone is
    // 96 MiB (and Film::save's encoded copy as much again); the stream holds a block row (64
    // rows, 3 MiB) twice and the encoder's blocks; the PNG stream a few waves. The peak resident
    // size of each streamed render, after a first render has warmed the allocator and the pools
    // up, is a fraction of the film.
    let mut big = spheres();
    big.image.width = 4096;
    big.image.height = 2048;
    big.image.samples = 1;
    big.render.max_depth = 1;
    let world = World::load(&big).unwrap();
    let options = RenderOptions {
        wave_samples: 4096,
        ..RenderOptions::default()
    };
    let peak_of = |name: &str| {
        let path = dir.join(name);
        // Writing 5 to clear_refs resets the peak resident size to the current one.
        std::fs::write("/proc/self/clear_refs", "5").expect("reset the peak RSS");
        let before = status_bytes("VmRSS:");
        in_pool(2, || stream_render(&big, &world, &options, &path));
        status_bytes("VmHWM:").saturating_sub(before)
    };
    peak_of("warm-up.png");
    let png = peak_of("big.png");
    let exr = peak_of("big.exr");
    let whole = 4096 * 2048 * 12;
    // Regression (CI, session 8): the wave workers ran ahead of a slower sink through an
    // unbounded channel, so both streams peaked at 40-90 MB, growing with the image.
    assert!(
        png < whole / 4 && exr < whole / 4,
        "peak {exr} bytes streaming the EXR, {png} the PNG; the whole film is {whole}"
    );
    let back = read_exr(&dir.join("big.exr")).unwrap();
    assert_eq!(back.size, (4096, 2048));
    assert_eq!(dir.files().len(), 8, "no partial files: {:?}", dir.files());
}
