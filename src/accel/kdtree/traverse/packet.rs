//! 4-ray packet traversal (Wald 2004 style, per-lane active mask) and the batch driver that
//! groups consecutive coherent rays into packets.
//!
//! Reads the tree's nodes, the accelerator's leaf-ordered triangles and root box, and 4 rays
//! (origin, direction, `t_max` columns); writes one answer per ray through the caller's sink.
//! One node fetch and one 4-wide interval step per node for the packet, each triangle tested
//! against the live lanes at once. Every lane takes its single ray's step (the shared [`step`])
//! and culls with its own visitor; where lanes disagree on the near child the packet visits both
//! children with their lanes (the lowest live lane's near side first), which changes no answer
//! (see `frustum`), so results are bit-identical to the single-ray queries.

use glam::Vec3;

use super::hit4::PacketTest;
use super::interval::step;
use super::ray::Ray;
use super::route::{self, Loop};
use super::visit::Visitor;
use super::{KdAccel, LANES};
use crate::accel::kdtree::MAX_DEPTH;
use crate::simd::F32x4;

/// One pending far child of a packet: node, the lanes that enter it and their intervals.
/// Intervals first and 16-byte aligned, so a whole-entry copy and the 4-wide loads of `t0`,
/// `t1` line up (a load straddling two smaller stores stalls store forwarding).
#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
struct PacketEntry {
    /// Start of each lane's interval inside the node.
    t0: [f32; LANES],
    /// End of each lane's interval inside the node.
    t1: [f32; LANES],
    /// Node index.
    node: u32,
    /// Lanes that enter the node.
    mask: u8,
}

/// Entries of a packet's stack: one per tree level.
const STACK: usize = MAX_DEPTH + 1;

/// Four rays' traversal data, structure-of-arrays (`[axis]` of lanes; the 4th axis pads so a
/// node's 2-bit axis field indexes without a bounds check).
struct PacketRays {
    /// Origins.
    origin: [F32x4; 4],
    /// Reciprocal directions.
    inv: [F32x4; 4],
    /// Per-axis `δ` slack in `t` units.
    slack: [F32x4; 4],
}

impl PacketRays {
    fn new<T>(rays: &[Ray<T>; LANES]) -> PacketRays {
        let col = |f: &dyn Fn(&Ray<T>) -> &[f32; 4]| -> [F32x4; 4] {
            std::array::from_fn(|a| F32x4::from_array(&std::array::from_fn(|k| f(&rays[k])[a])))
        };
        PacketRays {
            origin: col(&|r| &r.origin),
            inv: col(&|r| &r.inv),
            slack: col(&|r| &r.slack),
        }
    }
}

/// True when the four directions have the same sign in every component (sign bits, so
/// `-0.0` counts as negative): the packet is coherent enough to be worth tracing together.
/// Only a performance heuristic; results never depend on it.
#[inline(always)]
fn same_signs(dirs: &[Vec3]) -> bool {
    let bits = |d: &Vec3| {
        (d.x.is_sign_negative() as u8)
            | (d.y.is_sign_negative() as u8) << 1
            | (d.z.is_sign_negative() as u8) << 2
    };
    let b0 = bits(&dirs[0]);
    dirs[1..].iter().all(|d| bits(d) == b0)
}

impl KdAccel {
    /// The query `V` for many rays: `out(i, answer)` receives ray `i`'s answer, in order.
    /// Groups of 4 consecutive rays whose directions agree in sign (every full group with
    /// `force`, for tests) are traced as a packet, others one by one; the answers are the
    /// single-ray ones either way. Panics if the slices' lengths differ.
    #[inline(always)]
    pub(super) fn batch<T: PacketTest, V: Visitor>(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        force: bool,
        mut out: impl FnMut(usize, V::Out),
    ) {
        let n = origins.len();
        assert!(dirs.len() == n && t_max.len() == n);
        // One zeroed stack for all the batch's packets (zeroing 3 KiB per packet would be a
        // measurable share of a packet's work).
        let mut stack = [PacketEntry::default(); STACK];
        let mut i = 0;
        while i < n {
            if route::group(n - i, || same_signs(&dirs[i..i + LANES]), force) == Loop::Packet {
                let r = i..i + LANES;
                let answers = self.packet::<T, V>(
                    &origins[r.clone()],
                    &dirs[r.clone()],
                    &t_max[r],
                    &mut stack,
                );
                for (k, a) in answers.into_iter().enumerate() {
                    out(i + k, a);
                }
                i += LANES;
            } else {
                out(i, self.query::<T, V>(origins[i], dirs[i], t_max[i]));
                i += 1;
            }
        }
    }

