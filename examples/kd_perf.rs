//! kD-tree build and traversal timings on the Sibenik benchmark view (SPEC §5).
//!
//! `cargo run --release --example kd_perf [OBJ] [REPS]`
//!
//! Loads the mesh, builds the midpoint and SAH trees (1 and 2 threads), then traces the
//! 512×512 primary rays (closest hit) and the shadow rays toward the light at the origin
//! (occluded) from each hit point, pushed off along the normal facing the ray, at 1 and 2
//! threads. Prints Mrays/s (best of REPS), tree stats and a checksum of the results so runs
//! before and after a change can be compared.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree, TriHit};
use wavefront::mesh::TriangleMesh;

fn best_of<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..reps {
        let s = Instant::now();
        let r = f();
        best = best.min(s.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("reps > 0"))
}

fn pool(n: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .expect("thread pool")
}

fn primary_rays() -> Vec<(Vec3, Vec3)> {
    let e = Vec3::new(0.0, -10.0, 0.0);
    let (u, v, w) = (Vec3::Z, Vec3::Y, -Vec3::X);
    let (l, r, b, t, d, n) = (-0.1f32, 0.1f32, -0.1f32, 0.1f32, 0.1f32, 512usize);
    let mut rays = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let su = l + (r - l) * (i as f32 + 0.5) / n as f32;
            let sv = b + (t - b) * (j as f32 + 0.5) / n as f32;
            let dir = (-d * w + su * u + sv * v).normalize();
            rays.push((e, dir));
        }
    }
    rays
}

