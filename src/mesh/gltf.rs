//! glTF 2.0 meshes (SPEC §15): `.gltf` (JSON, with external or data-URI buffers) and `.glb`, read
//! by the `gltf` crate (JSON, validation, GLB container, scene graph, materials, cameras,
//! `KHR_lights_punctual`).
//!
//! Reads the file's bytes and the buffers it names (external files relative to it, through
//! [`crate::input::open_regular`], so a FIFO or device is refused; `data:` URIs decoded with
//! `base64`); writes an [`ObjMesh`]: every primitive of mode TRIANGLES of every node of the default
//! scene (depth first, children in file order, primitives in file order), its positions moved by
//! the node's world transform (composed in f64 from the file's values, then rounded to f32). The
//! accessors are sliced here with every offset, stride and count checked against its buffer view
//! and buffer (the crate's reader assumes a valid file), so a bad file is an error naming it and
//! the accessor, never a panic. Sparse accessors and quantized (non-float) positions are errors.

use std::path::Path;

use glam::{DMat3, DMat4, DQuat, DVec3};

use super::{MeshError, NO_MATERIAL, ObjMesh, ObjRead, area_weighted_normals, unit};

/// The error naming `path` with `message`.
pub(crate) fn fail(path: &Path, message: impl Into<String>) -> MeshError {
    MeshError::Format {
        path: path.to_path_buf(),
        message: format!("gltf: {}", message.into()),
    }
}

/// A parsed glTF file and its buffers' bytes (buffer `i` is `buffers[i]`).
pub(crate) struct GltfFile {
    /// The document.
    pub doc: ::gltf::Document,
    /// Every buffer's bytes, in order.
    pub buffers: Vec<Vec<u8>>,
}

