//! # wavefront-kit
//!
//! The measuring tools around the [`wavefront`] renderer, kept out of its library: the
//! independent f64 [`oracle`], the per-stage benchmark runner ([`mod@bench`]), the
//! error-against-run-time [`report`], the fixtures the test suites share ([`testkit`]) and scene
//! files written from scenes ([`scene_toml`]). The renderer never depends on this crate. Peers
//! (a recursive C tracer, Embree 4) are not part of the project: `../shared/peers/compare`
//! measures against them side by side.

pub mod bench;
pub mod fuzz;
pub mod meshes;
pub mod oracle;
pub mod report;
pub mod scene_toml;
pub mod testkit;
