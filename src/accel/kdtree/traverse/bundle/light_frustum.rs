//! Light-rooted frusta: up to [`SUBS`] consecutive bundles of one group (one apex, one face)
//! culled through the tree together with ONE scalar interval step per node, the way the camera
//! frusta are; the lanes still take the exact triangle test of their own original ray
//! ([`tri_hits`]) in every leaf the frustum reaches.
//!
//! **The frustum.** Every lane of the frustum runs from the apex `A` along `r = o − A` (its
//! reversed ray), which moves along the group's axis `m` with one sign for all lanes. With
//! `q = r / |r[m]|` (so `q[m] = ±1`) a lane's points are `A + t·q`, `t ∈ [0, |r[m]|]`. The
//! frustum is the box of the lanes' `q` and `t ∈ [0, T]` (`T` the largest `|r[m]|`), grown by
//! `G`, the largest of the lanes' slack `g` (see the parent module) plus bounds on the rounding
//! of `q`, of the plane distances and of this module's own steps. A node is entered with one
//! `t` interval for the whole frustum; a split plane at distance `p` from the apex bounds the
//! part below it (`t·q ≤ p + G` for some `q` of the box) and above it (`t·q ≥ p − G`), each end
//! rounded outward. So every leaf within `g` of some lane's segment is visited, as by the lane
//! alone: the answers are the parent module's (and so the single ray's).
//!
//! A frustum whose lanes do not all move the same way along `m`, or whose `q` is not finite,
//! goes bundle by bundle through the per-lane walk instead.

use super::super::interval::SLACK;
use super::{
    BundleInfo, Count, DELTA, KdAccel, ROUND, ROW_D, ROW_O, ROW_T_MAX, ROWS, Rays, TriLanes, Wide,
    tri_hits,
};

/// Most bundles traced as one frustum.
pub(super) const SUBS: usize = 4;

/// Relative outward widening of every interval end computed here: the single-ray step's
/// relative slack (far above the rounding of the product it covers).
const OUT: f32 = SLACK;

/// One pending far child of a frustum: its `t` interval and node.
#[derive(Clone, Copy, Default)]
pub(super) struct Span {
    t0: f32,
    t1: f32,
    node: u32,
}

/// The scalar frustum: the reciprocals of its direction box's ends and its slack.
struct Box3 {
    /// `1 / qlo` per axis (`qlo` moved away from zero to at least `TINY_Q` in magnitude).
    ilo: [f32; 3],
    /// Whether `qlo > 0`, per axis.
    lo_pos: [bool; 3],
    /// `1 / qhi` per axis (as `ilo`).
    ihi: [f32; 3],
    /// Whether `qhi > 0`, per axis.
    hi_pos: [bool; 3],
    /// World-space slack `G`.
    g: f32,
}

/// Direction-box ends closer to zero than this are moved to it (outward: a bigger box), so
/// their reciprocals stay finite.
const TINY_Q: f32 = 1e-20;

/// `x` rounded up by the relative bound `OUT` (and an absolute `f32::MIN_POSITIVE`).
#[inline(always)]
fn up(x: f32) -> f32 {
    x + (x.abs() * OUT + f32::MIN_POSITIVE)
}

/// `x` rounded down (as [`up`]).
#[inline(always)]
fn down(x: f32) -> f32 {
    x - (x.abs() * OUT + f32::MIN_POSITIVE)
}

impl Box3 {
    /// The part of `[t0, t1]` where the frustum can be below the plane `p` (relative to the
    /// apex) on `axis`, grown by the slack.
    #[inline(always)]
    fn below(&self, axis: usize, p: f32, t0: f32, t1: f32) -> (f32, f32) {
        let x = (p + self.g) * self.ilo[axis];
        if self.lo_pos[axis] {
            (t0, t1.min(up(x)))
        } else {
            (t0.max(down(x)), t1)
        }
    }

    /// The part of `[t0, t1]` where the frustum can be above the plane `p` (as [`Box3::below`]).
    #[inline(always)]
    fn above(&self, axis: usize, p: f32, t0: f32, t1: f32) -> (f32, f32) {
        let x = (p - self.g) * self.ihi[axis];
        if self.hi_pos[axis] {
            (t0.max(down(x)), t1)
        } else {
            (t0, t1.min(up(x)))
        }
    }
}

