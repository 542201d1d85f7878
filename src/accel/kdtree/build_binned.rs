//! The default SAH builder: min-max binned SAH (Shevtsov, Soupikov & Kapustin 2007; Wald 2007)
//! for nodes of more than [`EXACT_MAX`] triangles, the exact event sweep of [`super::build_sah`]
//! below.
//!
//! A node counts, per axis, how many triangle bounds start and end in each of [`BINS`] equal bins
//! spanning the node's geometry (the union of its triangles' clipped bounds, tracked while the
//! parent partitions), and evaluates the SAH (the exact sweep's [`AxisCost`]: same costs and
//! empty-space bonus) at the bin boundaries and at the geometry's two faces on each axis, so
//! empty space is cut off exactly where the geometry begins, as the exact sweep would. Triangles
//! are classified exactly against the chosen plane and straddlers are clipped exactly to each
//! child box. When binning finds no split cheaper than a leaf, the exact sweep decides.
//!
//! Nodes above [`TASK_MIN`] triangles bin and partition in parallel over chunks (counts reduced
//! by integer addition, chunks concatenated in order) and build their children with
//! `rayon::join`; a node at or below it is one sequential task that keeps its triangles and
//! every binned node's on its path in one arena (no allocation per node). The split decisions
//! never depend on the thread count, so neither does the tree.
//!
//! Reads mesh vertices and triangle indices; writes nodes in depth-first pre-order ([`Flat`])
//! and the time spent in each phase ([`BuildPhases`]).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::build_sah::{self, AxisCost, Flat, Split, box_costs, classify, clip, tri_bounds};
use super::node::KdNode;
use super::overlap::Aabb;
use super::{BuildPhases, COST_INTERSECT, split_box};
use crate::mesh::TriangleMesh;

/// Bins per axis.
pub(crate) const BINS: usize = 64;
/// Nodes with more triangles than this bin and partition in parallel; smaller ones are built as
/// one sequential task each.
const TASK_MIN: usize = 4096;
/// Nodes with at most this many triangles are built by the exact sweep. Measured on Sibenik:
/// binning down to 1,024 keeps the exact sweep's tree size (244,761 nodes against 234,509) and
/// SAH cost (74.34 against 74.57); binning lower makes ever larger trees (338,689 nodes when
/// binning down to 60) for no lower SAH cost, and a larger tree takes longer to build below.
pub(crate) const EXACT_MAX: usize = 1024;
/// Triangles per rayon task when binning and partitioning.
const CHUNK: usize = 4096;

/// The builder's own constants, for [`super::builder_settings`].
pub(crate) const SETTINGS: &str = "binned v2 64 geometry-faces above 1024";

/// An empty box (the identity of [`union`]).
const EMPTY: Aabb = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);

/// The smallest box holding `a` and `b`.
#[inline]
fn union(a: &Aabb, b: &Aabb) -> Aabb {
    (
        [0, 1, 2].map(|k| a.0[k].min(b.0[k])),
        [0, 1, 2].map(|k| a.1[k].max(b.1[k])),
    )
}

/// Time spent per phase, summed over threads (nanoseconds).
#[derive(Default)]
struct Clock {
    top: AtomicU64,
    tasks: AtomicU64,
    task_count: AtomicU64,
}

impl Clock {
    fn add(counter: &AtomicU64, since: Instant) {
        counter.fetch_add(since.elapsed().as_nanos() as u64, Ordering::Relaxed);
    }
}

