//! Every traversal variant gives the single-ray answer: 4-ray packets (forced through
//! `KdAccel::packets_forced`, whatever the rays' direction signs), 64-ray frusta (the closest-hit
//! batch on camera rays) and light-rooted shadow bundles (the occluded batch on shadow rays), at
//! every SIMD level this CPU supports, against `intersect_closest` / `intersect_occluded`: the
//! same closest triangle (lowest index on exact ties) with the same `t` bits, and the same
//! occlusion. On at least 100,000 Sibenik rays per variant (camera, shadow and incoherent rays),
//! plus the edge cases: rays along the tree's split planes, origins exactly on them, and rays
//! grazing shared edges and vertices of meshes built here.

use glam::Vec3;
use rayon::prelude::*;
use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree};
use wavefront::mesh::TriangleMesh;
use wavefront::sampling::Rng;
use wavefront::schedule::{Observer, Queues, RenderOptions, Stage, StageRun, render_observed};
use wavefront::simd::Level;
use wavefront::world::World;

/// A set of rays.
#[derive(Default)]
struct Rays {
    o: Vec<Vec3>,
    d: Vec<Vec3>,
    t_max: Vec<f32>,
}

impl Rays {
    fn push(&mut self, o: Vec3, d: Vec3, t_max: f32) {
        self.o.push(o);
        self.d.push(d);
        self.t_max.push(t_max);
    }

    fn len(&self) -> usize {
        self.o.len()
    }
}

/// Every shadow ray the schedule traces.
#[derive(Default)]
struct ShadowRays(Rays);

impl Observer for ShadowRays {
    fn after(&mut self, run: &StageRun, q: &Queues<'_>) {
        if run.stage == Stage::Shadow {
            self.0.o.extend_from_slice(q.shadows.origin());
            self.0.d.extend_from_slice(q.shadows.direction());
            self.0.t_max.extend_from_slice(q.shadows.t_max());
        }
    }
}

/// The mesh's bounding box.
fn bounds(mesh: &TriangleMesh) -> (Vec3, Vec3) {
    mesh.vertices
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(Vec3::from(v)), hi.max(Vec3::from(v)))
        })
}

/// The single-ray answers: closest `(t bits, triangle)` and occlusion.
fn single(accel: &KdAccel, r: &Rays) -> (Vec<(u32, u32)>, Vec<bool>) {
    (0..r.len())
        .into_par_iter()
        .map(|i| {
            let h = accel.intersect_closest(r.o[i], r.d[i], r.t_max[i]);
            (
                h.map_or((f32::INFINITY.to_bits(), u32::MAX), |h| {
                    (h.t.to_bits(), h.tri)
                }),
                accel.intersect_occluded(r.o[i], r.d[i], r.t_max[i]),
            )
        })
        .unzip()
}

/// The forced packets against the single rays; returns the rays checked.
fn check_packets(
    accel: &KdAccel,
    r: &Rays,
    want: &(Vec<(u32, u32)>, Vec<bool>),
    what: &str,
) -> usize {
    let n = r.len();
    let (mut t, mut tri, mut occ) = (vec![0.0f32; n], vec![0u32; n], vec![false; n]);
    // In pieces, in parallel (a piece's length is a multiple of 4 but the last).
    let piece = 4096;
    t.par_chunks_mut(piece)
        .zip(tri.par_chunks_mut(piece))
        .zip(occ.par_chunks_mut(piece))
        .enumerate()
        .for_each(|(c, ((t, tri), occ))| {
            let s = c * piece..c * piece + t.len();
            accel.packets_forced(&r.o[s.clone()], &r.d[s.clone()], &r.t_max[s], t, tri, occ);
        });
    for i in 0..n {
        assert_eq!(
            (t[i].to_bits(), tri[i]),
            want.0[i],
            "{what}: packet closest, ray {i}"
        );
        assert_eq!(occ[i], want.1[i], "{what}: packet occluded, ray {i}");
    }
    n
}

