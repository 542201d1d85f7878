//! PLY meshes (SPEC §15): ASCII, binary little-endian and binary big-endian, read by `ply-rs-bw`.
//!
//! Reads a PLY file's bytes; writes an [`ObjMesh`] whose positions are the `vertex` elements'
//! `x y z` (any scalar type, exactly as stored, in f64) and whose triangle `k` is the `k`-th
//! triangle in file order, each `face`'s `vertex_indices` (or `vertex_index`) polygon fanned from
//! its first corner as OBJ polygons are. Vertex normals are the file's `nx ny nz` when every vertex
//! has them, else area-weighted. Other elements and properties are read past. Errors name the file
//! and, where there is one, the line (ASCII) or the element (binary).

use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{ElementDef, Encoding, Property, PropertyAccess, PropertyAccessResult};

use super::{MeshError, ObjMesh, ObjRead, area_weighted_normals, unit};

/// A `vertex` element's position and normal.
#[derive(Default)]
struct Vertex {
    p: [f64; 3],
    n: [f64; 3],
}

/// The f64 value of a scalar property (`None` for lists).
fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(x) => x.into(),
        Property::UChar(x) => x.into(),
        Property::Short(x) => x.into(),
        Property::UShort(x) => x.into(),
        Property::Int(x) => x.into(),
        Property::UInt(x) => x.into(),
        Property::Float(x) => x.into(),
        Property::Double(x) => x,
        _ => return None,
    })
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let slot = match name {
            "x" => &mut self.p[0],
            "y" => &mut self.p[1],
            "z" => &mut self.p[2],
            "nx" => &mut self.n[0],
            "ny" => &mut self.n[1],
            "nz" => &mut self.n[2],
            _ => return PropertyAccessResult::Ignored,
        };
        match scalar(&property) {
            Some(x) => {
                *slot = x;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::UnsupportedType,
        }
    }
}

/// A `face` element's corners, as stored (signed, so a negative index is reported as written).
#[derive(Default)]
struct Face {
    corners: Vec<i64>,
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        if !matches!(name, "vertex_indices" | "vertex_index") {
            return PropertyAccessResult::Ignored;
        }
        self.corners = match property {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            _ => return PropertyAccessResult::UnsupportedType,
        };
        PropertyAccessResult::Set
    }
}

/// An element read past.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// The name of `def`'s index list property, if it has one.
fn index_property(def: &ElementDef) -> Option<&str> {
    ["vertex_indices", "vertex_index"]
        .into_iter()
        .find(|n| def.properties.contains_key(*n))
}