/// Builds the SAH tree over `tris` (non-degenerate triangle indices) in box `root`.
pub(crate) fn build(mesh: &TriangleMesh, root: Aabb, tris: Vec<u32>) -> (Flat, BuildPhases) {
    assert!(
        tris.len() < 1 << 30,
        "too many triangles for the SAH builder"
    );
    let start = Instant::now();
    let max_depth = build_sah::max_depth(tris.len());
    let bounds: Vec<Aabb> = tris
        .par_iter()
        .with_min_len(CHUNK)
        .map(|&t| tri_bounds(mesh, t))
        .collect();
    let geo = bounds
        .par_chunks(CHUNK)
        .map(|c| c.iter().fold(EMPTY, |g, b| union(&g, b)))
        .reduce(|| EMPTY, |a, b| union(&a, &b));
    let bounds_seconds = start.elapsed().as_secs_f64();
    let clock = Clock::default();
    let mut out = Flat::default();
    let ctx = Ctx {
        mesh,
        max_depth,
        clock: &clock,
    };
    node_large(&ctx, root, geo, tris, bounds, 0, &mut out);
    let ns = |c: &AtomicU64| c.load(Ordering::Relaxed) as f64 * 1e-9;
    let phases = BuildPhases {
        bounds_seconds,
        top_seconds: ns(&clock.top),
        task_seconds: ns(&clock.tasks),
        tasks: clock.task_count.load(Ordering::Relaxed) as usize,
        input_seconds: 0.0,
        wall_seconds: start.elapsed().as_secs_f64(),
    };
    (out, phases)
}

/// What every node of one build reads.
struct Ctx<'a> {
    mesh: &'a TriangleMesh,
    max_depth: usize,
    clock: &'a Clock,
}

/// Start and end counts per bin and axis.
#[derive(Clone)]
struct Bins {
    start: [[u32; BINS]; 3],
    end: [[u32; BINS]; 3],
}

impl Bins {
    fn zero() -> Bins {
        Bins {
            start: [[0; BINS]; 3],
            end: [[0; BINS]; 3],
        }
    }

    fn add(mut self, other: Bins) -> Bins {
        for a in 0..3 {
            for i in 0..BINS {
                self.start[a][i] += other.start[a][i];
                self.end[a][i] += other.end[a][i];
            }
        }
        self
    }
}

/// Where the bins of one node lie: per axis, the first bin's start and bins per unit length.
#[derive(Clone, Copy)]
struct Grid {
    lo: [f32; 3],
    scale: [f32; 3],
}

impl Grid {
    /// [`BINS`] bins spanning `geo` (an axis on which it is flat gets one bin).
    fn new(geo: &Aabb) -> Grid {
        Grid {
            lo: geo.0,
            scale: [0, 1, 2].map(|k| {
                let e = geo.1[k] - geo.0[k];
                if e > 0.0 { BINS as f32 / e } else { 0.0 }
            }),
        }
    }

    /// Bin of coordinate `x` on `axis`.
    #[inline(always)]
    fn bin(&self, x: f32, axis: usize) -> usize {
        (((x - self.lo[axis]) * self.scale[axis]) as i32).clamp(0, BINS as i32 - 1) as usize
    }

    /// Counts `bounds` into `bins`.
    fn count(&self, bins: &mut Bins, bounds: &[Aabb]) {
        for t in bounds {
            for a in 0..3 {
                bins.start[a][self.bin(t.0[a], a)] += 1;
                bins.end[a][self.bin(t.1[a], a)] += 1;
            }
        }
    }
}

