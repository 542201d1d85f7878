//! An independent reference renderer: a plain recursive per-pixel Whitted tracer in `f64`.
//!
//! Written straight from SPEC §1–§5 to check the wavefront pipeline against, so it shares no
//! intersection, shading, offset or acceleration code with it. It reads the [`Scene`] description,
//! the f64 vertex and index arrays of an [`ObjMesh`] (world coordinates as written), and takes sample positions from
//! [`sample_offset`] so multi-sample images use the same sample points. Everything else is here:
//! ray/sphere, ray/plane and ray/triangle tests, a small median-split BVH over the triangles,
//! Blinn-Phong shading, shadow rays and mirror reflections.
//!
//! Reads: a [`Scene`] and optionally its mesh. Writes: an [`OracleImage`] in linear radiance.

use std::fmt;

use glam::DVec3;
use rayon::prelude::*;

use wavefront::mesh::ObjMesh;
use wavefront::sampling::sample_offset;
use wavefront::scene::{Falloff, Light, LightKind, RenderMode, Scene};

/// A rendered image in linear radiance, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct OracleImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear radiance per pixel (mean of its samples).
    pub pixels: Vec<DVec3>,
}

impl OracleImage {
    /// 8-bit RGB: `round(255 · clamp(L, 0, 1)^(1/gamma))` per channel; NaN becomes 0.
    pub fn to_rgb8(&self, gamma: f64) -> Vec<u8> {
        let encode = |c: f64| {
            let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
            (255.0 * c.powf(1.0 / gamma)).round() as u8
        };
        self.pixels
            .iter()
            .flat_map(|p| p.to_array().map(encode))
            .collect()
    }
}

/// How far apart two 8-bit RGB images are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageDiff {
    /// Largest difference of any channel of any pixel, in levels of 255.
    pub max: u8,
    /// Pixels whose largest channel difference is more than 1 level.
    pub over_1: usize,
    /// Pixels whose largest channel difference is more than 3 levels.
    pub over_3: usize,
    /// Pixels compared.
    pub pixels: usize,
    /// Root mean square of the channel differences, in levels.
    pub rmse: f64,
    /// Peak signal-to-noise ratio in dB (infinite for identical images).
    pub psnr: f64,
}

impl fmt::Display for ImageDiff {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let share = |n: usize| 100.0 * n as f64 / self.pixels.max(1) as f64;
        write!(
            f,
            "max {} levels, {} px ({:.4}%) > 1, {} px ({:.4}%) > 3 of {}, rmse {:.4}, psnr {:.1} dB",
            self.max,
            self.over_1,
            share(self.over_1),
            self.over_3,
            share(self.over_3),
            self.pixels,
            self.rmse,
            self.psnr
        )
    }
}

/// Compares two 8-bit RGB images of the same size, pixel by pixel.
///
/// # Panics
/// When the lengths differ or are not a multiple of 3.
pub fn compare_rgb8(a: &[u8], b: &[u8]) -> ImageDiff {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    assert_eq!(a.len() % 3, 0, "not RGB");
    let mut diff = ImageDiff {
        max: 0,
        over_1: 0,
        over_3: 0,
        pixels: a.len() / 3,
        rmse: 0.0,
        psnr: f64::INFINITY,
    };
    let mut squares = 0.0;
    for (pa, pb) in a.chunks_exact(3).zip(b.chunks_exact(3)) {
        let d = pa
            .iter()
            .zip(pb)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        diff.max = diff.max.max(d);
        diff.over_1 += usize::from(d > 1);
        diff.over_3 += usize::from(d > 3);
        squares += pa
            .iter()
            .zip(pb)
            .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
            .sum::<f64>();
    }
    if !a.is_empty() {
        diff.rmse = (squares / a.len() as f64).sqrt();
    }
    if diff.rmse > 0.0 {
        diff.psnr = 20.0 * (255.0 / diff.rmse).log10();
    }
    diff
}

