//! SPEC §14 lights end to end, against analytic values: the radiance of a white Lambertian plane
//! (`kd = 1`, nothing else) at known points, through the scene parser and the renderer, for
//! inverse-square falloff, spot lights (full, penumbra, outside) and directional lights, each
//! also behind an occluder; the mesh shadow paths (light-rooted bundles, packets) with
//! directional and spot lights against an exact f64 shadow test; and the parser's errors.

// The platform's f64 trigonometry is the reference the expected values are computed with (the
// renderer's own comes from `wavefront::arith`).
#![allow(clippy::disallowed_methods)]

use std::path::Path;

use glam::{DVec3, Vec3};
use wavefront::accel::kdtree::KdAccel;
use wavefront::scene::file::parse;
use wavefront::simd::Level;
use wavefront::{RenderOptions, World};
use wavefront_kit::testkit::{Scratch, render_film_with};

/// A scene over the plane `y = 0` (white, diffuse only, no ambient) with `lights` (TOML
/// `[[light]]` tables) and `extra` (more primitives), seen from `eye` straight down through a
/// `size × size` image of half-width `half` at the plane (1 sample at each pixel centre).
fn scene_text(lights: &str, extra: &str, eye: DVec3, size: u32, half: f64) -> String {
    let fov = 2.0 * (half / eye.y).atan().to_degrees();
    format!(
        "[image]\nwidth = {size}\nheight = {size}\nsamples = 1\n\
         [camera]\neye = [{}, {}, {}]\nlook_at = [{}, 0.0, {}]\nup = [0.0, 0.0, -1.0]\nfov_y = {fov}\n\
         [render]\nmax_depth = 0\nshadows = true\nambient = [0.0, 0.0, 0.0]\n\
         [material.white]\nka = [0.0, 0.0, 0.0]\nkd = [1.0, 1.0, 1.0]\n\
         [material.black]\nka = [0.0, 0.0, 0.0]\nkd = [0.0, 0.0, 0.0]\n\
         [[plane]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"white\"\n\
         {extra}\n{lights}\n",
        eye.x, eye.y, eye.z, eye.x, eye.z
    )
}

/// The radiance of the plane at `(x, 0, z)` under `lights` (with `extra` primitives), shadows
/// on: one pixel seen from straight above.
fn plane_radiance(lights: &str, extra: &str, x: f64, z: f64) -> Vec3 {
    let text = scene_text(lights, extra, DVec3::new(x, 0.5, z), 1, 1e-4);
    let scene = parse(&text, Path::new("lights.toml")).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let film = render_film_with(&scene, RenderOptions::default());
    film.pixels[0]
}

/// `got` within `1e-5` relative (plus `1e-7`) of `want`, on every channel.
fn assert_near(got: Vec3, want: f64, what: &str) {
    assert_within(got, want, 1e-5, what);
}

/// `got` within `rel` relative (plus `1e-7`) of `want`, on every channel.
fn assert_within(got: Vec3, want: f64, rel: f64, what: &str) {
    for c in got.to_array() {
        let err = (f64::from(c) - want).abs();
        assert!(
            err <= rel * want.abs() + 1e-7,
            "{what}: got {got}, want {want}"
        );
    }
}

/// A black sphere: an occluder that is itself never lit.
fn sphere(c: DVec3, r: f64) -> String {
    format!(
        "[[sphere]]\ncenter = [{}, {}, {}]\nradius = {r}\nmaterial = \"black\"\n",
        c.x, c.y, c.z
    )
}

