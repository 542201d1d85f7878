//! Stage benchmarks (`wavefront bench`, `benches/stages.rs`): each stage timed alone on a
//! snapshot of its input queues taken from a real render.
//!
//! Reads: a [`Scene`] and its [`World`]. Writes: a [`Snapshot`] (copies of one wave's queues, depth
//! by depth: `RayQueue` for `intersect`, `HitQueue` for `shade` and `reflect`, `ShadowQueue` for
//! `shadow`) and a [`Report`] of [`Record`]s (stage, depth, rays, seconds).
//!
//! [`Snapshot::capture`] renders the wave through the schedule itself
//! ([`wavefront::render_observed`]) with an observer that copies each stage's input as the
//! schedule hands it over; [`StageBench::run`] then runs one stage on its snapshot through the
//! schedule's own dispatch ([`schedule::run_stage`]). The CLI takes the best of R runs after one
//! warm-up, criterion does its own sampling. With the `embree` feature, [`run`] also traces the
//! same intersect and shadow ray arrays with the Embree peer (`peer::embree`, behind the `embree` feature) and
//! reports project/Embree throughput ratios of the kernels alone.

use std::collections::BTreeMap;
use std::fmt;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use wavefront::error::LoadError;
use wavefront::queue::{HitColumns, HitQueue, RayQueue, ShadowQueue};
use wavefront::region::Region;
use wavefront::scene::Scene;
use wavefront::schedule::{
    self, Observer, Pipeline, Queues, RenderOptions, Stage, StageRun, WaveQueues, render_observed,
};
use wavefront::stages::shade::{ShadedHits, ShadowPass, ShadowRays};
use wavefront::wave::Wave;
use wavefront::world::World;

/// The queues one depth of the snapshot wave read, as the schedule produced them.
#[derive(Clone, Debug)]
pub struct DepthSnapshot {
    /// The bounce counter.
    pub depth: u32,
    /// Input of `intersect`: this depth's rays.
    pub rays: RayQueue,
    /// What `intersect_closest` returned for `rays` (one row per ray), kept to check peers.
    pub closest: HitColumns,
    /// Input of `shade` and `reflect`: the compacted hits, with the surface columns shade wrote
    /// (shade rewrites them with the same values, so one copy serves both stages).
    pub hits: HitQueue,
    /// Input of `shadow` (with the `occluded` answers the schedule computed) in the depth's first
    /// shade → shadow pass (the only one unless the lights need several); `None` when this depth
    /// runs no shadow stage.
    pub shadows: Option<ShadowQueue>,
    /// Whether this depth runs `reflect`.
    pub reflect: bool,
}

/// Every stage input of one wave of a scene.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// The scene's pipeline.
    pub pipeline: Pipeline,
    /// The wave (input of `generate`).
    pub wave: Wave,
    /// Number of waves a full frame renders (the snapshot covers one).
    pub waves: u32,
    /// One entry per depth that had rays, in depth order.
    pub depths: Vec<DepthSnapshot>,
}

/// The observer that copies each stage's input queues out of the schedule: those of the first
/// wave only (a row of the image can hold several waves).
#[derive(Default)]
struct Capture {
    depths: Vec<DepthSnapshot>,
    waves: u32,
}

impl Observer for Capture {
    fn before(&mut self, stage: Stage, depth: u32, q: &Queues<'_>) {
        if stage == Stage::Generate {
            self.waves += 1;
        }
        if self.waves > 1 {
            return;
        }
        if stage == Stage::Intersect {
            self.depths.push(DepthSnapshot {
                depth,
                rays: q.rays.clone(),
                closest: HitColumns::default(),
                hits: HitQueue::default(),
                shadows: None,
                reflect: false,
            });
        }
    }

    fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
        if self.waves > 1 {
            return;
        }
        let Some(d) = self.depths.last_mut() else {
            return;
        };
        match run.stage {
            Stage::Generate => {}
            Stage::Intersect => d.closest = q.closest.clone(),
            // Later passes leave the hits as the first left them.
            Stage::Shade if run.first_pass => d.hits = q.hits.clone(),
            Stage::Shadow if run.first_pass => d.shadows = Some(q.shadows.clone()),
            Stage::Shade | Stage::Shadow => {}
            Stage::Reflect => d.reflect = true,
        }
    }
}

/// Samples in the wave whose queues the stage kernels (and the Embree peer) are timed on: 2^16,
/// a queue far larger than a render's own waves (2^12 samples,
/// [`wavefront::schedule::DEFAULT_WAVE_SAMPLES`]), so a kernel's throughput is measured rather
/// than its fixed cost per call, and the same ray arrays as earlier sessions' figures (Sibenik:
/// the 65,536 camera rays of rows 256–383 and their shadow rays).
pub const SNAPSHOT_WAVE_SAMPLES: usize = 1 << 16;

impl Snapshot {
    /// Renders one wave of [`SNAPSHOT_WAVE_SAMPLES`] samples of `scene` through the schedule,
    /// keeping each stage's input: the whole frame when it fits one wave, else a full wave of
    /// whole rows starting at the image's middle row (the first rows are often all sky). Runs on
    /// the current rayon pool.
    pub fn capture(scene: &Scene, world: &World) -> Snapshot {
        let image = &scene.image;
        // A validated scene has at most u32::MAX pixels.
        let total = u32::try_from(scene.image.pixel_count()).unwrap_or(u32::MAX);
        let snapshot_options = RenderOptions {
            wave_samples: SNAPSHOT_WAVE_SAMPLES,
            ..RenderOptions::default()
        };
        let per_wave = snapshot_options.pixels_per_wave(scene);
        let rows = per_wave.div_ceil(image.width).min(image.height);
        let first_row = (image.height / 2).min(image.height - rows);
        let options = RenderOptions {
            region: Some(Region {
                x0: 0,
                x1: image.width,
                y0: first_row,
                y1: first_row + rows,
            }),
            ..snapshot_options
        };
        let wave = schedule::waves(scene, &options)
            .next()
            .expect("a non-empty image has a wave");
        debug_assert_eq!(wave.pixels, per_wave.min(total));
        let mut capture = Capture::default();
        render_observed(scene, world, &options, &mut capture);
        Snapshot {
            pipeline: Pipeline::for_scene(scene),
            wave,
            waves: total.div_ceil(per_wave.max(1)),
            depths: capture.depths,
        }
    }