/// Parses the glTF document in `bytes` (JSON or GLB) and checks it (the crate's validation:
/// indices in range, required extensions supported).
fn document(bytes: &[u8], path: &Path) -> Result<::gltf::Gltf, MeshError> {
    let invalid = |e: ::gltf::Error| {
        let text = e.to_string();
        let line: String = text
            .lines()
            .next()
            .unwrap_or("")
            .chars()
            .take(200)
            .collect();
        fail(path, format!("not a valid glTF 2.0 file: {line}"))
    };
    let unchecked = ::gltf::Gltf::from_slice_without_validation(bytes).map_err(invalid)?;
    let root = unchecked.document.into_json();
    // gltf-json 1.4.1's validation indexes a primitive's POSITION accessor before checking that
    // it exists (a panic on a bad file): check those indices first.
    for (mi, m) in root.meshes.iter().enumerate() {
        for (pi, p) in m.primitives.iter().enumerate() {
            for (semantic, index) in &p.attributes {
                if index.value() >= root.accessors.len() {
                    return Err(fail(
                        path,
                        format!(
                            "not a valid glTF 2.0 file: mesh {mi} primitive {pi}: attribute \
                             {semantic:?} names accessor {}, of {}",
                            index.value(),
                            root.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    let document = ::gltf::Document::from_json(root).map_err(invalid)?;
    Ok(::gltf::Gltf {
        document,
        blob: unchecked.blob,
    })
}

/// `%XX` escapes of a URI decoded; `None` when one is malformed or the result is not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Where a buffer's bytes are.
enum Place<'a> {
    /// The GLB file's binary chunk.
    Bin,
    /// A `data:` URI's payload (base64).
    Data(&'a str),
    /// A file relative to the glTF file's folder.
    File(std::path::PathBuf),
}

/// Where buffer `b` of the file `path` is.
fn place<'a>(b: &::gltf::Buffer<'a>, path: &Path) -> Result<Place<'a>, MeshError> {
    match b.source() {
        ::gltf::buffer::Source::Bin => Ok(Place::Bin),
        ::gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
            let (head, data) = uri.split_once(',').ok_or_else(|| {
                fail(
                    path,
                    format!("buffer {}: a data URI without data", b.index()),
                )
            })?;
            if !head.ends_with(";base64") {
                return Err(fail(
                    path,
                    format!("buffer {}: only base64 data URIs are read", b.index()),
                ));
            }
            Ok(Place::Data(data))
        }
        ::gltf::buffer::Source::Uri(uri) => {
            let name = percent_decode(uri).ok_or_else(|| {
                fail(path, format!("buffer {}: malformed URI {uri:?}", b.index()))
            })?;
            if name.contains("://") {
                return Err(fail(
                    path,
                    format!(
                        "buffer {}: only local files are read, not {name:?}",
                        b.index()
                    ),
                ));
            }
            let dir = path.parent().unwrap_or(Path::new(""));
            Ok(Place::File(dir.join(name)))
        }
    }
}

/// The bytes of the external file `file` (buffer `index` of `path`).
fn read_external(file: &Path, index: usize, path: &Path) -> Result<Vec<u8>, MeshError> {
    let read = || -> std::io::Result<Vec<u8>> {
        let (f, _) = crate::input::open_regular(file)?;
        let mut bytes = vec![];
        std::io::Read::read_to_end(&mut { f }, &mut bytes)?;
        Ok(bytes)
    };
    read().map_err(|e| {
        fail(
            path,
            format!("buffer {index}: cannot read {}: {e}", file.display()),
        )
    })
}

/// The bytes of every external buffer file of the glTF file `path` whose bytes are `bytes`, in
/// buffer order (for the tree cache's key: [`super::cache_sources`]).
pub(crate) fn external_buffers(bytes: &[u8], path: &Path) -> Result<Vec<Vec<u8>>, MeshError> {
    let gltf = document(bytes, path)?;
    let mut out = vec![];
    for b in gltf.buffers() {
        if let Place::File(file) = place(&b, path)? {
            out.push(read_external(&file, b.index(), path)?);
        }
    }
    Ok(out)
}

impl GltfFile {
    /// Parses the glTF file `path` whose bytes are `bytes` and reads its buffers; each must hold
    /// at least its declared `byteLength`.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<GltfFile, MeshError> {
        let mut gltf = document(bytes, path)?;
        let mut blob = gltf.blob.take();
        let mut buffers = Vec::with_capacity(gltf.buffers().len());
        for b in gltf.buffers() {
            let data = match place(&b, path)? {
                Place::Bin => match blob.take() {
                    Some(blob) => blob,
                    None => {
                        return Err(fail(
                            path,
                            format!(
                                "buffer {} refers to the GLB binary chunk, which is missing or \
                                 used by another buffer",
                                b.index()
                            ),
                        ));
                    }
                },
                Place::Data(data) => {
                    use base64::Engine as _;
                    base64::engine::general_purpose::STANDARD
                        .decode(data)
                        .map_err(|e| {
                            fail(path, format!("buffer {}: bad base64 data: {e}", b.index()))
                        })?
                }
                Place::File(file) => read_external(&file, b.index(), path)?,
            };
            if data.len() < b.length() {
                return Err(fail(
                    path,
                    format!(
                        "buffer {} holds {} bytes, less than its byteLength {}",
                        b.index(),
                        data.len(),
                        b.length()
                    ),
                ));
            }
            buffers.push(data);
        }
        Ok(GltfFile {
            doc: gltf.document,
            buffers,
        })
    }
}

/// The document of the glTF file `path`, checked, without its buffers (what materials, cameras
/// and lights are read from at scene load).
pub(crate) fn read_document(path: &Path) -> Result<::gltf::Document, MeshError> {
    let read = || -> std::io::Result<Vec<u8>> {
        let (f, _) = crate::input::open_regular(path)?;
        let mut bytes = vec![];
        std::io::Read::read_to_end(&mut { f }, &mut bytes)?;
        Ok(bytes)
    };
    let bytes = read().map_err(|source| MeshError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(document(&bytes, path)?.document)
}

/// The f64 matrix of a node's local transform (a TRS's rotation normalised).
fn local(node: &::gltf::Node, path: &Path) -> Result<DMat4, MeshError> {
    let m = match node.transform() {
        ::gltf::scene::Transform::Matrix { matrix } => {
            DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from)))
        }
        ::gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            let q = DQuat::from_array(rotation.map(f64::from));
            let len = q.length();
            if !(len > 0.0 && len.is_finite()) {
                return Err(fail(
                    path,
                    format!("node {}: rotation is not a valid quaternion", node.index()),
                ));
            }
            DMat4::from_scale_rotation_translation(
                DVec3::from_array(scale.map(f64::from)),
                q / len,
                DVec3::from_array(translation.map(f64::from)),
            )
        }
    };
    if !m.is_finite() {
        return Err(fail(
            path,
            format!("node {}: non-finite transform", node.index()),
        ));
    }
    Ok(m)
}