#[test]
fn inverse_square_falloff_divides_by_the_squared_distance() {
    let at = |h: f64, falloff: &str| {
        let light = format!("[[light]]\nposition = [0.0, {h}, 0.0]\n{falloff}");
        plane_radiance(&light, "", 0.0, 0.0)
    };
    // Without falloff (the default, or said): the same at every height.
    for h in [2.0, 10.0] {
        assert_near(at(h, ""), 1.0, "no falloff");
        assert_near(at(h, "falloff = \"none\""), 1.0, "falloff none");
    }
    let (near, far) = (
        at(2.0, "falloff = \"inverse-square\""),
        at(10.0, "falloff = \"inverse-square\""),
    );
    assert_near(near, 0.25, "1/2²");
    assert_near(far, 0.01, "1/10²");
    assert_near(near / far, 25.0, "the 1/r² ratio");
    // At an angle: light at (3, 4, 0) seen from the origin, r = 5, n·l = 4/5, intensity 2.
    let slanted = "[[light]]\nposition = [3.0, 4.0, 0.0]\nintensity = [2.0, 2.0, 2.0]\n\
                   falloff = \"inverse-square\"";
    assert_near(
        plane_radiance(slanted, "", 0.0, 0.0),
        2.0 * 0.8 / 25.0,
        "slanted",
    );
    // Shadowed: a sphere between the light and the point blocks it; beside it, lit.
    let above = "[[light]]\nposition = [0.0, 4.0, 0.0]\nfalloff = \"inverse-square\"";
    let blocker = sphere(DVec3::new(0.0, 2.0, 0.0), 0.5);
    assert_near(plane_radiance(above, &blocker, 0.0, 0.0), 0.0, "blocked");
    // At (3, 0, 0): r = 5, n·l = 4/5.
    assert_near(
        plane_radiance(above, &blocker, 3.0, 0.0),
        0.8 / 25.0,
        "beside the blocker",
    );
}

/// A spot 4 above the origin pointing down, cone 60° (outer half angle 30°).
fn spot(penumbra: f64) -> String {
    format!(
        "[[light]]\nposition = [0.0, 4.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 60.0\n\
         penumbra = {penumbra}\nintensity = [3.0, 3.0, 3.0]"
    )
}

/// The plane's radiance under [`spot`] at the angle `deg` from its axis (along `+x` or `−z`).
fn spot_at(penumbra: f64, deg: f64, extra: &str) -> (Vec3, f64) {
    let r = 4.0 * deg.to_radians().tan();
    let n_dot_l = deg.to_radians().cos();
    let a = plane_radiance(&spot(penumbra), extra, r, 0.0);
    let b = plane_radiance(&spot(penumbra), extra, 0.0, -r);
    assert_near(b, f64::from(a.x), "the spot is round");
    (a, 3.0 * n_dot_l)
}

#[test]
fn spot_lights_are_full_inside_zero_outside_and_smoothstep_between() {
    // Penumbra 20°: full within 20° of the axis, none beyond 30°.
    for deg in [0.0, 5.0, 19.5] {
        let (got, full) = spot_at(20.0, deg, "");
        assert_near(got, full, &format!("full at {deg}°"));
    }
    for deg in [30.5, 40.0, 80.0] {
        assert_near(spot_at(20.0, deg, "").0, 0.0, &format!("dark at {deg}°"));
    }
    // The penumbra's midpoint (25°): smoothstep(1/2) = 1/2; at 28°: t = 0.2, 0.2²·(3 − 0.4).
    let (got, full) = spot_at(20.0, 25.0, "");
    assert_near(got, 0.5 * full, "midpoint");
    let (got, full) = spot_at(20.0, 28.0, "");
    assert_near(got, 0.104 * full, "near the outer edge");
    // The whole cone as penumbra: smoothstep from the axis, at 15° the midpoint.
    let (got, full) = spot_at(60.0, 15.0, "");
    assert_near(got, 0.5 * full, "penumbra = cone");
    // No penumbra: a hard edge at 30°.
    let (got, full) = spot_at(0.0, 29.5, "");
    assert_near(got, full, "inside a hard edge");
    assert_near(spot_at(0.0, 30.5, "").0, 0.0, "outside a hard edge");
    // With inverse-square falloff as well: at 25°, r = 4 / cos 25°.
    let light = format!("{}\nfalloff = \"inverse-square\"", spot(20.0));
    let c = 25f64.to_radians().cos();
    let got = plane_radiance(&light, "", 4.0 * 25f64.to_radians().tan(), 0.0);
    assert_near(got, 0.5 * 3.0 * c * (c / 4.0).powi(2), "spot with falloff");
    // Shadowed: a sphere on the axis blocks the full-intensity centre, not the point at 10°.
    let blocker = sphere(DVec3::new(0.0, 2.0, 0.0), 0.2);
    assert_near(spot_at(20.0, 0.0, &blocker).0, 0.0, "blocked on the axis");
    let (got, full) = spot_at(20.0, 10.0, &blocker);
    assert_near(got, full, "lit beside the blocker");
}

