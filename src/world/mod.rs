//! [`World`]: a scene's geometry made ready to trace — analytic primitives, the merged triangle
//! mesh and its kD tree — with the per-ray queries the intersect and shadow stages call.

use glam::Vec3;

use crate::accel::kdtree::TreeError;
use crate::accel::kdtree::{BuildMethod, KdAccel, KdTree};
use crate::error::SceneError;
use crate::geometry::offset::{gamma, offset_fixed, offset_ray_origin};
use crate::geometry::{plane, sphere, triangle};
use crate::mesh::TriangleMesh;
use crate::mesh::{MeshError, ObjMesh};
use crate::queue::PrimId;
use crate::scene::{Material, OffsetMethod, Robustness, Scene, SphereTest, TreeSource};
use crate::world::frame::{Light, Plane, RenderFrame, Sphere};

mod analytic;
pub mod frame;
mod load;
mod sphere_bvh;
pub use analytic::SurfaceOut;
pub use load::{CacheStatus, Setup, cache_key, centred_entry, check_mesh_bytes, read_mesh_file};
pub use sphere_bvh::{SPHERE_BVH_MIN, SphereBvh};

/// Anything that can go wrong turning a [`Scene`] into a traceable world.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The scene itself is at fault (e.g. a missing mesh).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A mesh file is malformed.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A tree file is malformed or does not fit the mesh.
    #[error(transparent)]
    Tree(#[from] TreeError),
}

/// What kind of primitive a [`PrimId`] names, with its index within that kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PrimKind {
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
    /// Unit shading normal, on the side of `normal`: `normal` itself, or the interpolated vertex
    /// normal of a mesh with `normals = "vertex"` (used for `Ld`, `Ls` and reflection directions).
    pub shading: Vec3,
}

/// The triangles of all meshes, merged, with their tree.
#[derive(Debug)]
pub struct Triangles {
    /// All meshes' triangles, in scene order, in the render frame; triangle ids are indices into
    /// this mesh.
    mesh: TriangleMesh,
    /// The same vertices in world coordinates (f64 as read): what another frame is made from.
    world_positions: Vec<[f64; 3]>,
    /// Unit shading normal of each vertex, or zero where its mesh shades with geometric normals;
    /// empty when no mesh uses vertex normals.
    vertex_normals: Vec<[f32; 3]>,
    /// Material of each triangle (one entry per mesh: `(first triangle, material)`).
    material_ranges: Vec<(u32, u32)>,
    /// The kD tree over `mesh`, prepared for traversal (leaf-ordered triangle copy).
    tree: KdAccel,
    /// Where the tree came from.
    source: TreeSource,
}

/// How long a world took to set up (not part of the world: it does not change what is traced).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SetupTimes {
    /// Seconds spent loading the OBJ files.
    pub load_seconds: f64,
    /// Seconds spent building or reading the tree.
    pub tree_seconds: f64,
}

impl Triangles {
    /// The merged mesh.
    pub fn mesh(&self) -> &TriangleMesh {
        &self.mesh
    }

    /// The kD tree over [`Triangles::mesh`].
    pub fn tree(&self) -> &KdTree {
        self.tree.tree()
    }

    /// The tree prepared for traversal (what the world's queries walk).
    pub fn accel(&self) -> &KdAccel {
        &self.tree
    }

    /// The interpolated unit vertex normal of triangle `k` at barycentric coordinates `b`, or
    /// `None` where its mesh shades with geometric normals.
    #[inline]
    pub(crate) fn shading_normal(&self, k: usize, b: [f32; 3]) -> Option<Vec3> {
        if self.vertex_normals.is_empty() {
            return None;
        }
        let [n0, n1, n2] =
            self.mesh.indices[k].map(|i| Vec3::from(self.vertex_normals[i as usize]));
        let n = b[0] * n0 + b[1] * n1 + b[2] * n2;
        let len = n.length();
        (len > 0.0 && len.is_finite()).then(|| n / len)
    }

