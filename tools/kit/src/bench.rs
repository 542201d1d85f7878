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
//! warm-up, criterion does its own sampling. Peers (a recursive C tracer, Embree 4) are measured
//! outside the project, side by side in one run, by `../shared/peers/compare`.

use std::collections::BTreeMap;
use std::fmt;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use wavefront::LoadError;
use wavefront::queue::region::Region;
use wavefront::queue::wave::Wave;
use wavefront::queue::{HitColumns, HitQueue, RayQueue, ShadowQueue};
use wavefront::scene::Scene;
use wavefront::schedule::{
    self, Observer, Pipeline, Queues, RenderOptions, Stage, StageRun, WaveQueues, render_observed,
};
use wavefront::stages::shade::{ShadedHits, ShadowRays};
use wavefront::world::World;

/// The queues one depth of the snapshot wave read, as the schedule produced them.
#[derive(Clone, Debug)]
pub struct DepthSnapshot {
    /// The bounce counter.
    pub depth: u32,
    /// Input of `intersect`: this depth's rays.
    pub rays: RayQueue,
    /// What `intersect_closest` returned for `rays` (one row per ray).
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

/// Samples in the wave whose queues the stage kernels are timed on: 2^16,
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
        let pass = schedule::shadow_passes(hits, lights, RenderOptions::default().shadow_rows)
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
    let mut t: Vec<f64> = (0..repeat.max(1)).map(|_| seconds(&mut f)).collect();
    median(&mut t)
}

/// The median of `t` (the upper one of an even count); `t` not empty.
fn median(t: &mut [f64]) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
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

/// One stage measurement: one JSON line of `wavefront bench --json`.
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
    /// What was timed: `frame` (median of R renders), `load_obj`, `tree` (as loaded), `world`
    /// (setting up a world of many spheres: their BVH), `tree_check_build` and `tree_check` (a
    /// SAH build in the frame centred on the mesh and
    /// [`wavefront::accel::kdtree::KdTree::validate`] of it: what a tree file's check costs).
    pub timing: String,
    /// Worker threads.
    pub threads: usize,
    /// Seconds.
    pub seconds: f64,
    /// How many runs the figure summarises.
    pub runs: usize,
    /// `frame` of a scene without a mesh: the rays one frame traces (every `intersect` and
    /// `shadow` ray, counted by the [`TrafficMeter`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rays: Option<u64>,
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
    pub cache: Option<wavefront::accel::cache::TreeCache>,
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
    /// Frame, load and build timings.
    pub timings: Vec<Timing>,
    /// Remarks for the reader (cache hits, multi-wave snapshots).
    pub notes: Vec<String>,
    /// How close the frame runs to the memory-bandwidth bound.
    pub traffic: Option<Traffic>,
    /// Bytes of queue traffic per ray, per (stage label, depth), over a whole frame (scenes
    /// without a mesh, like [`Report::traffic`]).
    pub bytes_per_ray: BTreeMap<(String, u32), f64>,
    /// Spheres traced through a BVH and its node count, for worlds with more than
    /// [`wavefront::world::SPHERE_BVH_MIN`] spheres.
    pub sphere_bvh: Option<(usize, usize)>,
    /// The depth-0 shadow rays traced by each occluded-query variant (mesh scenes).
    pub shadow_variants: Vec<VariantWork>,
}

/// One traversal variant's work on the snapshot's depth-0 shadow rays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VariantWork {
    /// Variant label (`bundle`, `packet`, `single`).
    pub variant: String,
    /// Rays traced.
    pub rays: u64,
    /// Work counts (light-rooted bundles only; `None` for the uncounted single-ray walk).
    pub counts: Option<wavefront::accel::kdtree::BundleCounts>,
    /// Best time over the bench's repeats, in seconds.
    pub seconds: f64,
}

