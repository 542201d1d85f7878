//! Scene files written from [`Scene`] values: the many-spheres benchmark scene as a file for the
//! command line (`examples/many_spheres.rs`), so the built-in `many-spheres` and a scene file of
//! the same spheres can be timed side by side (the file adds its parse).
//!
//! Reads a scene of analytic primitives (spheres, planes, point lights, materials, a window
//! camera); writes the TOML of docs/scene-format.md, every number in full (shortest round-trip
//! form), so the file reads back as the same scene.

use std::fmt::Write;

use glam::{DVec3, Vec3};
use wavefront::scene::{Falloff, LightKind, RenderMode, Scene};

fn v3(v: Vec3) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

fn d3(v: DVec3) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

/// The scene as a scene file, or `None` for what this writer does not cover (meshes, camera
/// paths, the hit mask, non-default robustness settings).
pub fn analytic_scene_toml(scene: &Scene) -> Option<String> {
    if !scene.meshes.is_empty()
        || scene.camera_path.is_some()
        || scene.render.mode != RenderMode::Shaded
        || scene.render.robustness != Default::default()
    {
        return None;
    }
    let mut s = String::new();
    let (i, c, r) = (&scene.image, &scene.camera, &scene.render);
    // Writing to a String cannot fail.
    let _ = writeln!(
        s,
        "[image]\nwidth = {}\nheight = {}\nsamples = {}\ngamma = {:?}\nseed = {}\n",
        i.width, i.height, i.samples, i.gamma, i.seed
    );
    let _ = writeln!(
        s,
        "[camera]\neye = {}\nu = {}\nv = {}\nw = {}\n\
         window = {{ l = {:?}, r = {:?}, b = {:?}, t = {:?} }}\ndistance = {:?}\n",
        d3(c.eye),
        v3(c.u),
        v3(c.v),
        v3(c.w),
        c.l,
        c.r,
        c.b,
        c.t,
        c.d
    );
    let _ = writeln!(
        s,
        "[render]\nmax_depth = {}\nshadows = {}\nambient = {}\n",
        r.max_depth,
        r.shadows,
        v3(r.ambient)
    );
    for l in &scene.lights {
        let _ = match l.kind {
            LightKind::Point { position } => writeln!(s, "[[light]]\nposition = {}", d3(position)),
            LightKind::Directional { direction } => {
                writeln!(s, "[[light]]\ndirection = {}", d3(direction))
            }
            LightKind::Spot {
                position,
                direction,
                cone,
                penumbra,
            } => writeln!(
                s,
                "[[light]]\nposition = {}\ndirection = {}\ncone = {cone:?}\npenumbra = {penumbra:?}",
                d3(position),
                d3(direction)
            ),
        };
        if l.falloff == Falloff::InverseSquare {
            let _ = writeln!(s, "falloff = \"inverse-square\"");
        }
        let _ = writeln!(s, "intensity = {}\n", v3(l.intensity));
    }
    for m in &scene.materials {
        let _ = writeln!(
            s,
            "[material.{:?}]\nka = {}\nkd = {}\nks = {}\np = {:?}\nalpha = {:?}\n",
            m.name,
            v3(m.ka),
            v3(m.kd),
            v3(m.ks),
            m.p,
            m.alpha
        );
    }
    let name = |k: u32| format!("{:?}", scene.materials[k as usize].name);
    for p in &scene.planes {
        let _ = writeln!(
            s,
            "[[plane]]\npoint = {}\nnormal = {}\nmaterial = {}\n",
            d3(p.point),
            v3(p.normal),
            name(p.material)
        );
    }
    for sp in &scene.spheres {
        let _ = writeln!(
            s,
            "[[sphere]]\ncenter = {}\nradius = {:?}\nmaterial = {}\n",
            d3(sp.center),
            sp.radius,
            name(sp.material)
        );
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;
    use wavefront::scene::builtin::{many_spheres, sibenik, spheres};
    use wavefront::scene::file::parse;

    fn round_trip(scene: &Scene) {
        let text = analytic_scene_toml(scene).expect("an analytic scene");
        let mut back = parse(&text, Path::new("written.toml")).expect("the file parses");
        back.name = scene.name.clone();
        assert_eq!(&back, scene);
    }

    #[test]
    fn scene_a_and_many_spheres_read_back_as_the_same_scene() {
        round_trip(&spheres());
        round_trip(&many_spheres(3000));
    }

    #[test]
    fn every_kind_of_light_reads_back() {
        let mut scene = spheres();
        let base = scene.lights[0].clone();
        scene.lights.push(wavefront::scene::Light {
            kind: LightKind::Directional {
                direction: DVec3::new(0.5, -1.0, 0.25),
            },
            ..base.clone()
        });
        scene.lights.push(wavefront::scene::Light {
            kind: LightKind::Spot {
                position: DVec3::new(1.0, 5.0, -3.0),
                direction: DVec3::new(0.0, -1.0, 0.1),
                cone: 40.0,
                penumbra: 7.5,
            },
            falloff: Falloff::InverseSquare,
            ..base
        });
        round_trip(&scene);
    }

    #[test]
    fn meshes_are_not_written() {
        assert_eq!(analytic_scene_toml(&sibenik(false)), None);
    }
}
