//! Camera paths (SPEC §10): look-at keys at integer frames, interpolated linearly or along a
//! centripetal Catmull–Rom spline, or an orbit around a point; all in f64.
//!
//! Keys: frame `f` with consecutive keys `a.frame ≤ f ≤ b.frame` uses
//! `s = (f − a.frame) / (b.frame − a.frame)`; a frame equal to a key uses that key exactly, so it
//! renders as the key written as a static look-at camera. Linear paths mix every field with
//! `LookAt::lerp`; Catmull–Rom paths run `eye` and `look_at` along centripetal (α = 0.5)
//! Catmull–Rom curves through the keys (end keys duplicated), `up` and `fov_y` linearly.
//!
//! Orbits: frame `f` of `N` puts the eye at `eye` rotated about the axis through `look_at` along
//! `up` by `turns · f / N` of a full turn (Rodrigues' formula), so its distance to `look_at` stays
//! that of frame 0. The rotation's sine and cosine come from `crate::arith::sin_cos_turns`, built from basic
//! operations only, so an orbit's frames are the same bits on every CPU (SPEC §2).

use glam::DVec3;

use super::Scene;
use super::lookat::LookAt;
use crate::error::SceneError;

/// One key of a camera path (`[[camera.key]]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraKey {
    /// The frame this view belongs to.
    pub frame: u32,
    /// The view at that frame.
    pub view: LookAt,
}

/// How a path's views between keys are made (`[camera] interpolation`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Interpolation {
    /// Every field mixed linearly between the two keys (`"linear"`, the default).
    #[default]
    Linear,
    /// `eye` and `look_at` along centripetal Catmull–Rom curves, `up` and `fov_y` linearly
    /// (`"catmull-rom"`).
    CatmullRom,
}

/// An orbit (`[camera.orbit]`): the eye circles `look_at` about `up`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    /// The view at frame 0 (`eye`, `look_at`, `up`, `fov_y`).
    pub start: LookAt,
    /// Frames in the orbit, `0 ≤ f < frames` (at least 1).
    pub frames: u32,
    /// Full turns over `frames` frames (negative: the other way round).
    pub turns: f64,
}

/// How the camera moves over the frames of an animation.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraPath {
    /// `[[camera.key]]` entries with strictly increasing frames (at least one).
    Keys {
        /// The keys, in frame order.
        keys: Vec<CameraKey>,
        /// How views between keys are made.
        interpolation: Interpolation,
    },
    /// `[camera.orbit]`.
    Orbit(Orbit),
}

/// A frame the path does not cover.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("frame {frame} is outside the camera path's frames ({first}..={last})")]
pub struct FrameOutsidePath {
    /// The frame asked for.
    pub frame: u32,
    /// The first frame.
    pub first: u32,
    /// The last frame.
    pub last: u32,
}

impl CameraPath {
    /// A path through `keys` with linear interpolation.
    pub fn linear(keys: Vec<CameraKey>) -> CameraPath {
        CameraPath::Keys {
            keys,
            interpolation: Interpolation::Linear,
        }
    }

    /// The first frame (what a scene with a path renders without a frame range).
    pub fn first_frame(&self) -> u32 {
        match self {
            CameraPath::Keys { keys, .. } => keys.first().map_or(0, |k| k.frame),
            CameraPath::Orbit(_) => 0,
        }
    }

    /// The last frame.
    pub fn last_frame(&self) -> u32 {
        match self {
            CameraPath::Keys { keys, .. } => keys.last().map_or(0, |k| k.frame),
            CameraPath::Orbit(o) => o.frames - 1,
        }
    }