    /// The merged mesh in the frame centred on it — where `kdtree build` and the tree cache
    /// build and tree files are checked — and that frame (for `bench`'s tree-check figure).
    pub fn centred_mesh(&self) -> Result<(RenderFrame, TriangleMesh), MeshError> {
        let (_, frame, mesh) = centred_mesh(
            &self.world_positions,
            &self.mesh.indices,
            std::path::Path::new("the merged mesh"),
        )?;
        Ok((frame, mesh))
    }

    /// Where the tree came from.
    pub fn source(&self) -> &TreeSource {
        &self.source
    }

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

/// A scene ready to trace: read-only once built, reached through the accessors the stages need.
#[derive(Debug)]
pub struct World {
    spheres: Vec<Sphere>,
    planes: Vec<Plane>,
    /// The spheres' BVH, for more than [`SPHERE_BVH_MIN`] of them (fewer are tested directly).
    sphere_bvh: Option<SphereBvh>,
    /// Every analytic primitive as the surface kernel reads it, for more than
    /// [`analytic::SMALL_TABLE`] of them (kept so that each batch does not rebuild it; smaller
    /// tables are copied to the stack per batch).
    prim_table: Vec<analytic::PrimEntry>,
    /// `None` when the scene has no mesh (no acceleration structure).
    triangles: Option<Triangles>,
    materials: Vec<Material>,
    lights: Vec<Light>,
    robustness: Robustness,
    frame: RenderFrame,
}

impl World {
    /// Loads the scene's meshes and builds (or reads) their tree.
    pub fn load(scene: &Scene) -> Result<World, LoadError> {
        Ok(World::load_timed(scene)?.0)
    }

    /// [`World::load`], also saying how long loading and building took.
    pub(crate) fn load_timed(scene: &Scene) -> Result<(World, SetupTimes), LoadError> {
        let (world, setup) = World::load_cached(scene, None)?;
        Ok((world, setup.times))
    }

    /// The scene's analytic primitives, materials and lights in `frame`, with `triangles`.
    fn analytic(scene: &Scene, frame: RenderFrame, triangles: Option<Triangles>) -> World {
        let spheres: Vec<Sphere> = scene.spheres.iter().map(|s| frame.sphere(s)).collect();
        let planes: Vec<Plane> = scene.planes.iter().map(|p| frame.plane(p)).collect();
        let sphere_bvh = (spheres.len() > SPHERE_BVH_MIN).then(|| SphereBvh::new(&spheres));
        let prim_table = if spheres.len() + planes.len() > analytic::SMALL_TABLE {
            analytic::prim_entries(&spheres, &planes).collect()
        } else {
            vec![]
        };
        World {
            spheres,
            planes,
            sphere_bvh,
            prim_table,
            triangles,
            materials: scene.materials.clone(),
            lights: scene.lights.iter().map(|l| frame.light(l)).collect(),
            robustness: scene.render.robustness,
            frame,
        }
    }

    /// The same geometry traced with other numerical variants (the error report compares them
    /// without reloading the mesh).
    pub fn with_robustness(mut self, robustness: Robustness) -> World {
        self.robustness = robustness;
        self
    }

    /// The same world with every sphere tested directly, one by one, however many there are
    /// (no [`SphereBvh`]): the linear loop the tree's answers are checked against.
    pub fn with_direct_spheres(mut self) -> World {
        self.sphere_bvh = None;
        self
    }

