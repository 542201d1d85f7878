//! Image files: 8-bit PNG and binary PPM (P6) encoded row by row, OpenEXR (linear f32 RGB)
//! encoded block row by block row, all written atomically.
//!
//! Reads: resolved pixels in linear radiance ([`ImageStream`], a [`PixelSink`] the schedule feeds
//! wave by wave) or finished 8-bit RGB rows ([`write_rgb8`]). Writes: one image file.
//!
//! [`ImageStream`] encodes each wave's pixels to 8 bits (`round(255 · clamp(L, 0, 1)^(1/γ))`, SPEC
//! §2) as the wave arrives and sends every completed row through a bounded channel to a writer
//! thread, which feeds them to the PNG crate's [`png::StreamWriter`] (or writes P6 rows), so an
//! image of any size needs memory for a wave and a few rows, never the whole image. An EXR stream
//! sends rows of f32 RGB instead, which the writer thread hands to the `exr` crate's encoder as it
//! asks for them, tile row (64 rows) after tile row, so it holds a block row or two. Both paths use
//! the same encoder and settings, so a streamed render and [`crate::Film::save`] of the same pixels
//! write the same bytes. PNG text chunks ([`ImageMeta`]) go before the image data.
//!
//! Every file is written to a unique temporary file beside its target and renamed over it only
//! when complete ([`PartialFile`]); on any error, when an unfinished stream is dropped, or on a
//! signal the CLI catches ([`remove_partials`]), the temporary file is removed, so the target
//! appears complete or not at all. A target that exists and is not a regular file is an error.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender};
use glam::Vec3;

use crate::error::OutputError;
use crate::film::{Film, PixelSink, encode_rgb8};
use crate::queue::PixelIndex;

/// Bytes of compressed image data per PNG `IDAT` chunk (the stream writer's buffer).
pub(crate) const PNG_IDAT_BYTES: usize = 1 << 20;

/// Encoded row batches the channel to the writer thread holds before the renderer waits: bounds
/// the memory of rows not yet written to a few waves' worth.
const CHANNEL_BATCHES: usize = 4;

/// Most black pixels encoded at once while filling a gap (pixels outside a rendered range).
const FILL_PIXELS: u64 = 1 << 20;

/// Output format, chosen by the file name's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// `.png`: 8-bit RGB, with optional text chunks.
    Png,
    /// `.ppm`: binary PPM (P6), 8-bit RGB; no metadata.
    Ppm,
}

impl ImageFormat {
    /// The format `path`'s extension names (case-insensitive), or [`OutputError::Format`].
    pub fn from_path(path: &Path) -> Result<ImageFormat, OutputError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(ImageFormat::Png),
            Some("ppm") => Ok(ImageFormat::Ppm),
            _ => Err(OutputError::Format {
                file: path.to_path_buf(),
            }),
        }
    }
}

/// Metadata written with an image: PNG `tEXt` chunks (keyword, text), in order, before the image
/// data. Keywords must be 1–79 Latin-1 characters and texts Latin-1, or opening the file fails
/// with [`OutputError::Encode`]. PPM files carry no metadata: it is ignored there.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ImageMeta {
    /// `(keyword, text)` pairs.
    pub text: Vec<(String, String)>,
}

/// Temporary files of this process not yet renamed or removed: what [`remove_partials`] removes
/// when a signal ends the process.
static LIVE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Numbers this process's temporary files, so two of them (two streams to one target) never
/// share a name.
static NEXT_TEMP: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Removes every temporary file of this process not yet renamed into place: for a signal handler
/// (the CLI's, on SIGINT, SIGTERM or SIGHUP) before it ends the process. Old outputs stay intact.
pub fn remove_partials() {
    let live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
    for tmp in live.iter() {
        let _ = std::fs::remove_file(tmp);
    }
}