/// Times the depth-0 shadow rays `q` through the light-rooted bundles (in chunks of
/// [`wavefront::accel::kdtree::KdAccel::OCCLUDED_BATCH`], as the shadow stage), through 4-ray
/// packets (the same chunks) and through the single-ray walk, on the current pool, and counts
/// the bundles' work (one more, counted run at the CPU's SIMD level).
fn shadow_variants(
    tris: &wavefront::world::Triangles,
    q: &ShadowQueue,
    repeat: usize,
) -> Vec<VariantWork> {
    use rayon::prelude::*;
    use wavefront::accel::kdtree::{BundleCounts, KdAccel};
    let accel = tris.accel();
    let n = q.origin().len();
    let chunk = KdAccel::OCCLUDED_BATCH;
    let mut out = vec![false; n];
    let best = |f: &mut dyn FnMut()| {
        (0..repeat.max(1))
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let bundle = best(&mut || {
        out.par_chunks_mut(chunk).enumerate().for_each(|(c, out)| {
            let r = c * chunk..c * chunk + out.len();
            accel.intersect_occluded_batch(
                &q.origin()[r.clone()],
                &q.direction()[r.clone()],
                &q.t_max()[r],
                out,
            );
        })
    });
    let level = wavefront::simd::Level::current();
    let mut counts = BundleCounts::default();
    for (c, out) in out.chunks_mut(chunk).enumerate() {
        let r = c * chunk..c * chunk + out.len();
        counts.add(&accel.intersect_occluded_batch_counted(
            level,
            &q.origin()[r.clone()],
            &q.direction()[r.clone()],
            &q.t_max()[r],
            out,
        ));
    }
    let packet = best(&mut || {
        out.par_chunks_mut(chunk).enumerate().for_each(|(c, out)| {
            let r = c * chunk..c * chunk + out.len();
            accel.occluded_packets(
                &q.origin()[r.clone()],
                &q.direction()[r.clone()],
                &q.t_max()[r],
                out,
            );
        })
    });
    let single = best(&mut || {
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            *o = accel.intersect_occluded(q.origin()[i], q.direction()[i], q.t_max()[i]);
        })
    });
    vec![
        VariantWork {
            variant: "bundle".into(),
            rays: n as u64,
            counts: Some(counts),
            seconds: bundle,
        },
        VariantWork {
            variant: "packet".into(),
            rays: n as u64,
            counts: None,
            seconds: packet,
        },
        VariantWork {
            variant: "single".into(),
            rays: n as u64,
            counts: None,
            seconds: single,
        },
    ]
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
        for r in &self.stages {
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
            write!(
                f,
                "frame: {:.2} ms (median of {} renders)",
                t.seconds * 1e3,
                t.runs
            )?;
            if let Some(rays) = t.rays {
                write!(
                    f,
                    ", {:.2} Mrays/s ({rays} intersect and shadow rays)",
                    mrays_per_s(rays as usize, t.seconds)
                )?;
            }
            writeln!(f)?;
        }
        if let (Some((spheres, nodes)), Some(t)) = (self.sphere_bvh, self.timing("world")) {
            writeln!(
                f,
                "spheres: {spheres} through a BVH of {nodes} nodes, world set up in {:.1} ms",
                t.seconds * 1e3
            )?;
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
        if let (Some(b), Some(c)) = (self.timing("tree_check_build"), self.timing("tree_check")) {
            writeln!(
                f,
                "tree check (as for --kdtree FILE): {:.1} ms, {:.2}x the SAH build it checks ({:.1} ms)",
                c.seconds * 1e3,
                c.seconds / b.seconds,
                b.seconds * 1e3
            )?;
        }
        for v in &self.shadow_variants {
            write!(
                f,
                "shadow rays, {:<6}: {} rays, {:.1} Mrays/s",
                v.variant,
                v.rays,
                mrays_per_s(v.rays as usize, v.seconds)
            )?;
            if let Some(c) = &v.counts {
                let per = |x: u64| x as f64 / (c.lanes.max(1)) as f64;
                write!(
                    f,
                    "; {} bundles of {:.1} lanes, per bundled ray: {:.2} node steps, {:.2} leaves, \
                     {:.2} triangle tests (each against a whole bundle: {:.1} per bundle); \
                     cached occluder answered {:.1}% of lanes, {:.1}% of bundles whole; \
                     {} rays through packets",
                    c.bundles,
                    c.lanes as f64 / c.bundles.max(1) as f64,
                    per(c.nodes),
                    per(c.leaves),
                    per(c.tris),
                    c.tris as f64 / c.bundles.max(1) as f64,
                    100.0 * c.cache_hits as f64 / c.lanes.max(1) as f64,
                    100.0 * c.cache_done as f64 / c.bundles.max(1) as f64,
                    c.fallback
                )?;
            }
            writeln!(f)?;
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
}

/// Loads `scene`, snapshots its first wave and times every stage and a full frame, all on a pool
/// of `config.threads` threads.
pub fn run(scene: &Scene, config: BenchConfig) -> Result<Report, BenchError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads.max(1))
        .build()?;
    pool.install(|| run_on_current_pool(scene, config))
}