    /// The snapshot of `depth`, if that depth had rays.
    pub fn depth(&self, depth: u32) -> Option<&DepthSnapshot> {
        self.depths.iter().find(|d| d.depth == depth)
    }

    /// Every (stage, depth) the wave ran, in schedule order.
    pub fn entries(&self) -> Vec<(Stage, u32)> {
        let mut out = vec![(Stage::Generate, 0)];
        for d in &self.depths {
            out.push((Stage::Intersect, d.depth));
            out.push((Stage::Shade, d.depth));
            if d.shadows.is_some() {
                out.push((Stage::Shadow, d.depth));
            }
            if d.reflect {
                out.push((Stage::Reflect, d.depth));
            }
        }
        out
    }

    /// Rays one run of `stage` at `depth` handles: rays written by `generate`, rays read by the
    /// others (the figure `--stats` divides by). `None` when the wave did not run it.
    pub fn rays(&self, stage: Stage, depth: u32) -> Option<usize> {
        if stage == Stage::Generate {
            return (depth == 0).then_some(self.wave.len());
        }
        let d = self.depth(depth)?;
        match stage {
            Stage::Generate => unreachable!(),
            Stage::Intersect => Some(d.rays.len()),
            Stage::Shade => Some(d.hits.len()),
            Stage::Shadow => d.shadows.as_ref().map(ShadowQueue::len),
            Stage::Reflect => d.reflect.then_some(d.hits.len()),
        }
    }
}

/// Runs single stages on a scene's [`Snapshot`]: the shared core of `wavefront bench` and the
/// criterion benches.
#[derive(Debug)]
pub struct StageBench<'a> {
    scene: &'a Scene,
    world: &'a World,
    /// The stage inputs.
    pub snapshot: Snapshot,
    queues: WaveQueues,
}

impl<'a> StageBench<'a> {
    /// Captures the snapshot of `scene` (on the current rayon pool).
    pub fn new(scene: &'a Scene, world: &'a World) -> StageBench<'a> {
        StageBench {
            scene,
            world,
            snapshot: Snapshot::capture(scene, world),
            queues: WaveQueues::default(),
        }
    }

    /// Copies the input of `stage` at `depth` into the bench's queues (untimed).
    pub fn prepare(&mut self, stage: Stage, depth: u32) {
        let q = &mut self.queues;
        q.samples.reset(self.snapshot.wave.len());
        let Some(d) = self.snapshot.depth(depth) else {
            return;
        };
        match stage {
            Stage::Generate => {}
            Stage::Intersect => q.rays.clone_from(&d.rays),
            Stage::Shade | Stage::Reflect => q.hits.clone_from(&d.hits),
            Stage::Shadow => {
                if let Some(s) = &d.shadows {
                    q.shadows.clone_from(s);
                }
            }
        }
    }

    /// Runs `stage` at `depth` once through the schedule's dispatch on the queues
    /// [`StageBench::prepare`] filled, and returns the rays it handled (see [`Snapshot::rays`]).
    /// Panics when the wave did not run `stage` at `depth`.
    pub fn run_prepared(&mut self, stage: Stage, depth: u32) -> usize {
        let rays = self
            .snapshot
            .rays(stage, depth)
            .unwrap_or_else(|| panic!("the snapshot runs no {stage} at depth {depth}"));
        // The depth's first shade → shadow pass, as the schedule plans it.
        let lights = self.snapshot.pipeline.traced_lights(self.world);
        let hits = self.snapshot.depth(depth).map_or(0, |d| d.hits.len());
        let pass = ShadowPass::plan(hits, lights, RenderOptions::default().shadow_rows)
            .next()
            .unwrap_or_default();
        schedule::run_stage(
            stage,
            self.scene,
            self.world,
            &self.snapshot.pipeline,
            &self.snapshot.wave,
            &pass,
            &mut self.queues,
        );
        rays
    }

    /// The queues the last run left (its output).
    pub fn queues(&self) -> &WaveQueues {
        &self.queues
    }

    /// [`StageBench::prepare`] then [`StageBench::run_prepared`].
    pub fn run(&mut self, stage: Stage, depth: u32) -> usize {
        self.prepare(stage, depth);
        self.run_prepared(stage, depth)
    }

    /// Seconds of the fastest of `repeat` runs of `stage` at `depth` (after one warm-up), each on
    /// a fresh copy of its input; and the rays it handled.
    pub fn best_of(&mut self, repeat: usize, stage: Stage, depth: u32) -> (f64, usize) {
        let mut best = f64::INFINITY;
        let mut rays = 0;
        for i in 0..=repeat.max(1) {
            self.prepare(stage, depth);
            let start = Instant::now();
            rays = self.run_prepared(stage, depth);
            let s = start.elapsed().as_secs_f64();
            if i > 0 {
                best = best.min(s);
            }
        }
        (best, rays)
    }
}

/// Seconds of the fastest of `repeat` runs (at least one) of `f`, after one untimed warm-up.
pub fn best_of(repeat: usize, mut f: impl FnMut()) -> f64 {
    f();
    (0..repeat.max(1))
        .map(|_| seconds(&mut f))
        .fold(f64::INFINITY, f64::min)
}

/// Median seconds of `repeat` runs (at least one) of `f`, without warm-up.
pub fn median_of(repeat: usize, mut f: impl FnMut()) -> f64 {
    median((0..repeat.max(1)).map(|_| seconds(&mut f)).collect())
}

/// Median seconds of `repeat` runs (at least one) of each of `a` and `b`, without warm-up, the
/// runs alternating (a, b, a, b, …) so a change in the machine's load shows in both medians.
pub fn interleaved_medians(repeat: usize, mut a: impl FnMut(), mut b: impl FnMut()) -> (f64, f64) {
    let [ta, tb] = alternating_medians(repeat, &mut [&mut a, &mut b]);
    (ta, tb)
}

/// Median seconds of `samples` runs (at least one) of each of `sides`, after one warm-up run
/// of each, the runs alternating (side 0, 1, …, 0, 1, …) so a change in the machine's load
/// shows in every median.
pub fn interleaved_medians_of<const N: usize>(
    samples: usize,
    sides: &mut [&mut dyn FnMut(); N],
) -> [f64; N] {
    for f in sides.iter_mut() {
        f();
    }
    alternating_medians(samples, sides)
}

