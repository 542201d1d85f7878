//! Surface-area-heuristic builder in O(N log N) (Wald & Havran 2006, "On building fast kd-trees
//! for ray tracing, and on doing that in O(N log N)").
//!
//! Each node carries its triangles' bounds clipped to the node box and, per axis, the split
//! events (start / planar / end) sorted once at the root and kept sorted by filtering and merging
//! on the way down. A sweep per axis finds the cheapest plane; empty space gets a bonus; a node
//! becomes a leaf when splitting costs more than intersecting all its triangles.
//!
//! Boxes are closed, as in the midpoint builder and `validate()`: a triangle touching the split
//! plane goes to both sides. So that empty space can still be cut off exactly, candidate planes
//! are evaluated at every event position `p` and one float step on either side of it.

use super::overlap::{Aabb, clip_bounds, tri_box_overlap};
use super::{
    BuildNode, COST_INTERSECT, COST_TRAVERSAL, MAX_BUILD_DEPTH, area, split_box, tri_verts,
};
use crate::mesh::TriangleMesh;

/// Cost factor applied when one side of a split is empty (20 % empty-space bonus).
const EMPTY_FACTOR: f32 = 0.8;
/// Smallest empty slab (as a fraction of the node's extent on the split axis) that earns the
/// bonus; without it, zero-width slivers would be cut off forever.
const EMPTY_MIN_FRACTION: f32 = 0.05;
/// Nodes with more triangles than this build their children in parallel.
const PARALLEL_MIN: usize = 1024;

const END: u8 = 0;
const PLANAR: u8 = 1;
const START: u8 = 2;

/// One split candidate event: triangle `tri` (node-local index) starts, ends or lies flat at `pos`.
#[derive(Clone, Copy, Debug)]
struct Event {
    pos: f32,
    kind: u8,
    tri: u32,
}

#[inline]
fn event_less(a: &Event, b: &Event) -> bool {
    (a.pos, a.kind, a.tri) < (b.pos, b.kind, b.tri)
}

fn sort_events(v: &mut [Event]) {
    v.sort_unstable_by(|a, b| {
        a.pos
            .total_cmp(&b.pos)
            .then(a.kind.cmp(&b.kind))
            .then(a.tri.cmp(&b.tri))
    });
}

/// Triangles of one node: global ids, bounds clipped to the node box, sorted events per axis.
struct Work {
    ids: Vec<u32>,
    bounds: Vec<Aabb>,
    events: [Vec<Event>; 3],
}

fn push_events(local: u32, b: &Aabb, events: &mut [Vec<Event>; 3]) {
    for (a, ev) in events.iter_mut().enumerate() {
        if b.0[a] == b.1[a] {
            ev.push(Event {
                pos: b.0[a],
                kind: PLANAR,
                tri: local,
            });
        } else {
            ev.push(Event {
                pos: b.0[a],
                kind: START,
                tri: local,
            });
            ev.push(Event {
                pos: b.1[a],
                kind: END,
                tri: local,
            });
        }
    }
}

/// Builds the SAH tree over `tris` (non-degenerate triangle indices) in box `root`.
pub(crate) fn build(mesh: &TriangleMesh, root: Aabb, tris: Vec<u32>) -> BuildNode {
    let bounds: Vec<Aabb> = tris
        .iter()
        .map(|&t| {
            let v = tri_verts(mesh, t);
            let mut b = (v[0], v[0]);
            for p in &v[1..] {
                for (k, &c) in p.iter().enumerate() {
                    b.0[k] = b.0[k].min(c);
                    b.1[k] = b.1[k].max(c);
                }
            }
            b
        })
        .collect();
    let mut events: [Vec<Event>; 3] = Default::default();
    for (i, b) in bounds.iter().enumerate() {
        push_events(i as u32, b, &mut events);
    }
    {
        let [e0, e1, e2] = &mut events;
        rayon::join(
            || sort_events(e0),
            || rayon::join(|| sort_events(e1), || sort_events(e2)),
        );
    }
    let work = Work {
        ids: tris,
        bounds,
        events,
    };
    node(mesh, root, work, 0)
}

/// Best split found by the sweep.
#[derive(Clone, Copy, Debug)]
struct Split {
    cost: f32,
    axis: usize,
    pos: f32,
}