    /// The view at `frame`.
    pub fn view_at(&self, frame: u32) -> Result<LookAt, FrameOutsidePath> {
        let outside = FrameOutsidePath {
            frame,
            first: self.first_frame(),
            last: self.last_frame(),
        };
        let (keys, interpolation) = match self {
            CameraPath::Orbit(o) if frame < o.frames => return Ok(o.view_at(frame)),
            CameraPath::Orbit(_) => return Err(outside),
            CameraPath::Keys {
                keys,
                interpolation,
            } => (keys, interpolation),
        };
        // The last key at or before `frame`.
        let i = keys.partition_point(|k| k.frame <= frame);
        if i == 0 {
            return Err(outside);
        }
        let a = &keys[i - 1];
        if a.frame == frame {
            return Ok(a.view);
        }
        let b = keys.get(i).ok_or(outside)?;
        let s = f64::from(frame - a.frame) / f64::from(b.frame - a.frame);
        let linear = LookAt::lerp(&a.view, &b.view, s);
        Ok(match interpolation {
            Interpolation::Linear => linear,
            Interpolation::CatmullRom => {
                // The neighbours of the segment, the end keys duplicated.
                let before = &keys[(i - 1).saturating_sub(1)].view;
                let after = &keys[(i + 1).min(keys.len() - 1)].view;
                let curve = |f: fn(&LookAt) -> DVec3| {
                    centripetal_catmull_rom([f(before), f(&a.view), f(&b.view), f(after)], s)
                };
                LookAt {
                    eye: curve(|v| v.eye),
                    look_at: curve(|v| v.look_at),
                    ..linear
                }
            }
        })
    }

    /// The path with every position moved by `delta` (keys' or the orbit's `eye` and `look_at`).
    pub fn translated(&self, delta: DVec3) -> CameraPath {
        let mut path = self.clone();
        let mut views: Vec<&mut LookAt> = match &mut path {
            CameraPath::Keys { keys, .. } => keys.iter_mut().map(|k| &mut k.view).collect(),
            CameraPath::Orbit(o) => vec![&mut o.start],
        };
        for v in &mut views {
            v.eye += delta;
            v.look_at += delta;
        }
        path
    }
}

impl Orbit {
    /// The view at `frame` (`frame < self.frames`): frame 0's eye rotated about the axis through
    /// `look_at` along `up` by `turns · frame / frames` of a turn.
    pub fn view_at(&self, frame: u32) -> LookAt {
        if frame == 0 {
            return self.start;
        }
        let turn = self.turns * f64::from(frame) / f64::from(self.frames);
        let (sin, cos) = crate::arith::sin_cos_turns(turn);
        let k = self.start.up.normalize();
        let v = self.start.eye - self.start.look_at;
        // Rodrigues: v cos θ + (k × v) sin θ + k (k · v)(1 − cos θ).
        let rotated = v * cos + k.cross(v) * sin + k * (k.dot(v) * (1.0 - cos));
        LookAt {
            eye: self.start.look_at + rotated,
            ..self.start
        }
    }
}

/// A point on the centripetal (α = 0.5) Catmull–Rom curve through `p[1]` (at `s = 0`) and
/// `p[2]` (at `s = 1`), with `p[0]` and `p[3]` their outer neighbours (the Barry–Goldman
/// pyramid over knots spaced by the square root of the distance between points). Coincident
/// neighbours (duplicated end keys) add nothing; a segment whose ends coincide stays at them.
pub(crate) fn centripetal_catmull_rom(p: [DVec3; 4], s: f64) -> DVec3 {
    let knot = |a: DVec3, b: DVec3| a.distance(b).sqrt();
    let t0 = 0.0;
    let t1 = t0 + knot(p[0], p[1]);
    let t2 = t1 + knot(p[1], p[2]);
    let t3 = t2 + knot(p[2], p[3]);
    if t2 == t1 {
        return p[1];
    }
    let t = t1 + (t2 - t1) * s;
    // The point between `a` (at knot `ta`) and `b` (at `tb`) at `t`; `a` when the knots coincide
    // (then `a` and `b` are the same point).
    let mix = |a: DVec3, b: DVec3, ta: f64, tb: f64| {
        if tb == ta {
            a
        } else {
            a * ((tb - t) / (tb - ta)) + b * ((t - ta) / (tb - ta))
        }
    };
    let a1 = mix(p[0], p[1], t0, t1);
    let a2 = mix(p[1], p[2], t1, t2);
    let a3 = mix(p[2], p[3], t2, t3);
    let b1 = mix(a1, a2, t0, t2);
    let b2 = mix(a2, a3, t1, t3);
    mix(b1, b2, t1, t2)
}

impl Scene {
    /// The frame a render of this scene shows without a frame range: the path's first frame,
    /// none for a static camera.
    pub fn default_frame(&self) -> Option<u32> {
        self.camera_path.as_ref().map(CameraPath::first_frame)
    }