/// Calls `visit` with every node of the default scene (or the first scene) and its world
/// transform, depth first, children in file order. A node reached twice (a cycle, or a node with
/// two parents) is an error: the hierarchy must be a forest.
pub(crate) fn walk<'a>(
    doc: &'a ::gltf::Document,
    path: &Path,
    mut visit: impl FnMut(&::gltf::Node<'a>, &DMat4) -> Result<(), MeshError>,
) -> Result<(), MeshError> {
    let Some(scene) = doc.default_scene().or_else(|| doc.scenes().next()) else {
        return Err(fail(path, "the file has no scene"));
    };
    let mut seen = vec![false; doc.nodes().len()];
    let mut stack: Vec<(::gltf::Node<'a>, DMat4)> = scene
        .nodes()
        .map(|n| (n, DMat4::IDENTITY))
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(fail(
                path,
                format!(
                    "node {} is reached twice (the node hierarchy must be a tree)",
                    node.index()
                ),
            ));
        }
        let world = parent * local(&node, path)?;
        visit(&node, &world)?;
        let children: Vec<_> = node.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world));
        }
    }
    Ok(())
}

/// The bytes of accessor `a` as `(view bytes, first byte, stride, element size, count)`, every
/// range checked; `components` and `size` are the element's component count and component size.
fn slice<'b>(
    a: &::gltf::Accessor,
    buffers: &'b [Vec<u8>],
    path: &Path,
    size: usize,
    components: usize,
) -> Result<(&'b [u8], usize, usize, usize), MeshError> {
    let bad = |what: String| fail(path, format!("accessor {}: {what}", a.index()));
    if a.sparse().is_some() {
        return Err(bad("sparse accessors are not read".into()));
    }
    let Some(view) = a.view() else {
        return Err(bad("no bufferView (not read)".into()));
    };
    let buffer = &buffers[view.buffer().index()];
    let range = view
        .offset()
        .checked_add(view.length())
        .filter(|&end| end <= buffer.len())
        .map(|end| &buffer[view.offset()..end])
        .ok_or_else(|| {
            bad(format!(
                "bufferView {} reaches past the end of buffer {}",
                view.index(),
                view.buffer().index()
            ))
        })?;
    let element = size * components;
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(bad(format!(
            "byteStride {stride} is less than the element size {element}"
        )));
    }
    let count = a.count();
    if count > 0 {
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(element))
            .and_then(|x| x.checked_add(a.offset()));
        if end.is_none_or(|end| end > range.len()) {
            return Err(bad(format!(
                "{count} elements reach past the end of bufferView {}",
                view.index()
            )));
        }
    }
    Ok((range, a.offset(), stride, count))
}

/// Accessor `a` as f32 three-vectors (positions, normals), in f64.
fn vec3s(
    a: &::gltf::Accessor,
    buffers: &[Vec<u8>],
    path: &Path,
    what: &str,
) -> Result<Vec<[f64; 3]>, MeshError> {
    use ::gltf::accessor::{DataType, Dimensions};
    if a.data_type() != DataType::F32 || a.dimensions() != Dimensions::Vec3 || a.normalized() {
        return Err(fail(
            path,
            format!(
                "accessor {} ({what}): must be float VEC3, not {:?} {:?}",
                a.index(),
                a.data_type(),
                a.dimensions()
            ),
        ));
    }
    let (bytes, first, stride, count) = slice(a, buffers, path, 4, 3)?;
    Ok((0..count)
        .map(|i| {
            let at = first + i * stride;
            std::array::from_fn(|c| {
                let b = &bytes[at + 4 * c..at + 4 * c + 4];
                f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            })
        })
        .collect())
}

