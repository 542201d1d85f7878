//! Numerical stability of triangles and kD traversal: watertightness far from the origin,
//! rays through shared vertices and edges, degenerate triangles, subnormal and signed-zero
//! directions, poisoned rays.

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree, TriHit};
use wavefront::geometry::triangle::{intersect_all_closest, intersect_all_occluded};
use wavefront::mesh::TriangleMesh;
use wavefront_kit::testkit::Rng;

const PLANE_X: f32 = 148_376.0;
const CELLS: u32 = 200; // 200 × 200 quads = 80,000 triangles

/// A grid of `CELLS²` quads in the plane `x = PLANE_X`, spanning `[-1, 1]²` in y and z, each split
/// into two triangles along alternating diagonals.
fn grid() -> TriangleMesh {
    let n = CELLS + 1;
    let coord = |k: u32| -1.0 + 2.0 * k as f32 / CELLS as f32;
    let mut vertices = Vec::with_capacity((n * n) as usize);
    for j in 0..n {
        for i in 0..n {
            vertices.push([PLANE_X, coord(i), coord(j)]);
        }
    }
    let mut indices = Vec::with_capacity((2 * CELLS * CELLS) as usize);
    for j in 0..CELLS {
        for i in 0..CELLS {
            let v = |di: u32, dj: u32| (j + dj) * n + i + di;
            if (i + j) % 2 == 0 {
                indices.push([v(0, 0), v(1, 0), v(1, 1)]);
                indices.push([v(0, 0), v(1, 1), v(0, 1)]);
            } else {
                indices.push([v(0, 0), v(1, 0), v(0, 1)]);
                indices.push([v(1, 0), v(1, 1), v(0, 1)]);
            }
        }
    }
    TriangleMesh::new(vertices, indices)
}

fn trace_all(tree: &KdAccel, rays: &[(Vec3, Vec3)]) -> Vec<Option<TriHit>> {
    rays.par_iter()
        .map(|&(o, d)| tree.intersect_closest(o, d, f32::INFINITY))
        .collect()
}

#[test]
fn a_far_grid_plane_has_no_cracks() {
    let mesh = grid();
    assert_eq!(mesh.len(), 80_000);
    let trees: Vec<_> = [BuildMethod::Sah, BuildMethod::Midpoint]
        .into_iter()
        .map(|m| (m, KdAccel::new(KdTree::build(&mesh, m), &mesh)))
        .collect();

    // 10^6 rays from 3 units in front of the plane to random points inside it.
    let mut rng = Rng(148_376);
    let rays: Vec<(Vec3, Vec3)> = (0..1_000_000)
        .map(|_| {
            let o = Vec3::new(PLANE_X - 3.0, rng.unit() - 0.5, rng.unit() - 0.5);
            let target = Vec3::new(PLANE_X, 1.9 * rng.unit() - 0.95, 1.9 * rng.unit() - 0.95);
            (o, (target - o).normalize())
        })
        .collect();
    for (method, tree) in &trees {
        let misses = trace_all(tree, &rays)
            .iter()
            .filter(|h| h.is_none())
            .count();
        assert_eq!(
            misses, 0,
            "{method:?}: {misses} of 10^6 rays fell through the grid"
        );
    }

    // Rays aimed exactly at every shared vertex and the midpoint of every interior edge of a
    // 40 × 40 patch, from both sides, with the origin offset in y and z as well.
    let mut exact = vec![];
    for j in 80..=120u32 {
        for i in 80..=120u32 {
            let c = |k: u32| -1.0 + 2.0 * k as f32 / CELLS as f32;
            let half = 1.0 / CELLS as f32;
            for target in [
                Vec3::new(PLANE_X, c(i), c(j)),
                Vec3::new(PLANE_X, c(i) + half, c(j)),
                Vec3::new(PLANE_X, c(i), c(j) + half),
                Vec3::new(PLANE_X, c(i) + half, c(j) + half),
            ] {
                for o in [
                    Vec3::new(PLANE_X - 3.0, 0.25, -0.125),
                    Vec3::new(PLANE_X + 3.0, -0.5, 0.375),
                ] {
                    exact.push((o, target - o));
                }
            }
        }
    }
    let answers: Vec<_> = trees.iter().map(|(_, t)| trace_all(t, &exact)).collect();
    for (method, hits) in trees.iter().map(|(m, _)| m).zip(&answers) {
        let misses = hits.iter().filter(|h| h.is_none()).count();
        assert_eq!(
            misses, 0,
            "{method:?}: {misses} rays through vertices or edges missed"
        );
    }
    assert_eq!(
        answers[0], answers[1],
        "builders chose different triangles at shared vertices or edges"
    );
    // The same on one thread.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let single = pool.install(|| trace_all(&trees[0].1, &exact));
    assert_eq!(
        single, answers[0],
        "thread count changed the chosen triangle"
    );
}

