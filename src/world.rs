//! [`World`]: a scene's geometry made ready to trace — analytic primitives, the merged triangle
//! mesh and its kD tree — with the per-ray queries the intersect and shadow stages call.

use std::time::Instant;

use glam::Vec3;

use crate::accel::kdtree::{BuildMethod, KdAccel, KdTree};
use crate::error::{LoadError, SceneError};
use crate::geometry::offset::{EXACT_POINT_ULPS, RAY_POINT_ULPS, offset_origin};
use crate::geometry::{plane, sphere};
use crate::mesh::TriangleMesh;
use crate::queue::PrimId;
use crate::scene::{
    Material, Plane, PointLight, Robustness, Scene, Sphere, SphereTest, TreeSource,
};

/// What kind of primitive a [`PrimId`] names, with its index within that kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimKind {
    /// `spheres[i]`.
    Sphere(usize),
    /// `planes[i]`.
    Plane(usize),
    /// Triangle `i` of the merged mesh.
    Triangle(usize),
}

/// What shading needs to know about a hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Hit point (re-projected onto spheres and planes).
    pub point: Vec3,
    /// Unit normal facing the incoming ray.
    pub normal: Vec3,
    /// Material index.
    pub material: u32,
    /// Origin for rays leaving the hit on the facing side (reflections, shadow rays toward lights
    /// in front): the point offset by its error bound.
    pub spawn: Vec3,
}

/// The triangles of all meshes, merged, with their tree.
#[derive(Debug)]
pub struct Triangles {
    /// All meshes' triangles, in scene order; triangle ids are indices into this mesh.
    pub mesh: TriangleMesh,
    /// Material of each triangle (one entry per mesh: `(first triangle, material)`).
    pub material_ranges: Vec<(u32, u32)>,
    /// The kD tree over `mesh`, prepared for traversal.
    pub tree: KdAccel,
    /// Where the tree came from.
    pub source: TreeSource,
    /// Seconds spent loading the OBJ files.
    pub load_seconds: f64,
    /// Seconds spent building or reading the tree.
    pub tree_seconds: f64,
}

impl Triangles {
    /// Material of triangle `k`.
    #[inline]
    pub fn material(&self, k: u32) -> u32 {
        // Meshes are few; the last range starting at or before k owns it.
        let i = self
            .material_ranges
            .partition_point(|&(first, _)| first <= k);
        self.material_ranges[i - 1].1
    }
}

/// A scene ready to trace.
#[derive(Debug)]
pub struct World {
    /// Spheres.
    pub spheres: Vec<Sphere>,
    /// Planes.
    pub planes: Vec<Plane>,
    /// Triangles and their tree; `None` when the scene has no mesh (no acceleration structure).
    pub triangles: Option<Triangles>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Lights.
    pub lights: Vec<PointLight>,
    /// Numerical variants.
    pub robustness: Robustness,
}

impl World {
    /// Loads the scene's meshes and builds (or reads) their tree.
    pub fn load(scene: &Scene) -> Result<World, LoadError> {
        let triangles = if scene.meshes.is_empty() {
            None
        } else {
            Some(load_triangles(scene)?)
        };
        Ok(World {
            spheres: scene.spheres.clone(),
            planes: scene.planes.clone(),
            triangles,
            materials: scene.materials.clone(),
            lights: scene.lights.clone(),
            robustness: scene.render.robustness,
        })
    }

    /// Builds a world around an already loaded mesh and tree (for tests and benchmarks).
    pub fn with_mesh(scene: &Scene, mesh: TriangleMesh, tree: KdTree) -> World {
        let material = scene.meshes.first().map_or(0, |m| m.material);
        let tree = KdAccel::new(tree, &mesh);
        World {
            spheres: scene.spheres.clone(),
            planes: scene.planes.clone(),
            triangles: Some(Triangles {
                mesh,
                material_ranges: vec![(0, material)],
                tree,
                source: TreeSource::Sah,
                load_seconds: 0.0,
                tree_seconds: 0.0,
            }),
            materials: scene.materials.clone(),
            lights: scene.lights.clone(),
            robustness: scene.render.robustness,
        }
    }

