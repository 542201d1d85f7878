//! Scene files (SPEC §8): TOML in, a validated [`Scene`] out.
//!
//! Every error names the file, the 1-based line and the key. Unknown keys are errors, numbers must
//! be finite and fit an `f32`, directions must be non-zero, radii positive, materials defined.
//! Relative paths are resolved against the scene file's directory. `[camera]` is the explicit
//! camera, the look-at form ([`super::lookat`]), a camera path of `[[camera.key]]` entries or
//! an orbit (`[camera.orbit]`, [`super::camera_path`]), never a mix.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use serde::Deserialize;
use toml::Spanned;

use super::camera_path::{CameraKey, Interpolation, Orbit};
use super::lookat::LookAt;
use super::{
    Camera, CameraPath, Falloff, ImageSettings, Light, LightKind, Material, MeshRef, Normals,
    OffsetMethod, Plane, RenderMode, RenderSettings, Robustness, Scene, Sphere, SphereTest,
    TreeSource, TriangleTest,
};
use crate::error::{SceneError, short};

/// Largest accepted image side, samples per pixel and depth.
pub const MAX_IMAGE_SIDE: u32 = 1 << 15;
/// Largest accepted samples per pixel.
pub const MAX_SAMPLES: u32 = 1 << 16;
/// Largest accepted reflection depth.
pub(crate) const MAX_DEPTH: u32 = 64;

// Every product of the limits fits the type the renderer keeps it in, so validating each value
// validates the products: pixels (`width × height`) index as `u32`, samples (`× samples`) count
// as `u64`. Raising a limit past these fails to compile rather than wrapping at run time.
const _: () = assert!(MAX_IMAGE_SIDE as u64 * MAX_IMAGE_SIDE as u64 <= u32::MAX as u64);
const _: () = assert!(
    (MAX_IMAGE_SIDE as u128 * MAX_IMAGE_SIDE as u128 * MAX_SAMPLES as u128) <= u64::MAX as u128
);

type V3 = Spanned<Arr3>;

/// Exactly three numbers: a longer or shorter array is an error at its line, never truncated.
#[derive(Clone, Copy, Debug)]
struct Arr3([f64; 3]);

