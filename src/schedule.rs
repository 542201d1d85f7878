//! The schedule: the one place that orders the stages. Reading [`render`]'s loop top to bottom is
//! reading the renderer.
//!
//! ```text
//! for each wave of ≤ wave_samples samples (whole pixels):
//!   depth 0: generate ─► rays[0]
//!   depth k: intersect(rays[k]) ─► hits ─► shade ─► emitted ─────────────► samples
//!                                           │    └► shadow rays ─► shadow ─► samples (unoccluded)
//!                                           └► reflect (k < max_depth) ─► rays[k+1]
//!   resolve: samples ─► pixels (box filter)
//! ```
//!
//! [`Pipeline::for_scene`] leaves out what a scene does not need: no reflect stage without a
//! reflective material or with `max_depth = 0`, no shadow stage without shadows or lights, no
//! specular evaluation without `ks > 0`, no kD tree without a mesh, no shading at all for a hit mask.

use std::fmt;
use std::time::Instant;

use glam::Vec3;

use crate::film::{Film, SampleBuffer};
use crate::queue::{HitColumns, HitQueue, RayQueue, ShadowQueue};
use crate::scene::{RenderMode, Scene};
use crate::stages::Stage;
use crate::stages::generate::{Wave, generate_camera_rays};
use crate::stages::intersect::{compact_hits, intersect_closest};
use crate::stages::reflect::spawn_reflection_rays;
use crate::stages::shade::{ShadeScratch, ShadeSettings, shade_hit_mask, shade_hits};
use crate::stages::shadow::intersect_occluded;
use crate::stats::Stats;
use crate::world::World;

/// Default cap on samples per wave: bounds memory whatever the samples per pixel.
pub const DEFAULT_WAVE_SAMPLES: usize = 1 << 20;

/// The stages one depth runs, in order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DepthPlan {
    /// The bounce counter.
    pub depth: u32,
    /// Stages, in order.
    pub stages: Vec<Stage>,
}

/// A scene's pipeline: stages per depth, plus what the shade stage evaluates.
#[derive(Clone, Debug, PartialEq)]
pub struct Pipeline {
    /// One entry per depth that can have rays.
    pub depths: Vec<DepthPlan>,
    /// Shade settings (which terms are evaluated).
    pub shade: ShadeSettings,
    /// Hit mask instead of shading.
    pub mask: bool,
    /// What the intersect and shadow stages test against.
    pub geometry: String,
}

impl Pipeline {
    /// The pipeline `scene` needs.
    pub fn for_scene(scene: &Scene) -> Pipeline {
        let shade = ShadeSettings::for_scene(scene);
        let mask = scene.render.mode == RenderMode::HitMask;
        let reflect = scene.needs_reflections();
        let last = if reflect { scene.render.max_depth } else { 0 };
        let depths = (0..=last)
            .map(|depth| {
                let mut stages = vec![];
                if depth == 0 {
                    stages.push(Stage::Generate);
                }
                stages.push(Stage::Intersect);
                stages.push(Stage::Shade);
                if shade.shadows {
                    stages.push(Stage::Shadow);
                }
                if depth < last {
                    stages.push(Stage::Reflect);
                }
                DepthPlan { depth, stages }
            })
            .collect();
        Pipeline {
            depths,
            shade,
            mask,
            geometry: describe_geometry(scene),
        }
    }

    /// True when some depth runs `stage`.
    pub fn runs(&self, stage: Stage) -> bool {
        self.depths.iter().any(|d| d.stages.contains(&stage))
    }

    fn depth_runs(&self, depth: usize, stage: Stage) -> bool {
        self.depths
            .get(depth)
            .is_some_and(|d| d.stages.contains(&stage))
    }
}

fn describe_geometry(scene: &Scene) -> String {
    let mut parts = vec![];
    if !scene.spheres.is_empty() {
        parts.push(format!("{} spheres", scene.spheres.len()));
    }
    if !scene.planes.is_empty() {
        parts.push(format!("{} planes", scene.planes.len()));
    }
    let analytic = if parts.is_empty() {
        String::new()
    } else {
        format!("{} (brute force)", parts.join(", "))
    };
    let mesh = match scene.meshes.len() {
        0 => "no mesh, no kD tree".to_string(),
        n => {
            let tree = match &scene.meshes[0].kdtree {
                crate::scene::TreeSource::Sah => "SAH kD tree".to_string(),
                crate::scene::TreeSource::Midpoint => "midpoint kD tree".to_string(),
                crate::scene::TreeSource::File(p) => format!("kD tree from {}", p.display()),
            };
            format!("{n} mesh(es) through a {tree}")
        }
    };
    if analytic.is_empty() {
        mesh
    } else {
        format!("{analytic}; {mesh}")
    }
}

