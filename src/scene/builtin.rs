//! The built-in reference scenes of SPEC §3 and §5: `spheres`, `sibenik`, `sibenik-shadows`; and
//! `many-spheres`, scene A with 100,000 seeded random spheres (the many-primitives benchmark).

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

use super::{
    Camera, ImageSettings, Light, Material, MeshRef, Plane, RenderMode, RenderSettings, Robustness,
    Scene, Sphere, TreeSource,
};
use crate::error::SceneError;

/// Environment variable that overrides where the Sibenik mesh is looked for.
pub(crate) const SIBENIK_ENV: &str = "WAVEFRONT_SIBENIK";

/// The mesh path relative to the project root (SPEC §5).
pub(crate) const SIBENIK_RELATIVE: &str = "../shared/data/sibenik/sibenik.obj";

/// The built-in scene called `name`, or `None` when there is no such built-in.
///
/// The Sibenik scenes refer to [`sibenik_mesh_path`]; whether the file exists is checked when the
/// scene's geometry is loaded, so `plan` works without it.
pub fn builtin(name: &str) -> Option<Scene> {
    match name {
        "spheres" => Some(spheres()),
        "sibenik" => Some(sibenik(false)),
        "sibenik-shadows" => Some(sibenik(true)),
        "many-spheres" => Some(many_spheres(MANY_SPHERES)),
        _ => None,
    }
}

fn material(name: &str, ka: Vec3, kd: Vec3, ks: Vec3, p: f32, alpha: f32) -> Material {
    Material {
        name: name.to_owned(),
        ka,
        kd,
        ks,
        p,
        alpha,
    }
}

fn image_512() -> ImageSettings {
    ImageSettings {
        width: 512,
        height: 512,
        samples: 1,
        gamma: 2.2,
        seed: 0,
    }
}

/// Scene A (SPEC §3): three spheres over a mirror plane, shadows on, depth 2, one sample.
pub fn spheres() -> Scene {
    let v = DVec3::new;
    let c = Vec3::new;
    Scene {
        name: "spheres".into(),
        image: image_512(),
        camera: Camera {
            eye: DVec3::ZERO,
            u: Vec3::X,
            v: Vec3::Y,
            w: Vec3::Z,
            l: -0.1,
            r: 0.1,
            b: -0.1,
            t: 0.1,
            d: 0.1,
        },
        camera_path: None,
        render: RenderSettings {
            max_depth: 2,
            shadows: true,
            ambient: Vec3::ONE,
            mode: RenderMode::Shaded,
            robustness: Robustness::default(),
        },
        lights: vec![Light::point(v(-4.0, 4.0, -3.0), Vec3::ONE)],
        materials: vec![
            material("floor", Vec3::splat(0.2), Vec3::ONE, Vec3::ZERO, 0.0, 0.5),
            material(
                "red",
                c(0.2, 0.0, 0.0),
                c(1.0, 0.0, 0.0),
                Vec3::ZERO,
                0.0,
                0.0,
            ),
            material(
                "green",
                c(0.0, 0.2, 0.0),
                c(0.0, 0.5, 0.0),
                Vec3::splat(0.5),
                32.0,
                0.0,
            ),
            material(
                "blue",
                c(0.0, 0.0, 0.2),
                c(0.0, 0.0, 1.0),
                Vec3::ZERO,
                0.0,
                0.8,
            ),
        ],
        spheres: vec![
            Sphere {
                center: v(-4.0, 0.0, -7.0),
                radius: 1.0,
                material: 1,
            },
            Sphere {
                center: v(0.0, 0.0, -7.0),
                radius: 2.0,
                material: 2,
            },
            Sphere {
                center: v(4.0, 0.0, -7.0),
                radius: 1.0,
                material: 3,
            },
        ],
        planes: vec![Plane {
            point: v(0.0, -2.0, 0.0),
            normal: Vec3::Y,
            material: 0,
        }],
        meshes: vec![],
    }
}

/// Spheres in the built-in `many-spheres`.
pub const MANY_SPHERES: usize = 100_000;

