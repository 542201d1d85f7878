//! Prints Embree's build time and Mrays/s on the Sibenik benchmark view.
//!
//! `cargo run --release --features embree --example embree_probe [OBJ] [REPS]`
//!
//! Primary rays: 512x512 pixel centres from eye (0,-10,0), u=(0,0,1),
//! v=(0,1,0), w=(-1,0,0), window ±0.1 at distance 0.1. Shadow rays: from each
//! primary hit (pulled back by 1e-4 of t) toward the light at the origin.
//! "1 thr" runs the sequential methods on the calling thread; "2 thr" runs
//! the parallel variants inside a 2-thread rayon pool. Best of REPS runs.

use std::time::Instant;

use wavefront_kit::peer::embree::{EmbreeScene, TraceOpts};

/// Minimal `v` / `f` OBJ reader (the main crate has its own loader).
fn load_obj(path: &str) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut v = Vec::new();
    let mut f = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f32> = it.take(3).map(|s| s.parse().unwrap()).collect();
                v.push([c[0], c[1], c[2]]);
            }
            Some("f") => {
                let ids: Vec<u32> = it
                    .map(|s| {
                        let i: i64 = s.split('/').next().unwrap().parse().unwrap();
                        (if i < 0 { v.len() as i64 + i } else { i - 1 }) as u32
                    })
                    .collect();
                for k in 1..ids.len() - 1 {
                    f.push([ids[0], ids[k], ids[k + 1]]);
                }
            }
            _ => {}
        }
    }
    (v, f)
}

fn best_of(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .unwrap_or_else(|| "/work/shared/data/sibenik/sibenik.obj".into());
    let reps: usize = args.next().map_or(5, |s| s.parse().expect("REPS"));
    let (v, f) = load_obj(&path);
    println!("scene: {path}: {} vertices, {} triangles", v.len(), f.len());

    for config in ["threads=1", ""] {
        let builds: Vec<f64> = (0..reps)
            .map(|_| {
                EmbreeScene::with_config(&v, &f, config)
                    .expect("scene")
                    .build_seconds()
            })
            .collect();
        let best = builds.iter().copied().fold(f64::INFINITY, f64::min);
        let name = if config.is_empty() { "default" } else { config };
        println!("build ({name}): best {:.2} ms of {reps}", best * 1e3);
    }
    let scene = EmbreeScene::with_config(&v, &f, "threads=1").expect("scene");

    let n = 512usize;
    let eye = [0.0f32, -10.0, 0.0];
    let (u, vv, w) = ([0.0f32, 0.0, 1.0], [0.0f32, 1.0, 0.0], [-1.0f32, 0.0, 0.0]);
    let (l, r, b, t, d) = (-0.1f32, 0.1f32, -0.1f32, 0.1f32, 0.1f32);
    let mut dirs = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let us = l + (r - l) * (i as f32 + 0.5) / n as f32;
            let vs = t - (t - b) * (j as f32 + 0.5) / n as f32;
            dirs.push(std::array::from_fn(|k| us * u[k] + vs * vv[k] - d * w[k]));
        }
    }
    let orgs = vec![eye; n * n];
    let tmax = vec![f32::INFINITY; n * n];
    let mut out_t = vec![0.0f32; n * n];
    let mut out_p = vec![0u32; n * n];
    scene.intersect1(&orgs, &dirs, &tmax, &mut out_t, &mut out_p);

    let (mut so, mut sd) = (Vec::new(), Vec::new());
    for i in (0..n * n).filter(|&i| out_p[i] != u32::MAX) {
        let th = out_t[i] * (1.0 - 1e-4);
        let p: [f32; 3] = std::array::from_fn(|k| orgs[i][k] + th * dirs[i][k]);
        so.push(p);
        sd.push([-p[0], -p[1], -p[2]]);
    }
    let stmax = vec![1.0 - 1e-4f32; so.len()];
    let mut occ = vec![false; so.len()];
    println!(
        "primary rays: {} ({} hit), shadow rays: {}",
        n * n,
        so.len(),
        so.len()
    );

    let pool2 = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    let np = (n * n) as f64;
    let ns = so.len() as f64;
    let mrays = |rays: f64, secs: f64| rays / secs / 1e6;
    let seq = TraceOpts::default();
    let coh = TraceOpts {
        coherent: true,
        ..seq
    };
    let par = TraceOpts::parallel();
    let parc = TraceOpts {
        coherent: true,
        ..par
    };

    let row = |name: &str, rays: f64, mut run: Box<dyn FnMut(TraceOpts) + Send + '_>| {
        let one = best_of(reps, || run(seq));
        let one_c = best_of(reps, || run(coh));
        let two = pool2.install(|| best_of(reps, || run(par)));
        let two_c = pool2.install(|| best_of(reps, || run(parc)));
        println!(
            "{name:<11} 1 thr {:7.2} Mrays/s (coherent {:7.2}) | 2 thr {:7.2} Mrays/s (coherent {:7.2})",
            mrays(rays, one),
            mrays(rays, one_c),
            mrays(rays, two),
            mrays(rays, two_c)
        );
    };
    row(
        "intersect1",
        np,
        Box::new(|o| scene.intersect1_with(o, &orgs, &dirs, &tmax, &mut out_t, &mut out_p)),
    );
    let mut out_t2 = vec![0.0f32; n * n];
    let mut out_p2 = vec![0u32; n * n];
    row(
        "intersect1m",
        np,
        Box::new(|o| scene.intersect1m_with(o, &orgs, &dirs, &tmax, &mut out_t2, &mut out_p2)),
    );
    row(
        "occluded1",
        ns,
        Box::new(|o| scene.occluded1_with(o, &so, &sd, &stmax, &mut occ)),
    );
    let mut occ2 = vec![false; so.len()];
    row(
        "occluded1m",
        ns,
        Box::new(|o| scene.occluded1m_with(o, &so, &sd, &stmax, &mut occ2)),
    );
    // Incoherent streams must reproduce the single-ray results exactly.
    scene.intersect1(&orgs, &dirs, &tmax, &mut out_t, &mut out_p);
    scene.intersect1m(&orgs, &dirs, &tmax, &mut out_t2, &mut out_p2);
    scene.occluded1(&so, &sd, &stmax, &mut occ);
    scene.occluded1m(&so, &sd, &stmax, &mut occ2);
    assert!(out_p == out_p2 && occ == occ2, "1 vs 1M results differ");
    println!(
        "shadowed: {} of {}",
        occ.iter().filter(|&&b| b).count(),
        so.len()
    );
}
