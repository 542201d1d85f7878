//! The tree cache: one binary file per (OBJ bytes, builder, builder settings) holding the merged
//! mesh (f64 positions, triangle indices, triangles per mesh) and its kD tree in the frame
//! centred on the mesh, so a render with a warm cache skips parsing and building.
//!
//! Reads and writes `DIR/<key>.wfkd` (`DIR` is `$XDG_CACHE_HOME/wavefront`, else
//! `~/.cache/wavefront`, or the CLI's `--cache DIR`). The file is a fixed `Header` followed by
//! five arrays in `bytemuck` layouts (native endianness, which the magic word also checks): the
//! triangle count of each mesh (`u64`), positions (`[f64; 3]`), triangles (`[u32; 3]`), nodes
//! ([`KdNode`], 8 bytes) and the leaves' triangle list (`u32`). An entry is trusted only after its
//! magic, version, key, sizes, checksum (XXH3-64 over the header and each array's hash; arrays are
//! read straight from the file into their vectors and hashed in 1 MiB pieces, in parallel) and every index
//! have been checked; [`TreeCache::load`] reports anything else as [`CacheError::Invalid`] and the
//! caller rebuilds. Entries are written under a unique temporary name and renamed into place, so
//! concurrent renders sharing one cache never read a half-written file.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

use crate::accel::kdtree::{BuildMethod, KdNode, KdTree, MAX_DEPTH};

/// Format version: bump whenever the layout or anything that changes a cached result (the
/// builders, the OBJ reader) changes.
pub(crate) const CACHE_VERSION: u32 = 2;

/// `b"WFKDTREE"` read as a native-endian `u64`: a file written on a machine of the other
/// endianness fails this check.
const MAGIC: [u8; 8] = *b"WFKDTREE";

/// File name extension of cache entries.
const EXTENSION: &str = "wfkd";

/// Why a cache entry could not be used.
#[derive(Debug, Error)]
pub enum CacheError {
    /// The entry exists but could not be read.
    #[error("cannot read cache entry {path}")]
    Read {
        /// The entry.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: io::Error,
    },
    /// The entry is truncated, corrupt, from another version or for another key.
    #[error("invalid cache entry {path}: {reason}")]
    Invalid {
        /// The entry.
        path: PathBuf,
        /// What check failed.
        reason: String,
    },
}

/// The key of an entry: a 128-bit XXH3 hash of the cache version, the crate version, the builder
/// and its settings, and every mesh's OBJ bytes (length and `part_hash`, hashed in parallel
/// 1 MiB pieces, in scene order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CacheKey(pub u128);

impl CacheKey {
    /// The key of the tree `method` builds over the meshes whose OBJ files hold `sources`.
    pub fn new(method: BuildMethod, sources: &[&[u8]]) -> CacheKey {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(b"wavefront tree cache\0");
        h.update(&CACHE_VERSION.to_le_bytes());
        h.update(env!("CARGO_PKG_VERSION").as_bytes());
        h.update(crate::accel::kdtree::builder_settings(method).as_bytes());
        h.update(&(sources.len() as u64).to_le_bytes());
        for s in sources {
            h.update(&(s.len() as u64).to_le_bytes());
            h.update(&part_hash(s).to_le_bytes());
        }
        CacheKey(h.digest128())
    }

    /// The key as 32 hexadecimal digits (the entry's file stem).
    pub(crate) fn hex(self) -> String {
        format!("{:032x}", self.0)
    }
}

/// Reads a whole file in parallel 1 MiB pieces (positioned reads, so both cores copy from the page
/// cache at once).
pub(crate) fn read_parallel(path: &Path) -> io::Result<Vec<u8>> {
    use std::os::unix::fs::FileExt;
    let (file, len) = crate::input::open_regular(path)?;
    let len = usize::try_from(len).map_err(|_| io::Error::from(io::ErrorKind::OutOfMemory))?;
    let mut bytes: Vec<u8> = bytemuck::zeroed_vec(len);
    bytes
        .par_chunks_mut(PIECE)
        .enumerate()
        .try_for_each(|(i, piece)| file.read_exact_at(piece, (i * PIECE) as u64))?;
    Ok(bytes)
}