impl KdAccel {
    /// Traces the bundles `infos` (consecutive, of one apex and face; their blocks of lanes
    /// `rows` and lanes' rays `lanes`) as one frustum, writing each bundle's occluded lanes to
    /// `hits`. Returns `false`, having done nothing, when the bundles do not make a frustum
    /// (see the module docs).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn light_frustum<V: Wide, C: Count>(
        &self,
        apex: [f32; 3],
        infos: &[BundleInfo],
        rows: &[f32],
        lanes: &[u32],
        rays: &Rays<'_>,
        stack: &mut [Span],
        count: &mut C,
        hits: &mut [u32; SUBS],
    ) -> bool {
        let w = V::LANES;
        let subs = infos.len().min(SUBS);
        let k = infos[0].k.map(|x| (x as usize).min(2));
        let m = k[2];
        let zero = V::splat(0.0);
        let (inf, ninf) = (V::splat(f32::INFINITY), V::splat(f32::NEG_INFINITY));
        let apex_max = apex.iter().fold(0.0f32, |a, x| a.max(x.abs()));
        let root_max = (0..3).fold(0.0f32, |a, i| {
            a.max(self.root.0[i].abs()).max(self.root.1[i].abs())
        });
        let mut tri: [Option<TriLanes<V>>; SUBS] = [None, None, None, None];
        let mut alive = [0u32; SUBS];
        let mut qlo = [inf; 3];
        let mut qhi = [ninf; 3];
        let mut t_far = zero;
        let mut g_max = zero;
        // Lanes moving along `+m` / `−m` from the apex.
        let (mut plus, mut minus) = (0u32, 0u32);
        for (j, info) in infos.iter().enumerate().take(subs) {
            let rows = &rows[j * ROWS * w..(j + 1) * ROWS * w];
            let o = [
                V::load(&rows[ROW_O * w..]),
                V::load(&rows[(ROW_O + 1) * w..]),
                V::load(&rows[(ROW_O + 2) * w..]),
            ];
            let d = [
                V::load(&rows[ROW_D * w..]),
                V::load(&rows[(ROW_D + 1) * w..]),
                V::load(&rows[(ROW_D + 2) * w..]),
            ];
            let t_max = V::load(&rows[ROW_T_MAX * w..]);
            // The watertight shear, as `WatertightRay::new` computes it (as the per-lane walk).
            let dz = d[k[2]];
            let sz = V::splat(1.0).div(dz);
            let sx = d[k[0]].div(dz);
            let sy = d[k[1]].div(dz);
            let valid = V::and(
                V::and(V::eq(sz.sub(sz), zero), V::eq(sx.sub(sx), zero)),
                V::eq(sy.sub(sy), zero),
            );
            let filled = if info.len as usize >= 32 {
                u32::MAX
            } else {
                (1u32 << info.len) - 1
            };
            // The lane's slack, as the per-lane walk's.
            let mut reach = zero;
            let mut off = zero;
            let mut o_max = zero;
            let mut d_max = zero;
            for a in 0..3 {
                let r0 = V::splat(self.root.0[a]).sub(o[a]).abs();
                let r1 = V::splat(self.root.1[a]).sub(o[a]).abs();
                reach = reach.max(r0.max(r1));
                let far = o[a].add(d[a].mul(t_max));
                off = off.max(far.sub(V::splat(apex[a])).abs());
                o_max = o_max.max(o[a].abs());
                d_max = d_max.max(d[a].abs());
            }
            let scale = o_max.add(V::splat(apex_max)).add(t_max.mul(d_max));
            let grow = V::splat(DELTA * (1.0 + ROUND))
                .mul(reach)
                .add(off)
                .add(V::splat(ROUND).mul(scale));
            let rev = [
                o[0].sub(V::splat(apex[0])),
                o[1].sub(V::splat(apex[1])),
                o[2].sub(V::splat(apex[2])),
            ];
            let len = rev[m].abs();
            let live = V::bits(valid) & filled;
            plus |= V::bits(V::gt(rev[m], zero)) & live;
            minus |= V::bits(V::lt(rev[m], zero)) & live;
            let mut lane_ok = V::bits(V::gt(len, V::splat(1e-30)));
            for a in 0..3 {
                let q = rev[a].div(len);
                lane_ok &= V::bits(V::lt(q.abs(), V::splat(1e30)));
                qlo[a] = qlo[a].min(V::select(valid, q, inf));
                qhi[a] = qhi[a].max(V::select(valid, q, ninf));
            }
            if lane_ok & live != live {
                return false;
            }
            t_far = t_far.max(V::select(valid, len, zero));
            g_max = g_max.max(V::select(valid, grow, zero));
            alive[j] = live;
            tri[j] = Some(TriLanes {
                o: [o[k[0]], o[k[1]], o[k[2]]],
                sx,
                sy,
                sz,
                t_max,
            });
        }
        if plus != 0 && minus != 0 {
            return false;
        }
        // The box, reduced over lanes.
        let mut buf = [[0.0f32; 16]; 8];
        for a in 0..3 {
            qlo[a].store(&mut buf[a]);
            qhi[a].store(&mut buf[3 + a]);
        }
        t_far.store(&mut buf[6]);
        g_max.store(&mut buf[7]);
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let (mut t_far, mut g_lanes) = (0.0f32, 0.0f32);
        for l in 0..w {
            for a in 0..3 {
                lo[a] = lo[a].min(buf[a][l]);
                hi[a] = hi[a].max(buf[3 + a][l]);
            }
            t_far = t_far.max(buf[6][l]);
            g_lanes = g_lanes.max(buf[7][l]);
        }
        for j in 0..subs {
            count.bundle(alive[j].count_ones());
        }
        if alive.iter().all(|&a| a == 0) {
            *hits = [0; SUBS];
            return true;
        }
        // The slack: the lanes' own, the rounding of `q` (at most `ROUND·|r|`), of the plane
        // distances `split − A` and of `p ± G` (relative to the root box and the apex).
        let g = (g_lanes + ROUND * (t_far * 2.0 + apex_max + root_max)) * (1.0 + 1.0 / 1024.0)
            + f32::MIN_POSITIVE;
        let mut b = Box3 {
            ilo: [0.0; 3],
            lo_pos: [false; 3],
            ihi: [0.0; 3],
            hi_pos: [false; 3],
            g,
        };
        for a in 0..3 {
            let l = if lo[a].abs() < TINY_Q { -TINY_Q } else { lo[a] };
            let h = if hi[a].abs() < TINY_Q { TINY_Q } else { hi[a] };
            b.ilo[a] = 1.0 / l;
            b.lo_pos[a] = l > 0.0;
            b.ihi[a] = 1.0 / h;
            b.hi_pos[a] = h > 0.0;
        }
        // Clip `[0, T]` to the root box (grown by the slack).
        let (mut t0, mut t1) = (0.0f32, up(t_far));
        for a in 0..3 {
            (t0, t1) = b.below(a, self.root.1[a] - apex[a], t0, t1);
            (t0, t1) = b.above(a, self.root.0[a] - apex[a], t0, t1);
        }
        *hits = [0; SUBS];
        if t0 > t1 {
            return true;
        }
        let Some(first) = tri[0].as_ref() else {
            return true;
        };
        let mut tris4 = [first; SUBS];
        for j in 1..subs {
            if let Some(t) = tri[j].as_ref() {
                tris4[j] = t;
            }
        }
        let tri = tris4;
        let nodes = &self.tree.nodes[..];
        let mut sp = 0usize;
        let mut e = Span { t0, t1, node: 0 };
        loop {
            let leaf = loop {
                let Some(&n) = nodes.get(e.node as usize) else {
                    break None;
                };
                if n.is_leaf() {
                    break Some(n);
                }
                count.node();
                let axis = n.axis().min(2);
                let p = n.split() - apex[axis];
                let (b0, b1) = b.below(axis, p, e.t0, e.t1);
                let (a0, a1) = b.above(axis, p, e.t0, e.t1);
                let below = Span {
                    t0: b0,
                    t1: b1,
                    node: e.node + 1,
                };
                let above = Span {
                    t0: a0,
                    t1: a1,
                    node: n.right(),
                };
                // The apex's side first.
                let (near, far) = if p >= 0.0 {
                    (below, above)
                } else {
                    (above, below)
                };
                let (near_in, far_in) = (near.t0 <= near.t1, far.t0 <= far.t1);
                if near_in {
                    if far_in && sp < stack.len() {
                        stack[sp] = far;
                        sp += 1;
                    }
                    e = near;
                } else if far_in {
                    e = far;
                } else {
                    break None;
                }
            };
            if let Some(n) = leaf {
                let s = n.offset() as usize;
                let end = s + n.count() as usize;
                if let Some(tris) = self.tris.get(s..end)
                    && !tris.is_empty()
                {
                    count.leaf(tris.len() as u32, 0);
                    for t in tris {
                        let mut any = 0;
                        for j in 0..subs {
                            if alive[j] != 0 {
                                count.tri();
                                let l = &lanes[j * w..(j + 1) * w];
                                let h = tri_hits(tri[j], k, t, alive[j], rays, l);
                                hits[j] |= h;
                                alive[j] &= !h;
                            }
                            any |= alive[j];
                        }
                        if any == 0 {
                            return true;
                        }
                    }
                }
            }
            if sp == 0 {
                return true;
            }
            sp -= 1;
            e = stack[sp];
        }
    }
}
