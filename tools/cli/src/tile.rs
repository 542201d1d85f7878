//! Tile files and merging (SPEC §11): a region render written as a PNG that says where it belongs
//! and what it is a part of, and the check-then-compose merge of such tiles.
//!
//! A tile PNG is the region's pixels plus three `tEXt` chunks: [`BOUNDS_KEY`] (`x0,x1,y0,y1`),
//! [`IMAGE_KEY`] (`W,H`) and [`FINGERPRINT_KEY`] — a hash of everything that affects pixel values
//! (the scene's contents with its meshes' and tree files' bytes instead of their paths, the
//! settings in it, the frame and the renderer's version) and nothing else (not the thread count,
//! wave size, output path or bounds). Tiles merge only when they share one fingerprint and image
//! size and cover every pixel exactly once.

use std::collections::HashMap;
use std::fmt;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use wavefront::error::OutputError;
use wavefront::film::output::ImageMeta;
use wavefront::queue::region::Region;
use wavefront::scene::{Scene, TreeSource};

/// Text chunk holding the tile's region of the full image, `x0,x1,y0,y1`.
pub const BOUNDS_KEY: &str = "wavefront:bounds";
/// Text chunk holding the full image's size, `W,H`.
pub const IMAGE_KEY: &str = "wavefront:image";
/// Text chunk holding the render's [`Fingerprint`].
pub const FINGERPRINT_KEY: &str = "wavefront:fingerprint";

/// A 128-bit FNV-1a hash: stable across platforms and builds, not cryptographic (it tells tiles of
/// different renders apart; it does not resist forgery).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Fnv128(u128);

impl Fnv128 {
    const OFFSET: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
    const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013b;

    fn new() -> Fnv128 {
        Fnv128(Self::OFFSET)
    }

    fn bytes(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            self.0 = (self.0 ^ u128::from(b)).wrapping_mul(Self::PRIME);
        }
        self
    }

    /// Hashes a length-prefixed field, so that field boundaries cannot shift.
    fn field(&mut self, bytes: &[u8]) -> &mut Self {
        self.bytes(&(bytes.len() as u64).to_le_bytes()).bytes(bytes)
    }
}

/// The hash of the files a scene reads (mesh OBJs and tree files), in scene order: computed once
/// for all the frames of a render.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SourceDigest(u128);

impl SourceDigest {
    /// Reads and hashes every mesh file of `scene` and every tree file it names.
    pub fn of(scene: &Scene) -> std::io::Result<SourceDigest> {
        let mut h = Fnv128::new();
        let read = |p: &Path| {
            std::fs::read(p)
                .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", p.display())))
        };
        for mesh in &scene.meshes {
            h.field(&read(&mesh.path)?);
            if let TreeSource::File(tree) = &mesh.kdtree {
                h.field(&read(tree)?);
            }
        }
        Ok(SourceDigest(h.0))
    }
}

/// What a tile belongs to: the hash of everything that decides its pixel values.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Fingerprint(pub String);

impl Fingerprint {
    /// The fingerprint of rendering `scene` (settings and camera already applied; `frame` is the
    /// frame it shows, if it is one of an animation) whose files hash to `sources`.
    pub fn of(scene: &Scene, sources: SourceDigest, frame: Option<u32>) -> Fingerprint {
        // Scene contents without what does not change pixels: its display name, the paths of its
        // files (their bytes are in `sources`), and the camera path's other keys (the camera of
        // this frame is in `scene.camera`). Debug prints every f32 exactly (shortest round-trip).
        let mut s = scene.clone();
        s.name.clear();
        s.camera_path = None;
        for m in &mut s.meshes {
            m.path = PathBuf::new();
            if let TreeSource::File(p) = &mut m.kdtree {
                *p = PathBuf::new();
            }
        }
        let mut h = Fnv128::new();
        h.field(concat!("wavefront ", env!("CARGO_PKG_VERSION")).as_bytes())
            .field(format!("{s:?}").as_bytes())
            .field(&sources.0.to_le_bytes())
            .field(format!("{frame:?}").as_bytes());
        Fingerprint(format!("{:032x}", h.0))
    }
}

