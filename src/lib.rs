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
//! Rays are entities, SoA columns ([`queue`]) are components, stages ([`stages`]) are systems, and
//! one schedule ([`schedule`]) orders them. Each scene gets only the stages it needs
//! ([`schedule::Pipeline`]). Images are bit-identical for any thread count: every queue stays in
//! sample order and every sample is accumulated in schedule order.
//!
//! Memory is bounded by the wave: shadow rays are spawned and traced in passes of a fixed number
//! of rows however many lights there are ([`stages::shade::ShadowPass`]), and each wave's resolved
//! pixels go to a [`film::PixelSink`] — an in-memory [`Film`], or an image file encoded row by
//! row on a writer thread ([`output::ImageStream`]).
//!
//! `unsafe` code is denied crate-wide; one module opts out, [`simd`] (run-time dispatch to
//! AVX2/AVX-512 builds of a kernel, and the SSE2 lanes of the kD-tree packet traversal), and so
//! does the Embree FFI peer outside the library (`wavefront-kit`'s `peer::embree`, behind a
//! feature).
#![deny(unsafe_code)]

pub mod accel;
pub mod cache;
pub mod error;
pub mod film;
pub mod frame;
pub mod geometry;
pub mod input;
pub mod mesh;
pub mod obj_fast;
pub mod output;
pub mod queue;
pub mod region;
pub mod sampling;
pub mod scene;
pub mod schedule;
pub mod simd;
pub mod stats;
pub mod tile;
pub mod wave;
pub mod world;

#[path = "../stages/mod.rs"]
pub mod stages;

pub use film::Film;
pub use scene::Scene;
pub use schedule::{Pipeline, RenderOptions, Stage, render, render_into, render_observed};
pub use stats::Stats;
pub use world::World;

/// Loads a scene by built-in name or file path.
pub fn load_scene(name_or_path: &str) -> Result<Scene, error::SceneError> {
    if let Some(s) = scene::builtin::builtin(name_or_path) {
        return Ok(s);
    }
    let path = std::path::Path::new(name_or_path);
    if path.exists() {
        scene::file::load(path)
    } else {
        Err(error::SceneError::UnknownScene {
            name: name_or_path.to_owned(),
        })
    }
}