/// Median seconds of `samples` runs (at least one) of each of `sides`, without warm-up, the
/// runs alternating.
fn alternating_medians<const N: usize>(
    samples: usize,
    sides: &mut [&mut dyn FnMut(); N],
) -> [f64; N] {
    let mut t = [(); N].map(|_| Vec::new());
    for _ in 0..samples.max(1) {
        for (f, t) in sides.iter_mut().zip(t.iter_mut()) {
            t.push(seconds(f));
        }
    }
    t.map(median)
}

/// The median of `t` (the upper one of an even count); `t` not empty.
fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// Laps over the mirror reflection set per timed sample: at least 2,048 rays a sample (one lap
/// of Sibenik's 3,951 rays, under a millisecond: short enough that most samples see no other
/// process take the core, long enough for the timer).
pub fn reflect_laps(rays: usize) -> usize {
    2048usize.div_ceil(rays.max(1))
}

/// Samples per side of the mirror reflection set for `--repeat repeat`: 60 per repeat, odd, at
/// least 101 (the median of many short samples rides out load spikes).
pub fn reflect_samples(repeat: usize) -> usize {
    (60 * repeat.max(1)).max(101) | 1
}

fn seconds(f: &mut impl FnMut()) -> f64 {
    let start = Instant::now();
    f();
    start.elapsed().as_secs_f64()
}

/// Millions of rays per second.
pub fn mrays_per_s(rays: usize, seconds: f64) -> f64 {
    if seconds > 0.0 {
        rays as f64 / seconds / 1e6
    } else {
        0.0
    }
}

/// One stage (or peer) measurement: one JSON line of `wavefront bench --json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// Scene name.
    pub scene: String,
    /// Stage label (`generate`, `intersect`, `shade`, `shadow`, `reflect`).
    pub stage: String,
    /// The bounce counter.
    pub depth: u32,
    /// Worker threads.
    pub threads: usize,
    /// Rays handled (written by `generate`, read by the others).
    pub rays: usize,
    /// Best time of the kernel alone.
    pub seconds: f64,
    /// `rays / seconds`, in millions.
    pub mrays_per_s: f64,
    /// Peer rows: Mrays/s of the project's own kernel alone (`intersect_closest` or
    /// `intersect_occluded`, without compaction or accumulation) on the same rays, same run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub project_mrays_per_s: Option<f64>,
    /// Peer rows: which peer traced the same rays (e.g. `embree-intersect1`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peer: Option<String>,
    /// Peer rows: project Mrays/s ÷ peer Mrays/s (above 1: the project is faster).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ratio: Option<f64>,
    /// Peer closest-hit rows: rays whose triangle differs from the project's beyond an exact tie
    /// (`t` differs by more than 1e-5 relative, or one side misses).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mismatches: Option<usize>,
    /// Peer closest-hit rows: the mismatches where one side hits and the other misses.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hit_miss: Option<usize>,
    /// Peer closest-hit rows: rays whose triangle differs at the same `t` (exact ties).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ties: Option<usize>,
    /// Peer occlusion rows: rays the peer found occluded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluded: Option<usize>,
    /// Peer occlusion rows: rays the project found occluded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluded_project: Option<usize>,
}

impl Record {
    fn new(scene: &str, stage: Stage, depth: u32, threads: usize, rays: usize, s: f64) -> Record {
        Record {
            scene: scene.to_owned(),
            stage: stage.label().to_owned(),
            depth,
            threads,
            rays,
            seconds: s,
            mrays_per_s: mrays_per_s(rays, s),
            project_mrays_per_s: None,
            peer: None,
            ratio: None,
            mismatches: None,
            hit_miss: None,
            ties: None,
            occluded: None,
            occluded_project: None,
        }
    }

    /// The record as one line of JSON (no trailing newline).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("records serialise")
    }
}

/// A whole-job measurement (full frame, OBJ load, tree builds): one JSON line with a `timing`
/// key instead of `stage`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Scene name.
    pub scene: String,
    /// What was timed: `frame` (median of R renders), `baseline_recursive` (the recursive f32
    /// tracer of [`crate::baseline`] on the same scene and pool, median of R runs alternating
    /// with the frame's), `load_obj`, `tree` (as loaded), `build_sah` (best of R),
    /// `embree_build` (best of R).
    pub timing: String,
    /// Worker threads.
    pub threads: usize,
    /// Seconds.
    pub seconds: f64,
    /// How many runs the figure summarises.
    pub runs: usize,
}

impl Timing {
    /// The timing as one line of JSON (no trailing newline).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("timings serialise")
    }
}

/// What [`run`] measures and how.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BenchConfig {
    /// Worker threads of the rayon pool everything runs on.
    pub threads: usize,
    /// Timed runs per kernel (best taken) and renders per frame figure (median taken).
    pub repeat: usize,
    /// The tree cache the scene is loaded through (`None`: parse and build every time).
    pub cache: Option<wavefront::cache::TreeCache>,
}

/// Everything `wavefront bench` prints.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Scene name.
    pub scene: String,
    /// Worker threads.
    pub threads: usize,
    /// Timed runs per figure.
    pub repeat: usize,
    /// Stage rows, in schedule order.
    pub stages: Vec<Record>,
    /// Peer rows (empty without a peer).
    pub peers: Vec<Record>,
    /// Frame, load and build timings.
    pub timings: Vec<Timing>,
    /// Remarks for the reader (skipped peers, multi-wave snapshots).
    pub notes: Vec<String>,
    /// How close the frame runs to the memory-bandwidth bound.
    pub traffic: Option<Traffic>,
    /// Bytes of queue traffic per ray, per (stage label, depth), over a whole frame (scenes
    /// without a mesh, like [`Report::traffic`]).
    pub bytes_per_ray: BTreeMap<(String, u32), f64>,
}

/// Queue traffic of a frame against the machine's measured memory bandwidth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Traffic {
    /// Samples (primary rays) per second of the median frame.
    pub samples_per_s: f64,
    /// Modelled bytes read and written in queue columns per sample ([`queue_traffic_bytes`]).
    pub bytes_per_sample: f64,
    /// `samples_per_s · bytes_per_sample`, in GB/s.
    pub achieved_gb_per_s: f64,
    /// Measured copy bandwidth of this machine on the same pool, in GB/s ([`copy_bandwidth`]).
    pub machine_gb_per_s: f64,
}