/// `Err` when `target` exists and is not a regular file (a device, a FIFO, a directory, a
/// socket): only a regular file is ever replaced. A symlink is judged by what it points to.
fn check_target(target: &Path) -> io::Result<()> {
    match std::fs::metadata(target) {
        Ok(m) if m.is_file() => Ok(()),
        Ok(m) => {
            use std::os::unix::fs::FileTypeExt;
            let t = m.file_type();
            let kind = if t.is_dir() {
                "a directory"
            } else if t.is_fifo() {
                "a FIFO"
            } else if t.is_char_device() || t.is_block_device() {
                "a device"
            } else if t.is_socket() {
                "a socket"
            } else {
                "not a regular file"
            };
            Err(io::Error::other(format!(
                "it exists and is {kind}: only a regular file is replaced"
            )))
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e),
    }
}

/// A file written under a unique temporary name in its target's folder
/// (`.wavefront-PID-N.partial`: hidden, never the target's extension, so a killed process's
/// leftover is never mistaken for an output), created exclusively (`create_new`: a planted file
/// or symlink of that name is never opened or followed), renamed over the target by
/// [`PartialFile::commit`] and removed when dropped uncommitted, or by [`remove_partials`].
///
/// The target must be absent or a regular file, checked at creation and again before the
/// rename; anything else (a device, a FIFO, a directory) is an error and is never replaced.
#[derive(Debug)]
pub struct PartialFile {
    /// The temporary file.
    tmp: PathBuf,
    /// Where it goes when complete.
    target: PathBuf,
    /// Renamed: nothing to remove.
    committed: bool,
}

impl PartialFile {
    /// Creates a new temporary file beside `target` and returns its guard and the open file.
    pub fn create(target: &Path) -> io::Result<(PartialFile, File)> {
        check_target(target)?;
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let pid = std::process::id();
        let mut tries = 0;
        loop {
            let n = NEXT_TEMP.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let tmp = dir.join(format!(".wavefront-{pid}-{n}.partial"));
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp)
            {
                Ok(file) => {
                    LIVE.lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .push(tmp.clone());
                    let guard = PartialFile {
                        tmp,
                        target: target.to_path_buf(),
                        committed: false,
                    };
                    return Ok((guard, file));
                }
                // A leftover of an earlier process with this id, or a planted name: next one.
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && tries < 100 => tries += 1,
                Err(e) => return Err(e),
            }
        }
    }

    /// Renames the complete file over its target (the temporary file is removed if that fails).
    pub fn commit(mut self) -> io::Result<()> {
        check_target(&self.target)?;
        std::fs::rename(&self.tmp, &self.target)?;
        self.committed = true;
        self.forget();
        Ok(())
    }

    /// Takes the temporary file off the list [`remove_partials`] removes.
    fn forget(&self) {
        let mut live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = live.iter().position(|p| p == &self.tmp) {
            live.swap_remove(i);
        }
    }
}

impl Drop for PartialFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
            self.forget();
        }
    }
}

/// Writes `bytes` to `path` so that the file appears complete or not at all (see
/// [`PartialFile`]).
pub fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let (guard, mut file) = PartialFile::create(path)?;
    file.write_all(bytes)?;
    drop(file);
    guard.commit()
}

/// An image file whose header is written and whose rows are to come: the encoder both
/// [`ImageStream`]'s writer thread and [`write_rgb8`] run.
enum Body {
    /// PNG: the header and text chunks are written; rows go through a stream writer.
    Png(png::Writer<BufWriter<File>>),
    /// PPM: the P6 header is written; rows are written as they are.
    Ppm(BufWriter<File>),
    /// EXR: nothing is written yet; rows of f32 RGB (little-endian) are encoded block row by
    /// block row (`encode_exr`) as they arrive.
    Exr {
        /// The file.
        out: BufWriter<File>,
        /// Image size.
        size: (u32, u32),
        /// Layer attributes.
        meta: ImageMeta,
    },
}

/// Bytes of one pixel in an [`ImageStream`]'s rows: 8-bit RGB, or f32 RGB for EXR.
fn pixel_bytes(exr: bool) -> usize {
    if exr { 12 } else { 3 }
}

