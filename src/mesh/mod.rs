//! Triangle meshes: flat vertex and index arrays loaded from Wavefront OBJ, PLY (`ply`) and
//! glTF (`gltf`) files, told apart by extension in one place (`check_format`,
//! [`read_bytes`]).
//!
//! Reads OBJ text (checked line by line by `check_lines`, then parsed by `tobj`), writes a
//! [`TriangleMesh`] whose triangle `k` is the `k`-th face of the file (for PLY and glTF: the
//! `k`-th triangle in file order). Bad input is rejected here,
//! at load time, with errors naming file and line, so the kernels that read the mesh later never
//! see non-finite coordinates or bad indices — and a file that is not OBJ (binary bytes, a text
//! file of another kind) is an error at its first line that is not OBJ, never an empty mesh.
//! Line ends may be LF, CR LF or CR alone.

use std::borrow::Cow;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use glam::DVec3;
use thiserror::Error;

pub(crate) mod gltf;
pub mod mtl;
pub mod obj_fast;
pub(crate) mod ply;

pub use crate::geometry::mesh::TriangleMesh;

/// Errors from loading a mesh. Messages are lowercase and name the file and, where there is one,
/// the 1-based line.
#[derive(Debug, Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("cannot read mesh file {path}")]
    Read {
        /// File that failed.
        path: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A `v` line holds a NaN or infinite coordinate.
    #[error("{path}:{line}: non-finite vertex coordinate in `v` line")]
    NonFiniteVertex {
        /// File that failed.
        path: PathBuf,
        /// 1-based line number of the `v` line.
        line: usize,
    },
    /// An `f` line refers to a vertex that does not exist (at that point of the file).
    #[error(
        "{path}:{line}: face index {index} out of range ({count} vertices defined) in `f` line"
    )]
    FaceIndexOutOfRange {
        /// File that failed.
        path: PathBuf,
        /// 1-based line number of the `f` line.
        line: usize,
        /// The index as written in the file (1-based, or negative for relative indices).
        index: i64,
        /// Number of vertices defined before that line.
        count: usize,
    },
    /// A line could not be parsed.
    #[error("{path}:{line}: parse error: {message}")]
    Parse {
        /// File that failed.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// The mesh has no triangles, and its scene does not allow that.
    #[error(
        "{path}: the mesh has no triangles (set allow_empty = true in its [[mesh]] if that is meant)"
    )]
    Empty {
        /// File that failed.
        path: PathBuf,
    },
    /// The path names a mesh format this build does not read.
    #[error("{path}: {message}")]
    Format {
        /// File that failed.
        path: PathBuf,
        /// Which format, and what is read.
        message: String,
    },
    /// `tobj` rejected the file and the line scan could not locate the cause.
    #[error("{path}: obj error: {message}")]
    Obj {
        /// File that failed.
        path: PathBuf,
        /// `tobj`'s description.
        message: String,
    },
}

/// A mesh file format (SPEC §15), told by the file's extension ([`check_format`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Format {
    /// Wavefront OBJ (`.obj`), with its MTL libraries.
    Obj,
    /// PLY (`.ply`): ASCII or binary (`ply`).
    Ply,
    /// glTF 2.0 as JSON (`.gltf`) with external or data-URI buffers (`gltf`).
    Gltf,
    /// Binary glTF 2.0 (`.glb`) (`gltf`).
    Glb,
}

impl Format {
    /// The name used in messages (`OBJ`, `PLY`, `glTF`).
    pub fn name(self) -> &'static str {
        match self {
            Format::Obj => "OBJ",
            Format::Ply => "PLY",
            Format::Gltf | Format::Glb => "glTF",
        }
    }
}

/// The format of the mesh file `path` by its extension (any case): `.obj`, `.ply`, `.gltf` or
/// `.glb`; any other extension, or none, is an error naming the file. Every mesh read goes
/// through here ([`read_bytes`] dispatches on it).
pub(crate) fn check_format(path: &Path) -> Result<Format, MeshError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let message = match ext.as_deref() {
        Some("obj") => return Ok(Format::Obj),
        Some("ply") => return Ok(Format::Ply),
        Some("gltf") => return Ok(Format::Gltf),
        Some("glb") => return Ok(Format::Glb),
        Some(e) => format!("unknown mesh format .{e} (use .obj, .ply, .gltf or .glb)"),
        None => {
            "no extension: the mesh format is not known (use .obj, .ply, .gltf or .glb)".to_owned()
        }
    };
    Err(MeshError::Format {
        path: path.to_path_buf(),
        message,
    })
}

