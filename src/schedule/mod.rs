//! The schedule: the one place that orders the stages. Reading [`render_into`]'s loop top to
//! bottom is reading the renderer.
//!
//! ```text
//! for each wave of ≤ wave_samples samples (whole pixels):
//!   depth 0: generate ─► rays[0]
//!   depth k: intersect(rays[k]) ─► hits ─► shade ─► emitted ─────────────► samples
//!                                           │    └► shadow rays ─► shadow ─► samples (unoccluded)
//!                                           │       (shade → shadow once per pass of
//!                                           │        ≤ shadow_rows hits × lights)
//!                                           └► reflect (k < max_depth) ─► rays[k+1]
//!   resolve: samples ─► pixels (box filter) ─► sink (the film, or a streaming image file)
//! ```
//!
//! [`Pipeline::for_scene`] leaves out what a scene does not need: no reflect stage without a
//! reflective material or with `max_depth = 0`, no shadow stage without shadows or lights, no
//! specular evaluation without `ks > 0`, no kD tree without a mesh, no shading at all for a hit mask.

pub(crate) mod observer;
pub(crate) mod passes;
pub mod stage;
pub(crate) mod stats;

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fmt;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use glam::Vec3;

use crate::film::{Film, PixelSink, resolve_wave};
use crate::queue::pass::{MAX_SHADOW_ROWS, ShadowPass};
use crate::queue::region::Region;
use crate::queue::wave::Wave;
use crate::queue::{
    HitColumns, HitQueue, PixelIndex, RayQueue, SampleBuffer, Samples, ShadowQueue,
};
use crate::scene::{RenderMode, Scene, ShadeSettings};
use crate::stages::generate::{CameraRays, generate_camera_rays};
use crate::stages::intersect::{
    ClosestOut, ClosestRays, CompactHits, CompactOut, CompactRays, compact_hits, intersect_closest,
};
use crate::stages::reflect::{NextRays, ReflectHits, spawn_reflection_rays};
use crate::stages::shade::{
    EmittedHits, MaskHits, ShadeHits, ShadeScratch, ShadedHits, ShadowRays, add_emitted,
    shade_hit_mask, shade_hits, spawn_shadow_rays,
};
use crate::stages::shadow::{LitRays, ShadowTrace, add_unoccluded, intersect_occluded};
use crate::world::World;
use observer::RunLog;
pub use observer::{Observer, Progress, Queues, StageRun};
pub use passes::shadow_passes;
pub use stage::Stage;
pub use stats::Stats;

/// Default cap on samples per wave: bounds memory whatever the samples per pixel. 2^12 samples
/// keep a wave's queues at about 2 MB, near the core's L2 (512 KiB on the EPYC used for tuning),
/// and a render traces one wave per thread at once; CPU time is flat from 2^10 to 2^13 and 10%
/// above it at 2^16 (scene A, 16 spp, 1 thread), whose first-touch faults also cost 1 spp ~25%.
pub const DEFAULT_WAVE_SAMPLES: usize = 1 << 12;

/// Largest accepted cap on samples per wave: a wave's sample slots are `u32`, and its queues must
/// fit in memory (2^28 samples already need tens of GB).
pub const MAX_WAVE_SAMPLES: usize = 1 << 28;

/// Default cap on the shadow rays one shade → shadow pass spawns (hits × lights of the pass):
/// bounds memory whatever the number of lights. About 61 bytes a row (candidate radiance, kept
/// row index, the shadow queue's columns): 2^19 rows are 32 MB, which keeps scene A with 2,000
/// lights within 1.5× the peak memory of scene A with one (2^20 rows came to 2.03×).
pub(crate) const DEFAULT_SHADOW_ROWS: usize = 1 << 19;

/// The stages one depth runs, in order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DepthPlan {
    /// The bounce counter.
    pub depth: u32,
    /// Stages, in order.
    pub stages: Vec<Stage>,
}

/// A scene's pipeline: stages per depth, plus what the shade stage evaluates.
#[derive(Clone, Debug, PartialEq)]
pub struct Pipeline {
    /// One entry per depth that can have rays.
    pub depths: Vec<DepthPlan>,
    /// Shade settings (which terms are evaluated).
    pub shade: ShadeSettings,
    /// Hit mask instead of shading.
    pub mask: bool,
    /// What the intersect and shadow stages test against.
    pub geometry: String,
}