fn find_split(w: &Work, bx: &Aabb) -> Option<Split> {
    let n = w.ids.len();
    let sa = area(bx);
    if sa.is_nan() || sa <= 0.0 {
        return None;
    }
    let inv_sa = 1.0 / sa;
    let mut best: Option<Split> = None;
    for axis in 0..3 {
        let (lo, hi) = (bx.0[axis], bx.1[axis]);
        if lo >= hi {
            continue;
        }
        let d1 = bx.1[(axis + 1) % 3] - bx.0[(axis + 1) % 3];
        let d2 = bx.1[(axis + 2) % 3] - bx.0[(axis + 2) % 3];
        let mut consider = |pos: f32, nl: usize, nr: usize| {
            if !(pos > lo && pos < hi) {
                return;
            }
            let sl = 2.0 * (d1 * d2 + (pos - lo) * (d1 + d2));
            let sr = 2.0 * (d1 * d2 + (hi - pos) * (d1 + d2));
            let mut cost =
                COST_TRAVERSAL + COST_INTERSECT * (sl * nl as f32 + sr * nr as f32) * inv_sa;
            // Bonus only for a real slab of empty space, not a sliver.
            let empty_width = if nl == 0 {
                pos - lo
            } else if nr == 0 {
                hi - pos
            } else {
                0.0
            };
            if empty_width >= EMPTY_MIN_FRACTION * (hi - lo) {
                cost *= EMPTY_FACTOR;
            }
            if best.is_none_or(|b| cost < b.cost) {
                best = Some(Split { cost, axis, pos });
            }
        };
        let ev = &w.events[axis];
        // Counts over triangle bounds [a, b]: left of plane q holds a <= q, right holds b >= q.
        let mut starts_before = 0usize; // triangles with a < p
        let mut ends_before = 0usize; // triangles with b < p
        let mut prev: Option<(f32, usize)> = None; // previous group position and its ends
        let mut i = 0;
        while i < ev.len() {
            let p = ev[i].pos;
            let (mut pe, mut pp, mut ps) = (0usize, 0usize, 0usize);
            while i < ev.len() && ev[i].pos == p {
                match ev[i].kind {
                    END => pe += 1,
                    PLANAR => pp += 1,
                    _ => ps += 1,
                }
                i += 1;
            }
            // Just below the first start: empty space on the left.
            let q = p.next_down();
            let ends_at_q = match prev {
                Some((pos, e)) if pos == q => e,
                _ => 0,
            };
            if starts_before == 0 {
                consider(q, 0, n - (ends_before - ends_at_q));
            }
            // At p: triangles touching p go to both sides.
            consider(p, starts_before + ps + pp, n - ends_before);
            // Just above the last end: empty space on the right.
            let q = p.next_up();
            let starts_at_q = if i < ev.len() && ev[i].pos == q {
                ev[i..]
                    .iter()
                    .take_while(|e| e.pos == q)
                    .filter(|e| e.kind != END)
                    .count()
            } else {
                0
            };
            starts_before += ps + pp;
            ends_before += pe + pp;
            if ends_before == n {
                consider(q, starts_before + starts_at_q, 0);
            }
            prev = Some((p, pe + pp));
        }
    }
    best
}

fn node(mesh: &TriangleMesh, bx: Aabb, w: Work, depth: usize) -> BuildNode {
    let n = w.ids.len();
    let leaf = |w: Work| {
        let mut ids = w.ids;
        ids.sort_unstable();
        BuildNode::Leaf(ids)
    };
    if n == 0 || depth >= MAX_BUILD_DEPTH {
        return leaf(w);
    }
    let Some(split) = find_split(&w, &bx) else {
        return leaf(w);
    };
    if split.cost >= COST_INTERSECT * n as f32 {
        return leaf(w);
    }
    let (axis, s) = (split.axis, split.pos);
    let (lb, rb) = split_box(&bx, axis, s);
    // Classify: 1 = left only, 2 = right only, 3 = both.
    let tol = 4.0 * f32::EPSILON * s.abs().max(bx.1[axis] - bx.0[axis]);
    let side: Vec<u8> = w
        .bounds
        .iter()
        .zip(&w.ids)
        .map(|(b, &id)| {
            if b.1[axis] < s {
                // Safety net: agree with the exact overlap test used by validate().
                if s - b.1[axis] <= tol && tri_box_overlap(&tri_verts(mesh, id), &rb) {
                    3
                } else {
                    1
                }
            } else if b.0[axis] > s {
                if b.0[axis] - s <= tol && tri_box_overlap(&tri_verts(mesh, id), &lb) {
                    3
                } else {
                    2
                }
            } else {
                3
            }
        })
        .collect();
    let (left, right) = if n > PARALLEL_MIN {
        rayon::join(
            || child(mesh, &w, &side, 1, &lb),
            || child(mesh, &w, &side, 2, &rb),
        )
    } else {
        (
            child(mesh, &w, &side, 1, &lb),
            child(mesh, &w, &side, 2, &rb),
        )
    };
    if left.ids.len() == n && right.ids.len() == n {
        // No progress possible (every triangle straddles); stop here.
        return leaf(w);
    }
    drop(w);
    let (l, r) = if n > PARALLEL_MIN {
        rayon::join(
            || node(mesh, lb, left, depth + 1),
            || node(mesh, rb, right, depth + 1),
        )
    } else {
        (
            node(mesh, lb, left, depth + 1),
            node(mesh, rb, right, depth + 1),
        )
    };
    BuildNode::Inner {
        axis,
        split: s,
        left: Box::new(l),
        right: Box::new(r),
    }
}

