//! Fast OBJ reading: files made only of the common lines (`v`, `vt`, `f` in any index form,
//! `o`/`g`, `s`, comments) are parsed in parallel, in f64; any other file goes through `tobj`
//! ([`ObjMesh::read`]), which also reports every error (one line naming file and line).
//!
//! Reads the OBJ bytes; writes an [`ObjMesh`] with exactly the positions and triangles `tobj`
//! makes with `triangulate` and `single_index`: per object or group (a model), each distinct
//! `(v, vt, vn)` corner becomes one vertex in order of first use, polygons are fanned from their
//! first corner, models are concatenated in file order. Two passes over line-aligned chunks: the
//! first counts `v` and `vt` lines (so relative indices resolve without a sequential scan), the
//! second parses; the per-model renumbering is one sequential pass over the corners.
//!
//! Anything the fast path does not reproduce exactly — `mtllib`, `usemtl`, `vn` and normal
//! indices (normals are tobj's business), index 0, `l`, `p`, unknown keywords, `v` with a weight or colours, continuation
//! backslashes, non-ASCII bytes, and any malformed line or out-of-range index — sends the whole
//! file to `tobj`.

use std::collections::HashMap;
use std::path::Path;

use rayon::prelude::*;

use crate::mesh::{MeshError, ObjMesh, ObjRead};

/// Index not given in a corner (`a`, `a//c`): tobj's `MISSING_INDEX`.
const MISSING: u64 = u64::MAX;

/// Bytes per parallel chunk (at least; chunks end at a line end).
const CHUNK_BYTES: usize = 1 << 20;

/// Reads the mesh file `path` whose bytes are `bytes` (already read, e.g. to hash them): for an
/// OBJ file the same positions and triangles as [`ObjMesh::read`], through the fast path where it
/// applies; any other format through its reader ([`crate::mesh::read_bytes`], the one dispatch).
pub fn read_bytes(path: &Path, bytes: &[u8]) -> Result<ObjMesh, MeshError> {
    crate::mesh::read_bytes(path, bytes, ObjRead::default(), true)
}

/// Positions (f64) and triangles, as [`ObjMesh`] holds them.
pub(crate) type Parsed = (Vec<[f64; 3]>, Vec<[u32; 3]>);

/// One face corner: `(v, vt, vn)` resolved to 0-based indices (wrapped as tobj wraps them).
type Corner = (u64, u64, u64);

/// What one chunk holds.
#[derive(Default)]
struct Chunk {
    positions: Vec<[f64; 3]>,
    /// Triangles (fanned), three corners each.
    corners: Vec<Corner>,
    /// Triangle counts (within the chunk) at which an `o` or `g` line appears.
    groups: Vec<usize>,
}

/// The fast path: `None` when the file needs tobj.
pub fn parse(bytes: &[u8]) -> Option<Parsed> {
    // Continuation lines and the one whitespace `split_whitespace` knows but
    // `split_ascii_whitespace` does not (vertical tab) are tobj's business.
    if !bytes.is_ascii() || bytes.iter().any(|&b| b == b'\\' || b == 0x0b) {
        return None;
    }
    // A CR not followed by LF ends a line for the full reader (CR-only files): its business.
    let lone_cr = |i: usize| bytes[i] == b'\r' && bytes.get(i + 1) != Some(&b'\n');
    if bytes.contains(&b'\r') && (0..bytes.len()).any(lone_cr) {
        return None;
    }
    let text = std::str::from_utf8(bytes).ok()?;
    let chunks = split(text);
    // Pass 1: `v` and `vt` lines per chunk.
    let counts: Vec<(usize, usize)> = chunks
        .par_iter()
        .map(|c| {
            let (mut v, mut vt) = (0, 0);
            for line in c.lines() {
                match line.split_ascii_whitespace().next() {
                    Some("v") => v += 1,
                    Some("vt") => vt += 1,
                    _ => {}
                }
            }
            (v, vt)
        })
        .collect();
    let mut bases = Vec::with_capacity(chunks.len());
    let (mut nv, mut nvt) = (0usize, 0usize);
    for &(v, vt) in &counts {
        bases.push((nv, nvt));
        nv += v;
        nvt += vt;
    }
    // Pass 2: parse.
    let parsed: Vec<Option<Chunk>> = chunks
        .par_iter()
        .zip(&bases)
        .map(|(c, &base)| parse_chunk(c, base))
        .collect();
    let mut chunks_out = Vec::with_capacity(parsed.len());
    for c in parsed {
        chunks_out.push(c?);
    }
    let positions: Vec<[f64; 3]> = chunks_out
        .iter()
        .flat_map(|c| c.positions.iter().copied())
        .collect();
    if positions.len() != nv || !positions.iter().flatten().all(|&c| (c as f32).is_finite()) {
        return None;
    }
    renumber(&chunks_out, &positions, nvt)
}