/// Renders `scene` with the oracle. `meshes[i]` holds the triangles of `scene.meshes[i]` (read
/// with [`ObjMesh::read_with`], with its per-face MTL materials when the mesh binds an MTL
/// library), which get that mesh's material or their own; meshes not given are ignored. Shading
/// is with geometric normals.
pub fn render_oracle(scene: &Scene, meshes: &[ObjMesh]) -> OracleImage {
    let oracle = Oracle::new(scene, meshes);
    let (w, h) = (scene.image.width, scene.image.height);
    let pixels = (0..h)
        .into_par_iter()
        .flat_map_iter(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| oracle.pixel(i, j))
        .collect();
    OracleImage {
        width: w,
        height: h,
        pixels,
    }
}

/// A material in f64.
#[derive(Clone, Copy, Debug)]
struct Mat {
    ka: DVec3,
    kd: DVec3,
    ks: DVec3,
    p: f64,
    alpha: f64,
}

/// What a ray hit: distance, unit geometric normal (not yet facing the ray), material.
#[derive(Clone, Copy, Debug)]
struct Hit {
    t: f64,
    normal: DVec3,
    material: usize,
}

/// The scene converted to f64, with a BVH over the triangles.
struct Oracle<'a> {
    scene: &'a Scene,
    materials: Vec<Mat>,
    spheres: Vec<(DVec3, f64, usize)>,
    planes: Vec<(DVec3, DVec3, usize)>,
    triangles: Vec<[DVec3; 3]>,
    /// Material of each triangle.
    triangle_material: Vec<usize>,
    bvh: Bvh,
}

/// Relative epsilon for secondary-ray origins: `p + EPS·max(1, |p − eye|, 10⁻⁶·|p|)·n` — relative
/// to the distance from the eye, so a scene moved far from the world's origin is traced as at
/// home, and never below f64's own rounding of `p` (≈ 10⁻¹⁶·|p|).
const EPS: f64 = 1e-9;

impl<'a> Oracle<'a> {
    fn new(scene: &'a Scene, meshes: &[ObjMesh]) -> Self {
        let materials = scene
            .materials
            .iter()
            .map(|m| Mat {
                ka: m.ka.as_dvec3(),
                kd: m.kd.as_dvec3(),
                ks: m.ks.as_dvec3(),
                p: f64::from(m.p),
                alpha: f64::from(m.alpha),
            })
            .collect();
        let spheres = scene
            .spheres
            .iter()
            .map(|s| (s.center, f64::from(s.radius), s.material as usize))
            .collect();
        let planes = scene
            .planes
            .iter()
            .map(|p| {
                let n = p.normal.as_dvec3().normalize();
                (p.point, n, p.material as usize)
            })
            .collect();
        let mut triangles: Vec<[DVec3; 3]> = vec![];
        let mut triangle_material = vec![];
        for (m, r) in meshes.iter().zip(&scene.meshes) {
            triangles.extend(
                m.indices
                    .iter()
                    .map(|t| t.map(|i| DVec3::from(m.positions[i as usize]))),
            );
            match &r.mtl {
                // Per-face materials: the face's MTL material, or the fallback before any usemtl.
                Some(b) if m.face_materials.len() == m.indices.len() => {
                    triangle_material.extend(m.face_materials.iter().map(|&f| {
                        if f == wavefront::mesh::NO_MATERIAL {
                            b.fallback.unwrap_or(r.material) as usize
                        } else {
                            (b.first + f) as usize
                        }
                    }))
                }
                _ => triangle_material.resize(triangles.len(), r.material as usize),
            }
        }
        let bvh = Bvh::build(&triangles);
        Oracle {
            scene,
            materials,
            spheres,
            planes,
            triangles,
            triangle_material,
            bvh,
        }
    }