/// What an entry holds: the merged mesh in world coordinates and its tree in the frame centred
/// on it (origin `origin`), as `kdtree build` makes it.
#[derive(Clone, Debug, PartialEq)]
pub struct CachedTree {
    /// Origin (world coordinates) of the frame the tree was built in.
    pub origin: DVec3,
    /// Vertex positions in world coordinates, as read (f64).
    pub positions: Vec<[f64; 3]>,
    /// Triangles (indices into `positions`), meshes one after another.
    pub indices: Vec<[u32; 3]>,
    /// Number of triangles of each mesh, in scene order (sums to `indices.len()`).
    pub mesh_triangles: Vec<u64>,
    /// The tree over `indices`, in the frame at `origin`.
    pub tree: KdTree,
}

/// The fixed-size start of an entry (120 bytes, no padding).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct Header {
    /// [`MAGIC`].
    magic: [u8; 8],
    /// [`CACHE_VERSION`].
    version: u32,
    /// Number of meshes.
    meshes: u32,
    /// The entry's key (low, high 64 bits).
    key: [u64; 2],
    /// Origin of the tree's frame.
    origin: [f64; 3],
    /// The tree's root box (min, max).
    root: [f32; 6],
    /// Number of vertex positions.
    positions: u64,
    /// Number of triangles.
    triangles: u64,
    /// Number of tree nodes.
    nodes: u64,
    /// Length of the leaves' triangle list.
    tri_indices: u64,
    /// [`checksum`]: XXH3-64 of this header with this field zero and of each array's hash.
    checksum: u64,
}

/// Unique suffix of temporary files within one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A folder of cache entries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TreeCache {
    dir: PathBuf,
}

impl TreeCache {
    /// A cache in `dir` (created when the first entry is stored).
    pub fn new(dir: impl Into<PathBuf>) -> TreeCache {
        TreeCache { dir: dir.into() }
    }