/// The closest-hit batch (frusta where the rays suit them) at `level` against the single rays.
fn check_closest_batch(
    accel: &KdAccel,
    level: Level,
    r: &Rays,
    want: &[(u32, u32)],
    what: &str,
) -> usize {
    let n = r.len();
    let (mut t, mut tri) = (vec![0.0f32; n], vec![0u32; n]);
    let piece = 4096;
    t.par_chunks_mut(piece)
        .zip(tri.par_chunks_mut(piece))
        .enumerate()
        .for_each(|(c, (t, tri))| {
            let s = c * piece..c * piece + t.len();
            accel.intersect_closest_batch_at(
                level,
                &r.o[s.clone()],
                &r.d[s.clone()],
                &r.t_max[s],
                t,
                tri,
            );
        });
    for i in 0..n {
        assert_eq!(
            (t[i].to_bits(), tri[i]),
            want[i],
            "{what}: batch closest at {level:?}, ray {i}"
        );
    }
    n
}

/// The occluded batch (light-rooted bundles where rays share an end point) at `level` against
/// the single rays.
fn check_occluded_batch(
    accel: &KdAccel,
    level: Level,
    r: &Rays,
    want: &[bool],
    what: &str,
) -> usize {
    let n = r.len();
    let mut occ = vec![false; n];
    let piece = KdAccel::OCCLUDED_BATCH;
    occ.par_chunks_mut(piece).enumerate().for_each(|(c, occ)| {
        let s = c * piece..c * piece + occ.len();
        accel.intersect_occluded_batch_counted(
            level,
            &r.o[s.clone()],
            &r.d[s.clone()],
            &r.t_max[s],
            occ,
        );
    });
    for i in 0..n {
        assert_eq!(
            occ[i], want[i],
            "{what}: batch occluded at {level:?}, ray {i}: {:?} {:?} {}",
            r.o[i], r.d[i], r.t_max[i]
        );
    }
    n
}

/// Sibenik's camera rays (512², every 7th with a `t_max` cutting some hits), its shadow rays
/// (one render) and incoherent rays between random points inside the nave.
#[test]
fn every_variant_matches_single_rays_on_sibenik() {
    let Some(scene) = wavefront_kit::testkit::sibenik_scene(true) else {
        return;
    };
    let world = World::load(&scene).expect("load sibenik");
    let tris = world.triangles().expect("a mesh");
    let accel = KdAccel::new(tris.tree().clone(), tris.mesh());

    let camera = scene.camera.clone();
    let eye = camera.eye.as_vec3();
    let mut cam = Rays::default();
    for (i, d) in camera
        .pixel_centre_directions(512, 512)
        .into_iter()
        .enumerate()
    {
        let t_max = if i % 7 == 3 {
            0.5 + (i % 13) as f32
        } else {
            f32::INFINITY
        };
        cam.push(eye, d, t_max);
    }
    let mut shadow = ShadowRays::default();
    render_observed(&scene, &world, &RenderOptions::default(), &mut shadow);
    let shadow = shadow.0;
    let mut rng = Rng(0x7a41_a175);
    let (lo, hi) = bounds(tris.mesh());
    let point = |rng: &mut Rng| {
        Vec3::new(
            rng.range(lo.x, hi.x),
            rng.range(lo.y, hi.y),
            rng.range(lo.z, hi.z),
        )
    };
    let mut random = Rays::default();
    for i in 0..131_072 {
        let (p, q) = (point(&mut rng), point(&mut rng));
        random.push(p, q - p, if i % 2 == 0 { 1.0 } else { f32::INFINITY });
    }

    let mut total = 0;
    for (what, r) in [("camera", &cam), ("shadow", &shadow), ("random", &random)] {
        assert!(r.len() >= 100_000, "{what}: only {} rays", r.len());
        let want = single(&accel, r);
        let hits = want.0.iter().filter(|w| w.1 != u32::MAX).count();
        assert!(hits > r.len() / 10, "{what}: {hits} hits of {}", r.len());
        total += check_packets(&accel, r, &want, what);
        for level in Level::supported() {
            total += check_closest_batch(&accel, level, r, &want.0, what);
            total += check_occluded_batch(&accel, level, r, &want.1, what);
        }
    }
    assert!(total > 500_000, "{total}");
}

