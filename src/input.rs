//! Opening input files: only regular files, and files with a size cap no larger than it.
//!
//! Reads file metadata and bytes; writes nothing. A FIFO would block `open` until a writer comes
//! (forever), a device may never end, a directory is not a file: each is refused before it is
//! opened, with an I/O error naming what it is, and checked again on the opened handle. Scene,
//! MTL and tree files are small text files, so a file past its cap (`SCENE_CAP`, `MTL_CAP`,
//! `TREE_CAP`) is refused before anything is allocated (a 2 GB sparse file would otherwise ask
//! the TOML lexer for 15 GB).

use std::fs::{File, Metadata};
use std::io::{self, Read};
use std::path::Path;

/// Largest scene file read: 16 MiB.
pub(crate) const SCENE_CAP: u64 = 16 << 20;
/// Largest MTL library read: 16 MiB.
pub(crate) const MTL_CAP: u64 = 16 << 20;
/// Largest tree file read: 4 GiB (the text tree of a mesh of tens of millions of triangles).
pub(crate) const TREE_CAP: u64 = 4 << 30;

/// What `meta` is when it is not a regular file (`"a FIFO"`, `"a directory"`, …).
fn not_regular(meta: &Metadata) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_file() {
        None
    } else if t.is_dir() {
        Some("a directory")
    } else if t.is_fifo() {
        Some("a FIFO")
    } else if t.is_char_device() {
        Some("a character device")
    } else if t.is_block_device() {
        Some("a block device")
    } else if t.is_socket() {
        Some("a socket")
    } else {
        Some("not a regular file")
    }
}

/// `Err` naming what `meta` is unless it is a regular file.
fn check_regular(meta: &Metadata) -> io::Result<()> {
    match not_regular(meta) {
        None => Ok(()),
        Some("not a regular file") => Err(io::Error::other("not a regular file")),
        Some(kind) => Err(io::Error::other(format!("is {kind}, not a regular file"))),
    }
}

/// `len` bytes as a short size (`64 MiB`, `3.5 GiB`, `812 bytes`).
pub fn size(len: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    for (unit, name) in UNITS {
        if len >= unit {
            let x = len as f64 / unit as f64;
            return if x.fract() == 0.0 {
                format!("{x} {name}")
            } else {
                format!("{x:.1} {name}")
            };
        }
    }
    format!("{len} bytes")
}

/// Opens `path` for reading if it is a regular file (following symlinks), with its length.
pub(crate) fn open_regular(path: &Path) -> io::Result<(File, u64)> {
    check_regular(&std::fs::metadata(path)?)?;
    let file = File::open(path)?;
    let meta = file.metadata()?;
    check_regular(&meta)?;
    Ok((file, meta.len()))
}

/// True when `path` is not there at all (a broken symlink counts as there: opening it says why).
pub(crate) fn is_absent(path: &Path) -> bool {
    matches!(std::fs::symlink_metadata(path), Err(e) if e.kind() == io::ErrorKind::NotFound)
}

/// The whole regular file at `path`, refused past `cap` bytes (`what` names the kind of file in
/// the error: `scene files are capped at 16 MiB`).
pub(crate) fn read_capped(path: &Path, cap: u64, what: &str) -> io::Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    let too_big = |len: u64| {
        io::Error::other(format!(
            "is {}; {what} are capped at {}",
            size(len),
            size(cap)
        ))
    };
    if len > cap {
        return Err(too_big(len));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    // The file may grow while it is read: never read past the cap.
    file.take(cap + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_capped`] as UTF-8 text.
pub(crate) fn read_text_capped(path: &Path, cap: u64, what: &str) -> io::Result<String> {
    String::from_utf8(read_capped(path, cap, what)?)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "is not UTF-8 text"))
}

/// The whole regular file at `path` as UTF-8 text, without a cap (meshes: checked as they are
/// parsed).
pub fn read_text(path: &Path) -> io::Result<String> {
    read_text_capped(path, u64::MAX - 1, "files")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_short() {
        assert_eq!(size(16 << 20), "16 MiB");
        assert_eq!(size(3 << 29), "1.5 GiB");
        assert_eq!(size(812), "812 bytes");
    }

    #[test]
    fn a_directory_is_named_as_one() {
        let e = open_regular(&std::env::temp_dir()).unwrap_err();
        assert_eq!(e.to_string(), "is a directory, not a regular file");
    }
}
