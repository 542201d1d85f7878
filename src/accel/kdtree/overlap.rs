//! Exact-ish triangle/box geometry shared by the builders and `validate()`: the separating-axis
//! overlap test (Akenine-Möller) and triangle clipping to a box, both in `f64`.
//!
//! Boxes are closed: a triangle touching a box face counts as overlapping it.

use glam::DVec3;

/// Axis-aligned box `[lo, hi]` (closed) in `f32`.
pub type Aabb = ([f32; 3], [f32; 3]);

/// Separating-axis triangle/box overlap test (13 axes), evaluated in `f64` on the `f32` inputs.
/// Touching counts as overlap.
pub(crate) fn tri_box_overlap(tri: &[[f32; 3]; 3], bx: &Aabb) -> bool {
    sat(tri, bx, false)
}

/// True when the triangle meets the box in a set of positive area: it meets the OPEN box, or
/// it lies in an axis plane within the box's slab on that axis and meets the open rectangle of
/// the box in that plane. Touching along an edge or at a point does not count.
///
/// This is the builders' contract (checked by `validate()`): a triangle must be listed in every
/// leaf it meets with positive area, except that a triangle lying in a split plane need only be
/// listed on one side of it.
pub(crate) fn tri_box_overlap_area(tri: &[[f32; 3]; 3], bx: &Aabb) -> bool {
    let mut b = *bx;
    if let Some(a) = planar_axis(tri) {
        let c = tri[0][a];
        if c >= b.0[a] && c <= b.1[a] {
            // Widen the slab so the triangle's plane is strictly inside: a 2-D test.
            let pad = 1.0 + c.abs();
            b.0[a] = c - pad;
            b.1[a] = c + pad;
        }
    }
    sat(tri, &b, true)
}

/// The axis the triangle lies flat in (all three vertices share that coordinate), if any.
pub(crate) fn planar_axis(tri: &[[f32; 3]; 3]) -> Option<usize> {
    (0..3).find(|&a| tri[0][a] == tri[1][a] && tri[1][a] == tri[2][a])
}

/// Separating-axis test; `open` makes touching count as separated.
fn sat(tri: &[[f32; 3]; 3], bx: &Aabb, open: bool) -> bool {
    let (lo, hi) = bx;
    for a in 0..3 {
        let mn = tri[0][a].min(tri[1][a]).min(tri[2][a]);
        let mx = tri[0][a].max(tri[1][a]).max(tri[2][a]);
        let separated = if open {
            mn >= hi[a] || mx <= lo[a]
        } else {
            mn > hi[a] || mx < lo[a]
        };
        if separated {
            return false;
        }
    }
    let lo = DVec3::new(lo[0] as f64, lo[1] as f64, lo[2] as f64);
    let hi = DVec3::new(hi[0] as f64, hi[1] as f64, hi[2] as f64);
    let c = (lo + hi) * 0.5;
    let h = (hi - lo) * 0.5;
    let v = tri.map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) - c);
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let separated = |n: DVec3| {
        let p0 = n.dot(v[0]);
        let p1 = n.dot(v[1]);
        let p2 = n.dot(v[2]);
        let r = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
        let (mn, mx) = (p0.min(p1).min(p2), p0.max(p1).max(p2));
        if open {
            mn >= r || mx <= -r
        } else {
            mn > r || mx < -r
        }
    };
    for edge in e {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            let n = edge.cross(axis);
            if n != DVec3::ZERO && separated(n) {
                return false;
            }
        }
    }
    let n = e[0].cross(e[1]);
    !(n != DVec3::ZERO && separated(n))
}