fn checksum(hits: &[Option<TriHit>]) -> u64 {
    hits.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, x| {
        let v = x.map_or(u64::MAX, |x| ((x.t.to_bits() as u64) << 32) | x.tri as u64);
        (h ^ v).wrapping_mul(0x100_0000_01b3)
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .cloned()
        .unwrap_or_else(|| "../shared/data/sibenik/sibenik.obj".to_string());
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let (p1, p2) = (pool(1), pool(2));

    let (t_load, mesh) = best_of(1, || TriangleMesh::load_obj(path.as_ref()).expect("mesh"));
    println!("load {:.1} ms, {} triangles", t_load * 1e3, mesh.len());

    // `KD_PERF_SAH_ONLY=1` skips the midpoint tree (for profiling).
    let methods: &[BuildMethod] = if std::env::var_os("KD_PERF_SAH_ONLY").is_some() {
        &[BuildMethod::Sah]
    } else {
        &[BuildMethod::Midpoint, BuildMethod::Sah]
    };
    for &method in methods {
        let (b1, _) = p1.install(|| best_of(reps, || KdTree::build(&mesh, method)));
        let (b2, tree) = p2.install(|| best_of(reps, || KdTree::build(&mesh, method)));
        println!(
            "{method:?}: build {:.1} ms (1 thr) {:.1} ms (2 thr)\n  {}",
            b1 * 1e3,
            b2 * 1e3,
            tree.stats(&mesh)
        );
        if method == BuildMethod::Midpoint {
            continue;
        }
        let tree = KdAccel::new(tree, &mesh);
        let rays = primary_rays();
        let n = rays.len() as f64;
        let closest = |&(o, d): &(Vec3, Vec3)| tree.intersect_closest(o, d, f32::INFINITY);
        let (c1, hits) =
            p1.install(|| best_of(reps, || rays.iter().map(closest).collect::<Vec<_>>()));
        let (c2, hits2) = p2.install(|| {
            best_of(reps, || {
                rays.par_iter()
                    .with_min_len(256)
                    .map(closest)
                    .collect::<Vec<_>>()
            })
        });
        assert_eq!(checksum(&hits), checksum(&hits2));
        // Shadow rays toward the light at the origin.
        let shadow: Vec<(Vec3, Vec3)> = rays
            .iter()
            .zip(&hits)
            .filter_map(|(&(o, d), h)| {
                let h = (*h)?;
                let p = o + h.t * d;
                let mut nrm = mesh.geometric_normal(h.tri as usize).normalize();
                if nrm.dot(d) > 0.0 {
                    nrm = -nrm;
                }
                let origin = p + nrm * 1e-4;
                Some((origin, Vec3::ZERO - origin))
            })
            .collect();
        let ns = shadow.len() as f64;
        let occ = |&(o, d): &(Vec3, Vec3)| tree.intersect_occluded(o, d, 1.0);
        let (o1, occl) =
            p1.install(|| best_of(reps, || shadow.iter().map(occ).collect::<Vec<_>>()));
        let (o2, occl2) = p2.install(|| {
            best_of(reps, || {
                shadow
                    .par_iter()
                    .with_min_len(256)
                    .map(occ)
                    .collect::<Vec<_>>()
            })
        });
        assert_eq!(occl, occl2);
        // Batch (packet) kernels over chunks, as the stages call them.
        const CHUNK: usize = 1024;
        let (po, pd): (Vec<Vec3>, Vec<Vec3>) = rays.iter().copied().unzip();
        let ptm = vec![f32::INFINITY; rays.len()];
        let closest_batch = |o: &[Vec3], d: &[Vec3], tm: &[f32]| {
            let (mut t, mut tri) = (vec![0.0; o.len()], vec![0u32; o.len()]);
            tree.intersect_closest_batch(o, d, tm, &mut t, &mut tri);
            t.into_iter()
                .zip(tri)
                .map(|(t, tri)| (tri != u32::MAX).then_some(TriHit { t, tri }))
                .collect::<Vec<_>>()
        };
        let (cb1, bh) = p1.install(|| best_of(reps, || closest_batch(&po, &pd, &ptm)));
        let (cb2, bh2) = p2.install(|| {
            best_of(reps, || {
                po.par_chunks(CHUNK)
                    .zip(pd.par_chunks(CHUNK))
                    .zip(ptm.par_chunks(CHUNK))
                    .flat_map_iter(|((o, d), tm)| closest_batch(o, d, tm))
                    .collect::<Vec<_>>()
            })
        });
        let (so, sd): (Vec<Vec3>, Vec<Vec3>) = shadow.iter().copied().unzip();
        let stm = vec![1.0f32; shadow.len()];
        let occ_batch = |o: &[Vec3], d: &[Vec3], tm: &[f32]| {
            let mut out = vec![false; o.len()];
            tree.intersect_occluded_batch(o, d, tm, &mut out);
            out
        };
        let (ob1, bo) = p1.install(|| best_of(reps, || occ_batch(&so, &sd, &stm)));
        let (ob2, bo2) = p2.install(|| {
            best_of(reps, || {
                so.par_chunks(CHUNK)
                    .zip(sd.par_chunks(CHUNK))
                    .zip(stm.par_chunks(CHUNK))
                    .flat_map_iter(|((o, d), tm)| occ_batch(o, d, tm))
                    .collect::<Vec<_>>()
            })
        });
        let blocked = occl.iter().filter(|&&b| b).count();
        println!(
            "  closest  {:.2} Mrays/s (1 thr) {:.2} Mrays/s (2 thr), {} hits, checksum {:016x}",
            n / c1 * 1e-6,
            n / c2 * 1e-6,
            hits.iter().filter(|h| h.is_some()).count(),
            checksum(&hits)
        );
        println!(
            "  occluded {:.2} Mrays/s (1 thr) {:.2} Mrays/s (2 thr), {} shadow rays, {} blocked",
            ns / o1 * 1e-6,
            ns / o2 * 1e-6,
            shadow.len(),
            blocked
        );
        println!(
            "  closest  batch {:.2} Mrays/s (1 thr) {:.2} Mrays/s (2 thr)\n  occluded batch {:.2} Mrays/s (1 thr) {:.2} Mrays/s (2 thr)",
            n / cb1 * 1e-6,
            n / cb2 * 1e-6,
            ns / ob1 * 1e-6,
            ns / ob2 * 1e-6
        );
        assert_eq!(
            checksum(&bh),
            checksum(&hits),
            "batch closest differs from single"
        );
        assert_eq!(checksum(&bh2), checksum(&hits));
        assert_eq!(bo, occl, "batch occluded differs from single");
        assert_eq!(bo2, occl);
        println!("  batch results identical to single-ray results");
    }
}
