//! The stage registry: every stage's stable label, its kernels and the queue columns they read and
//! write, collected from each stage's kernel declarations ([`crate::kernels!`]: each kernel's
//! name with the column sets it takes), so names and columns come from the stage files.
//!
//! `plan`, `--stats`, the benchmark ids and the queue-traffic model all read it;
//! [`columns_table`] renders it as the Markdown table the README and `stages/mod.rs` show (a test
//! checks that they match).

use std::fmt;

use crate::queue::{Access, Column, ColumnAccess, KernelDecl};
use crate::stages::{generate, intersect, reflect, shade, shadow};

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

    /// The kernels the stage runs, in order (as the schedule calls them), with their column
    /// sets: the stage file's `KERNELS`.
    pub fn kernels(self) -> &'static [KernelDecl] {
        match self {
            Stage::Generate => generate::KERNELS,
            Stage::Intersect => intersect::KERNELS,
            Stage::Shade => shade::KERNELS,
            Stage::Shadow => shadow::KERNELS,
            Stage::Reflect => reflect::KERNELS,
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
        columns_of(self.kernels())
    }

    /// The columns of the shade stage's hit-mask variant.
    pub fn mask_columns() -> Vec<ColumnAccess> {
        columns_of(shade::MASK_KERNELS)
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

/// Every column `kernels` touch, kernel by kernel.
fn columns_of(kernels: &[KernelDecl]) -> Vec<ColumnAccess> {
    kernels.iter().flat_map(KernelDecl::columns).collect()
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
pub(crate) fn format_columns(columns: &[Column]) -> String {
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
        s.push_str(&table_row(stage.label(), stage.kernels(), stage.context()));
    }
    s
}

/// One row of [`columns_table`]: a stage's label, kernels, context and distinct columns.
fn table_row(label: &str, kernels: &[KernelDecl], context: &str) -> String {
    let names: Vec<String> = kernels.iter().map(|k| format!("`{}`", k.name)).collect();
    let columns = columns_of(kernels);
    format!(
        "| `{label}` | {} | {context} | {} | {} |\n",
        names.join(", "),
        format_columns(&distinct(&columns, Access::Read)),
        format_columns(&distinct(&columns, Access::Write)),
    )
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

    /// Test kernels: a stage that gains a kernel shows it, with its columns, in its row.
    #[allow(dead_code)]
    mod probe {
        use glam::Vec3;

        use crate::queue::{HitQueue, SampleSlot};

        crate::column_set! {
            /// What the probe kernel reads.
            pub struct ProbeHits<'a>: read HitQueue { slot: SampleSlot, point: Vec3 }
        }

        /// A kernel added to the reflect stage.
        pub fn probe_kernel(_hits: ProbeHits<'_>) {}

        crate::kernels! {
            /// Reflect's kernels and the probe.
            pub const KERNELS = [
                spawn_reflection_rays(ReflectHits, NextRays),
                probe_kernel(ProbeHits),
            ];
        }

        use crate::stages::reflect::{NextRays, ReflectHits, spawn_reflection_rays};
    }

    #[test]
    fn kernel_names_and_columns_come_from_the_stage_declarations() {
        let names = |s: Stage| s.kernels().iter().map(|k| k.name).collect::<Vec<_>>();
        assert_eq!(
            names(Stage::Intersect),
            ["intersect_closest", "compact_hits"]
        );
        assert_eq!(
            names(Stage::Shade),
            ["shade_hits", "add_emitted", "spawn_shadow_rays"]
        );
        let row = table_row(
            "reflect",
            Stage::Reflect.kernels(),
            Stage::Reflect.context(),
        );
        let added = table_row("reflect", probe::KERNELS, Stage::Reflect.context());
        assert!(!row.contains("probe_kernel"));
        assert!(
            added.starts_with("| `reflect` | `spawn_reflection_rays`, `probe_kernel` |"),
            "{added}"
        );
        // The probe reads `point`, which reflect does not: it shows up among the reads.
        let reads = |r: &str| r.split(" | ").nth(3).unwrap().to_owned();
        assert!(!reads(&row).contains("point"), "{row}");
        assert!(reads(&added).contains("slot, point}"), "{added}");
        let columns: Vec<_> = probe::KERNELS[1].columns().map(|c| c.column.name).collect();
        assert_eq!(columns, ["slot", "point"]);
    }

    /// After every stage call of a render, every queue's columns have one length: on scene A
    /// (shadows, reflections), in passes of few shadow rows, without shadows, and as a hit mask.
    #[test]
    fn every_queue_has_one_length_after_every_stage() {
        use crate::queue::Queue;
        use crate::scene::RenderMode;
        use crate::schedule::{Observer, Queues, RenderOptions, StageRun, render_observed};

        #[derive(Default)]
        struct OneLength(Vec<String>, usize);
        impl Observer for OneLength {
            fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
                let lens = [
                    ("rays", q.rays.column_lens()),
                    ("closest", q.closest.column_lens()),
                    ("hits", q.hits.column_lens()),
                    ("shadows", q.shadows.column_lens()),
                    ("next", q.next.column_lens()),
                    ("samples", q.samples.column_lens()),
                ];
                for (name, l) in lens {
                    if l.iter().any(|&n| n != l[0]) {
                        self.0
                            .push(format!("{} depth {}: {name} {l:?}", run.stage, run.depth));
                    }
                }
                self.1 += 1;
            }
            fn watches_stages(&self) -> bool {
                true
            }
        }
        let mut scenes = vec![];
        let mut a = crate::scene::builtin::spheres();
        (a.image.width, a.image.height, a.image.samples) = (48, 32, 2);
        scenes.push((a.clone(), 1 << 19));
        scenes.push((a.clone(), 100));
        let mut off = a.clone();
        off.render.shadows = false;
        scenes.push((off, 1 << 19));
        let mut mask = a;
        mask.render.mode = RenderMode::HitMask;
        scenes.push((mask, 1 << 19));
        for (scene, shadow_rows) in scenes {
            let world = crate::World::load(&scene).unwrap();
            let options = RenderOptions {
                shadow_rows,
                wave_samples: 500,
                ..RenderOptions::default()
            };
            let mut check = OneLength::default();
            render_observed(&scene, &world, &options, &mut check);
            assert!(check.1 > 10, "{} stage calls", check.1);
            assert!(check.0.is_empty(), "{:?}", check.0);
        }
    }
}