/// Scene A's camera, light, materials and mirror floor at 256 × 256 with `n` seeded random
/// spheres instead of its three (the built-in `many-spheres` has [`MANY_SPHERES`]): centres
/// uniform in `x ∈ [−20, 20)`, `y ∈ [−1.75, 10)`, `z ∈ [−60, −5)`, radii in `[0.05, 0.25)`,
/// materials red, green and blue in turn by a random pick, all from [`crate::sampling::Rng`]
/// with seed 26, in f32 values (so a scene file printing them in full reads back the same
/// scene).
pub fn many_spheres(n: usize) -> Scene {
    let mut rng = crate::sampling::Rng(26);
    let mut scene = spheres();
    scene.name = "many-spheres".into();
    scene.image.width = 256;
    scene.image.height = 256;
    scene.spheres = (0..n)
        .map(|_| {
            let x = rng.range(-20.0, 20.0);
            let y = rng.range(-1.75, 10.0);
            let z = rng.range(-60.0, -5.0);
            let radius = rng.range(0.05, 0.25);
            let material = 1 + (rng.next_u64() % 3) as u32;
            Sphere {
                center: DVec3::new(x as f64, y as f64, z as f64),
                radius,
                material,
            }
        })
        .collect();
    scene
}

/// Scene B (SPEC §5): the Sibenik cathedral lit from the origin, with or without shadow rays.
pub fn sibenik(shadows: bool) -> Scene {
    Scene {
        name: if shadows {
            "sibenik-shadows"
        } else {
            "sibenik"
        }
        .into(),
        image: image_512(),
        camera: Camera {
            eye: DVec3::new(0.0, -10.0, 0.0),
            u: Vec3::Z,
            v: Vec3::Y,
            w: Vec3::NEG_X,
            l: -0.1,
            r: 0.1,
            b: -0.1,
            t: 0.1,
            d: 0.1,
        },
        camera_path: None,
        render: RenderSettings {
            max_depth: 0,
            shadows,
            ambient: Vec3::ONE,
            mode: RenderMode::Shaded,
            robustness: Robustness::default(),
        },
        lights: vec![Light::point(DVec3::ZERO, Vec3::ONE)],
        materials: vec![material(
            "white",
            Vec3::ZERO,
            Vec3::ONE,
            Vec3::ZERO,
            0.0,
            0.0,
        )],
        spheres: vec![],
        planes: vec![],
        meshes: vec![MeshRef {
            path: sibenik_mesh_path(),
            material: 0,
            kdtree: TreeSource::Sah,
            normals: Default::default(),
            mtl: None,
            allow_empty: false,
        }],
    }
}

/// Where the built-in Sibenik scenes look for the mesh: `$WAVEFRONT_SIBENIK` if set, else
/// `SIBENIK_RELATIVE` relative to the working directory (the project root, SPEC §5).
pub fn sibenik_mesh_path() -> PathBuf {
    sibenik_mesh_path_in(Path::new(""))
}

/// [`sibenik_mesh_path`] for a project rooted at `root`: `$WAVEFRONT_SIBENIK` if set, else
/// `root/``SIBENIK_RELATIVE`. The one place the mesh's location is decided.
pub fn sibenik_mesh_path_in(root: &Path) -> PathBuf {
    match std::env::var_os(SIBENIK_ENV) {
        Some(p) => PathBuf::from(p),
        None => root.join(SIBENIK_RELATIVE),
    }
}

/// The error for a mesh file that is not there; for the Sibenik mesh (a file named `sibenik.obj`)
/// it says where to put it.
pub(crate) fn missing_mesh(path: &Path) -> SceneError {
    SceneError::MissingMesh {
        path: path.to_path_buf(),
        sibenik: path.file_name().is_some_and(|n| n == "sibenik.obj"),
    }
}

/// [`missing_mesh`] for a mesh of `scene`: a built-in Sibenik scene's mesh says where to put it
/// whatever its name (it may come from `--mesh`).
pub(crate) fn missing_scene_mesh(scene: &Scene, path: &Path) -> SceneError {
    match missing_mesh(path) {
        SceneError::MissingMesh { path, sibenik } => SceneError::MissingMesh {
            path,
            sibenik: sibenik || matches!(scene.name.as_str(), "sibenik" | "sibenik-shadows"),
        },
        e => e,
    }
}