#[test]
fn directional_lights_give_n_dot_l_everywhere_and_are_blocked_from_afar() {
    let d = DVec3::new(1.0, -2.0, 0.5);
    let l = -d.normalize();
    let light = format!(
        "[[light]]\ndirection = [{}, {}, {}]\nintensity = [0.5, 0.5, 0.5]",
        d.x, d.y, d.z
    );
    for (x, z) in [(0.0, 0.0), (100.0, -50.0), (-1000.0, 7.0), (3.25, 2e4)] {
        let got = plane_radiance(&light, "", x, z);
        assert_near(got, 0.5 * l.y, &format!("at ({x}, 0, {z})"));
    }
    // `falloff = "none"` is allowed (and changes nothing).
    let none = format!("{light}\nfalloff = \"none\"");
    assert_near(
        plane_radiance(&none, "", 1.0, 1.0),
        0.5 * l.y,
        "falloff none",
    );
    // An occluder 1000 away along l blocks the point under it, not one 50 away from it.
    let blocker = sphere(DVec3::new(10.0, 0.0, 20.0) + 1000.0 * l, 10.0);
    assert_near(plane_radiance(&light, &blocker, 10.0, 20.0), 0.0, "blocked");
    let got = plane_radiance(&light, &blocker, 60.0, 20.0);
    assert_near(got, 0.5 * l.y, "beside the far blocker");
    // Below the horizon: nothing, whatever the distance.
    let under = "[[light]]\ndirection = [0.0, 1.0, 0.0]";
    assert_near(plane_radiance(under, "", 0.0, 0.0), 0.0, "from below");
}

/// Whether the segment `p + t·d`, `0 < t < t_max`, crosses the axis-aligned square at height
/// `y` with `|x − cx|, |z − cz| < half` (f64, exact enough away from its edges); also how far
/// from the nearest edge it crosses (to skip rays that graze it).
fn crosses_square(
    p: DVec3,
    d: DVec3,
    t_max: f64,
    (cx, y, cz, half): (f64, f64, f64, f64),
) -> (bool, f64) {
    if d.y == 0.0 {
        return (false, f64::INFINITY);
    }
    let t = (y - p.y) / d.y;
    if !(t > 0.0 && t < t_max) {
        return (false, f64::INFINITY);
    }
    let q = p + t * d;
    let margin = half - (q.x - cx).abs().max((q.z - cz).abs());
    (margin > 0.0, margin.abs())
}

/// A floor `y = 0` of two triangles (white) and a square roof (black) at `roof`, as one OBJ
/// (two materials by `usemtl`-free grouping: the roof is a second mesh file).
fn write_meshes(dir: &Scratch, (cx, y, cz, half): (f64, f64, f64, f64)) {
    let s = 200.0;
    dir.write(
        "floor.obj",
        &format!("v -{s} 0 -{s}\nv {s} 0 -{s}\nv {s} 0 {s}\nv -{s} 0 {s}\nf 1 3 2\nf 1 4 3\n"),
    );
    let (x0, x1, z0, z1) = (cx - half, cx + half, cz - half, cz + half);
    dir.write(
        "roof.obj",
        &format!(
            "v {x0} {y} {z0}\nv {x1} {y} {z0}\nv {x1} {y} {z1}\nv {x0} {y} {z1}\nf 1 2 3\nf 1 3 4\n"
        ),
    );
}