    /// The query `V` for 4 rays traced together. Each lane computes its child intervals with
    /// the single-ray step; while all live lanes agree on the near child (always, for rays
    /// sharing an origin) every lane visits its leaves in the single ray's order and culls
    /// with its own visitor, so answers are identical. Where lanes disagree, the packet visits
    /// both children with their lanes, the lowest live lane's near side first: any-hit answers
    /// do not depend on the order, and a closest-hit lane still meets every leaf that starts
    /// before its best hit, so they stay identical too.
    #[inline(never)]
    fn packet<T: PacketTest, V: Visitor>(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        stack: &mut [PacketEntry; STACK],
    ) -> [V::Out; LANES] {
        let mut v: [V; LANES] = std::array::from_fn(|k| V::new(t_max[k]));
        let stopped = match self.packet_setup::<T>(origins, dirs, t_max) {
            Some((rays, entry)) => self.walk_packet(&rays, entry, &mut v, stack),
            None => 0,
        };
        std::array::from_fn(|k| v[k].finish(stopped & (1 << k) != 0))
    }

    /// Per-lane setup: prepared rays (a dummy for lanes that cannot hit), and the root
    /// intervals with the mask of live lanes; `None` when no lane is live.
    #[inline(always)]
    fn packet_setup<T: PacketTest>(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
    ) -> Option<([Ray<T>; LANES], PacketEntry)> {
        let mut entry = PacketEntry::default();
        let rays: [Ray<T>; LANES] = std::array::from_fn(|k| {
            let live = if t_max[k].is_nan() || t_max[k] <= 0.0 {
                None
            } else {
                Ray::<T>::new(origins[k], dirs[k], &self.root)
            };
            match live.and_then(|r| r.clip(&self.root, t_max[k]).map(|c| (r, c))) {
                Some((r, (t0, t1))) => {
                    entry.mask |= 1 << k;
                    entry.t0[k] = t0;
                    entry.t1[k] = t1;
                    r
                }
                None => Ray::<T>::new(Vec3::ZERO, Vec3::X, &self.root).expect("dummy ray"),
            }
        });
        (entry.mask != 0).then_some((rays, entry))
    }

