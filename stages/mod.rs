//! The stage kernels, in pipeline order. Each is a rayon batch kernel over whole queues; its
//! signature names the columns it reads and writes through column sets
//! ([`crate::column_set!`]), which the stage registry ([`crate::schedule::stage`]) collects into
//! this table (checked against the registry by `tests/plan.rs`):
//!
//! <!-- registry:begin -->
//! | stage | kernels | context | reads | writes |
//! |---|---|---|---|---|
//! | `generate` | `generate_camera_rays` | camera, image settings, wave | — | `RayQueue.{origin, direction, t_max, weight, slot}` |
//! | `intersect` | `intersect_closest`, `compact_hits` | world geometry | `RayQueue.{origin, direction, t_max, weight, slot}`, `HitColumns.{t, prim}` | `HitColumns.{t, prim}`, `HitQueue.{origin, direction, weight, slot, t, prim}` |
//! | `shade` | `shade_hits`, `add_emitted`, `spawn_shadow_rays` | world geometry, materials, lights; shade settings | `HitQueue.{origin, direction, t, prim, weight, slot, emitted, point, normal, shading, material, spawn}` | `HitQueue.{point, normal, material, spawn, shading, emitted}`, `SampleBuffer.{radiance}`, `ShadowQueue.{origin, direction, t_max, radiance, slot}` |
//! | `shadow` | `intersect_occluded`, `add_unoccluded` | world geometry | `ShadowQueue.{origin, direction, t_max, slot, radiance, occluded}` | `ShadowQueue.{occluded}`, `SampleBuffer.{radiance}` |
//! | `reflect` | `spawn_reflection_rays` | world materials | `HitQueue.{spawn, shading, material, direction, weight, slot}` | `RayQueue.{origin, direction, t_max, weight, slot}` |
//! <!-- registry:end -->

pub mod generate;
pub mod intersect;
pub mod reflect;
pub mod shade;
pub mod shadow;