impl Body {
    /// Writes the header of a `width × height` image in `format` (`None`: EXR) to `file`.
    fn start(
        file: File,
        format: Option<ImageFormat>,
        (width, height): (u32, u32),
        meta: &ImageMeta,
        path: &Path,
    ) -> Result<Body, OutputError> {
        let out = BufWriter::new(file);
        let Some(format) = format else {
            if let Some((key, _)) = meta.text.iter().find(|(k, v)| {
                exr::prelude::Text::new_or_none(k).is_none()
                    || exr::prelude::Text::new_or_none(v).is_none()
            }) {
                return Err(io_error(
                    path,
                    io::Error::other(format!("attribute {key:?} is not EXR text")),
                ));
            }
            return Ok(Body::Exr {
                out,
                size: (width, height),
                meta: meta.clone(),
            });
        };
        match format {
            ImageFormat::Png => {
                let mut encoder = png::Encoder::new(out, width, height);
                encoder.set_color(png::ColorType::Rgb);
                encoder.set_depth(png::BitDepth::Eight);
                encoder.set_compression(png::Compression::Fast);
                encoder.set_filter(png::Filter::Adaptive);
                for (keyword, text) in &meta.text {
                    encoder
                        .add_text_chunk(keyword.clone(), text.clone())
                        .map_err(|e| encode_error(path, e))?;
                }
                let writer = encoder.write_header().map_err(|e| encode_error(path, e))?;
                Ok(Body::Png(writer))
            }
            ImageFormat::Ppm => {
                let mut out = out;
                write!(out, "P6\n{width} {height} 255\n").map_err(|e| io_error(path, e))?;
                Ok(Body::Ppm(out))
            }
        }
    }

    /// Writes the image's rows (`expected` bytes in all, in batches of whole rows), then ends the
    /// file and flushes it.
    fn finish<B: AsRef<[u8]>, I: IntoIterator<Item = B>>(
        self,
        batches: I,
        expected: u64,
        path: &Path,
    ) -> Result<(), OutputError>
    where
        I::IntoIter: Send,
    {
        match self {
            Body::Png(mut writer) => {
                let mut stream = writer
                    .stream_writer_with_size(PNG_IDAT_BYTES)
                    .map_err(|e| encode_error(path, e))?;
                for batch in batches {
                    stream
                        .write_all(batch.as_ref())
                        .map_err(|e| io_error(path, e))?;
                }
                stream.finish().map_err(|e| encode_error(path, e))?;
                writer.finish().map_err(|e| encode_error(path, e))
            }
            Body::Ppm(mut out) => {
                let mut written = 0u64;
                for batch in batches {
                    out.write_all(batch.as_ref())
                        .map_err(|e| io_error(path, e))?;
                    written += batch.as_ref().len() as u64;
                }
                if written != expected {
                    let missing = io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        format!("{written} of {expected} pixel bytes"),
                    );
                    return Err(io_error(path, missing));
                }
                out.flush().map_err(|e| io_error(path, e))
            }
            Body::Exr { out, size, meta } => {
                let band = Mutex::new(Band {
                    batches: batches.into_iter(),
                    rows: Vec::new(),
                    first: 0,
                    row: row_bytes(size.0, true),
                    short: false,
                });
                let pixel = |x: usize, y: usize| {
                    let mut band = band.lock().unwrap_or_else(|e| e.into_inner());
                    band.pixel(x, y)
                };
                encode_exr(out, size, &meta, pixel, path)?;
                let band = band.into_inner().unwrap_or_else(|e| e.into_inner());
                if band.short {
                    let missing = io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        format!("the rows ended before the {} rows of the image", size.1),
                    );
                    return Err(io_error(path, missing));
                }
                Ok(())
            }
        }
    }
}