impl fmt::Display for Fingerprint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// What a tile file says about itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TileInfo {
    /// The tile's rectangle of the full image.
    pub bounds: Region,
    /// The full image's width and height.
    pub image: (u32, u32),
    /// The render it is a part of.
    pub fingerprint: Fingerprint,
}

impl TileInfo {
    /// The text chunks that carry this information, in the order they are written.
    pub fn text_chunks(&self) -> [(&'static str, String); 3] {
        [
            (BOUNDS_KEY, self.bounds.to_string()),
            (IMAGE_KEY, format!("{},{}", self.image.0, self.image.1)),
            (FINGERPRINT_KEY, self.fingerprint.0.clone()),
        ]
    }
}

/// A tile read back: its information and its pixels (the region's size).
#[derive(Clone, Debug)]
pub struct Tile {
    /// The file it was read from (errors name it).
    pub file: PathBuf,
    /// Its bounds, image size and fingerprint.
    pub info: TileInfo,
    /// Row-major pixels, `bounds.width() × bounds.height()` of them: 8-bit RGB for a PNG tile,
    /// linear f32 RGB (native-endian bytes, [`Tile::hdr`]) for an EXR tile.
    pub rgb: Vec<u8>,
    /// True for an EXR tile (linear f32 RGB, 12 bytes a pixel).
    pub hdr: bool,
}

/// A merged image of the full size, in the tiles' pixel format.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Merged {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, row 0 at the top: 8-bit RGB, or linear f32 RGB bytes when `hdr`.
    pub rgb: Vec<u8>,
    /// True when merged from EXR tiles.
    pub hdr: bool,
}

impl Merged {
    /// Writes the merged image: an EXR for EXR tiles, else PNG or PPM by `path`'s extension.
    /// Mixing (EXR tiles into a `.png`, or the reverse) is an error naming `path`.
    pub fn save(&self, path: &Path) -> Result<(), OutputError> {
        let exr = wavefront::film::output::is_exr(path);
        if exr != self.hdr {
            return Err(OutputError::Io {
                file: path.to_path_buf(),
                source: std::io::Error::other(if self.hdr {
                    "the tiles are linear EXR: merge them into a .exr file"
                } else {
                    "the tiles are 8-bit PNG: merge them into a .png or .ppm file"
                }),
            });
        }
        if self.hdr {
            let film = wavefront::film::Film {
                width: self.width,
                height: self.height,
                pixels: bytemuck::cast_slice::<u8, [f32; 3]>(&self.rgb)
                    .iter()
                    .map(|&p| p.into())
                    .collect(),
            };
            wavefront::film::output::write_exr(path, &film)
        } else {
            wavefront::film::output::write_rgb8(
                path,
                (self.width, self.height),
                &ImageMeta::default(),
                &self.rgb,
            )
        }
    }
}

/// A tile that cannot be read, or tiles that do not make one image. Each names the file at fault.
#[derive(Debug, thiserror::Error)]
pub enum TileError {
    /// The file cannot be read or decoded.
    #[error("unreadable tile {}: {message}", file.display())]
    Unreadable {
        /// The tile file.
        file: PathBuf,
        /// Why.
        message: String,
    },
    /// The PNG lacks a tile chunk or holds a malformed one.
    #[error("{}: not a wavefront tile: {message}", file.display())]
    NotATile {
        /// The tile file.
        file: PathBuf,
        /// What is missing or malformed.
        message: String,
    },
    /// The tile belongs to another render (another fingerprint or image size).
    #[error("foreign tile {}: {message}", file.display())]
    Foreign {
        /// The tile file.
        file: PathBuf,
        /// How it differs.
        message: String,
    },
    /// Two tiles cover the same pixels.
    #[error("overlapping tiles {} and {}: both cover pixels {region} (x0,x1,y0,y1)",
        first.display(), second.display())]
    Overlap {
        /// The earlier tile.
        first: PathBuf,
        /// The later tile.
        second: PathBuf,
        /// The shared pixels.
        region: Region,
    },
    /// Some pixels are in no tile.
    #[error(
        "missing tile: no tile covers pixels {region} (x0,x1,y0,y1) of the {width}x{height} image"
    )]
    Missing {
        /// Uncovered pixels (the first uncovered run of columns, over the rows it spans).
        region: Region,
        /// Full image width.
        width: u32,
        /// Full image height.
        height: u32,
    },
    /// No tile was given.
    #[error("no tiles to merge")]
    NoTiles,
}