/// A 48 × 48 view of a mesh floor under a mesh roof lit by `light` (shadow rays: bundles or
/// packets on the mesh tree), pixel by pixel against the analytic `want(p)` and the exact
/// shadow test; returns how many pixels were lit and shadowed.
fn mesh_shadows(
    name: &str,
    light: &str,
    analytic_floor: bool,
    want: impl Fn(DVec3) -> (f64, DVec3, f64),
) -> (usize, usize) {
    let dir = Scratch::new(name);
    let roof = (1.0, 4.0, -0.5, 2.0);
    write_meshes(&dir, roof);
    let meshes = format!(
        "{}[[mesh]]\npath = \"roof.obj\"\nmaterial = \"black\"\n",
        if analytic_floor {
            ""
        } else {
            "[[mesh]]\npath = \"floor.obj\"\nmaterial = \"white\"\n"
        }
    );
    let (size, half) = (48, 6.0);
    let eye = DVec3::new(0.0, 10.0, 0.0);
    let mut text = scene_text(light, &meshes, eye, size, half);
    if !analytic_floor {
        // The floor is the mesh: drop the plane.
        text = text.replace(
            "[[plane]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"white\"\n",
            "",
        );
    }
    let path = dir.write("scene.toml", &text);
    let scene = parse(&text, &path).unwrap_or_else(|e| panic!("{e}"));
    let world = World::load(&scene).unwrap();
    let film = wavefront::render(&scene, &world, RenderOptions::default(), |_, _| {}).0;
    let (mut lit, mut dark) = (0, 0);
    for j in 0..size {
        for i in 0..size {
            // The pixel centre's ray from the eye to the floor.
            let fx = (f64::from(i) + 0.5) / f64::from(size) * 2.0 - 1.0;
            let fz = (f64::from(j) + 0.5) / f64::from(size) * 2.0 - 1.0;
            let p = DVec3::new(fx * half, 0.0, fz * half);
            let (value, to_light, t_max) = want(p);
            let (blocked, margin) = crosses_square(p, to_light, t_max, roof);
            let got = film.pixels[(j * size + i) as usize];
            // Skip rays through the roof's edges and pixels that see the roof (or near it).
            let (cx, y, cz, half) = roof;
            if margin < 0.05 || crosses_square(eye, p - eye, 1.0, (cx, y, cz, half + 0.05)).0 {
                continue;
            }
            let want = if blocked { 0.0 } else { value };
            // The hit points are f32 at 10 from the eye: the penumbra's steep smoothstep turns
            // their rounding into a few 1e-5 relative.
            assert_within(
                got,
                want,
                1e-4,
                &format!("{name}: pixel ({i}, {j}), floor {p}"),
            );
            if blocked {
                dark += 1;
            } else if value > 0.0 {
                lit += 1;
            }
        }
    }
    (lit, dark)
}

#[test]
fn mesh_shadows_of_directional_and_spot_lights_are_exact() {
    for analytic_floor in [false, true] {
        // Directional: every floor point lit by n·l, the roof's shadow cast along l.
        let d = DVec3::new(-0.6, -1.0, 0.3);
        let l = -d.normalize();
        let light = format!("[[light]]\ndirection = [{}, {}, {}]", d.x, d.y, d.z);
        let (lit, dark) = mesh_shadows("dir-shadow", &light, analytic_floor, |_| {
            (l.y, l, f64::INFINITY)
        });
        assert!(
            lit > 300 && dark > 100,
            "directional: {lit} lit, {dark} dark"
        );
        // Spot (inverse-square, penumbra) above the roof: the roof's shadow inside the cone.
        let q = DVec3::new(0.5, 8.0, 0.0);
        let light = format!(
            "[[light]]\nposition = [{}, {}, {}]\ndirection = [0.0, -1.0, 0.0]\ncone = 90.0\n\
             penumbra = 30.0\nfalloff = \"inverse-square\"\nintensity = [20.0, 20.0, 20.0]",
            q.x, q.y, q.z
        );
        let (lit, dark) = mesh_shadows("spot-shadow", &light, analytic_floor, |p| {
            let to = q - p;
            let l = to.normalize();
            let angle = (-l).dot(DVec3::NEG_Y).acos().to_degrees();
            let t = ((45.0 - angle) / 15.0).clamp(0.0, 1.0);
            let value = 20.0 * l.y * t * t * (3.0 - 2.0 * t) / to.length_squared();
            (value, l, to.length())
        });
        assert!(lit > 300 && dark > 100, "spot: {lit} lit, {dark} dark");
    }
}