/// Distance, in f64, from where the ray meets the plane `z = 0` to the triangle (which lies in
/// that plane); 0 inside.
fn distance_in_plane(o: Vec3, d: Vec3, tri: [Vec3; 3]) -> f64 {
    let (o, d): (DVec3, DVec3) = (o.as_dvec3(), d.as_dvec3());
    let p = o + (-o.z / d.z) * d;
    let [a, b, c] = tri.map(|v| v.as_dvec3().truncate());
    let p = p.truncate();
    let cross = |u: glam::DVec2, v: glam::DVec2| u.x * v.y - u.y * v.x;
    let area = cross(b - a, c - a);
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(u, v)| cross(v - u, p - u) * area.signum() >= 0.0);
    if inside && area != 0.0 {
        return 0.0;
    }
    [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(u, v)| {
            let e = v - u;
            let t = ((p - u).dot(e) / e.length_squared()).clamp(0.0, 1.0);
            (p - (u + t * e)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn degenerate_triangles_are_never_hit_and_never_produce_nan() {
    let vertices = vec![
        // collinear
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [2.0, 2.0, 0.0],
        // repeated vertex
        [0.0, 1.0, 0.0],
        [1.0, 2.0, 0.0],
        // needle 1e-7 wide and 1 long
        [0.0, -1.0, 0.0],
        [1.0, -1.0, 0.0],
        [0.5, -1.0 + 1e-7, 0.0],
    ];
    let indices = vec![[0, 1, 2], [3, 3, 4], [3, 4, 4], [5, 6, 7]];
    let mesh = TriangleMesh::new(vertices, indices);
    for method in [BuildMethod::Sah, BuildMethod::Midpoint] {
        let tree = KdAccel::new(KdTree::build(&mesh, method), &mesh);
        let mut rng = Rng(99);
        let (mut needle_hits, mut clear_misses) = (0, 0);
        for k in 0..200_000 {
            // Rays from above at points along and across the degenerate shapes.
            let target = match k % 3 {
                0 => Vec3::new(2.0 * rng.unit(), 2.0 * rng.unit(), 0.0),
                1 => Vec3::new(rng.unit(), 1.0 + rng.unit(), 0.0),
                _ => Vec3::new(rng.unit(), -1.0 + 4e-6 * (rng.unit() - 0.5), 0.0),
            };
            let o = Vec3::new(0.3, 0.2, 2.0) + Vec3::new(rng.unit(), rng.unit(), 0.0);
            let d = target - o;
            if let Some(h) = tree.intersect_closest(o, d, f32::INFINITY) {
                assert!(h.t.is_finite() && h.t > 0.0, "bad t {}", h.t);
                assert_eq!(h.tri, 3, "a zero-area triangle was hit ({method:?})");
                // f32 inputs near 1 are only known to ~1.2e-7; a hit may stray from the exact
                // (f64) triangle by a few such ulps, not more.
                let off = distance_in_plane(o, d, mesh.triangle(3));
                assert!(off <= 5e-7, "hit {off:e} away from the needle ({method:?})");
                needle_hits += 1;
            } else if k % 3 == 2 && distance_in_plane(o, d, mesh.triangle(3)) == 0.0 {
                clear_misses += 1;
            }
            assert_eq!(
                tree.intersect_occluded(o, d, f32::INFINITY),
                intersect_all_occluded(&mesh, o, d, f32::INFINITY)
            );
        }
        assert!(
            needle_hits > 100,
            "the needle must be hit for the test to be live ({needle_hits})"
        );
        // Misses of rays that f64 puts inside the needle are allowed (it is thinner than the
        // rounding of its inputs) but must stay a minority.
        assert!(
            clear_misses < needle_hits,
            "{clear_misses} misses vs {needle_hits} hits"
        );
    }
}

/// A seeded soup of small triangles in the unit cube.
fn soup(n: usize, seed: u64) -> TriangleMesh {
    let mut rng = Rng(seed);
    let mut vertices = vec![];
    let mut indices = vec![];
    for k in 0..n {
        let c = Vec3::new(rng.unit(), rng.unit(), rng.unit());
        for _ in 0..3 {
            let v = c + 0.05 * Vec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5);
            vertices.push(v.to_array());
        }
        let b = 3 * k as u32;
        indices.push([b, b + 1, b + 2]);
    }
    TriangleMesh::new(vertices, indices)
}

#[test]
fn subnormal_and_signed_zero_directions_match_brute_force() {
    let mesh = soup(3000, 5);
    let tiny = f32::from_bits(1); // smallest subnormal
    let sub = 1e-40f32;
    let trees = [BuildMethod::Sah, BuildMethod::Midpoint]
        .map(|method| KdAccel::new(KdTree::build(&mesh, method), &mesh));
    let mut rng = Rng(11);
    let mut hits = 0;
    for k in 0..20_000 {
        let o = Vec3::new(rng.unit(), rng.unit(), -0.5);
        let mut d = Vec3::new(0.0, 0.0, 1.0);
        // Cycle through ±0, ±smallest subnormal and a mid subnormal in x and y.
        let comps = [0.0, -0.0, tiny, -tiny, sub, -sub];
        d.x = comps[k % comps.len()];
        d.y = comps[(k / comps.len()) % comps.len()];
        let expected = intersect_all_closest(&mesh, o, d, f32::INFINITY);
        for tree in &trees {
            let got = tree
                .intersect_closest(o, d, f32::INFINITY)
                .map(|h| (h.t.to_bits(), h.tri));
            assert_eq!(
                got,
                expected.map(|(t, i)| (t.to_bits(), i)),
                "ray {o} {d:?}"
            );
            assert_eq!(
                tree.intersect_occluded(o, d, f32::INFINITY),
                expected.is_some()
            );
        }
        hits += usize::from(expected.is_some());
    }
    assert!(
        hits > 1000,
        "the rays must hit often for the test to be live ({hits})"
    );
}

#[test]
fn poisoned_rays_terminate_and_miss_in_the_tree() {
    let mesh = soup(3000, 6);
    let tree = KdAccel::new(KdTree::build(&mesh, BuildMethod::Sah), &mesh);
    let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    for &b in &bad {
        for (o, d) in [
            (Vec3::new(b, 0.5, 0.5), Vec3::X),
            (Vec3::new(0.5, 0.5, -1.0), Vec3::new(0.0, b, 1.0)),
            (Vec3::new(0.5, 0.5, -1.0), Vec3::splat(b)),
            (Vec3::new(0.5, 0.5, -1.0), Vec3::ZERO),
        ] {
            assert_eq!(tree.intersect_closest(o, d, f32::INFINITY), None, "{o} {d}");
            assert!(!tree.intersect_occluded(o, d, f32::INFINITY), "{o} {d}");
        }
    }
}
