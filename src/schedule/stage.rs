//! The stage registry: every stage's stable label and the queue columns its kernels read and
//! write, collected from the kernels' own column sets (so it cannot drift from their signatures).
//!
//! `plan`, `--stats`, the benchmark ids and the queue-traffic model all read it;
//! [`columns_table`] renders it as the Markdown table the README and `stages/mod.rs` show (a test
//! checks that they match).

use std::fmt;

use crate::queue::{Access, Column, ColumnAccess};
use crate::stages::generate::CameraRays;
use crate::stages::intersect::{ClosestOut, ClosestRays, CompactHits, CompactOut, CompactRays};
use crate::stages::reflect::{NextRays, ReflectHits};
use crate::stages::shade::{EmittedHits, MaskHits, Samples, ShadeHits, ShadedHits, ShadowRays};
use crate::stages::shadow::{LitRays, ShadowTrace};

/// A stage: one system of the schedule, one or more kernels over queues.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Stage {
    /// Camera rays.
    Generate,
    /// Closest hit, then compaction of the hits.
    Intersect,
    /// Local shading and shadow-ray generation.
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

    /// The stable label (`plan`, `--stats`, benchmark ids).
    pub fn label(self) -> &'static str {
        match self {
            Stage::Generate => "generate",
            Stage::Intersect => "intersect",
            Stage::Shade => "shade",
            Stage::Shadow => "shadow",
            Stage::Reflect => "reflect",
        }
    }

    /// The kernel names the stage runs, in order (as the schedule calls them).
    pub fn kernels(self) -> &'static [&'static str] {
        match self {
            Stage::Generate => &["generate_camera_rays"],
            Stage::Intersect => &["intersect_closest", "compact_hits"],
            Stage::Shade => &["shade_hits", "add_emitted", "spawn_shadow_rays"],
            Stage::Shadow => &["intersect_occluded", "add_unoccluded"],
            Stage::Reflect => &["spawn_reflection_rays"],
        }
    }

    /// What the stage reads besides queues.
    pub fn context(self) -> &'static str {
        match self {
            Stage::Generate => "camera, image settings, wave",
            Stage::Intersect | Stage::Shadow => "world geometry",
            Stage::Shade => "world geometry, materials, lights; shade settings",
            Stage::Reflect => "world materials",
        }
    }

    /// Every column the stage's kernels touch, in kernel order (a column may appear as read by
    /// one kernel and written by another). The shade stage's hit-mask variant is
    /// [`Stage::mask_columns`].
    pub fn columns(self) -> Vec<ColumnAccess> {
        match self {
            Stage::Generate => CameraRays::COLUMNS.to_vec(),
            Stage::Intersect => [
                ClosestRays::COLUMNS,
                ClosestOut::COLUMNS,
                CompactRays::COLUMNS,
                CompactHits::COLUMNS,
                CompactOut::COLUMNS,
            ]
            .concat(),
            Stage::Shade => [
                ShadeHits::COLUMNS,
                EmittedHits::COLUMNS,
                Samples::COLUMNS,
                ShadedHits::COLUMNS,
                ShadowRays::COLUMNS,
            ]
            .concat(),
            Stage::Shadow => [ShadowTrace::COLUMNS, LitRays::COLUMNS, Samples::COLUMNS].concat(),
            Stage::Reflect => [ReflectHits::COLUMNS, NextRays::COLUMNS].concat(),
        }
    }

    /// The columns of the shade stage's hit-mask variant.
    pub fn mask_columns() -> Vec<ColumnAccess> {
        [MaskHits::COLUMNS, EmittedHits::COLUMNS, Samples::COLUMNS].concat()
    }

    /// Distinct columns the stage reads, in first-use order.
    pub fn reads(self) -> Vec<Column> {
        distinct(&self.columns(), Access::Read)
    }

    /// Distinct columns the stage writes, in first-use order.
    pub fn writes(self) -> Vec<Column> {
        distinct(&self.columns(), Access::Write)
    }
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.label())
    }
}

fn distinct(columns: &[ColumnAccess], access: Access) -> Vec<Column> {
    let mut out: Vec<Column> = vec![];
    for c in columns.iter().filter(|c| c.access == access) {
        if !out.contains(&c.column) {
            out.push(c.column);
        }
    }
    out
}

/// `Queue.{a, b}, Other.{c}`: columns grouped by queue in first-use order.
pub fn format_columns(columns: &[Column]) -> String {
    if columns.is_empty() {
        return "—".into();
    }
    let mut groups: Vec<(&str, Vec<&str>)> = vec![];
    for c in columns {
        match groups.iter_mut().find(|(q, _)| *q == c.queue) {
            Some((_, names)) => names.push(c.name),
            None => groups.push((c.queue, vec![c.name])),
        }
    }
    groups
        .iter()
        .map(|(q, names)| format!("`{q}.{{{}}}`", names.join(", ")))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The registry as a Markdown table: stage, kernels, context, columns read, columns written.
pub fn columns_table() -> String {
    let mut s =
        String::from("| stage | kernels | context | reads | writes |\n|---|---|---|---|---|\n");
    for stage in Stage::ALL {
        let kernels: Vec<String> = stage.kernels().iter().map(|k| format!("`{k}`")).collect();
        s.push_str(&format!(
            "| `{}` | {} | {} | {} | {} |\n",
            stage.label(),
            kernels.join(", "),
            stage.context(),
            format_columns(&stage.reads()),
            format_columns(&stage.writes()),
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shade_writes_spawn_and_reflect_reads_it() {
        let spawn = |s: Stage, a: Access| {
            s.columns()
                .iter()
                .any(|c| c.access == a && c.column.queue == "HitQueue" && c.column.name == "spawn")
        };
        assert!(spawn(Stage::Shade, Access::Write));
        assert!(spawn(Stage::Reflect, Access::Read));
        assert!(!Stage::Reflect.reads().iter().any(|c| c.name == "point"));
    }

    #[test]
    fn columns_know_their_row_sizes() {
        let origin = Stage::Intersect.reads()[0];
        assert_eq!(
            (origin.queue, origin.name, origin.bytes),
            ("RayQueue", "origin", 12)
        );
        assert!(
            Stage::Shadow
                .writes()
                .iter()
                .any(|c| c.name == "occluded" && c.bytes == 1)
        );
    }

    #[test]
    fn the_table_has_one_row_per_stage() {
        let t = columns_table();
        assert_eq!(t.lines().count(), 2 + Stage::ALL.len());
        assert!(t.contains("| `generate` | `generate_camera_rays` |"));
    }
}
