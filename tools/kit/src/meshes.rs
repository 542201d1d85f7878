//! Small test meshes made in code and written in every mesh format the renderer reads (OBJ, PLY
//! ASCII / binary little- and big-endian, glTF with a data URI or an external buffer, GLB), so
//! the format tests compare one set of faces across formats without downloaded data.
//!
//! Positions are f32 values; the OBJ text writes each as the f64 it is exactly (Rust's shortest
//! round-trip form of that f64), so every format holds bit-identical coordinates.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A polygon mesh: f32 positions and polygons (3 or more vertex indices each, 0-based).
#[derive(Clone, Debug, PartialEq)]
pub struct PolyMesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Polygons, each fanned from its first corner by the readers.
    pub polygons: Vec<Vec<u32>>,
}

/// PLY payload encodings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `format ascii 1.0`.
    Ascii,
    /// `format binary_little_endian 1.0`.
    LittleEndian,
    /// `format binary_big_endian 1.0`.
    BigEndian,
}

impl PolyMesh {
    /// A bumpy, closed-ish test object: a `n × n` grid of quads on a wavy height field whose
    /// rim has a pentagon and a few triangles, with coordinates that are not short decimals
    /// (thirds, sevenths) so that text and binary forms must agree bit for bit.
    pub fn bumpy(n: u32) -> PolyMesh {
        let mut positions = vec![];
        for j in 0..=n {
            for i in 0..=n {
                let (x, z) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
                let y = 0.15 * ((7.0 * x).sin() * (5.0 * z).cos()) + x * z / 3.0;
                positions.push([x * 2.0 + 0.1, y, z * 2.0 - 0.2]);
            }
        }
        let id = |i: u32, j: u32| j * (n + 1) + i;
        let mut polygons = vec![];
        for j in 0..n {
            for i in 0..n {
                let q = vec![id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j)];
                if (i + j) % 5 == 0 {
                    polygons.push(vec![q[0], q[1], q[2]]);
                    polygons.push(vec![q[0], q[2], q[3]]);
                } else {
                    polygons.push(q);
                }
            }
        }
        // A pentagon lid over one corner, above the field.
        let base = positions.len() as u32;
        for k in 0..5 {
            let a = k as f32 * std::f32::consts::TAU / 5.0;
            positions.push([0.3 * a.cos(), 0.4, 0.3 * a.sin() / 7.0 * 3.0]);
        }
        polygons.push((base..base + 5).collect());
        PolyMesh {
            positions,
            polygons,
        }
    }

    /// The triangles a reader makes: each polygon fanned from its first corner, in order.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = vec![];
        for p in &self.polygons {
            for k in 2..p.len() {
                out.push([p[0], p[k - 1], p[k]]);
            }
        }
        out
    }

    /// The OBJ text (`v` lines with each f32 written as its exact f64, `f` lines 1-based).
    pub fn obj(&self) -> String {
        let mut s = String::from("# test mesh\n");
        for p in &self.positions {
            let [x, y, z] = p.map(f64::from);
            let _ = writeln!(s, "v {x:?} {y:?} {z:?}");
        }
        for f in &self.polygons {
            s.push('f');
            for i in f {
                let _ = write!(s, " {}", i + 1);
            }
            s.push('\n');
        }
        s
    }

    /// The PLY file (`float` x y z, `uchar int` vertex_indices lists).
    pub fn ply(&self, encoding: PlyEncoding) -> Vec<u8> {
        let format = match encoding {
            PlyEncoding::Ascii => "ascii",
            PlyEncoding::LittleEndian => "binary_little_endian",
            PlyEncoding::BigEndian => "binary_big_endian",
        };
        let mut out = format!(
            "ply\nformat {format} 1.0\ncomment made by wavefront-kit\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            self.positions.len(),
            self.polygons.len()
        )
        .into_bytes();
        match encoding {
            PlyEncoding::Ascii => {
                let mut s = String::new();
                for p in &self.positions {
                    let _ = writeln!(s, "{:?} {:?} {:?}", p[0], p[1], p[2]);
                }
                for f in &self.polygons {
                    s.push_str(&f.len().to_string());
                    for i in f {
                        let _ = write!(s, " {i}");
                    }
                    s.push('\n');
                }
                out.extend(s.into_bytes());
            }
            PlyEncoding::LittleEndian | PlyEncoding::BigEndian => {
                let le = encoding == PlyEncoding::LittleEndian;
                for p in &self.positions {
                    for c in p {
                        out.extend(if le { c.to_le_bytes() } else { c.to_be_bytes() });
                    }
                }
                for f in &self.polygons {
                    out.push(f.len() as u8);
                    for &i in f {
                        let i = i as i32;
                        out.extend(if le { i.to_le_bytes() } else { i.to_be_bytes() });
                    }
                }
            }
        }
        out
    }

    /// The binary buffer of the glTF forms: positions (f32 VEC3) then the triangles' indices
    /// (u32), each 4-byte aligned.
    fn gltf_buffer(&self) -> Vec<u8> {
        let mut b = vec![];
        for p in &self.positions {
            for c in p {
                b.extend(c.to_le_bytes());
            }
        }
        for t in self.triangles() {
            for i in t {
                b.extend(i.to_le_bytes());
            }
        }
        b
    }

    /// The glTF JSON whose one buffer is at `uri` (`None`: the GLB binary chunk), with one node
    /// holding the mesh under a parent node whose `matrix` (column-major) is `matrix`, and a
    /// material.
    fn gltf_json(&self, uri: Option<&str>, matrix: Option<[f64; 16]>) -> String {
        let n = self.positions.len();
        let t = self.triangles().len();
        let (lo, hi) = self.positions.iter().fold(
            ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    std::array::from_fn(|i| lo[i].min(p[i])),
                    std::array::from_fn(|i| hi[i].max(p[i])),
                )
            },
        );
        let len = self.gltf_buffer().len();
        let uri = uri.map_or(String::new(), |u| format!(r#""uri": "{u}", "#));
        let matrix = matrix.map_or(String::new(), |m| {
            let m: Vec<String> = m.iter().map(|x| format!("{x:?}")).collect();
            format!(r#""matrix": [{}], "#, m.join(", "))
        });
        format!(
            r#"{{
  "asset": {{"version": "2.0", "generator": "wavefront-kit"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [{{{matrix}"children": [1]}}, {{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "materials": [{{"name": "paint", "pbrMetallicRoughness": {{"baseColorFactor": [0.8, 0.6, 0.4, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5}}}}],
  "buffers": [{{{uri}"byteLength": {len}}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": {pl}}},
    {{"buffer": 0, "byteOffset": {pl}, "byteLength": {il}}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": {n}, "type": "VEC3", "min": [{l0:?}, {l1:?}, {l2:?}], "max": [{h0:?}, {h1:?}, {h2:?}]}},
    {{"bufferView": 1, "componentType": 5125, "count": {ic}, "type": "SCALAR"}}
  ]
}}
"#,
            pl = n * 12,
            il = t * 12,
            ic = t * 3,
            l0 = lo[0],
            l1 = lo[1],
            l2 = lo[2],
            h0 = hi[0],
            h1 = hi[1],
            h2 = hi[2],
        )
    }

    /// A `.gltf` file whose buffer is a base64 data URI; `matrix` as for [`PolyMesh::gltf_files`].
    pub fn gltf_embedded(&self, matrix: Option<[f64; 16]>) -> String {
        let data = base64(&self.gltf_buffer());
        self.gltf_json(
            Some(&format!("data:application/octet-stream;base64,{data}")),
            matrix,
        )
    }

    /// Writes `dir/NAME.gltf` and its external buffer `dir/NAME.bin`; the mesh's node is the
    /// child of a node with the column-major `matrix` when given. Returns the `.gltf` path.
    pub fn gltf_files(&self, dir: &Path, name: &str, matrix: Option<[f64; 16]>) -> PathBuf {
        std::fs::write(dir.join(format!("{name}.bin")), self.gltf_buffer()).unwrap();
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, self.gltf_json(Some(&format!("{name}.bin")), matrix)).unwrap();
        path
    }

    /// The `.glb` file.
    pub fn glb(&self, matrix: Option<[f64; 16]>) -> Vec<u8> {
        let mut json = self.gltf_json(None, matrix).into_bytes();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = self.gltf_buffer();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = vec![];
        out.extend(b"glTF");
        out.extend(2u32.to_le_bytes());
        out.extend((total as u32).to_le_bytes());
        out.extend((json.len() as u32).to_le_bytes());
        out.extend(b"JSON");
        out.extend(json);
        out.extend((bin.len() as u32).to_le_bytes());
        out.extend(b"BIN\0");
        out.extend(bin);
        out
    }
}

/// Standard base64 with padding.
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}