/// Writes a tile: `rgb` (the region's pixels) with `info`'s text chunks.
pub fn write_tile(path: &Path, info: &TileInfo, rgb: &[u8]) -> Result<(), OutputError> {
    let (w, h) = (info.bounds.width(), info.bounds.height());
    write_png_with_text(path, (w, h), rgb, &info.text_chunks())
}

/// 8-bit RGB as a PNG file with `tEXt` chunks, through the one image writer
/// ([`wavefront::film::output::write_rgb8`]: atomic, the same encoder as every render).
fn write_png_with_text(
    path: &Path,
    size: (u32, u32),
    rgb: &[u8],
    text: &[(&str, String)],
) -> Result<(), OutputError> {
    let meta = ImageMeta {
        text: text
            .iter()
            .map(|(k, v)| ((*k).to_owned(), v.clone()))
            .collect(),
    };
    wavefront::film::output::write_rgb8(path, size, &meta, rgb)
}

/// Writes an EXR tile: the region's linear film with `info` as string attributes.
pub fn write_tile_exr(
    path: &Path,
    info: &TileInfo,
    film: &wavefront::film::Film,
) -> Result<(), OutputError> {
    let meta = ImageMeta {
        text: info
            .text_chunks()
            .iter()
            .map(|(k, v)| ((*k).to_owned(), v.clone()))
            .collect(),
    };
    wavefront::film::output::write_exr_with(path, film, &meta)
}

/// Reads a tile file (PNG with text chunks, or EXR with string attributes) and checks it against
/// itself: its metadata parses, its bounds lie inside its image, and its pixels are the bounds'
/// size.
pub fn read_tile(path: &Path) -> Result<Tile, TileError> {
    if wavefront::film::output::is_exr(path) {
        return read_exr_tile(path);
    }
    let unreadable = |message: String| TileError::Unreadable {
        file: path.to_path_buf(),
        message,
    };
    let not_a_tile = |message: String| TileError::NotATile {
        file: path.to_path_buf(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| unreadable(e.to_string()))?;
    let mut reader = png::Decoder::new(Cursor::new(bytes))
        .read_info()
        .map_err(|e| unreadable(format!("not a PNG file: {e}")))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| unreadable("image too large".into()))?;
    let mut rgb = vec![0; size];
    let frame = reader
        .next_frame(&mut rgb)
        .map_err(|e| unreadable(format!("corrupt PNG data: {e}")))?;
    if (frame.color_type, frame.bit_depth) != (png::ColorType::Rgb, png::BitDepth::Eight) {
        return Err(not_a_tile("not 8-bit RGB".into()));
    }
    rgb.truncate(frame.buffer_size());
    let text: HashMap<&str, &str> = reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .map(|c| (c.keyword.as_str(), c.text.as_str()))
        .collect();
    let info = tile_info(path, &text, (frame.width, frame.height))?;
    Ok(Tile {
        file: path.to_path_buf(),
        info,
        rgb,
        hdr: false,
    })
}

