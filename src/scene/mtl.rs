//! Materials from an OBJ's MTL libraries (SPEC §12): `[[mesh]] material = "mtl"`.
//!
//! At scene load the OBJ's `mtllib`, `usemtl` and `f` lines are scanned, its libraries read with
//! [`read_library`] (this crate's MTL reader, strict: a value that is not a finite, non-negative
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
use crate::error::{SceneError, short};
use crate::input::{MTL_CAP, read_text_capped};

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
pub fn bind(
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

/// Reads the MTL library at `path` (a regular file of at most [`MTL_CAP`] bytes): its materials
/// in file order, as tobj's `Material` (name, `Ka`, `Kd`, `Ks`, `Ns`, `illum`). Colours take one
/// to three components (g and b default to r); every number must be finite, non-negative and fit
/// an f32; `illum` is an integer 0–10; texture maps and other known statements are skipped; a
/// statement before any `newmtl`, an unknown keyword, or a spectral or CIE XYZ colour is an error
/// naming the file and line. A file that cannot be read is [`SceneError::MeshIo`].
pub fn read_library(path: &Path) -> Result<Vec<tobj::Material>, SceneError> {
    Ok(read_library_noting(path)?.0)
}

/// [`read_library`], with one warning line for every key the renderer does not use (once per
/// key: `FILE:LINE: MTL key `map_Kd` is not used (texture maps are not read)`).
pub fn read_library_noting(path: &Path) -> Result<(Vec<tobj::Material>, Vec<String>), SceneError> {
    let text =
        read_text_capped(path, MTL_CAP, "MTL files").map_err(|source| SceneError::MeshIo {
            file: path.to_path_buf(),
            source,
        })?;
    parse_library_noting(&text, path)
}

/// [`read_library`] of MTL text already read; `path` names the file in errors.
pub fn parse_library(text: &str, path: &Path) -> Result<Vec<tobj::Material>, SceneError> {
    Ok(parse_library_noting(text, path)?.0)
}

/// Why an MTL key is not used, or `None` for the keys the renderer reads (`newmtl`, `Ka`, `Kd`,
/// `Ks`, `Ns`, `illum`).
pub fn unused_reason(key: &str) -> Option<&'static str> {
    Some(match key {
        "newmtl" | "Ka" | "Kd" | "Ks" | "Ns" | "illum" => return None,
        _ if key.starts_with("map_")
            || matches!(key, "bump" | "disp" | "decal" | "refl" | "norm") =>
        {
            "texture maps are not read"
        }
        "d" | "Tr" | "Tf" | "Ni" => "transparency and refraction are not rendered",
        "Ke" => "emission is not rendered",
        "sharpness" => "reflection-map sharpness is not read",
        _ => "physically based MTL extensions are not rendered",
    })
}