/// The batch occlusion query (light-rooted bundles where rays share a far end, packets
/// otherwise) against the single-ray one, with unbounded `t_max` (a directional light's shadow
/// rays: all routed to the packet path) and with rays that all end at one point (a spot's:
/// bundled), on a mesh of random triangles, through the world and at every SIMD level.
#[test]
fn unbounded_shadow_rays_take_the_same_answers_in_batches_as_one_by_one() {
    let dir = Scratch::new("unbounded");
    let mut rng = wavefront::sampling::Rng(0x11e7);
    let mut obj = String::new();
    for k in 0..400 {
        let c = DVec3::new(
            f64::from(rng.range(-8.0, 8.0)),
            f64::from(rng.range(0.5, 6.0)),
            f64::from(rng.range(-8.0, 8.0)),
        );
        for _ in 0..3 {
            let v = c + DVec3::new(
                f64::from(rng.range(-0.7, 0.7)),
                f64::from(rng.range(-0.7, 0.7)),
                f64::from(rng.range(-0.7, 0.7)),
            );
            obj += &format!("v {} {} {}\n", v.x, v.y, v.z);
        }
        obj += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
    }
    dir.write("soup.obj", &obj);
    let text = scene_text(
        "",
        "[[mesh]]\npath = \"soup.obj\"\nmaterial = \"white\"\n",
        DVec3::new(0.0, 20.0, 0.0),
        4,
        1.0,
    )
    .replace(
        "[[plane]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"white\"\n",
        "",
    );
    let path = dir.write("scene.toml", &text);
    let scene = parse(&text, &path).unwrap();
    let world = World::load(&scene).unwrap();
    let n = 4096;
    // In the render frame (the eye at the origin).
    let frame = world.frame();
    let origins: Vec<Vec3> = (0..n)
        .map(|_| {
            let (x, y, z) = (
                rng.range(-9.0, 9.0),
                rng.range(-0.5, 0.2),
                rng.range(-9.0, 9.0),
            );
            frame.point(DVec3::new(x.into(), y.into(), z.into()))
        })
        .collect();
    let sun = Vec3::new(0.3, 1.0, -0.2).normalize();
    let spot = frame.point(DVec3::new(0.5, 9.0, 0.0));
    let cases: [(&str, Vec<Vec3>, Vec<f32>); 2] = [
        ("directional", vec![sun; n], vec![f32::INFINITY; n]),
        (
            "spot",
            origins.iter().map(|&o| (spot - o).normalize()).collect(),
            origins.iter().map(|&o| (spot - o).length()).collect(),
        ),
    ];
    let tris = world.triangles().expect("a mesh");
    let accel = tris.accel();
    for (what, dirs, t_max) in cases {
        let mut batch = vec![false; n];
        world.intersect_occluded_batch(&origins, &dirs, &t_max, &mut batch);
        let single: Vec<bool> = (0..n)
            .map(|i| world.intersect_occluded(origins[i], dirs[i], t_max[i]))
            .collect();
        let blocked = single.iter().filter(|&&b| b).count();
        assert!(
            blocked > n / 20 && blocked < n - n / 20,
            "{what}: {blocked} of {n} blocked"
        );
        assert_eq!(batch, single, "{what}");
        // At every SIMD level, in the shadow stage's chunks: unbounded rays all take the packet
        // path (no finite far end to bundle at); rays ending at the spot are bundled there.
        for level in Level::supported() {
            let mut out = vec![false; n];
            let mut fallback = 0;
            for (c, o) in out.chunks_mut(KdAccel::OCCLUDED_BATCH).enumerate() {
                let r = c * KdAccel::OCCLUDED_BATCH..c * KdAccel::OCCLUDED_BATCH + o.len();
                let counts = accel.intersect_occluded_batch_counted(
                    level,
                    &origins[r.clone()],
                    &dirs[r.clone()],
                    &t_max[r],
                    o,
                );
                fallback += counts.fallback as usize;
            }
            assert_eq!(out, single, "{what}, {level:?}");
            if what == "directional" {
                assert_eq!(fallback, n, "{what}, {level:?}: all on the packet path");
            } else {
                assert!(
                    fallback < n / 10,
                    "{what}, {level:?}: {fallback} of {n} not bundled"
                );
            }
        }
    }
}