/// Rays in and across the split planes of Sibenik's tree: origins exactly on a plane, moving
/// along it (the direction's component on the axis ±0) or through it; grouped 4 by 4 with a
/// shared origin, and 256 at a time from one origin (so the batch takes frusta), and shadow-like
/// rays that all end at one point on a plane (so the occluded batch takes bundles).
#[test]
fn every_variant_matches_single_rays_on_sibenik_split_planes() {
    let Some(scene) = wavefront_kit::testkit::sibenik_scene(false) else {
        return;
    };
    let world = World::load(&scene).expect("load sibenik");
    let tris = world.triangles().expect("a mesh");
    let accel = KdAccel::new(tris.tree().clone(), tris.mesh());
    let (lo, hi) = bounds(tris.mesh());
    let planes: Vec<(usize, f32)> = accel
        .tree()
        .nodes()
        .iter()
        .filter(|n| !n.is_leaf())
        .map(|n| (n.axis(), n.split()))
        .collect();
    assert!(planes.len() > 1000);
    let mut rng = Rng(0x5b1e_a9e5);
    let mut r = Rays::default();
    let mut round = 0;
    while r.len() < 120_000 {
        round += 1;
        let (axis, split) = planes[(rng.next_u64() % planes.len() as u64) as usize];
        let mut o = Vec3::new(
            rng.range(lo.x, hi.x),
            rng.range(lo.y, hi.y),
            rng.range(lo.z, hi.z),
        );
        o[axis] = split;
        let fan = if round % 8 == 0 { 256 } else { 4 };
        for k in 0..fan {
            let mut d = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            match k % 3 {
                0 => d[axis] = 0.0,
                1 => d[axis] = -0.0,
                _ => {}
            }
            r.push(o, d, if k % 5 == 0 { 2.0 } else { f32::INFINITY });
        }
        if round % 8 == 4 {
            // Shadow-like rays from points on other planes to this origin.
            for _ in 0..64 {
                let (a2, s2) = planes[(rng.next_u64() % planes.len() as u64) as usize];
                let mut p = Vec3::new(
                    rng.range(lo.x, hi.x),
                    rng.range(lo.y, hi.y),
                    rng.range(lo.z, hi.z),
                );
                p[a2] = s2;
                r.push(p, o - p, 1.0);
            }
        }
    }
    let want = single(&accel, &r);
    check_packets(&accel, &r, &want, "split planes");
    for level in Level::supported() {
        check_closest_batch(&accel, level, &r, &want.0, "split planes");
        check_occluded_batch(&accel, level, &r, &want.1, "split planes");
    }
}

/// A grid of unit squares, each split into two triangles along a diagonal, on several parallel
/// planes (and a copy of each triangle: exact ties), in integer coordinates so the trees split
/// on the vertices' planes.
fn grid_mesh() -> TriangleMesh {
    let (mut v, mut idx) = (vec![], vec![]);
    for z in [0.0f32, 2.0, 3.0] {
        for i in 0..6 {
            for j in 0..6 {
                let base = v.len() as u32;
                let (x, y) = (i as f32, j as f32);
                v.extend([
                    [x, y, z],
                    [x + 1.0, y, z],
                    [x + 1.0, y + 1.0, z],
                    [x, y + 1.0, z],
                ]);
                idx.push([base, base + 1, base + 2]);
                idx.push([base, base + 2, base + 3]);
                if (i + j) % 5 == 0 {
                    idx.push([base + 2, base, base + 1]);
                }
            }
        }
    }
    // Two walls across the planes, sharing an edge with each other.
    let base = v.len() as u32;
    v.extend([
        [3.0, 0.0, -1.0],
        [3.0, 6.0, -1.0],
        [3.0, 6.0, 4.0],
        [3.0, 0.0, 4.0],
        [0.0, 3.0, 4.0],
    ]);
    idx.extend([
        [base, base + 1, base + 2],
        [base, base + 2, base + 3],
        [base + 3, base + 2, base + 4],
    ]);
    TriangleMesh::new(v, idx)
}