/// The rows of an EXR stream the encoder is reading: from the first row of the current block
/// row to the last row received (at most a block row and a batch).
struct Band<I> {
    /// Row batches still to come.
    batches: I,
    /// Rows `first..` as f32 RGB bytes.
    rows: Vec<u8>,
    /// The image row `rows` starts at.
    first: usize,
    /// Bytes of one row.
    row: usize,
    /// The batches ended before a row asked for (the file is then an error).
    short: bool,
}

impl<I: Iterator<Item = B>, B: AsRef<[u8]>> Band<I> {
    /// Pixel `(x, y)`; rows before `y`'s block row are dropped, rows up to `y` are received.
    fn pixel(&mut self, x: usize, y: usize) -> (f32, f32, f32) {
        let block = y / exr_block_rows() * exr_block_rows();
        if block > self.first {
            let gone = ((block - self.first) * self.row).min(self.rows.len());
            self.rows.drain(..gone);
            self.first += gone / self.row.max(1);
        }
        while (self.first + self.rows.len() / self.row.max(1)) <= y && !self.short {
            match self.batches.next() {
                Some(b) => self.rows.extend_from_slice(b.as_ref()),
                None => self.short = true,
            }
        }
        let at = (y.wrapping_sub(self.first)) * self.row + 12 * x;
        match (y >= self.first)
            .then(|| self.rows.get(at..at + 12))
            .flatten()
        {
            Some(p) => {
                let c = |k: usize| f32::from_le_bytes([p[k], p[k + 1], p[k + 2], p[k + 3]]);
                (c(0), c(4), c(8))
            }
            None => {
                self.short = true;
                (0.0, 0.0, 0.0)
            }
        }
    }
}

fn io_error(path: &Path, source: io::Error) -> OutputError {
    OutputError::Io {
        file: path.to_path_buf(),
        source,
    }
}

fn encode_error(path: &Path, source: png::EncodingError) -> OutputError {
    match source {
        png::EncodingError::IoError(source) => io_error(path, source),
        source => OutputError::Encode {
            file: path.to_path_buf(),
            source,
        },
    }
}

/// Bytes of one row of 8-bit RGB (of f32 RGB for EXR).
fn row_bytes(width: u32, exr: bool) -> usize {
    pixel_bytes(exr) * width as usize
}

/// Writes 8-bit RGB pixels (row-major, row 0 at the top) to `path` as PNG or binary PPM (by
/// extension), with `meta` as PNG text chunks, atomically. The same encoder as [`ImageStream`].
pub fn write_rgb8(
    path: &Path,
    (width, height): (u32, u32),
    meta: &ImageMeta,
    rgb: &[u8],
) -> Result<(), OutputError> {
    let format = ImageFormat::from_path(path)?;
    let expected = 3 * u64::from(width) * u64::from(height);
    debug_assert_eq!(rgb.len() as u64, expected, "rgb holds the whole image");
    let (guard, file) = PartialFile::create(path).map_err(|e| io_error(path, e))?;
    let body = Body::start(file, Some(format), (width, height), meta, path)?;
    body.finish(rgb.chunks(row_bytes(width, false).max(1)), expected, path)?;
    guard.commit().map_err(|e| io_error(path, e))
}

/// An image file written while the image renders: a [`PixelSink`] that encodes each wave's
/// pixels to 8 bits (f32 for `.exr`) and sends every completed row to a writer thread (PNG through
/// [`png::StreamWriter`], PPM, or EXR block row by block row), so memory is bounded by the wave
/// and a few rows, not the image.
///
/// Pixels the schedule never delivers (outside a rendered pixel range) are black, as in a
/// [`crate::Film`]. [`ImageStream::finish`] completes the file and renames it into place; dropping
/// the stream unfinished, or any error, removes the partial file.
#[derive(Debug)]
pub struct ImageStream {
    /// The target path (for errors).
    path: PathBuf,
    /// Image width, for row bookkeeping.
    width: u32,
    /// `1 / gamma`, cached for the per-channel encoding.
    inv_gamma: f32,
    /// An EXR file: rows are f32 RGB (linear, no gamma), not 8-bit.
    exr: bool,
    /// Pixels in the image.
    total: u64,
    /// The next pixel expected: every pixel before it is encoded (sent, or in `pending`).
    next: u64,
    /// Encoded bytes not yet sent: less than one row between calls.
    pending: Vec<u8>,
    /// Row batches to the writer thread; `None` once the thread has stopped taking them.
    rows: Option<Sender<Vec<u8>>>,
    /// The writer thread and what it returns.
    writer: Option<JoinHandle<Result<(), OutputError>>>,
    /// The temporary file, renamed into place on success.
    partial: Option<PartialFile>,
}

