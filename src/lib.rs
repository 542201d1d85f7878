//! # wavefront
//!
//! A data-oriented wavefront ray tracer: Whitted shading, shadows and mirror reflections of
//! analytic scenes and large triangle meshes (through a kD tree), every stage a parallel batch
//! kernel over a structure-of-arrays ray queue.
//!
//! ## The stage graph
//!
//! ```text
//!            ┌──────────┐  RayQueue[0]   ┌───────────┐  HitQueue   ┌───────┐  emitted   ┌─────────┐
//!  camera ──►│ generate │──────────────►│ intersect │───────────►│ shade │───────────►│         │
//!            └──────────┘               └───────────┘  (misses   └───────┘            │         │
//!                                            ▲          leave)     │    │ ShadowQueue │ samples │─► film
//!                                            │                     │    ▼             │         │
//!                                            │                     │ ┌────────┐ lit   │         │
//!                                            │  RayQueue[k+1]      │ │ shadow │──────►│         │
//!                                            │  ┌─────────┐        │ └────────┘       └─────────┘
//!                                            └──│ reflect │◄───────┘ (α > 0, k < D)
//!                                               └─────────┘
//! ```
//!
//! Rays are entities, SoA columns ([`queue`](mod@queue)) are components, stages ([`stages`]) are systems, and
//! one schedule ([`schedule`]) orders them. Each scene gets only the stages it needs
//! ([`schedule::Pipeline`]). Images are bit-identical for any thread count: every queue stays in
//! sample order and every sample is accumulated in schedule order.
//!
//! Memory is bounded by the wave: shadow rays are spawned and traced in passes of a fixed number
//! of rows however many lights there are ([`queue::pass::ShadowPass`]), and each wave's resolved
//! pixels go to a [`film::PixelSink`] — an in-memory [`Film`], or an image file encoded row by
//! row on a writer thread ([`film::output::ImageStream`]).
//!
//! `unsafe` code is denied crate-wide; one module opts out, [`simd`] (run-time dispatch to
//! AVX2/AVX-512 builds of a kernel, and the SSE2 lanes of the kD-tree packet traversal).
#![deny(unsafe_code)]

// The kD tree's build depth and shadow-bundle order use the platform's log2: they shape the
// work, not any answer (traversal is checked against brute force), so no pixel depends on them.
#[allow(clippy::disallowed_methods)]
pub mod accel;
pub(crate) mod arith;
pub mod error;
pub mod film;
pub mod geometry;
pub mod input;
pub mod mesh;
pub mod queue;
pub mod sampling;
pub mod scene;
pub mod schedule;
pub mod simd;
pub mod world;

#[path = "../stages/mod.rs"]
pub mod stages;

pub use film::Film;
pub use scene::Scene;
pub use schedule::Stats;
pub use schedule::{Pipeline, RenderOptions, Stage, render, render_into, render_observed};
pub use world::{LoadError, World};

/// Loads a scene by built-in name or file path: a scene file, or a bare mesh (`.obj`), which
/// is framed automatically (`scene::framing::bare_mesh`, SPEC §16).
pub fn load_scene(name_or_path: &str) -> Result<Scene, world::LoadError> {
    load_scene_with(name_or_path, &[])
}

/// [`load_scene`] with command-line settings (`--set`, `--size`, SPEC §16) applied: to a scene
/// file's own keys (`scene::set::load_with`); to a built-in or a bare mesh only
/// `image.width` and `image.height` (`scene::set::image_size`; a bare mesh is framed for it).
pub fn load_scene_with(
    name_or_path: &str,
    settings: &[scene::set::Setting],
) -> Result<Scene, world::LoadError> {
    let path = std::path::Path::new(name_or_path);
    let builtin = scene::builtin::builtin(name_or_path);
    if builtin.is_none() && !path.exists() {
        return Err(error::SceneError::UnknownScene {
            name: name_or_path.to_owned(),
        }
        .into());
    }
    if builtin.is_none() && !scene::framing::is_mesh_path(path) {
        return Ok(scene::set::load_with(path, settings)?);
    }
    let (width, height) = scene::set::image_size(settings, name_or_path)?;
    if let Some(mut s) = builtin {
        s.image.width = width.unwrap_or(s.image.width);
        s.image.height = height.unwrap_or(s.image.height);
        return Ok(s);
    }
    mesh::check_format(path)?;
    let mesh = mesh::ObjMesh::read(path)?;
    let size = (width.unwrap_or(512), height.unwrap_or(512));
    Ok(scene::framing::bare_mesh(path, &mesh, size)?)
}
