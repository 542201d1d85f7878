//! The closest-hit batch kernel (frusta for camera rays and mirror reflections, 4-ray packets
//! otherwise) against the single-ray query on Sibenik, bit for bit, at every SIMD level this CPU
//! supports.

use glam::Vec3;
use rayon::prelude::*;
use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree};
use wavefront::simd::Level;

/// The batch at `level` over `chunk`-sized pieces (as the intersect stage calls it), against
/// the single-ray query; returns the number of hits. Panics naming the first differing ray.
fn check(
    tree: &KdAccel,
    level: Level,
    chunk: usize,
    o: &[Vec3],
    d: &[Vec3],
    tm: &[f32],
    want: &[(u32, u32)],
) -> usize {
    let n = o.len();
    let (mut t, mut tri) = (vec![0.0f32; n], vec![0u32; n]);
    t.par_chunks_mut(chunk)
        .zip(tri.par_chunks_mut(chunk))
        .enumerate()
        .for_each(|(c, (t, tri))| {
            let r = c * chunk..c * chunk + t.len();
            tree.intersect_closest_batch_at(level, &o[r.clone()], &d[r.clone()], &tm[r], t, tri);
        });
    for i in 0..n {
        assert_eq!(
            (t[i].to_bits(), tri[i]),
            want[i],
            "{level:?}, chunk {chunk}: ray {i} ({:?} + t {:?}, t_max {})",
            o[i],
            d[i],
            tm[i]
        );
    }
    want.iter().filter(|w| w.1 != u32::MAX).count()
}

fn single(tree: &KdAccel, o: &[Vec3], d: &[Vec3], tm: &[f32]) -> Vec<(u32, u32)> {
    (0..o.len())
        .into_par_iter()
        .map(|i| {
            tree.intersect_closest(o[i], d[i], tm[i])
                .map_or((f32::INFINITY.to_bits(), u32::MAX), |h| {
                    (h.t.to_bits(), h.tri)
                })
        })
        .collect()
}

#[test]
fn sibenik_camera_and_reflection_rays_match_single_rays_at_every_simd_level() {
    let Some(mesh) = wavefront_kit::testkit::sibenik_triangles() else {
        return;
    };
    let tree = KdAccel::new(KdTree::build(&mesh, BuildMethod::Sah), &mesh);
    let camera = wavefront::scene::builtin::sibenik(false).camera;
    let eye = camera.eye.as_vec3();
    // Camera rays: the 512 × 512 pixel centres, row-major (262,144 rays), every 7th with a
    // t_max that cuts some hits off, every 97th with a bad t_max or direction.
    let dirs = camera.pixel_centre_directions(512, 512);
    let n = dirs.len();
    let mut d = dirs.clone();
    let mut tm = vec![f32::INFINITY; n];
    for i in 0..n {
        if i % 7 == 3 {
            tm[i] = 0.5 + (i % 13) as f32;
        }
        if i % 97 == 5 {
            match i % 3 {
                0 => tm[i] = f32::NAN,
                1 => tm[i] = 0.0,
                _ => d[i] = Vec3::ZERO,
            }
        }
    }
    let o = vec![eye; n];
    let want = single(&tree, &o, &d, &tm);
    // Reflection rays: from the primary hits (nudged back along the ray), mirrored about a
    // per-pixel tilted normal: incoherent origins and directions.
    let (mut ro, mut rd) = (vec![], vec![]);
    for (i, dir) in dirs.iter().enumerate() {
        if let Some(h) = tree.intersect_closest(eye, *dir, f32::INFINITY) {
            let p = eye + *dir * (h.t * 0.9999);
            let nrm = Vec3::new(
                ((i * 37) % 11) as f32 - 5.0,
                8.0,
                ((i * 53) % 7) as f32 - 3.0,
            )
            .normalize();
            ro.push(p);
            rd.push(*dir - 2.0 * dir.dot(nrm) * nrm);
        }
    }
    let rtm = vec![f32::INFINITY; ro.len()];
    let rwant = single(&tree, &ro, &rd, &rtm);
    assert!(n + ro.len() > 400_000);
    // Mirror reflections: every camera ray that goes down meets a mirror plane at the height of
    // the 2nd-percentile hit and leaves it nudged up, its direction mirrored (the bench's
    // reflection set, without the mirror's triangles): many origins, one virtual eye, traced as
    // frusta.
    let mut heights: Vec<f32> = want
        .iter()
        .zip(&dirs)
        .filter(|(w, _)| w.1 != u32::MAX)
        .map(|(w, dir)| (eye + *dir * f32::from_bits(w.0)).y)
        .collect();
    heights.sort_by(f32::total_cmp);
    let (lo, hi) = mesh.bounds();
    let y = heights[heights.len() / 50] + 0.01 * (hi.y - lo.y);
    let nudge = 1e-4 * (hi - lo).max_element();
    let (mut mo, mut md) = (vec![], vec![]);
    for dir in &dirs {
        let t = (y - eye.y) / dir.y;
        if t > 0.0 && t.is_finite() {
            let p = eye + *dir * t;
            mo.push(Vec3::new(p.x, y + nudge, p.z));
            md.push(Vec3::new(dir.x, -dir.y, dir.z));
        }
    }
    let mtm: Vec<f32> = (0..mo.len())
        .map(|i| {
            if i % 7 == 3 {
                0.5 + (i % 13) as f32
            } else {
                f32::INFINITY
            }
        })
        .collect();
    let mwant = single(&tree, &mo, &md, &mtm);
    assert!(mo.len() > 100_000, "{} mirror rays", mo.len());
    // On one thread every batch is traced whole by its caller's thread; on several, batches of
    // 1,024 rays or more spread their frusta over the pool (the whole set: one batch).
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    for level in Level::supported() {
        for (pool, chunks) in [(&one, [4096, 1000]), (&three, [4096, n])] {
            pool.install(|| {
                for chunk in chunks {
                    let hits = check(&tree, level, chunk, &o, &d, &tm, &want);
                    assert!(hits > n / 2, "{hits} hits of {n}: not a useful test");
                }
                for chunk in [4096, ro.len()] {
                    let hits = check(&tree, level, chunk, &ro, &rd, &rtm, &rwant);
                    assert!(hits > ro.len() / 2, "{hits} of {}", ro.len());
                }
                for chunk in [1000, 4096, mo.len()] {
                    let hits = check(&tree, level, chunk, &mo, &md, &mtm, &mwant);
                    assert!(hits > mo.len() / 2, "{hits} of {}", mo.len());
                }
            });
        }
    }
}