impl<'de> Deserialize<'de> for Arr3 {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Arr3, D::Error> {
        use serde::de::{Error, IgnoredAny, SeqAccess, Visitor};
        struct Three;
        impl<'de> Visitor<'de> for Three {
            type Value = Arr3;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an array of 3 numbers")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Arr3, A::Error> {
                let mut out = [0.0; 3];
                for (i, o) in out.iter_mut().enumerate() {
                    *o = seq
                        .next_element::<f64>()?
                        .ok_or_else(|| A::Error::invalid_length(i, &self))?;
                }
                let mut n = 3;
                while seq.next_element::<IgnoredAny>()?.is_some() {
                    n += 1;
                }
                if n > 3 {
                    return Err(A::Error::invalid_length(n, &self));
                }
                Ok(Arr3(out))
            }
        }
        d.deserialize_seq(Three)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    image: Option<RawImage>,
    camera: Spanned<RawCamera>,
    render: Option<RawRender>,
    #[serde(default)]
    light: Vec<Spanned<RawLight>>,
    #[serde(default)]
    material: BTreeMap<String, Spanned<RawMaterial>>,
    #[serde(default)]
    plane: Vec<RawPlane>,
    #[serde(default)]
    sphere: Vec<RawSphere>,
    #[serde(default)]
    mesh: Vec<RawMesh>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawImage {
    width: Option<Spanned<i64>>,
    height: Option<Spanned<i64>>,
    samples: Option<Spanned<i64>>,
    gamma: Option<Spanned<f64>>,
    seed: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWindow {
    l: Spanned<f64>,
    r: Spanned<f64>,
    b: Spanned<f64>,
    t: Spanned<f64>,
}

/// `[camera]`: the explicit form (`eye u v w window distance`), the look-at form
/// (`eye look_at up fov_y`, SPEC §10), or a camera path (`[[camera.key]]` only).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCamera {
    eye: Option<V3>,
    u: Option<V3>,
    v: Option<V3>,
    w: Option<V3>,
    window: Option<Spanned<RawWindow>>,
    distance: Option<Spanned<f64>>,
    look_at: Option<V3>,
    up: Option<V3>,
    fov_y: Option<Spanned<f64>>,
    key: Option<Vec<Spanned<RawKey>>>,
    interpolation: Option<Spanned<String>>,
    orbit: Option<Spanned<RawOrbit>>,
    frame: Option<Spanned<String>>,
    /// A direction (`frame = "auto"`) or `"gltf"` (the first glTF mesh's camera).
    from: Option<Spanned<toml::Value>>,
}

/// The keys of `[camera]`'s explicit form besides `eye`.
const EXPLICIT_KEYS: [&str; 5] = ["u", "v", "w", "window", "distance"];

/// The keys of `[camera]`'s look-at form besides `eye`.
const LOOK_AT_KEYS: [&str; 3] = ["look_at", "up", "fov_y"];

impl RawCamera {
    /// Every key of `[camera]` with where it was given (`None`: absent): the one list the
    /// checks of which keys go together read. `[[camera.key]]` entries have no span of their
    /// own, so `key_span` stands for them.
    fn keys_given(&self, key_span: Range<usize>) -> [(&'static str, Option<Range<usize>>); 14] {
        [
            ("eye", self.eye.as_ref().map(Spanned::span)),
            ("u", self.u.as_ref().map(Spanned::span)),
            ("v", self.v.as_ref().map(Spanned::span)),
            ("w", self.w.as_ref().map(Spanned::span)),
            ("window", self.window.as_ref().map(Spanned::span)),
            ("distance", self.distance.as_ref().map(Spanned::span)),
            ("look_at", self.look_at.as_ref().map(Spanned::span)),
            ("up", self.up.as_ref().map(Spanned::span)),
            ("fov_y", self.fov_y.as_ref().map(Spanned::span)),
            ("key", self.key.as_ref().map(|_| key_span)),
            (
                "interpolation",
                self.interpolation.as_ref().map(Spanned::span),
            ),
            ("orbit", self.orbit.as_ref().map(Spanned::span)),
            ("frame", self.frame.as_ref().map(Spanned::span)),
            ("from", self.from.as_ref().map(Spanned::span)),
        ]
    }

    /// The first of `among` (in its order) that is given, with its span.
    fn first_given(
        &self,
        among: &[&'static str],
        key_span: Range<usize>,
    ) -> Option<(&'static str, Range<usize>)> {
        let given = self.keys_given(key_span);
        among.iter().find_map(|k| {
            given
                .iter()
                .find(|(name, _)| name == k)
                .and_then(|(name, sp)| sp.clone().map(|sp| (*name, sp)))
        })
    }
}

/// The first of `meshes` that is a glTF file: where `from = "gltf"` and `lights_from = "gltf"`
/// read the camera and the lights.
fn first_gltf(meshes: &[MeshRef]) -> Option<&MeshRef> {
    meshes.iter().find(|m| {
        matches!(
            crate::mesh::check_format(&m.path),
            Ok(crate::mesh::Format::Gltf | crate::mesh::Format::Glb)
        )
    })
}

/// `[camera.orbit]`: the eye circles `look_at` about `up` (SPEC §10).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOrbit {
    look_at: V3,
    eye: V3,
    up: V3,
    fov_y: Spanned<f64>,
    frames: Spanned<i64>,
    turns: Option<Spanned<f64>>,
}

/// One `[[camera.key]]` of a camera path.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawKey {
    frame: Spanned<i64>,
    eye: V3,
    look_at: V3,
    up: V3,
    fov_y: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRender {
    max_depth: Option<Spanned<i64>>,
    shadows: Option<bool>,
    ambient: Option<V3>,
    mode: Option<Spanned<String>>,
    offset: Option<Spanned<String>>,
    sphere_test: Option<Spanned<String>>,
    triangle_test: Option<Spanned<String>>,
    /// `"gltf"`: add the first glTF mesh's `KHR_lights_punctual` lights (SPEC §15).
    lights_from: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    position: Option<V3>,
    intensity: Option<V3>,
    falloff: Option<Spanned<String>>,
    direction: Option<V3>,
    cone: Option<Spanned<f64>>,
    penumbra: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    ka: Option<V3>,
    kd: Option<V3>,
    ks: Option<V3>,
    p: Option<Spanned<f64>>,
    alpha: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlane {
    point: V3,
    normal: V3,
    material: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSphere {
    center: V3,
    radius: Spanned<f64>,
    material: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMesh {
    path: Spanned<String>,
    material: Spanned<String>,
    fallback_material: Option<Spanned<String>>,
    normals: Option<Spanned<String>>,
    kdtree: Option<Spanned<String>>,
    allow_empty: Option<bool>,
}

/// Reads and validates the scene file at `path` (a regular file of at most
/// `crate::input::SCENE_CAP` bytes).
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    parse(&read(path)?, path)
}

/// The text of the scene file at `path` (a regular file within the scene-file size cap).
pub fn read(path: &Path) -> Result<String, SceneError> {
    crate::input::read_text_capped(path, crate::input::SCENE_CAP, "scene files").map_err(|source| {
        SceneError::Io {
            file: path.to_path_buf(),
            source,
        }
    })
}

/// Parses scene text; `path` names the file in errors and anchors relative paths.
pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
    let cx = Cx { text, path };
    let raw: RawScene = toml::from_str(text).map_err(|e| cx.toml_error(&e))?;
    cx.scene(raw)
}

/// Error context: the source text and its path.
struct Cx<'a> {
    text: &'a str,
    path: &'a Path,
}

impl Cx<'_> {
    fn line(&self, span: Range<usize>) -> usize {
        let end = span.start.min(self.text.len());
        1 + self.text.as_bytes()[..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    }

    fn err(
        &self,
        span: Range<usize>,
        key: impl Into<String>,
        message: impl Into<String>,
    ) -> SceneError {
        SceneError::Invalid {
            file: self.path.to_path_buf(),
            line: self.line(span),
            key: key.into(),
            message: message.into(),
        }
    }

    fn toml_error(&self, e: &toml::de::Error) -> SceneError {
        let span = e.span().unwrap_or(0..0);
        // The key is the start of the offending line up to `=`, or the table header.
        let line_text = self.text[..span.start.min(self.text.len())]
            .rsplit('\n')
            .next()
            .unwrap_or("")
            .to_owned()
            + self.text[span.start.min(self.text.len())..]
                .split('\n')
                .next()
                .unwrap_or("");
        let key = line_text
            .split('=')
            .next()
            .unwrap_or("")
            .trim()
            .trim_matches(|c| c == '[' || c == ']')
            .to_owned();
        let key = if key.is_empty() {
            "(document)".into()
        } else {
            key
        };
        self.err(span, key, e.message().trim().to_owned())
    }

    fn float(&self, v: &Spanned<f64>, key: &str) -> Result<f32, SceneError> {
        let x = *v.get_ref();
        if !x.is_finite() {
            return Err(self.err(v.span(), key, format!("{x} is not a finite number")));
        }
        if x.abs() > f32::MAX as f64 {
            let x = short(x);
            return Err(self.err(v.span(), key, format!("{x} does not fit a 32-bit float")));
        }
        Ok(x as f32)
    }

    /// A finite f64 (look-at fields are computed in f64).
    fn finite(&self, v: &Spanned<f64>, key: &str) -> Result<f64, SceneError> {
        self.float(v, key).map(|_| *v.get_ref())
    }

    /// A finite 3-vector kept in f64 (each component must still fit an f32).
    fn dvec3(&self, v: &V3, key: &str) -> Result<DVec3, SceneError> {
        self.vec3(v, key).map(|_| DVec3::from(v.get_ref().0))
    }

    fn vec3(&self, v: &V3, key: &str) -> Result<Vec3, SceneError> {
        let a = v.get_ref().0;
        let mut out = [0.0f32; 3];
        for (o, &x) in out.iter_mut().zip(&a) {
            if !x.is_finite() {
                return Err(self.err(v.span(), key, format!("{x} is not a finite number")));
            }
            if x.abs() > f32::MAX as f64 {
                let x = short(x);
                return Err(self.err(v.span(), key, format!("{x} does not fit a 32-bit float")));
            }
            *o = x as f32;
        }
        Ok(Vec3::from(out))
    }

    /// A position in world coordinates, kept in f64 as written (the render frame is made from
    /// it by [`crate::world::World`]).
    fn position(&self, v: &V3, key: &str) -> Result<DVec3, SceneError> {
        self.vec3(v, key)?; // the same checks: finite, within f32 range
        Ok(DVec3::from_array(v.get_ref().0))
    }

    fn direction(&self, v: &V3, key: &str) -> Result<Vec3, SceneError> {
        let d = self.vec3(v, key)?;
        if d == Vec3::ZERO || !d.length_squared().is_finite() {
            return Err(self.err(
                v.span(),
                key,
                "must be a non-zero vector of moderate length",
            ));
        }
        Ok(d)
    }

    /// A unit direction from any non-zero finite vector. A vector whose f32 square length is a
    /// normal number is normalised in f32 as always (the same bits as before); a tiny or huge one
    /// is scaled by its largest component and normalised in f64 first, so it neither underflows
    /// to a zero length nor overflows to an infinite one.
    fn unit(&self, v: &V3, key: &str) -> Result<Vec3, SceneError> {
        let d = self.vec3(v, key)?;
        if d == Vec3::ZERO {
            return Err(self.err(v.span(), key, "must be a non-zero vector"));
        }
        let l2 = d.length_squared();
        if l2.is_normal() && l2.is_finite() {
            return Ok(d.normalize());
        }
        let d = d.as_dvec3();
        Ok((d / d.abs().max_element()).normalize().as_vec3())
    }

    fn colour(&self, v: Option<&V3>, key: &str, default: Vec3) -> Result<Vec3, SceneError> {
        let Some(v) = v else { return Ok(default) };
        let c = self.vec3(v, key)?;
        if c.min_element() < 0.0 {
            return Err(self.err(v.span(), key, "components must be ≥ 0"));
        }
        Ok(c)
    }

    /// `[[light]]` number `i` (SPEC §14): `position` alone is a point light, `direction` alone a
    /// directional one, both with `cone` (and optionally `penumbra`) a spot light; any other
    /// combination is an error naming the key that does not belong.
    fn light(&self, l: &Spanned<RawLight>, i: usize) -> Result<Light, SceneError> {
        let key = |k: &str| format!("light[{i}].{k}");
        let r = l.get_ref();
        let intensity = self.colour(r.intensity.as_ref(), &key("intensity"), Vec3::ONE)?;
        let falloff = match &r.falloff {
            Some(f) => self.choice(
                f,
                &key("falloff"),
                &[
                    ("none", Falloff::None),
                    ("inverse-square", Falloff::InverseSquare),
                ],
            )?,
            None => Falloff::None,
        };
        let position = match &r.position {
            Some(p) => Some(self.position(p, &key("position"))?),
            None => None,
        };
        let direction = match &r.direction {
            Some(d) => {
                let v = self.dvec3(d, &key("direction"))?;
                if v == DVec3::ZERO {
                    return Err(self.err(d.span(), key("direction"), "must be a non-zero vector"));
                }
                Some((v, d.span()))
            }
            None => None,
        };
        let degrees = |v: &Spanned<f64>, k: &str| self.finite(v, &key(k));
        let kind = match (position, direction, &r.cone) {
            (Some(position), None, None) => LightKind::Point { position },
            (None, Some((direction, _)), None) => LightKind::Directional { direction },
            (Some(position), Some((direction, _)), Some(c)) => {
                let cone = degrees(c, "cone")?;
                if !(cone > 0.0 && cone < 180.0) {
                    let msg = format!(
                        "{} must be an angle in degrees with 0 < cone < 180",
                        short(cone)
                    );
                    return Err(self.err(c.span(), key("cone"), msg));
                }
                let penumbra = match &r.penumbra {
                    Some(p) => {
                        let x = degrees(p, "penumbra")?;
                        if !(0.0..=cone).contains(&x) {
                            let msg = format!(
                                "{} must be an angle in degrees with 0 ≤ penumbra ≤ cone ({})",
                                short(x),
                                short(cone)
                            );
                            return Err(self.err(p.span(), key("penumbra"), msg));
                        }
                        x
                    }
                    None => 0.0,
                };
                LightKind::Spot {
                    position,
                    direction,
                    cone,
                    penumbra,
                }
            }
            (None, None, _) => {
                return Err(self.err(
                    l.span(),
                    key("position"),
                    "a light needs `position` (a point or spot light) or `direction` (a directional light)",
                ));
            }
            (Some(_), Some((_, span)), None) => {
                return Err(self.err(
                    span,
                    key("direction"),
                    "a light with both `position` and `direction` is a spot light and needs `cone`",
                ));
            }
            (None, Some(_), Some(c)) => {
                return Err(self.err(
                    c.span(),
                    key("cone"),
                    "a spot light needs `position` as well as `direction`",
                ));
            }
            (Some(_), None, Some(c)) => {
                return Err(self.err(
                    c.span(),
                    key("cone"),
                    "a spot light needs `direction` (its axis) as well as `position`",
                ));
            }
        };
        if let (Some(p), None) = (&r.penumbra, &r.cone) {
            return Err(self.err(
                p.span(),
                key("penumbra"),
                "only a spot light (`position`, `direction` and `cone`) has a penumbra",
            ));
        }
        if let (LightKind::Directional { .. }, Falloff::InverseSquare, Some(f)) =
            (&kind, falloff, &r.falloff)
        {
            return Err(self.err(
                f.span(),
                key("falloff"),
                "a directional light has no falloff (it is infinitely far)",
            ));
        }
        Ok(Light {
            kind,
            intensity,
            falloff,
        })
    }

    fn int(&self, v: &Spanned<i64>, key: &str, lo: i64, hi: i64) -> Result<u32, SceneError> {
        let x = *v.get_ref();
        if x < lo || x > hi {
            return Err(self.err(v.span(), key, format!("{x} is out of range {lo}..={hi}")));
        }
        Ok(x as u32)
    }

    fn choice<T: Copy>(
        &self,
        v: &Spanned<String>,
        key: &str,
        options: &[(&str, T)],
    ) -> Result<T, SceneError> {
        options
            .iter()
            .find(|(name, _)| name == v.get_ref())
            .map(|&(_, t)| t)
            .ok_or_else(|| {
                let names: Vec<_> = options.iter().map(|(n, _)| format!("{n:?}")).collect();
                self.err(
                    v.span(),
                    key,
                    format!(
                        "unknown value {:?}; expected one of {}",
                        v.get_ref(),
                        names.join(", ")
                    ),
                )
            })
    }

    fn relative(&self, p: &str) -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.path.parent().unwrap_or(Path::new("")).join(p)
        }
    }