    /// Decodes a primitive id.
    #[inline]
    pub fn prim_kind(&self, id: PrimId) -> PrimKind {
        let i = id.0 as usize;
        let ns = self.spheres.len();
        let np = self.planes.len();
        if i < ns {
            PrimKind::Sphere(i)
        } else if i < ns + np {
            PrimKind::Plane(i - ns)
        } else {
            PrimKind::Triangle(i - ns - np)
        }
    }

    fn triangle_base(&self) -> u32 {
        (self.spheres.len() + self.planes.len()) as u32
    }

    /// Closest hit with `0 < t < t_max`; ties go to the lowest primitive id.
    #[inline]
    pub fn intersect_closest(&self, o: Vec3, d: Vec3, t_max: f32) -> (f32, PrimId) {
        let mut best_t = t_max;
        let mut best = PrimId::NONE;
        for (i, s) in self.spheres.iter().enumerate() {
            let hit = match self.robustness.sphere {
                SphereTest::Stable => sphere::intersect_stable(o, d, s.center, s.radius, best_t),
                SphereTest::Naive => sphere::intersect_naive(o, d, s.center, s.radius, best_t),
            };
            if let Some(t) = hit {
                best_t = t;
                best = PrimId(i as u32);
            }
        }
        let ns = self.spheres.len() as u32;
        for (i, p) in self.planes.iter().enumerate() {
            if let Some(t) = plane::intersect(o, d, p.point, p.normal, best_t) {
                best_t = t;
                best = PrimId(ns + i as u32);
            }
        }
        if let Some(tris) = &self.triangles
            && let Some(h) =
                tris.tree
                    .intersect_closest_with(o, d, best_t, self.robustness.triangle)
        {
            best_t = h.t;
            best = PrimId(self.triangle_base() + h.tri);
        }
        if best.is_hit() {
            (best_t, best)
        } else {
            (f32::INFINITY, best)
        }
    }

    /// True when anything is hit with `0 < t < t_max`; stops at the first hit found.
    #[inline]
    pub fn intersect_occluded(&self, o: Vec3, d: Vec3, t_max: f32) -> bool {
        let sphere_hit = |s: &Sphere| match self.robustness.sphere {
            SphereTest::Stable => sphere::intersect_stable(o, d, s.center, s.radius, t_max),
            SphereTest::Naive => sphere::intersect_naive(o, d, s.center, s.radius, t_max),
        };
        self.spheres.iter().any(|s| sphere_hit(s).is_some())
            || self
                .planes
                .iter()
                .any(|p| plane::intersect(o, d, p.point, p.normal, t_max).is_some())
            || self.triangles.as_ref().is_some_and(|t| {
                t.tree
                    .intersect_occluded_with(o, d, t_max, self.robustness.triangle)
            })
    }

    /// [`World::intersect_closest`] for many rays, bit-identical to it row for row: `out_t[i]`,
    /// `out_prim[i]` receive ray `i`'s answer. Mesh-only scenes with the watertight test go
    /// through [`KdAccel::intersect_closest_batch`] (4-ray packets); others ray by ray.
    /// Panics if the slices' lengths differ.
    pub fn intersect_closest_batch(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_prim: &mut [PrimId],
    ) {
        let n = origins.len();
        assert!(dirs.len() == n && t_max.len() == n && out_t.len() == n && out_prim.len() == n);
        match &self.triangles {
            Some(t) if self.mesh_only_watertight() => {
                // `PrimId` is a transparent `u32`; triangle ids start at 0 in a mesh-only world,
                // and a miss (`u32::MAX`) is `PrimId::NONE`.
                let tri: &mut [u32] = bytemuck::cast_slice_mut(out_prim);
                t.tree
                    .intersect_closest_batch(origins, dirs, t_max, out_t, tri);
            }
            _ => {
                for i in 0..n {
                    (out_t[i], out_prim[i]) = self.intersect_closest(origins[i], dirs[i], t_max[i]);
                }
            }
        }
    }

    /// [`World::intersect_occluded`] for many rays into `out`, bit-identical to it row for row
    /// (mesh-only scenes with the watertight test go through
    /// [`KdAccel::intersect_occluded_batch`]). Panics if the slices' lengths differ.
    pub fn intersect_occluded_batch(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
    ) {
        let n = origins.len();
        assert!(dirs.len() == n && t_max.len() == n && out.len() == n);
        match &self.triangles {
            Some(t) if self.mesh_only_watertight() => {
                t.tree.intersect_occluded_batch(origins, dirs, t_max, out);
            }
            _ => {
                for i in 0..n {
                    out[i] = self.intersect_occluded(origins[i], dirs[i], t_max[i]);
                }
            }
        }
    }