impl Pipeline {
    /// The pipeline `scene` needs.
    pub fn for_scene(scene: &Scene) -> Pipeline {
        let shade = ShadeSettings::for_scene(scene);
        let mask = scene.render.mode == RenderMode::HitMask;
        let reflect = scene.needs_reflections();
        let last = if reflect { scene.render.max_depth } else { 0 };
        let depths = (0..=last)
            .map(|depth| {
                let mut stages = vec![];
                if depth == 0 {
                    stages.push(Stage::Generate);
                }
                stages.push(Stage::Intersect);
                stages.push(Stage::Shade);
                if shade.shadows {
                    stages.push(Stage::Shadow);
                }
                if depth < last {
                    stages.push(Stage::Reflect);
                }
                DepthPlan { depth, stages }
            })
            .collect();
        Pipeline {
            depths,
            shade,
            mask,
            geometry: describe_geometry(scene),
        }
    }

    /// True when some depth runs `stage`.
    pub fn runs(&self, stage: Stage) -> bool {
        self.depths.iter().any(|d| d.stages.contains(&stage))
    }

    /// Lights reached through shadow rays, whose passes [`shadow_passes`] lays out: all of
    /// `world`'s when shadows are traced, none when they are off or for the hit mask.
    pub fn traced_lights(&self, world: &World) -> usize {
        if self.shade.shadows && !self.mask {
            world.lights().len()
        } else {
            0
        }
    }
}

fn describe_geometry(scene: &Scene) -> String {
    // More than a handful of spheres go through their BVH (`world::sphere_bvh`); the rest, and
    // planes, are tested one by one.
    let bvh = scene.spheres.len() > crate::world::SPHERE_BVH_MIN;
    let mut parts = vec![];
    if !scene.spheres.is_empty() && !bvh {
        parts.push(format!("{} spheres", scene.spheres.len()));
    }
    if !scene.planes.is_empty() {
        parts.push(format!("{} planes", scene.planes.len()));
    }
    let mut analytic = vec![];
    if bvh {
        analytic.push(format!("{} spheres in a BVH", scene.spheres.len()));
    }
    if !parts.is_empty() {
        analytic.push(format!("{} (brute force)", parts.join(", ")));
    }
    let analytic = analytic.join("; ");
    let mesh = match scene.meshes.len() {
        0 => "no mesh, no kD tree".to_string(),
        n => {
            let tree = match &scene.meshes[0].kdtree {
                crate::scene::TreeSource::Sah => "SAH kD tree".to_string(),
                crate::scene::TreeSource::Midpoint => "midpoint kD tree".to_string(),
                crate::scene::TreeSource::File(p) => format!("kD tree from {}", p.display()),
            };
            format!("{n} mesh(es) through a {tree}")
        }
    };
    if analytic.is_empty() {
        mesh
    } else {
        format!("{analytic}; {mesh}")
    }
}

impl fmt::Display for Pipeline {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "geometry: {}", self.geometry)?;
        let terms = if self.mask {
            "hit mask (no shading)".to_string()
        } else {
            let mut t = vec!["ambient", "diffuse"];
            if self.shade.specular {
                t.push("specular");
            }
            format!(
                "{}; direct light {}",
                t.join(" + "),
                if self.shade.shadows {
                    "through shadow rays"
                } else {
                    "unshadowed"
                }
            )
        };
        writeln!(f, "shade: {terms}")?;
        for d in &self.depths {
            let stages: Vec<_> = d
                .stages
                .iter()
                .map(|s| match (s, self.mask) {
                    (Stage::Shade, true) => "shade[mask]",
                    (Stage::Intersect, _) => "intersect[closest]",
                    (Stage::Shadow, _) => "shadow[occluded]",
                    (s, _) => s.label(),
                })
                .collect();
            writeln!(f, "depth {}: {}", d.depth, stages.join(" -> "))?;
        }
        Ok(())
    }
}

/// Options that change how, not what, the schedule renders.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Upper bound on samples per wave (rounded to whole pixels, at least one pixel).
    pub wave_samples: usize,
    /// The rectangle of the image to render (`None`: the whole image); the film has its size.
    /// Its pixels are exactly the full render's there: samples are seeded by the whole image's
    /// pixel index, whatever the waves.
    pub region: Option<Region>,
    /// Upper bound on the shadow rays of one shade → shadow pass (hits × lights; clamped to
    /// `1..=MAX_SHADOW_ROWS`). Any value gives the same image; smaller ones use less memory.
    pub shadow_rows: usize,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            wave_samples: DEFAULT_WAVE_SAMPLES,
            region: None,
            shadow_rows: DEFAULT_SHADOW_ROWS,
        }
    }
}

