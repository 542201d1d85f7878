//! The error types every layer shares (scene files, output images) and how errors are printed;
//! a layer's own errors live with it ([`crate::mesh::MeshError`], the tree's `TreeError`,
//! [`crate::world::LoadError`], which gathers them).
//!
//! Messages are lowercase and name the file and line where there is one.
//!
//! **One rule for every error type of the workspace: a message says what failed at its own layer
//! and never repeats its cause.** A wrapped error (an I/O error, an encoder's error) is exposed
//! through [`std::error::Error::source`] only, and whoever prints the error walks the chain once:
//! the CLI prints anyhow's `{:#}`, library code and tests print [`chain`]. Embedding `{source}` in
//! the message as well would print the cause twice (`cannot read scene file /tmp: Is a directory
//! (os error 21): Is a directory (os error 21)`). A wrapper that adds nothing is
//! `#[error(transparent)]`.

use std::path::PathBuf;

/// A scene that cannot be read or is not valid.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("cannot read scene file {}", file.display())]
    Io {
        /// The scene file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The scene file is malformed or holds an invalid value.
    #[error("{}:{line}: {key}: {message}", file.display())]
    Invalid {
        /// The scene file.
        file: PathBuf,
        /// 1-based line of the offending key or value.
        line: usize,
        /// Dotted key path, e.g. `sphere[2].radius`.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// Neither a scene file nor a built-in name.
    #[error(
        "no scene file or built-in scene named {name:?} (built-ins: spheres, sibenik, sibenik-shadows, many-spheres)"
    )]
    UnknownScene {
        /// The name given.
        name: String,
    },
    /// A mesh file the scene needs is not there.
    #[error("mesh file not found: {}{}", path.display(), sibenik_hint(*sibenik))]
    MissingMesh {
        /// Where it was looked for.
        path: PathBuf,
        /// The mesh is the Sibenik cathedral (a built-in scene's, or a file named `sibenik.obj`):
        /// the message says where it belongs.
        sibenik: bool,
    },
    /// A mesh file the scene reads (for its MTL materials) cannot be read.
    #[error("cannot read mesh file {}", file.display())]
    MeshIo {
        /// The mesh file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A frame the scene's camera cannot show (outside its camera path, or a degenerate view).
    #[error("{scene}: {message}")]
    Frame {
        /// The scene's name.
        scene: String,
        /// What is wrong, naming the frame.
        message: String,
    },
    /// A setting overridden on the command line is out of range.
    #[error("invalid setting {key}: {message}")]
    Setting {
        /// The setting, e.g. `--samples`.
        key: String,
        /// What is wrong.
        message: String,
    },
}

/// Where the Sibenik mesh belongs, for [`SceneError::MissingMesh`].
fn sibenik_hint(sibenik: bool) -> &'static str {
    if sibenik {
        " — the Sibenik mesh (sibenik.obj, 75,284 triangles) belongs at \
         ../shared/data/sibenik/sibenik.obj relative to the project root; put it there, set \
         WAVEFRONT_SIBENIK=/path/to/sibenik.obj, or pass --mesh PATH"
    } else {
        ""
    }
}

/// `x` printed short: as Rust prints it when that is short, else in exponent form (`1e308`, not
/// 309 digits; `1e-40`, not 44 zeros).
pub fn short(x: f64) -> String {
    let plain = x.to_string();
    if plain.len() <= 12 {
        plain
    } else {
        format!("{x:e}")
    }
}

/// An image that cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The extension is neither `.png` nor `.ppm`.
    #[error("unsupported output format for {}: use a .png, .ppm or .exr file name", file.display())]
    Format {
        /// The output path.
        file: PathBuf,
    },
    /// Writing failed.
    #[error("cannot write {}", file.display())]
    Io {
        /// The output path.
        file: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The PNG encoder failed (e.g. a text chunk whose keyword is not 1–79 Latin-1 characters).
    #[error("cannot encode {}", file.display())]
    Encode {
        /// The output path.
        file: PathBuf,
        /// The encoder's error.
        source: png::EncodingError,
    },
}

/// An error and its causes on one line, outermost first, joined by `: ` — what the CLI prints,
/// for library code and tests that print errors without anyhow.
pub fn chain(error: &dyn std::error::Error) -> String {
    let mut s = error.to_string();
    let mut cause = error.source();
    while let Some(e) = cause {
        s.push_str(": ");
        s.push_str(&e.to_string());
        cause = e.source();
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::kdtree::TreeError;
    use crate::mesh::MeshError;
    use crate::world::LoadError;

    #[test]
    fn every_wrapped_cause_is_said_once() {
        let io = || std::io::Error::other("disk on fire");
        let errors: Vec<Box<dyn std::error::Error>> = vec![
            Box::new(SceneError::Io {
                file: "s.toml".into(),
                source: io(),
            }),
            Box::new(LoadError::Mesh(MeshError::Read {
                path: "m.obj".into(),
                source: io(),
            })),
            Box::new(LoadError::Tree(TreeError::Io {
                path: "t.kd".into(),
                source: io(),
            })),
            Box::new(OutputError::Io {
                file: "o.png".into(),
                source: io(),
            }),
        ];
        for e in errors {
            let line = chain(e.as_ref());
            assert_eq!(line.matches("disk on fire").count(), 1, "{line}");
            assert!(!e.to_string().contains("disk on fire"), "{e}");
        }
    }
}
