//! Profiling harness for the kD traversal on Sibenik (not a benchmark of record: `compare
//! sibenik` is). Captures every depth-0 camera ray and every shadow ray of a 1-spp render of
//! `sibenik-shadows`, then traces them `REPEAT` times through the batch queries in the chunks the
//! stages use, on the current thread, and prints Mrays/s per kernel.
//!
//! usage: `cargo run --release -p wavefront-kit --example trace_sibenik -- [closest|occluded|both] [REPEAT]`
//! (mesh from `$WAVEFRONT_SIBENIK` or `../shared/data/sibenik/sibenik.obj`). Under
//! `valgrind --tool=callgrind` use REPEAT 1 and one kernel for instruction counts.

use std::time::Instant;

use glam::Vec3;
use wavefront::schedule::{Observer, Queues, RenderOptions, Stage, StageRun, render_observed};
use wavefront::world::World;

/// Rays captured from the render.
#[derive(Default)]
struct Capture {
    cam: (Vec<Vec3>, Vec<Vec3>, Vec<f32>),
    shadow: (Vec<Vec3>, Vec<Vec3>, Vec<f32>),
}

impl Observer for Capture {
    fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
        if run.stage == Stage::Intersect && run.depth == 0 {
            self.cam.0.extend_from_slice(q.rays.origin());
            self.cam.1.extend_from_slice(q.rays.direction());
            self.cam.2.extend_from_slice(q.rays.t_max());
        }
        if run.stage == Stage::Shadow && run.depth == 0 {
            self.shadow.0.extend_from_slice(q.shadows.origin());
            self.shadow.1.extend_from_slice(q.shadows.direction());
            self.shadow.2.extend_from_slice(q.shadows.t_max());
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map_or("both", |s| s.as_str()).to_string();
    let repeat: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20);
    let scene = wavefront_kit::testkit::sibenik_scene(true).expect("sibenik mesh");
    let world = World::load(&scene).expect("load");
    let tris = world.triangles().expect("mesh");
    let tree = &wavefront::accel::kdtree::KdAccel::new(tris.tree().clone(), tris.mesh());
    let mut cap = Capture::default();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    pool.install(|| render_observed(&scene, &world, &RenderOptions::default(), &mut cap));
    let (o, d, t) = &cap.cam;
    let n = o.len();
    let chunk = wavefront::queue::TRACE_CHUNK;
    let (mut ot, mut otri) = (vec![0.0f32; n], vec![0u32; n]);
    let (so, sd, st) = &cap.shadow;
    let m = so.len();
    let mut occ = vec![false; m];
    let schunk = wavefront::accel::kdtree::KdAccel::OCCLUDED_BATCH;
    let (mut best_c, mut best_s) = (f64::INFINITY, f64::INFINITY);
    pool.install(|| {
        for _ in 0..repeat {
            if which != "occluded" {
                let t0 = Instant::now();
                for s in (0..n).step_by(chunk) {
                    let e = (s + chunk).min(n);
                    tree.intersect_closest_batch(
                        &o[s..e],
                        &d[s..e],
                        &t[s..e],
                        &mut ot[s..e],
                        &mut otri[s..e],
                    );
                }
                best_c = best_c.min(t0.elapsed().as_secs_f64());
            }
            if which != "closest" {
                let t0 = Instant::now();
                for s in (0..m).step_by(schunk) {
                    let e = (s + schunk).min(m);
                    tree.intersect_occluded_batch(&so[s..e], &sd[s..e], &st[s..e], &mut occ[s..e]);
                }
                best_s = best_s.min(t0.elapsed().as_secs_f64());
            }
        }
    });
    let hits = otri.iter().filter(|&&x| x != u32::MAX).count();
    let blocked = occ.iter().filter(|&&x| x).count();
    let sum: u64 = otri.iter().map(|&x| x as u64).sum();
    println!(
        "closest: {n} rays, {hits} hits (tri sum {sum}), best {:.2} ms = {:.2} Mrays/s",
        best_c * 1e3,
        n as f64 / best_c / 1e6
    );
    println!(
        "occluded: {m} rays, {blocked} blocked, best {:.2} ms = {:.2} Mrays/s",
        best_s * 1e3,
        m as f64 / best_s / 1e6
    );
}
