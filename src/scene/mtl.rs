//! Materials from an OBJ's MTL libraries (SPEC §12): `[[mesh]] material = "mtl"`.
//!
//! At scene load the OBJ's `mtllib`, `usemtl` and `f` lines are scanned, its libraries read with
//! `crate::mesh::mtl::read_library` (this crate's MTL reader, strict: a value that is not a finite, non-negative
//! number is an error naming the MTL file and line, as in a scene file; a colour with one or two
//! components takes g and b from r, as MTL says), and every library material appended to the scene's materials — so the
//! pipeline knows before any geometry is loaded which materials the mesh uses (no reflect stage
//! when no face reflects). `Ka`, `Kd`, `Ks`, `Ns` become `ka`, `kd`, `ks`, `p` (defaults 0, 0.8,
//! 0, 0); the mirror weight is the mean of `Ks` for `illum` 3, 5 or 7 and 0 otherwise. A library
//! that cannot be read, an unknown `usemtl` name, or faces before any `usemtl` without a
//! `fallback_material` is an error naming the OBJ file and line.

use std::collections::HashMap;
use std::path::Path;

use glam::Vec3;

use super::Material;
use crate::error::SceneError;
use crate::mesh::mtl::read_library_noting;

/// How a mesh's faces get their materials from its MTL libraries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MtlBinding {
    /// Scene material index of the libraries' first material; library material `i` (in the order
    /// tobj loads them: libraries in `mtllib` order, materials in file order) is `first + i`.
    pub first: u32,
    /// Number of library materials.
    pub count: u32,
    /// Scene material of faces before any `usemtl`.
    pub fallback: Option<u32>,
    /// Scene materials some face uses (those named by `usemtl`, and the fallback if faces come
    /// before any `usemtl`).
    pub used: Vec<u32>,
    /// One line per thing the libraries hold that is not used (an MTL key, once per key and
    /// file, with its first line; glTF textures), shown when the scene is loaded.
    pub warnings: Vec<String>,
}

/// The MTL material `m` as a scene material named `prefix:NAME`.
fn convert(prefix: &str, m: &tobj::Material) -> Material {
    let v = |c: Option<[f64; 3]>, default: f32| {
        c.map_or(Vec3::splat(default), |c| {
            Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)
        })
    };
    let ks = v(m.specular, 0.0);
    let mirror = matches!(m.illumination_model, Some(3 | 5 | 7));
    Material {
        name: format!("{prefix}:{}", m.name),
        ka: v(m.ambient, 0.0),
        kd: v(m.diffuse, 0.8),
        ks,
        p: m.shininess.unwrap_or(0.0) as f32,
        alpha: if mirror {
            (ks.element_sum() / 3.0).clamp(0.0, 1.0)
        } else {
            0.0
        },
    }
}

/// Reads the MTL libraries of the OBJ at `obj`, appends their materials to `materials` (whose
/// element `i` will be scene material `base + i`) and returns the binding. `fallback` is the
/// mesh's `fallback_material`, if any.
pub(crate) fn bind(
    obj: &Path,
    fallback: Option<u32>,
    base: u32,
    materials: &mut Vec<Material>,
) -> Result<MtlBinding, SceneError> {
    let text = crate::input::read_text(obj).map_err(|source| SceneError::MeshIo {
        file: obj.to_path_buf(),
        source,
    })?;
    let invalid = |line: usize, key: &str, message: String| SceneError::Invalid {
        file: obj.to_path_buf(),
        line,
        key: key.into(),
        message,
    };
    let dir = obj.parent().unwrap_or(Path::new(""));
    let index = |materials: &Vec<Material>| base + materials.len() as u32;
    let first = index(materials);
    let mut names: HashMap<String, u32> = HashMap::new();
    let mut used: Vec<u32> = vec![];
    let mut current: Option<u32> = None;
    let mut warnings = vec![];
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let mut tokens = raw.split_whitespace();
        match tokens.next() {
            Some("mtllib") => {
                for lib in tokens {
                    let (lib_materials, unused) =
                        read_library_noting(&dir.join(lib)).map_err(|e| match e {
                            SceneError::MeshIo { source, .. } => invalid(
                                line,
                                "mtllib",
                                format!(
                                    "cannot read material library {lib}: {}",
                                    crate::error::chain(&source)
                                ),
                            ),
                            e => e,
                        })?;
                    warnings.extend(unused);
                    for m in &lib_materials {
                        names.insert(m.name.clone(), index(materials));
                        materials.push(convert(&obj.display().to_string(), m));
                    }
                }
            }
            Some("usemtl") => {
                let name = tokens.collect::<Vec<_>>().join(" ");
                let Some(&index) = names.get(&name) else {
                    return Err(invalid(
                        line,
                        "usemtl",
                        format!("unknown material `{name}` (not in any mtllib read so far)"),
                    ));
                };
                current = Some(index);
                if !used.contains(&index) {
                    used.push(index);
                }
            }
            Some("f") if current.is_none() => {
                let Some(f) = fallback else {
                    return Err(invalid(
                        line,
                        "f",
                        "a face before any usemtl needs the mesh's fallback_material".into(),
                    ));
                };
                current = Some(f);
                if !used.contains(&f) {
                    used.push(f);
                }
            }
            _ => {}
        }
    }
    Ok(MtlBinding {
        first,
        count: index(materials) - first,
        fallback,
        used,
        warnings,
    })
}