    /// True when the world's only primitives are triangles, tested with the watertight test
    /// (what the batch kernels of [`KdAccel`] compute).
    fn mesh_only_watertight(&self) -> bool {
        self.spheres.is_empty()
            && self.planes.is_empty()
            && self.triangle_base() == 0
            && self.robustness.triangle == crate::scene::TriangleTest::Watertight
    }

    /// The surface at a hit: point, normal facing the incoming direction `d`, material, and the
    /// origin for rays leaving it.
    ///
    /// Sphere and plane hits are re-projected onto the surface, which leaves an error of a few
    /// ulps, and are offset by [`EXACT_POINT_ULPS`]; triangle hits keep `o + t·d`, whose error grows
    /// with `t`, and are offset by [`RAY_POINT_ULPS`].
    #[inline]
    pub fn surface(&self, prim: PrimId, o: Vec3, d: Vec3, t: f32) -> Surface {
        let p = o + t * d;
        let (point, n, material, ulps) = match self.prim_kind(prim) {
            PrimKind::Sphere(i) => {
                let s = &self.spheres[i];
                let (p, n) = sphere::reproject(p, s.center, s.radius);
                (p, n, s.material, EXACT_POINT_ULPS)
            }
            PrimKind::Plane(i) => {
                let pl = &self.planes[i];
                let p = p - (p - pl.point).dot(pl.normal) * pl.normal;
                (p, pl.normal, pl.material, EXACT_POINT_ULPS)
            }
            PrimKind::Triangle(k) => {
                let tris = self
                    .triangles
                    .as_ref()
                    .expect("triangle id without triangles");
                let n = tris.mesh.geometric_normal(k).normalize();
                (p, n, tris.material(k as u32), RAY_POINT_ULPS)
            }
        };
        let normal = if n.dot(d) > 0.0 { -n } else { n };
        Surface {
            point,
            normal,
            material,
            spawn: offset_origin(point, normal, ulps, self.robustness.offset),
        }
    }
}

fn load_triangles(scene: &Scene) -> Result<Triangles, LoadError> {
    let start = Instant::now();
    let mut mesh = TriangleMesh::default();
    let mut material_ranges = Vec::with_capacity(scene.meshes.len());
    for m in &scene.meshes {
        if !m.path.exists() {
            return Err(crate::scene::builtin::missing_mesh(&m.path).into());
        }
        let part = TriangleMesh::load_obj(&m.path)?;
        material_ranges.push((mesh.len() as u32, m.material));
        let base = mesh.vertices.len() as u32;
        mesh.vertices.extend_from_slice(&part.vertices);
        mesh.indices
            .extend(part.indices.iter().map(|t| t.map(|i| i + base)));
    }
    let load_seconds = start.elapsed().as_secs_f64();

    let source = tree_source(scene)?;
    let start = Instant::now();
    let tree = match &source {
        TreeSource::Sah => KdTree::build(&mesh, BuildMethod::Sah),
        TreeSource::Midpoint => KdTree::build(&mesh, BuildMethod::Midpoint),
        TreeSource::File(path) => KdTree::load_text(path, mesh.len())?,
    };
    let tree = KdAccel::new(tree, &mesh);
    Ok(Triangles {
        mesh,
        material_ranges,
        tree,
        source,
        load_seconds,
        tree_seconds: start.elapsed().as_secs_f64(),
    })
}

/// One tree covers all meshes: a tree file only makes sense for a single mesh.
fn tree_source(scene: &Scene) -> Result<TreeSource, SceneError> {
    let first = scene.meshes[0].kdtree.clone();
    if scene.meshes.len() > 1
        && scene
            .meshes
            .iter()
            .any(|m| matches!(m.kdtree, TreeSource::File(_)))
    {
        return Err(SceneError::Setting {
            key: "mesh.kdtree".into(),
            message: "a tree file can only be used with a scene that has exactly one mesh".into(),
        });
    }
    Ok(first)
}