/// Reads the mesh file `path` whose bytes are `bytes`, in the format its extension names
/// (`check_format`): the one place where formats are told apart. OBJ goes through the fast
/// parser ([`crate::mesh::obj_fast`]) when `fast` and `what` asks for nothing but positions and faces,
/// else through tobj ([`ObjMesh::parse_with`]); PLY through `ply::parse`; glTF through
/// `gltf::parse` (which reads external buffers relative to `path`).
pub fn read_bytes(
    path: &Path,
    bytes: &[u8],
    what: ObjRead,
    fast: bool,
) -> Result<ObjMesh, MeshError> {
    match check_format(path)? {
        Format::Obj => {
            if fast
                && what == ObjRead::default()
                && let Some((positions, indices)) = crate::mesh::obj_fast::parse(bytes)
            {
                return Ok(ObjMesh {
                    path: path.to_path_buf(),
                    positions,
                    indices,
                    ..ObjMesh::default()
                });
            }
            let text = std::str::from_utf8(bytes).map_err(|_| MeshError::Read {
                path: path.to_path_buf(),
                source: std::io::Error::new(std::io::ErrorKind::InvalidData, "is not UTF-8 text"),
            })?;
            ObjMesh::parse_with(text, path, what)
        }
        Format::Ply => ply::parse(bytes, path, what),
        Format::Gltf | Format::Glb => gltf::parse(bytes, path, what),
    }
}

/// What the tree cache's key is made from for the mesh file `path` whose bytes are `bytes`: the
/// bytes themselves for OBJ; for the other formats a tag naming the format first (the same bytes
/// read as another format are another mesh), then the bytes, then, for glTF, every external
/// buffer's bytes (a `.gltf` file does not change when its `.bin` does).
pub(crate) fn cache_sources(path: &Path, bytes: &[u8]) -> Result<Vec<Vec<u8>>, MeshError> {
    let format = check_format(path)?;
    if format == Format::Obj {
        return Ok(vec![]);
    }
    let mut out = vec![format!("wavefront mesh format {format:?}").into_bytes()];
    if matches!(format, Format::Gltf | Format::Glb) {
        out.extend(gltf::external_buffers(bytes, path)?);
    }
    Ok(out)
}

/// The largest distance along an axis from a render frame's origin to a mesh vertex. The f32
/// watertight triangle test shears the vertices (each coordinate grows to at most 2M for
/// vertices within ±M), forms edge products (at most 8M²) and sums three of them times a
/// sheared depth (at most √3·M): about 42·M³, which overflows f32 (3.4e38) near M = 2e12 and
/// stays eight times below it at M = 1e12. A mesh beyond it is refused ([`ObjMesh::to_frame`])
/// rather than rendered with missing triangles.
pub const MAX_FRAME_COORDINATE: f64 = 1e12;

/// World positions `positions` (of the mesh file `path`, for errors) in the render frame whose
/// origin is `origin`: each `p − origin` in f64, rounded once to f32. A vertex farther than
/// [`MAX_FRAME_COORDINATE`] from `origin` along an axis is an error naming the file: the f32
/// triangle test would overflow on it and lose its triangles. The one conversion every load
/// path (direct, tree cache, tree file) makes.
pub(crate) fn frame_vertices(
    path: &Path,
    positions: &[[f64; 3]],
    origin: DVec3,
) -> Result<Vec<[f32; 3]>, MeshError> {
    use rayon::prelude::*;
    let far = positions
        .par_iter()
        .with_min_len(1 << 14)
        .map(|p| (DVec3::from_array(*p) - origin).abs().max_element())
        .reduce(
            || 0.0,
            |a, d| {
                if d.is_nan() || a.is_nan() {
                    f64::NAN
                } else {
                    a.max(d)
                }
            },
        );
    if far.is_nan() || far > MAX_FRAME_COORDINATE {
        return Err(MeshError::Obj {
            path: path.to_path_buf(),
            message: format!(
                "a vertex is {far:.2e} from the render frame's origin (the eye, or the mesh's \
                 centre) along an axis; beyond ±{} the f32 triangle test overflows (move the \
                 mesh or the eye closer)",
                crate::error::short(MAX_FRAME_COORDINATE)
            ),
        });
    }
    Ok(positions
        .par_iter()
        .with_min_len(1 << 14)
        .map(|p| (DVec3::from_array(*p) - origin).as_vec3().to_array())
        .collect())
}