impl RenderOptions {
    /// Pixels per wave for `scene`: `wave_samples` (clamped to `1..=MAX_WAVE_SAMPLES`) divided by
    /// the samples per pixel, at least one, at most the image. A wave's samples therefore never
    /// exceed `max(MAX_WAVE_SAMPLES, spp)`, so its sample slots fit a `u32`.
    pub fn pixels_per_wave(&self, scene: &Scene) -> u32 {
        let image = &scene.image;
        let spp = u64::from(image.samples.max(1));
        let cap = self.wave_samples.clamp(1, MAX_WAVE_SAMPLES) as u64;
        let total = image.pixel_count().max(1);
        // total ≤ u32::MAX for a validated scene; the clamp keeps the cast exact regardless.
        (cap / spp).clamp(1, total.min(u64::from(u32::MAX))) as u32
    }

    /// The region rendered for `scene`: [`RenderOptions::region`] clipped to the image, or the
    /// whole image.
    pub fn region_of(&self, scene: &Scene) -> Region {
        let (w, h) = (scene.image.width, scene.image.height);
        self.region.map_or(Region::full(w, h), |r| r.clipped(w, h))
    }
}

/// The waves of a render, in order: the region's pixels, row-major, in runs of
/// [`RenderOptions::pixels_per_wave`]. For the whole image these are runs of the image's pixels.
pub fn waves(scene: &Scene, options: &RenderOptions) -> impl Iterator<Item = Wave> + use<> {
    let image = &scene.image;
    let region = options.region_of(scene);
    let image_width = image.width;
    let total = region.pixels() as u32;
    let per_wave = options.pixels_per_wave(scene);
    let samples = image.samples.max(1);
    (0..total)
        .step_by(per_wave as usize)
        .map(move |first| Wave {
            region,
            image_width,
            first,
            pixels: (first + per_wave).min(total) - first,
            samples,
        })
}

/// The queues of one wave, reused across depths and waves so kernels allocate only while growing.
#[derive(Debug, Default)]
pub struct WaveQueues {
    /// This depth's rays.
    pub rays: RayQueue,
    /// The next depth's rays (written by `reflect`).
    pub next: RayQueue,
    /// One closest-hit answer per ray.
    pub closest: HitColumns,
    /// The rays that hit, with their surfaces.
    pub hits: HitQueue,
    /// Shadow rays.
    pub shadows: ShadowQueue,
    /// The wave's samples.
    pub samples: SampleBuffer,
    /// The wave's resolved pixels (linear radiance), handed to the sink.
    pub pixels: Vec<Vec3>,
    counts: Vec<usize>,
    shade: ShadeScratch,
}

impl WaveQueues {
    /// Read-only views for observers.
    pub fn queues<'a>(&'a self, wave: &'a Wave) -> Queues<'a> {
        Queues {
            wave,
            rays: &self.rays,
            closest: &self.closest,
            hits: &self.hits,
            shadows: &self.shadows,
            next: &self.next,
            samples: &self.samples,
        }
    }
}

/// Renders `scene` (whose geometry is `world`) and returns the film and per-stage statistics.
/// `progress` is called after each wave with (pixels done, pixels total).
pub fn render(
    scene: &Scene,
    world: &World,
    options: RenderOptions,
    progress: impl FnMut(u64, u64),
) -> (Film, Stats) {
    let mut stats = Stats::default();
    let film = render_observed(scene, world, &options, (&mut stats, Progress(progress)));
    (film, stats)
}

/// Renders `scene` into an in-memory [`Film`], showing every stage call and wave to `observer`
/// ([`render_into`] with a film as the sink).
pub fn render_observed(
    scene: &Scene,
    world: &World,
    options: &RenderOptions,
    observer: impl Observer,
) -> Film {
    let region = options.region_of(scene);
    let mut film = Film::new(region.width(), region.height());
    render_into(scene, world, options, observer, &mut film);
    film
}