fn run_on_current_pool(scene: &Scene, config: BenchConfig) -> Result<Report, BenchError> {
    let threads = rayon::current_num_threads();
    let repeat = config.repeat.max(1);
    let start = Instant::now();
    let (world, setup) = World::load_cached(scene, config.cache.as_ref())?;
    let world_seconds = start.elapsed().as_secs_f64();
    let mut report = Report {
        scene: scene.name.clone(),
        threads,
        repeat,
        ..Report::default()
    };
    report.notes.extend(setup.warnings.iter().cloned());
    report.sphere_bvh = world
        .sphere_bvh()
        .map(|b| (world.spheres().len(), b.bvh().nodes.len()));
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
    let shadows = bench.snapshot.depth(0).and_then(|d| d.shadows.as_ref());
    if let (Some(tris), Some(q)) = (world.triangles(), shadows) {
        report.shadow_variants = shadow_variants(tris, q, repeat);
    }

    // The frame as `render` traces it: no stage observer, so one wave per thread at once.
    let frame = median_of(repeat, || {
        render_observed(scene, &world, &RenderOptions::default(), ());
    });
    let mut frame_timing = timing(scene, "frame", threads, frame, repeat);
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
        let traced = traffic
            .per_stage
            .iter()
            .filter_map(|(&(_, stage), &(_, rays))| {
                matches!(stage, Stage::Intersect | Stage::Shadow).then_some(rays)
            });
        frame_timing.rays = Some(traced.sum());
        report.traffic = Some(Traffic {
            samples_per_s: samples / frame,
            bytes_per_sample: bytes,
            achieved_gb_per_s: samples / frame * bytes / 1e9,
            machine_gb_per_s: copy_bandwidth(),
        });
    }
    report.timings.push(frame_timing);
    if report.sphere_bvh.is_some() {
        report
            .timings
            .push(timing(scene, "world", threads, world_seconds, 1));
    }
    if world.triangles().is_some() {
        report
            .timings
            .push(timing(scene, "load_obj", threads, setup.load_seconds, 1));
        report
            .timings
            .push(timing(scene, "tree", threads, setup.tree_seconds, 1));
        // What `render --kdtree FILE` adds: the check of a tree against its mesh, timed against
        // the SAH build of the same tree in the same (centred) frame.
        let triangles = world.triangles().expect("a mesh");
        let (_, mesh) = triangles.centred_mesh().map_err(LoadError::from)?;
        let start = std::time::Instant::now();
        let tree = wavefront::accel::kdtree::KdTree::build(
            &mesh,
            wavefront::accel::kdtree::BuildMethod::Sah,
        );
        let build = start.elapsed().as_secs_f64();
        let start = std::time::Instant::now();
        let checked = tree.validate(&mesh);
        let check = start.elapsed().as_secs_f64();
        if let Err(e) = checked {
            report
                .notes
                .push(format!("the SAH tree fails its check: {e}"));
        }
        report
            .timings
            .push(timing(scene, "tree_check_build", threads, build, 1));
        report
            .timings
            .push(timing(scene, "tree_check", threads, check, 1));
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
        rays: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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

    /// The many-spheres scene (at 64 × 48, 2,000 spheres): the frame's ray count is every
    /// intersect and shadow ray of the frame, which the snapshot (one wave: the whole frame)
    /// counts stage by stage; the BVH and the world's set-up time are reported.
    #[test]
    fn many_spheres_report_the_frame_rays_and_the_bvh() {
        let mut scene = wavefront::scene::builtin::many_spheres(2000);
        (scene.image.width, scene.image.height) = (64, 48);
        let config = BenchConfig {
            threads: 1,
            repeat: 1,
            cache: None,
        };
        let report = run(&scene, config).unwrap();
        let traced: usize = report
            .stages
            .iter()
            .filter(|r| r.stage == "intersect" || r.stage == "shadow")
            .map(|r| r.rays)
            .sum();
        let frame = report.timing("frame").unwrap();
        assert_eq!(frame.rays, Some(traced as u64));
        assert!(traced > 64 * 48 * 2, "{traced}");
        let (spheres, nodes) = report.sphere_bvh.unwrap();
        // A binary tree with leaves of at most 4 spheres.
        assert!(spheres == 2000 && nodes >= 2 * (2000 / 4) - 1, "{nodes}");
        assert!(report.timing("world").is_some());
        let text = report.to_string();
        assert!(
            text.contains("Mrays/s (") && text.contains("through a BVH of"),
            "{text}"
        );
        let json = report.json_lines();
        let line = json.lines().find(|l| l.contains("\"frame\"")).unwrap();
        let back: Timing = serde_json::from_str(line).unwrap();
        assert_eq!(back.rays, Some(traced as u64));
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
        assert_eq!(bench.queues().closest.prim(), d1.closest.prim());
        assert_eq!(bench.queues().hits.slot(), d1.hits.slot());
        bench.run(Stage::Shadow, 1);
        let shadows = d1.shadows.as_ref().unwrap();
        assert_eq!(bench.queues().shadows.occluded(), shadows.occluded());
        bench.run(Stage::Reflect, 0);
        assert_eq!(bench.queues().next.direction(), d1.rays.direction());
        bench.run(Stage::Shade, 1);
        assert_eq!(bench.queues().hits.normal(), d1.hits.normal());
        assert_eq!(bench.queues().shadows.radiance(), shadows.radiance());
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
                assert!(["frame"].contains(&timing), "{timing}");
            }
        }
        assert_eq!(stages, report.stages.len());
        assert_eq!(
            stages, 12,
            "generate + 3 × (intersect, shade, shadow) + 2 reflect"
        );
        let text = report.to_string();
        assert!(text.contains("intersect") && text.contains("frame:"));
    }
}