    /// Materials, indexed by the material ids of primitives.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// The same world for `scene`'s camera (a frame of a camera path): analytic primitives and
    /// lights are taken from `scene`, the mesh is moved into the new eye's frame from its f64
    /// world coordinates, and the tree is moved with it ([`KdTree::reframed`]) instead of being
    /// rebuilt. What a frame renders is then exactly what a static scene with that camera
    /// renders (the closest hit does not depend on the tree).
    pub fn reframed(&self, scene: &Scene) -> World {
        let frame = RenderFrame::at(scene.camera.eye);
        let triangles = self.triangles.as_ref().map(|t| {
            let mesh = TriangleMesh::new(
                t.world_positions
                    .iter()
                    .map(|&p| frame.point(p.into()).to_array())
                    .collect(),
                t.mesh.indices.clone(),
            );
            let tree = KdAccel::new(t.tree.tree().reframed(&self.frame, &frame), &mesh);
            Triangles {
                mesh,
                world_positions: t.world_positions.clone(),
                vertex_normals: t.vertex_normals.clone(),
                material_ranges: t.material_ranges.clone(),
                tree,
                source: t.source.clone(),
            }
        });
        World::analytic(scene, frame, triangles)
    }

    /// The render frame everything is traced in (world coordinates minus the eye).
    pub fn frame(&self) -> &RenderFrame {
        &self.frame
    }

    /// The lights (point, directional, spot) in the render frame.
    pub fn lights(&self) -> &[Light] {
        &self.lights
    }

    /// Spheres.
    pub fn spheres(&self) -> &[Sphere] {
        &self.spheres
    }

    /// Planes.
    pub fn planes(&self) -> &[Plane] {
        &self.planes
    }

    /// The spheres' BVH, when there are more than [`SPHERE_BVH_MIN`] of them.
    pub fn sphere_bvh(&self) -> Option<&SphereBvh> {
        self.sphere_bvh.as_ref()
    }

    /// The merged triangle mesh and its tree, if the scene has meshes.
    pub fn triangles(&self) -> Option<&Triangles> {
        self.triangles.as_ref()
    }

    /// The numerical variants traced.
    pub fn robustness(&self) -> Robustness {
        self.robustness
    }

    /// Builds a world around a mesh given in world coordinates (for tests and benchmarks): the
    /// mesh is moved into the scene's render frame and a tree built over it with `method`.
    pub fn with_mesh(scene: &Scene, mesh: &TriangleMesh, method: BuildMethod) -> World {
        let frame = RenderFrame::at(scene.camera.eye);
        let world_positions: Vec<[f64; 3]> =
            mesh.vertices.iter().map(|v| v.map(f64::from)).collect();
        let vertices = world_positions
            .iter()
            .map(|&p| frame.point(p.into()).to_array())
            .collect();
        let mesh = TriangleMesh::new(vertices, mesh.indices.clone());
        let tree = KdAccel::new(KdTree::build(&mesh, method), &mesh);
        let material = scene.meshes.first().map_or(0, |m| m.material);
        let triangles = Triangles {
            mesh,
            world_positions,
            vertex_normals: vec![],
            material_ranges: vec![(0, material)],
            tree,
            source: TreeSource::Sah,
        };
        World::analytic(scene, frame, Some(triangles))
    }