/// Renders `scene`, showing every stage call and wave to `observer` and handing each wave's
/// resolved pixels to `sink`, in wave order. This is the renderer: for each wave, for each depth
/// of the [`Pipeline`], each of that depth's stages in order (`trace_wave`) — shade and shadow
/// once per [`ShadowPass`] of at most `options.shadow_rows` shadow rays. When the observer
/// [watches stages](Observer::watches_stages) (or on one thread) waves are traced one at a time,
/// each kernel split over the threads; otherwise each thread traces whole waves, taking the next
/// wave as it finishes one, with every kernel on that thread, and the waves (with their stage
/// records, [`Observer::stage_done`]) reach the sink and the observer in order. The image is the
/// same either way (every kernel is deterministic). Stops early, after a wave, when the sink no
/// longer [accepts](PixelSink::accepts) pixels. The sink
/// receives the pixels of [`RenderOptions::region_of`] the scene, row-major within the region.
pub fn render_into(
    scene: &Scene,
    world: &World,
    options: &RenderOptions,
    mut observer: impl Observer,
    sink: &mut impl PixelSink,
) {
    // Camera rays start at the frame's origin: trace in the frame of this scene's eye (a world
    // loaded for another camera of a path is moved, not rebuilt).
    let reframed;
    let world = if world.frame().origin == scene.camera.eye {
        world
    } else {
        reframed = world.reframed(scene);
        &reframed
    };
    let pipeline = Pipeline::for_scene(scene);
    let region = options.region_of(scene);
    let total = region.pixels();
    let mut done = 0;
    let traced_lights = pipeline.traced_lights(world);
    let threads = rayon::current_num_threads();
    let pools = if observer.watches_stages() || threads == 1 {
        None
    } else {
        wave_pools(threads)
    };
    let in_flight = pools.as_ref().map_or(1, |p| p.len() as u32);
    let trace = |wave: &Wave, ws: &mut WaveQueues, observer: &mut dyn Observer| {
        trace_wave(
            (scene, world, &pipeline),
            (options, traced_lights, in_flight),
            wave,
            ws,
            observer,
        );
    };
    let Some(pools) = pools else {
        // One wave at a time, each stage's kernels over all threads; observers see every call.
        let mut ws = WaveQueues::default();
        for wave in waves(scene, options) {
            trace(&wave, &mut ws, &mut observer);
            sink.put(PixelIndex(wave.first), &ws.pixels);
            done += u64::from(wave.pixels);
            observer.wave_done(done, total);
            if !sink.accepts() {
                break;
            }
        }
        return;
    };
    // Several waves at once: each worker traces whole waves, taken in order from a shared
    // counter, on its own queues (kept warm in its core's cache), inside its own one-thread pool
    // so the kernels run on that thread unsplit (no stealing of another wave's chunks). The
    // calling thread hands finished waves to the sink in wave order (a reorder buffer). A worker
    // takes a ticket before a wave and the calling thread returns it once the wave is in the
    // sink, so at most `WAVES_AHEAD_PER_THREAD` waves per thread are traced and not yet written:
    // a sink slower than the tracers (PNG compression at one sample per pixel) holds memory of a
    // few waves, not of the image.
    let next = Mutex::new(waves(scene, options).enumerate());
    let stop = AtomicBool::new(false);
    let (send, receive) = crossbeam_channel::unbounded::<(usize, Wave, Vec<Vec3>, RunLog)>();
    let window = WAVES_AHEAD_PER_THREAD * pools.len();
    let (give_ticket, take_ticket) = crossbeam_channel::bounded::<()>(window);
    for _ in 0..window {
        let _ = give_ticket.send(());
    }
    std::thread::scope(|scope| {
        // Dropped when this closure returns, which wakes workers waiting for a ticket.
        let give_ticket = give_ticket;
        for pool in &pools {
            let send = send.clone();
            let (next, stop, trace, take_ticket) = (&next, &stop, &trace, &take_ticket);
            scope.spawn(move || {
                pool.install(|| {
                    WAVE_QUEUES.with_borrow_mut(|ws| {
                        while !stop.load(Ordering::Relaxed) {
                            if take_ticket.recv().is_err() {
                                break;
                            }
                            let Some((i, wave)) = next.lock().ok().and_then(|mut w| w.next())
                            else {
                                break;
                            };
                            let mut log = RunLog::default();
                            trace(&wave, ws, &mut log);
                            if send.send((i, wave, ws.pixels.clone(), log)).is_err() {
                                break;
                            }
                        }
                    });
                });
            });
        }
        drop(send);
        let mut pending = BTreeMap::new();
        let mut expected = 0;
        for (i, wave, px, log) in receive.iter() {
            pending.insert(i, (wave, px, log));
            while let Some((wave, px, log)) = pending.remove(&expected) {
                for run in &log.0 {
                    observer.stage_done(run);
                }
                sink.put(PixelIndex(wave.first), &px);
                let _ = give_ticket.send(());
                done += u64::from(wave.pixels);
                observer.wave_done(done, total);
                expected += 1;
                if !sink.accepts() {
                    stop.store(true, Ordering::Relaxed);
                    return;
                }
            }
        }
    });
    if let Ok(mut idle) = WAVE_POOLS.lock() {
        idle.extend(pools);
    }
}