    fn scene(&self, raw: RawScene) -> Result<Scene, SceneError> {
        let image = self.image(raw.image)?;
        let from_gltf = self.camera_from_gltf(&raw.camera)?;
        let auto = match from_gltf {
            Some(_) => None,
            None => self.auto_frame(&raw.camera)?,
        };
        // A framed camera (or a glTF file's) is made once the geometry is known, below.
        let (camera, camera_path) = match (auto, &from_gltf) {
            (Some(_), _) | (_, Some(_)) => (None, None),
            (None, None) => {
                let (camera, path) = self.camera(&raw.camera, &image)?;
                (Some(camera), path)
            }
        };
        let lights_from = raw.render.as_ref().and_then(|r| r.lights_from.clone());
        let render = self.render(raw.render)?;

        let mut lights = Vec::with_capacity(raw.light.len());
        for (i, l) in raw.light.iter().enumerate() {
            lights.push(self.light(l, i)?);
        }

        // Materials in declaration order, so indices follow the file.
        let mut declared: Vec<_> = raw.material.iter().collect();
        declared.sort_by_key(|(_, m)| m.span().start);
        let mut materials = Vec::with_capacity(declared.len());
        for (name, m) in declared {
            let key = |k: &str| format!("material.{name}.{k}");
            let mr = m.get_ref();
            let p = match &mr.p {
                Some(p) => {
                    let x = self.float(p, &key("p"))?;
                    if x < 0.0 {
                        return Err(self.err(p.span(), key("p"), "must be ≥ 0"));
                    }
                    x
                }
                None => 0.0,
            };
            let alpha = match &mr.alpha {
                Some(a) => {
                    let x = self.float(a, &key("alpha"))?;
                    if !(0.0..=1.0).contains(&x) {
                        return Err(self.err(a.span(), key("alpha"), "must be in [0, 1]"));
                    }
                    x
                }
                None => 0.0,
            };
            materials.push(Material {
                name: name.clone(),
                ka: self.colour(mr.ka.as_ref(), &key("ka"), Vec3::ZERO)?,
                kd: self.colour(mr.kd.as_ref(), &key("kd"), Vec3::ZERO)?,
                ks: self.colour(mr.ks.as_ref(), &key("ks"), Vec3::ZERO)?,
                p,
                alpha,
            });
        }
        let find = |m: &Spanned<String>, key: String| -> Result<u32, SceneError> {
            materials
                .iter()
                .position(|x| &x.name == m.get_ref())
                .map(|i| i as u32)
                .ok_or_else(|| {
                    self.err(
                        m.span(),
                        key,
                        format!("undefined material {:?}", m.get_ref()),
                    )
                })
        };

        let mut planes = Vec::with_capacity(raw.plane.len());
        for (i, p) in raw.plane.iter().enumerate() {
            planes.push(Plane {
                point: self.position(&p.point, &format!("plane[{i}].point"))?,
                normal: self.unit(&p.normal, &format!("plane[{i}].normal"))?,
                material: find(&p.material, format!("plane[{i}].material"))?,
            });
        }

        let mut spheres = Vec::with_capacity(raw.sphere.len());
        for (i, s) in raw.sphere.iter().enumerate() {
            let key = format!("sphere[{i}].radius");
            let radius = self.float(&s.radius, &key)?;
            if radius <= 0.0 {
                return Err(self.err(
                    s.radius.span(),
                    key,
                    format!("{} must be > 0", short(radius as f64)),
                ));
            }
            spheres.push(Sphere {
                center: self.position(&s.center, &format!("sphere[{i}].center"))?,
                radius,
                material: find(&s.material, format!("sphere[{i}].material"))?,
            });
        }

        let mut meshes = Vec::with_capacity(raw.mesh.len());
        // Materials read from meshes' MTL libraries, appended after the scene's own.
        let mut library: Vec<Material> = vec![];
        for (i, m) in raw.mesh.iter().enumerate() {
            let kdtree = m.kdtree.as_ref().map_or(TreeSource::Sah, |k| {
                TreeSource::parse(k.get_ref(), |file| self.relative(file))
            });
            let path = self.relative(m.path.get_ref());
            let fallback = m
                .fallback_material
                .as_ref()
                .map(|f| find(f, format!("mesh[{i}].fallback_material")))
                .transpose()?;
            let format = crate::mesh::check_format(&path)
                .map_err(|e| self.err(m.path.span(), format!("mesh[{i}].path"), e.to_string()))?;
            let from_file = match (m.material.get_ref().as_str(), format) {
                ("mtl", crate::mesh::Format::Obj)
                | ("gltf", crate::mesh::Format::Gltf)
                | ("gltf", crate::mesh::Format::Glb) => true,
                (name @ ("mtl" | "gltf"), f) => {
                    return Err(self.err(
                        m.material.span(),
                        format!("mesh[{i}].material"),
                        format!(
                            "material = {name:?} reads the materials of {} files; {} is {} {} \
                             file (use a scene material{})",
                            if name == "mtl" { "OBJ (MTL)" } else { "glTF" },
                            path.display(),
                            if f == crate::mesh::Format::Obj {
                                "an"
                            } else {
                                "a"
                            },
                            f.name(),
                            if matches!(f, crate::mesh::Format::Gltf | crate::mesh::Format::Glb) {
                                ", or \"gltf\""
                            } else if f == crate::mesh::Format::Obj {
                                ", or \"mtl\""
                            } else {
                                ""
                            }
                        ),
                    ));
                }
                _ => false,
            };
            let (material, mtl) = if from_file {
                if !path.exists() {
                    return Err(self.err(
                        m.path.span(),
                        format!("mesh[{i}].path"),
                        format!(
                            "{} not found (material = {:?} reads it now)",
                            path.display(),
                            m.material.get_ref()
                        ),
                    ));
                }
                let base = (materials.len() + library.len()) as u32;
                let binding = if format == crate::mesh::Format::Obj {
                    super::mtl::bind(&path, fallback, base, &mut library)?
                } else {
                    super::mtl::bind_gltf(&path, fallback, base, &mut library).map_err(|e| {
                        self.err(
                            m.material.span(),
                            format!("mesh[{i}].material"),
                            crate::error::chain(&e),
                        )
                    })?
                };
                (fallback.unwrap_or(0), Some(binding))
            } else {
                if let Some(f) = &m.fallback_material {
                    return Err(self.err(
                        f.span(),
                        format!("mesh[{i}].fallback_material"),
                        "only meaningful with material = \"mtl\" or \"gltf\"",
                    ));
                }
                (find(&m.material, format!("mesh[{i}].material"))?, None)
            };
            let normals = match &m.normals {
                None => Normals::Geometric,
                Some(n) => self.choice(
                    n,
                    &format!("mesh[{i}].normals"),
                    &[
                        ("geometric", Normals::Geometric),
                        ("vertex", Normals::Vertex),
                    ],
                )?,
            };
            meshes.push(MeshRef {
                path,
                material,
                kdtree,
                normals,
                mtl,
                allow_empty: m.allow_empty.unwrap_or(false),
            });
        }

        materials.extend(library);
        if let Some(from) = &lights_from {
            lights.extend(self.gltf_lights(from, &meshes)?);
        }
        let camera = match (auto, camera) {
            (_, Some(camera)) => camera,
            (None, None) if from_gltf.is_some() => {
                let span = from_gltf.expect("checked");
                self.gltf_camera(span, &image, &meshes)?
            }
            (view, None) => {
                let view = view.expect("a camera is framed or given");
                self.framed(&raw.camera, view, &image, &spheres, &meshes)?
            }
        };
        Ok(Scene {
            name: self.path.display().to_string(),
            image,
            camera,
            camera_path,
            render,
            lights,
            materials,
            spheres,
            planes,
            meshes,
        })
    }