/// Reading a [`TriangleMesh`] (the f32 mesh a tree is built over, defined with the geometry).
impl TriangleMesh {
    /// Loads an OBJ file in its own coordinates (see [`ObjMesh::read`]).
    pub fn load_obj(path: &Path) -> Result<TriangleMesh, MeshError> {
        ObjMesh::read(path)?.to_frame(DVec3::ZERO)
    }
}

/// A mesh file's triangles with the positions as written, in f64: what the render frame's f32
/// mesh ([`ObjMesh::to_frame`]) and the f64 oracle are both made from. Named for OBJ, its first
/// format; PLY and glTF files are read into it too ([`read_bytes`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjMesh {
    /// The file read.
    pub path: PathBuf,
    /// Vertex positions, as parsed (f64).
    pub positions: Vec<[f64; 3]>,
    /// Vertex indices of each triangle; triangle `k` is the `k`-th face of the file.
    pub indices: Vec<[u32; 3]>,
    /// Unit shading normal of each vertex ([`ObjRead::normals`]): the file's `vn`, or
    /// area-weighted face normals where a model has none. Empty unless asked for.
    pub normals: Vec<[f64; 3]>,
    /// Index of each triangle's MTL material in the order of the file's `mtllib` libraries (for
    /// glTF: its primitive's material index), or [`NO_MATERIAL`] for faces before any `usemtl`
    /// (primitives without a material) ([`ObjRead::materials`]). Empty unless asked for.
    pub face_materials: Vec<u32>,
}

/// What [`ObjMesh::read_with`] reads besides positions and faces.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObjRead {
    /// Per-vertex shading normals.
    pub normals: bool,
    /// Per-face materials: MTL (the `mtllib` files are read relative to the OBJ's folder) or
    /// glTF primitive materials.
    pub materials: bool,
}

/// [`ObjMesh::face_materials`] of a face before any `usemtl`.
pub const NO_MATERIAL: u32 = u32::MAX;