impl ImageStream {
    /// Opens `path` (its `.partial` name) for a `width × height` image in the format its extension
    /// names (`.png`, `.ppm`, `.exr`), writes the header and `meta`'s text chunks (EXR: as the
    /// rows come), and starts the writer thread. Fails — leaving no file — on an unsupported
    /// extension, an unwritable path or invalid metadata.
    pub fn create(
        path: &Path,
        (width, height): (u32, u32),
        gamma: f32,
        meta: &ImageMeta,
    ) -> Result<ImageStream, OutputError> {
        let exr = is_exr(path);
        let format = if exr {
            None
        } else {
            Some(ImageFormat::from_path(path)?)
        };
        let (partial, file) = PartialFile::create(path).map_err(|e| io_error(path, e))?;
        let body = Body::start(file, format, (width, height), meta, path)?;
        let total = u64::from(width) * u64::from(height);
        let (sender, receiver): (Sender<Vec<u8>>, Receiver<Vec<u8>>) =
            crossbeam_channel::bounded(CHANNEL_BATCHES);
        let target = path.to_path_buf();
        let writer = std::thread::Builder::new()
            .name("image-writer".into())
            .spawn(move || body.finish(receiver, pixel_bytes(exr) as u64 * total, &target))
            .map_err(|e| io_error(path, e))?;
        Ok(ImageStream {
            path: path.to_path_buf(),
            width,
            inv_gamma: 1.0 / gamma,
            exr,
            total,
            next: 0,
            pending: Vec::new(),
            rows: Some(sender),
            writer: Some(writer),
            partial: Some(partial),
        })
    }

    /// Encodes black up to pixel `until` (a gap the schedule did not render).
    fn fill_black(&mut self, until: u64) {
        while self.next < until && self.rows.is_some() {
            let n = (until - self.next).min(FILL_PIXELS);
            let bytes = pixel_bytes(self.exr) * n as usize;
            self.pending.resize(self.pending.len() + bytes, 0);
            self.next += n;
            self.send_rows();
        }
    }

    /// Sends the completed rows in `pending` to the writer thread, keeping the partial row.
    fn send_rows(&mut self) {
        let row = row_bytes(self.width, self.exr).max(1);
        let complete = self.pending.len() / row * row;
        if complete == 0 {
            return;
        }
        let rest = self.pending[complete..].to_vec();
        self.pending.truncate(complete);
        let batch = std::mem::replace(&mut self.pending, rest);
        if let Some(rows) = &self.rows
            && rows.send(batch).is_err()
        {
            // The writer thread stopped (its error comes out of `finish`).
            self.rows = None;
        }
    }

    /// Completes the image (black after the last delivered pixel), waits for the writer thread
    /// and renames the file into place; or returns the first error, removing the partial file.
    pub fn finish(mut self) -> Result<(), OutputError> {
        self.fill_black(self.total);
        debug_assert!(self.pending.is_empty() || self.rows.is_none());
        self.rows = None; // closes the channel: the writer ends the file
        let written = match self.writer.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) | None => Err(io_error(
                &self.path,
                io::Error::other("the image writer thread panicked"),
            )),
        };
        written?;
        match self.partial.take() {
            Some(partial) => partial.commit().map_err(|e| io_error(&self.path, e)),
            None => Ok(()),
        }
    }
}