/// Counts the bytes the schedule moves through queue columns, from the stage registry: each
/// stage call touches every column its kernels declare ([`Stage::columns`]) once per row of that
/// column's queue as the stage leaves it (the wave's samples: once per row added, read and
/// written). An [`Observer`] of the schedule.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TrafficMeter {
    /// Bytes counted so far.
    pub bytes: u64,
    /// Per (depth, stage): bytes counted and rays handled (written by `generate`, read by the
    /// others), for the bytes of queue traffic per ray of each stage.
    pub per_stage: BTreeMap<(u32, Stage), (u64, u64)>,
}

impl Observer for TrafficMeter {
    fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
        let bytes = queue_traffic_bytes(run, q);
        self.bytes += bytes;
        let rays = match run.stage {
            Stage::Generate => run.rays_out,
            _ => run.rays_in,
        };
        let e = self.per_stage.entry((run.depth, run.stage)).or_default();
        (e.0, e.1) = (e.0 + bytes, e.1 + rays as u64);
    }
}

/// Bytes one stage call moves through queue columns (see [`TrafficMeter`]).
pub fn queue_traffic_bytes(run: &StageRun, q: &Queues<'_>) -> u64 {
    let rows = |queue: &str| -> usize {
        match queue {
            "RayQueue" if run.stage == Stage::Reflect => q.next.len(),
            "RayQueue" => q.rays.len(),
            "HitColumns" => q.closest.len(),
            "HitQueue" => q.hits.len(),
            "ShadowQueue" => q.shadows.len(),
            // Read-modify-write of one sample per row added.
            "SampleBuffer" if run.stage == Stage::Shadow => 2 * run.rays_out,
            "SampleBuffer" => 2 * q.hits.len(),
            other => unreachable!("queue {other} missing from the traffic model"),
        }
    };
    // A depth's later shade passes only spawn shadow rays (whole hit queue counted: an upper
    // bound when the pass covers a block of the hits).
    let columns = if run.stage == Stage::Shade && !run.first_pass {
        [ShadedHits::COLUMNS, ShadowRays::COLUMNS].concat()
    } else {
        run.stage.columns()
    };
    columns
        .iter()
        .map(|c| (c.column.bytes * rows(c.column.queue)) as u64)
        .sum()
}

/// Best-of-3 parallel copy bandwidth (bytes read + written per second, in GB/s) of a 256 MiB
/// buffer on the current rayon pool: the bound a queue-streaming renderer runs against.
pub fn copy_bandwidth() -> f64 {
    use rayon::prelude::*;
    let n = 32 << 20; // u64 words = 256 MiB
    let src: Vec<u64> = (0..n as u64).into_par_iter().collect();
    let mut dst = vec![0u64; n];
    let s = best_of(3, || {
        dst.par_chunks_mut(1 << 16)
            .zip(src.par_chunks(1 << 16))
            .for_each(|(d, s)| d.copy_from_slice(s));
    });
    std::hint::black_box(&dst);
    2.0 * (n * 8) as f64 / s / 1e9
}

impl Report {
    /// All records and timings, one JSON object per line.
    pub fn json_lines(&self) -> String {
        let mut s = String::new();
        for r in self.stages.iter().chain(&self.peers) {
            s.push_str(&r.to_json());
            s.push('\n');
        }
        for t in &self.timings {
            s.push_str(&t.to_json());
            s.push('\n');
        }
        s
    }

    fn timing(&self, name: &str) -> Option<&Timing> {
        self.timings.iter().find(|t| t.timing == name)
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "scene {} on {} thread(s), best of {} after one warm-up",
            self.scene, self.threads, self.repeat
        )?;
        writeln!(
            f,
            "{:<10} {:>5} {:>10} {:>10} {:>10} {:>8} {:>7}",
            "stage", "depth", "rays", "ms", "Mrays/s", "ns/ray", "B/ray"
        )?;
        for r in &self.stages {
            let ns = if r.rays > 0 {
                format!("{:.2}", r.seconds * 1e9 / r.rays as f64)
            } else {
                "-".into()
            };
            let bytes = self
                .bytes_per_ray
                .get(&(r.stage.clone(), r.depth))
                .map_or("-".into(), |b| format!("{b:.0}"));
            write!(
                f,
                "{:<10} {:>5} {:>10} {:>10.3} {:>10.1} {ns:>8} {bytes:>7}",
                r.stage,
                r.depth,
                r.rays,
                r.seconds * 1e3,
                r.mrays_per_s
            )?;
            writeln!(f)?;
        }
        if let Some(t) = self.timing("frame") {
            writeln!(
                f,
                "frame: {:.2} ms (median of {} renders)",
                t.seconds * 1e3,
                t.runs
            )?;
            if let Some(b) = self.timing("baseline_recursive") {
                writeln!(
                    f,
                    "recursive baseline: {:.2} ms (median of {}); wavefront speed-up over it: {:.2}x",
                    b.seconds * 1e3,
                    b.runs,
                    b.seconds / t.seconds
                )?;
            }
        }
        if let Some(t) = &self.traffic {
            writeln!(
                f,
                "traffic: {:.2} Msamples/s x {:.0} B/sample of queue columns = {:.2} GB/s; \
                 machine copy bandwidth {:.2} GB/s ({:.0}% of the bound)",
                t.samples_per_s / 1e6,
                t.bytes_per_sample,
                t.achieved_gb_per_s,
                t.machine_gb_per_s,
                100.0 * t.achieved_gb_per_s / t.machine_gb_per_s
            )?;
        }
        if let (Some(l), Some(t)) = (self.timing("load_obj"), self.timing("tree")) {
            writeln!(
                f,
                "mesh: OBJ load {:.1} ms, tree build {:.1} ms",
                l.seconds * 1e3,
                t.seconds * 1e3
            )?;
        }
        if !self.peers.is_empty() {
            writeln!(
                f,
                "{:<20} {:<10} {:>5} {:>10} {:>10} {:>10} {:>15}  agreement",
                "peer", "stage", "depth", "rays", "ms", "Mrays/s", "project/peer"
            )?;
            for r in &self.peers {
                let agreement = match (r.mismatches, r.ties, r.occluded, r.occluded_project) {
                    (Some(m), Some(t), _, _) => format!(
                        "{m} mismatches ({} hit/miss), {t} exact ties",
                        r.hit_miss.unwrap_or(0)
                    ),
                    (_, _, Some(o), Some(p)) => format!("{o} occluded (project {p})"),
                    _ => String::new(),
                };
                writeln!(
                    f,
                    "{:<20} {:<10} {:>5} {:>10} {:>10.3} {:>10.1} {:>15.3}  {agreement}",
                    r.peer.as_deref().unwrap_or("?"),
                    r.stage,
                    r.depth,
                    r.rays,
                    r.seconds * 1e3,
                    r.mrays_per_s,
                    r.ratio.unwrap_or(f64::NAN),
                )?;
            }
        }
        if let (Some(e), Some(s)) = (self.timing("embree_build"), self.timing("build_sah")) {
            writeln!(
                f,
                "build: Embree BVH {:.1} ms vs SAH kD tree {:.1} ms (best of {})",
                e.seconds * 1e3,
                s.seconds * 1e3,
                e.runs
            )?;
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        Ok(())
    }
}