/// Waves per worker thread that may be traced and not yet in the sink (the wave-parallel
/// path's window: enough that a worker never waits for the reorder buffer on an even load).
const WAVES_AHEAD_PER_THREAD: usize = 4;

/// One-thread pools of the wave-parallel path, idle between renders: a render takes one per
/// thread and gives them back, so their threads (and the queues each keeps in
/// [`WAVE_QUEUES`], warm in its cache) outlive the render.
static WAVE_POOLS: Mutex<Vec<rayon::ThreadPool>> = Mutex::new(Vec::new());

thread_local! {
    /// The queues a wave-parallel worker traces its waves on, kept across waves and renders.
    static WAVE_QUEUES: RefCell<WaveQueues> = RefCell::new(WaveQueues::default());
}

/// `threads` one-thread pools, idle ones first, new ones built as needed; `None` if a pool
/// cannot be built (the render then traces one wave at a time).
fn wave_pools(threads: usize) -> Option<Vec<rayon::ThreadPool>> {
    let mut pools = WAVE_POOLS
        .lock()
        .map(|mut idle| {
            let keep = idle.len().saturating_sub(threads);
            idle.split_off(keep)
        })
        .unwrap_or_default();
    while pools.len() < threads {
        pools.push(
            rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .ok()?,
        );
    }
    Some(pools)
}

/// Traces one wave: each depth of the pipeline, each of its stages in order (shade and shadow
/// once per [`ShadowPass`]), then resolves the wave's samples into `ws.pixels`.
fn trace_wave(
    (scene, world, pipeline): (&Scene, &World, &Pipeline),
    (options, traced_lights, waves_in_flight): (&RenderOptions, usize, u32),
    wave: &Wave,
    ws: &mut WaveQueues,
    observer: &mut dyn Observer,
) {
    ws.samples.reset(wave.len());
    for plan in &pipeline.depths {
        let mut call = |stage, pass: &ShadowPass, ws: &mut WaveQueues| {
            observer.before(stage, plan.depth, &ws.queues(wave));
            let start = Instant::now();
            let (rays_in, rays_out) = run_stage(stage, scene, world, pipeline, wave, pass, ws);
            let run = StageRun {
                stage,
                depth: plan.depth,
                first_pass: pass.is_first(),
                rays_in,
                rays_out,
                elapsed: start.elapsed(),
                waves_in_flight,
            };
            observer.after(&run, &ws.queues(wave));
            observer.stage_done(&run);
        };
        // The stages of one depth, in the order `plan.stages` lists them.
        let runs = |stage| plan.stages.contains(&stage);
        let whole = ShadowPass::default();
        if runs(Stage::Generate) {
            call(Stage::Generate, &whole, ws);
        }
        if ws.rays.is_empty() {
            break; // every ray of the previous depth missed or stopped
        }
        call(Stage::Intersect, &whole, ws);
        // Direct light, a bounded pass at a time: shade spawns the shadow rays of a block of
        // hits × lights (the first pass also shades the hits and adds what they emit), and
        // shadow traces them before the next block.
        for pass in shadow_passes(ws.hits.len(), traced_lights, options.shadow_rows) {
            call(Stage::Shade, &pass, ws);
            if runs(Stage::Shadow) {
                call(Stage::Shadow, &pass, ws);
            }
        }
        if runs(Stage::Reflect) {
            call(Stage::Reflect, &whole, ws);
        }
        // The next depth traces the reflections this one spawned.
        std::mem::swap(&mut ws.rays, &mut ws.next);
        ws.next.clear();
    }
    resolve_wave(&ws.samples, wave, &mut ws.pixels);
}

