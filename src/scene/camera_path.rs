//! Camera paths (SPEC §10): look-at keys at integer frames, interpolated linearly in f64.
//!
//! Frame `f` with consecutive keys `a.frame ≤ f ≤ b.frame` uses
//! `s = (f − a.frame) / (b.frame − a.frame)` and [`LookAt::lerp`]; a frame equal to a key uses that
//! key exactly, so it renders as the key written as a static look-at camera.

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

/// A camera path: keys with strictly increasing frames (at least one).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    /// The keys, in frame order.
    pub keys: Vec<CameraKey>,
}

/// A frame the path does not cover.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("frame {frame} is outside the camera path's keys ({first}..={last})")]
pub struct FrameOutsidePath {
    /// The frame asked for.
    pub frame: u32,
    /// The first key's frame.
    pub first: u32,
    /// The last key's frame.
    pub last: u32,
}

impl CameraPath {
    /// The first key's frame (what a scene with a path renders without a frame range).
    pub fn first_frame(&self) -> u32 {
        self.keys.first().map_or(0, |k| k.frame)
    }

    /// The last key's frame.
    pub fn last_frame(&self) -> u32 {
        self.keys.last().map_or(0, |k| k.frame)
    }

    /// The view at `frame`.
    pub fn view_at(&self, frame: u32) -> Result<LookAt, FrameOutsidePath> {
        let outside = FrameOutsidePath {
            frame,
            first: self.first_frame(),
            last: self.last_frame(),
        };
        // The last key at or before `frame`.
        let i = self.keys.partition_point(|k| k.frame <= frame);
        if i == 0 {
            return Err(outside);
        }
        let a = &self.keys[i - 1];
        if a.frame == frame {
            return Ok(a.view);
        }
        let b = self.keys.get(i).ok_or(outside)?;
        let s = f64::from(frame - a.frame) / f64::from(b.frame - a.frame);
        Ok(LookAt::lerp(&a.view, &b.view, s))
    }
}

impl Scene {
    /// The frame a render of this scene shows without a frame range: the first key's with a
    /// camera path, none for a static camera.
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
        let path = CameraPath {
            keys: vec![key(10, 0.0, 30.0), key(20, 1.0, 50.0), key(24, 0.3, 60.0)],
        };
        assert_eq!(path.view_at(10).unwrap(), path.keys[0].view);
        assert_eq!(path.view_at(20).unwrap(), path.keys[1].view);
        assert_eq!(path.view_at(24).unwrap(), path.keys[2].view);
        let v = path.view_at(15).unwrap();
        assert_eq!((v.eye.x, v.fov_y), (0.5, 40.0));
        let v = path.view_at(22).unwrap();
        assert_eq!(v.fov_y, 55.0);
    }

    #[test]
    fn frames_outside_the_keys_are_errors() {
        let path = CameraPath {
            keys: vec![key(10, 0.0, 30.0), key(20, 1.0, 50.0)],
        };
        let e = path.view_at(9).unwrap_err();
        assert_eq!(
            e.to_string(),
            "frame 9 is outside the camera path's keys (10..=20)"
        );
        assert!(path.view_at(21).is_err());
        let single = CameraPath {
            keys: vec![key(3, 0.0, 30.0)],
        };
        assert!(single.view_at(3).is_ok());
        assert!(single.view_at(4).is_err());
    }
}