/// The error a scene with `light` (a `[[light]]` table's keys) gives: one line naming the file,
/// `key`, and the line of the key's last part (`cone` for `light[0].cone`), or of the
/// `[[light]]` header when the table has no such key.
fn light_error(light: &str, key: &str) -> String {
    let text = scene_text(
        &format!("[[light]]\n{light}"),
        "",
        DVec3::new(0.0, 1.0, 0.0),
        1,
        0.1,
    );
    let header = text.lines().position(|l| l == "[[light]]").unwrap();
    let name = key.rsplit('.').next().unwrap();
    let line = text
        .lines()
        .enumerate()
        .skip(header)
        .find(|(_, l)| l.starts_with(&format!("{name} =")))
        .map_or(header, |(i, _)| i)
        + 1;
    let e = parse(&text, Path::new("bad.toml"))
        .expect_err(light)
        .to_string();
    assert!(!e.contains('\n'), "one line: {e}");
    let at = format!("bad.toml:{line}: ");
    assert!(
        e.starts_with(&at),
        "{light:?}: names the file and line ({at}): {e}"
    );
    assert!(e.contains(key), "{light:?}: names {key}: {e}");
    e
}

#[test]
fn bad_light_tables_are_errors_naming_file_line_and_key() {
    let cases = [
        ("intensity = [1.0, 1.0, 1.0]", "light[0].position"),
        ("direction = [0.0, 0.0, 0.0]", "light[0].direction"),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]",
            "light[0].direction",
        ),
        ("direction = [0.0, -1.0, 0.0]\ncone = 30.0", "light[0].cone"),
        ("position = [0.0, 1.0, 0.0]\ncone = 30.0", "light[0].cone"),
        (
            "position = [0.0, 1.0, 0.0]\npenumbra = 3.0",
            "light[0].penumbra",
        ),
        (
            "direction = [0.0, -1.0, 0.0]\npenumbra = 3.0",
            "light[0].penumbra",
        ),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 0.0",
            "light[0].cone",
        ),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 180.0",
            "light[0].cone",
        ),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = -5.0",
            "light[0].cone",
        ),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = nan",
            "light[0].cone",
        ),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 30.0\npenumbra = 31.0",
            "light[0].penumbra",
        ),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 30.0\npenumbra = -1.0",
            "light[0].penumbra",
        ),
        (
            "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 30.0\npenumbra = inf",
            "light[0].penumbra",
        ),
        (
            "direction = [0.0, -1.0, 0.0]\nfalloff = \"inverse-square\"",
            "light[0].falloff",
        ),
        (
            "position = [0.0, 1.0, 0.0]\nfalloff = \"quadratic\"",
            "light[0].falloff",
        ),
        ("direction = [0.0, inf, 0.0]", "light[0].direction"),
        ("position = [0.0, nan, 0.0]", "light[0].position"),
        ("position = [0.0, 1.0, 0.0]\ntype = \"spot\"", "type"),
    ];
    for (light, key) in cases {
        println!("{}", light_error(light, key));
    }
    // The good ones parse.
    for light in [
        "position = [0.0, 1.0, 0.0]\nfalloff = \"inverse-square\"",
        "direction = [1e-30, -1e-30, 0.0]",
        "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 179.0\npenumbra = 179.0",
        "position = [0.0, 1.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\ncone = 1.0\nfalloff = \"inverse-square\"",
    ] {
        let text = scene_text(
            &format!("[[light]]\n{light}"),
            "",
            DVec3::new(0.0, 1.0, 0.0),
            1,
            0.1,
        );
        parse(&text, Path::new("good.toml")).unwrap_or_else(|e| panic!("{light:?}: {e}"));
    }
}

