//! MTL material libraries (SPEC §12): this crate's strict reader, giving tobj's `Material` rows
//! (name, `Ka`, `Kd`, `Ks`, `Ns`, `illum`) that the OBJ reader takes and that
//! [`crate::scene::mtl`] binds to a scene's materials.

use std::collections::HashMap;
use std::path::Path;

use crate::error::{SceneError, short};
use crate::input::{MTL_CAP, read_text_capped};

/// Reads the MTL library at `path` (a regular file of at most [`MTL_CAP`] bytes): its materials
/// in file order, as tobj's `Material` (name, `Ka`, `Kd`, `Ks`, `Ns`, `illum`). Colours take one
/// to three components (g and b default to r); every number must be finite, non-negative and fit
/// an f32; `illum` is an integer 0–10; texture maps and other known statements are skipped; a
/// statement before any `newmtl`, an unknown keyword, or a spectral or CIE XYZ colour is an error
/// naming the file and line. A file that cannot be read is [`SceneError::MeshIo`].
pub(crate) fn read_library(path: &Path) -> Result<Vec<tobj::Material>, SceneError> {
    Ok(read_library_noting(path)?.0)
}

/// [`read_library`], with one warning line for every key the renderer does not use (once per
/// key: `FILE:LINE: MTL key `map_Kd` is not used (texture maps are not read)`).
pub(crate) fn read_library_noting(
    path: &Path,
) -> Result<(Vec<tobj::Material>, Vec<String>), SceneError> {
    let text =
        read_text_capped(path, MTL_CAP, "MTL files").map_err(|source| SceneError::MeshIo {
            file: path.to_path_buf(),
            source,
        })?;
    parse_library_noting(&text, path)
}

/// `read_library` of MTL text already read; `path` names the file in errors.
pub fn parse_library(text: &str, path: &Path) -> Result<Vec<tobj::Material>, SceneError> {
    Ok(parse_library_noting(text, path)?.0)
}

/// Why an MTL key is not used, or `None` for the keys the renderer reads (`newmtl`, `Ka`, `Kd`,
/// `Ks`, `Ns`, `illum`).
pub(crate) fn unused_reason(key: &str) -> Option<&'static str> {
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
pub(crate) fn parse_library_noting(
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

/// [`read_library`] in the form tobj's OBJ loader takes: the materials and their indices by name
/// (a later material of the same name wins, as in tobj).
pub(crate) fn tobj_library(path: &Path) -> Result<MtlLibrary, SceneError> {
    let materials = read_library(path)?;
    let names = materials
        .iter()
        .enumerate()
        .map(|(i, m)| (m.name.clone(), i))
        .collect();
    Ok((materials, names))
}

/// What tobj's OBJ loader takes from a material library.
pub(crate) type MtlLibrary = (Vec<tobj::Material>, HashMap<String, usize>);

/// At most 24 characters of `w`, escaped: words of a binary file quoted in messages.
fn clip(w: &str) -> String {
    let s: String = w.chars().take(24).collect();
    s.escape_debug().to_string()
}
