//! kD tree against brute force: Sibenik with seeded random and axis-parallel rays for every
//! builder and the text round trip, plus small hand-made meshes with known answers.

use glam::Vec3;
use rayon::prelude::*;
use wavefront::accel::kdtree::{BuildMethod, KdAccel, KdTree, TriHit};
use wavefront::geometry::triangle::{WatertightRay, intersect_all_closest, intersect_all_occluded};
use wavefront::mesh::TriangleMesh;
use wavefront::sampling::Rng;

/// A random unnormalised direction: uniform in the unit ball (away from the centre), scaled by
/// 0.1–10.
fn random_dir(rng: &mut Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let l = v.length();
        if l > 0.05 && l <= 1.0 {
            // Unnormalised on purpose.
            return v * rng.range(0.1, 10.0);
        }
    }
}

fn sibenik() -> Option<TriangleMesh> {
    wavefront_kit::testkit::sibenik_triangles()
}

/// Brute force over a superset of the triangles a ray can hit: every triangle whose bounding box
/// touches a coarse grid cell (inflated by a margin) that the ray crosses, cells taken in order of
/// entry distance. Each candidate is tested exactly as the plain brute force does and the minimum
/// by `(t, index)` is kept, so the answer equals `intersect_all_closest`'s (checked on a subset of
/// rays below). Only here to keep 100,000+ rays within a few seconds.
struct GridOracle {
    cells: Vec<Vec<u32>>,
    boxes: Vec<(Vec3, Vec3)>,
}

const G: usize = 16;

impl GridOracle {
    fn new(mesh: &TriangleMesh) -> GridOracle {
        let (lo, hi) = mesh.bounds();
        let size = (hi - lo) / G as f32;
        let margin = (hi - lo).max_element() * 1e-3;
        let mut cells = vec![Vec::new(); G * G * G];
        let mut boxes = Vec::with_capacity(G * G * G);
        for z in 0..G {
            for y in 0..G {
                for x in 0..G {
                    let c = Vec3::new(x as f32, y as f32, z as f32);
                    boxes.push((lo + c * size - margin, lo + (c + 1.0) * size + margin));
                }
            }
        }
        let cell_of = |p: Vec3| {
            ((p - lo) / size)
                .floor()
                .clamp(Vec3::ZERO, Vec3::splat(G as f32 - 1.0))
        };
        for k in 0..mesh.len() {
            let [a, b, c] = mesh.triangle(k);
            let c0 = cell_of(a.min(b).min(c) - margin);
            let c1 = cell_of(a.max(b).max(c) + margin);
            for z in c0.z as usize..=c1.z as usize {
                for y in c0.y as usize..=c1.y as usize {
                    for x in c0.x as usize..=c1.x as usize {
                        cells[(z * G + y) * G + x].push(k as u32);
                    }
                }
            }
        }
        GridOracle { cells, boxes }
    }

    fn closest(&self, mesh: &TriangleMesh, o: Vec3, d: Vec3, t_max: f32) -> Option<(f32, u32)> {
        let ray = WatertightRay::new(o, d)?;
        let inv = Vec3::ONE / d;
        let hits = |lo: Vec3, hi: Vec3| {
            let ta = (lo - o) * inv;
            let tb = (hi - o) * inv;
            let mut t0 = 0.0f32;
            let mut t1 = t_max;
            for a in 0..3 {
                t0 = t0.max(ta[a].min(tb[a]));
                t1 = t1.min(ta[a].max(tb[a]));
            }
            (t0 <= t1).then_some(t0)
        };
        // Cells the ray crosses, with their entry distance.
        let mut cells: Vec<(f32, usize)> = Vec::new();
        // Two levels: blocks of 4x4x4 cells (their inflated union box), then the cells.
        for bz in 0..G / 4 {
            for by in 0..G / 4 {
                for bx in 0..G / 4 {
                    let first = (bz * 4 * G + by * 4) * G + bx * 4;
                    let last = ((bz * 4 + 3) * G + by * 4 + 3) * G + bx * 4 + 3;
                    if hits(self.boxes[first].0, self.boxes[last].1).is_none() {
                        continue;
                    }
                    for z in bz * 4..bz * 4 + 4 {
                        for y in by * 4..by * 4 + 4 {
                            for x in bx * 4..bx * 4 + 4 {
                                let i = (z * G + y) * G + x;
                                if let Some(t0) = hits(self.boxes[i].0, self.boxes[i].1) {
                                    cells.push((t0, i));
                                }
                            }
                        }
                    }
                }
            }
        }
        cells.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // A hit at t lies in a cell whose inflated box the ray enters well before t, so once
        // the next cell starts beyond the best t, nothing closer (or tying) remains.
        let mut best: Option<(f32, u32)> = None;
        for (t0, i) in cells {
            if best.is_some_and(|b| t0 > b.0) {
                break;
            }
            for &k in &self.cells[i] {
                let [p0, p1, p2] = mesh.indices[k as usize].map(|i| mesh.vertices[i as usize]);
                if let Some(t) = ray.intersect(p0, p1, p2, t_max)
                    && best.is_none_or(|b| t < b.0 || (t == b.0 && k < b.1))
                    && !mesh.is_degenerate(k as usize)
                {
                    best = Some((t, k));
                }
            }
        }
        best
    }
}