/// [`parse_library`], with [`read_library_noting`]'s warnings.
pub fn parse_library_noting(
    text: &str,
    path: &Path,
) -> Result<(Vec<tobj::Material>, Vec<String>), SceneError> {
    let mut warned: Vec<String> = vec![];
    let mut warnings: Vec<String> = vec![];
    let mut out: Vec<tobj::Material> = vec![];
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let invalid = |key: &str, message: String| SceneError::Invalid {
            file: path.to_path_buf(),
            line,
            key: key.into(),
            message,
        };
        let l = raw.trim();
        let mut words = l.split_whitespace();
        let Some(key) = words.next() else { continue };
        if key.starts_with('#') {
            continue;
        }
        if key == "newmtl" {
            let name = l[6..].trim();
            if name.is_empty() {
                return Err(invalid(key, "needs a material name".into()));
            }
            out.push(tobj::Material {
                name: name.to_owned(),
                ..tobj::Material::default()
            });
            continue;
        }
        let number = |w: &str| -> Result<f64, SceneError> {
            let x: f64 = w
                .parse()
                .map_err(|_| invalid(key, format!("`{}` is not a number", clip(w))))?;
            if !x.is_finite() {
                return Err(invalid(key, format!("{x} is not a finite number")));
            }
            if x.abs() > f32::MAX as f64 {
                return Err(invalid(
                    key,
                    format!("{} does not fit a 32-bit float", short(x)),
                ));
            }
            if x < 0.0 {
                return Err(invalid(key, format!("{} must be ≥ 0", short(x))));
            }
            Ok(x)
        };
        let words: Vec<&str> = words.collect();
        let colour = || -> Result<[f64; 3], SceneError> {
            if matches!(words.first(), Some(&("spectral" | "xyz"))) {
                return Err(invalid(
                    key,
                    format!("{} colours are not supported (give r g b)", words[0]),
                ));
            }
            if words.is_empty() || words.len() > 3 {
                return Err(invalid(
                    key,
                    format!("needs 1 to 3 components, not {}", words.len()),
                ));
            }
            let r = number(words[0])?;
            let g = words.get(1).map_or(Ok(r), |w| number(w))?;
            let b = words.get(2).map_or(Ok(r), |w| number(w))?;
            Ok([r, g, b])
        };
        let scalar = || -> Result<f64, SceneError> {
            match words.as_slice() {
                [w] => number(w),
                _ => Err(invalid(
                    key,
                    format!("needs one number, not {}", words.len()),
                )),
            }
        };
        let textures = key.starts_with("map_")
            || matches!(
                key,
                "bump" | "disp" | "decal" | "refl" | "norm" | "sharpness"
            );
        let Some(m) = out.last_mut() else {
            return Err(invalid(key, "comes before any newmtl".into()));
        };
        match key {
            "Ka" => m.ambient = Some(colour()?),
            "Kd" => m.diffuse = Some(colour()?),
            "Ks" => m.specular = Some(colour()?),
            "Ke" => m.emissive = Some(colour()?),
            "Tf" => {
                colour()?;
            }
            "Ns" => m.shininess = Some(scalar()?),
            "d" => m.dissolve = Some(scalar()?),
            "Ni" => m.optical_density = Some(scalar()?),
            "Tr" | "Pr" | "Pm" | "Ps" | "Pc" | "Pcr" | "aniso" | "anisor" => {
                scalar()?;
            }
            "illum" => match words.as_slice() {
                [w] => match w.parse::<u8>() {
                    Ok(x) if x <= 10 => m.illumination_model = Some(x),
                    _ => {
                        return Err(invalid(
                            key,
                            format!("`{}` is not an illumination model 0–10", clip(w)),
                        ));
                    }
                },
                _ => return Err(invalid(key, "needs one integer 0–10".into())),
            },
            _ if textures => {}
            _ => {
                return Err(invalid(
                    &clip(key),
                    "not an MTL statement (is this an MTL file?)".into(),
                ));
            }
        }
        if let Some(reason) = unused_reason(key)
            && !warned.iter().any(|w| w == key)
        {
            warned.push(key.to_owned());
            warnings.push(format!(
                "{}:{line}: MTL key `{key}` is not used ({reason})",
                path.display()
            ));
        }
    }
    Ok((out, warnings))
}

/// Binds a glTF file's materials (`material = "gltf"`, SPEC §15) as [`bind`] binds an OBJ's MTL
/// libraries: every material of `gltf` ([`crate::mesh::gltf::materials`]) is appended to
/// `materials` (scene material `base + materials.len()` onwards), in file order. Primitives
/// without a material take `fallback`; without one, that is an error. Ignored textures are one
/// warning line.
pub fn bind_gltf(
    gltf: &Path,
    fallback: Option<u32>,
    base: u32,
    materials: &mut Vec<Material>,
) -> Result<MtlBinding, crate::mesh::MeshError> {
    let g = crate::mesh::gltf::materials(gltf)?;
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

/// [`read_library`] in the form tobj's OBJ loader takes: the materials and their indices by name
/// (a later material of the same name wins, as in tobj).
pub fn tobj_library(path: &Path) -> Result<MtlLibrary, SceneError> {
    let materials = read_library(path)?;
    let names = materials
        .iter()
        .enumerate()
        .map(|(i, m)| (m.name.clone(), i))
        .collect();
    Ok((materials, names))
}

/// What tobj's OBJ loader takes from a material library.
pub type MtlLibrary = (Vec<tobj::Material>, HashMap<String, usize>);

/// At most 24 characters of `w`, escaped: words of a binary file quoted in messages.
fn clip(w: &str) -> String {
    let s: String = w.chars().take(24).collect();
    s.escape_debug().to_string()
}

/// The warnings of loading `scene`: each mesh binding's ([`MtlBinding::warnings`]), then one
/// line per scene material that no primitive can use (for example one defined beside
/// `material = "mtl"`, whose faces take their MTL materials).
pub fn load_warnings(scene: &super::Scene) -> Vec<String> {
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