    fn image(&self, raw: Option<RawImage>) -> Result<ImageSettings, SceneError> {
        let mut image = ImageSettings {
            width: 512,
            height: 512,
            samples: 1,
            gamma: 2.2,
            seed: 0,
        };
        let Some(raw) = raw else { return Ok(image) };
        let side = MAX_IMAGE_SIDE as i64;
        if let Some(w) = &raw.width {
            image.width = self.int(w, "image.width", 1, side)?;
        }
        if let Some(h) = &raw.height {
            image.height = self.int(h, "image.height", 1, side)?;
        }
        if let Some(s) = &raw.samples {
            image.samples = self.int(s, "image.samples", 1, MAX_SAMPLES as i64)?;
        }
        if let Some(s) = &raw.seed {
            image.seed = self.int(s, "image.seed", 0, u32::MAX as i64)?;
        }
        if let Some(g) = &raw.gamma {
            let x = self.float(g, "image.gamma")?;
            if x <= 0.0 {
                return Err(self.err(g.span(), "image.gamma", "must be > 0"));
            }
            image.gamma = x;
        }
        Ok(image)
    }

    fn camera(
        &self,
        raw: &Spanned<RawCamera>,
        image: &ImageSettings,
    ) -> Result<(Camera, Option<CameraPath>), SceneError> {
        let c = raw.get_ref();
        let span = |v: Option<Range<usize>>| v.unwrap_or(raw.span());
        let given = |among: &[&'static str], key_span: Range<usize>| c.first_given(among, key_span);
        if let Some(i) = &c.interpolation
            && c.key.is_none()
        {
            return Err(self.err(
                i.span(),
                "camera.interpolation",
                "only meaningful with [[camera.key]] entries",
            ));
        }
        if let Some(orbit) = &c.orbit {
            let views = [&["key", "eye"][..], &EXPLICIT_KEYS, &LOOK_AT_KEYS].concat();
            if let Some((k, sp)) = given(&views, orbit.span()) {
                return Err(self.err(
                    sp,
                    format!("camera.{k}"),
                    "cannot be combined with [camera.orbit]: the orbit gives every view",
                ));
            }
            return self.orbit(orbit, image);
        }
        if let Some(keys) = &c.key {
            let views = [&["eye"][..], &EXPLICIT_KEYS, &LOOK_AT_KEYS].concat();
            if let Some((k, sp)) = given(&views, raw.span()) {
                return Err(self.err(
                    sp,
                    format!("camera.{k}"),
                    "cannot be combined with [[camera.key]]: a camera path gives every view",
                ));
            }
            let interpolation = match &c.interpolation {
                None => Interpolation::Linear,
                Some(i) => self.choice(
                    i,
                    "camera.interpolation",
                    &[
                        ("linear", Interpolation::Linear),
                        ("catmull-rom", Interpolation::CatmullRom),
                    ],
                )?,
            };
            let path = self.camera_path(keys, raw.span())?;
            let camera = self.look_at_camera(&path[0].view, image, "camera.key[0]", |k| {
                let key = keys[0].get_ref();
                match k {
                    "look_at" => key.look_at.span(),
                    "up" => key.up.span(),
                    _ => key.fov_y.span(),
                }
            })?;
            let path = CameraPath::Keys {
                keys: path,
                interpolation,
            };
            return Ok((camera, Some(path)));
        }
        if let Some((k, sp)) = given(&LOOK_AT_KEYS, raw.span()) {
            if let Some((e, esp)) = given(&EXPLICIT_KEYS, raw.span()) {
                let (key, sp) = if esp.start > sp.start {
                    (e, esp)
                } else {
                    (k, sp)
                };
                return Err(self.err(
                    sp,
                    format!("camera.{key}"),
                    "the look-at form (eye, look_at, up, fov_y) cannot be combined with the \
                     explicit form (eye, u, v, w, window, distance)",
                ));
            }
            let missing = |key: &str| {
                self.err(
                    raw.span(),
                    format!("camera.{key}"),
                    "missing: a look-at camera needs eye, look_at, up and fov_y",
                )
            };
            let view = LookAt {
                eye: self.dvec3(c.eye.as_ref().ok_or_else(|| missing("eye"))?, "camera.eye")?,
                look_at: self.dvec3(
                    c.look_at.as_ref().ok_or_else(|| missing("look_at"))?,
                    "camera.look_at",
                )?,
                up: self.dvec3(c.up.as_ref().ok_or_else(|| missing("up"))?, "camera.up")?,
                fov_y: self.finite(
                    c.fov_y.as_ref().ok_or_else(|| missing("fov_y"))?,
                    "camera.fov_y",
                )?,
            };
            let camera = self.look_at_camera(&view, image, "camera", |k| {
                span(match k {
                    "look_at" => c.look_at.as_ref().map(Spanned::span),
                    "up" => c.up.as_ref().map(Spanned::span),
                    _ => c.fov_y.as_ref().map(Spanned::span),
                })
            })?;
            return Ok((camera, None));
        }
        let missing = |key: &str| {
            self.err(
                raw.span(),
                format!("camera.{key}"),
                "missing: an explicit camera needs eye, u, v, w, window and distance \
                 (or use the look-at form: eye, look_at, up, fov_y)",
            )
        };
        let (Some(eye), Some(u), Some(v), Some(w), Some(window), Some(distance)) =
            (&c.eye, &c.u, &c.v, &c.w, &c.window, &c.distance)
        else {
            let given = c.keys_given(raw.span());
            let absent = ["eye"]
                .iter()
                .chain(&EXPLICIT_KEYS)
                .find(|k| given.iter().any(|(name, sp)| name == *k && sp.is_none()));
            return Err(missing(absent.copied().unwrap_or("eye")));
        };
        let win = window.get_ref();
        let cam = Camera {
            eye: self.position(eye, "camera.eye")?,
            u: self.direction(u, "camera.u")?,
            v: self.direction(v, "camera.v")?,
            w: self.direction(w, "camera.w")?,
            l: self.float(&win.l, "camera.window.l")?,
            r: self.float(&win.r, "camera.window.r")?,
            b: self.float(&win.b, "camera.window.b")?,
            t: self.float(&win.t, "camera.window.t")?,
            d: self.float(distance, "camera.distance")?,
        };
        if cam.l >= cam.r || cam.b >= cam.t {
            return Err(self.err(window.span(), "camera.window", "needs l < r and b < t"));
        }
        if cam.d <= 0.0 {
            return Err(self.err(distance.span(), "camera.distance", "must be > 0"));
        }
        Ok((cam, None))
    }

    /// The camera of a look-at view; a degenerate view is an error at the field `span_of` names.
    fn look_at_camera(
        &self,
        view: &LookAt,
        image: &ImageSettings,
        prefix: &str,
        span_of: impl Fn(&str) -> Range<usize>,
    ) -> Result<Camera, SceneError> {
        view.camera(image.width, image.height).map_err(|e| {
            self.err(
                span_of(e.key()),
                format!("{prefix}.{}", e.key()),
                e.to_string(),
            )
        })
    }

    /// `[camera] frame = "auto"` (SPEC §16): the view direction and field of view it asks for
    /// (`from`, default (1, 0.6, 1); `fov_y`, default 40), or `None` for every other camera.
    /// `from` without `frame`, or `frame` with any key but `from` and `fov_y`, is an error.
    fn auto_frame(&self, raw: &Spanned<RawCamera>) -> Result<Option<(DVec3, f64)>, SceneError> {
        let c = raw.get_ref();
        let Some(frame) = &c.frame else {
            if let Some(from) = &c.from {
                return Err(self.err(
                    from.span(),
                    "camera.from",
                    "only meaningful with frame = \"auto\"",
                ));
            }
            return Ok(None);
        };
        if frame.get_ref() != "auto" {
            return Err(self.err(
                frame.span(),
                "camera.frame",
                format!("unknown value {:?}; expected \"auto\"", frame.get_ref()),
            ));
        }
        let others = [&["eye"][..], &EXPLICIT_KEYS, &["look_at", "up"]].concat();
        let others = [others, vec!["interpolation", "orbit", "key"]].concat();
        if let Some((k, sp)) = c.first_given(&others, frame.span()) {
            return Err(self.err(
                sp,
                format!("camera.{k}"),
                "cannot be combined with frame = \"auto\" (only from and fov_y)",
            ));
        }
        let from = match &c.from {
            Some(f) => self
                .direction(&self.camera_from_direction(f)?, "camera.from")?
                .as_dvec3(),
            None => super::framing::DEFAULT_FROM,
        };
        let fov_y = match &c.fov_y {
            Some(f) => self.finite(f, "camera.fov_y")?,
            None => super::framing::DEFAULT_FOV_Y,
        };
        Ok(Some((from, fov_y)))
    }

    /// `camera.from` as a direction (three numbers).
    fn camera_from_direction(&self, f: &Spanned<toml::Value>) -> Result<V3, SceneError> {
        let value = Arr3::deserialize(f.get_ref().clone())
            .map_err(|e| self.err(f.span(), "camera.from", e.to_string()))?;
        Ok(Spanned::new(f.span(), value))
    }

    /// `[camera] from = "gltf"` (SPEC §15): the span of the key when the camera comes from the
    /// first glTF mesh's file, `None` otherwise. No other camera key may be given with it but
    /// nothing else.
    fn camera_from_gltf(
        &self,
        raw: &Spanned<RawCamera>,
    ) -> Result<Option<Range<usize>>, SceneError> {
        let c = raw.get_ref();
        let Some(from) = &c.from else { return Ok(None) };
        let Some(name) = from.get_ref().as_str() else {
            return Ok(None);
        };
        if name != "gltf" {
            return Err(self.err(
                from.span(),
                "camera.from",
                format!("unknown value {name:?}; expected \"gltf\" or a direction [x, y, z]"),
            ));
        }
        let others = [&["eye"][..], &EXPLICIT_KEYS, &LOOK_AT_KEYS].concat();
        let others = [others, vec!["interpolation", "orbit", "frame", "key"]].concat();
        if let Some((k, sp)) = c.first_given(&others, from.span()) {
            return Err(self.err(
                sp,
                format!("camera.{k}"),
                "cannot be combined with from = \"gltf\" (the file gives the whole view)",
            ));
        }
        Ok(Some(from.span()))
    }

    /// The camera of `from = "gltf"`: the first perspective camera of the first glTF mesh
    /// ([`crate::scene::gltf::camera`]) on this scene's image.
    fn gltf_camera(
        &self,
        span: Range<usize>,
        image: &ImageSettings,
        meshes: &[MeshRef],
    ) -> Result<Camera, SceneError> {
        let fail = |message: String| self.err(span.clone(), "camera.from", message);
        let gltf = first_gltf(meshes)
            .ok_or_else(|| fail("from = \"gltf\" needs a [[mesh]] that is a glTF file".into()))?;
        let view = crate::scene::gltf::camera(&gltf.path)
            .map_err(|e| fail(format!("no camera: {}", crate::error::chain(&e))))?;
        view.camera(image.width, image.height)
            .map_err(|e| fail(format!("the glTF camera has no view: {e}")))
    }

    /// `[render] lights_from = "gltf"`: the `KHR_lights_punctual` lights of the first glTF mesh
    /// ([`crate::scene::gltf::lights`]) as SPEC §14 lights with inverse-square falloff (SPEC §15;
    /// a directional light has none); a file without lights is an error.
    fn gltf_lights(
        &self,
        from: &Spanned<String>,
        meshes: &[MeshRef],
    ) -> Result<Vec<Light>, SceneError> {
        let fail = |message: String| self.err(from.span(), "render.lights_from", message);
        if from.get_ref() != "gltf" {
            return Err(fail(format!(
                "unknown value {:?}; expected \"gltf\"",
                from.get_ref()
            )));
        }
        let gltf = first_gltf(meshes)
            .ok_or_else(|| fail("needs a [[mesh]] that is a glTF file".into()))?;
        let found =
            crate::scene::gltf::lights(&gltf.path).map_err(|e| fail(crate::error::chain(&e)))?;
        if found.is_empty() {
            return Err(fail(format!(
                "{} has no KHR_lights_punctual light in its default scene",
                gltf.path.display()
            )));
        }
        Ok(found.into_iter().map(gltf_light).collect())
    }

    /// The camera of `frame = "auto"`: [`super::framing::frame_box`] of the bounds of every
    /// sphere and every mesh's vertices (planes are unbounded and left out).
    fn framed(
        &self,
        raw: &Spanned<RawCamera>,
        (from, fov_y): (DVec3, f64),
        image: &ImageSettings,
        spheres: &[Sphere],
        meshes: &[MeshRef],
    ) -> Result<Camera, SceneError> {
        let span = raw
            .get_ref()
            .frame
            .as_ref()
            .map_or(raw.span(), Spanned::span);
        let fail = |message: String| self.err(span.clone(), "camera.frame", message);
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for s in spheres {
            lo = lo.min(s.center - f64::from(s.radius));
            hi = hi.max(s.center + f64::from(s.radius));
        }
        for m in meshes {
            let mesh = crate::mesh::ObjMesh::read(&m.path)
                .map_err(|e| fail(format!("cannot read a mesh to frame: {e}")))?;
            let (mlo, mhi) = mesh.bounds();
            (lo, hi) = (lo.min(mlo), hi.max(mhi));
        }
        let view = super::framing::frame_box(lo, hi, from, fov_y, (image.width, image.height))
            .ok_or_else(|| fail("nothing to frame: no sphere or mesh vertex".into()))?;
        view.camera(image.width, image.height)
            .map_err(|e| self.err(span.clone(), format!("camera.{}", e.key()), e.to_string()))
    }

    /// `[camera.orbit]`: frame 0's camera and the orbit. Every frame is a valid view when frame
    /// 0 is (the rotation about `up` keeps the angle between `up` and the view).
    fn orbit(
        &self,
        raw: &Spanned<RawOrbit>,
        image: &ImageSettings,
    ) -> Result<(Camera, Option<CameraPath>), SceneError> {
        let o = raw.get_ref();
        let frames = self.int(&o.frames, "camera.orbit.frames", 1, i64::from(u32::MAX))?;
        let turns = match &o.turns {
            Some(t) => self.finite(t, "camera.orbit.turns")?,
            None => 1.0,
        };
        let start = LookAt {
            eye: self.dvec3(&o.eye, "camera.orbit.eye")?,
            look_at: self.dvec3(&o.look_at, "camera.orbit.look_at")?,
            up: self.dvec3(&o.up, "camera.orbit.up")?,
            fov_y: self.finite(&o.fov_y, "camera.orbit.fov_y")?,
        };
        let camera = self.look_at_camera(&start, image, "camera.orbit", |k| match k {
            "look_at" => o.look_at.span(),
            "up" => o.up.span(),
            _ => o.fov_y.span(),
        })?;
        let orbit = Orbit {
            start,
            frames,
            turns,
        };
        Ok((camera, Some(CameraPath::Orbit(orbit))))
    }

    /// `[[camera.key]]` entries: frames ≥ 0 and strictly increasing, every key a valid view.
    fn camera_path(
        &self,
        keys: &[Spanned<RawKey>],
        table: Range<usize>,
    ) -> Result<Vec<CameraKey>, SceneError> {
        if keys.is_empty() {
            return Err(self.err(table, "camera.key", "a camera path needs at least one key"));
        }
        let mut out: Vec<CameraKey> = Vec::with_capacity(keys.len());
        for (i, key) in keys.iter().enumerate() {
            let k = key.get_ref();
            let name = |f: &str| format!("camera.key[{i}].{f}");
            let frame = self.int(&k.frame, &name("frame"), 0, i64::from(u32::MAX))?;
            if let Some(prev) = out.last()
                && frame <= prev.frame
            {
                return Err(self.err(
                    k.frame.span(),
                    name("frame"),
                    format!(
                        "{frame} must be greater than the previous key's frame {}",
                        prev.frame
                    ),
                ));
            }
            let view = LookAt {
                eye: self.dvec3(&k.eye, &name("eye"))?,
                look_at: self.dvec3(&k.look_at, &name("look_at"))?,
                up: self.dvec3(&k.up, &name("up"))?,
                fov_y: self.finite(&k.fov_y, &name("fov_y"))?,
            };
            // Every key must be a valid view on its own (1×1: the aspect does not matter here).
            view.camera(1, 1).map_err(|e| {
                let sp = match e.key() {
                    "look_at" => k.look_at.span(),
                    "up" => k.up.span(),
                    _ => k.fov_y.span(),
                };
                self.err(sp, name(e.key()), e.to_string())
            })?;
            out.push(CameraKey { frame, view });
        }
        Ok(out)
    }

    fn render(&self, raw: Option<RawRender>) -> Result<RenderSettings, SceneError> {
        let mut render = RenderSettings {
            max_depth: 2,
            shadows: true,
            ambient: Vec3::ONE,
            mode: RenderMode::Shaded,
            robustness: Robustness::default(),
        };
        let Some(raw) = raw else { return Ok(render) };
        if let Some(d) = &raw.max_depth {
            render.max_depth = self.int(d, "render.max_depth", 0, MAX_DEPTH as i64)?;
        }
        if let Some(s) = raw.shadows {
            render.shadows = s;
        }
        render.ambient = self.colour(raw.ambient.as_ref(), "render.ambient", Vec3::ONE)?;
        if let Some(m) = &raw.mode {
            render.mode = self.choice(
                m,
                "render.mode",
                &[
                    ("shaded", RenderMode::Shaded),
                    ("mask", RenderMode::HitMask),
                ],
            )?;
        }
        if let Some(o) = &raw.offset {
            render.robustness.offset = self.choice(
                o,
                "render.offset",
                &[
                    ("error-bound", OffsetMethod::ErrorBound),
                    // The name before error bounds replaced ulp counts; same meaning: the robust one.
                    ("scale-aware", OffsetMethod::ErrorBound),
                    ("fixed-epsilon", OffsetMethod::FixedEpsilon),
                ],
            )?;
        }
        if let Some(o) = &raw.sphere_test {
            render.robustness.sphere = self.choice(
                o,
                "render.sphere_test",
                &[("stable", SphereTest::Stable), ("naive", SphereTest::Naive)],
            )?;
        }
        if let Some(o) = &raw.triangle_test {
            render.robustness.triangle = self.choice(
                o,
                "render.triangle_test",
                &[
                    ("watertight", TriangleTest::Watertight),
                    ("moller-trumbore", TriangleTest::MollerTrumbore),
                ],
            )?;
        }
        Ok(render)
    }
}

/// A glTF light as a SPEC §14 light: the cone's full angle is twice `outerConeAngle` and the
/// penumbra twice the angle between the cones (full intensity inside `2 · innerConeAngle`), in
/// degrees; point and spot lights fall off with the inverse square of the distance (SPEC §15).
fn gltf_light(l: crate::scene::gltf::GltfLight) -> Light {
    use crate::scene::gltf::GltfLightKind as G;
    let (kind, falloff) = match l.kind {
        G::Point { position } => (LightKind::Point { position }, Falloff::InverseSquare),
        G::Directional { direction } => (LightKind::Directional { direction }, Falloff::None),
        G::Spot {
            position,
            direction,
            inner,
            outer,
        } => (
            LightKind::Spot {
                position,
                direction,
                cone: 2.0 * outer.to_degrees(),
                penumbra: 2.0 * (outer - inner).to_degrees(),
            },
            Falloff::InverseSquare,
        ),
    };
    Light {
        kind,
        intensity: Vec3::from_array(l.intensity),
        falloff,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
[camera]
eye = [0.0, 0.0, 0.0]
u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
w = [0.0, 0.0, 1.0]
window = { l = -0.1, r = 0.1, b = -0.1, t = 0.1 }
distance = 0.1

[material.m]
kd = [1.0, 1.0, 1.0]

[[sphere]]
center = [0.0, 0.0, -5.0]
radius = 1.0
material = "m"
"#;

    fn parse_err(text: &str) -> String {
        parse(text, Path::new("t.toml")).unwrap_err().to_string()
    }

    #[test]
    fn minimal_scene_parses_with_defaults() {
        let s = parse(MINIMAL, Path::new("t.toml")).unwrap();
        assert_eq!(s.image.width, 512);
        assert_eq!(s.render.max_depth, 2);
        assert_eq!(s.spheres.len(), 1);
        assert_eq!(s.materials[0].kd, Vec3::ONE);
    }

    #[test]
    fn negative_radius_names_line_and_key() {
        let e = parse_err(&MINIMAL.replace("radius = 1.0", "radius = -1.0"));
        assert!(e.starts_with("t.toml:15: sphere[0].radius:"), "{e}");
    }

    #[test]
    fn unknown_key_is_an_error_with_its_line() {
        let e = parse_err(&MINIMAL.replace("radius = 1.0", "radius = 1.0\nradus = 2.0"));
        assert!(e.starts_with("t.toml:16: radus:"), "{e}");
        assert!(e.contains("unknown field"), "{e}");
    }

    #[test]
    fn undefined_material_is_named() {
        let e = parse_err(&MINIMAL.replace("material = \"m\"", "material = \"gold\""));
        assert!(
            e.contains("t.toml:16: sphere[0].material: undefined material \"gold\""),
            "{e}"
        );
    }

    #[test]
    fn zero_direction_is_rejected() {
        let e = parse_err(&MINIMAL.replace("u = [1.0, 0.0, 0.0]", "u = [0.0, 0.0, 0.0]"));
        assert!(e.starts_with("t.toml:4: camera.u:"), "{e}");
    }

    #[test]
    fn non_finite_numbers_are_rejected() {
        let e =
            parse_err(&MINIMAL.replace("center = [0.0, 0.0, -5.0]", "center = [nan, 0.0, -5.0]"));
        assert!(e.starts_with("t.toml:14: sphere[0].center:"), "{e}");
        let e = parse_err(&MINIMAL.replace("distance = 0.1", "distance = inf"));
        assert!(e.starts_with("t.toml:8: camera.distance:"), "{e}");
        let e = parse_err(&MINIMAL.replace("distance = 0.1", "distance = 1e300"));
        assert!(e.contains("32-bit"), "{e}");
    }

    #[test]
    fn missing_required_key_is_an_error() {
        let e = parse_err(&MINIMAL.replace("distance = 0.1\n", ""));
        assert!(e.contains("distance"), "{e}");
        assert!(e.starts_with("t.toml:"), "{e}");
    }

    #[test]
    fn wrong_type_is_an_error() {
        let e = parse_err(&MINIMAL.replace("radius = 1.0", "radius = \"big\""));
        assert!(e.starts_with("t.toml:15: radius:"), "{e}");
    }

    #[test]
    fn out_of_range_settings_are_rejected() {
        let e = parse_err(&format!("[image]\nsamples = 0\n{MINIMAL}"));
        assert!(e.starts_with("t.toml:2: image.samples:"), "{e}");
        let e = parse_err(&format!("[render]\nmax_depth = -1\n{MINIMAL}"));
        assert!(e.starts_with("t.toml:2: render.max_depth:"), "{e}");
        let e = parse_err(&MINIMAL.replace("kd = [1.0, 1.0, 1.0]", "alpha = 1.5"));
        assert!(e.starts_with("t.toml:11: material.m.alpha:"), "{e}");
    }

    /// MINIMAL with its camera replaced by `camera` (the `[camera]` header is line 2).
    fn with_camera(camera: &str) -> String {
        let start = MINIMAL.find("[camera]").unwrap();
        let end = MINIMAL.find("[material.m]").unwrap();
        format!(
            "{}[camera]\n{camera}\n{}",
            &MINIMAL[..start],
            &MINIMAL[end..]
        )
    }

    const LOOK_AT: &str =
        "eye = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -5.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0";

    #[test]
    fn a_look_at_camera_is_the_spec_basis_and_window() {
        let s = parse(&with_camera(LOOK_AT), Path::new("t.toml")).unwrap();
        let c = &s.camera;
        assert_eq!((c.u, c.v, c.w), (Vec3::X, Vec3::Y, Vec3::Z));
        assert_eq!((c.l, c.r, c.b, c.t, c.d), (-1.0, 1.0, -1.0, 1.0, 1.0));
        assert!(s.camera_path.is_none());
    }

    #[test]
    fn degenerate_look_at_cameras_name_line_and_key() {
        let e = parse_err(&with_camera(
            &LOOK_AT.replace("up = [0.0, 1.0, 0.0]", "up = [0.0, 0.0, -3.0]"),
        ));
        assert!(
            e.starts_with("t.toml:5: camera.up: up is zero or parallel"),
            "{e}"
        );
        let e = parse_err(&with_camera(
            &LOOK_AT.replace("[0.0, 0.0, -5.0]", "[0.0, 0.0, 0.0]"),
        ));
        assert!(
            e.starts_with("t.toml:4: camera.look_at: look_at equals eye"),
            "{e}"
        );
        for fov in ["0.0", "180.0", "-1.0", "200.0"] {
            let e = parse_err(&with_camera(&LOOK_AT.replace("90.0", fov)));
            assert!(
                e.starts_with("t.toml:6: camera.fov_y: fov_y must be inside (0, 180)"),
                "{e}"
            );
        }
        let e = parse_err(&with_camera(&LOOK_AT.replace("fov_y = 90.0", "")));
        assert!(
            e.starts_with("t.toml:") && e.contains("camera.fov_y: missing"),
            "{e}"
        );
    }

    #[test]
    fn both_camera_forms_at_once_is_an_error() {
        let e = parse_err(&with_camera(&format!("{LOOK_AT}\ndistance = 0.1")));
        assert!(
            e.starts_with("t.toml:7: camera.distance: the look-at form"),
            "{e}"
        );
        let e = parse_err(&MINIMAL.replace("distance = 0.1", "distance = 0.1\nfov_y = 30.0"));
        assert!(
            e.starts_with("t.toml:9: camera.fov_y: the look-at form"),
            "{e}"
        );
    }

    fn key(frame: i64, x: f64) -> String {
        format!(
            "[[camera.key]]\nframe = {frame}\neye = [{x}, 0.0, 0.0]\nlook_at = [0.0, 0.0, -5.0]\n\
             up = [0.0, 1.0, 0.0]\nfov_y = 60.0\n"
        )
    }

    /// MINIMAL with a camera path of `keys` (the first key's header is line 2).
    fn with_keys(keys: &str) -> String {
        let start = MINIMAL.find("[camera]").unwrap();
        let end = MINIMAL.find("[material.m]").unwrap();
        format!("{}{keys}\n{}", &MINIMAL[..start], &MINIMAL[end..])
    }

    #[test]
    fn a_camera_path_starts_at_its_first_key() {
        let s = parse(
            &with_keys(&(key(3, 1.0) + &key(7, 2.0))),
            Path::new("t.toml"),
        )
        .unwrap();
        let path = s.camera_path.as_ref().unwrap();
        assert_eq!((path.first_frame(), path.last_frame()), (3, 7));
        assert_eq!(s.default_frame(), Some(3));
        assert_eq!(s.camera.eye, glam::DVec3::X);
        assert_eq!(
            s.at_frame(5).unwrap().camera.eye,
            glam::DVec3::new(1.5, 0.0, 0.0)
        );
        let e = s.at_frame(8).unwrap_err().to_string();
        assert_eq!(
            e,
            "t.toml: frame 8 is outside the camera path's frames (3..=7)"
        );
    }

    #[test]
    fn bad_camera_keys_name_line_and_key() {
        let e = parse_err(&with_keys(&(key(3, 1.0) + &key(3, 2.0))));
        assert!(
            e.starts_with("t.toml:9: camera.key[1].frame: 3 must be greater"),
            "{e}"
        );
        let e = parse_err(&with_keys(&key(-1, 1.0)));
        assert!(e.starts_with("t.toml:3: camera.key[0].frame:"), "{e}");
        let e = parse_err(&with_keys(
            &key(0, 0.0).replace("[0.0, 0.0, -5.0]", "[0.0, 0.0, 0.0]"),
        ));
        assert!(e.starts_with("t.toml:5: camera.key[0].look_at:"), "{e}");
        let e = parse_err(&with_keys(
            &key(0, 0.0).replace("fov_y = 60.0", "fov_y = 180.0"),
        ));
        assert!(e.starts_with("t.toml:7: camera.key[0].fov_y:"), "{e}");
        let e = parse_err(&with_keys(&format!(
            "[camera]\nfov_y = 20.0\n{}",
            key(0, 0.0)
        )));
        assert!(
            e.starts_with("t.toml:3: camera.fov_y: cannot be combined with [[camera.key]]"),
            "{e}"
        );
        let e = parse_err(&with_keys(
            &key(0, 0.0).replace("fov_y = 60.0", "fov_y = 60.0\nroll = 3.0"),
        ));
        assert!(
            e.starts_with("t.toml:8: roll:") && e.contains("unknown field"),
            "{e}"
        );
    }

    #[test]
    fn relative_mesh_paths_follow_the_scene_file() {
        let text =
            format!("{MINIMAL}\n[[mesh]]\npath = \"m.obj\"\nmaterial = \"m\"\nkdtree = \"t.kd\"\n");
        let s = parse(&text, Path::new("dir/s.toml")).unwrap();
        assert_eq!(s.meshes[0].path, Path::new("dir/m.obj"));
        assert_eq!(s.meshes[0].kdtree, TreeSource::File("dir/t.kd".into()));
    }

    #[test]
    fn the_largest_image_counts_its_pixels_and_samples_without_wrapping() {
        let side = MAX_IMAGE_SIDE;
        let text =
            format!("[image]\nwidth = {side}\nheight = {side}\nsamples = {MAX_SAMPLES}\n{MINIMAL}");
        let s = parse(&text, Path::new("t.toml")).unwrap();
        assert_eq!(s.image.pixel_count(), 1 << 30);
        assert_eq!(s.image.sample_count(), Some(1 << 46));
        let e = parse_err(&format!(
            "[image]\nwidth = {}\n{MINIMAL}",
            MAX_IMAGE_SIDE + 1
        ));
        assert!(e.starts_with("t.toml:2: image.width:"), "{e}");
    }
}
