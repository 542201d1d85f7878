//! Look-at cameras and camera paths (SPEC §10) render exactly what the cameras they stand for
//! render.

// Test data and references may use the platform's functions (SPEC §2 binds the renderer).
#![allow(clippy::disallowed_methods)]

use std::path::Path;

use wavefront::Scene;
use wavefront::scene::file::parse;
use wavefront_kit::testkit::*;

/// Scene A as shipped (`scenes/spheres.toml`).
const SPHERES: &str = include_str!("../scenes/spheres.toml");

/// Scene A's explicit camera fields (after `eye`), as written in `scenes/spheres.toml`.
const EXPLICIT: &str = "u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
w = [0.0, 0.0, 1.0]
window = { l = -0.1, r = 0.1, b = -0.1, t = 0.1 }
distance = 0.1";

/// Scene A with its `[camera]` fields after `eye` replaced by `fields`.
fn spheres_with(fields: &str) -> Scene {
    assert!(SPHERES.contains(EXPLICIT), "scenes/spheres.toml changed");
    parse(
        &SPHERES.replace(EXPLICIT, fields),
        Path::new("spheres.toml"),
    )
    .unwrap()
}

/// Scene A with its `[camera]` table (header and fields) replaced by `camera`.
fn spheres_with_camera(camera: &str) -> Scene {
    let text = SPHERES.replace(
        &format!("[camera]\neye = [0.0, 0.0, 0.0]\n{EXPLICIT}"),
        camera,
    );
    assert_ne!(text, SPHERES, "scenes/spheres.toml changed");
    parse(&text, Path::new("spheres.toml")).unwrap()
}

fn differing_pixels(a: &[u8], b: &[u8]) -> (usize, u8) {
    assert_eq!(a.len(), b.len());
    let pixels = a
        .chunks_exact(3)
        .zip(b.chunks_exact(3))
        .filter(|(x, y)| x != y)
        .count();
    let max = a
        .iter()
        .zip(b)
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0);
    (pixels, max)
}

#[test]
fn a_look_at_camera_renders_as_the_explicit_camera_it_stands_for() {
    // Scene A's camera looks down −z from the origin with a 90° vertical field (t/d = 1). In the
    // look-at form's own normalisation (distance 1, window ±tan 45° = ±1) the explicit camera is
    // the same f32 numbers, so the images are the same bytes.
    let look_at = spheres_with("look_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0");
    let explicit = spheres_with(
        "u = [1.0, 0.0, 0.0]\nv = [0.0, 1.0, 0.0]\nw = [0.0, 0.0, 1.0]\n\
         window = { l = -1.0, r = 1.0, b = -1.0, t = 1.0 }\ndistance = 1.0",
    );
    assert_eq!(look_at.camera, explicit.camera);
    let a = render_png_bytes(&look_at);
    assert!(a == render_png_bytes(&explicit), "images differ");
    // Against scene A's own numbers (window ±0.1 at distance 0.1, where 0.1 is not an f32) the
    // rays differ in their last bits: at most one pixel in 10,000 (2 measured), by one level.
    let shipped = render_png_bytes(&spheres_with(EXPLICIT));
    let (pixels, max) = differing_pixels(&a, &shipped);
    assert!(
        pixels <= 26 && max <= 1,
        "{pixels} pixels differ, by up to {max}"
    );
}

/// Scene A with a camera path: a dolly from the origin to (2, 1, 1) with a changing field of view
/// and a tilting up vector.
fn path_scene() -> Scene {
    spheres_with_camera(
        "[[camera.key]]
frame = 0
eye = [0.0, 0.0, 0.0]
look_at = [0.0, 0.0, -7.0]
up = [0.0, 1.0, 0.0]
fov_y = 90.0

[[camera.key]]
frame = 4
eye = [2.0, 1.0, 1.0]
look_at = [0.0, -0.5, -7.0]
up = [0.1, 1.0, 0.0]
fov_y = 60.0

[[camera.key]]
frame = 10
eye = [-1.5, 0.5, 0.3]
look_at = [0.0, 0.0, -7.0]
up = [0.0, 1.0, 0.2]
fov_y = 75.5",
    )
}

#[test]
fn a_key_frame_renders_as_the_key_written_as_a_static_camera() {
    let path = path_scene();
    let statics = [
        "eye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0",
        "eye = [2.0, 1.0, 1.0]\nlook_at = [0.0, -0.5, -7.0]\nup = [0.1, 1.0, 0.0]\nfov_y = 60.0",
        "eye = [-1.5, 0.5, 0.3]\nlook_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.2]\nfov_y = 75.5",
    ];
    for (frame, fields) in [0, 4, 10].into_iter().zip(statics) {
        let keyed = path.at_frame(frame).unwrap();
        let fixed = spheres_with_camera(&format!("[camera]\n{fields}"));
        assert_eq!(keyed.camera, fixed.camera, "frame {frame}");
        assert!(
            render_png_bytes(&keyed) == render_png_bytes(&fixed),
            "frame {frame} differs from its key as a static camera"
        );
    }
    // Without a frame range the scene shows its first key.
    assert_eq!(path.camera, path.at_frame(0).unwrap().camera);
}

#[test]
fn frames_between_keys_interpolate_in_f64() {
    let path = path_scene();
    let mid = path.at_frame(2).unwrap();
    // Halfway from key 0 to key 4: eye (1, 0.5, 0.5), fov 75° → t = tan 37.5°.
    assert_eq!(mid.camera.eye, glam::DVec3::new(1.0, 0.5, 0.5));
    assert_eq!(mid.camera.t, (37.5f64).to_radians().tan() as f32);
    assert_ne!(render_png_bytes(&mid), render_png_bytes(&path));
    let e = path.at_frame(11).unwrap_err().to_string();
    assert!(
        e.contains("frame 11 is outside the camera path's keys (0..=10)"),
        "{e}"
    );
}

/// A world loaded once for a camera path serves every frame: rendered with the world of the first
/// key (moved to each frame's eye by `render`), a later frame is byte-identical to the same
/// camera rendered with its own freshly loaded world, mesh and tree included.
#[test]
fn one_world_serves_every_frame_of_a_path_over_a_mesh() {
    use wavefront::scene::camera_path::{CameraKey, CameraPath};
    use wavefront::scene::lookat::LookAt;
    use wavefront::{RenderOptions, World, render};
    let Some(mut scene) = sibenik_scene(true) else {
        return;
    };
    scene.image.width = 48;
    scene.image.height = 48;
    let key = |frame: u32, eye: [f64; 3]| CameraKey {
        frame,
        view: LookAt {
            eye: eye.into(),
            look_at: glam::DVec3::new(-5.0, -11.0, 1.0),
            up: glam::DVec3::Y,
            fov_y: 60.0,
        },
    };
    scene.camera_path = Some(CameraPath {
        keys: vec![key(0, [10.0, -8.0, 2.0]), key(4, [2.0, -6.0, -3.0])],
    });
    let first = scene.at_frame(0).unwrap();
    let world = World::load(&first).unwrap();
    for frame in [2, 4] {
        let at = scene.at_frame(frame).unwrap();
        assert_ne!(at.camera.eye, first.camera.eye);
        let shared = render(&at, &world, RenderOptions::default(), |_, _| {}).0;
        let own = render_png_bytes(&at);
        assert!(
            own.iter().filter(|&&b| b > 0).count() > 1000,
            "frame {frame} sees the walls"
        );
        assert!(
            shared.to_rgb8(at.image.gamma) == own,
            "frame {frame} differs when rendered with the first frame's world"
        );
    }
}