impl fmt::Display for Pipeline {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "geometry: {}", self.geometry)?;
        let terms = if self.mask {
            "hit mask (no shading)".to_string()
        } else {
            let mut t = vec!["ambient", "diffuse"];
            if self.shade.specular {
                t.push("specular");
            }
            format!(
                "{}; direct light {}",
                t.join(" + "),
                if self.shade.shadows {
                    "through shadow rays"
                } else {
                    "unshadowed"
                }
            )
        };
        writeln!(f, "shade: {terms}")?;
        for d in &self.depths {
            let stages: Vec<_> = d
                .stages
                .iter()
                .map(|s| match (s, self.mask) {
                    (Stage::Shade, true) => "shade[mask]",
                    (Stage::Intersect, _) => "intersect[closest]",
                    (Stage::Shadow, _) => "shadow[occluded]",
                    (s, _) => s.label(),
                })
                .collect();
            writeln!(f, "depth {}: {}", d.depth, stages.join(" -> "))?;
        }
        Ok(())
    }
}

/// Options that change how, not what, the schedule renders.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions {
    /// Upper bound on samples per wave (rounded to whole pixels, at least one pixel).
    pub wave_samples: usize,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            wave_samples: DEFAULT_WAVE_SAMPLES,
        }
    }
}

/// Queues and scratch reused across depths and waves, so kernels allocate only while growing.
#[derive(Debug, Default)]
struct Workspace {
    rays: RayQueue,
    next: RayQueue,
    hit_columns: HitColumns,
    hits: HitQueue,
    shadows: ShadowQueue,
    emitted: Vec<Vec3>,
    occluded: Vec<bool>,
    rows: Vec<u32>,
    shade: ShadeScratch,
    samples: SampleBuffer,
}

/// Times one stage call and records its rays in and out.
/// `f` runs the stage and returns its rays out.
fn timed(stats: &mut Stats, stage: Stage, depth: u32, rays_in: usize, f: impl FnOnce() -> usize) {
    let start = Instant::now();
    let rays_out = f();
    stats.record(stage, depth, rays_in, rays_out, start.elapsed());
}

/// Renders `scene` (whose geometry is `world`) and returns the film and per-stage statistics.
/// `progress` is called after each wave with (pixels done, pixels total).
pub fn render(
    scene: &Scene,
    world: &World,
    options: RenderOptions,
    mut progress: impl FnMut(u64, u64),
) -> (Film, Stats) {
    let pipeline = Pipeline::for_scene(scene);
    let image = &scene.image;
    let spp = image.samples.max(1);
    let total = image.width * image.height;
    let pixels_per_wave = ((options.wave_samples / spp as usize).max(1)).min(total as usize) as u32;

    let mut film = Film::new(image.width, image.height);
    let mut stats = Stats::default();
    let mut ws = Workspace::default();

    let mut first = 0;
    while first < total {
        let wave = Wave {
            first_pixel: first,
            pixels: pixels_per_wave.min(total - first),
            samples: spp,
        };
        ws.samples.reset(wave.len());

        // depth 0: generate
        timed(&mut stats, Stage::Generate, 0, 0, || {
            generate_camera_rays(&scene.camera, image, &wave, &mut ws.rays);
            ws.rays.len()
        });

        for (depth, plan) in pipeline.depths.iter().enumerate() {
            let d = plan.depth;
            if ws.rays.is_empty() {
                break;
            }
            // intersect: closest hit, misses leave
            timed(&mut stats, Stage::Intersect, d, ws.rays.len(), || {
                intersect_closest(world, &ws.rays, &mut ws.hit_columns);
                compact_hits(&ws.rays, &ws.hit_columns, &mut ws.rows, &mut ws.hits);
                ws.hits.len()
            });

            // shade: local radiance now, direct light deferred to shadow rays
            timed(&mut stats, Stage::Shade, d, ws.hits.len(), || {
                if pipeline.mask {
                    shade_hit_mask(&ws.hits, &mut ws.emitted);
                } else {
                    shade_hits(
                        world,
                        &pipeline.shade,
                        &mut ws.hits,
                        &mut ws.emitted,
                        &mut ws.shade,
                        &mut ws.shadows,
                    );
                }
                ws.samples.add_sorted(&ws.hits.slot, &ws.emitted, |_| true);
                ws.shadows.len()
            });

            // shadow: unoccluded shadow rays add their radiance
            if pipeline.depth_runs(depth, Stage::Shadow) {
                timed(&mut stats, Stage::Shadow, d, ws.shadows.len(), || {
                    intersect_occluded(world, &ws.shadows, &mut ws.occluded);
                    let occluded = &ws.occluded;
                    ws.samples
                        .add_sorted(&ws.shadows.slot, &ws.shadows.radiance, |i| !occluded[i]);
                    occluded.iter().filter(|&&o| !o).count()
                });
            }

            // reflect: the next depth's rays
            if pipeline.depth_runs(depth, Stage::Reflect) {
                timed(&mut stats, Stage::Reflect, d, ws.hits.len(), || {
                    spawn_reflection_rays(world, &ws.hits, &mut ws.rows, &mut ws.next);
                    ws.next.len()
                });
                std::mem::swap(&mut ws.rays, &mut ws.next);
            } else {
                break;
            }
        }

        film.resolve_wave(&ws.samples, wave.first_pixel as usize, spp as usize);
        first += wave.pixels;
        progress(first as u64, total as u64);
    }
    (film, stats)
}
