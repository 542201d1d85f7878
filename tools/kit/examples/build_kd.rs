//! Profiling harness for the SAH kD build (not a benchmark of record: `compare build` is).
//! Loads a mesh once, then builds the default SAH tree `REPEAT` times on the current thread
//! pool and prints the best wall time, the phases and the tree's statistics.
//!
//! usage: `cargo run --release -p wavefront-kit --example build_kd -- [MESH.obj] [REPEAT] [exact]` (default
//! `../shared/data/sibenik/sibenik.obj`, 5; `exact` builds the exact-sweep reference tree).
//! Under `valgrind --tool=callgrind` use REPEAT 1 and `RAYON_NUM_THREADS=1`.

use std::path::Path;
use std::time::Instant;

use wavefront::accel::kdtree::{BuildMethod, KdTree};
use wavefront::mesh::TriangleMesh;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .map_or("../shared/data/sibenik/sibenik.obj", |s| s.as_str());
    let repeat: usize = args.get(2).map_or(5, |s| s.parse().expect("REPEAT"));
    let exact = args.get(3).is_some_and(|s| s == "exact");
    let mesh = TriangleMesh::load_obj(Path::new(path)).expect("mesh loads");
    let mut best = f64::INFINITY;
    let mut tree = None;
    for _ in 0..repeat {
        let start = Instant::now();
        let (t, phases) = if exact {
            (KdTree::build_sah_exact(&mesh), Default::default())
        } else {
            KdTree::build_profiled(&mesh, BuildMethod::Sah)
        };
        let s = start.elapsed().as_secs_f64();
        if s < best {
            best = s;
            println!("{:.2} ms {phases:?}", s * 1e3);
        }
        tree = Some(t);
    }
    let tree = tree.expect("built");
    println!(
        "{} triangles: best {:.2} ms\n{}",
        mesh.len(),
        best * 1e3,
        tree.stats(&mesh)
    );
}