/// The cheapest plane for `n` triangles with geometry `geo` in box `bx`, given their `bins`
/// ([`Grid::new`] of `geo`): bin boundaries inside the geometry, and its faces (cutting off the
/// empty space beyond them).
fn find_split(bx: &Aabb, geo: &Aabb, n: usize, bins: &Bins) -> Option<Split> {
    let (ext, ki) = box_costs(bx)?;
    let mut best: Option<Split> = None;
    let mut consider = |cost: f32, axis: usize, pos: f32, planar_left: bool| {
        if best.is_none_or(|b| cost < b.cost) {
            best = Some(Split {
                cost,
                axis,
                pos,
                planar_left,
            });
        }
    };
    let nb = BINS;
    for axis in 0..3 {
        let Some(axis_cost) = AxisCost::new(bx, ext, axis, ki) else {
            continue;
        };
        let (lo, hi) = (axis_cost.lo, axis_cost.hi);
        let inside = |p: f32| p > lo && p < hi;
        // The geometry's faces: everything on one side (triangles lying in the face with it).
        let (g0, g1) = (geo.0[axis], geo.1[axis]);
        if inside(g0) {
            consider(axis_cost.cost(g0, 0, n), axis, g0, false);
        }
        if inside(g1) {
            consider(axis_cost.cost(g1, n, 0), axis, g1, true);
        }
        if g1 <= g0 {
            continue;
        }
        // Plane i lies between bins i-1 and i: left = bounds starting below it, right = bounds
        // ending at or above it.
        let (mut nl, mut nr) = (0usize, n);
        for i in 1..nb {
            nl += bins.start[axis][i - 1] as usize;
            nr -= bins.end[axis][i - 1] as usize;
            let p = g0 + (g1 - g0) * (i as f32 / nb as f32);
            if inside(p) {
                consider(axis_cost.cost(p, nl, nr), axis, p, true);
            }
        }
    }
    best
}

/// The triangles of one child: those on side `me`, straddlers clipped to `cb` (chunks filtered
/// in parallel, concatenated in order), and the union of their bounds.
fn child_large(
    mesh: &TriangleMesh,
    ids: &[u32],
    bounds: &[Aabb],
    side: &[u8],
    me: u8,
    cb: &Aabb,
) -> (Vec<u32>, Vec<Aabb>, Aabb) {
    let part = |start: usize| {
        let end = (start + CHUNK).min(ids.len());
        let mut out_ids = Vec::with_capacity(end - start);
        let mut out_bounds = Vec::with_capacity(end - start);
        let mut geo = EMPTY;
        for i in start..end {
            let s = side[i];
            if s & me != 0 {
                let b = if s == 3 {
                    clip(mesh, ids[i], &bounds[i], cb)
                } else {
                    bounds[i]
                };
                geo = union(&geo, &b);
                out_ids.push(ids[i]);
                out_bounds.push(b);
            }
        }
        (out_ids, out_bounds, geo)
    };
    let parts: Vec<(Vec<u32>, Vec<Aabb>, Aabb)> = (0..ids.len().div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| part(c * CHUNK))
        .collect();
    let total = parts.iter().map(|p| p.0.len()).sum();
    let (mut out_ids, mut out_bounds) = (Vec::with_capacity(total), Vec::with_capacity(total));
    let mut geo = EMPTY;
    for (i, b, g) in parts {
        out_ids.extend_from_slice(&i);
        out_bounds.extend_from_slice(&b);
        geo = union(&geo, &g);
    }
    (out_ids, out_bounds, geo)
}