/// Why [`run`] could not measure.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The scene's geometry could not be loaded.
    #[error(transparent)]
    Load(#[from] LoadError),
    /// The rayon pool could not start.
    #[error("cannot start the thread pool")]
    Pool(#[from] rayon::ThreadPoolBuildError),
    /// The peer could not build its scene.
    #[error("peer: {0}")]
    Peer(String),
}

/// Loads `scene`, snapshots its first wave and times every stage, a full frame and (with the
/// `embree` feature, for pure triangle scenes) the Embree peer, all on a pool of
/// `config.threads` threads.
pub fn run(scene: &Scene, config: BenchConfig) -> Result<Report, BenchError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads.max(1))
        .build()?;
    pool.install(|| run_on_current_pool(scene, config))
}

fn run_on_current_pool(scene: &Scene, config: BenchConfig) -> Result<Report, BenchError> {
    let threads = rayon::current_num_threads();
    let repeat = config.repeat.max(1);
    let (world, setup) = World::load_cached(scene, config.cache.as_ref())?;
    let mut report = Report {
        scene: scene.name.clone(),
        threads,
        repeat,
        ..Report::default()
    };
    report.notes.extend(setup.warnings.iter().cloned());
    if setup.cache == wavefront::world::CacheStatus::Hit {
        report
            .notes
            .push("mesh and tree read from the tree cache (load_obj, tree)".into());
    }
    let setup = setup.times;
    let mut bench = StageBench::new(scene, &world);
    if bench.snapshot.waves > 1 {
        report.notes.push(format!(
            "stages timed on the middle one of {} waves ({} samples)",
            bench.snapshot.waves,
            bench.snapshot.wave.len()
        ));
    }
    for (stage, depth) in bench.snapshot.entries() {
        let (s, rays) = bench.best_of(repeat, stage, depth);
        report
            .stages
            .push(Record::new(&scene.name, stage, depth, threads, rays, s));
    }

    // The frame as `render` traces it: no stage observer, so one wave per thread at once.
    // The frame and the recursive baseline alternate, so both medians see the same machine.
    let (frame, baseline) = interleaved_medians(
        repeat,
        || {
            render_observed(scene, &world, &RenderOptions::default(), ());
        },
        || {
            std::hint::black_box(crate::baseline::render_recursive(scene, &world));
        },
    );
    if world.triangles().is_none() {
        // Queue traffic counted on one more, untimed, render (the meter watches every stage).
        let mut traffic = TrafficMeter::default();
        render_observed(scene, &world, &RenderOptions::default(), &mut traffic);
        let samples =
            scene.image.width as f64 * scene.image.height as f64 * scene.image.samples as f64;
        let bytes = traffic.bytes as f64 / samples;
        for (&(depth, stage), &(b, rays)) in &traffic.per_stage {
            if rays > 0 {
                let key = (stage.label().to_string(), depth);
                report.bytes_per_ray.insert(key, b as f64 / rays as f64);
            }
        }
        report.traffic = Some(Traffic {
            samples_per_s: samples / frame,
            bytes_per_sample: bytes,
            achieved_gb_per_s: samples / frame * bytes / 1e9,
            machine_gb_per_s: copy_bandwidth(),
        });
    }
    report
        .timings
        .push(timing(scene, "frame", threads, frame, repeat));
    report.timings.push(timing(
        scene,
        "baseline_recursive",
        threads,
        baseline,
        repeat,
    ));
    if world.triangles().is_some() {
        report
            .timings
            .push(timing(scene, "load_obj", threads, setup.load_seconds, 1));
        report
            .timings
            .push(timing(scene, "tree", threads, setup.tree_seconds, 1));
        peers(scene, &world, &bench.snapshot, repeat, &mut report)?;
    }
    Ok(report)
}

fn timing(scene: &Scene, name: &str, threads: usize, seconds: f64, runs: usize) -> Timing {
    Timing {
        scene: scene.name.clone(),
        timing: name.into(),
        threads,
        seconds,
        runs,
    }
}

#[cfg(not(feature = "embree"))]
fn peers(
    _scene: &Scene,
    _world: &World,
    _snapshot: &Snapshot,
    _repeat: usize,
    report: &mut Report,
) -> Result<(), BenchError> {
    report
        .notes
        .push("Embree peer not built (rebuild with `--features embree`)".into());
    Ok(())
}