fn sibenik_rays(mesh: &TriangleMesh, tree: &KdTree) -> Vec<(Vec3, Vec3)> {
    let (lo, hi) = mesh.bounds();
    let centre = (lo + hi) * 0.5;
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut rays = Vec::new();
    let inside = |rng: &mut Rng| {
        Vec3::new(
            rng.range(lo.x, hi.x),
            rng.range(lo.y, hi.y),
            rng.range(lo.z, hi.z),
        )
    };
    // Origins inside the box, random directions.
    for _ in 0..45_000 {
        let o = inside(&mut rng);
        rays.push((o, random_dir(&mut rng)));
    }
    // Origins outside, aimed at points inside (and some random, mostly missing).
    for i in 0..30_000 {
        let o = centre + random_dir(&mut rng).normalize() * 40.0;
        let d = if i % 5 == 0 {
            random_dir(&mut rng)
        } else {
            (inside(&mut rng) - o) * rng.range(0.01, 3.0)
        };
        rays.push((o, d));
    }
    // Origins exactly on split planes of the tree.
    let splits: Vec<(usize, f32)> = tree
        .nodes()
        .iter()
        .filter(|n| !n.is_leaf())
        .map(|n| (n.axis(), n.split()))
        .collect();
    for i in 0..15_000 {
        let (axis, s) = splits[(rng.next_u64() % splits.len() as u64) as usize];
        let mut o = inside(&mut rng);
        o[axis] = s;
        let mut d = random_dir(&mut rng);
        if i % 3 == 0 {
            d[axis] = if i % 2 == 0 { 0.0 } else { -0.0 }; // parallel to, and in, the plane
        }
        rays.push((o, d));
    }
    // Axis-parallel grids from every face, on the face and outside, with +0.0 and -0.0.
    let n = 24;
    for axis in 0..3 {
        for side in 0..2 {
            for zero in [0.0f32, -0.0] {
                for offset in [0.0f32, 1.0] {
                    for i in 0..n {
                        for j in 0..n {
                            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                            let mut o = Vec3::ZERO;
                            let mut d = Vec3::splat(zero);
                            o[a1] = lo[a1] + (hi[a1] - lo[a1]) * (i as f32 + 0.37) / n as f32;
                            o[a2] = lo[a2] + (hi[a2] - lo[a2]) * (j as f32 + 0.61) / n as f32;
                            if side == 0 {
                                o[axis] = lo[axis] - offset;
                                d[axis] = 1.0;
                            } else {
                                o[axis] = hi[axis] + offset;
                                d[axis] = -2.5;
                            }
                            rays.push((o, d));
                        }
                    }
                }
            }
        }
    }
    rays
}