/// Builds the work set of one child: triangles on side `me` keep their events (filtered,
/// still sorted); straddling triangles are clipped to the child box and their new events are
/// sorted and merged in.
fn child(mesh: &TriangleMesh, w: &Work, side: &[u8], me: u8, cb: &Aabb) -> Work {
    let mut remap = vec![u32::MAX; w.ids.len()];
    let count = side.iter().filter(|&&s| s & me != 0).count();
    let mut ids = Vec::with_capacity(count);
    let mut bounds = Vec::with_capacity(count);
    let mut new_events: [Vec<Event>; 3] = Default::default();
    for (i, &s) in side.iter().enumerate() {
        if s & me == 0 {
            continue;
        }
        let local = ids.len() as u32;
        remap[i] = local;
        ids.push(w.ids[i]);
        if s == 3 {
            let old = w.bounds[i];
            let b = clip_bounds(&tri_verts(mesh, w.ids[i]), cb).unwrap_or_else(|| {
                let mut b = old;
                for k in 0..3 {
                    b.0[k] = b.0[k].max(cb.0[k]);
                    b.1[k] = b.1[k].min(cb.1[k]).max(b.0[k]);
                }
                b
            });
            push_events(local, &b, &mut new_events);
            bounds.push(b);
        } else {
            bounds.push(w.bounds[i]);
        }
    }
    let events = std::array::from_fn(|a| {
        let kept = w.events[a].iter().filter_map(|e| {
            let i = e.tri as usize;
            (side[i] == me).then(|| Event {
                tri: remap[i],
                ..*e
            })
        });
        let mut fresh = std::mem::take(&mut new_events[a]);
        sort_events(&mut fresh);
        merge(kept, fresh, 2 * count)
    });
    Work {
        ids,
        bounds,
        events,
    }
}

/// Merges two event sequences sorted by `(pos, kind, tri)`; `capacity` bounds the total.
fn merge(kept: impl Iterator<Item = Event>, fresh: Vec<Event>, capacity: usize) -> Vec<Event> {
    if fresh.is_empty() {
        let mut out = Vec::with_capacity(capacity);
        out.extend(kept);
        return out;
    }
    let mut out = Vec::with_capacity(capacity);
    let mut f = fresh.into_iter().peekable();
    for e in kept {
        while let Some(x) = f.next_if(|x| event_less(x, &e)) {
            out.push(x);
        }
        out.push(e);
    }
    out.extend(f);
    out
}

#[cfg(test)]
mod tests {
    use crate::accel::kdtree::{BuildMethod, KdTree};
    use crate::mesh::TriangleMesh;

    /// Many small triangles in one corner of a large, otherwise empty box.
    fn corner_mesh() -> TriangleMesh {
        let mut v = vec![
            [0.0, 0.0, 0.0],
            [100.0, 100.0, 100.0],
            [100.0, 100.0, 100.0],
        ];
        let mut idx = vec![[0, 1, 2]]; // degenerate: only sets the bounds
        for i in 0..64 {
            let x = (i % 8) as f32;
            let y = (i / 8) as f32;
            let b = v.len() as u32;
            v.extend([[x, y, 1.0], [x + 0.9, y, 1.0], [x, y + 0.9, 1.5]]);
            idx.push([b, b + 1, b + 2]);
        }
        TriangleMesh::new(v, idx)
    }

    #[test]
    fn cuts_off_empty_space_first() {
        let mesh = corner_mesh();
        let tree = KdTree::build(&mesh, BuildMethod::Sah);
        tree.validate(&mesh).expect("valid");
        let root = tree.nodes()[0];
        assert!(!root.is_leaf());
        // The first plane bounds the cluster (x, y < 8; z in [1, 1.5]).
        assert!(root.split() <= 8.0, "split at {}", root.split());
        let s = tree.stats(&mesh);
        assert!(s.leaves > 8 && s.max_tris_per_leaf < 16, "{s}");
        // The degenerate triangle is in no leaf.
        assert!((0..tree.nodes().len()).all(|i| !tree.leaf_triangles(i).contains(&0)));
    }

    #[test]
    fn build_is_deterministic_across_thread_counts() {
        let mesh = corner_mesh();
        let a = KdTree::build(&mesh, BuildMethod::Sah);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool");
        let b = pool.install(|| KdTree::build(&mesh, BuildMethod::Sah));
        assert_eq!(a, b);
    }
}