/// Clips triangle `tri` to the closed box `bx` (Sutherland–Hodgman in `f64`) and returns the
/// bounds of the clipped polygon, rounded outward to `f32` and clamped to the box, or `None`
/// when nothing of the triangle lies in the box.
pub(crate) fn clip_bounds(tri: &[[f32; 3]; 3], bx: &Aabb) -> Option<Aabb> {
    let mut poly = [[0.0f64; 3]; 12];
    let mut n = 3;
    for (i, p) in tri.iter().enumerate() {
        poly[i] = [p[0] as f64, p[1] as f64, p[2] as f64];
    }
    let mut tmp = [[0.0f64; 3]; 12];
    for a in 0..3 {
        for side in 0..2 {
            let plane = if side == 0 { bx.0[a] } else { bx.1[a] } as f64;
            let inside = |p: &[f64; 3]| {
                if side == 0 {
                    p[a] >= plane
                } else {
                    p[a] <= plane
                }
            };
            if poly[..n].iter().all(inside) {
                continue; // this plane cuts nothing off
            }
            let mut m = 0;
            for i in 0..n {
                let p = poly[i];
                let q = poly[(i + 1) % n];
                let (pin, qin) = (inside(&p), inside(&q));
                if pin {
                    tmp[m] = p;
                    m += 1;
                }
                if pin != qin && m < tmp.len() {
                    let t = (plane - p[a]) / (q[a] - p[a]);
                    let mut x = [0.0; 3];
                    for k in 0..3 {
                        x[k] = p[k] + (q[k] - p[k]) * t;
                    }
                    x[a] = plane;
                    tmp[m] = x;
                    m += 1;
                }
            }
            n = m;
            poly[..n].copy_from_slice(&tmp[..n]);
            if n == 0 {
                return None;
            }
        }
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &poly[..n] {
        for k in 0..3 {
            lo[k] = lo[k].min(round_down(p[k]));
            hi[k] = hi[k].max(round_up(p[k]));
        }
    }
    for k in 0..3 {
        lo[k] = lo[k].max(bx.0[k]);
        hi[k] = hi[k].min(bx.1[k]);
        if lo[k] > hi[k] {
            return None;
        }
    }
    Some((lo, hi))
}

/// Largest `f32` not above `x`.
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) > x { f.next_down() } else { f }
}

/// Smallest `f32` not below `x`.
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNIT: Aabb = ([0.0; 3], [1.0; 3]);

    #[test]
    fn overlap_detects_touching_inside_and_separated() {
        let inside = [[0.2, 0.2, 0.2], [0.8, 0.2, 0.2], [0.2, 0.8, 0.2]];
        assert!(tri_box_overlap(&inside, &UNIT));
        let touching = [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(tri_box_overlap(&touching, &UNIT));
        // Bounding boxes overlap but the triangle passes beside the corner.
        let diagonal = [[1.5, 0.0, 0.5], [0.0, 1.5, 0.5], [1.5, 1.5, 0.5]];
        assert!(tri_box_overlap(&diagonal, &UNIT));
        let beside = [[2.1, 0.0, 0.5], [0.0, 2.1, 0.5], [2.1, 2.1, 0.5]];
        assert!(!tri_box_overlap(&beside, &UNIT));
    }

    #[test]
    fn area_overlap_ignores_touching_but_keeps_faces() {
        let inside = [[0.2, 0.2, 0.2], [0.8, 0.2, 0.7], [0.2, 0.8, 0.2]];
        assert!(tri_box_overlap_area(&inside, &UNIT));
        // Touches the face x = 1 along an edge only.
        let edge = [[1.0, 0.0, 0.0], [2.0, 0.5, 0.0], [1.0, 1.0, 1.0]];
        assert!(tri_box_overlap(&edge, &UNIT) && !tri_box_overlap_area(&edge, &UNIT));
        // Lies in the face x = 1: positive area in the face.
        let face = [[1.0, 0.1, 0.1], [1.0, 0.9, 0.1], [1.0, 0.1, 0.9]];
        assert!(tri_box_overlap_area(&face, &UNIT));
        // Lies in the face plane but beyond the box's edge y = 1.
        let beyond = [[1.0, 1.0, 0.1], [1.0, 2.0, 0.1], [1.0, 1.0, 0.9]];
        assert!(tri_box_overlap(&beyond, &UNIT) && !tri_box_overlap_area(&beyond, &UNIT));
    }

    #[test]
    fn clipping_shrinks_bounds_to_the_box() {
        let big = [[-1.0, -1.0, 0.5], [3.0, -1.0, 0.5], [-1.0, 3.0, 0.5]];
        let b = clip_bounds(&big, &UNIT).expect("overlaps");
        assert_eq!(b, ([0.0, 0.0, 0.5], [1.0, 1.0, 0.5]));
        let far = [[5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]];
        assert_eq!(clip_bounds(&far, &UNIT), None);
    }
}