fn check_tree(
    name: &str,
    full: bool,
    tree: &KdTree,
    mesh: &TriangleMesh,
    rays: &[(Vec3, Vec3)],
    want: &[Option<(f32, u32)>],
) {
    let tree = &KdAccel::new(tree.clone(), mesh);
    let bad: Vec<String> = rays
        .par_iter()
        .zip(want)
        .enumerate()
        .filter_map(|(i, (&(o, d), &w))| {
            let got = tree
                .intersect_closest(o, d, f32::INFINITY)
                .map(|h| (h.t, h.tri));
            let same = match (got, w) {
                (Some(a), Some(b)) => a.0.to_bits() == b.0.to_bits() && a.1 == b.1,
                (None, None) => true,
                _ => false,
            };
            if !same {
                return Some(format!(
                    "{name} ray {i} o={o:?} d={d:?}: closest {got:?}, brute {w:?}"
                ));
            }
            let occ_inf = tree.intersect_occluded(o, d, f32::INFINITY);
            if occ_inf != w.is_some() {
                return Some(format!(
                    "{name} ray {i}: occluded(inf) {occ_inf}, brute {w:?}"
                ));
            }
            if let Some((t, _)) = w {
                // Strict t_max: the closest hit itself does not occlude at t_max = t.
                if full && tree.intersect_occluded(o, d, t) {
                    return Some(format!(
                        "{name} ray {i} o={o:?} d={d:?}: occluded at t_max = t = {t:e}"
                    ));
                }
                if full && !tree.intersect_occluded(o, d, t.next_up()) {
                    return Some(format!(
                        "{name} ray {i} o={o:?} d={d:?}: not occluded just past t = {t:e}"
                    ));
                }
                if full && tree.intersect_closest(o, d, t).is_some() {
                    return Some(format!("{name} ray {i}: closest hit with t_max = t"));
                }
            }
            None
        })
        .collect();
    assert!(
        bad.is_empty(),
        "{} mismatches, first: {:?}",
        bad.len(),
        &bad[..bad.len().min(5)]
    );
    // The batch (packet) queries give the same answers bit for bit. Rays sorted by direction
    // octant, so nearly every group of 4 is traced as a packet (lanes with unrelated origins
    // and directions: the lanes often disagree on the near child).
    let sign = |d: Vec3| {
        d.x.is_sign_negative() as u8
            | (d.y.is_sign_negative() as u8) << 1
            | (d.z.is_sign_negative() as u8) << 2
    };
    let mut order: Vec<usize> = (0..rays.len()).collect();
    order.sort_by_key(|&i| sign(rays[i].1));
    let (o, d): (Vec<Vec3>, Vec<Vec3>) = order.iter().map(|&i| rays[i]).unzip();
    let n = order.len();
    let tm = vec![f32::INFINITY; n];
    let (mut bt, mut btri, mut occ) = (vec![0.0; n], vec![0u32; n], vec![false; n]);
    tree.intersect_closest_batch(&o, &d, &tm, &mut bt, &mut btri);
    tree.intersect_occluded_batch(&o, &d, &tm, &mut occ);
    for (j, &i) in order.iter().enumerate() {
        let got = (btri[j] != u32::MAX).then_some((bt[j].to_bits(), btri[j]));
        assert_eq!(
            got,
            want[i].map(|(t, k)| (t.to_bits(), k)),
            "{name} batch closest ray {i}"
        );
        assert_eq!(occ[j], want[i].is_some(), "{name} batch occluded ray {i}");
    }
}