/// A tile's information from its metadata (`text`: PNG text chunks or EXR string attributes),
/// checked against itself and against its pixels' `size`.
fn tile_info(
    path: &Path,
    text: &HashMap<&str, &str>,
    size: (u32, u32),
) -> Result<TileInfo, TileError> {
    let not_a_tile = |message: String| TileError::NotATile {
        file: path.to_path_buf(),
        message,
    };
    let chunk = |key: &str| {
        text.get(key)
            .copied()
            .ok_or_else(|| not_a_tile(format!("no {key} text chunk")))
    };
    let bounds: Region = chunk(BOUNDS_KEY)?
        .parse()
        .map_err(|_| not_a_tile(format!("malformed {BOUNDS_KEY} {:?}", text[BOUNDS_KEY])))?;
    let image = chunk(IMAGE_KEY)?;
    let (w, h) = image
        .split_once(',')
        .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)))
        .ok_or_else(|| not_a_tile(format!("malformed {IMAGE_KEY} {image:?}")))?;
    let fingerprint = Fingerprint(chunk(FINGERPRINT_KEY)?.to_owned());
    bounds
        .check_inside(w, h, BOUNDS_KEY)
        .map_err(|e| not_a_tile(e.to_string()))?;
    if size != (bounds.width(), bounds.height()) {
        return Err(not_a_tile(format!(
            "its pixels are {}x{} but its bounds {bounds} are {}x{}",
            size.0,
            size.1,
            bounds.width(),
            bounds.height()
        )));
    }
    Ok(TileInfo {
        bounds,
        image: (w, h),
        fingerprint,
    })
}

/// [`read_tile`] for an EXR tile.
fn read_exr_tile(path: &Path) -> Result<Tile, TileError> {
    let image =
        wavefront::film::output::read_exr(path).map_err(|message| TileError::Unreadable {
            file: path.to_path_buf(),
            message,
        })?;
    let text: HashMap<&str, &str> = image
        .text
        .iter()
        .map(|(k, v)| (k.as_str(), v.as_str()))
        .collect();
    let info = tile_info(path, &text, image.size)?;
    let pixels: Vec<[f32; 3]> = image.pixels.iter().map(|p| p.to_array()).collect();
    Ok(Tile {
        file: path.to_path_buf(),
        info,
        rgb: bytemuck::cast_slice(&pixels).to_vec(),
        hdr: true,
    })
}

/// Composes `tiles` into the full image after checking that they share one fingerprint and image
/// size (the most common pair; the first tile that differs is foreign) and cover every pixel
/// exactly once.
pub fn merge_tiles(tiles: &[Tile]) -> Result<Merged, TileError> {
    let first = tiles.first().ok_or(TileError::NoTiles)?;
    // The render most tiles belong to (ties: the earliest), so the odd one out is named.
    let mut counts: HashMap<(&Fingerprint, (u32, u32)), usize> = HashMap::new();
    for t in tiles {
        *counts.entry(key(t)).or_default() += 1;
    }
    fn key(t: &Tile) -> (&Fingerprint, (u32, u32)) {
        (&t.info.fingerprint, t.info.image)
    }
    let reference = tiles
        .iter()
        .enumerate()
        .max_by_key(|(i, t)| (counts[&key(t)], std::cmp::Reverse(*i)))
        .map_or(first, |(_, t)| t);
    let (width, height) = reference.info.image;
    for t in tiles {
        let message = if t.info.fingerprint != reference.info.fingerprint {
            format!(
                "fingerprint {} differs from {} ({}): it is part of another render",
                t.info.fingerprint,
                reference.info.fingerprint,
                reference.file.display()
            )
        } else if t.info.image != reference.info.image {
            format!(
                "image size {}x{} differs from {}x{} ({})",
                t.info.image.0,
                t.info.image.1,
                width,
                height,
                reference.file.display()
            )
        } else {
            continue;
        };
        return Err(TileError::Foreign {
            file: t.file.clone(),
            message,
        });
    }
    for (i, a) in tiles.iter().enumerate() {
        for b in &tiles[i + 1..] {
            if let Some(region) = a.info.bounds.intersection(&b.info.bounds) {
                return Err(TileError::Overlap {
                    first: a.file.clone(),
                    second: b.file.clone(),
                    region,
                });
            }
        }
    }
    let covered: u64 = tiles.iter().map(|t| t.info.bounds.pixels()).sum();
    if covered < u64::from(width) * u64::from(height) {
        let region = first_gap(tiles, width, height);
        return Err(TileError::Missing {
            region,
            width,
            height,
        });
    }
    let hdr = reference.hdr;
    if let Some(t) = tiles.iter().find(|t| t.hdr != hdr) {
        return Err(TileError::Foreign {
            file: t.file.clone(),
            message: format!(
                "it is {} but {} is {}",
                if t.hdr { "EXR" } else { "PNG" },
                reference.file.display(),
                if hdr { "EXR" } else { "PNG" }
            ),
        });
    }
    let bpp = if hdr { 12 } else { 3 };
    let mut rgb = vec![0u8; width as usize * height as usize * bpp];
    for t in tiles {
        let b = t.info.bounds;
        let row = b.width() as usize * bpp;
        for (j, src) in (b.y0..b.y1).zip(t.rgb.chunks_exact(row)) {
            let start = (j as usize * width as usize + b.x0 as usize) * bpp;
            rgb[start..start + row].copy_from_slice(src);
        }
    }
    Ok(Merged {
        width,
        height,
        rgb,
        hdr,
    })
}