/// Rays grazing the grid's shared edges and vertices (aimed exactly at edge midpoints, vertices
/// and the diagonals), from origins on the grid's planes and between them, along the planes, in
/// fans of 4 and of 256 (frusta) and as shadow rays to a shared point (bundles), through both
/// builders' trees.
#[test]
fn every_variant_matches_single_rays_on_grazing_edges() {
    let mesh = grid_mesh();
    let mut rng = Rng(0x0ed9_e5a1);
    let mut r = Rays::default();
    let coarse = |rng: &mut Rng, n: u64| (rng.next_u64() % (2 * n + 1)) as f32 * 0.5;
    let mut round = 0;
    while r.len() < 100_000 {
        round += 1;
        let o = Vec3::new(
            coarse(&mut rng, 6) - 0.5,
            coarse(&mut rng, 6) - 0.5,
            coarse(&mut rng, 5) - 1.0,
        );
        let fan = if round % 8 == 0 { 256 } else { 4 };
        for k in 0..fan {
            // A target on an edge, a vertex or a diagonal of the grid (every coordinate a
            // multiple of 0.5 on a grid plane), sometimes moved along the ray past it.
            let z = [0.0, 2.0, 3.0][(rng.next_u64() % 3) as usize];
            let target = Vec3::new(coarse(&mut rng, 6), coarse(&mut rng, 6), z);
            let mut d = target - o;
            if k % 7 == 0 {
                d.z = 0.0; // along a plane
            }
            let t_max = match k % 4 {
                0 => 1.0, // ends exactly on the target
                1 => 2.0,
                _ => f32::INFINITY,
            };
            r.push(o, d, t_max);
        }
        if round % 8 == 4 {
            let light = Vec3::new(coarse(&mut rng, 6), coarse(&mut rng, 6), 5.0);
            for _ in 0..128 {
                let p = Vec3::new(
                    coarse(&mut rng, 6),
                    coarse(&mut rng, 6),
                    [0.0, 2.0, 3.0][(rng.next_u64() % 3) as usize],
                );
                r.push(p, light - p, 1.0);
            }
        }
    }
    for method in [BuildMethod::Sah, BuildMethod::Midpoint] {
        let accel = KdAccel::new(KdTree::build(&mesh, method), &mesh);
        let want = single(&accel, &r);
        let hits = want.0.iter().filter(|w| w.1 != u32::MAX).count();
        assert!(
            hits > r.len() / 10 && hits < r.len() * 9 / 10,
            "{hits} of {}",
            r.len()
        );
        // The single rays against the brute-force reference on a sample (not the rays lying
        // in a plane of the grid's triangles: a triangle seen edge-on is another question).
        for i in (0..r.len()).step_by(97).filter(|&i| r.d[i].z != 0.0) {
            let bf = wavefront::geometry::triangle::intersect_all_closest(
                &mesh, r.o[i], r.d[i], r.t_max[i],
            );
            assert_eq!(
                bf.map_or((f32::INFINITY.to_bits(), u32::MAX), |(t, tri)| (
                    t.to_bits(),
                    tri
                )),
                want.0[i],
                "{method:?}: brute force, ray {i}: {:?} {:?} {}",
                r.o[i],
                r.d[i],
                r.t_max[i]
            );
        }
        let what = format!("grid, {method:?}");
        check_packets(&accel, &r, &want, &what);
        for level in Level::supported() {
            check_closest_batch(&accel, level, &r, &want.0, &what);
            check_occluded_batch(&accel, level, &r, &want.1, &what);
        }
    }
}
