//! `wavefront info FILE` (SPEC §16): what a scene or a mesh holds — triangles (and degenerate
//! ones), vertices, bounds, materials and their face counts, lights, the camera, the pipeline.

use std::fmt::Write as _;

use anyhow::{Context, Result};
use glam::DVec3;
use serde_json::{Value, json};

use wavefront::mesh::{NO_MATERIAL, ObjMesh, ObjRead};
use wavefront::{Pipeline, Scene};

/// One mesh of the scene, as read.
struct MeshInfo {
    path: String,
    triangles: usize,
    degenerate: usize,
    vertices: usize,
    bounds: Option<(DVec3, DVec3)>,
}

/// Everything `info` prints.
pub struct Info {
    scene: Scene,
    meshes: Vec<MeshInfo>,
    /// Faces per scene material (index into `scene.materials`).
    faces: Vec<usize>,
}

impl Info {
    /// Reads every mesh of `scene` (positions, faces and, for `material = "mtl"`, each face's
    /// material).
    pub fn of(scene: Scene) -> Result<Info> {
        let mut faces = vec![0usize; scene.materials.len()];
        let mut meshes = vec![];
        for m in &scene.meshes {
            let read = ObjRead {
                normals: false,
                materials: m.mtl.is_some(),
            };
            let mesh = ObjMesh::read_with(&m.path, read)
                .with_context(|| format!("cannot read mesh {}", m.path.display()))?;
            let (lo, hi) = mesh.bounds();
            // Degenerate as the renderer sees it: in f32, in the frame centred on the mesh.
            let centred = mesh.to_frame((lo + hi) / 2.0)?;
            let degenerate = (0..centred.len())
                .filter(|&k| centred.is_degenerate(k))
                .count();
            for k in 0..mesh.indices.len() {
                let material = match (&m.mtl, mesh.face_materials.get(k)) {
                    (Some(b), Some(&i)) if i != NO_MATERIAL => b.first + i,
                    (Some(b), _) => b.fallback.unwrap_or(m.material),
                    (None, _) => m.material,
                };
                if let Some(n) = faces.get_mut(material as usize) {
                    *n += 1;
                }
            }
            meshes.push(MeshInfo {
                path: m.path.display().to_string(),
                triangles: mesh.indices.len(),
                degenerate,
                vertices: mesh.positions.len(),
                bounds: (!mesh.positions.is_empty()).then_some((lo, hi)),
            });
        }
        Ok(Info {
            scene,
            meshes,
            faces,
        })
    }