/// Scene A's spheres and floor under all three kinds at once: the sun, a soft spot with falloff,
/// a blue inverse-square point light; mirrors on, shadows on.
fn three_kinds() -> wavefront::Scene {
    let mut s = wavefront::scene::builtin::spheres();
    let text = r#"
[[light]]
direction = [1.0, -0.5, 0.2]
intensity = [0.3, 0.28, 0.25]

[[light]]
position = [-1.0, 3.0, -6.0]
direction = [-0.3, -1.0, -0.1]
cone = 50.0
penumbra = 15.0
falloff = "inverse-square"
intensity = [9.0, 8.0, 6.0]

[[light]]
position = [3.0, 0.0, -4.0]
falloff = "inverse-square"
intensity = [0.0, 0.0, 3.0]
"#;
    let lights = parse(
        &scene_text(text, "", DVec3::new(0.0, 1.0, 0.0), 1, 0.1),
        Path::new("three.toml"),
    )
    .unwrap()
    .lights;
    s.lights = lights;
    s.image.width = 160;
    s.image.height = 120;
    s
}

#[test]
fn all_three_kinds_render_the_same_bytes_on_any_threads_waves_and_passes() {
    use wavefront_kit::testkit::{in_pool, render_png_bytes_with};
    let scene = three_kinds();
    let reference = in_pool(1, || {
        render_png_bytes_with(&scene, RenderOptions::default())
    });
    for (threads, wave_samples, shadow_rows) in [(2, 4096, usize::MAX), (2, 333, 50), (1, 1000, 7)]
    {
        let options = RenderOptions {
            wave_samples,
            shadow_rows,
            ..RenderOptions::default()
        };
        let got = in_pool(threads, || render_png_bytes_with(&scene, options.clone()));
        assert!(
            got == reference,
            "{threads} threads, waves of {wave_samples}, passes of {shadow_rows} rows"
        );
    }
}

#[test]
fn all_three_kinds_match_the_f64_oracle() {
    use wavefront_kit::oracle::compare_rgb8;
    use wavefront_kit::testkit::{oracle_png_bytes, render_png_bytes};
    let scene = three_kinds();
    let image = render_png_bytes(&scene);
    if let Ok(dir) = std::env::var("WAVEFRONT_TEST_IMAGES") {
        let path = Path::new(&dir).join("three_kinds.png");
        let (w, h) = (scene.image.width, scene.image.height);
        wavefront::film::output::save_rgb8(&path, w, h, &image).unwrap();
    }
    // Each light changes at least 2% of the pixels (so the oracle agrees about all three).
    for k in 0..scene.lights.len() {
        let mut without = scene.clone();
        without.lights.remove(k);
        let d = compare_rgb8(&image, &render_png_bytes(&without));
        assert!(
            d.over_3 * 50 > d.pixels,
            "light {k} changes only {} pixels",
            d.over_3
        );
    }
    let d = compare_rgb8(&image, &oracle_png_bytes(&scene));
    println!("three kinds against the oracle: {d}");
    // As tests/oracle.rs asks of scene A: 99.9% within 1/255, 99.99% within 3/255.
    assert!(
        d.over_1 * 1000 <= d.pixels && d.over_3 * 10_000 <= d.pixels,
        "{d}"
    );
}