#[test]
fn every_builder_and_the_text_round_trip_match_brute_force_on_sibenik() {
    let Some(mesh) = sibenik() else { return };
    let clock = std::time::Instant::now();
    let lap = |what: &str| eprintln!("{what}: {:.2} s", clock.elapsed().as_secs_f64());
    let sah = KdTree::build(&mesh, BuildMethod::Sah);
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool")
        .install(|| KdTree::build(&mesh, BuildMethod::Sah));
    assert_eq!(one_thread, sah, "sah tree depends on the thread count");
    let midpoint = KdTree::build(&mesh, BuildMethod::Midpoint);
    sah.validate(&mesh).expect("sah tree valid");
    midpoint.validate(&mesh).expect("midpoint tree valid");
    let mut text = Vec::new();
    sah.write_text(&mut text).expect("write");
    let read = KdTree::read_text(&text[..], "mem.kd".as_ref(), mesh.len()).expect("read back");
    assert_eq!(read, sah, "round trip changes the tree");
    read.validate(&mesh).expect("read tree valid");

    lap("built, validated, round trip");
    let rays = sibenik_rays(&mesh, &sah);
    assert!(rays.len() >= 100_000);
    let oracle = GridOracle::new(&mesh);
    let want: Vec<Option<(f32, u32)>> = rays
        .par_iter()
        .map(|&(o, d)| oracle.closest(&mesh, o, d, f32::INFINITY))
        .collect();
    lap("oracle");
    // The culled oracle equals the plain brute force (checked on a spread subset).
    let sub: Vec<usize> = (0..rays.len()).step_by(rays.len() / 300).collect();
    sub.par_iter().for_each(|&i| {
        let (o, d) = rays[i];
        let plain = intersect_all_closest(&mesh, o, d, f32::INFINITY);
        assert_eq!(
            plain.map(|h| (h.0.to_bits(), h.1)),
            want[i].map(|h| (h.0.to_bits(), h.1)),
            "ray {i}"
        );
        assert_eq!(
            intersect_all_occluded(&mesh, o, d, f32::INFINITY),
            plain.is_some()
        );
    });
    let hits = want.iter().filter(|w| w.is_some()).count();
    assert!(
        hits > rays.len() / 3,
        "too few hits ({hits}) to be a meaningful test"
    );

    lap("plain brute force subset");
    check_tree("sah", true, &sah, &mesh, &rays, &want);
    check_tree("text", true, &read, &mesh, &rays, &want);
    lap("sah and text trees");
    check_tree("midpoint", false, &midpoint, &mesh, &rays, &want);
    lap("midpoint tree");
}

// ---- small meshes with known answers ----

fn build_both(mesh: &TriangleMesh) -> [KdAccel; 2] {
    [BuildMethod::Midpoint, BuildMethod::Sah].map(|method| {
        let tree = KdTree::build(mesh, method);
        tree.validate(mesh).expect("valid");
        KdAccel::new(tree, mesh)
    })
}