/// Splits `text` into chunks of about [`CHUNK_BYTES`] ending at line ends.
fn split(text: &str) -> Vec<&str> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut start = 0;
    while start < b.len() {
        let mut end = (start + CHUNK_BYTES).min(b.len());
        while end < b.len() && b[end - 1] != b'\n' {
            end += 1;
        }
        out.push(&text[start..end]);
        start = end;
    }
    out
}

/// tobj's index rule: negative = relative to the count so far, else 1-based; wraps like its
/// `as usize` casts.
#[inline]
fn resolve(x: i64, count: usize) -> u64 {
    if x < 0 {
        (count as i64 + x) as u64
    } else {
        (x - 1) as u64
    }
}

/// Parses one chunk whose first line follows `base = (v lines, vt lines)` before it.
fn parse_chunk(text: &str, (mut nv, mut nvt): (usize, usize)) -> Option<Chunk> {
    let mut c = Chunk::default();
    let mut face: Vec<Corner> = Vec::with_capacity(8);
    for line in text.lines() {
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            None | Some("#") | Some("s") => {}
            Some(w) if w.starts_with('#') => {}
            Some("v") => {
                let mut p = [0.0f64; 3];
                for x in &mut p {
                    *x = words.next()?.parse().ok()?;
                }
                if words.next().is_some() {
                    return None; // weight or colours: tobj's business
                }
                c.positions.push(p);
                nv += 1;
            }
            Some("vt") => {
                for _ in 0..2 {
                    words.next()?.parse::<f64>().ok()?;
                }
                nvt += 1;
            }
            Some("f") => {
                face.clear();
                for w in words {
                    let mut parts = w.split('/');
                    let mut corner = [MISSING; 3];
                    for (k, part) in parts.by_ref().take(3).enumerate() {
                        if !part.is_empty() {
                            let x: i64 = part.parse().ok()?;
                            // Index 0 is never valid; a normal index is tobj's business (the
                            // fast path takes no `vn` lines, so it cannot be in range).
                            if x == 0 || k == 2 {
                                return None;
                            }
                            corner[k] = match k {
                                0 => resolve(x, nv),
                                _ => resolve(x, nvt),
                            };
                        }
                    }
                    if parts.next().is_some() {
                        return None;
                    }
                    face.push((corner[0], corner[1], corner[2]));
                }
                if face.len() < 3 {
                    return None; // points and lines: tobj's business
                }
                for k in 2..face.len() {
                    c.corners.extend([face[0], face[k - 1], face[k]]);
                }
            }
            Some("o") | Some("g") => c.groups.push(c.corners.len() / 3),
            Some(_) => return None,
        }
    }
    Some(c)
}