/// Traces the snapshot's intersect and shadow rays with Embree and adds peer rows and build times.
#[cfg(feature = "embree")]
fn peers(
    scene: &Scene,
    world: &World,
    snapshot: &Snapshot,
    repeat: usize,
    report: &mut Report,
) -> Result<(), BenchError> {
    use crate::peer::embree::{EmbreeScene, TraceOpts};
    use bytemuck::cast_slice;
    use wavefront::accel::kdtree::{BuildMethod, KdTree};

    use wavefront::stages::intersect::{ClosestOut, ClosestRays, intersect_closest};
    use wavefront::stages::shadow::{ShadowTrace, intersect_occluded};

    let Some(tris) = world.triangles() else {
        return Ok(());
    };
    if !world.spheres().is_empty() || !world.planes().is_empty() {
        report.notes.push(
            "Embree peer skipped: the scene has spheres or planes, the peer only triangles".into(),
        );
        return Ok(());
    }
    let threads = report.threads;
    let config = format!("threads={threads}");
    let (v, idx) = (&tris.mesh().vertices, &tris.mesh().indices);
    let embree = EmbreeScene::with_config(v, idx, &config).map_err(BenchError::Peer)?;
    let mut build = embree.build_seconds();
    for _ in 1..repeat {
        let s = EmbreeScene::with_config(v, idx, &config).map_err(BenchError::Peer)?;
        build = build.min(s.build_seconds());
    }
    report
        .timings
        .push(timing(scene, "embree_build", threads, build, repeat));
    let sah = best_of(repeat, || {
        std::hint::black_box(KdTree::build(tris.mesh(), BuildMethod::Sah));
    });
    report
        .timings
        .push(timing(scene, "build_sah", threads, sah, repeat));

    let opts = TraceOpts::parallel();
    let mut rows = vec![];
    for d in &snapshot.depths {
        // The project's kernels alone on the same rays, timed in the same run as the peer.
        let mut closest = HitColumns::default();
        let ours_closest = mrays_per_s(
            d.rays.len(),
            best_of(repeat, || {
                intersect_closest(
                    world,
                    ClosestRays::of(&d.rays),
                    ClosestOut::of(&mut closest),
                )
            }),
        );
        let mut shadows = d.shadows.clone().unwrap_or_default();
        let ours_occluded = mrays_per_s(
            shadows.len(),
            best_of(repeat, || {
                intersect_occluded(world, ShadowTrace::of(&mut shadows))
            }),
        );
        let peer_row = |name: &str, stage: Stage, rays: usize, s: f64| {
            let mut r = Record::new(&scene.name, stage, d.depth, threads, rays, s);
            let ours = if stage == Stage::Shadow {
                ours_occluded
            } else {
                ours_closest
            };
            r.peer = Some(name.into());
            r.project_mrays_per_s = Some(ours);
            r.ratio = Some(ours / r.mrays_per_s);
            r
        };
        let (o, dir) = (cast_slice(&d.rays.origin), cast_slice(&d.rays.direction));
        let n = d.rays.len();
        let (mut t, mut prim) = (vec![0.0; n], vec![0u32; n]);
        for (name, stream) in [("embree-intersect1", false), ("embree-intersect1m", true)] {
            let s = best_of(repeat, || {
                if stream {
                    embree.intersect1m_with(opts, o, dir, &d.rays.t_max, &mut t, &mut prim)
                } else {
                    embree.intersect1_with(opts, o, dir, &d.rays.t_max, &mut t, &mut prim)
                }
            });
            let mut r = peer_row(name, Stage::Intersect, n, s);
            let c = compare_closest(&d.closest, &t, &prim);
            (r.mismatches, r.hit_miss, r.ties) =
                (Some(c.mismatches), Some(c.hit_miss), Some(c.ties));
            rows.push(r);
        }
        if let Some(sh) = &d.shadows {
            let (o, dir) = (cast_slice(&sh.origin), cast_slice(&sh.direction));
            let mut occ = vec![false; sh.len()];
            for (name, stream) in [("embree-occluded1", false), ("embree-occluded1m", true)] {
                let s = best_of(repeat, || {
                    if stream {
                        embree.occluded1m_with(opts, o, dir, &sh.t_max, &mut occ)
                    } else {
                        embree.occluded1_with(opts, o, dir, &sh.t_max, &mut occ)
                    }
                });
                let mut r = peer_row(name, Stage::Shadow, sh.len(), s);
                let ours = sh.occluded.iter().filter(|&&b| b).count();
                let theirs = occ.iter().filter(|&&b| b).count();
                (r.occluded, r.occluded_project) = (Some(theirs), Some(ours));
                if ours.abs_diff(theirs) as f64 > 1e-4 * sh.len() as f64 {
                    report.notes.push(format!(
                        "{name} depth {}: occluded counts differ by more than 0.01%: \
                         embree {theirs}, project {ours} of {}",
                        d.depth,
                        sh.len()
                    ));
                }
                rows.push(r);
            }
        }
    }
    if let Some(depth0) = snapshot.depth(0) {
        mirror_reflections(scene, depth0, repeat, threads, &config, &mut rows, report)?;
    }
    for r in &rows {
        if r.mismatches.is_some_and(|m| m > 0) {
            report.notes.push(format!(
                "{} depth {}: {} rays hit a different triangle at a t more than 1e-5 apart \
                 ({} of them hit on one side and miss on the other)",
                r.peer.as_deref().unwrap_or("?"),
                r.depth,
                r.mismatches.unwrap_or(0),
                r.hit_miss.unwrap_or(0)
            ));
        }
    }
    report.peers = rows;
    Ok(())
}

