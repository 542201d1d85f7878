//! Command-line overrides of a scene's settings (SPEC §9), validated like scene-file values.

use std::path::PathBuf;

use super::file::{MAX_DEPTH, MAX_SAMPLES};
use super::{RenderMode, Scene, TreeSource};
use crate::error::SceneError;

/// Settings that replace the scene's own; `None` keeps the scene's value.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    /// `--samples N`.
    pub samples: Option<u32>,
    /// `--depth D`.
    pub depth: Option<u32>,
    /// `--shadows` / `--no-shadows`.
    pub shadows: Option<bool>,
    /// `--kdtree sah|midpoint|FILE`.
    pub kdtree: Option<TreeSource>,
    /// `--mesh PATH`: replaces the path of every mesh.
    pub mesh: Option<PathBuf>,
    /// `--mask`: render the hit/miss mask.
    pub mask: bool,
}

impl Overrides {
    /// Parses a `--kdtree` value: a builder name or a tree file path.
    pub fn tree_source(value: &str) -> TreeSource {
        TreeSource::parse(value, |file| PathBuf::from(file))
    }

    /// Applies the overrides to `scene`, rejecting out-of-range values.
    pub fn apply(&self, scene: &mut Scene) -> Result<(), SceneError> {
        let bad = |key: &str, message: String| SceneError::Setting {
            key: key.into(),
            message,
        };
        if let Some(n) = self.samples {
            if n == 0 || n > MAX_SAMPLES {
                return Err(bad(
                    "--samples",
                    format!("{n} is out of range 1..={MAX_SAMPLES}"),
                ));
            }
            scene.image.samples = n;
        }
        if let Some(d) = self.depth {
            if d > MAX_DEPTH {
                return Err(bad(
                    "--depth",
                    format!("{d} is out of range 0..={MAX_DEPTH}"),
                ));
            }
            scene.render.max_depth = d;
        }
        if let Some(s) = self.shadows {
            scene.render.shadows = s;
        }
        if self.kdtree.is_some() || self.mesh.is_some() {
            if scene.meshes.is_empty() {
                let key = if self.mesh.is_some() {
                    "--mesh"
                } else {
                    "--kdtree"
                };
                return Err(bad(key, format!("scene {} has no mesh", scene.name)));
            }
            for m in &mut scene.meshes {
                if let Some(k) = &self.kdtree {
                    m.kdtree = k.clone();
                }
                if let Some(p) = &self.mesh {
                    m.path = p.clone();
                }
            }
        }
        if self.mask {
            scene.render.mode = RenderMode::HitMask;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin::{sibenik, spheres};

    #[test]
    fn overrides_replace_settings() {
        let mut s = spheres();
        let o = Overrides {
            samples: Some(4),
            depth: Some(0),
            shadows: Some(false),
            mask: true,
            ..Default::default()
        };
        o.apply(&mut s).unwrap();
        assert_eq!(
            (s.image.samples, s.render.max_depth, s.render.shadows),
            (4, 0, false)
        );
        assert_eq!(s.render.mode, RenderMode::HitMask);
    }

    #[test]
    fn out_of_range_overrides_are_errors() {
        let e = Overrides {
            samples: Some(0),
            ..Default::default()
        }
        .apply(&mut spheres())
        .unwrap_err();
        assert!(e.to_string().contains("--samples"), "{e}");
        let e = Overrides {
            depth: Some(1000),
            ..Default::default()
        }
        .apply(&mut spheres())
        .unwrap_err();
        assert!(e.to_string().contains("--depth"), "{e}");
        let e = Overrides {
            kdtree: Some(TreeSource::Midpoint),
            ..Default::default()
        }
        .apply(&mut spheres())
        .unwrap_err();
        assert!(e.to_string().contains("has no mesh"), "{e}");
    }

    #[test]
    fn mesh_and_tree_overrides_reach_every_mesh() {
        let mut s = sibenik(true);
        let o = Overrides {
            mesh: Some("x.obj".into()),
            kdtree: Some(Overrides::tree_source("t.kd")),
            ..Default::default()
        };
        o.apply(&mut s).unwrap();
        assert_eq!(s.meshes[0].path, PathBuf::from("x.obj"));
        assert_eq!(s.meshes[0].kdtree, TreeSource::File("t.kd".into()));
    }
}
