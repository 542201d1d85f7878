//! Criterion benches: one group per stage over a snapshot of its input queue, plus full frames,
//! kD tree builds and OBJ loading.
//!
//! Reads: scene A (built in) and, when present, the Sibenik mesh
//! (`wavefront_kit::testkit::sibenik_mesh`) (its benches are skipped with a message
//! otherwise). Snapshots come from [`wavefront_kit::bench::StageBench`], the same code
//! `wavefront bench` times; each stage bench times exactly that kernel, with
//! `Throughput::Elements(rays)` so criterion reports rays per second. Everything runs on rayon's
//! global pool (all cores; set `RAYON_NUM_THREADS` to change it).
//!
//! Ids: `generate/spheres/depth0`, `intersect/{spheres,sibenik}/depth0`, `shade/spheres/depth0`,
//! `shadow/sibenik-shadows/depth0`, `reflect/spheres/depth1`, `frame/{spheres-1spp,
//! spheres-64spp, sibenik, sibenik-shadows}`, `build/{sah,midpoint}`, `load/obj`.
//!
//! `cargo bench --bench stages -- spheres` runs only the scene A benches.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{
    BenchmarkId, Criterion, SamplingMode, Throughput, criterion_group, criterion_main,
};

use wavefront::accel::kdtree::{BuildMethod, KdTree};
use wavefront::mesh::TriangleMesh;
use wavefront::scene::builtin;
use wavefront::{RenderOptions, Scene, Stage, World, render};
use wavefront_kit::bench::StageBench;
use wavefront_kit::testkit::{sibenik_mesh, sibenik_scene};

/// A scene with its loaded geometry.
struct Fixture {
    scene: Scene,
    world: World,
}

impl Fixture {
    fn new(scene: Scene) -> Fixture {
        let world = World::load(&scene).expect("scene loads");
        Fixture { scene, world }
    }
}

fn spheres() -> Fixture {
    Fixture::new(builtin::spheres())
}

/// `sibenik-shadows` (its primary rays are also `sibenik`'s), or `None` with a message when the
/// mesh is missing.
fn sibenik_shadows() -> Option<Fixture> {
    sibenik_scene(true).map(Fixture::new)
}

/// Benches `stage` at `depth` of `bench`'s snapshot as `STAGE/LABEL/depthD`.
fn stage_bench(c: &mut Criterion, bench: &mut StageBench, label: &str, stage: Stage, depth: u32) {
    let rays = bench
        .snapshot
        .rays(stage, depth)
        .unwrap_or_else(|| panic!("{label}: the first wave runs no {stage} at depth {depth}"));
    let mut group = c.benchmark_group(stage.label());
    group.throughput(Throughput::Elements(rays as u64));
    group.bench_function(BenchmarkId::new(label, format!("depth{depth}")), |b| {
        // Each iteration gets a fresh copy of the stage's input; only the stage is timed.
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                bench.prepare(stage, depth);
                let start = Instant::now();
                black_box(bench.run_prepared(stage, depth));
                total += start.elapsed();
            }
            total
        })
    });
    group.finish();
}

fn stages(c: &mut Criterion) {
    let a = spheres();
    let mut bench = StageBench::new(&a.scene, &a.world);
    stage_bench(c, &mut bench, "spheres", Stage::Generate, 0);
    stage_bench(c, &mut bench, "spheres", Stage::Intersect, 0);
    stage_bench(c, &mut bench, "spheres", Stage::Shade, 0);
    stage_bench(c, &mut bench, "spheres", Stage::Reflect, 1);
    drop(bench);

    if let Some(b) = sibenik_shadows() {
        let mut bench = StageBench::new(&b.scene, &b.world);
        stage_bench(c, &mut bench, "sibenik", Stage::Intersect, 0);
        stage_bench(c, &mut bench, "sibenik-shadows", Stage::Shadow, 0);
    }
}

fn frame(c: &mut Criterion, label: &str, scene: &Scene, world: &World) {
    let mut group = c.benchmark_group("frame");
    let i = &scene.image;
    group.throughput(Throughput::Elements(
        i.sample_count()
            .expect("a validated scene's samples fit a u64"),
    ));
    // Frames take tens of ms to seconds: one iteration per sample.
    group.sampling_mode(SamplingMode::Flat);
    if i.samples > 1 {
        // Seconds per frame: ten single frames are enough, without warm-up.
        group.warm_up_time(Duration::from_millis(1));
    }
    group.bench_function(label, |b| {
        b.iter(|| render(scene, world, RenderOptions::default(), |_, _| {}))
    });
    group.finish();
}

fn frames(c: &mut Criterion) {
    let mut a = spheres();
    frame(c, "spheres-1spp", &a.scene, &a.world);
    a.scene.image.samples = 64;
    frame(c, "spheres-64spp", &a.scene, &a.world);

    if let Some(b) = sibenik_shadows() {
        // Both Sibenik scenes share geometry; they differ only in the schedule's shadow stage.
        let mut plain = builtin::sibenik(false);
        plain.meshes = b.scene.meshes.clone();
        frame(c, "sibenik", &plain, &b.world);
        frame(c, "sibenik-shadows", &b.scene, &b.world);
    }
}

fn builds(c: &mut Criterion) {
    let Some(path) = sibenik_mesh() else {
        return;
    };
    let mesh = TriangleMesh::load_obj(&path).expect("sibenik loads");
    let mut group = c.benchmark_group("build");
    group.sampling_mode(SamplingMode::Flat);
    group.throughput(Throughput::Elements(mesh.len() as u64));
    for (label, method) in [
        ("sah", BuildMethod::Sah),
        ("midpoint", BuildMethod::Midpoint),
    ] {
        group.bench_function(label, |b| b.iter(|| KdTree::build(&mesh, method)));
    }
    group.finish();

    let mut group = c.benchmark_group("load");
    group.sampling_mode(SamplingMode::Flat);
    group.throughput(Throughput::Elements(mesh.len() as u64));
    group.bench_function("obj", |b| {
        b.iter(|| TriangleMesh::load_obj(&path).expect("sibenik loads"))
    });
    group.finish();
}

/// Short measurements (the machine is shared) and no plots: with the crate's `plotters` features
/// criterion's chart backend needs system fonts, which the machines do not have.
fn config() -> Criterion {
    Criterion::default()
        .without_plots()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
}

criterion_group! {
    name = benches;
    config = config();
    targets = stages, frames, builds
}
criterion_main!(benches);