    /// Mean radiance of pixel `(i, j)` over its samples.
    fn pixel(&self, i: u32, j: u32) -> DVec3 {
        let image = &self.scene.image;
        let n = image.samples.max(1);
        let index = j * image.width + i;
        let mut sum = DVec3::ZERO;
        for s in 0..n {
            let (dx, dy) = sample_offset(image.seed, index, s, n);
            let x = f64::from(i) + f64::from(dx);
            let y = f64::from(j) + f64::from(dy);
            let d = self.primary_direction(x, y);
            sum += match self.scene.render.mode {
                RenderMode::HitMask => {
                    if self.closest(self.eye(), d, f64::INFINITY).is_some() {
                        DVec3::ONE
                    } else {
                        DVec3::ZERO
                    }
                }
                RenderMode::Shaded => self.trace(self.eye(), d, 0),
            };
        }
        sum / f64::from(n)
    }

    fn eye(&self) -> DVec3 {
        self.scene.camera.eye
    }

    /// SPEC §1: `us·u + vs·v − d·w` through image-plane point `(x, y)` in pixel units, normalised.
    fn primary_direction(&self, x: f64, y: f64) -> DVec3 {
        let c = &self.scene.camera;
        let (l, r, b, t, d) = (
            f64::from(c.l),
            f64::from(c.r),
            f64::from(c.b),
            f64::from(c.t),
            f64::from(c.d),
        );
        let nx = f64::from(self.scene.image.width);
        let ny = f64::from(self.scene.image.height);
        let us = l + (r - l) * x / nx;
        let vs = t - (t - b) * y / ny;
        (us * c.u.as_dvec3() + vs * c.v.as_dvec3() - d * c.w.as_dvec3()).normalize()
    }

    /// Radiance along the ray `o + t·d` (`d` unit) that has been reflected `depth` times.
    fn trace(&self, o: DVec3, d: DVec3, depth: u32) -> DVec3 {
        let Some(hit) = self.closest(o, d, f64::INFINITY) else {
            return DVec3::ZERO;
        };
        let p = o + hit.t * d;
        let n = if hit.normal.dot(d) > 0.0 {
            -hit.normal
        } else {
            hit.normal
        };
        let m = self.materials[hit.material];
        let view = -d;
        let scale = (p - self.eye()).length().max(1.0).max(1e-6 * p.length());
        let off = p + EPS * scale * n;
        let render = &self.scene.render;

        let mut local = m.ka * render.ambient.as_dvec3();
        for light in &self.scene.lights {
            let Some((l, factor)) = light_at(light, p) else {
                continue;
            };
            let intensity = light.intensity.as_dvec3() * factor;
            let n_dot_l = n.dot(l);
            if render.shadows {
                let (dir, t_max) = match light.position() {
                    Some(q) => ((q - off).normalize(), (q - off).length()),
                    None => (l, f64::INFINITY),
                };
                if n_dot_l <= 0.0 || self.occluded(off, dir, t_max) {
                    continue;
                }
            }
            local += m.kd * intensity * n_dot_l.max(0.0);
            if m.ks != DVec3::ZERO {
                let h = l + view;
                let n_dot_h = if h.length() > 0.0 {
                    n.dot(h.normalize()).max(0.0)
                } else {
                    0.0
                };
                local += m.ks * intensity * n_dot_h.powf(m.p);
            }
        }

        let mut radiance = (1.0 - m.alpha) * local;
        if m.alpha > 0.0 && depth < render.max_depth {
            let r = d - 2.0 * d.dot(n) * n;
            radiance += m.alpha * self.trace(off, r.normalize(), depth + 1);
        }
        radiance
    }

