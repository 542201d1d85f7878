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

/// Three look-at keys: a dolly from the origin to (2, 1, 1) with a changing field of view and a
/// tilting up vector.
const PATH_KEYS: &str = "[[camera.key]]
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
fov_y = 75.5";

/// Scene A with the camera path [`PATH_KEYS`].
fn path_scene() -> Scene {
    spheres_with_camera(PATH_KEYS)
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
        e.contains("frame 11 is outside the camera path's frames (0..=10)"),
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
    scene.camera_path = Some(CameraPath::linear(vec![
        key(0, [10.0, -8.0, 2.0]),
        key(4, [2.0, -6.0, -3.0]),
    ]));
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

/// Scene A's text with its `[camera]` table replaced by `camera` (for error cases).
fn spheres_text_with_camera(camera: &str) -> String {
    SPHERES.replace(
        &format!("[camera]\neye = [0.0, 0.0, 0.0]\n{EXPLICIT}"),
        camera,
    )
}

const ORBIT: &str = "[camera.orbit]
look_at = [0.0, 0.0, -7.0]
eye = [0.0, 1.0, 2.0]
up = [0.0, 1.0, 0.0]
fov_y = 60.0
frames = 24
turns = 0.5";

#[test]
fn an_orbits_frame_0_renders_as_its_static_camera_and_every_frame_keeps_the_distance() {
    let orbit = spheres_with_camera(ORBIT);
    let path = orbit
        .camera_path
        .as_ref()
        .expect("an orbit is a camera path");
    assert_eq!((path.first_frame(), path.last_frame()), (0, 23));
    let fixed = spheres_with_camera(
        "[camera]\neye = [0.0, 1.0, 2.0]\nlook_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 60.0",
    );
    let first = orbit.at_frame(0).unwrap();
    assert_eq!(first.camera, fixed.camera);
    assert!(render_png_bytes(&first) == render_png_bytes(&fixed));
    let r0 = (glam::DVec3::new(0.0, 1.0, 2.0) - glam::DVec3::new(0.0, 0.0, -7.0)).length();
    for f in 0..24 {
        let v = path.view_at(f).unwrap();
        let r = (v.eye - v.look_at).length();
        assert!((r - r0).abs() <= 1e-9 * r0, "frame {f}: {r} vs {r0}");
    }
    // Half a turn over 24 frames: frame 12 is a quarter turn about +y, eye (9, 1, -7).
    let quarter = path.view_at(12).unwrap().eye;
    assert!(
        (quarter - glam::DVec3::new(9.0, 1.0, -7.0)).length() < 1e-14,
        "{quarter}"
    );
    assert!(orbit.at_frame(24).is_err());
}

#[test]
fn a_catmull_rom_key_frame_renders_as_the_key_and_frames_between_bend() {
    let text = spheres_text_with_camera(&format!(
        "[camera]\ninterpolation = \"catmull-rom\"\n\n{PATH_KEYS}"
    ));
    let smooth = parse(&text, Path::new("spheres.toml")).unwrap();
    let linear = path_scene();
    for frame in [0, 4, 10] {
        let (a, b) = (
            smooth.at_frame(frame).unwrap(),
            linear.at_frame(frame).unwrap(),
        );
        assert_eq!(a.camera, b.camera, "frame {frame} is its key");
        assert!(render_png_bytes(&a) == render_png_bytes(&b));
    }
    // Between keys the spline leaves the chord; `up` and `fov_y` stay linear.
    let (a, b) = (smooth.at_frame(2).unwrap(), linear.at_frame(2).unwrap());
    assert_ne!(a.camera.eye, b.camera.eye);
    assert_eq!((a.camera.t, a.camera.b), (b.camera.t, b.camera.b));
}

#[test]
fn bad_orbits_and_interpolations_name_line_and_key() {
    let cases = [
        (format!("{ORBIT}\n\n[[camera.key]]\nframe = 0\neye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0"),
         "camera.key: cannot be combined with [camera.orbit]"),
        (format!("[camera]\neye = [0.0, 0.0, 0.0]\n\n{ORBIT}"), "camera.eye: cannot be combined with [camera.orbit]"),
        (ORBIT.replace("frames = 24", "frames = 0"), "camera.orbit.frames: 0 is out of range"),
        (ORBIT.replace("turns = 0.5", "turns = nan"), "camera.orbit.turns"),
        (ORBIT.replace("up = [0.0, 1.0, 0.0]", "up = [0.0, 2.0, 18.0]"), "camera.orbit.up"),
        (ORBIT.replace("fov_y = 60.0\n", ""), "missing field `fov_y`"),
        ("[camera]\ninterpolation = \"linear\"\neye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0".into(),
         "camera.interpolation: only meaningful with [[camera.key]]"),
        ("[camera]\ninterpolation = \"cubic\"\n\n[[camera.key]]\nframe = 0\neye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0".into(),
         "camera.interpolation: unknown value \"cubic\""),
    ];
    for (camera, expect) in cases {
        let text = spheres_text_with_camera(&camera);
        let e = parse(&text, Path::new("s.toml")).unwrap_err().to_string();
        assert!(e.contains(expect), "{camera}\n-> {e}");
        assert!(e.starts_with("s.toml:"), "names the file and line: {e}");
    }
}

#[test]
fn frame_auto_fits_the_bounding_sphere_of_the_geometry() {
    // Scene A's spheres span x in [-5, 5], y in [-2, 2], z in [-9, -5] (the plane is unbounded
    // and left out): centre (0, 0, -7), bounding-sphere radius |(5, 2, 2)| = √33.
    for size in [(512, 512), (300, 200), (200, 300)] {
        let text = spheres_text_with_camera("[camera]\nframe = \"auto\"\nfrom = [0.0, 1.0, 2.0]")
            .replace(
                "width = 512\nheight = 512",
                &format!("width = {}\nheight = {}", size.0, size.1),
            );
        let s = parse(&text, Path::new("s.toml")).unwrap();
        let c = &s.camera;
        let centre = glam::DVec3::new(0.0, 0.0, -7.0);
        let to_eye = c.eye - centre;
        let d = to_eye.length();
        let dir = glam::DVec3::new(0.0, 1.0, 2.0) / 5f64.sqrt();
        assert!(
            (to_eye / d - dir).length() < 1e-12,
            "{size:?}: looks from `from`"
        );
        // The sphere touches the smaller side: R / d = sin(half-angle) = t / √(1 + t²).
        let t = f64::from(c.t.min(c.r));
        let sine = t / (1.0 + t * t).sqrt();
        assert!((33f64.sqrt() / d - sine).abs() < 1e-6, "{size:?}");
        assert_eq!(c.d, 1.0);
    }
    // The defaults: from (1, 0.6, 1), fov_y 40.
    let s = parse(
        &spheres_text_with_camera("[camera]\nframe = \"auto\""),
        Path::new("s.toml"),
    )
    .unwrap();
    let dir = (s.camera.eye - glam::DVec3::new(0.0, 0.0, -7.0)).normalize();
    assert!((dir - glam::DVec3::new(1.0, 0.6, 1.0).normalize()).length() < 1e-12);
    let cases = [
        (
            "[camera]\nframe = \"manual\"",
            "camera.frame: unknown value \"manual\"",
        ),
        (
            "[camera]\nframe = \"auto\"\neye = [0.0, 0.0, 0.0]",
            "camera.eye: cannot be combined",
        ),
        (
            "[camera]\nframe = \"auto\"\nfrom = [0.0, 0.0, 0.0]",
            "camera.from",
        ),
        (
            "[camera]\nfrom = [0.0, 1.0, 0.0]\neye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0",
            "camera.from: only meaningful with frame = \"auto\"",
        ),
        ("[camera]\nframe = \"auto\"\nfov_y = 180.0", "camera.fov_y"),
    ];
    for (camera, expect) in cases {
        let e = parse(&spheres_text_with_camera(camera), Path::new("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(expect) && e.starts_with("s.toml:"),
            "{camera}\n-> {e}"
        );
    }
}