impl ObjMesh {
    /// The bounding box of the vertex positions, in f64; `(+∞, −∞)` without vertices.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.positions
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p.into()), hi.max(p.into()))
            })
    }

    /// Reads a mesh file in f64: an OBJ file through `tobj` (triangulated, single index, all
    /// models merged in file order, so triangle `k` is the `k`-th face of the file; polygons are
    /// fanned in place), a PLY or glTF file through its reader ([`read_bytes`]).
    ///
    /// Errors name the file and line: unreadable file, an extension that names no format this
    /// build reads, non-finite coordinates (the `v` line), face indices out of range (the `f`
    /// line), and parse errors.
    pub fn read(path: &Path) -> Result<ObjMesh, MeshError> {
        ObjMesh::read_with(path, ObjRead::default())
    }

    /// [`ObjMesh::read`], also reading what `what` asks for: vertex normals (`vn`, PLY `nx ny
    /// nz`, glTF `NORMAL`, or area-weighted ones for models without) and per-face materials
    /// (OBJ: tobj's MTL loader, a library that cannot be read is an error naming the OBJ file and
    /// its `mtllib` line; glTF: each primitive's material).
    pub fn read_with(path: &Path, what: ObjRead) -> Result<ObjMesh, MeshError> {
        if check_format(path)? == Format::Obj {
            // Checked as it streams, so a file that is not OBJ fails at its first bad line
            // without being read whole (a 2 GB sparse file of NULs fails at once, in bounded
            // memory).
            check_file(path, None)?;
            let text = crate::input::read_text(path).map_err(|source| MeshError::Read {
                path: path.to_path_buf(),
                source,
            })?;
            return ObjMesh::parse_checked(&unix_line_ends(&text), path, what);
        }
        let (file, _) = crate::input::open_regular(path).map_err(|source| MeshError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let mut bytes = vec![];
        std::io::Read::read_to_end(&mut { file }, &mut bytes).map_err(|source| {
            MeshError::Read {
                path: path.to_path_buf(),
                source,
            }
        })?;
        read_bytes(path, &bytes, what, false)
    }

    /// [`ObjMesh::read_with`] of OBJ text already read; `path` names the file in errors and
    /// anchors its `mtllib` files.
    pub fn parse_with(text: &str, path: &Path, what: ObjRead) -> Result<ObjMesh, MeshError> {
        let text = unix_line_ends(text);
        check_lines(&text, path)?;
        ObjMesh::parse_checked(&text, path, what)
    }

    /// [`ObjMesh::parse_with`] of text with Unix line ends whose lines [`check_lines`] passed.
    fn parse_checked(text: &str, path: &Path, what: ObjRead) -> Result<ObjMesh, MeshError> {
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        // The first library that cannot be read, with its error (naming the MTL file and line).
        let library_error = std::cell::RefCell::new(None);
        let loaded = tobj::load_obj_buf(&mut BufReader::new(text.as_bytes()), &options, |lib| {
            if !what.materials {
                return Err(tobj::LoadError::OpenFileFailed);
            }
            mtl::tobj_library(&dir.join(lib)).map_err(|e| {
                library_error
                    .borrow_mut()
                    .get_or_insert_with(|| crate::error::chain(&e));
                tobj::LoadError::MaterialParseError
            })
        });
        let invalid = |message: &str| MeshError::Obj {
            path: path.to_path_buf(),
            message: message.to_string(),
        };
        let models = match loaded {
            Ok((models, materials)) => {
                if what.materials
                    && let Err(e) = materials
                {
                    let message = library_error.take().unwrap_or_else(|| e.to_string());
                    return Err(mtl_error(text, path, &message));
                }
                if let Some(message) = library_error.take() {
                    return Err(mtl_error(text, path, &message));
                }
                models
            }
            Err(e) => return Err(invalid(&e.to_string())),
        };
        let mut mesh = ObjMesh {
            path: path.to_path_buf(),
            ..ObjMesh::default()
        };
        for model in &models {
            let m = &model.mesh;
            let base = mesh.positions.len() as u32;
            let first = mesh.indices.len();
            mesh.positions
                .extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
            mesh.indices.extend(
                m.indices
                    .chunks_exact(3)
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
            if what.normals {
                if m.normals.len() == m.positions.len() {
                    mesh.normals
                        .extend(m.normals.chunks_exact(3).map(|n| unit([n[0], n[1], n[2]])));
                } else {
                    mesh.normals.extend(area_weighted_normals(
                        &mesh.positions,
                        &mesh.indices[first..],
                        base,
                    ));
                }
            }
            if what.materials {
                let id = m.material_id.map_or(NO_MATERIAL, |i| i as u32);
                mesh.face_materials.resize(mesh.indices.len(), id);
            }
        }
        let n = mesh.positions.len();
        // Coordinates must also be finite as f32 (the render frame's type).
        let finite = mesh
            .positions
            .iter()
            .flatten()
            .all(|&c| (c as f32).is_finite());
        let in_range = mesh.indices.iter().flatten().all(|&i| (i as usize) < n);
        if !finite || !in_range {
            return Err(invalid("invalid vertex data"));
        }
        Ok(mesh)
    }

    /// The vertices' shading normals as f32 (empty when not read).
    pub(crate) fn normals_f32(&self) -> Vec<[f32; 3]> {
        self.normals.iter().map(|n| n.map(|c| c as f32)).collect()
    }

    /// The mesh in a render frame whose origin is `origin` (world coordinates): each position
    /// `p − origin` computed in f64, then rounded once to f32. A vertex farther than
    /// [`MAX_FRAME_COORDINATE`] from `origin` along an axis is an error: the f32 triangle test
    /// would overflow on it and lose its triangles.
    pub fn to_frame(&self, origin: DVec3) -> Result<TriangleMesh, MeshError> {
        let vertices = frame_vertices(&self.path, &self.positions, origin)?;
        Ok(TriangleMesh {
            vertices,
            indices: self.indices.clone(),
        })
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// True when the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }
}

/// `v / |v|`, or zero for a zero vector.
fn unit(v: [f64; 3]) -> [f64; 3] {
    let d = DVec3::from(v);
    let l = d.length();
    if l > 0.0 && l.is_finite() {
        (d / l).to_array()
    } else {
        [0.0; 3]
    }
}

/// Unit area-weighted normals of the vertices `base..` used by `faces` (each face adds its
/// unnormalised cross product, whose length is twice its area, to its three vertices).
fn area_weighted_normals(positions: &[[f64; 3]], faces: &[[u32; 3]], base: u32) -> Vec<[f64; 3]> {
    let mut sum = vec![DVec3::ZERO; positions.len() - base as usize];
    for f in faces {
        let [a, b, c] = f.map(|i| DVec3::from(positions[i as usize]));
        let n = (b - a).cross(c - a);
        for &i in f {
            sum[(i - base) as usize] += n;
        }
    }
    sum.into_iter().map(|n| unit(n.to_array())).collect()
}

/// The error for an MTL library that could not be read: the OBJ file and its first `mtllib`
/// line.
fn mtl_error(text: &str, path: &Path, message: &str) -> MeshError {
    let line = text
        .lines()
        .position(|l| l.trim_start().starts_with("mtllib"))
        .map_or(1, |i| i + 1);
    MeshError::Parse {
        path: path.to_path_buf(),
        line,
        message: format!("cannot read its material library: {message}"),
    }
}

/// `text` with every line end as LF: a CR not followed by LF (classic Mac line ends) becomes LF,
/// so a CR-only file is read line by line instead of as one line.
pub(crate) fn unix_line_ends(text: &str) -> Cow<'_, str> {
    let b = text.as_bytes();
    let lone = |i: usize| b[i] == b'\r' && b.get(i + 1) != Some(&b'\n');
    if !(0..b.len()).any(lone) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\r' && chars.peek() != Some(&'\n') {
            out.push('\n');
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// OBJ statements this reader skips (free-form geometry, display and render attributes).
const SKIPPED: &[&str] = &[
    "vp",
    "cstype",
    "deg",
    "bmat",
    "step",
    "curv",
    "curv2",
    "surf",
    "parm",
    "trim",
    "hole",
    "scrv",
    "sp",
    "end",
    "con",
    "mg",
    "bevel",
    "c_interp",
    "d_interp",
    "lod",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "maplib",
    "usemap",
    "call",
    "csh",
];

/// Checks every line of OBJ text (LF line ends, [`unix_line_ends`]): `v` has 3 to 7 numbers whose
/// first three are finite and fit an f32; `vt` 1 to 3 numbers, `vn` 3; `f` at least 3 corners, `l`
/// at least 2 and `p` at least 1, each corner `v`, `v/vt`, `v//vn` or `v/vt/vn` with indices
/// (1-based, or negative: relative) of elements defined before the line; `o`, `g`, `s`, `mtllib`,
/// `usemtl`, comments and the free-form statements (`SKIPPED`) pass. Anything else is not OBJ:
/// the error names the file and line. Continuation lines (a trailing `\`) are joined first, as
/// tobj joins them.
pub(crate) fn check_lines(text: &str, path: &Path) -> Result<(), MeshError> {
    let mut check = LineCheck::new(path);
    for (i, raw) in text.lines().enumerate() {
        check.line(i + 1, raw)?;
    }
    Ok(())
}

/// Longest line [`check_file`] holds: a longer one is checked by its first `MAX_LINE` bytes and
/// is an error if they pass (no OBJ line is that long; a binary file's "line" may be gigabytes).
const MAX_LINE: usize = 16 << 20;

/// [`check_lines`] of the OBJ file `path` as it streams, in bounded memory: lines end at `\n`,
/// `\r\n` or a lone `\r` (numbered as [`unix_line_ends`] numbers them), and each must be UTF-8.
/// With `prefix`, only the lines within its first `prefix` bytes are checked (a quick look before
/// a file is read whole). A PLY or glTF file passes: its own reader checks it.
pub(crate) fn check_file(path: &Path, prefix: Option<u64>) -> Result<(), MeshError> {
    if check_format(path)? != Format::Obj {
        return Ok(());
    }
    let (file, _) = crate::input::open_regular(path).map_err(|source| MeshError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    check_stream(path, file, prefix)
}

/// [`check_file`] of the bytes of `path` already read (`bytes`): the same lines checked, the
/// same errors.
pub(crate) fn check_bytes(path: &Path, bytes: &[u8], prefix: Option<u64>) -> Result<(), MeshError> {
    if check_format(path)? != Format::Obj {
        return Ok(());
    }
    check_stream(path, bytes, prefix)
}

/// [`check_file`] of OBJ text streamed from `reader` (the file `path`).
fn check_stream(
    path: &Path,
    reader: impl std::io::Read,
    prefix: Option<u64>,
) -> Result<(), MeshError> {
    use std::io::Read as _;
    let read_error = |source| MeshError::Read {
        path: path.to_path_buf(),
        source,
    };
    let mut file = reader.take(prefix.unwrap_or(u64::MAX));
    let mut check = LineCheck::new(path);
    let mut chunk = vec![0u8; prefix.map_or(1 << 20, |p| p.min(1 << 20) as usize)];
    let mut line: Vec<u8> = Vec::new();
    let mut line_no = 0usize;
    let mut after_cr = false;
    let run = |line: &[u8], line_no: usize, check: &mut LineCheck| {
        let text = std::str::from_utf8(line).map_err(|_| MeshError::Parse {
            path: path.to_path_buf(),
            line: line_no,
            message: "not UTF-8 text: is this an OBJ file?".to_string(),
        })?;
        check.line(line_no, text)
    };
    loop {
        let n = match file.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(read_error(e)),
        };
        for &b in &chunk[..n] {
            if b == b'\n' && after_cr {
                after_cr = false; // the `\n` of a `\r\n`
                continue;
            }
            after_cr = b == b'\r';
            if b == b'\n' || b == b'\r' {
                line_no += 1;
                run(&line, line_no, &mut check)?;
                line.clear();
            } else if line.len() < MAX_LINE {
                line.push(b);
            } else {
                // Too long: its start is checked as a line; if that passes, the length is the
                // error.
                let mut end = MAX_LINE;
                while std::str::from_utf8(&line[..end]).is_err() && end > MAX_LINE - 4 {
                    end -= 1;
                }
                run(&line[..end], line_no + 1, &mut check)?;
                return Err(MeshError::Parse {
                    path: path.to_path_buf(),
                    line: line_no + 1,
                    message: format!(
                        "line longer than {}: is this an OBJ file?",
                        crate::input::size(MAX_LINE as u64)
                    ),
                });
            }
        }
    }
    if prefix.is_none() {
        if !line.is_empty() {
            run(&line, line_no + 1, &mut check)?;
        }
        return Ok(());
    }
    // A prefix may have cut the last line: only its first word is checked, when it is whole
    // (followed by a space) or longer than any OBJ keyword (a file of NULs has no line end).
    let text = String::from_utf8_lossy(&line);
    if let Some(key) = text.split_whitespace().next()
        && (text.trim_start().len() > key.len() || key.len() > 64)
        && !known_key(key)
    {
        return Err(MeshError::Parse {
            path: path.to_path_buf(),
            line: line_no + 1,
            message: not_obj(key),
        });
    }
    Ok(())
}

/// True for the first word of a line [`check_lines`] knows (elements, groups, materials,
/// comments, free-form statements).
fn known_key(key: &str) -> bool {
    matches!(
        key,
        "v" | "vt" | "vn" | "f" | "l" | "p" | "o" | "g" | "s" | "mtllib" | "usemtl"
    ) || key.starts_with('#')
        || SKIPPED.contains(&key)
}

/// The message of a line starting with `key`, which is not OBJ.
fn not_obj(key: &str) -> String {
    format!(
        "not an OBJ line (it starts with `{}`): is this an OBJ file?",
        clip(key)
    )
}

/// The state of [`check_lines`] between lines (elements defined so far, a continued line), so
/// that [`check_file`] runs the same check on lines as they stream.
struct LineCheck<'p> {
    path: &'p Path,
    nv: usize,
    nvt: usize,
    nvn: usize,
    joined: String,
    first_line: usize,
}

impl<'p> LineCheck<'p> {
    fn new(path: &'p Path) -> LineCheck<'p> {
        LineCheck {
            path,
            nv: 0,
            nvt: 0,
            nvn: 0,
            joined: String::new(),
            first_line: 0,
        }
    }

    /// Checks line `line_no` (1-based) whose text, without its line end, is `raw`.
    fn line(&mut self, line_no: usize, raw: &str) -> Result<(), MeshError> {
        let LineCheck {
            path,
            nv,
            nvt,
            nvn,
            joined,
            first_line,
        } = self;
        let path: &Path = path;
        if joined.is_empty() {
            *first_line = line_no;
        }
        if let Some(head) = raw.strip_suffix('\\') {
            joined.push_str(head);
            joined.push(' ');
            return Ok(());
        }
        let l: Cow<str> = if joined.is_empty() {
            Cow::Borrowed(raw)
        } else {
            joined.push_str(raw);
            Cow::Owned(std::mem::take(joined))
        };
        let line = *first_line;
        let parse = |message: String| MeshError::Parse {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut words = l.split_whitespace();
        let Some(key) = words.next() else {
            return Ok(());
        };
        if key.starts_with('#') {
            return Ok(());
        }
        let numbers = |words: std::str::SplitWhitespace, lo: usize, hi: usize| {
            let mut xs = Vec::with_capacity(hi);
            for w in words {
                match w.parse::<f64>() {
                    Ok(x) => xs.push(x),
                    Err(_) => {
                        return Err(parse(format!("bad number `{}` in `{key}` line", clip(w))));
                    }
                }
            }
            if xs.len() < lo || xs.len() > hi {
                let want = if lo == hi {
                    format!("{lo}")
                } else {
                    format!("{lo} to {hi}")
                };
                return Err(parse(format!(
                    "`{key}` line needs {want} numbers, not {}",
                    xs.len()
                )));
            }
            Ok(xs)
        };
        match key {
            "v" => {
                let xs = numbers(words, 3, 7)?;
                if !xs[..3].iter().all(|&x| (x as f32).is_finite()) {
                    return Err(MeshError::NonFiniteVertex {
                        path: path.to_path_buf(),
                        line,
                    });
                }
                *nv += 1;
            }
            "vt" => {
                numbers(words, 1, 3)?;
                *nvt += 1;
            }
            "vn" => {
                numbers(words, 3, 3)?;
                *nvn += 1;
            }
            "f" | "l" | "p" => {
                let mut corners = 0;
                for w in words {
                    corners += 1;
                    let parts: Vec<&str> = w.split('/').collect();
                    if parts.len() > 3 || parts[0].is_empty() {
                        return Err(parse(format!("bad corner `{}` in `{key}` line", clip(w))));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let (count, what) = [
                            (*nv, "vertices"),
                            (*nvt, "texture coordinates"),
                            (*nvn, "normals"),
                        ][k];
                        let index: i64 = part.parse().map_err(|_| {
                            parse(format!("bad index `{}` in `{key}` line", clip(w)))
                        })?;
                        let resolved = if index < 0 {
                            count as i64 + index
                        } else {
                            index - 1
                        };
                        if index == 0 || resolved < 0 || resolved >= count as i64 {
                            if k == 0 {
                                return Err(MeshError::FaceIndexOutOfRange {
                                    path: path.to_path_buf(),
                                    line,
                                    index,
                                    count,
                                });
                            }
                            return Err(parse(format!(
                                "{} index {index} out of range ({count} {what} defined) in `{key}` line",
                                ["vertex", "texture coordinate", "normal"][k]
                            )));
                        }
                    }
                }
                let least = match key {
                    "f" => 3,
                    "l" => 2,
                    _ => 1,
                };
                if corners < least {
                    return Err(parse(format!(
                        "`{key}` line needs at least {least} vertices, not {corners}"
                    )));
                }
            }
            "o" | "g" | "s" | "mtllib" | "usemtl" => {}
            _ if SKIPPED.contains(&key) => {}
            _ => return Err(parse(not_obj(key))),
        }
        Ok(())
    }
}

/// At most 24 characters of `w`, escaped (words of a binary file quoted in messages).
fn clip(w: &str) -> String {
    let s: String = w.chars().take(24).collect();
    s.escape_debug().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn temp_obj(name: &str, text: &str) -> PathBuf {
        let path = std::env::temp_dir().join(format!(
            "wavefront-mesh-{}-{}.obj",
            std::process::id(),
            name
        ));
        std::fs::write(&path, text).expect("write temp obj");
        path
    }

    /// The streaming check gives what the whole-text check gives, line numbers included, for
    /// every kind of line end and for continued lines.
    #[test]
    fn the_streaming_check_agrees_with_the_whole_text_check() {
        let texts = [
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 4\r\n",
            "v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\rbad line\r",
            "v 0 0 0\r\rv 1 0 \\\n0\nv 0 1 0\nf 1 2 3\nf 1 2",
            "# c\n\nv 0 0 nan\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3",
        ];
        for (k, text) in texts.iter().enumerate() {
            let path = temp_obj(&format!("stream-{k}"), text);
            let whole = check_lines(&unix_line_ends(text), &path).map_err(|e| e.to_string());
            let streamed = check_file(&path, None).map_err(|e| e.to_string());
            assert_eq!(streamed, whole, "{text:?}");
            std::fs::remove_file(&path).ok();
        }
        // A prefix: the cut last line is not judged unless its first word is whole.
        let path = temp_obj("prefix", "v 0 0 0\nv 1.25 0 0\n");
        assert!(check_file(&path, Some(12)).is_ok());
        let path2 = temp_obj("prefix-bad", "v 0 0 0\nwhat is this\n");
        let e = check_file(&path2, Some(14))
            .expect_err("not OBJ")
            .to_string();
        assert!(e.contains(":2:") && e.contains("not an OBJ line"), "{e}");
        std::fs::remove_file(&path).ok();
        std::fs::remove_file(&path2).ok();
    }

    #[test]
    fn loads_faces_in_file_order_with_triangulation() {
        let path = temp_obj(
            "order",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\no second\nf 1 2 3 4\nf 4 3 2\n",
        );
        let mesh = TriangleMesh::load_obj(&path).expect("loads");
        let _ = std::fs::remove_file(&path);
        assert_eq!(mesh.len(), 3);
        assert_eq!(mesh.triangle(2)[0], Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(mesh.bounds(), (Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)));
        assert_eq!(mesh.geometric_normal(0), Vec3::new(0.0, 0.0, 1.0));
    }

    #[test]
    fn nan_vertex_names_file_and_line() {
        let path = temp_obj("nan", "v 0 0 0\nv 1 0 0\n# c\nv nan 1 0\nf 1 2 3\n");
        let err = TriangleMesh::load_obj(&path).expect_err("nan rejected");
        let _ = std::fs::remove_file(&path);
        let msg = err.to_string();
        assert!(
            matches!(err, MeshError::NonFiniteVertex { line: 4, .. }),
            "{msg}"
        );
        assert!(msg.contains(&format!("{}:4:", path.display())), "{msg}");
    }

    #[test]
    fn out_of_range_face_names_file_and_line() {
        let path = temp_obj("range", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 9\n");
        let err = TriangleMesh::load_obj(&path).expect_err("bad face rejected");
        let _ = std::fs::remove_file(&path);
        let msg = err.to_string();
        assert!(
            matches!(
                err,
                MeshError::FaceIndexOutOfRange {
                    line: 5,
                    index: 9,
                    ..
                }
            ),
            "{msg}"
        );
        assert!(msg.contains(&format!("{}:5:", path.display())), "{msg}");
    }

    #[test]
    fn missing_file_names_the_file() {
        let path = std::env::temp_dir().join("wavefront-definitely-missing.obj");
        let err = TriangleMesh::load_obj(&path).expect_err("missing");
        assert!(matches!(err, MeshError::Read { .. }));
        assert!(err.to_string().contains(&path.display().to_string()));
    }

    #[test]
    fn garbage_coordinate_is_a_parse_error_with_line() {
        let path = temp_obj("garbage", "v 0 0 0\nv 1 x 0\nv 1 1 0\nf 1 2 3\n");
        let err = TriangleMesh::load_obj(&path).expect_err("garbage rejected");
        let _ = std::fs::remove_file(&path);
        assert!(matches!(err, MeshError::Parse { line: 2, .. }), "{err}");
    }

    #[test]
    fn collinear_triangle_is_degenerate() {
        let mesh = TriangleMesh::new(
            vec![[0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2], [0, 1, 3], [1, 1, 3]],
        );
        assert!(mesh.is_degenerate(0));
        assert!(!mesh.is_degenerate(1));
        assert!(mesh.is_degenerate(2));
    }
}