    /// The scene at `frame`: its camera is the camera path's view at that frame. A scene without
    /// a path has the same camera at every frame.
    pub fn at_frame(&self, frame: u32) -> Result<Scene, SceneError> {
        let mut scene = self.clone();
        let Some(path) = &self.camera_path else {
            return Ok(scene);
        };
        let fail = |message: String| SceneError::Frame {
            scene: self.name.clone(),
            message,
        };
        let view = path.view_at(frame).map_err(|e| fail(e.to_string()))?;
        scene.camera = view
            .camera(self.image.width, self.image.height)
            .map_err(|e| fail(format!("frame {frame}: camera.{}: {e}", e.key())))?;
        Ok(scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn key(frame: u32, x: f64, fov_y: f64) -> CameraKey {
        CameraKey {
            frame,
            view: LookAt {
                eye: DVec3::new(x, 0.0, 0.0),
                look_at: DVec3::new(x, 0.0, -1.0),
                up: DVec3::Y,
                fov_y,
            },
        }
    }

    #[test]
    fn frames_between_keys_interpolate_and_keys_are_exact() {
        let keys = vec![key(10, 0.0, 30.0), key(20, 1.0, 50.0), key(24, 0.3, 60.0)];
        let path = CameraPath::linear(keys.clone());
        assert_eq!(path.view_at(10).unwrap(), keys[0].view);
        assert_eq!(path.view_at(20).unwrap(), keys[1].view);
        assert_eq!(path.view_at(24).unwrap(), keys[2].view);
        let v = path.view_at(15).unwrap();
        assert_eq!((v.eye.x, v.fov_y), (0.5, 40.0));
        let v = path.view_at(22).unwrap();
        assert_eq!(v.fov_y, 55.0);
    }

    #[test]
    fn frames_outside_the_keys_are_errors() {
        let path = CameraPath::linear(vec![key(10, 0.0, 30.0), key(20, 1.0, 50.0)]);
        let e = path.view_at(9).unwrap_err();
        assert_eq!(
            e.to_string(),
            "frame 9 is outside the camera path's frames (10..=20)"
        );
        assert!(path.view_at(21).is_err());
        let single = CameraPath::linear(vec![key(3, 0.0, 30.0)]);
        assert!(single.view_at(3).is_ok());
        assert!(single.view_at(4).is_err());
    }

    fn orbit(frames: u32, turns: f64) -> Orbit {
        Orbit {
            start: LookAt {
                eye: DVec3::new(3.0, 1.5, -2.0),
                look_at: DVec3::new(0.25, -0.5, -7.0),
                up: DVec3::new(0.1, 2.0, 0.3),
                fov_y: 40.0,
            },
            frames,
            turns,
        }
    }

    #[test]
    fn an_orbit_keeps_the_eyes_distance_on_every_frame() {
        for (frames, turns) in [(7, 1.0), (360, 1.0), (100, 2.5), (13, -0.75)] {
            let o = orbit(frames, turns);
            let path = CameraPath::Orbit(o);
            let r0 = o.start.eye.distance(o.start.look_at);
            let k = o.start.up.normalize();
            let h0 = k.dot(o.start.eye - o.start.look_at);
            for f in 0..frames {
                let v = path.view_at(f).unwrap();
                let r = v.eye.distance(v.look_at);
                assert!((r - r0).abs() <= 1e-9 * r0, "frame {f}: {r} vs {r0}");
                // It turns about the axis: the height along `up` stays, and so does the view.
                let h = k.dot(v.eye - v.look_at);
                assert!((h - h0).abs() <= 1e-9 * r0, "frame {f}: height {h} vs {h0}");
                assert_eq!(
                    (v.look_at, v.up, v.fov_y),
                    (o.start.look_at, o.start.up, 40.0)
                );
                assert!(v.camera(64, 64).is_ok());
            }
            assert!(path.view_at(frames).is_err());
        }
    }

    #[test]
    fn an_orbit_turns_by_its_fraction_of_a_turn() {
        // A quarter of a turn about +y takes an eye on +z to +x (right-handed rotation).
        let o = Orbit {
            start: LookAt {
                eye: DVec3::new(0.0, 0.0, 5.0),
                look_at: DVec3::ZERO,
                up: DVec3::Y,
                fov_y: 30.0,
            },
            frames: 8,
            turns: 1.0,
        };
        let quarter = o.view_at(2).eye;
        assert!(
            quarter.distance(DVec3::new(5.0, 0.0, 0.0)) < 1e-15,
            "{quarter}"
        );
        let half = o.view_at(4).eye;
        assert!(half.distance(DVec3::new(0.0, 0.0, -5.0)) < 1e-15, "{half}");
        let eighth = o.view_at(1).eye;
        let c = 5.0 * std::f64::consts::FRAC_1_SQRT_2;
        assert!(eighth.distance(DVec3::new(c, 0.0, c)) < 1e-14, "{eighth}");
    }

    fn view(eye: DVec3, look_at: DVec3) -> LookAt {
        LookAt {
            eye,
            look_at,
            up: DVec3::Y,
            fov_y: 50.0,
        }
    }

    #[test]
    fn catmull_rom_passes_through_every_key_and_moves_between_them() {
        let eyes = [
            (0.0, 10.0),
            (10.0, 0.0),
            (0.0, -10.0),
            (-10.0, 0.0),
            (0.0, 10.0),
        ];
        let keys: Vec<CameraKey> = eyes
            .iter()
            .enumerate()
            .map(|(i, &(x, z))| CameraKey {
                frame: 12 * i as u32,
                view: view(DVec3::new(x, 1.0, z), DVec3::ZERO),
            })
            .collect();
        let smooth = CameraPath::Keys {
            keys: keys.clone(),
            interpolation: Interpolation::CatmullRom,
        };
        let linear = CameraPath::linear(keys.clone());
        for k in &keys {
            assert_eq!(smooth.view_at(k.frame).unwrap(), k.view);
        }
        // The linear orbit cuts the corners (0.71 of the radius mid-segment); the spline keeps
        // near the circle through the keys between inner keys, and bends outwards of the chord
        // even in the end segments (whose outer neighbours are the duplicated end keys).
        let radius = |p: &CameraPath, f: u32| {
            let e = p.view_at(f).unwrap().eye;
            (e.x * e.x + e.z * e.z).sqrt() / 10.0
        };
        assert!((radius(&linear, 18) - 0.5f64.sqrt()).abs() < 1e-12);
        // Equal chords make the centripetal knots uniform, where the midpoint of a segment is
        // (−P0 + 9·P1 + 9·P2 − P3) / 16: for keys a quarter turn apart, (6.25, −6.25) between
        // (10, 0) and (0, −10), 0.884 of the radius.
        let mid = smooth.view_at(18).unwrap().eye;
        assert!(mid.distance(DVec3::new(6.25, 1.0, -6.25)) < 1e-12, "{mid}");
        let inner: Vec<f64> = (12..=36).map(|f| radius(&smooth, f)).collect();
        assert!(inner.iter().all(|&r| r > 0.88 && r <= 1.0), "{inner:?}");
        for f in (1..12).chain(37..48) {
            assert!(radius(&smooth, f) > radius(&linear, f) + 0.05, "frame {f}");
        }
        for k in &keys[1..4] {
            let before = smooth.view_at(k.frame - 1).unwrap().eye;
            let after = smooth.view_at(k.frame + 1).unwrap().eye;
            assert!(before.distance(after) < 3.0, "no jump at frame {}", k.frame);
        }
    }

    #[test]
    fn catmull_rom_through_evenly_spaced_collinear_keys_is_a_straight_even_line() {
        let keys: Vec<CameraKey> = (0..5)
            .map(|i| CameraKey {
                frame: 10 * i,
                view: view(DVec3::new(2.0 * i as f64, 0.0, 5.0), DVec3::ZERO),
            })
            .collect();
        let smooth = CameraPath::Keys {
            keys,
            interpolation: Interpolation::CatmullRom,
        };
        // Inner segments (the end segments bend towards their duplicated end keys' tangents).
        for f in 10..=30 {
            let e = smooth.view_at(f).unwrap().eye;
            let expect = DVec3::new(0.2 * f as f64, 0.0, 5.0);
            assert!(e.distance(expect) < 1e-12, "frame {f}: {e}");
        }
    }

    #[test]
    fn a_segment_whose_ends_coincide_stays_put() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        let q = DVec3::new(-1.0, 0.0, 3.0);
        for s in [0.0, 0.3, 1.0] {
            assert_eq!(centripetal_catmull_rom([q, p, p, q], s), p);
        }
        // Duplicated end keys: the curve still runs from p[1] to p[2].
        assert_eq!(centripetal_catmull_rom([p, p, q, q], 0.0), p);
        assert!(centripetal_catmull_rom([p, p, q, q], 1.0).distance(q) < 1e-15);
    }
}
