//! What one `render` command renders: the region (`--pixel-bounds`, `--tile`) and the frames
//! (`--frames`, `--skip-existing`) with their scenes and output paths, all checked before anything
//! is rendered or written.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;

use crate::tile::{Fingerprint, SourceDigest, TileInfo, write_tile};
use wavefront::queue::region::{Region, TileSpec};
use wavefront::{Film, Scene};

use crate::frames::{FrameRange, frame_path, has_frame_placeholder};

/// The part of the work a render does: a region of the image, a range of frames.
#[derive(Args, Clone, Debug, Default)]
pub struct PartArgs {
    /// Render only pixels x0 ≤ i < x1, y0 ≤ j < y1 (row 0 at the top) into an image of that
    /// size; a PNG carries its place in the full image for `merge`.
    #[arg(long, value_name = "X0,X1,Y0,Y1")]
    pub pixel_bounds: Option<String>,
    /// Render rows ⌊K·H/N⌋ ≤ j < ⌊(K+1)·H/N⌋ (a tile for `merge`). `--tile N` takes K from
    /// SLURM_ARRAY_TASK_ID, else JOB_COMPLETION_INDEX.
    #[arg(long, value_name = "K/N|N")]
    pub tile: Option<String>,
    /// Render frames A to B (inclusive) of the scene's camera path in one process; each run of
    /// `#` in the output path becomes the zero-padded frame number.
    #[arg(long, value_name = "A-B|N")]
    pub frames: Option<String>,
    /// Skip frames (or the image) whose output file already exists.
    #[arg(long)]
    pub skip_existing: bool,
}

/// One image to render: the scene at its frame and where it goes.
#[derive(Clone, Debug)]
pub struct FrameJob {
    /// The frame, if the scene has a camera path (or `--frames` was given).
    pub frame: Option<u32>,
    /// The scene with that frame's camera.
    pub scene: Scene,
    /// The output file.
    pub output: PathBuf,
}

/// Everything a render command will do, validated.
#[derive(Clone, Debug)]
pub struct RenderPlan {
    /// The region of every frame (`None`: the whole image).
    pub region: Option<Region>,
    /// The images, in frame order.
    pub frames: Vec<FrameJob>,
    /// Print a line per file written (frame ranges).
    pub announce: bool,
}

impl RenderPlan {
    /// Checks `part` against `scene` and expands it into jobs; `var` reads the environment (for
    /// `--tile N`).
    pub fn new(
        scene: &Scene,
        part: &PartArgs,
        output: &Path,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<RenderPlan> {
        let (w, h) = (scene.image.width, scene.image.height);
        let region = match (&part.pixel_bounds, &part.tile) {
            (Some(_), Some(_)) => bail!("--pixel-bounds and --tile cannot be combined"),
            (Some(b), None) => {
                let r: Region = b.parse()?;
                r.check_inside(w, h, "--pixel-bounds")?;
                Some(r)
            }
            (None, Some(t)) => Some(t.parse::<TileSpec>()?.region(w, h, var)?),
            (None, None) => None,
        };
        let frames = match &part.frames {
            None => vec![FrameJob {
                frame: scene.default_frame(),
                scene: scene.clone(),
                output: output.to_path_buf(),
            }],
            Some(text) => {
                let range: FrameRange = text.parse()?;
                let Some(path) = &scene.camera_path else {
                    bail!(
                        "invalid --frames {text:?}: scene {} has no camera path \
                         ([[camera.key]] entries)",
                        scene.name
                    );
                };
                if range.first < path.first_frame() || range.last > path.last_frame() {
                    bail!(
                        "invalid --frames {text:?}: scene {} has camera keys for frames {}..={}",
                        scene.name,
                        path.first_frame(),
                        path.last_frame()
                    );
                }
                if range.len() > 1 && !has_frame_placeholder(output) {
                    bail!(
                        "--frames {range} renders {} frames but the output path {} has no run \
                         of # for the frame number (e.g. frame_####.png)",
                        range.len(),
                        output.display()
                    );
                }
                range
                    .frames()
                    .map(|f| {
                        Ok(FrameJob {
                            frame: Some(f),
                            scene: scene.at_frame(f)?,
                            output: frame_path(output, f),
                        })
                    })
                    .collect::<Result<Vec<_>>>()?
            }
        };
        Ok(RenderPlan {
            region,
            announce: part.frames.is_some(),
            frames,
        })
    }
}

/// Writes a region render: a tile PNG (with its bounds, image size and fingerprint) for `.png`,
/// the bare region image otherwise.
pub fn save_part(
    film: &Film,
    job: &FrameJob,
    region: Option<Region>,
    sources: SourceDigest,
) -> Result<()> {
    let image = &job.scene.image;
    let is_png = job
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let is_exr = wavefront::film::output::is_exr(&job.output);
    match region {
        Some(bounds) if is_exr => {
            let info = TileInfo {
                bounds,
                image: (image.width, image.height),
                fingerprint: Fingerprint::of(&job.scene, sources, job.frame),
            };
            crate::tile::write_tile_exr(&job.output, &info, film)
                .with_context(|| format!("cannot write tile {}", job.output.display()))
        }
        Some(bounds) if is_png => {
            let info = TileInfo {
                bounds,
                image: (image.width, image.height),
                fingerprint: Fingerprint::of(&job.scene, sources, job.frame),
            };
            write_tile(&job.output, &info, &film.to_rgb8(image.gamma))
                .with_context(|| format!("cannot write tile {}", job.output.display()))
        }
        _ => Ok(film.save(&job.output, image.gamma)?),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wavefront::scene::builtin::spheres;

    fn part(bounds: Option<&str>, tile: Option<&str>, frames: Option<&str>) -> PartArgs {
        PartArgs {
            pixel_bounds: bounds.map(str::to_owned),
            tile: tile.map(str::to_owned),
            frames: frames.map(str::to_owned),
            skip_existing: false,
        }
    }

    fn error(p: PartArgs) -> String {
        RenderPlan::new(&spheres(), &p, Path::new("o.png"), |_| None)
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn bad_regions_are_one_line_errors() {
        assert!(error(part(Some("0,600,0,10"), None, None)).contains("outside the 512x512"));
        assert!(error(part(Some("0,1,0"), None, None)).contains("--pixel-bounds"));
        assert!(error(part(None, Some("5/4"), None)).contains("below 4"));
        assert!(error(part(None, Some("4"), None)).contains("SLURM_ARRAY_TASK_ID"));
        assert!(error(part(Some("0,1,0,1"), Some("0/2"), None)).contains("cannot be combined"));
    }

    #[test]
    fn frames_need_a_camera_path() {
        let e = error(part(None, None, Some("0-3")));
        assert!(e.contains("no camera path"), "{e}");
        assert!(error(part(None, None, Some("3-0"))).contains("after the last"));
    }

    #[test]
    fn a_tile_from_the_environment_is_a_band_of_rows() {
        let p = part(None, Some("4"), None);
        let plan = RenderPlan::new(&spheres(), &p, Path::new("t.png"), |v| {
            (v == "JOB_COMPLETION_INDEX").then(|| "1".to_owned())
        })
        .unwrap();
        assert_eq!(plan.region, Some("0,512,128,256".parse().unwrap()));
        assert_eq!(plan.frames.len(), 1);
        assert_eq!(plan.frames[0].frame, None);
    }
}
