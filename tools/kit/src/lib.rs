//! # wavefront-kit
//!
//! The measuring tools around the [`wavefront`] renderer, kept out of its library: the
//! independent f64 [`oracle`], the recursive f32 [`baseline`] tracer, the per-stage benchmark runner ([`mod@bench`]), the
//! error-against-run-time [`report`], the Embree [`peer`] and the fixtures the test suites share
//! ([`testkit`]). The renderer never depends on this crate.

pub mod baseline;
pub mod bench;
pub mod oracle;
pub mod peer;
pub mod report;
pub mod testkit;