/// Builds the subtree over `ids` (with clipped `bounds`, whose union is `geo`) in box `bx`,
/// appending it to `out`: in parallel above [`TASK_MIN`] triangles, else as one task.
fn node_large(
    ctx: &Ctx,
    bx: Aabb,
    geo: Aabb,
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
    depth: usize,
    out: &mut Flat,
) {
    let n = ids.len();
    if n <= TASK_MIN {
        let start = Instant::now();
        let mut arena = Arena {
            ids,
            bounds,
            small: build_sah::SmallArena::new(),
        };
        node_task(ctx, bx, geo, 0, n, depth, out, &mut arena);
        Clock::add(&ctx.clock.tasks, start);
        ctx.clock.task_count.fetch_add(1, Ordering::Relaxed);
        return;
    }
    let start = Instant::now();
    let split = if depth >= ctx.max_depth {
        None
    } else {
        let grid = Grid::new(&geo);
        let bins = bounds
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut b = Bins::zero();
                grid.count(&mut b, chunk);
                b
            })
            .reduce(Bins::zero, Bins::add);
        find_split(&bx, &geo, n, &bins).filter(|s| s.cost < COST_INTERSECT * n as f32)
    };
    let Some(split) = split else {
        Clock::add(&ctx.clock.top, start);
        let start = Instant::now();
        build_sah::subtree(ctx.mesh, bx, ids, bounds, depth, ctx.max_depth, out);
        Clock::add(&ctx.clock.tasks, start);
        ctx.clock.task_count.fetch_add(1, Ordering::Relaxed);
        return;
    };
    let (axis, s) = (split.axis, split.pos);
    let (lb, rb) = split_box(&bx, axis, s);
    let side: Vec<u8> = bounds
        .par_iter()
        .with_min_len(CHUNK)
        .map(|b| classify(b, &split))
        .collect();
    let ((lids, lbounds, lgeo), (rids, rbounds, rgeo)) = rayon::join(
        || child_large(ctx.mesh, &ids, &bounds, &side, 1, &lb),
        || child_large(ctx.mesh, &ids, &bounds, &side, 2, &rb),
    );
    drop((ids, bounds, side));
    Clock::add(&ctx.clock.top, start);
    let here = out.nodes.len();
    out.nodes.push(KdNode::inner(axis, s, 0));
    let mut sub = Flat::default();
    rayon::join(
        || node_large(ctx, lb, lgeo, lids, lbounds, depth + 1, out),
        || node_large(ctx, rb, rgeo, rids, rbounds, depth + 1, &mut sub),
    );
    out.nodes[here] = KdNode::inner(axis, s, out.nodes.len() as u32);
    out.append(sub);
}

/// Scratch of one sequential task: the triangles of the binned nodes on the current path, each
/// node's after its parent's (pushed before descending, truncated after), and the exact sweep's
/// arena, reused by every small subtree of the task.
struct Arena {
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
    small: build_sah::SmallArena,
}

/// One node of a sequential task: its triangles are `arena.ids/bounds[first..first + n]`, the
/// union of their bounds is `geo`.
#[allow(clippy::too_many_arguments)]
fn node_task(
    ctx: &Ctx,
    bx: Aabb,
    geo: Aabb,
    first: usize,
    n: usize,
    depth: usize,
    out: &mut Flat,
    arena: &mut Arena,
) {
    let range = first..first + n;
    let binned = n > EXACT_MAX;
    if binned && depth >= ctx.max_depth {
        out.leaf(&arena.ids[range]);
        return;
    }
    // A binned split that beats a leaf; small nodes, and large ones without one, take the exact
    // sweep.
    let split = binned
        .then(|| {
            let grid = Grid::new(&geo);
            let mut bins = Bins::zero();
            grid.count(&mut bins, &arena.bounds[range.clone()]);
            find_split(&bx, &geo, n, &bins).filter(|s| s.cost < COST_INTERSECT * n as f32)
        })
        .flatten();
    let Some(split) = split else {
        if n <= build_sah::SMALL {
            let Arena { ids, bounds, small } = arena;
            build_sah::node_small(
                bx,
                &ids[range.clone()],
                &bounds[range],
                depth,
                ctx.max_depth,
                out,
                small,
            );
            return;
        }
        build_sah::subtree(
            ctx.mesh,
            bx,
            arena.ids[range.clone()].to_vec(),
            arena.bounds[range].to_vec(),
            depth,
            ctx.max_depth,
            out,
        );
        return;
    };
    let (axis, s) = (split.axis, split.pos);
    let (lb, rb) = split_box(&bx, axis, s);
    let mark = arena.ids.len();
    let mut geos = [EMPTY; 2];
    let mut counts = [0usize; 2];
    for (c, cb) in [(0usize, &lb), (1, &rb)] {
        let me = 1u8 << c;
        for i in range.clone() {
            let b = arena.bounds[i];
            let sd = classify(&b, &split);
            if sd & me != 0 {
                let id = arena.ids[i];
                let b = if sd == 3 {
                    clip(ctx.mesh, id, &b, cb)
                } else {
                    b
                };
                geos[c] = union(&geos[c], &b);
                arena.ids.push(id);
                arena.bounds.push(b);
                counts[c] += 1;
            }
        }
    }
    let here = out.nodes.len();
    out.nodes.push(KdNode::inner(axis, s, 0));
    node_task(ctx, lb, geos[0], mark, counts[0], depth + 1, out, arena);
    out.nodes[here] = KdNode::inner(axis, s, out.nodes.len() as u32);
    node_task(
        ctx,
        rb,
        geos[1],
        mark + counts[0],
        counts[1],
        depth + 1,
        out,
        arena,
    );
    arena.ids.truncate(mark);
    arena.bounds.truncate(mark);
}