    /// The report as text.
    pub fn text(&self) -> String {
        let s = &self.scene;
        let i = &s.image;
        let c = &s.camera;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "scene: {} ({}x{}, {} spp, gamma {}, max_depth {}, shadows {})",
            s.name,
            i.width,
            i.height,
            i.samples,
            i.gamma,
            s.render.max_depth,
            if s.render.shadows { "on" } else { "off" }
        );
        let _ = writeln!(
            t,
            "camera: eye {} u {} v {} w {} window l {} r {} b {} t {} distance {}",
            c.eye, c.u, c.v, c.w, c.l, c.r, c.b, c.t, c.d
        );
        if let Some(p) = &s.camera_path {
            let _ = writeln!(
                t,
                "camera path: frames {}..={}",
                p.first_frame(),
                p.last_frame()
            );
        }
        let _ = writeln!(t, "lights: {}", s.lights.len());
        for (k, l) in s.lights.iter().enumerate() {
            let _ = writeln!(t, "  {k}: {} intensity {}", light_text(l), l.intensity);
        }
        let _ = writeln!(t, "materials: {}", s.materials.len());
        for (m, n) in s.materials.iter().zip(&self.faces) {
            let _ = writeln!(
                t,
                "  {}: ka {} kd {} ks {} p {} alpha {} ({n} faces)",
                m.name, m.ka, m.kd, m.ks, m.p, m.alpha
            );
        }
        let _ = writeln!(
            t,
            "spheres: {}, planes: {}, meshes: {}",
            s.spheres.len(),
            s.planes.len(),
            s.meshes.len()
        );
        for m in &self.meshes {
            let bounds = m
                .bounds
                .map_or("none".into(), |(lo, hi)| format!("{lo} to {hi}"));
            let _ = writeln!(
                t,
                "  {}: {} triangles ({} degenerate), {} vertices, bounds {bounds}",
                m.path, m.triangles, m.degenerate, m.vertices
            );
        }
        let _ = write!(t, "{}", Pipeline::for_scene(s));
        t
    }

    /// The report as one JSON object.
    pub fn json(&self) -> Value {
        let s = &self.scene;
        let v3 = |v: DVec3| json!([v.x, v.y, v.z]);
        let f3 = |v: glam::Vec3| json!([v.x, v.y, v.z]);
        let c = &s.camera;
        json!({
            "scene": s.name,
            "image": {"width": s.image.width, "height": s.image.height,
                      "samples": s.image.samples, "gamma": s.image.gamma},
            "render": {"max_depth": s.render.max_depth, "shadows": s.render.shadows},
            "camera": {"eye": v3(c.eye), "u": f3(c.u), "v": f3(c.v), "w": f3(c.w),
                       "window": {"l": c.l, "r": c.r, "b": c.b, "t": c.t}, "distance": c.d},
            "camera_path": s.camera_path.as_ref().map(|p| json!({
                "first_frame": p.first_frame(), "last_frame": p.last_frame()})),
            "lights": s.lights.iter().map(light_json).collect::<Vec<_>>(),
            "materials": s.materials.iter().zip(&self.faces).map(|(m, n)| json!({
                "name": m.name, "ka": f3(m.ka), "kd": f3(m.kd), "ks": f3(m.ks),
                "p": m.p, "alpha": m.alpha, "faces": n})).collect::<Vec<_>>(),
            "spheres": s.spheres.len(),
            "planes": s.planes.len(),
            "meshes": self.meshes.iter().map(|m| json!({
                "path": m.path, "triangles": m.triangles, "degenerate": m.degenerate,
                "vertices": m.vertices,
                "bounds": m.bounds.map(|(lo, hi)| json!([v3(lo), v3(hi)]))})).collect::<Vec<_>>(),
            "triangles": self.meshes.iter().map(|m| m.triangles).sum::<usize>(),
            "pipeline": Pipeline::for_scene(s).to_string(),
        })
    }
}

/// A light's kind, position and direction as `info` prints them.
fn light_text(l: &wavefront::scene::Light) -> String {
    use wavefront::scene::{Falloff, LightKind};
    let falloff = match l.falloff {
        Falloff::None => "",
        Falloff::InverseSquare => ", inverse-square falloff",
    };
    match l.kind {
        LightKind::Point { position } => format!("point at {position}{falloff},"),
        LightKind::Directional { direction } => format!("directional along {direction},"),
        LightKind::Spot {
            position,
            direction,
            cone,
            penumbra,
        } => format!(
            "spot at {position} along {direction}, cone {cone}°, penumbra {penumbra}°{falloff},"
        ),
    }
}

/// A light as `info --json` gives it: `kind`, `position` and `direction` where it has them,
/// `cone` and `penumbra` for a spot, `falloff`, `intensity`.
fn light_json(l: &wavefront::scene::Light) -> Value {
    use wavefront::scene::{Falloff, LightKind};
    let v3 = |v: DVec3| json!([v.x, v.y, v.z]);
    let f3 = |v: glam::Vec3| json!([v.x, v.y, v.z]);
    let falloff = match l.falloff {
        Falloff::None => "none",
        Falloff::InverseSquare => "inverse-square",
    };
    match l.kind {
        LightKind::Point { position } => json!({"kind": "point", "position": v3(position),
            "falloff": falloff, "intensity": f3(l.intensity)}),
        LightKind::Directional { direction } => json!({"kind": "directional",
            "direction": v3(direction), "falloff": falloff, "intensity": f3(l.intensity)}),
        LightKind::Spot {
            position,
            direction,
            cone,
            penumbra,
        } => json!({"kind": "spot",
            "position": v3(position), "direction": v3(direction), "cone": cone,
            "penumbra": penumbra, "falloff": falloff, "intensity": f3(l.intensity)}),
    }
}