#[test]
fn quad_is_hit_inside_and_missed_outside() {
    let mesh = TriangleMesh::new(
        vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    for tree in build_both(&mesh) {
        let h = tree.intersect_closest(Vec3::new(0.25, 0.75, 0.0), Vec3::Z * 2.0, f32::INFINITY);
        assert_eq!(h, Some(TriHit { t: 0.5, tri: 1 }));
        let h = tree.intersect_closest(Vec3::new(0.75, 0.25, 3.0), -Vec3::Z, f32::INFINITY);
        assert_eq!(h, Some(TriHit { t: 2.0, tri: 0 }));
        // On the shared diagonal: both triangles at equal t, the lower index wins.
        let h = tree.intersect_closest(Vec3::new(0.5, 0.5, 0.0), Vec3::Z, f32::INFINITY);
        assert_eq!(h, Some(TriHit { t: 1.0, tri: 0 }));
        assert_eq!(
            tree.intersect_closest(Vec3::new(1.5, 0.5, 0.0), Vec3::Z, f32::INFINITY),
            None
        );
        assert!(!tree.intersect_occluded(Vec3::new(0.5, 0.25, 0.0), Vec3::Z, 1.0));
        assert!(tree.intersect_occluded(Vec3::new(0.5, 0.25, 0.0), Vec3::Z, 1.5));
    }
}

fn cube() -> TriangleMesh {
    let mut v = Vec::new();
    for i in 0..8 {
        v.push([
            (i & 1) as f32 * 2.0 - 1.0,
            ((i >> 1) & 1) as f32 * 2.0 - 1.0,
            ((i >> 2) & 1) as f32 * 2.0 - 1.0,
        ]);
    }
    let quads = [
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ];
    let mut idx = Vec::new();
    for q in quads {
        idx.push([q[0], q[1], q[2]]);
        idx.push([q[0], q[2], q[3]]);
    }
    TriangleMesh::new(v, idx)
}

#[test]
fn every_ray_from_inside_a_closed_cube_hits_it() {
    let mesh = cube();
    let mut rng = Rng(7);
    for tree in build_both(&mesh) {
        for i in 0..20_000 {
            let o = Vec3::new(
                rng.range(-0.9, 0.9),
                rng.range(-0.9, 0.9),
                rng.range(-0.9, 0.9),
            );
            let mut d = random_dir(&mut rng);
            if i % 4 == 0 {
                d[i % 3] = if i % 8 == 0 { 0.0 } else { -0.0 };
            }
            let h = tree
                .intersect_closest(o, d, f32::INFINITY)
                .expect("inside a closed cube");
            let brute = intersect_all_closest(&mesh, o, d, f32::INFINITY).expect("brute");
            assert_eq!((h.t.to_bits(), h.tri), (brute.0.to_bits(), brute.1));
            assert!(tree.intersect_occluded(o, d, f32::INFINITY));
        }
        // From the centre along the axes, on every edge and corner direction.
        for d in [
            Vec3::X,
            -Vec3::X,
            Vec3::Y,
            -Vec3::Y,
            Vec3::Z,
            -Vec3::Z,
            Vec3::ONE,
            -Vec3::ONE,
            Vec3::new(1.0, 1.0, 0.0),
        ] {
            assert!(
                tree.intersect_closest(Vec3::ZERO, d, f32::INFINITY)
                    .is_some(),
                "{d:?}"
            );
        }
    }
}

#[test]
fn triangle_lying_in_a_split_plane_is_found() {
    // Two triangles far apart on x; a third lies in the plane x = 0, where the midpoint and SAH
    // builders split.
    let mesh = TriangleMesh::new(
        vec![
            [-4.0, -1.0, -1.0],
            [-4.0, 1.0, -1.0],
            [-4.0, 0.0, 1.0],
            [4.0, -1.0, -1.0],
            [4.0, 1.0, -1.0],
            [4.0, 0.0, 1.0],
            [0.0, -1.0, -1.0],
            [0.0, 1.0, -1.0],
            [0.0, 0.0, 1.0],
        ],
        vec![[0, 1, 2], [3, 4, 5], [6, 7, 8]],
    );
    for tree in build_both(&mesh) {
        assert!(tree.tree().nodes().len() > 1, "expected a split");
        for (o, d) in [
            (Vec3::new(-8.0, 0.1, 0.0), Vec3::X),
            (Vec3::new(8.0, 0.1, 0.0), -Vec3::X),
        ] {
            let h = tree.intersect_closest(o, d, f32::INFINITY).expect("hit");
            assert_eq!(h.tri, if d.x > 0.0 { 0 } else { 1 });
            let h = tree
                .intersect_closest(o + d * 5.0, d, f32::INFINITY)
                .expect("hit");
            assert_eq!((h.t, h.tri), (3.0, 2));
        }
        // Ray starting exactly on the plane: the plane triangle is at t = 0, not hit.
        let h = tree.intersect_closest(Vec3::new(0.0, 0.1, 0.0), Vec3::X, f32::INFINITY);
        assert_eq!(h.map(|h| h.tri), Some(1));
    }
}

#[test]
fn empty_and_all_degenerate_meshes_never_hit() {
    let empty = TriangleMesh::default();
    let flat = TriangleMesh::new(
        vec![[0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2], [3, 3, 3], [0, 0, 1]],
    );
    for mesh in [empty, flat] {
        for tree in build_both(&mesh) {
            let mut rng = Rng(3);
            for _ in 0..1000 {
                let o = Vec3::new(
                    rng.range(-1.0, 3.0),
                    rng.range(-1.0, 3.0),
                    rng.range(-1.0, 3.0),
                );
                let d = random_dir(&mut rng);
                assert_eq!(tree.intersect_closest(o, d, f32::INFINITY), None);
                assert!(!tree.intersect_occluded(o, d, f32::INFINITY));
            }
            let mut text = Vec::new();
            tree.tree().write_text(&mut text).expect("write");
            let back = KdTree::read_text(&text[..], "m.kd".as_ref(), mesh.len()).expect("read");
            assert_eq!(&back, tree.tree());
            assert!(tree.tree().stats(&mesh).to_string().contains("nodes 1"));
        }
    }
}