/// The incoherent closest-hit set: the scene's mesh with a mirror floor added (two triangles
/// spanning the mesh's horizontal extent, 1% of its height above the floor the camera sees), the
/// snapshot's camera rays traced against it, and at every camera ray that hits the mirror a
/// reflection ray (origin on the mirror, nudged up by 1e-4 of the scene's extent; direction
/// reflected about the mirror's normal, `+y`; no `t_max`). Times the project's `intersect`
/// kernel and Embree's `rtcIntersect1` / `rtcIntersect1M` on those rays in the same run, the
/// same way ([`interleaved_medians_of`] over samples of [`reflect_laps`] laps of the set), and
/// adds peer rows (depth 1, peer names `embree-reflect1`, `embree-reflect1m`).
#[cfg(feature = "embree")]
fn mirror_reflections(
    scene: &Scene,
    camera: &DepthSnapshot,
    repeat: usize,
    threads: usize,
    config: &str,
    rows: &mut Vec<Record>,
    report: &mut Report,
) -> Result<(), BenchError> {
    use crate::peer::embree::{EmbreeScene, TraceOpts};
    use bytemuck::cast_slice;
    use glam::Vec3;
    use wavefront::accel::kdtree::BuildMethod;
    use wavefront::mesh::TriangleMesh;
    use wavefront::queue::{RayItem, SampleSlot};
    use wavefront::stages::intersect::{ClosestOut, ClosestRays, intersect_closest};

    let Some(spec) = scene.meshes.first() else {
        return Ok(());
    };
    let mut mesh = TriangleMesh::load_obj(&spec.path)
        .map_err(|e| BenchError::Peer(format!("mirror set: {}", wavefront::error::chain(&e))))?;
    let (lo, hi) = mesh.bounds();
    // The floor: the 2nd percentile of the camera rays' hit heights (world `y`), raised by 1%
    // of the mesh's height so the mirror covers it.
    let eye_y = scene.camera.eye.y as f32;
    let mut heights: Vec<f32> = (0..camera.rays.len())
        .filter(|&i| camera.closest.prim[i].is_hit())
        .map(|i| (camera.rays.origin[i] + camera.rays.direction[i] * camera.closest.t[i]).y + eye_y)
        .collect();
    if heights.is_empty() {
        return Ok(());
    }
    heights.sort_by(f32::total_cmp);
    let y = heights[heights.len() / 50] + 0.01 * (hi.y - lo.y);
    let base = mesh.vertices.len() as u32;
    mesh.vertices.extend([
        [lo.x, y, lo.z],
        [hi.x, y, lo.z],
        [hi.x, y, hi.z],
        [lo.x, y, hi.z],
    ]);
    let mirror = [mesh.len() as u32, mesh.len() as u32 + 1];
    mesh.indices
        .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    let world = World::with_mesh(scene, &mesh, BuildMethod::Sah);
    let Some(tris) = world.triangles() else {
        return Ok(());
    };
    let (v, idx) = (&tris.mesh().vertices, &tris.mesh().indices);
    let mirror_y = v[base as usize][1];
    let nudge = 1e-4 * (hi - lo).max_element();
    // Camera rays against the mirrored scene; reflection rays where they meet the mirror.
    let mut hits = HitColumns::default();
    intersect_closest(
        &world,
        ClosestRays::of(&camera.rays),
        ClosestOut::of(&mut hits),
    );
    let mut rays = RayQueue::default();
    for i in 0..camera.rays.len() {
        if !mirror.contains(&hits.prim[i].0) {
            continue;
        }
        let (o, d) = (camera.rays.origin[i], camera.rays.direction[i]);
        let p = o + d * hits.t[i];
        rays.push(RayItem {
            origin: Vec3::new(p.x, mirror_y + nudge, p.z),
            direction: Vec3::new(d.x, -d.y, d.z),
            t_max: f32::INFINITY,
            weight: Vec3::ONE,
            slot: SampleSlot(i as u32),
        });
    }
    let n = rays.len();
    if n == 0 {
        report
            .notes
            .push("mirror reflections: no camera ray hits the mirror floor".into());
        return Ok(());
    }
    let mut ours = HitColumns::default();
    let embree = EmbreeScene::with_config(v, idx, config).map_err(BenchError::Peer)?;
    let opts = TraceOpts::parallel();
    let (o, dir) = (cast_slice(&rays.origin), cast_slice(&rays.direction));
    let (mut t1, mut prim1) = (vec![0.0; n], vec![0u32; n]);
    let (mut tm, mut primm) = (vec![0.0; n], vec![0u32; n]);
    // The set is small (a few thousand rays, well under a millisecond): one sample traces it
    // `laps` times (the same rays each lap), the three sides' samples alternate, and each
    // side's time is the median of its samples.
    let laps = reflect_laps(n);
    let samples = reflect_samples(repeat);
    let mut sides: [&mut dyn FnMut(); 3] = [
        &mut || {
            for _ in 0..laps {
                intersect_closest(&world, ClosestRays::of(&rays), ClosestOut::of(&mut ours));
            }
        },
        &mut || {
            for _ in 0..laps {
                embree.intersect1_with(opts, o, dir, &rays.t_max, &mut t1, &mut prim1);
            }
        },
        &mut || {
            for _ in 0..laps {
                embree.intersect1m_with(opts, o, dir, &rays.t_max, &mut tm, &mut primm);
            }
        },
    ];
    let [s_ours, s_1, s_1m] = interleaved_medians_of(samples, &mut sides).map(|s| s / laps as f64);
    let ours_mrays = mrays_per_s(n, s_ours);
    for (name, s, t, prim) in [
        ("embree-reflect1", s_1, &t1, &prim1),
        ("embree-reflect1m", s_1m, &tm, &primm),
    ] {
        let mut r = Record::new(&scene.name, Stage::Intersect, 1, threads, n, s);
        r.peer = Some(name.into());
        r.project_mrays_per_s = Some(ours_mrays);
        r.ratio = Some(ours_mrays / r.mrays_per_s);
        let c = compare_closest(&ours, t, prim);
        (r.mismatches, r.hit_miss, r.ties) = (Some(c.mismatches), Some(c.hit_miss), Some(c.ties));
        rows.push(r);
    }
    let hit = ours.prim.iter().filter(|p| p.is_hit()).count();
    report.notes.push(format!(
        "embree-reflect rows: {n} reflection rays off a mirror floor added to the mesh \
         (of {} camera rays), {hit} of them hit; project {ours_mrays:.1} Mrays/s; each side \
         timed as the median of {samples} samples of {laps} lap(s) over the same rays, the \
         three sides' samples alternating (one warm-up sample each)",
        camera.rays.len()
    ));
    Ok(())
}

/// How a peer's closest hits differ from the project's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClosestAgreement {
    /// Rays with a different primitive whose `t` differs by more than 1e-5 relative (a hit
    /// against a miss included).
    pub mismatches: usize,
    /// The mismatches where exactly one side misses (e.g. rays through a shared edge).
    pub hit_miss: usize,
    /// Rays with a different primitive at a `t` within 1e-5 relative (exact ties).
    pub ties: usize,
}