/// The first run of uncovered columns (top to bottom, left to right), extended over the rows below
/// where the same columns are uncovered too. Tiles do not overlap and lie inside the image.
fn first_gap(tiles: &[Tile], width: u32, height: u32) -> Region {
    let row_gap = |j: u32| {
        let mut spans: Vec<(u32, u32)> = tiles
            .iter()
            .map(|t| t.info.bounds)
            .filter(|b| b.y0 <= j && j < b.y1)
            .map(|b| (b.x0, b.x1))
            .collect();
        spans.sort_unstable();
        let mut x = 0;
        for (x0, x1) in spans {
            if x0 > x {
                return Some((x, x0));
            }
            x = x.max(x1);
        }
        (x < width).then_some((x, width))
    };
    let Some((y0, (x0, x1))) = (0..height).find_map(|j| row_gap(j).map(|g| (j, g))) else {
        return Region::full(0, 0);
    };
    let uncovered = |j: u32| {
        let row = Region {
            x0,
            x1,
            y0: j,
            y1: j + 1,
        };
        tiles
            .iter()
            .all(|t| t.info.bounds.intersection(&row).is_none())
    };
    let y1 = (y0 + 1..height).find(|&j| !uncovered(j)).unwrap_or(height);
    Region { x0, x1, y0, y1 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wavefront_kit::fuzz::fuzz;
    use wavefront_kit::testkit::Scratch;

    fn tile(name: &str, bounds: &str, fingerprint: &str) -> Tile {
        let bounds: Region = bounds.parse().unwrap();
        // Each pixel holds its own coordinates, so a misplaced row shows.
        let rgb = (bounds.y0..bounds.y1)
            .flat_map(|j| (bounds.x0..bounds.x1).flat_map(move |i| [i as u8, j as u8, 7]))
            .collect();
        Tile {
            file: name.into(),
            info: TileInfo {
                bounds,
                image: (6, 4),
                fingerprint: Fingerprint(fingerprint.into()),
            },
            rgb,
            hdr: false,
        }
    }

    fn whole() -> Vec<u8> {
        tile("all", "0,6,0,4", "f").rgb
    }

    #[test]
    fn uneven_tiles_and_rectangles_merge_into_the_whole_image() {
        let bands = [
            tile("a", "0,6,0,1", "f"),
            tile("b", "0,6,1,3", "f"),
            tile("c", "0,6,3,4", "f"),
        ];
        assert_eq!(merge_tiles(&bands).unwrap().rgb, whole());
        let rects = [
            tile("d", "3,6,2,4", "f"),
            tile("a", "0,6,0,2", "f"),
            tile("b", "0,3,2,3", "f"),
            tile("c", "0,3,3,4", "f"),
        ];
        let m = merge_tiles(&rects).unwrap();
        assert_eq!((m.width, m.height, m.rgb), (6, 4, whole()));
    }

    #[test]
    fn a_missing_tile_is_named_by_its_pixels() {
        let tiles = [tile("a", "0,6,0,1", "f"), tile("c", "0,6,3,4", "f")];
        let e = merge_tiles(&tiles).unwrap_err().to_string();
        assert!(e.contains("missing tile") && e.contains("0,6,1,3"), "{e}");
        let tiles = [tile("a", "0,6,0,2", "f"), tile("b", "0,3,2,4", "f")];
        let e = merge_tiles(&tiles).unwrap_err().to_string();
        assert!(e.contains("3,6,2,4"), "{e}");
    }

    #[test]
    fn overlapping_and_repeated_tiles_are_named() {
        let tiles = [tile("a", "0,6,0,2", "f"), tile("b", "0,6,1,4", "f")];
        let e = merge_tiles(&tiles).unwrap_err().to_string();
        assert!(
            e.contains("overlapping tiles a and b") && e.contains("0,6,1,2"),
            "{e}"
        );
        let tiles = [tile("a", "0,6,0,4", "f"), tile("a", "0,6,0,4", "f")];
        assert!(matches!(
            merge_tiles(&tiles),
            Err(TileError::Overlap { .. })
        ));
    }

    #[test]
    fn the_odd_fingerprint_out_is_the_foreign_tile() {
        let tiles = [
            tile("x", "0,6,0,1", "other"),
            tile("a", "0,6,1,2", "f"),
            tile("b", "0,6,2,4", "f"),
        ];
        let e = merge_tiles(&tiles).unwrap_err().to_string();
        assert!(e.starts_with("foreign tile x:"), "{e}");
        let mut t = tile("y", "0,6,0,1", "f");
        t.info.image = (6, 5);
        let tiles = [t, tile("a", "0,6,1,2", "f"), tile("b", "0,6,2,4", "f")];
        let e = merge_tiles(&tiles).unwrap_err().to_string();
        assert!(e.starts_with("foreign tile y:") && e.contains("6x5"), "{e}");
        assert!(matches!(merge_tiles(&[]), Err(TileError::NoTiles)));
    }

    #[test]
    fn tiles_round_trip_through_png_text_chunks() {
        let dir = std::env::temp_dir().join(format!("wf-tile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let t = tile("t", "1,4,2,4", "0123abcd");
        let path = dir.join("t.png");
        write_tile(&path, &t.info, &t.rgb).unwrap();
        let back = read_tile(&path).unwrap();
        assert_eq!((back.info, back.rgb), (t.info.clone(), t.rgb.clone()));
        // A plain PNG is not a tile; garbage is unreadable; both name the file.
        let plain = dir.join("plain.png");
        wavefront::film::output::save_rgb8(&plain, 3, 2, &t.rgb).unwrap();
        let e = read_tile(&plain).unwrap_err().to_string();
        assert!(e.contains("plain.png: not a wavefront tile"), "{e}");
        let junk = dir.join("junk.png");
        std::fs::write(&junk, b"not a png").unwrap();
        let e = read_tile(&junk).unwrap_err().to_string();
        assert!(
            e.starts_with("unreadable tile") && e.contains("junk.png"),
            "{e}"
        );
        // Bounds that disagree with the pixels.
        let mut info = t.info.clone();
        info.bounds = "0,3,0,2".parse().unwrap();
        write_png_with_text(&path, (3, 3), &[0; 27], &info.text_chunks()).unwrap();
        let e = read_tile(&path).unwrap_err().to_string();
        assert!(e.contains("3x3") && e.contains("3x2"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn exr_tiles_round_trip_and_merge_into_the_linear_film() {
        let dir = std::env::temp_dir().join(format!("wf-tile-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // A 5 × 3 linear image with values beyond 1 (HDR), split into two bands.
        let whole: Vec<glam::Vec3> = (0..15)
            .map(|i| glam::Vec3::new(i as f32 * 0.37, -(i as f32), 1e3 + i as f32))
            .collect();
        let band = |y0: u32, y1: u32| wavefront::film::Film {
            width: 5,
            height: y1 - y0,
            pixels: whole[(y0 * 5) as usize..(y1 * 5) as usize].to_vec(),
        };
        let mut tiles = vec![];
        for (name, y0, y1) in [("a.exr", 0, 2), ("b.exr", 2, 3)] {
            let info = TileInfo {
                bounds: Region {
                    x0: 0,
                    x1: 5,
                    y0,
                    y1,
                },
                image: (5, 3),
                fingerprint: Fingerprint("f00d".into()),
            };
            let path = dir.join(name);
            write_tile_exr(&path, &info, &band(y0, y1)).unwrap();
            let back = read_tile(&path).unwrap();
            assert!(back.hdr);
            assert_eq!(back.info, info);
            tiles.push(back);
        }
        let merged = merge_tiles(&tiles).unwrap();
        let out = dir.join("whole.exr");
        merged.save(&out).unwrap();
        let image = wavefront::film::output::read_exr(&out).unwrap();
        assert_eq!(image.size, (5, 3));
        assert!(
            image.pixels == whole,
            "merged EXR differs from the linear film"
        );
        // EXR tiles into a PNG is an error naming the output; nothing is written.
        let png = dir.join("whole.png");
        let e = wavefront::error::chain(&merged.save(&png).unwrap_err());
        assert!(e.contains("whole.png") && e.contains(".exr"), "{e}");
        assert!(!png.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_fingerprint_follows_pixels_not_paths_or_names() {
        let scene = wavefront::scene::builtin::spheres();
        let src = SourceDigest::of(&scene).unwrap();
        let fp = Fingerprint::of(&scene, src, None);
        assert_eq!(fp.0.len(), 32);
        let mut renamed = scene.clone();
        renamed.name = "elsewhere.toml".into();
        assert_eq!(Fingerprint::of(&renamed, src, None), fp);
        let mut more = scene.clone();
        more.image.samples = 4;
        assert_ne!(Fingerprint::of(&more, src, None), fp);
        let mut moved = scene.clone();
        moved.camera.eye.x += 1e-6;
        assert_ne!(Fingerprint::of(&moved, src, None), fp);
        assert_ne!(Fingerprint::of(&scene, src, Some(0)), fp);
        assert_ne!(
            Fingerprint::of(&scene, SourceDigest(1), None),
            fp,
            "mesh bytes count"
        );
    }

    // Fuzzed tiles (the harness of tests/fuzz.rs): every mutation reads valid or fails naming the file.
    /// A 4 × 2 tile of a 4 × 4 image, written as `name`.
    fn tile_bytes(dir: &Scratch, name: &str) -> (PathBuf, Vec<u8>) {
        let info = TileInfo {
            bounds: wavefront::queue::region::Region {
                x0: 0,
                x1: 4,
                y0: 0,
                y1: 2,
            },
            image: (4, 4),
            fingerprint: Fingerprint("0123456789abcdef".into()),
        };
        let path = dir.join(name);
        if name.ends_with(".exr") {
            let mut film = wavefront::Film::new(4, 2);
            film.pixels[3] = glam::Vec3::ONE;
            write_tile_exr(&path, &info, &film).unwrap();
        } else {
            let rgb: Vec<u8> = (0..4 * 2 * 3).map(|i| i as u8 * 9).collect();
            write_tile(&path, &info, &rgb).unwrap();
        }
        let bytes = std::fs::read(&path).unwrap();
        (path, bytes)
    }

    fn fuzz_tiles(name: &'static str) {
        let dir = Scratch::new(&format!("fuzz-{name}"));
        let (path, valid) = tile_bytes(&dir, name);
        fuzz(name, &valid, |bytes| {
            std::fs::write(&path, bytes).unwrap();
            match read_tile(&path) {
                Ok(tile) => {
                    let b = tile.info.bounds;
                    assert!(b.x0 < b.x1 && b.y0 < b.y1);
                    assert!(b.x1 <= tile.info.image.0 && b.y1 <= tile.info.image.1);
                }
                Err(e) => {
                    let e = wavefront::error::chain(&e);
                    assert!(e.contains(name), "error does not name {name}: {e}");
                }
            }
        });
    }

    #[test]
    fn fuzzed_png_tiles_are_read_valid_or_rejected() {
        fuzz_tiles("tile.png");
    }

    #[test]
    fn fuzzed_exr_tiles_are_read_valid_or_rejected() {
        fuzz_tiles("tile.exr");
    }
}