    /// The closest hit with `0 < t < t_max`.
    fn closest(&self, o: DVec3, d: DVec3, t_max: f64) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut bound = t_max;
        for &(c, r, material) in &self.spheres {
            if let Some(t) = hit_sphere(o, d, c, r, bound) {
                bound = t;
                let normal = (o + t * d - c) / r;
                best = Some(Hit {
                    t,
                    normal,
                    material,
                });
            }
        }
        for &(point, normal, material) in &self.planes {
            if let Some(t) = hit_plane(o, d, point, normal, bound) {
                bound = t;
                best = Some(Hit {
                    t,
                    normal,
                    material,
                });
            }
        }
        if let Some((t, k)) = self.bvh.closest(&self.triangles, o, d, bound) {
            let [a, b, c] = self.triangles[k];
            best = Some(Hit {
                t,
                normal: (b - a).cross(c - a).normalize(),
                material: self.triangle_material[k],
            });
        }
        best
    }

    /// True when anything is hit with `0 < t < t_max`.
    fn occluded(&self, o: DVec3, d: DVec3, t_max: f64) -> bool {
        self.spheres
            .iter()
            .any(|&(c, r, _)| hit_sphere(o, d, c, r, t_max).is_some())
            || self
                .planes
                .iter()
                .any(|&(p, n, _)| hit_plane(o, d, p, n, t_max).is_some())
            || self.bvh.closest(&self.triangles, o, d, t_max).is_some()
    }
}

/// SPEC §14 in f64, written independently of the renderer's: the unit vector from `p` toward
/// `light` and the factor on its intensity there (spot cone by the angle from the axis through
/// `acos`, `1/r²` falloff); `None` at a point or spot light's own position.
fn light_at(light: &Light, p: DVec3) -> Option<(DVec3, f64)> {
    let (l, dist, mut factor) = match light.kind {
        LightKind::Directional { direction } => (-direction.normalize(), f64::INFINITY, 1.0),
        LightKind::Point { position } | LightKind::Spot { position, .. } => {
            let dist = (position - p).length();
            if dist == 0.0 {
                return None;
            }
            ((position - p) / dist, dist, 1.0)
        }
    };
    if let LightKind::Spot {
        direction,
        cone,
        penumbra,
        ..
    } = light.kind
    {
        let angle = (-l)
            .dot(direction.normalize())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        let (outer, inner) = (cone / 2.0, (cone - penumbra) / 2.0);
        factor = if angle <= inner {
            1.0
        } else if angle >= outer {
            0.0
        } else {
            let t = (outer - angle) / (outer - inner);
            t * t * (3.0 - 2.0 * t)
        };
    }
    if light.falloff == Falloff::InverseSquare {
        factor /= dist * dist;
    }
    Some((l, factor))
}

/// The nearest root `0 < t < t_max` of `|o + t·d − c|² = r²` (`d` unit).
fn hit_sphere(o: DVec3, d: DVec3, c: DVec3, r: f64, t_max: f64) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    [-b - root, -b + root]
        .into_iter()
        .find(|&t| t > 0.0 && t < t_max)
}

/// `0 < t < t_max` where the ray meets the plane through `point` with normal `n`.
fn hit_plane(o: DVec3, d: DVec3, point: DVec3, n: DVec3, t_max: f64) -> Option<f64> {
    let denom = d.dot(n);
    if denom == 0.0 {
        return None;
    }
    let t = (point - o).dot(n) / denom;
    (t > 0.0 && t < t_max).then_some(t)
}

