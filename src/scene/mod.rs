//! The scene description: image, camera, render settings, lights, materials and primitives.
//!
//! A [`Scene`] is pure data, as read from a TOML file ([`mod@file`]) or built in ([`builtin`]), in world
//! coordinates: positions (eye, lights, sphere centres, plane points) are kept in f64 as read.
//! Meshes are referred to by path; [`crate::world::World`] loads them, moves everything into the
//! camera-relative f32 render frame and builds the acceleration structure.

pub mod builtin;
pub(crate) mod camera;
pub mod camera_path;
pub mod file;
pub(crate) mod framing;
pub(crate) mod gltf;
pub mod lookat;
pub mod mtl;
pub mod overrides;
pub mod set;

use std::path::PathBuf;

use glam::{DVec3, Vec3};

pub use crate::geometry::triangle::TriangleTest;
pub use camera::Camera;
pub use camera_path::CameraPath;

/// Image size, sampling and output transfer curve (`[image]`).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageSettings {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel (box filter). 1 means one ray through each pixel centre.
    pub samples: u32,
    /// Display gamma applied after averaging: `pixel = round(255 · L^(1/gamma))`.
    pub gamma: f32,
    /// Seed of the stratified jitter; the same seed gives the same image.
    pub seed: u32,
}

impl ImageSettings {
    /// Pixels in the image, `width × height`, computed in `u64` so it never wraps. Scene files keep
    /// it within `u32` (pixel indices are `u32`): see [`file::MAX_IMAGE_SIDE`].
    pub fn pixel_count(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Samples in the image, `width × height × samples`, or `None` where that overflows `u64`
    /// (never within the scene-file limits: at most 2^46).
    pub fn sample_count(&self) -> Option<u64> {
        self.pixel_count().checked_mul(u64::from(self.samples))
    }
}

/// What the film records for each sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RenderMode {
    /// Whitted shading: ambient, Blinn-Phong, shadows, mirror reflections.
    Shaded,
    /// White where the primary ray hits anything, black elsewhere.
    HitMask,
}

/// How secondary-ray origins are moved off the surface they leave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OffsetMethod {
    /// Along the geometric normal by the hit point's conservative error bound (PBR 4th ed.
    /// §6.8): correct at coordinate 0 and at any magnitude. The default.
    ErrorBound,
    /// A fixed world-space epsilon of 1e-4 along the normal: the naive method, kept only so the
    /// error report can show where it breaks.
    FixedEpsilon,
}

/// Which ray/sphere formulation the intersect stage uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SphereTest {
    /// Haines, Günther & Akenine-Möller, Ray Tracing Gems ch. 7. The default.
    Stable,
    /// The textbook `b² − 4ac` quadratic, kept for the error report.
    Naive,
}

/// Numerical variants; the defaults are the robust ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Robustness {
    /// Secondary-ray origin offset.
    pub offset: OffsetMethod,
    /// Ray/sphere test.
    pub sphere: SphereTest,
    /// Ray/triangle test.
    pub triangle: TriangleTest,
}

impl Default for Robustness {
    fn default() -> Self {
        Self {
            offset: OffsetMethod::ErrorBound,
            sphere: SphereTest::Stable,
            triangle: TriangleTest::Watertight,
        }
    }
}

/// Global render settings (`[render]`).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Reflections after the primary ray (SPEC §2's `D`).
    pub max_depth: u32,
    /// Trace shadow rays.
    pub shadows: bool,
    /// Ambient intensity `Ia` per channel.
    pub ambient: Vec3,
    /// Shaded image or hit/miss mask.
    pub mode: RenderMode,
    /// Numerical variants (robust by default).
    pub robustness: Robustness,
}

/// A light (`[[light]]`, SPEC §14): a point, directional or spot light, with or without
/// distance falloff.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// Where it is and where it points.
    pub kind: LightKind,
    /// Intensity `I` per channel.
    pub intensity: Vec3,
    /// Distance falloff (never for a directional light).
    pub falloff: Falloff,
}