    /// The user's cache folder: `$XDG_CACHE_HOME/wavefront`, else `$HOME/.cache/wavefront`
    /// (`None` when neither variable is set to an absolute path).
    pub fn default_dir() -> Option<PathBuf> {
        let absolute = |v: &str| {
            std::env::var_os(v)
                .map(PathBuf::from)
                .filter(|p| p.is_absolute())
        };
        absolute("XDG_CACHE_HOME")
            .or_else(|| absolute("HOME").map(|h| h.join(".cache")))
            .map(|d| d.join("wavefront"))
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Where the entry for `key` lives.
    pub fn path_of(&self, key: CacheKey) -> PathBuf {
        self.dir.join(format!("{}.{EXTENSION}", key.hex()))
    }

    /// The entry for `key`: `Ok(None)` when there is none, an error when it exists but cannot
    /// be trusted (the caller rebuilds and overwrites it).
    pub fn load(&self, key: CacheKey) -> Result<Option<CachedTree>, CacheError> {
        use std::os::unix::fs::FileExt;
        let path = self.path_of(key);
        // Only a regular file is opened: a FIFO planted in the cache folder would block `open`.
        if crate::input::is_absent(&path) {
            return Ok(None);
        }
        let (file, len) = match crate::input::open_regular(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(CacheError::Read { path, source }),
        };
        let read = |offset: u64, out: &mut [u8]| file.read_exact_at(out, offset);
        match decode_from(&read, len, key) {
            Ok(entry) => Ok(Some(entry)),
            Err(Failure::Io(source)) => Err(CacheError::Read { path, source }),
            Err(Failure::Invalid(reason)) => Err(CacheError::Invalid { path, reason }),
        }
    }

    /// Writes the entry for `key` atomically (unique temporary name, then rename).
    pub fn store(&self, key: CacheKey, entry: &CachedTree) -> io::Result<PathBuf> {
        std::fs::create_dir_all(&self.dir)?;
        let path = self.path_of(key);
        let tmp = self.dir.join(format!(
            ".{}.{}-{}.tmp",
            key.hex(),
            std::process::id(),
            TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let result = write_entry(&tmp, key, entry).and_then(|()| {
            std::fs::rename(&tmp, &path)?;
            Ok(path)
        });
        if result.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        result
    }
}

/// The entry's header (checksum included) and its five arrays, borrowed from the entry.
fn parts(key: CacheKey, e: &CachedTree) -> (Header, [&[u8]; 5]) {
    let tree = &e.tree;
    let parts: [&[u8]; 5] = [
        bytemuck::cast_slice(&e.mesh_triangles),
        bytemuck::cast_slice(&e.positions),
        bytemuck::cast_slice(&e.indices),
        bytemuck::cast_slice(&tree.nodes),
        bytemuck::cast_slice(&tree.tri_indices),
    ];
    let (lo, hi) = tree.root;
    let mut header = Header {
        magic: MAGIC,
        version: CACHE_VERSION,
        meshes: e.mesh_triangles.len() as u32,
        key: [key.0 as u64, (key.0 >> 64) as u64],
        origin: e.origin.to_array(),
        root: [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]],
        positions: e.positions.len() as u64,
        triangles: e.indices.len() as u64,
        nodes: tree.nodes.len() as u64,
        tri_indices: tree.tri_indices.len() as u64,
        checksum: 0,
    };
    let hashes: Vec<u64> = parts.par_iter().map(|p| part_hash(p)).collect();
    header.checksum = checksum(
        &header,
        &[hashes[0], hashes[1], hashes[2], hashes[3], hashes[4]],
    );
    (header, parts)
}

/// Writes the entry to `path`: the header, then the arrays straight from the entry's vectors.
fn write_entry(path: &Path, key: CacheKey, e: &CachedTree) -> io::Result<()> {
    use std::io::Write;
    let (header, parts) = parts(key, e);
    let mut file = std::fs::File::create(path)?;
    file.write_all(bytemuck::bytes_of(&header))?;
    for p in parts {
        file.write_all(p)?;
    }
    Ok(())
}

/// The entry's bytes: header, then the five arrays.
#[cfg(test)]
fn encode(key: CacheKey, e: &CachedTree) -> Vec<u8> {
    let (header, parts) = parts(key, e);
    let mut out = bytemuck::bytes_of(&header).to_vec();
    for p in parts {
        out.extend_from_slice(p);
    }
    out
}

/// Bytes per piece of an array hashed (and read) on its own, in parallel.
const PIECE: usize = 1 << 20;

/// The hash of one array: XXH3-64 over the XXH3-64 of each [`PIECE`] of its bytes, so the pieces
/// are read and hashed in parallel.
fn part_hash(bytes: &[u8]) -> u64 {
    let pieces: Vec<u64> = bytes
        .par_chunks(PIECE)
        .map(xxhash_rust::xxh3::xxh3_64)
        .collect();
    xxhash_rust::xxh3::xxh3_64(bytemuck::cast_slice(&pieces))
}

/// The entry's checksum: XXH3-64 of its header with the checksum field zero, followed by each
/// array's [`part_hash`].
fn checksum(header: &Header, part_hashes: &[u64; 5]) -> u64 {
    let mut h = *header;
    h.checksum = 0;
    let mut x = xxhash_rust::xxh3::Xxh3::new();
    x.update(bytemuck::bytes_of(&h));
    x.update(bytemuck::cast_slice(part_hashes));
    x.digest()
}

/// Why decoding failed: the file could not be read, or its contents are not a valid entry.
enum Failure {
    Io(io::Error),
    Invalid(String),
}

impl From<String> for Failure {
    fn from(reason: String) -> Failure {
        Failure::Invalid(reason)
    }
}

impl From<&str> for Failure {
    fn from(reason: &str) -> Failure {
        Failure::Invalid(reason.into())
    }
}

/// Fills a buffer with the entry's bytes at an offset (a file read, or a copy from memory).
type Reader<'a> = dyn Fn(u64, &mut [u8]) -> io::Result<()> + Sync + 'a;

/// Reads `n` values of `T` at `offset` straight into their vector, in pieces read and hashed in
/// parallel; returns them with their [`part_hash`].
fn read_part<T: Pod + Send>(read: &Reader, offset: u64, n: usize) -> io::Result<(Vec<T>, u64)> {
    let mut v: Vec<T> = bytemuck::zeroed_vec(n);
    let pieces = bytemuck::cast_slice_mut::<T, u8>(&mut v)
        .par_chunks_mut(PIECE)
        .enumerate()
        .map(|(i, piece)| {
            read(offset + (i * PIECE) as u64, piece)?;
            Ok(xxhash_rust::xxh3::xxh3_64(piece))
        })
        .collect::<io::Result<Vec<u64>>>()?;
    let hash = xxhash_rust::xxh3::xxh3_64(bytemuck::cast_slice(&pieces));
    Ok((v, hash))
}

/// Checks and decodes an entry held in memory; the error says which check failed.
#[cfg(test)]
fn decode(bytes: &[u8], key: CacheKey) -> Result<CachedTree, String> {
    let read = |offset: u64, out: &mut [u8]| {
        let start = offset as usize;
        bytes
            .get(start..start + out.len())
            .map(|b| out.copy_from_slice(b))
            .ok_or_else(|| io::Error::from(io::ErrorKind::UnexpectedEof))
    };
    decode_from(&read, bytes.len() as u64, key).map_err(|f| match f {
        Failure::Io(e) => e.to_string(),
        Failure::Invalid(reason) => reason,
    })
}

/// Checks and decodes an entry of `len` bytes read through `read`: the header first, then every
/// array straight into its own vector (in parallel pieces), then the checksum and the indices.
fn decode_from(read: &Reader, len: u64, key: CacheKey) -> Result<CachedTree, Failure> {
    let hsize = size_of::<Header>();
    if len < hsize as u64 {
        return Err(format!("truncated ({len} bytes)").into());
    }
    let mut h = Header::zeroed();
    read(0, bytemuck::bytes_of_mut(&mut h)).map_err(Failure::Io)?;
    if h.magic != MAGIC {
        return Err("not a wavefront tree cache entry (bad magic)".into());
    }
    if h.version != CACHE_VERSION {
        return Err(format!(
            "format version {} (this build reads {CACHE_VERSION})",
            h.version
        )
        .into());
    }
    if h.key != [key.0 as u64, (key.0 >> 64) as u64] {
        return Err("stored for another key".into());
    }
    let sizes = [
        (h.meshes as u64, 8u64),
        (h.positions, 24),
        (h.triangles, 12),
        (h.nodes, 8),
        (h.tri_indices, 4),
    ];
    let mut offsets = [0u64; 5];
    let mut payload: u64 = 0;
    for (k, (n, size)) in sizes.into_iter().enumerate() {
        offsets[k] = hsize as u64 + payload;
        payload = n
            .checked_mul(size)
            .and_then(|b| payload.checked_add(b))
            .ok_or("sizes overflow")?;
    }
    if len != hsize as u64 + payload {
        return Err(format!(
            "{len} bytes where the header announces {}",
            hsize as u64 + payload
        )
        .into());
    }
    let count = |k: usize| sizes[k].0 as usize;
    let (((meshes, positions), indices), (nodes, tri_indices)) = rayon::join(
        || {
            rayon::join(
                || {
                    rayon::join(
                        || read_part::<u64>(read, offsets[0], count(0)),
                        || read_part::<[f64; 3]>(read, offsets[1], count(1)),
                    )
                },
                || read_part::<[u32; 3]>(read, offsets[2], count(2)),
            )
        },
        || {
            rayon::join(
                || read_part::<KdNode>(read, offsets[3], count(3)),
                || read_part::<u32>(read, offsets[4], count(4)),
            )
        },
    );
    let ((mesh_triangles, h0), (positions, h1)) = (
        meshes.map_err(Failure::Io)?,
        positions.map_err(Failure::Io)?,
    );
    let (indices, h2) = indices.map_err(Failure::Io)?;
    let (nodes, h3) = nodes.map_err(Failure::Io)?;
    let (tri_indices, h4) = tri_indices.map_err(Failure::Io)?;
    if checksum(&h, &[h0, h1, h2, h3, h4]) != h.checksum {
        return Err("checksum mismatch".into());
    }

    if mesh_triangles.iter().sum::<u64>() != indices.len() as u64 {
        return Err("mesh triangle counts do not add up".into());
    }
    let (structure, arrays) = rayon::join(
        || check_nodes(&nodes, tri_indices.len()),
        || -> Result<(), &str> {
            if positions.len() > u32::MAX as usize
                || indices
                    .par_iter()
                    .with_min_len(1 << 14)
                    .any(|t| t.iter().any(|&i| i as usize >= positions.len()))
            {
                return Err("vertex index out of range");
            }
            if !positions
                .par_iter()
                .with_min_len(1 << 14)
                .all(|p| p.iter().all(|c| c.is_finite()))
                || !h.origin.iter().all(|c| c.is_finite())
            {
                return Err("non-finite coordinate");
            }
            if tri_indices
                .par_iter()
                .with_min_len(1 << 14)
                .any(|&t| t as usize >= indices.len())
            {
                return Err("triangle index out of range");
            }
            Ok(())
        },
    );
    arrays?;
    structure?;
    let r = h.root;
    Ok(CachedTree {
        origin: DVec3::from_array(h.origin),
        positions,
        mesh_triangles,
        tree: KdTree {
            nodes,
            tri_indices,
            root: ([r[0], r[1], r[2]], [r[3], r[4], r[5]]),
            triangle_count: indices.len(),
            lines: Vec::new(),
        },
        indices,
    })
}

/// Structure of a pre-order node array: every right child after its left child (so no cycles),
/// every node reached exactly once from the root, leaves within the triangle list, depth at most
/// [`MAX_DEPTH`], finite split planes.
fn check_nodes(nodes: &[KdNode], list: usize) -> Result<(), String> {
    if nodes.is_empty() {
        return Err("no nodes".into());
    }
    // Pre-order walk: (node, depth); the next node visited must be the next in the array.
    let mut stack = vec![(0usize, 0usize)];
    let mut expected = 0usize;
    while let Some((i, depth)) = stack.pop() {
        if i != expected || i >= nodes.len() {
            return Err(format!("node {i} out of pre-order"));
        }
        expected += 1;
        if depth > MAX_DEPTH {
            return Err("tree deeper than the traversal stack".into());
        }
        let n = nodes[i];
        if n.is_leaf() {
            if n.offset() as usize + n.count() as usize > list {
                return Err(format!("leaf {i} outside the triangle list"));
            }
        } else {
            let right = n.right() as usize;
            if right <= i + 1 || right >= nodes.len() || !n.split().is_finite() {
                return Err(format!("inner node {i} has a bad child or split"));
            }
            stack.push((right, depth + 1));
            stack.push((i + 1, depth + 1));
        }
    }
    if expected != nodes.len() {
        return Err("unreachable nodes".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriangleMesh;

    fn entry() -> CachedTree {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let indices = vec![[0, 1, 2], [0, 1, 3], [1, 2, 3]];
        let mesh = TriangleMesh::new(
            positions.iter().map(|p| p.map(|c| c as f32)).collect(),
            indices.clone(),
        );
        CachedTree {
            origin: DVec3::ZERO,
            positions,
            indices,
            mesh_triangles: vec![2, 1],
            tree: KdTree::build(&mesh, BuildMethod::Sah),
        }
    }

    #[test]
    fn entries_round_trip() {
        let key = CacheKey(0x1234_5678_9abc_def0_0fed_cba9_8765_4321);
        let e = entry();
        assert_eq!(decode(&encode(key, &e), key).expect("valid"), e);
    }

    #[test]
    fn every_truncation_and_byte_flip_is_rejected() {
        let key = CacheKey(7);
        let bytes = encode(key, &entry());
        for len in 0..bytes.len() {
            assert!(decode(&bytes[..len], key).is_err(), "truncated to {len}");
        }
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x40;
            assert!(decode(&b, key).is_err(), "flipped byte {i}");
        }
        assert!(decode(&bytes, CacheKey(8)).is_err(), "another key");
    }

    #[test]
    fn keys_depend_on_bytes_and_builder() {
        let a = CacheKey::new(BuildMethod::Sah, &[b"v 0 0 0"]);
        assert_ne!(a, CacheKey::new(BuildMethod::Midpoint, &[b"v 0 0 0"]));
        assert_ne!(a, CacheKey::new(BuildMethod::Sah, &[b"v 0 0 1"]));
        assert_ne!(a, CacheKey::new(BuildMethod::Sah, &[b"v 0 0", b" 0"]));
        assert_eq!(a, CacheKey::new(BuildMethod::Sah, &[b"v 0 0 0"]));
    }
}