/// Möller–Trumbore: `0 < t < t_max` where the ray meets triangle `[a, b, c]`, edges included.
fn hit_triangle(o: DVec3, d: DVec3, [a, b, c]: [DVec3; 3], t_max: f64) -> Option<f64> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = o - a;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = d.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > 0.0 && t < t_max).then_some(t)
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: DVec3,
    max: DVec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: DVec3::INFINITY,
        max: DVec3::NEG_INFINITY,
    };

    fn grow(self, p: DVec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// Grown by a tiny relative epsilon so rounding in the slab test never loses a triangle.
    fn padded(self) -> Aabb {
        let pad = DVec3::splat(1e-9 * self.min.abs().max(self.max.abs()).max_element().max(1.0));
        Aabb {
            min: self.min - pad,
            max: self.max + pad,
        }
    }

    /// True when the ray overlaps the box for some `t` in `[0, t_max]`.
    fn hit(&self, o: DVec3, d: DVec3, t_max: f64) -> bool {
        let (mut t0, mut t1) = (0.0f64, t_max);
        for a in 0..3 {
            if d[a] == 0.0 {
                if o[a] < self.min[a] || o[a] > self.max[a] {
                    return false;
                }
            } else {
                let ta = (self.min[a] - o[a]) / d[a];
                let tb = (self.max[a] - o[a]) / d[a];
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        t0 <= t1
    }
}

/// A BVH node: a padded box and either two children or a run of triangles.
#[derive(Clone, Copy, Debug)]
enum Node {
    Inner {
        bounds: Aabb,
        left: u32,
        right: u32,
    },
    Leaf {
        bounds: Aabb,
        first: u32,
        count: u32,
    },
}

/// A median-split bounding volume hierarchy over triangles: each node's triangles are split in
/// half by their centroids along the longest axis of the centroids' box.
#[derive(Debug, Default)]
struct Bvh {
    nodes: Vec<Node>,
    /// Triangle indices, leaves referring to runs of it.
    order: Vec<u32>,
}

const LEAF_SIZE: usize = 4;

impl Bvh {
    fn build(triangles: &[[DVec3; 3]]) -> Bvh {
        let mut bvh = Bvh {
            nodes: vec![],
            order: (0..triangles.len() as u32).collect(),
        };
        if !triangles.is_empty() {
            let centroids: Vec<DVec3> = triangles
                .iter()
                .map(|t| (t[0] + t[1] + t[2]) / 3.0)
                .collect();
            bvh.split(triangles, &centroids, 0, triangles.len());
        }
        bvh
    }

    /// Adds the node over `order[first..end]` and returns its index.
    fn split(&mut self, tris: &[[DVec3; 3]], centroids: &[DVec3], first: usize, end: usize) -> u32 {
        let items = &mut self.order[first..end];
        let bounds = items
            .iter()
            .flat_map(|&k| tris[k as usize])
            .fold(Aabb::EMPTY, Aabb::grow)
            .padded();
        let index = self.nodes.len() as u32;
        if items.len() <= LEAF_SIZE {
            self.nodes.push(Node::Leaf {
                bounds,
                first: first as u32,
                count: items.len() as u32,
            });
            return index;
        }
        let cbox = items
            .iter()
            .map(|&k| centroids[k as usize])
            .fold(Aabb::EMPTY, Aabb::grow);
        let extent = cbox.max - cbox.min;
        let axis = (0..3)
            .max_by(|&a, &b| extent[a].total_cmp(&extent[b]))
            .unwrap_or(0);
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |&a, &b| {
            centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
        });
        // Placeholder, patched once both children exist.
        self.nodes.push(Node::Leaf {
            bounds,
            first: 0,
            count: 0,
        });
        let left = self.split(tris, centroids, first, first + mid);
        let right = self.split(tris, centroids, first + mid, end);
        self.nodes[index as usize] = Node::Inner {
            bounds,
            left,
            right,
        };
        index
    }

    /// Closest triangle hit with `0 < t < t_max`: `(t, triangle index)`.
    fn closest(&self, tris: &[[DVec3; 3]], o: DVec3, d: DVec3, t_max: f64) -> Option<(f64, usize)> {
        let mut best = None;
        let mut bound = t_max;
        let mut stack = vec![];
        if !self.nodes.is_empty() {
            stack.push(0u32);
        }
        while let Some(i) = stack.pop() {
            match self.nodes[i as usize] {
                Node::Inner {
                    bounds,
                    left,
                    right,
                } => {
                    if bounds.hit(o, d, bound) {
                        stack.push(left);
                        stack.push(right);
                    }
                }
                Node::Leaf {
                    bounds,
                    first,
                    count,
                } => {
                    if !bounds.hit(o, d, bound) {
                        continue;
                    }
                    for &k in &self.order[first as usize..(first + count) as usize] {
                        if let Some(t) = hit_triangle(o, d, tris[k as usize], bound) {
                            bound = t;
                            best = Some((t, k as usize));
                        }
                    }
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    // Materials are stored in f32 (0.2 is 0.2000000030), so shading checks allow 1e-7.

    use super::*;
    use wavefront::scene::builtin::spheres;

    /// Scene A shrunk to one pixel looking straight down -z at the green sphere.
    fn one_pixel_scene() -> Scene {
        let mut s = spheres();
        s.image.width = 1;
        s.image.height = 1;
        s
    }

    #[test]
    fn central_ray_hits_the_green_sphere_at_its_front_pole() {
        let scene = one_pixel_scene();
        let o = Oracle::new(&scene, &[]);
        let d = o.primary_direction(0.5, 0.5);
        assert_eq!(d, DVec3::new(0.0, 0.0, -1.0));
        let hit = o.closest(DVec3::ZERO, d, f64::INFINITY).unwrap();
        assert!((hit.t - 5.0).abs() < 1e-12);
        assert!((hit.normal - DVec3::Z).length() < 1e-12);
        assert_eq!(hit.material, 2);
    }

    #[test]
    fn green_pole_has_hand_computed_blinn_phong_colour() {
        let scene = one_pixel_scene();
        let img = render_oracle(&scene, &[]);
        // p = (0, 0, -5), n = +z, v = +z, light (-4, 4, -3): l = (-4, 4, 2)/6.
        let l = DVec3::new(-4.0, 4.0, 2.0) / 6.0;
        let h = (l + DVec3::Z).normalize();
        let g = 0.2 + 0.5 * l.z + 0.5 * h.z.powf(32.0);
        let s = 0.5 * h.z.powf(32.0);
        let expected = DVec3::new(s, g, s);
        assert!(
            (img.pixels[0] - expected).length() < 1e-7,
            "{} vs {expected}",
            img.pixels[0]
        );
        // l.z = 1/3: the green channel is 0.2 + 0.5/3 plus the small specular term.
        assert!((img.pixels[0].y - (0.2 + 0.5 / 3.0 + s)).abs() < 1e-7);
    }

    #[test]
    fn floor_point_in_the_red_spheres_shadow_keeps_only_ambient() {
        let scene = spheres();
        let o = Oracle::new(&scene, &[]);
        // The light (-4, 4, -3) through the red sphere's centre (-4, 0, -7) meets the floor at
        // (-4, -2, -9): in shadow.
        let p = DVec3::new(-4.0, -2.0, -9.0);
        let d = p.normalize();
        let with = o.trace(DVec3::ZERO, d, scene.render.max_depth);
        assert!((with - DVec3::splat(0.5 * 0.2)).length() < 1e-7, "{with}");
        let mut lit = scene.clone();
        lit.render.shadows = false;
        let o = Oracle::new(&lit, &[]);
        let l = (DVec3::new(-4.0, 4.0, -3.0) - p).normalize();
        let without = o.trace(DVec3::ZERO, d, lit.render.max_depth);
        assert!((without - DVec3::splat(0.5 * (0.2 + l.y))).length() < 1e-7);
    }

    #[test]
    fn reflection_stops_at_max_depth_and_keeps_local_shading() {
        let mut scene = spheres();
        scene.render.shadows = false;
        let o = Oracle::new(&scene, &[]);
        let d = DVec3::new(0.0, -1.0, -1.0).normalize(); // floor at (0, -2, -2), mirrored upward
        let at_limit = o.trace(DVec3::ZERO, d, scene.render.max_depth);
        let p = DVec3::new(0.0, -2.0, -2.0);
        let l = (DVec3::new(-4.0, 4.0, -3.0) - p).normalize();
        assert!((at_limit - DVec3::splat(0.5 * (0.2 + l.y))).length() < 1e-7);
        // Below the limit the mirrored ray (0, 1, -1) misses everything: still black.
        let below = o.trace(DVec3::ZERO, d, 0);
        assert!((below - at_limit).length() < 1e-12);
    }

    #[test]
    fn two_sided_triangle_is_hit_from_both_sides_and_shadows() {
        let mut scene = spheres();
        scene.spheres.clear();
        scene.planes.clear();
        scene.materials[0].alpha = 0.0;
        scene.meshes = vec![wavefront::scene::MeshRef {
            path: "unused.obj".into(),
            material: 0,
            kdtree: wavefront::scene::TreeSource::Sah,
            normals: Default::default(),
            mtl: None,
            allow_empty: false,
        }];
        let mesh = ObjMesh {
            positions: vec![[-1.0, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]],
            indices: vec![[0, 1, 2]],
            ..ObjMesh::default()
        };
        let o = Oracle::new(&scene, &[mesh]);
        let front = o.closest(DVec3::ZERO, DVec3::NEG_Z, f64::INFINITY).unwrap();
        assert!((front.t - 3.0).abs() < 1e-12);
        let back = o
            .closest(DVec3::new(0.0, 0.0, -6.0), DVec3::Z, f64::INFINITY)
            .unwrap();
        assert!((back.t - 3.0).abs() < 1e-12);
        assert!(o.occluded(DVec3::ZERO, DVec3::NEG_Z, 10.0));
        assert!(!o.occluded(DVec3::ZERO, DVec3::NEG_Z, 2.0));
        assert!(!o.occluded(DVec3::ZERO, DVec3::Z, 10.0));
    }

    #[test]
    fn bvh_finds_the_same_hits_as_brute_force() {
        // A grid of small triangles and a fan of rays through it.
        let mut tris = vec![];
        for i in 0..20 {
            for j in 0..20 {
                let p = DVec3::new(i as f64, j as f64, (i * j % 7) as f64 - 10.0);
                tris.push([p, p + DVec3::X, p + DVec3::Y + 0.3 * DVec3::Z]);
            }
        }
        let bvh = Bvh::build(&tris);
        for r in 0..500 {
            let o = DVec3::new(10.0, 10.0, 5.0);
            let target = DVec3::new((r % 23) as f64 - 1.0, (r / 23) as f64, -10.0);
            let d = (target - o).normalize();
            let brute = tris
                .iter()
                .enumerate()
                .filter_map(|(k, &t)| hit_triangle(o, d, t, f64::INFINITY).map(|t| (t, k)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let fast = bvh.closest(&tris, o, d, f64::INFINITY);
            assert_eq!(fast.map(|h| h.0), brute.map(|h| h.0), "ray {r}");
        }
    }

    #[test]
    fn hit_mask_is_white_on_geometry_and_black_on_sky() {
        let mut scene = spheres();
        scene.render.mode = RenderMode::HitMask;
        scene.image.width = 8;
        scene.image.height = 8;
        let img = render_oracle(&scene, &[]);
        assert_eq!(img.pixels[0], DVec3::ZERO, "top-left corner sees the sky");
        assert_eq!(
            img.pixels[63],
            DVec3::ONE,
            "bottom-right corner sees the floor"
        );
    }

    #[test]
    fn encoding_and_comparison_count_levels() {
        let img = OracleImage {
            width: 2,
            height: 1,
            pixels: vec![DVec3::new(0.5, f64::NAN, 2.0), DVec3::new(-1.0, 0.0, 1.0)],
        };
        let rgb = img.to_rgb8(2.2);
        let half = (255.0 * 0.5f64.powf(1.0 / 2.2)).round() as u8;
        assert_eq!(rgb, vec![half, 0, 255, 0, 0, 255]);
        let mut other = rgb.clone();
        other[1] = 2;
        other[5] = 250;
        let d = compare_rgb8(&rgb, &other);
        assert_eq!((d.max, d.over_1, d.over_3, d.pixels), (5, 2, 1, 2));
        assert!((d.rmse - (29.0f64 / 6.0).sqrt()).abs() < 1e-12);
        let same = compare_rgb8(&rgb, &rgb);
        assert_eq!((same.max, same.rmse, same.psnr), (0, 0.0, f64::INFINITY));
    }
}