    /// Decodes a primitive id.
    #[inline]
    pub(crate) fn prim_kind(&self, id: PrimId) -> PrimKind {
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
        match &self.sphere_bvh {
            // The tree gives the loop's answer (`world::sphere_bvh`) for the stable test.
            Some(bvh) if self.robustness.sphere == SphereTest::Stable => {
                let (t, i) = bvh.closest(o, d, t_max);
                (best_t, best) = (t, PrimId(i));
            }
            _ => {
                for (i, s) in self.spheres.iter().enumerate() {
                    let hit = match self.robustness.sphere {
                        SphereTest::Stable => {
                            sphere::intersect_stable(o, d, s.center, s.radius, best_t)
                        }
                        SphereTest::Naive => {
                            sphere::intersect_naive(o, d, s.center, s.radius, best_t)
                        }
                    };
                    if let Some(t) = hit {
                        best_t = t;
                        best = PrimId(i as u32);
                    }
                }
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
        let spheres = match &self.sphere_bvh {
            Some(bvh) if self.robustness.sphere == SphereTest::Stable => bvh.occluded(o, d, t_max),
            _ => self.spheres.iter().any(|s| sphere_hit(s).is_some()),
        };
        spheres
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
    /// `out_prim[i]` receive ray `i`'s answer. Spheres and planes go through one SIMD batch
    /// kernel (`world::analytic`; many spheres through their BVH ray by ray), then the mesh through [`KdAccel::intersect_closest_batch`]
    /// (4-ray packets) with each ray's `t_max` lowered to its analytic hit — the scalar query's
    /// order, and its ties (analytic ids are lower, and triangles must be strictly nearer).
    /// Worlds with the naive sphere test or a non-watertight triangle test go ray by ray.
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
        if !self.batch_kernels() {
            for i in 0..n {
                (out_t[i], out_prim[i]) = self.intersect_closest(origins[i], dirs[i], t_max[i]);
            }
            return;
        }
        let analytic = !(self.spheres.is_empty() && self.planes.is_empty());
        match &self.triangles {
            Some(t) if !analytic => {
                // `PrimId` is a transparent `u32`; triangle ids start at 0 in a mesh-only world,
                // and a miss (`u32::MAX`) is `PrimId::NONE`.
                let tri: &mut [u32] = bytemuck::cast_slice_mut(out_prim);
                t.tree
                    .intersect_closest_batch(origins, dirs, t_max, out_t, tri);
            }
            tris => {
                analytic::closest(analytic::Closest {
                    spheres: &self.spheres,
                    sphere_bvh: self.sphere_bvh.as_ref(),
                    planes: &self.planes,
                    origins,
                    dirs,
                    t_max,
                    out_t,
                    out_prim,
                });
                if let Some(t) = tris {
                    self.mesh_closest_after_analytic(t, origins, dirs, t_max, out_t, out_prim);
                }
            }
        }
    }

    /// The mesh part of a mixed world's closest hits, after the analytic kernel has written its
    /// answers: each ray is traced with `t_max` = its analytic hit (or its own `t_max`), and a
    /// triangle hit, necessarily nearer, replaces the analytic one.
    fn mesh_closest_after_analytic(
        &self,
        t: &Triangles,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out_t: &mut [f32],
        out_prim: &mut [PrimId],
    ) {
        // Whole trace chunks, so camera rays still form 8 × 8-pixel frusta (blocks of 256 rays,
        // half an image row, traced at about half the speed).
        const BLOCK: usize = crate::queue::TRACE_CHUNK;
        let base = self.triangle_base();
        let mut limit = [0.0f32; BLOCK];
        let mut tri_t = [0.0f32; BLOCK];
        let mut tri = [0u32; BLOCK];
        for start in (0..origins.len()).step_by(BLOCK) {
            let end = (start + BLOCK).min(origins.len());
            let m = end - start;
            let rows = out_prim[start..end].iter().zip(&out_t[start..end]);
            for ((l, (p, &t)), &own) in limit.iter_mut().zip(rows).zip(&t_max[start..end]) {
                *l = if p.is_hit() { t } else { own };
            }
            t.tree.intersect_closest_batch(
                &origins[start..end],
                &dirs[start..end],
                &limit[..m],
                &mut tri_t[..m],
                &mut tri[..m],
            );
            let found = tri[..m].iter().zip(&tri_t[..m]);
            let rows = out_t[start..end].iter_mut().zip(&mut out_prim[start..end]);
            for ((t, p), (&k, &tt)) in rows.zip(found) {
                if k != u32::MAX {
                    (*t, *p) = (tt, PrimId(base + k));
                }
            }
        }
    }

    /// [`World::intersect_occluded`] for many rays into `out`, bit-identical to it row for row:
    /// spheres and planes through one SIMD batch kernel, then the rays they leave unblocked
    /// through [`KdAccel::intersect_occluded_batch`]. Panics if the slices' lengths differ.
    pub fn intersect_occluded_batch(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
    ) {
        let n = origins.len();
        assert!(dirs.len() == n && t_max.len() == n && out.len() == n);
        if !self.batch_kernels() {
            for i in 0..n {
                out[i] = self.intersect_occluded(origins[i], dirs[i], t_max[i]);
            }
            return;
        }
        let analytic = !(self.spheres.is_empty() && self.planes.is_empty());
        match &self.triangles {
            Some(t) if !analytic => t.tree.intersect_occluded_batch(origins, dirs, t_max, out),
            tris => {
                analytic::occluded(analytic::Occluded {
                    spheres: &self.spheres,
                    sphere_bvh: self.sphere_bvh.as_ref(),
                    planes: &self.planes,
                    origins,
                    dirs,
                    t_max,
                    out,
                });
                if let Some(t) = tris {
                    self.mesh_occluded_after_analytic(t, origins, dirs, t_max, out);
                }
            }
        }
    }

    /// The mesh part of a mixed world's occlusion: rays already blocked by an analytic primitive
    /// are traced with `t_max = 0` (nothing can be accepted, so they end at once) and stay
    /// blocked; the others take the mesh's answer.
    fn mesh_occluded_after_analytic(
        &self,
        t: &Triangles,
        origins: &[Vec3],
        dirs: &[Vec3],
        t_max: &[f32],
        out: &mut [bool],
    ) {
        const BLOCK: usize = 256;
        let mut limit = [0.0f32; BLOCK];
        let mut blocked = [false; BLOCK];
        for start in (0..origins.len()).step_by(BLOCK) {
            let end = (start + BLOCK).min(origins.len());
            let m = end - start;
            let rows = out[start..end].iter().zip(&t_max[start..end]);
            for (l, (&hit, &own)) in limit.iter_mut().zip(rows) {
                *l = if hit { 0.0 } else { own };
            }
            t.tree.intersect_occluded_batch(
                &origins[start..end],
                &dirs[start..end],
                &limit[..m],
                &mut blocked[..m],
            );
            for (o, &b) in out[start..end].iter_mut().zip(&blocked[..m]) {
                *o |= b;
            }
        }
    }

    /// True when the batch kernels compute what the scalar queries do: the stable sphere test
    /// (the analytic kernel's) and the watertight triangle test (the kD packets').
    fn batch_kernels(&self) -> bool {
        (self.spheres.is_empty() || self.robustness.sphere == SphereTest::Stable)
            && (self.triangles.is_none()
                || self.robustness.triangle == crate::scene::TriangleTest::Watertight)
    }

    /// The surface at a hit: point, normal facing the incoming direction `d`, material, and the
    /// origin for rays leaving it.
    ///
    /// Every primitive kind computes its hit point with an error bound (spheres and planes
    /// re-project `o + t·d` onto the surface, triangles rebuild it from barycentric coordinates),
    /// and rays leave from the point pushed along the facing normal by that bound
    /// (`offset_ray_origin`).
    #[inline]
    pub fn surface(&self, prim: PrimId, o: Vec3, d: Vec3, t: f32) -> Surface {
        let p = o + t * d;
        let mut shading = None;
        let (point, n, material, error) = match self.prim_kind(prim) {
            PrimKind::Sphere(i) => {
                let s = &self.spheres[i];
                let (p, n, error) = sphere::reproject(p, s.center, s.radius);
                (p, n, s.material, error)
            }
            PrimKind::Plane(i) => {
                let pl = &self.planes[i];
                let (p, error) = plane::reproject(p, pl.point, pl.normal);
                (p, pl.normal, pl.material, error)
            }
            PrimKind::Triangle(k) => {
                let tris = self
                    .triangles
                    .as_ref()
                    .expect("triangle id without triangles");
                let n = tris.mesh.unit_normal(k);
                let (p, error, b) = triangle::hit_point(o, d, tris.mesh.triangle(k))
                    .unwrap_or_else(|| (p, gamma(8) * (o.abs() + (t * d).abs()), [1.0, 0.0, 0.0]));
                shading = tris.shading_normal(k, b);
                (p, n, tris.material(k as u32), error)
            }
        };
        let normal = if n.dot(d) > 0.0 { -n } else { n };
        // The shading normal on the facing side (or the facing normal itself).
        let shading = match shading {
            Some(s) if s.dot(normal) < 0.0 => -s,
            Some(s) => s,
            None => normal,
        };
        let spawn = match self.robustness.offset {
            OffsetMethod::ErrorBound => offset_ray_origin(point, error, normal),
            OffsetMethod::FixedEpsilon => offset_fixed(point, normal),
        };
        Surface {
            point,
            normal,
            material,
            spawn,
            shading,
        }
    }
}

/// Checks the tree file `path` against the mesh of `positions` (world coordinates) and
/// `indices` with `KdTree::validate_file`, and returns the tree and the mesh it was checked
/// with. A file's numbers are exact in the frame its tree was built in, where the check is exact
/// too: the frame centred on the mesh (where `kdtree build` and the tree cache build) is tried
/// first, then the world's own frame (a tree built on the mesh as read). Checked in another frame
/// — the camera's — vertices and planes are rounded apart, and a valid tree can fail by a
/// rounding. The error is the centred frame's.
pub fn check_tree_file(
    path: &std::path::Path,
    positions: &[[f64; 3]],
    indices: &[[u32; 3]],
) -> Result<(KdTree, TriangleMesh), LoadError> {
    let (merged, centred, mesh) = centred_mesh(positions, indices, path)?;
    let tree = KdTree::load_text_in(path, mesh.len(), &centred)?;
    let first = match tree.validate_file(&mesh, path) {
        Ok(()) => return Ok((tree, mesh)),
        Err(e) => e,
    };
    let world = RenderFrame::default();
    if let Ok(mesh) = merged.to_frame(world.origin) {
        let tree = KdTree::load_text_in(path, mesh.len(), &world)?;
        if tree.validate_file(&mesh, path).is_ok() {
            return Ok((tree, mesh));
        }
    }
    Err(first.into())
}

/// The mesh of `positions` (world coordinates) and `indices` as one [`ObjMesh`] (`path` names
/// it in errors), the frame centred on it, and the mesh in that frame.
fn centred_mesh(
    positions: &[[f64; 3]],
    indices: &[[u32; 3]],
    path: &std::path::Path,
) -> Result<(ObjMesh, RenderFrame, TriangleMesh), MeshError> {
    let merged = ObjMesh {
        path: path.to_path_buf(),
        positions: positions.to_vec(),
        indices: indices.to_vec(),
        ..ObjMesh::default()
    };
    let centred = RenderFrame::centered_on(&merged);
    let mesh = merged.to_frame(centred.origin)?;
    Ok((merged, centred, mesh))
}

/// Before a mesh is read: it is there ([`crate::scene::builtin::missing_scene_mesh`]) and its
/// extension names a format this build reads.
fn check_mesh_path(scene: &Scene, m: &crate::scene::MeshRef) -> Result<(), LoadError> {
    check_mesh_file(&m.path, Some(scene))
}

/// The one check before a mesh file is read (a scene's mesh, `kdtree build`, `kdtree check`):
/// it is there — else the missing-mesh error, which says where to put Sibenik for `scene`'s
/// built-in Sibenik scenes — and its extension names a format this build reads.
pub fn check_mesh_file(path: &std::path::Path, scene: Option<&Scene>) -> Result<(), LoadError> {
    if crate::input::is_absent(path) {
        return Err(match scene {
            Some(scene) => crate::scene::builtin::missing_scene_mesh(scene, path),
            None => crate::scene::builtin::missing_mesh(path),
        }
        .into());
    }
    crate::mesh::check_format(path)?;
    Ok(())
}

/// After a mesh is read: it has triangles, unless its `[[mesh]]` says `allow_empty = true`.
fn check_not_empty(m: &crate::scene::MeshRef, obj: &ObjMesh) -> Result<(), MeshError> {
    if obj.is_empty() && !m.allow_empty {
        return Err(MeshError::Empty {
            path: m.path.clone(),
        });
    }
    Ok(())
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