impl PixelSink for ImageStream {
    fn put(&mut self, first: PixelIndex, pixels: &[Vec3]) {
        let first = u64::from(first.0);
        debug_assert!(first >= self.next, "waves arrive in pixel order");
        debug_assert!(first + pixels.len() as u64 <= self.total);
        self.fill_black(first);
        if self.rows.is_none() {
            return;
        }
        // On the calling thread: a wave's pixels take microseconds, and the wave workers keep
        // the cores (waking the pool's threads per wave cost more than it saved).
        let start = self.pending.len();
        let size = pixel_bytes(self.exr);
        self.pending.resize(start + size * pixels.len(), 0);
        let out = &mut self.pending[start..];
        if self.exr {
            // Linear radiance as it is (no gamma, no clamp; SPEC §13).
            for (rgb, p) in out.chunks_exact_mut(size).zip(pixels) {
                for (o, c) in rgb.chunks_exact_mut(4).zip(p.to_array()) {
                    o.copy_from_slice(&c.to_le_bytes());
                }
            }
        } else {
            encode_rgb8(pixels, self.inv_gamma, out);
        }
        self.next = first + pixels.len() as u64;
        self.send_rows();
    }

    fn accepts(&self) -> bool {
        self.rows.is_some()
    }
}

impl Drop for ImageStream {
    fn drop(&mut self) {
        // Unfinished: stop the writer, then let `partial` remove the file.
        self.rows = None;
        if let Some(writer) = self.writer.take() {
            let _ = writer.join();
        }
    }
}

/// Saving a whole film (a render that is not streamed).
impl Film {
    /// Writes the image as `.png` or `.ppm` (by extension). The file appears complete or not at
    /// all: it is written to a temporary name beside it and renamed. The same encoder as a
    /// streamed render ([`ImageStream`]): the same pixels give the same bytes.
    pub fn save(&self, path: &Path, gamma: f32) -> Result<(), OutputError> {
        self.save_with(path, gamma, &ImageMeta::default())
    }

    /// [`Film::save`] with metadata (PNG text chunks). A `.exr` path gets the linear radiance
    /// (f32 RGB, no gamma, no clamp; SPEC §13) through [`write_exr`].
    pub(crate) fn save_with(
        &self,
        path: &Path,
        gamma: f32,
        meta: &ImageMeta,
    ) -> Result<(), OutputError> {
        if is_exr(path) {
            return write_exr(path, self);
        }
        write_rgb8(path, (self.width, self.height), meta, &self.to_rgb8(gamma))
    }
}

/// Writes 8-bit RGB pixels to `path` as PNG or binary PPM (P6), atomically: the bytes go to a
/// temporary file beside it, which is renamed over `path` only when complete.
pub fn save_rgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), OutputError> {
    write_rgb8(path, (width, height), &ImageMeta::default(), rgb)
}