    /// Packet traversal from `start`, with `stack` as scratch space for pending far children
    /// (its contents on entry do not matter); returns the mask of lanes whose visitor asked to
    /// stop.
    #[inline(always)]
    fn walk_packet<T: PacketTest, V: Visitor>(
        &self,
        rays: &[Ray<T>; LANES],
        start: PacketEntry,
        v: &mut [V; LANES],
        stack: &mut [PacketEntry; STACK],
    ) -> u8 {
        let p = PacketRays::new(rays);
        let pre = T::pre(rays, start.mask);
        let nodes = &self.tree.nodes[..];
        let mut sp = 0usize;
        let mut done = 0u8;
        let mut cur = start;
        loop {
            let mut e = cur;
            // Descend to a leaf.
            let leaf = loop {
                let Some(&n) = nodes.get(e.node as usize) else {
                    break None;
                };
                if n.is_leaf() {
                    break Some(n);
                }
                let axis = n.axis();
                let s = step(
                    F32x4::splat(n.split()),
                    p.origin[axis],
                    p.inv[axis],
                    p.slack[axis],
                    F32x4::from_array(&e.t0),
                    F32x4::from_array(&e.t1),
                );
                let (n_t1, f_t0, f_t1) = (
                    s.near_t1.to_array(),
                    s.far_t0.to_array(),
                    s.far_t1.to_array(),
                );
                let m = e.mask;
                let near_left = s.near_left.bits() & m;
                let (go_near, go_far) = (!s.skip_near.bits() & m, s.go_far.bits() & m);
                // All lanes agree on the near child: its entry and the far one's. (Two arms
                // below rather than one selecting the child indices: LLVM turned that select
                // into a `cmov`, which makes every node fetch wait for the step's masks;
                // measured ~15 % slower on shadow-ray packets than this predicted branch.)
                let near_far = |near: u32, far: u32| {
                    (
                        PacketEntry {
                            node: near,
                            mask: go_near,
                            t0: e.t0,
                            t1: n_t1,
                        },
                        PacketEntry {
                            node: far,
                            mask: go_far,
                            t0: f_t0,
                            t1: f_t1,
                        },
                    )
                };
                let (near, far) = if near_left == m {
                    near_far(e.node + 1, n.right())
                } else if near_left == 0 {
                    near_far(n.right(), e.node + 1)
                } else {
                    // Lanes disagree on the near child (their origins lie on both sides of
                    // the plane): orient each lane's children as left/right and visit the
                    // lowest live lane's near side first. The order does not change any-hit
                    // answers, nor closest-hit ones: a lane still visits every leaf that
                    // starts before its best hit (culling only skips entries beyond it), so it
                    // still meets the leaf holding its closest hit, and keeps the least
                    // `(t, index)` of what it tests, as the single ray does.
                    let mut left = PacketEntry {
                        node: e.node + 1,
                        mask: (near_left & go_near) | (!near_left & go_far & m),
                        ..e
                    };
                    let mut right = PacketEntry {
                        node: n.right(),
                        mask: (near_left & go_far) | (!near_left & go_near & m),
                        ..e
                    };
                    for k in 0..LANES {
                        let (lt, rt) = if near_left & (1 << k) != 0 {
                            (&mut left, &mut right)
                        } else {
                            (&mut right, &mut left)
                        };
                        lt.t1[k] = n_t1[k];
                        (rt.t0[k], rt.t1[k]) = (f_t0[k], f_t1[k]);
                    }
                    if near_left & (m & m.wrapping_neg()) != 0 {
                        (left, right)
                    } else {
                        (right, left)
                    }
                };
                if near.mask != 0 && far.mask != 0 {
                    if sp < stack.len() {
                        stack[sp] = far;
                        sp += 1;
                    }
                    e = near;
                } else if near.mask != 0 {
                    e = near;
                } else {
                    e = far;
                }
                if e.mask == 0 {
                    break None;
                }
            };
            if let Some(n) = leaf {
                let start = n.offset() as usize;
                let end = start + n.count() as usize;
                // Triangle by triangle, each live lane in turn: every lane still sees the
                // leaf's triangles in order, as its single ray would, and each triangle's
                // vertices are loaded once for the packet.
                if let (Some(ts), Some(ids)) = (
                    self.tris.get(start..end),
                    self.tree.tri_indices.get(start..end),
                ) {
                    let mut live = e.mask & !done;
                    // A lane's limit changes only when it accepts a hit.
                    let mut limits: [f32; LANES] = std::array::from_fn(|k| v[k].limit());
                    for (t, &id) in ts.iter().zip(ids) {
                        let (mut hits, ts) = T::hit4(&pre, rays, live, t, &limits);
                        while hits != 0 {
                            let k = hits.trailing_zeros() as usize;
                            hits &= hits - 1;
                            if v[k].accept(ts[k], id) {
                                live &= !(1 << k);
                                done |= 1 << k;
                            }
                            limits[k] = v[k].limit();
                        }
                        if live == 0 {
                            break;
                        }
                    }
                }
            }
            // Pop the next entry with a lane that can still hold a closer (or tying) hit.
            loop {
                if sp == 0 {
                    return done;
                }
                sp -= 1;
                cur = stack[sp];
                let mut m = cur.mask & !done;
                for (k, vk) in v.iter().enumerate() {
                    // As the single ray: a NaN entry distance is skipped too.
                    let keep = cur.t0[k] <= vk.cull();
                    if !keep {
                        m &= !(1 << k);
                    }
                }
                cur.mask = m;
                if m != 0 {
                    break;
                }
            }
        }
    }
}