/// Reads the PLY file `path` whose bytes are `bytes` (see the module documentation).
pub fn parse(bytes: &[u8], path: &Path, what: ObjRead) -> Result<ObjMesh, MeshError> {
    let fail = |message: String| MeshError::Format {
        path: path.to_path_buf(),
        message,
    };
    if !bytes.starts_with(b"ply") {
        return Err(fail(
            "not a PLY file (it does not start with `ply`)".to_owned(),
        ));
    }
    let mut reader = Reader::new(bytes);
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| ply_error(path, &e, None))?;
    let ascii = header.encoding == Encoding::Ascii;
    // Lines up to and including `end_header` (ASCII files: the payload's first line follows).
    let header_lines = match bytes.windows(11).position(|w| w == b"end_header\n") {
        Some(at) => bytes[..at].iter().filter(|&&b| b == b'\n').count() + 1,
        None => 0,
    };
    let vertex_def = header
        .elements
        .get("vertex")
        .ok_or_else(|| fail("no `vertex` element in the header".to_owned()))?;
    for axis in ["x", "y", "z"] {
        if !vertex_def.properties.contains_key(axis) {
            return Err(fail(format!(
                "the `vertex` element has no `{axis}` property"
            )));
        }
    }
    let normals_given = ["nx", "ny", "nz"]
        .iter()
        .all(|n| vertex_def.properties.contains_key(*n));
    let mut vertices: Vec<Vertex> = vec![];
    let mut faces: Vec<Face> = vec![];
    // Line of the first `face` line (ASCII files): face `i` is on line `face_line + i`.
    let mut face_line = 0;
    for (name, def) in &header.elements {
        let element = |what: &str| format!("`{name}` element ({what})");
        match name.as_str() {
            "vertex" => {
                vertices = Parser::<Vertex>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(|e| ply_error(path, &e, Some(&element("vertices"))))?;
            }
            "face" => {
                if index_property(def).is_none() {
                    return Err(fail(
                        "the `face` element has no `vertex_indices` (or `vertex_index`) list"
                            .to_owned(),
                    ));
                }
                // Each element before it is one line of an ASCII file.
                face_line = header_lines
                    + header
                        .elements
                        .values()
                        .take_while(|d| d.name != "face")
                        .map(|d| d.count)
                        .sum::<usize>()
                    + 1;
                faces = Parser::<Face>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(|e| ply_error(path, &e, Some(&element("faces"))))?;
            }
            _ => {
                Parser::<Skip>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(|e| ply_error(path, &e, Some(&element("read past"))))?;
            }
        }
    }
    let n = vertices.len();
    let mut mesh = ObjMesh {
        path: path.to_path_buf(),
        ..ObjMesh::default()
    };
    if n > u32::MAX as usize {
        return Err(fail(format!("{n} vertices: at most 2^32 − 1 are read")));
    }
    for (i, v) in vertices.iter().enumerate() {
        // Coordinates must also be finite as f32 (the render frame's type).
        if !v.p.iter().all(|&c| (c as f32).is_finite()) {
            return Err(fail(format!(
                "vertex {i}: non-finite coordinate (or beyond the f32 range)"
            )));
        }
    }
    mesh.positions = vertices.iter().map(|v| v.p).collect();
    let at = |i: usize| {
        if ascii {
            format!("line {}: face {i}", face_line + i)
        } else {
            format!("face {i}")
        }
    };
    for (i, f) in faces.iter().enumerate() {
        if f.corners.len() < 3 {
            return Err(fail(format!(
                "{}: needs at least 3 vertices, not {}",
                at(i),
                f.corners.len()
            )));
        }
        if let Some(&bad) = f.corners.iter().find(|&&c| c < 0 || c as usize >= n) {
            return Err(fail(format!(
                "{}: vertex index {bad} out of range ({n} vertices)",
                at(i)
            )));
        }
        let c: Vec<u32> = f.corners.iter().map(|&c| c as u32).collect();
        for k in 2..c.len() {
            mesh.indices.push([c[0], c[k - 1], c[k]]);
        }
    }
    if what.normals {
        mesh.normals =
            if normals_given && vertices.iter().all(|v| v.n.iter().all(|c| c.is_finite())) {
                vertices.iter().map(|v| unit(v.n)).collect()
            } else {
                area_weighted_normals(&mesh.positions, &mesh.indices, 0)
            };
    }
    Ok(mesh)
}

/// `ply-rs-bw`'s error as one line naming the file, the line (when it gives one) and `element`.
fn ply_error(path: &Path, e: &ply_rs_bw::parser::ParseError, element: Option<&str>) -> MeshError {
    // Its messages may span lines and quote a whole data line: keep the innermost cause (after
    // the last `Error:`), clipped.
    let text = e.to_string();
    let text = match e.line() {
        Some(line) => text
            .strip_prefix(&format!("Line {line}: "))
            .unwrap_or(&text)
            .to_owned(),
        None => text,
    };
    let cause = text.rsplit("Error:").next().unwrap_or("");
    let cause = cause.split_whitespace().collect::<Vec<_>>().join(" ");
    let mut message = String::from("ply: ");
    if let Some(el) = element {
        message.push_str(&format!("in the {el}: "));
    }
    if text.contains("Error:") {
        message.push_str("bad data: ");
    }
    message.extend(cause.trim_end_matches('.').chars().take(200));
    // Control characters of a binary file are escaped, so the error stays one line.
    let message: String = message
        .chars()
        .flat_map(|c| {
            let escaped: Vec<char> = if c.is_control() {
                c.escape_default().collect()
            } else {
                vec![c]
            };
            escaped
        })
        .collect();
    match e.line() {
        Some(line) => MeshError::Parse {
            path: path.to_path_buf(),
            line,
            message,
        },
        None => MeshError::Format {
            path: path.to_path_buf(),
            message,
        },
    }
}
