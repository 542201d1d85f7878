//! What a glTF file says about the scene beyond its triangles (SPEC §15): its materials as
//! Blinn-Phong materials (`material = "gltf"`), its first camera (`[camera] from = "gltf"`) and its
//! `KHR_lights_punctual` lights (`[render] lights_from = "gltf"`). The file is read by
//! [`crate::mesh::gltf`].

use std::path::Path;

use glam::DVec3;

use super::Material;
use super::lookat::LookAt;
use crate::mesh::MeshError;
use crate::mesh::gltf::{fail, read_document, walk};

/// The glTF materials of a file as Blinn-Phong materials (SPEC §15), and what the triangle
/// primitives of its default scene use.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct GltfMaterials {
    /// Every material of the file, in order, named `PREFIX:NAME` (or `PREFIX:#i` without a name).
    pub materials: Vec<Material>,
    /// Indices (into `materials`) some triangle primitive uses, in order of first use.
    pub used: Vec<u32>,
    /// Some triangle primitive has no material.
    pub unassigned: bool,
    /// The textures the mapping ignores, one entry each (`baseColorTexture of material "x"`).
    pub textures: Vec<String>,
}

/// The glTF material `m` as a Blinn-Phong material named `name`: `kd = baseColor.rgb · (1 −
/// metallic)`, `ks = 0.04 + (baseColor − 0.04) · metallic`, `p = 2 / max(roughness, 0.01)^4 − 2`
/// (at most 10,000), `α = metallic · (1 − roughness)`, `ka = 0`.
pub(crate) fn blinn_phong(m: &::gltf::Material, name: String) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor().map(f64::from);
    let base = DVec3::new(r, g, b);
    let metallic = f64::from(pbr.metallic_factor()).clamp(0.0, 1.0);
    let roughness = f64::from(pbr.roughness_factor()).clamp(0.0, 1.0);
    let kd = base * (1.0 - metallic);
    let ks = DVec3::splat(0.04) + (base - 0.04) * metallic;
    let r2 = roughness.max(0.01) * roughness.max(0.01);
    let p = (2.0 / (r2 * r2) - 2.0).clamp(0.0, 10_000.0);
    Material {
        name,
        ka: glam::Vec3::ZERO,
        kd: kd.as_vec3(),
        ks: ks.as_vec3(),
        p: p as f32,
        alpha: (metallic * (1.0 - roughness)) as f32,
    }
}

/// The materials of the glTF file `path` (see [`GltfMaterials`]); names are prefixed with the
/// file's path.
pub fn materials(path: &Path) -> Result<GltfMaterials, MeshError> {
    let doc = read_document(path)?;
    let prefix = path.display().to_string();
    let mut textures = vec![];
    let materials = doc
        .materials()
        .map(|m| {
            let i = m.index().unwrap_or(0);
            let label = m.name().map_or(format!("#{i}"), str::to_owned);
            let pbr = m.pbr_metallic_roughness();
            for (kind, present) in [
                ("baseColorTexture", pbr.base_color_texture().is_some()),
                (
                    "metallicRoughnessTexture",
                    pbr.metallic_roughness_texture().is_some(),
                ),
                ("normalTexture", m.normal_texture().is_some()),
                ("occlusionTexture", m.occlusion_texture().is_some()),
                ("emissiveTexture", m.emissive_texture().is_some()),
            ] {
                if present {
                    textures.push(format!("{kind} of material {label:?}"));
                }
            }
            blinn_phong(&m, format!("{prefix}:{label}"))
        })
        .collect();
    let mut used = vec![];
    let mut unassigned = false;
    walk(&doc, path, |node, _| {
        if let Some(m) = node.mesh() {
            for prim in m.primitives() {
                if prim.mode() != ::gltf::mesh::Mode::Triangles {
                    continue;
                }
                match prim.material().index() {
                    Some(i) if !used.contains(&(i as u32)) => used.push(i as u32),
                    Some(_) => {}
                    None => unassigned = true,
                }
            }
        }
        Ok(())
    })?;
    Ok(GltfMaterials {
        materials,
        used,
        unassigned,
        textures,
    })
}

/// The view of the first perspective camera of the glTF file `path`'s default scene (in node
/// order): the eye at the node's origin looking down its −z axis, up its +y axis, `fov_y` the
/// camera's `yfov`.
pub fn camera(path: &Path) -> Result<LookAt, MeshError> {
    let doc = read_document(path)?;
    let mut found = None;
    walk(&doc, path, |node, world| {
        if found.is_none()
            && let Some(c) = node.camera()
            && let ::gltf::camera::Projection::Perspective(p) = c.projection()
        {
            let eye = world.transform_point3(DVec3::ZERO);
            let dir = world.transform_vector3(DVec3::NEG_Z);
            found = Some(LookAt {
                eye,
                look_at: eye + dir,
                up: world.transform_vector3(DVec3::Y),
                fov_y: f64::from(p.yfov()).to_degrees(),
            });
        }
        Ok(())
    })?;
    found.ok_or_else(|| fail(path, "no perspective camera in the default scene"))
}