/// Runs one stage's kernels on a wave's queues; returns (rays in, rays out). The one dispatch
/// from stage to kernels: the render loop above and the stage benchmarks both call it.
///
/// `pass` matters to `shade` only: its first pass (of a depth) shades the hits and adds their
/// emitted radiance (rays in: the hits), and every pass spawns the shadow rays of its hits and
/// lights (rays out; later passes read no new rays: rays in 0). Other stages ignore it.
pub fn run_stage(
    stage: Stage,
    scene: &Scene,
    world: &World,
    pipeline: &Pipeline,
    wave: &Wave,
    pass: &ShadowPass,
    ws: &mut WaveQueues,
) -> (usize, usize) {
    match stage {
        Stage::Generate => {
            generate_camera_rays(
                &scene.camera,
                &scene.image,
                wave,
                CameraRays::resizing(&mut ws.rays),
            );
            (0, ws.rays.len())
        }
        Stage::Intersect => {
            intersect_closest(
                world,
                ClosestRays::of(&ws.rays),
                ClosestOut::resizing(&mut ws.closest),
            );
            compact_hits(
                CompactRays::of(&ws.rays),
                CompactHits::of(&ws.closest),
                &mut ws.counts,
                CompactOut::resizing(&mut ws.hits),
            );
            (ws.rays.len(), ws.hits.len())
        }
        Stage::Shade => {
            let first = pass.is_first();
            if first {
                if pipeline.mask {
                    shade_hit_mask(MaskHits::of(&mut ws.hits));
                } else {
                    shade_hits(world, &pipeline.shade, ShadeHits::of(&mut ws.hits));
                }
                add_emitted(EmittedHits::of(&ws.hits), Samples::of(&mut ws.samples));
            }
            let rays_in = if first { ws.hits.len() } else { 0 };
            if pipeline.shade.shadows && !pipeline.mask {
                debug_assert!(pass.rows() <= MAX_SHADOW_ROWS);
                spawn_shadow_rays(
                    world,
                    &pipeline.shade,
                    pass,
                    ShadedHits::of(&ws.hits),
                    &mut ws.shade,
                    ShadowRays::resizing(&mut ws.shadows),
                );
                (rays_in, ws.shadows.len())
            } else {
                ws.shadows.clear();
                (rays_in, 0)
            }
        }
        Stage::Shadow => {
            intersect_occluded(world, ShadowTrace::of(&mut ws.shadows));
            let lit = add_unoccluded(LitRays::of(&ws.shadows), Samples::of(&mut ws.samples));
            (ws.shadows.len(), lit)
        }
        Stage::Reflect => {
            spawn_reflection_rays(
                world,
                ReflectHits::of(&ws.hits),
                &mut ws.counts,
                NextRays::resizing(&mut ws.next),
            );
            (ws.hits.len(), ws.next.len())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin::spheres;

    fn stats_on(threads: usize, scene: &Scene, world: &World) -> (Stats, Vec<u32>) {
        /// Stage records only, as `--stats` takes them, plus how many waves were in flight.
        #[derive(Default)]
        struct Records(Stats, Vec<u32>);
        impl Observer for Records {
            fn stage_done(&mut self, run: &StageRun) {
                self.0.stage_done(run);
                self.1.push(run.waves_in_flight);
            }
            fn watches_stages(&self) -> bool {
                self.0.watches_stages()
            }
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut records = Records::default();
        pool.install(|| render_observed(scene, world, &RenderOptions::default(), &mut records));
        (records.0, records.1)
    }

    /// Regression (issue 20): collecting statistics made the render trace one wave at a time
    /// (kernels split over the threads), so `render --threads 2` barely used the second core and
    /// `--stats` measured a path no plain render took.
    #[test]
    fn statistics_are_taken_on_the_wave_parallel_path() {
        let mut scene = spheres();
        (scene.image.width, scene.image.height, scene.image.samples) = (64, 64, 2);
        let world = World::load(&scene).unwrap();
        let (one, flights_one) = stats_on(1, &scene, &world);
        let (two, flights_two) = stats_on(2, &scene, &world);
        assert!(flights_one.iter().all(|&n| n == 1));
        assert!(!flights_two.is_empty() && flights_two.iter().all(|&n| n == 2));
        // The same calls, counted the same way, whichever path traced them.
        let counts = |s: &Stats| {
            s.entries
                .iter()
                .map(|(k, e)| (*k, e.rays_in, e.rays_out))
                .collect::<Vec<_>>()
        };
        assert_eq!(counts(&one), counts(&two));
        assert!(
            counts(&one)
                .iter()
                .any(|&((_, s), n, _)| s == Stage::Intersect && n > 0)
        );
    }
}
