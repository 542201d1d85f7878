//! Observers: what the schedule shows the outside after each stage call and each wave, so
//! statistics, progress bars and benchmark snapshots watch the one schedule instead of copying
//! its loop.

use std::time::Duration;

use super::stage::Stage;
use crate::queue::wave::Wave;
use crate::queue::{HitColumns, HitQueue, RayQueue, SampleBuffer, ShadowQueue};

/// The queues of the current wave, as a stage finds them (`before`) or leaves them (`after`).
#[derive(Clone, Copy, Debug)]
pub struct Queues<'a> {
    /// The wave being rendered.
    pub wave: &'a Wave,
    /// This depth's rays (input of `intersect`).
    pub rays: &'a RayQueue,
    /// One closest-hit answer per ray (written by `intersect`).
    pub closest: &'a HitColumns,
    /// The rays that hit (written by `intersect`, surface columns by `shade`).
    pub hits: &'a HitQueue,
    /// Shadow rays (written by `shade`, `occluded` by `shadow`).
    pub shadows: &'a ShadowQueue,
    /// The next depth's rays (written by `reflect`; they become `rays` after it).
    pub next: &'a RayQueue,
    /// The wave's samples.
    pub samples: &'a SampleBuffer,
}

/// One stage call: what ran, on how many rays, for how long.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageRun {
    /// The stage.
    pub stage: Stage,
    /// The bounce counter.
    pub depth: u32,
    /// False for the second and later shade → shadow passes of a depth (see
    /// [`crate::queue::pass::ShadowPass`]); true for every other call.
    pub first_pass: bool,
    /// Rays read (0 for `generate`, and for `shade` after a depth's first pass).
    pub rays_in: usize,
    /// Rays produced: camera rays, hits, shadow rays, unoccluded shadow rays, reflection rays.
    pub rays_out: usize,
    /// Wall time of the call.
    pub elapsed: Duration,
    /// Waves traced at once while the call ran: 1 when waves are traced one at a time (each
    /// kernel split over all threads), the number of threads when each thread traces its own
    /// waves. The call's share of the render's wall time is `elapsed / waves_in_flight`.
    pub waves_in_flight: u32,
}

/// Watches a render. Every method has an empty default.
pub trait Observer {
    /// Called before each stage call.
    fn before(&mut self, _stage: Stage, _depth: u32, _queues: &Queues<'_>) {}
    /// Called after each stage call, with the queues as the stage left them (only when the
    /// observer [watches stages](Observer::watches_stages)).
    fn after(&mut self, _run: &StageRun, _queues: &Queues<'_>) {}
    /// Called with every stage call's record, in wave order then call order, whichever way the
    /// schedule traces the waves (one at a time, or one per thread: then after the wave is done).
    /// An observer that needs only these records (statistics) need not watch stages.
    fn stage_done(&mut self, _run: &StageRun) {}
    /// Called after each wave is resolved into the film, with pixels done and total.
    fn wave_done(&mut self, _done: u64, _total: u64) {}
    /// True when the observer watches stage calls with their queues ([`Observer::before`],
    /// [`Observer::after`]): the schedule then traces one wave at a time, each stage's kernels
    /// split over the threads. False (an observer of waves and stage records only) lets it trace
    /// one wave per thread at once, every wave's stages in the same order, as a plain render does.
    fn watches_stages(&self) -> bool {
        true
    }
}

/// Observes nothing.
impl Observer for () {
    fn watches_stages(&self) -> bool {
        false
    }
}

/// Both observers, in order.
impl<A: Observer, B: Observer> Observer for (A, B) {
    fn before(&mut self, stage: Stage, depth: u32, queues: &Queues<'_>) {
        self.0.before(stage, depth, queues);
        self.1.before(stage, depth, queues);
    }
    fn after(&mut self, run: &StageRun, queues: &Queues<'_>) {
        self.0.after(run, queues);
        self.1.after(run, queues);
    }
    fn stage_done(&mut self, run: &StageRun) {
        self.0.stage_done(run);
        self.1.stage_done(run);
    }
    fn wave_done(&mut self, done: u64, total: u64) {
        self.0.wave_done(done, total);
        self.1.wave_done(done, total);
    }
    fn watches_stages(&self) -> bool {
        self.0.watches_stages() || self.1.watches_stages()
    }
}

impl<O: Observer + ?Sized> Observer for &mut O {
    fn before(&mut self, stage: Stage, depth: u32, queues: &Queues<'_>) {
        (**self).before(stage, depth, queues);
    }
    fn after(&mut self, run: &StageRun, queues: &Queues<'_>) {
        (**self).after(run, queues);
    }
    fn stage_done(&mut self, run: &StageRun) {
        (**self).stage_done(run);
    }
    fn wave_done(&mut self, done: u64, total: u64) {
        (**self).wave_done(done, total);
    }
    fn watches_stages(&self) -> bool {
        (**self).watches_stages()
    }
}

/// The stage records of one wave, kept by the thread that traced it until the wave reaches the
/// observer (the wave-parallel path replays them in wave order).
#[derive(Debug, Default)]
pub(crate) struct RunLog(pub(crate) Vec<StageRun>);

impl Observer for RunLog {
    fn stage_done(&mut self, run: &StageRun) {
        self.0.push(*run);
    }
    fn watches_stages(&self) -> bool {
        false
    }
}

/// Calls a closure with (pixels done, pixels total) after each wave: a progress report.
#[derive(Debug)]
pub struct Progress<F>(pub F);

impl<F: FnMut(u64, u64)> Observer for Progress<F> {
    fn wave_done(&mut self, done: u64, total: u64) {
        (self.0)(done, total);
    }
    fn watches_stages(&self) -> bool {
        false
    }
}