/// True when `path` names an OpenEXR file (`.exr`, any case).
pub fn is_exr(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

/// Writes `film`'s linear radiance as OpenEXR (f32 RGB, no gamma, no clamp; SPEC §13),
/// atomically, from the whole film in memory ([`ImageStream`] streams the same bytes).
pub fn write_exr(path: &Path, film: &crate::film::Film) -> Result<(), OutputError> {
    write_exr_with(path, film, &ImageMeta::default())
}

/// [`write_exr`] with `meta`'s text as string attributes of the layer (a tile's bounds, image
/// size and fingerprint, as PNG tiles carry them in text chunks).
pub fn write_exr_with(
    path: &Path,
    film: &crate::film::Film,
    meta: &ImageMeta,
) -> Result<(), OutputError> {
    let width = film.width as usize;
    let pixels = |x: usize, y: usize| {
        let c = film.pixels[y * width + x];
        (c.x, c.y, c.z)
    };
    let mut bytes = std::io::Cursor::new(Vec::new());
    encode_exr(&mut bytes, (film.width, film.height), meta, pixels, path)?;
    write_atomically(path, bytes.get_ref()).map_err(|e| io_error(path, e))
}

/// Rows per EXR block: the height of the tiles of the encoding `encode_exr` uses (its blocks
/// are written tile row after tile row, so a stream holds at most this many rows).
pub fn exr_block_rows() -> usize {
    match exr_encoding().blocks {
        exr::prelude::Blocks::Tiles(size) => size.height(),
        exr::prelude::Blocks::ScanLines => exr_encoding().compression.scan_lines_per_block(),
    }
}

/// The one EXR encoding: RLE in 64 × 64 tiles, increasing-Y order — the same pixels give the same
/// bytes whatever the thread count (SPEC §13; `FAST_LOSSLESS` leaves the order unspecified).
fn exr_encoding() -> exr::prelude::Encoding {
    exr::prelude::Encoding {
        line_order: exr::prelude::LineOrder::Increasing,
        ..exr::prelude::Encoding::FAST_LOSSLESS
    }
}

/// Encodes a `width × height` EXR of `pixels(x, y)` (linear RGB) to `out`, with `meta`'s text as
/// layer attributes. The blocks are made one after another in increasing Y (tile rows top to
/// bottom), each pixel asked for once: [`ImageStream`] feeds `pixels` from rows as they arrive.
fn encode_exr(
    out: impl Write + io::Seek,
    (width, height): (u32, u32),
    meta: &ImageMeta,
    pixels: impl Fn(usize, usize) -> (f32, f32, f32) + Sync,
    path: &Path,
) -> Result<(), OutputError> {
    use exr::prelude::{
        AttributeValue, Image, Layer, LayerAttributes, SpecificChannels, Text, Vec2, WritableImage,
    };
    let mut attributes = LayerAttributes::default();
    for (key, value) in &meta.text {
        let (Some(k), Some(v)) = (Text::new_or_none(key), Text::new_or_none(value)) else {
            return Err(io_error(
                path,
                io::Error::other(format!("attribute {key:?} is not EXR text")),
            ));
        };
        attributes.other.insert(k, AttributeValue::Text(v));
    }
    let layer = Layer::new(
        (width as usize, height as usize),
        attributes,
        exr_encoding(),
        SpecificChannels::rgb(|p: Vec2<usize>| pixels(p.x(), p.y())),
    );
    // Sequential: blocks are extracted in order on this thread (what a stream needs); the
    // compressed bytes are the same as a parallel write's.
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(out)
        .map_err(|e| match e {
            exr::error::Error::Io(e) => io_error(path, e),
            e => io_error(path, io::Error::other(e)),
        })
}

/// An EXR file read back: its size, linear RGB pixels (row-major) and string attributes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExrImage {
    /// Width and height.
    pub size: (u32, u32),
    /// Linear RGB, row-major, row 0 at the top.
    pub pixels: Vec<glam::Vec3>,
    /// The layer's string attributes.
    pub text: Vec<(String, String)>,
}

/// Reads the first RGB layer of an OpenEXR file with its string attributes.
pub fn read_exr(path: &Path) -> Result<ExrImage, String> {
    use exr::prelude::{AttributeValue, ReadChannels, ReadLayers};
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            |size, _| {
                (
                    size.width(),
                    vec![glam::Vec3::ZERO; size.width() * size.height()],
                )
            },
            |(w, pixels): &mut (usize, Vec<glam::Vec3>), p, (r, g, b): (f32, f32, f32)| {
                pixels[p.y() * *w + p.x()] = glam::Vec3::new(r, g, b)
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| e.to_string())?;
    let layer = image.layer_data;
    let size = layer.size;
    let text = layer
        .attributes
        .other
        .iter()
        .filter_map(|(k, v)| match v {
            AttributeValue::Text(t) => Some((k.to_string(), t.to_string())),
            _ => None,
        })
        .collect();
    Ok(ExrImage {
        size: (size.width() as u32, size.height() as u32),
        pixels: layer.channel_data.pixels.1,
        text,
    })
}