/// tobj's per-model renumbering: each distinct corner of a model becomes one vertex, in order of
/// first use. `None` when an index is out of range (tobj reports it).
fn renumber(chunks: &[Chunk], all: &[[f64; 3]], texcoords: usize) -> Option<Parsed> {
    let triangles: usize = chunks.iter().map(|c| c.corners.len() / 3).sum();
    let plain = chunks.iter().all(|c| {
        c.corners
            .iter()
            .all(|&(_, t, n)| t == MISSING && n == MISSING)
    });
    let mut positions = Vec::with_capacity(all.len());
    let mut indices: Vec<[u32; 3]> = Vec::with_capacity(triangles);
    // Plain corners: a vertex's new index per model, stamped with the model number.
    let mut stamp: Vec<(u32, u32)> = if plain {
        vec![(u32::MAX, 0); all.len()]
    } else {
        Vec::new()
    };
    let mut map: HashMap<Corner, u32> = HashMap::new();
    let mut model = 0u32;
    let mut model_start = 0usize; // first vertex of the current model
    let mut model_first_tri = 0usize;
    for c in chunks {
        let mut g = c.groups.iter().peekable();
        for (t, tri) in c.corners.chunks_exact(3).enumerate() {
            while let Some(&&at) = g.peek() {
                if at > t {
                    break;
                }
                g.next();
                if indices.len() > model_first_tri {
                    model += 1;
                    model_start = positions.len();
                    model_first_tri = indices.len();
                    map.clear();
                }
            }
            let mut out = [0u32; 3];
            for (o, &(v, vt, vn)) in out.iter_mut().zip(tri) {
                if v >= all.len() as u64 || (vt != MISSING && vt >= texcoords as u64) {
                    return None;
                }
                let next = (positions.len() - model_start) as u32;
                let id = if plain {
                    let s = &mut stamp[v as usize];
                    if s.0 != model {
                        *s = (model, next);
                        positions.push(all[v as usize]);
                    }
                    s.1
                } else {
                    *map.entry((v, vt, vn)).or_insert_with(|| {
                        positions.push(all[v as usize]);
                        next
                    })
                };
                *o = id + model_start as u32;
            }
            indices.push(out);
        }
        // Group lines after a chunk's last triangle still close the model.
        for _ in g {
            if indices.len() > model_first_tri {
                model += 1;
                model_start = positions.len();
                model_first_tri = indices.len();
                map.clear();
            }
        }
    }
    if positions.len() > u32::MAX as usize {
        return None;
    }
    Some((positions, indices))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// tobj's result through [`ObjMesh::read`] on a temporary file.
    fn tobj(text: &str) -> Result<ObjMesh, MeshError> {
        let path = std::env::temp_dir().join(format!(
            "wavefront-obj-fast-{}-{:x}.obj",
            std::process::id(),
            xxhash_rust::xxh3::xxh3_64(text.as_bytes())
        ));
        std::fs::write(&path, text).unwrap();
        let r = ObjMesh::read(&path);
        let _ = std::fs::remove_file(&path);
        r
    }

    fn same_as_tobj(text: &str) {
        let fast = parse(text.as_bytes()).expect("fast path taken");
        let slow = tobj(text).expect("tobj reads it");
        assert_eq!(fast.0, slow.positions, "positions of\n{text}");
        assert_eq!(fast.1, slow.indices, "indices of\n{text}");
    }

    #[test]
    fn every_index_form_matches_tobj() {
        let v = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1e-3\n";
        let vt = "vt 0 0\nvt 1 0\nvt 1 1\n";
        for f in [
            "f 1 2 3\nf 1 3 4\n",
            "f 1/1 2/2 3/3\nf 1/1 3/3 4/1\n",
            "f -5 -4 -3\nf -5/-3 -3/-1 -2/-2\n",
            "f 1 2 3 4 5\nf 5 4 3 2\n",
            "f 3 2 1\nf 1 2 3\nf 5 1 3\n",
        ] {
            same_as_tobj(&format!("# c\n{v}{vt}s off\n{f}"));
        }
    }

    #[test]
    fn groups_renumber_like_tobj_models() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\no a\nf 1 2 3\ng b\ng c\nf 1 3 4\nf 4 1 2\no\n\
                    o d\nf 2 3 4\ng tail\n";
        same_as_tobj(text);
    }

    #[test]
    fn chunks_resolve_relative_indices_across_their_borders() {
        let mut text = String::new();
        for i in 0..60_000 {
            let x = i as f64 * 0.25;
            text.push_str(&format!(
                "v {x} {} -1.5\nv {x} 1 2\nv 0.125 {x} 3\n",
                x * 0.5
            ));
            text.push_str(if i % 3 == 0 {
                "f -3 -2 -1\n"
            } else {
                "f -1 -2 -3 1\n"
            });
            if i % 7919 == 0 {
                text.push_str("g part\n");
            }
        }
        assert!(text.len() > 3 * CHUNK_BYTES);
        same_as_tobj(&text);
    }

    #[test]
    fn uncommon_or_bad_files_go_to_tobj() {
        for text in [
            "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n",
            "v 0 0 0\nvn 0 0 1\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n",
            "v 0 0 0 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            "v 0 0 x\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "v 0 0 1e39\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/2 2/1 3/1\n",
            // Normal indices (here of normals that do not exist) and index 0 of any kind.
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/0 2/1 3/1\n",
        ] {
            assert!(
                parse(text.as_bytes()).is_none(),
                "fast path taken for\n{text}"
            );
        }
    }
}
