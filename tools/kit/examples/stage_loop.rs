//! Runs one stage of a built-in scene's bench snapshot (the middle wave's queues) many times on
//! one thread: a steady target for `perf record` / `perf stat` / callgrind.
//!
//!     cargo run --release -p wavefront-kit --example stage_loop -- sibenik-shadows shadow 200
//!
//! Stages: `intersect` or `shadow` (depth 0). Prints the best time per run.

use std::time::Instant;

use wavefront::schedule::Stage;
use wavefront_kit::bench::StageBench;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: stage_loop SCENE intersect|shadow RUNS";
    let (Some(name), Some(stage), Some(runs)) = (args.get(1), args.get(2), args.get(3)) else {
        anyhow::bail!(usage);
    };
    let stage = match stage.as_str() {
        "intersect" => Stage::Intersect,
        "shadow" => Stage::Shadow,
        _ => anyhow::bail!(usage),
    };
    let runs: usize = runs.parse()?;
    let scene = wavefront::scene::builtin::builtin(name).ok_or_else(|| anyhow::anyhow!(usage))?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    pool.install(|| {
        let world = wavefront::world::World::load(&scene)?;
        let mut bench = StageBench::new(&scene, &world);
        let mut best = f64::INFINITY;
        let mut rays = 0;
        for _ in 0..runs {
            bench.prepare(stage, 0);
            let t = Instant::now();
            rays = bench.run_prepared(stage, 0);
            best = best.min(t.elapsed().as_secs_f64());
        }
        println!(
            "{stage} of {name}: {rays} rays, best {:.3} ms, {:.2} Mrays/s",
            best * 1e3,
            rays as f64 / best / 1e6
        );
        Ok(())
    })
}