/// The kinds of light (SPEC §14), in world coordinates as read (f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// A point light at `position` (`q`), shining every way.
    Point {
        /// Position (world coordinates).
        position: DVec3,
    },
    /// A directional light (the sun): every point is lit along `l = −normalize(direction)`.
    Directional {
        /// The direction the light travels (non-zero, finite; not necessarily unit).
        direction: DVec3,
    },
    /// A spot light at `position` pointing along `direction`: full intensity within the half
    /// angle `(cone − penumbra) / 2` of its axis, none beyond `cone / 2`, smoothstep between.
    Spot {
        /// Position (world coordinates).
        position: DVec3,
        /// The axis (non-zero, finite; not necessarily unit).
        direction: DVec3,
        /// Full cone angle θ in degrees, 0 < θ < 180.
        cone: f64,
        /// Penumbra φ in degrees, 0 ≤ φ ≤ θ.
        penumbra: f64,
    },
}

/// A light's distance falloff (`falloff`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Falloff {
    /// None (`"none"`, the default and SPEC §2's point light).
    #[default]
    None,
    /// `1 / r²` at distance `r` (`"inverse-square"`).
    InverseSquare,
}

impl Light {
    /// A point light at `position` without falloff (SPEC §2's light).
    pub fn point(position: DVec3, intensity: Vec3) -> Light {
        Light {
            kind: LightKind::Point { position },
            intensity,
            falloff: Falloff::None,
        }
    }

    /// The light's position: `None` for a directional light.
    pub fn position(&self) -> Option<DVec3> {
        match self.kind {
            LightKind::Point { position } | LightKind::Spot { position, .. } => Some(position),
            LightKind::Directional { .. } => None,
        }
    }
}

/// A Whitted material: `L = (1 − α)(La + Ld + Ls) + α·Lm`.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name used by primitives in scene files.
    pub name: String,
    /// Ambient reflectance.
    pub ka: Vec3,
    /// Diffuse reflectance.
    pub kd: Vec3,
    /// Specular reflectance; zero means no specular evaluation at all.
    pub ks: Vec3,
    /// Blinn-Phong exponent.
    pub p: f32,
    /// Mirror reflectivity α in [0, 1].
    pub alpha: f32,
}

impl Material {
    /// True when the material has a specular term to evaluate.
    pub(crate) fn has_specular(&self) -> bool {
        self.ks != Vec3::ZERO
    }

    /// True when the material spawns reflection rays.
    pub fn reflects(&self) -> bool {
        self.alpha > 0.0
    }
}

/// A sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct Sphere {
    /// Centre (world coordinates, f64 as read).
    pub center: DVec3,
    /// Radius (> 0).
    pub radius: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// An infinite plane.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    /// Any point on the plane (world coordinates, f64 as read).
    pub point: DVec3,
    /// Unit normal (shading flips it to face the ray).
    pub normal: Vec3,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// Where a mesh's kD tree comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum TreeSource {
    /// Build with the surface area heuristic (the default).
    Sah,
    /// Build with the assignment's midpoint rule.
    Midpoint,
    /// Load a prebuilt tree in SPEC §6's text format.
    File(PathBuf),
}

impl TreeSource {
    /// Parses a `kdtree` value (scene file or `--kdtree`): `sah`, `midpoint`, or a tree file,
    /// resolved by `path` (relative to the scene file, or as given on the command line).
    pub fn parse(value: &str, path: impl FnOnce(&str) -> PathBuf) -> TreeSource {
        match value {
            "sah" => TreeSource::Sah,
            "midpoint" => TreeSource::Midpoint,
            file => TreeSource::File(path(file)),
        }
    }
}

/// A triangle mesh referenced by path.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshRef {
    /// OBJ file (relative paths are already resolved against the scene file).
    pub path: PathBuf,
    /// Index into [`Scene::materials`]: every face's material, or, with [`MeshRef::mtl`], the
    /// material of faces before any `usemtl` (the fallback; unused without one).
    pub material: u32,
    /// Tree to use for this mesh.
    pub kdtree: TreeSource,
    /// Shading normals (SPEC §12).
    pub normals: Normals,
    /// Per-face materials from the OBJ's MTL libraries (`material = "mtl"`).
    pub mtl: Option<mtl::MtlBinding>,
    /// The mesh may have no triangles (`allow_empty = true`); otherwise that is an error.
    pub allow_empty: bool,
}

