//! Automatic framing (SPEC §16): a look-at view that fits a bounding box, and the scene
//! `wavefront render MESH.obj` renders when no scene file is given.
//!
//! The view looks at the centre of the box from a direction (`(1, 0.6, 1)` unless asked
//! otherwise, y up) at the distance where the box's bounding sphere just fits the smaller image
//! side: the sphere of radius `R` is tangent to the view cone of half-angle `θ` at distance
//! `R / sin θ = R · √(1 + tan²θ) / tan θ`, where `tan θ` is the look-at camera's own `t` for the
//! vertical side, `t · width / height` for the horizontal one.

use std::path::Path;

use glam::{DVec3, Vec3};

use super::lookat::LookAt;
use super::{
    ImageSettings, Light, Material, MeshRef, RenderMode, RenderSettings, Robustness, Scene,
    TreeSource,
};
use crate::error::SceneError;
use crate::mesh::ObjMesh;

/// The default direction from the box's centre to the eye.
pub(crate) const DEFAULT_FROM: DVec3 = DVec3::new(1.0, 0.6, 1.0);

/// The default vertical field of view of a framed camera, in degrees.
pub(crate) const DEFAULT_FOV_Y: f64 = 40.0;

/// The look-at view of the box `lo..=hi` seen from direction `from` (need not be unit) with a
/// vertical field of `fov_y` degrees on a `width × height` image; `None` when the box has no
/// extent, `from` is zero or not finite. `up` is +y, or −z when `from` is vertical.
pub(crate) fn frame_box(
    lo: DVec3,
    hi: DVec3,
    from: DVec3,
    fov_y: f64,
    (width, height): (u32, u32),
) -> Option<LookAt> {
    let radius = (hi - lo).length() / 2.0;
    let dir = from.try_normalize()?;
    if !(radius > 0.0 && radius.is_finite()) {
        return None;
    }
    // The half-angle tangents exactly as `LookAt::camera` computes its window.
    let t = crate::arith::tan(fov_y.to_radians() / 2.0);
    let t = t.min(t * f64::from(width) / f64::from(height));
    let distance = radius * (1.0 + t * t).sqrt() / t;
    let centre = (lo + hi) / 2.0;
    let up = if dir.cross(DVec3::Y).length() > 1e-6 {
        DVec3::Y
    } else {
        DVec3::NEG_Z
    };
    Some(LookAt {
        eye: centre + dir * distance,
        look_at: centre,
        up,
        fov_y,
    })
}

/// The scene of `wavefront render MESH.obj`: the mesh framed by [`frame_box`] from
/// [`DEFAULT_FROM`] at [`DEFAULT_FOV_Y`] on a `width × height` image (512 × 512 unless
/// `--size` says otherwise), one white point light at the eye (no falloff), a grey material
/// (`kd = 0.8`, `ka = 0.1`), shadows on, no reflections. `mesh` is the file at `path` as read.
pub(crate) fn bare_mesh(
    path: &Path,
    mesh: &ObjMesh,
    (width, height): (u32, u32),
) -> Result<Scene, SceneError> {
    let (lo, hi) = mesh.bounds();
    let image = ImageSettings {
        width,
        height,
        samples: 1,
        gamma: 2.2,
        seed: 0,
    };
    let invalid = |message: &str| SceneError::Invalid {
        file: path.to_path_buf(),
        line: 1,
        key: "mesh".into(),
        message: message.into(),
    };
    let view = frame_box(
        lo,
        hi,
        DEFAULT_FROM,
        DEFAULT_FOV_Y,
        (image.width, image.height),
    )
    .ok_or_else(|| invalid("has no extent to frame (no vertices, or all at one point)"))?;
    let camera = view
        .camera(image.width, image.height)
        .map_err(|e| invalid(&format!("cannot frame it: {e}")))?;
    Ok(Scene {
        name: path.display().to_string(),
        image,
        camera,
        camera_path: None,
        render: RenderSettings {
            max_depth: 0,
            shadows: true,
            ambient: Vec3::ONE,
            mode: RenderMode::Shaded,
            robustness: Robustness::default(),
        },
        lights: vec![Light::point(view.eye, Vec3::ONE)],
        materials: vec![Material {
            name: "grey".into(),
            ka: Vec3::splat(0.1),
            kd: Vec3::splat(0.8),
            ks: Vec3::ZERO,
            p: 0.0,
            alpha: 0.0,
        }],
        spheres: vec![],
        planes: vec![],
        meshes: vec![MeshRef {
            path: path.to_path_buf(),
            material: 0,
            kdtree: TreeSource::Sah,
            normals: Default::default(),
            mtl: None,
            allow_empty: false,
        }],
    })
}

/// True when `path` names a mesh file rather than a scene file, by its extension.
pub(crate) fn is_mesh_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ["obj", "ply", "gltf", "glb"].contains(&e.to_ascii_lowercase().as_str()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bounding_sphere_just_fits_the_smaller_side() {
        let (lo, hi) = (DVec3::new(-1.0, 2.0, -7.0), DVec3::new(3.0, 4.0, -6.0));
        let radius = (hi - lo).length() / 2.0;
        for size in [(512, 512), (800, 400), (300, 600)] {
            let v = frame_box(lo, hi, DEFAULT_FROM, 40.0, size).unwrap();
            assert_eq!(v.look_at, (lo + hi) / 2.0);
            let d = v.eye - v.look_at;
            assert!((d.normalize() - DEFAULT_FROM.normalize()).length() < 1e-15);
            // The half-angle of the smaller side, from the camera's own window.
            let c = v.camera(size.0, size.1).unwrap();
            // sin(atan t) = t / √(1 + t²).
            let t = f64::from(c.t.min(c.r));
            let expect = t / (1.0 + t * t).sqrt();
            let sine = radius / d.length();
            assert!((sine - expect).abs() < 1e-6, "{size:?}: {sine} vs {expect}");
        }
    }

    #[test]
    fn a_box_without_extent_or_a_zero_direction_cannot_be_framed() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        assert!(frame_box(p, p, DEFAULT_FROM, 40.0, (64, 64)).is_none());
        assert!(frame_box(p, p + 1.0, DVec3::ZERO, 40.0, (64, 64)).is_none());
        let inf = DVec3::splat(f64::INFINITY);
        assert!(frame_box(-inf, inf, DEFAULT_FROM, 40.0, (64, 64)).is_none());
        // Straight down: up falls back to −z, and the view is valid.
        let v = frame_box(p, p + 1.0, DVec3::Y, 40.0, (64, 64)).unwrap();
        assert!(v.camera(64, 64).is_ok());
    }

    #[test]
    fn mesh_paths_are_told_by_their_extension() {
        for p in ["a.obj", "b/c.OBJ", "x.ply", "y.gltf", "z.glb"] {
            assert!(is_mesh_path(Path::new(p)), "{p}");
        }
        for p in ["a.toml", "obj", "spheres", "a.obj.toml"] {
            assert!(!is_mesh_path(Path::new(p)), "{p}");
        }
    }
}
