//! Per-stage, per-depth counters: rays in, rays out, time, throughput (`--stats`).

use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;

use super::{Observer, Stage, StageRun};

/// Totals for one (depth, stage) over all waves.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageStat {
    /// Rays the stage read.
    pub rays_in: u64,
    /// Rays the stage produced (hits, shadow rays, unoccluded rays, reflection rays).
    pub rays_out: u64,
    /// The stage's share of the render's wall time: each call's wall time divided by the waves
    /// traced at once ([`StageRun::waves_in_flight`]), so that on the wave-parallel path (one
    /// wave per thread) the rates are the render's throughput, not one thread's.
    pub seconds: f64,
}

impl StageStat {
    /// Input rays per second, in millions (the throughput figure).
    pub fn mrays_per_s(&self) -> f64 {
        if self.seconds > 0.0 {
            self.rays_in as f64 / self.seconds / 1e6
        } else {
            0.0
        }
    }
}

/// All stage statistics of a render, keyed by (depth, stage).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// Entries in depth order, then pipeline order.
    pub entries: BTreeMap<(u32, Stage), StageStat>,
}

impl Stats {
    /// Adds one stage call.
    pub fn record(
        &mut self,
        stage: Stage,
        depth: u32,
        rays_in: usize,
        rays_out: usize,
        time: Duration,
    ) {
        let e = self.entries.entry((depth, stage)).or_default();
        e.rays_in = e.rays_in.saturating_add(rays_in as u64);
        e.rays_out = e.rays_out.saturating_add(rays_out as u64);
        e.seconds += time.as_secs_f64();
    }

    /// Sum of all stage times.
    pub(crate) fn total_seconds(&self) -> f64 {
        self.entries.values().map(|e| e.seconds).sum()
    }

    /// The entry for (depth, stage), if that stage ran at that depth.
    pub fn get(&self, depth: u32, stage: Stage) -> Option<&StageStat> {
        self.entries.get(&(depth, stage))
    }
}

/// Stats are collected from the schedule's stage records, which both of its paths give (so
/// `--stats` measures the path a plain render takes).
impl Observer for Stats {
    fn stage_done(&mut self, run: &StageRun) {
        let share = run.elapsed / run.waves_in_flight.max(1);
        self.record(run.stage, run.depth, run.rays_in, run.rays_out, share);
    }
    fn watches_stages(&self) -> bool {
        false
    }
}

impl fmt::Display for Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:>5}  {:<10} {:>12} {:>12} {:>10} {:>10}",
            "depth", "stage", "rays in", "rays out", "ms", "Mrays/s"
        )?;
        for ((depth, stage), e) in &self.entries {
            let rate = if *stage == Stage::Generate {
                // generate reads no rays: report rays written per second.
                if e.seconds > 0.0 {
                    e.rays_out as f64 / e.seconds / 1e6
                } else {
                    0.0
                }
            } else {
                e.mrays_per_s()
            };
            writeln!(
                f,
                "{depth:>5}  {:<10} {:>12} {:>12} {:>10.2} {:>10.1}",
                stage.label(),
                e.rays_in,
                e.rays_out,
                e.seconds * 1e3,
                rate
            )?;
        }
        write!(f, "total stage time: {:.2} ms", self.total_seconds() * 1e3)
    }
}