#[cfg(test)]
mod tests {
    use crate::accel::kdtree::{BuildMethod, KdTree};
    use crate::mesh::TriangleMesh;

    /// `n` small triangles in a grid in the corner `[0, 32]² × [1, 1.5]` of the box `[0, 100]³`
    /// (set by one degenerate triangle, which no tree holds).
    fn corner_cluster(n: usize) -> TriangleMesh {
        let mut v = vec![
            [0.0, 0.0, 0.0],
            [100.0, 100.0, 100.0],
            [100.0, 100.0, 100.0],
        ];
        let mut idx = vec![[0, 1, 2]];
        let side = (n as f32).sqrt().ceil() as usize;
        let step = 32.0 / side as f32;
        for i in 0..n {
            let x = (i % side) as f32 * step;
            let y = (i / side) as f32 * step;
            let b = v.len() as u32;
            v.extend([
                [x, y, 1.0],
                [x + 0.9 * step, y, 1.0],
                [x, y + 0.9 * step, 1.5],
            ]);
            idx.push([b, b + 1, b + 2]);
        }
        TriangleMesh::new(v, idx)
    }

    #[test]
    fn binned_nodes_cut_off_empty_space_at_the_geometry_face() {
        // 10,000 triangles: the root is binned. Bins over the root box would put the plane at a
        // bin boundary (a multiple of 100 / bins); the geometry's faces are candidates too, so
        // the root plane bounds the cluster exactly.
        let mesh = corner_cluster(10_000);
        let tree = KdTree::build(&mesh, BuildMethod::Sah);
        tree.validate(&mesh).expect("valid");
        let root = tree.nodes()[0];
        assert!(!root.is_leaf());
        let (lo, hi) = (1..mesh.len()).fold(
            ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
            |(mut lo, mut hi), k| {
                for i in mesh.indices[k] {
                    for a in 0..3 {
                        lo[a] = lo[a].min(mesh.vertices[i as usize][a]);
                        hi[a] = hi[a].max(mesh.vertices[i as usize][a]);
                    }
                }
                (lo, hi)
            },
        );
        let (a, s) = (root.axis(), root.split());
        assert!(
            s == lo[a] || s == hi[a],
            "root plane {s} on axis {a} is not a face of the cluster {lo:?}..{hi:?}"
        );
    }

    #[test]
    fn binned_tree_costs_no_more_than_the_exact_sweep_tree() {
        let mesh = corner_cluster(6000);
        let binned = KdTree::build(&mesh, BuildMethod::Sah);
        let exact = KdTree::build_sah_exact(&mesh);
        binned.validate(&mesh).expect("valid");
        let (b, e) = (binned.stats(&mesh), exact.stats(&mesh));
        assert!(b.sah_cost <= 1.03 * e.sah_cost, "binned {b}\nexact {e}");
    }

    #[test]
    fn build_reports_its_sequential_tasks() {
        let mesh = corner_cluster(20_000);
        let (tree, phases) = KdTree::build_profiled(&mesh, BuildMethod::Sah);
        tree.validate(&mesh).expect("valid");
        // 20,000 triangles split in parallel down to nodes of at most 4,096: several tasks.
        assert!(phases.tasks >= 5, "{phases:?}");
    }
}