/// Binds a glTF file's materials (`material = "gltf"`, SPEC §15) as [`bind`] binds an OBJ's MTL
/// libraries: every material of `gltf` (`crate::scene::gltf::materials`) is appended to
/// `materials` (scene material `base + materials.len()` onwards), in file order. Primitives
/// without a material take `fallback`; without one, that is an error. Ignored textures are one
/// warning line.
pub(crate) fn bind_gltf(
    gltf: &Path,
    fallback: Option<u32>,
    base: u32,
    materials: &mut Vec<Material>,
) -> Result<MtlBinding, crate::mesh::MeshError> {
    let g = crate::scene::gltf::materials(gltf)?;
    let first = base + materials.len() as u32;
    materials.extend(g.materials.iter().cloned());
    let mut used: Vec<u32> = g.used.iter().map(|&i| first + i).collect();
    if g.unassigned {
        let Some(f) = fallback else {
            return Err(crate::mesh::MeshError::Format {
                path: gltf.to_path_buf(),
                message: "a triangle primitive has no material: give its [[mesh]] a \
                          fallback_material"
                    .into(),
            });
        };
        if !used.contains(&f) {
            used.push(f);
        }
    }
    let mut warnings = vec![];
    if !g.textures.is_empty() {
        warnings.push(format!(
            "{}: textures are ignored (material = \"gltf\" maps the factors only): {}",
            gltf.display(),
            g.textures.join(", ")
        ));
    }
    Ok(MtlBinding {
        first,
        count: g.materials.len() as u32,
        fallback,
        used,
        warnings,
    })
}

/// The warnings of loading `scene`: each mesh binding's ([`MtlBinding::warnings`]), then one
/// line per scene material that no primitive can use (for example one defined beside
/// `material = "mtl"`, whose faces take their MTL materials).
pub(crate) fn load_warnings(scene: &super::Scene) -> Vec<String> {
    let mut out: Vec<String> = scene
        .meshes
        .iter()
        .filter_map(|m| m.mtl.as_ref())
        .flat_map(|b| b.warnings.iter().cloned())
        .collect();
    let bound = |i: u32| {
        scene
            .meshes
            .iter()
            .filter_map(|m| m.mtl.as_ref())
            .any(|b| (b.first..b.first + b.count).contains(&i))
    };
    let used: Vec<&Material> = scene.used_materials().collect();
    let from_files = scene.meshes.iter().any(|m| m.mtl.is_some());
    for (i, m) in scene.materials.iter().enumerate() {
        if bound(i as u32) || used.iter().any(|u| std::ptr::eq(*u, m)) {
            continue;
        }
        let hint = if from_files {
            " (faces of a mesh with material = \"mtl\" or \"gltf\" take the file's materials, \
             and only faces without one take its fallback_material)"
        } else {
            ""
        };
        out.push(format!(
            "{}: material `{}` is not used by any primitive{hint}",
            scene.name, m.name
        ));
    }
    out
}