/// Which normal shades a mesh (SPEC §12).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Normals {
    /// The triangle's geometric normal (faceted). The default.
    #[default]
    Geometric,
    /// The OBJ's `vn` (or area-weighted vertex normals) interpolated with the hit's barycentric
    /// coordinates, on the facing side; shadow rays still start from the geometric surface.
    Vertex,
}

/// A complete scene description.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Display name (built-in name or file path).
    pub name: String,
    /// Image settings.
    pub image: ImageSettings,
    /// Camera (with a camera path: the first key's, or the frame's after [`Scene::at_frame`]).
    pub camera: Camera,
    /// Look-at keys of an animated camera (`[[camera.key]]`), if any.
    pub camera_path: Option<CameraPath>,
    /// Render settings.
    pub render: RenderSettings,
    /// Lights, in file order.
    pub lights: Vec<Light>,
    /// Materials, referenced by index.
    pub materials: Vec<Material>,
    /// Spheres.
    pub spheres: Vec<Sphere>,
    /// Planes.
    pub planes: Vec<Plane>,
    /// Triangle meshes.
    pub meshes: Vec<MeshRef>,
}

impl Scene {
    /// The scene with every position moved by `delta` (eye, camera path, lights, sphere
    /// centres, plane points; mesh files are not rewritten), in f64.
    pub fn translated(&self, delta: DVec3) -> Scene {
        let mut s = self.clone();
        s.name = format!("{} moved by {delta}", self.name);
        s.camera.eye += delta;
        s.camera_path = s.camera_path.as_ref().map(|p| p.translated(delta));
        for l in &mut s.lights {
            if let LightKind::Point { position } | LightKind::Spot { position, .. } = &mut l.kind {
                *position += delta;
            }
        }
        for sp in &mut s.spheres {
            sp.center += delta;
        }
        for p in &mut s.planes {
            p.point += delta;
        }
        s
    }

    /// True when some material reflects and the depth limit allows a reflection.
    pub fn needs_reflections(&self) -> bool {
        self.render.mode == RenderMode::Shaded
            && self.render.max_depth > 0
            && self.used_materials().any(Material::reflects)
    }

    /// True when shadow rays are traced: shadows on, at least one light, shaded mode.
    pub(crate) fn needs_shadows(&self) -> bool {
        self.render.mode == RenderMode::Shaded && self.render.shadows && !self.lights.is_empty()
    }

    /// True when some used material has a specular term and there is a light.
    pub(crate) fn needs_specular(&self) -> bool {
        self.render.mode == RenderMode::Shaded
            && !self.lights.is_empty()
            && self.used_materials().any(Material::has_specular)
    }

    /// Materials referenced by at least one primitive.
    pub(crate) fn used_materials(&self) -> impl Iterator<Item = &Material> {
        let used = |m: u32| {
            self.spheres.iter().any(|s| s.material == m)
                || self.planes.iter().any(|p| p.material == m)
                || self.meshes.iter().any(|x| match &x.mtl {
                    Some(b) => b.used.contains(&m),
                    None => x.material == m,
                })
        };
        self.materials
            .iter()
            .enumerate()
            .filter(move |(i, _)| used(*i as u32))
            .map(|(_, m)| m)
    }
}

/// What the shade stage evaluates, as a scene implies it: the ambient intensity, and whether
/// direct light goes through shadow rays and the specular term is evaluated at all.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeSettings {
    /// Ambient intensity `Ia`.
    pub ambient: Vec3,
    /// Defer the direct terms to shadow rays.
    pub shadows: bool,
    /// Evaluate the specular term at all (false when no material has `ks > 0`).
    pub specular: bool,
}

impl ShadeSettings {
    /// The settings a scene implies.
    pub fn for_scene(scene: &Scene) -> ShadeSettings {
        ShadeSettings {
            ambient: scene.render.ambient,
            shadows: scene.needs_shadows(),
            specular: scene.needs_specular(),
        }
    }
}
