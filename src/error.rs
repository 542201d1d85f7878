//! Error types, one per domain: scene files, geometry loading (meshes and trees), output images.
//!
//! Messages are lowercase and name the file and line where there is one.

use std::path::PathBuf;

pub use crate::accel::kdtree::TreeError;
pub use crate::mesh::MeshError;

/// A scene that cannot be read or is not valid.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("cannot read scene file {}: {source}", file.display())]
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
        "no scene file or built-in scene named {name:?} (built-ins: spheres, sibenik, sibenik-shadows)"
    )]
    UnknownScene {
        /// The name given.
        name: String,
    },
    /// A mesh file the scene needs is not there.
    #[error(
        "mesh file not found: {} — the Sibenik mesh (sibenik.obj, 75,284 triangles) belongs at \
         ../shared/data/sibenik/sibenik.obj relative to the project root; put it there, set \
         WAVEFRONT_SIBENIK=/path/to/sibenik.obj, or pass --mesh PATH",
        path.display()
    )]
    MissingMesh {
        /// Where it was looked for.
        path: PathBuf,
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

/// Anything that can go wrong turning a [`crate::scene::Scene`] into a traceable world.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The scene itself is at fault (e.g. a missing mesh).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A mesh file is malformed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A tree file is malformed or does not fit the mesh.
    #[error(transparent)]
    Tree(#[from] TreeError),
}

/// An image that cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The extension is neither `.png` nor `.ppm`.
    #[error("unsupported output format for {}: use a .png or .ppm file name", file.display())]
    Format {
        /// The output path.
        file: PathBuf,
    },
    /// Writing failed.
    #[error("cannot write {}: {source}", file.display())]
    Io {
        /// The output path.
        file: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The PNG encoder failed.
    #[error("cannot encode {}: {source}", file.display())]
    Encode {
        /// The output path.
        file: PathBuf,
        /// The encoder's error.
        source: image::ImageError,
    },
}