/// Accessor `a` as vertex indices (unsigned byte, short or int scalars).
fn indices(a: &::gltf::Accessor, buffers: &[Vec<u8>], path: &Path) -> Result<Vec<u32>, MeshError> {
    use ::gltf::accessor::{DataType, Dimensions};
    let size = match a.data_type() {
        DataType::U8 => 1,
        DataType::U16 => 2,
        DataType::U32 => 4,
        t => {
            return Err(fail(
                path,
                format!(
                    "accessor {} (indices): must be unsigned, not {t:?}",
                    a.index()
                ),
            ));
        }
    };
    if a.dimensions() != Dimensions::Scalar {
        return Err(fail(
            path,
            format!("accessor {} (indices): must be SCALAR", a.index()),
        ));
    }
    let (bytes, first, stride, count) = slice(a, buffers, path, size, 1)?;
    Ok((0..count)
        .map(|i| {
            let b = &bytes[first + i * stride..];
            match size {
                1 => u32::from(b[0]),
                2 => u32::from(u16::from_le_bytes([b[0], b[1]])),
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            }
        })
        .collect())
}

/// Reads the glTF file `path` whose bytes are `bytes` (see the module documentation): vertex
/// normals from `NORMAL` (moved by the inverse transpose of the node's transform) when `what`
/// asks for them, area-weighted where a primitive has none; per-triangle material indices (or
/// [`NO_MATERIAL`]) when it asks for materials.
pub fn parse(bytes: &[u8], path: &Path, what: ObjRead) -> Result<ObjMesh, MeshError> {
    let file = GltfFile::parse(bytes, path)?;
    mesh(&file, path, what)
}

/// [`parse`] of a file already parsed.
pub fn mesh(file: &GltfFile, path: &Path, what: ObjRead) -> Result<ObjMesh, MeshError> {
    let mut out = ObjMesh {
        path: path.to_path_buf(),
        ..ObjMesh::default()
    };
    walk(&file.doc, path, |node, world| {
        let Some(m) = node.mesh() else { return Ok(()) };
        for (pi, prim) in m.primitives().enumerate() {
            if prim.mode() != ::gltf::mesh::Mode::Triangles {
                continue;
            }
            let at = format!("mesh {} primitive {pi}", m.index());
            let Some(pos) = prim.get(&::gltf::Semantic::Positions) else {
                return Err(fail(path, format!("{at}: no POSITION attribute")));
            };
            let local = vec3s(&pos, &file.buffers, path, "POSITION")?;
            let n = local.len();
            let tris: Vec<u32> = match prim.indices() {
                Some(a) => indices(&a, &file.buffers, path)?,
                None => (0..n as u32).collect(),
            };
            if !tris.len().is_multiple_of(3) {
                return Err(fail(
                    path,
                    format!(
                        "{at}: {} indices is not a whole number of triangles",
                        tris.len()
                    ),
                ));
            }
            if let Some(&bad) = tris.iter().find(|&&i| i as usize >= n) {
                return Err(fail(
                    path,
                    format!("{at}: vertex index {bad} out of range ({n} vertices)"),
                ));
            }
            let base = out.positions.len();
            if base + n > u32::MAX as usize {
                return Err(fail(path, "more than 2^32 − 1 vertices"));
            }
            for p in &local {
                let w = world.transform_point3(DVec3::from_array(*p));
                let r = w.to_array().map(|c| c as f32);
                if !r.iter().all(|c| c.is_finite()) {
                    return Err(fail(
                        path,
                        format!("{at}: a vertex is not finite in f32 after its node's transform"),
                    ));
                }
                out.positions.push(r.map(f64::from));
            }
            let first = out.indices.len();
            out.indices.extend(
                tris.chunks_exact(3)
                    .map(|t| [t[0], t[1], t[2]].map(|i| i + base as u32)),
            );
            if what.normals {
                let given = match prim.get(&::gltf::Semantic::Normals) {
                    Some(a) => Some(vec3s(&a, &file.buffers, path, "NORMAL")?),
                    None => None,
                };
                let normal_matrix = DMat3::from_mat4(*world).inverse().transpose();
                match given {
                    Some(ns) if ns.len() == n && normal_matrix.is_finite() => out.normals.extend(
                        ns.iter()
                            .map(|v| unit((normal_matrix * DVec3::from(*v)).into())),
                    ),
                    _ => out.normals.extend(area_weighted_normals(
                        &out.positions,
                        &out.indices[first..],
                        base as u32,
                    )),
                }
            }
            if what.materials {
                let id = prim.material().index().map_or(NO_MATERIAL, |i| i as u32);
                out.face_materials.resize(out.indices.len(), id);
            }
        }
        Ok(())
    })?;
    Ok(out)
}