/// Compares a peer's closest hits (`t`, primitive id or `u32::MAX` for a miss) with the
/// project's, row for row.
pub fn compare_closest(project: &HitColumns, t: &[f32], prim: &[u32]) -> ClosestAgreement {
    let mut c = ClosestAgreement::default();
    for i in 0..t.len() {
        if project.prim[i].0 == prim[i] {
            continue;
        }
        let (a, b) = (project.t[i], t[i]);
        if a.is_finite() && b.is_finite() && (a - b).abs() <= 1e-5 * a.abs().max(b.abs()) {
            c.ties += 1;
        } else {
            c.mismatches += 1;
            c.hit_miss += usize::from(a.is_finite() != b.is_finite());
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use wavefront::queue::PrimId;
    use wavefront::render;
    use wavefront::scene::builtin::spheres;

    fn small_spheres() -> Scene {
        let mut scene = spheres();
        scene.image.width = 64;
        scene.image.height = 48;
        scene
    }

    #[test]
    fn snapshot_ray_counts_match_the_render_stats() {
        let scene = small_spheres();
        let world = World::load(&scene).unwrap();
        let snapshot = Snapshot::capture(&scene, &world);
        assert_eq!(snapshot.waves, 1);
        let (_, stats) = render(&scene, &world, RenderOptions::default(), |_, _| {});
        let entries = snapshot.entries();
        assert_eq!(
            entries.len(),
            stats.entries.len(),
            "the same (stage, depth) pairs run"
        );
        for (stage, depth) in entries {
            let stat = stats.get(depth, stage).expect("stage ran in the render");
            let expected = if stage == Stage::Generate {
                stat.rays_out
            } else {
                stat.rays_in
            };
            assert_eq!(
                snapshot.rays(stage, depth),
                Some(expected as usize),
                "{stage} depth {depth}"
            );
        }
        // Scene A: depths 0..=2, shadows at each, reflect at 0 and 1.
        assert_eq!(snapshot.depths.len(), 3);
        assert!(snapshot.depth(1).unwrap().reflect);
        assert!(!snapshot.depth(2).unwrap().reflect);
    }

    #[test]
    fn every_kernel_reproduces_its_snapshot() {
        let scene = small_spheres();
        let world = World::load(&scene).unwrap();
        let mut bench = StageBench::new(&scene, &world);
        for (stage, depth) in bench.snapshot.entries() {
            let rays = bench.run(stage, depth);
            assert_eq!(Some(rays), bench.snapshot.rays(stage, depth));
        }
        let d1 = bench.snapshot.depth(1).unwrap().clone();
        bench.run(Stage::Intersect, 1);
        assert_eq!(bench.queues().closest.prim, d1.closest.prim);
        assert_eq!(bench.queues().hits.slot, d1.hits.slot);
        bench.run(Stage::Shadow, 1);
        let shadows = d1.shadows.as_ref().unwrap();
        assert_eq!(bench.queues().shadows.occluded, shadows.occluded);
        bench.run(Stage::Reflect, 0);
        assert_eq!(bench.queues().next.direction, d1.rays.direction);
        bench.run(Stage::Shade, 1);
        assert_eq!(bench.queues().hits.normal, d1.hits.normal);
        assert_eq!(bench.queues().shadows.radiance, shadows.radiance);
    }

    #[test]
    fn traffic_counts_every_registered_column_once_per_row() {
        let scene = small_spheres();
        let world = World::load(&scene).unwrap();
        let mut meter = TrafficMeter::default();
        let mut stats = wavefront::Stats::default();
        render_observed(
            &scene,
            &world,
            &RenderOptions::default(),
            (&mut meter, &mut stats),
        );
        let rays = stats.get(0, Stage::Generate).unwrap().rays_out;
        // generate writes origin, direction, weight (12 B), t_max and slot (4 B) per ray.
        let generate = 44 * rays;
        assert!(meter.bytes > 4 * generate, "{} vs {generate}", meter.bytes);
        let mut only = TrafficMeter::default();
        let mut generate_only = GenerateOnly(&mut only);
        render_observed(
            &scene,
            &world,
            &RenderOptions::default(),
            &mut generate_only,
        );
        assert_eq!(only.bytes, generate);
        assert_eq!(
            only.per_stage.get(&(0, Stage::Generate)),
            Some(&(generate, rays))
        );
        let summed: u64 = meter.per_stage.values().map(|&(b, _)| b).sum();
        assert_eq!(summed, meter.bytes);
    }

    /// Meters the generate stage alone.
    struct GenerateOnly<'a>(&'a mut TrafficMeter);

    impl Observer for GenerateOnly<'_> {
        fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
            if run.stage == Stage::Generate {
                self.0.after(run, q);
            }
        }
    }

    #[test]
    fn a_scene_without_reflections_snapshots_one_depth() {
        let mut scene = small_spheres();
        scene.render.max_depth = 0;
        scene.render.shadows = false;
        let world = World::load(&scene).unwrap();
        let snapshot = Snapshot::capture(&scene, &world);
        assert_eq!(
            snapshot.entries(),
            vec![
                (Stage::Generate, 0),
                (Stage::Intersect, 0),
                (Stage::Shade, 0)
            ]
        );
        assert_eq!(snapshot.rays(Stage::Shadow, 0), None);
    }

    #[test]
    fn json_lines_parse_with_the_documented_keys() {
        let scene = small_spheres();
        let report = run(
            &scene,
            BenchConfig {
                threads: 1,
                repeat: 1,
                cache: None,
            },
        )
        .unwrap();
        let lines = report.json_lines();
        let mut stages = 0;
        for line in lines.lines() {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            assert_eq!(v["scene"], "spheres");
            assert_eq!(v["threads"], 1);
            assert!(v["seconds"].as_f64().unwrap() >= 0.0);
            if let Some(stage) = v["stage"].as_str() {
                stages += 1;
                assert!(Stage::ALL.iter().any(|s| s.label() == stage), "{stage}");
                assert!(v["depth"].is_u64() && v["rays"].is_u64());
                assert!(v["mrays_per_s"].is_f64());
                let back: Record = serde_json::from_str(line).unwrap();
                let orig = &report.stages[stages - 1];
                assert_eq!(
                    (&back.stage, back.depth, back.rays),
                    (&orig.stage, orig.depth, orig.rays)
                );
                assert!((back.mrays_per_s - orig.mrays_per_s).abs() <= 1e-9 * orig.mrays_per_s);
            } else {
                let timing = v["timing"].as_str().unwrap();
                assert!(
                    ["frame", "baseline_recursive"].contains(&timing),
                    "{timing}"
                );
            }
        }
        assert_eq!(stages, report.stages.len());
        assert_eq!(
            stages, 12,
            "generate + 3 × (intersect, shade, shadow) + 2 reflect"
        );
        let text = report.to_string();
        assert!(text.contains("intersect") && text.contains("frame:"));
        assert!(
            text.contains("speed-up over it"),
            "the baseline ratio is printed"
        );
    }

    #[test]
    fn closest_hit_comparison_separates_ties_from_mismatches() {
        let project = HitColumns {
            t: vec![1.0, 2.0, 3.0, f32::INFINITY, 5.0],
            prim: [0, 1, 2, u32::MAX, 4].map(PrimId).to_vec(),
        };
        let t = [1.0, 2.0, 3.5, 4.0, 5.0 * (1.0 + 1e-6)];
        let prim = [0, 7, 9, 3, 8];
        let c = compare_closest(&project, &t, &prim);
        assert_eq!((c.mismatches, c.hit_miss, c.ties), (2, 1, 2));
    }
}
