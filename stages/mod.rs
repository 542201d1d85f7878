//! The stage kernels, in pipeline order. Each is a rayon batch kernel over a whole queue.
//!
//! | stage | reads | writes |
//! |---|---|---|
//! | [`generate`] | camera, wave | `RayQueue` (all columns) |
//! | [`intersect`] | `RayQueue.{origin, direction, t_max}` | `HitColumns.{t, prim}`, then `HitQueue` (compacted) |
//! | [`shade`] | `HitQueue.{origin, direction, weight, slot, t, prim}` | `HitQueue.{point, normal, material}`, emitted radiance, `ShadowQueue` |
//! | [`shadow`] | `ShadowQueue.{origin, direction, t_max}` | occlusion flags; `ShadowQueue.radiance` of unoccluded rows into the film |
//! | [`reflect`] | `HitQueue.{point, normal, material, direction, weight, slot}` | next depth's `RayQueue` |

pub mod generate;
pub mod intersect;
pub mod reflect;
pub mod shade;
pub mod shadow;

/// A stage's stable label, shared by `plan`, `--stats` and benchmark ids.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Stage {
    /// Camera rays.
    Generate,
    /// Closest hit.
    Intersect,
    /// Local shading.
    Shade,
    /// Any-hit occlusion toward lights.
    Shadow,
    /// Mirror reflection rays.
    Reflect,
}

impl Stage {
    /// All stages in pipeline order.
    pub const ALL: [Stage; 5] = [
        Stage::Generate,
        Stage::Intersect,
        Stage::Shade,
        Stage::Shadow,
        Stage::Reflect,
    ];

    /// The stable label.
    pub fn label(self) -> &'static str {
        match self {
            Stage::Generate => "generate",
            Stage::Intersect => "intersect",
            Stage::Shade => "shade",
            Stage::Shadow => "shadow",
            Stage::Reflect => "reflect",
        }
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.label())
    }
}