/// A `KHR_lights_punctual` light in world coordinates: what it is, and its intensity
/// (`color · intensity`, as given).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct GltfLight {
    /// Point, spot or directional, placed by its node's world transform.
    pub kind: GltfLightKind,
    /// `color · intensity` per channel.
    pub intensity: [f32; 3],
}

/// The kinds of `KHR_lights_punctual` light. A light shines along its node's local −Z axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum GltfLightKind {
    /// A point light at the node's origin.
    Point {
        /// The node's origin in world coordinates.
        position: DVec3,
    },
    /// A spot light at the node's origin along its −Z axis.
    Spot {
        /// The node's origin in world coordinates.
        position: DVec3,
        /// The node's −Z axis in world coordinates (not necessarily unit).
        direction: DVec3,
        /// `innerConeAngle` (radians, from the axis; default 0).
        inner: f64,
        /// `outerConeAngle` (radians, from the axis; default π/4).
        outer: f64,
    },
    /// A directional light along the node's −Z axis.
    Directional {
        /// The node's −Z axis in world coordinates (not necessarily unit).
        direction: DVec3,
    },
}

/// The `KHR_lights_punctual` lights of the glTF file `path`'s default scene, in node order. The
/// lights are read from the JSON (the crate's accessors unwrap, so a light index out of range
/// would panic there). A light whose values are not finite, whose intensity is negative, whose
/// node transform collapses its axis, or whose cone angles are not `0 ≤ inner < outer < π/2` (a
/// SPEC §14 cone is under 180°), is
/// an error naming it.
pub fn lights(path: &Path) -> Result<Vec<GltfLight>, MeshError> {
    use ::gltf::json::extensions::scene::khr_lights_punctual::Type;
    use ::gltf::json::validation::Checked;
    let doc = read_document(path)?;
    let json = doc.as_json();
    let lights = json
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
        .map_or(&[][..], |k| k.lights.as_slice());
    let mut out = vec![];
    walk(&doc, path, |node, world| {
        let Some(l) = json.nodes[node.index()]
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
        else {
            return Ok(());
        };
        let i = l.light.value();
        let light = lights.get(i).ok_or_else(|| {
            fail(
                path,
                format!(
                    "node {}: light {i} is not in KHR_lights_punctual",
                    node.index()
                ),
            )
        })?;
        let bad = |what: &str| fail(path, format!("light {i} (node {}): {what}", node.index()));
        let intensity = light.color.map(|c| c * light.intensity);
        if !intensity.iter().all(|c| c.is_finite() && *c >= 0.0) {
            return Err(bad("color · intensity must be finite and ≥ 0"));
        }
        let position = world.transform_point3(DVec3::ZERO);
        let direction = world.transform_vector3(DVec3::NEG_Z);
        let aimed = direction.is_finite() && direction != DVec3::ZERO;
        let kind = match light.type_ {
            Checked::Valid(Type::Point) => GltfLightKind::Point { position },
            Checked::Valid(Type::Directional) if aimed => GltfLightKind::Directional { direction },
            Checked::Valid(Type::Spot) if aimed => {
                let (inner, outer) = light
                    .spot
                    .as_ref()
                    .map_or((0.0, std::f32::consts::FRAC_PI_4), |s| {
                        (s.inner_cone_angle, s.outer_cone_angle)
                    });
                let (inner, outer) = (f64::from(inner), f64::from(outer));
                if !(0.0 <= inner && inner < outer && outer < std::f64::consts::FRAC_PI_2) {
                    return Err(bad(&format!(
                        "spot cone angles must be 0 ≤ innerConeAngle < outerConeAngle < π/2 \
                         (got {inner} and {outer})"
                    )));
                }
                GltfLightKind::Spot {
                    position,
                    direction,
                    inner,
                    outer,
                }
            }
            Checked::Valid(_) => {
                return Err(bad("the node transform gives the light no direction"));
            }
            Checked::Invalid => return Err(fail(path, format!("light {i}: unknown type"))),
        };
        if !position.is_finite() {
            return Err(bad(
                "the node transform puts the light at a non-finite position",
            ));
        }
        out.push(GltfLight { kind, intensity });
        Ok(())
    })?;
    Ok(out)
}
