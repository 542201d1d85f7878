//! `wavefront report`: error against run time.
//!
//! Renders a set of configurations, times each (median of several runs), measures its error
//! against an f64 reference from [`crate::oracle`], and writes `report.md`, `report.csv` and
//! `error_vs_time.png`. The groups:
//!
//! - **convergence**: 1, 4, 16, 64, 256 samples per pixel against a many-sample f64 reference;
//! - **precision**: the f32 wavefront against the f64 oracle at one sample;
//! - **robustness**: naive vs stable sphere test, Möller–Trumbore vs watertight triangle test,
//!   fixed epsilon vs scale-aware offset, each on the scene, Sibenik, and the scene moved to
//!   coordinates around 1e4;
//! - **kd**: the kD builders (midpoint, SAH, a tree file written and read back): zero error,
//!   different times.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use glam::Vec3;

use crate::mesh::TriangleMesh;
use crate::oracle::{ImageDiff, compare_rgb8, render_oracle};
use crate::scene::builtin::{sibenik, sibenik_mesh_path};
use crate::scene::{OffsetMethod, Robustness, Scene, SphereTest, TreeSource, TriangleTest};
use crate::{RenderOptions, World, render};

/// What to run.
#[derive(Clone, Debug)]
pub struct ReportSettings {
    /// The main scene (convergence, precision, robustness).
    pub scene: Scene,
    /// Sibenik mesh; its parts are skipped (and the report says so) when missing.
    pub sibenik_mesh: PathBuf,
    /// Timed runs per configuration (the median is reported).
    pub runs: usize,
    /// Samples per pixel of the convergence sweep.
    pub sweep: Vec<u32>,
    /// Samples per pixel of the convergence reference.
    pub reference_samples: u32,
}

impl ReportSettings {
    /// The full report for `scene`: sweep 1–256 spp against a 1024-spp reference, 3 runs each.
    pub fn new(scene: Scene) -> ReportSettings {
        ReportSettings {
            scene,
            sibenik_mesh: sibenik_mesh_path(),
            runs: 3,
            sweep: vec![1, 4, 16, 64, 256],
            reference_samples: 1024,
        }
    }
}

/// One configuration's result.
#[derive(Clone, Debug)]
pub struct ReportPoint {
    /// `convergence`, `precision`, `robustness` or `kd`.
    pub group: &'static str,
    /// Scene label.
    pub scene: String,
    /// Configuration label.
    pub config: String,
    /// Median render time in seconds (geometry loading excluded).
    pub seconds: f64,
    /// Error against the f64 reference.
    pub diff: ImageDiff,
}

impl ReportPoint {
    /// Share of pixels more than one level off, in percent.
    pub fn pct_over_1(&self) -> f64 {
        100.0 * self.diff.over_1 as f64 / self.diff.pixels.max(1) as f64
    }
}

/// Everything the report measured, plus notes on what was skipped.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Measured points.
    pub points: Vec<ReportPoint>,
    /// Skipped parts and why.
    pub notes: Vec<String>,
}

/// Renders `scene` `runs` times; returns the 8-bit image and the median time.
fn timed_render(scene: &Scene, world: &World, runs: usize) -> (Vec<u8>, f64) {
    let mut times = Vec::with_capacity(runs);
    let mut image = Vec::new();
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let (film, _) = render(scene, world, RenderOptions::default(), |_, _| {});
        times.push(start.elapsed().as_secs_f64());
        image = film.to_rgb8(scene.image.gamma);
    }
    times.sort_by(f64::total_cmp);
    (image, times[times.len() / 2])
}

fn oracle_rgb8(scene: &Scene, mesh: Option<&TriangleMesh>) -> Vec<u8> {
    render_oracle(scene, mesh).to_rgb8(scene.image.gamma as f64)
}

/// Moves every position of the scene by `delta` (camera, lights, primitives; not meshes).
pub fn translated(scene: &Scene, delta: Vec3) -> Scene {
    let mut s = scene.clone();
    s.name = format!("{} moved by {delta}", scene.name);
    s.camera.eye += delta;
    for l in &mut s.lights {
        l.position += delta;
    }
    for sp in &mut s.spheres {
        sp.center += delta;
    }
    for p in &mut s.planes {
        p.point += delta;
    }
    s
}

/// The numerical variants compared in the robustness group.
fn variants() -> Vec<(&'static str, Robustness)> {
    let robust = Robustness::default();
    vec![
        ("robust (default)", robust),
        (
            "naive sphere test",
            Robustness {
                sphere: SphereTest::Naive,
                ..robust
            },
        ),
        (
            "Möller–Trumbore triangles",
            Robustness {
                triangle: TriangleTest::MollerTrumbore,
                ..robust
            },
        ),
        (
            "fixed epsilon offset",
            Robustness {
                offset: OffsetMethod::FixedEpsilon,
                ..robust
            },
        ),
    ]
}

/// Runs the report's configurations.
pub fn measure(settings: &ReportSettings, mut log: impl FnMut(&str)) -> Result<Report> {
    let mut report = Report::default();
    let base = &settings.scene;
    let world = World::load(base).context("cannot load the report scene")?;
    let mesh = world.triangles.as_ref().map(|t| &t.mesh);
    let label = base.name.clone();

    // Convergence: the sweep against a many-sample f64 reference.
    log(&format!(
        "convergence: {} spp reference (f64 oracle)",
        settings.reference_samples
    ));
    let mut reference_scene = base.clone();
    reference_scene.image.samples = settings.reference_samples;
    let reference = oracle_rgb8(&reference_scene, mesh);
    for &spp in &settings.sweep {
        let mut s = base.clone();
        s.image.samples = spp;
        let (image, seconds) = timed_render(&s, &world, settings.runs);
        log(&format!("convergence: {spp} spp in {:.3} s", seconds));
        report.points.push(ReportPoint {
            group: "convergence",
            scene: label.clone(),
            config: format!("{spp} spp"),
            seconds,
            diff: compare_rgb8(&image, &reference),
        });
    }

    // Scenes for precision and robustness: the base, Sibenik (if present), the base moved far.
    let mut scenes: Vec<(String, Scene)> = vec![(label.clone(), base.clone())];
    if settings.sibenik_mesh.exists() {
        let mut s = sibenik(true);
        s.meshes[0].path = settings.sibenik_mesh.clone();
        scenes.push(("sibenik-shadows".into(), s));
    } else {
        report.notes.push(format!(
            "Sibenik parts skipped: mesh not found at {} (set WAVEFRONT_SIBENIK or put sibenik.obj there)",
            settings.sibenik_mesh.display()
        ));
    }
    scenes.push((
        format!("{label} at 1e4"),
        translated(base, Vec3::splat(1e4)),
    ));

    // Each scene is loaded once and its oracle reference rendered once; the variants only switch
    // the world's numerical settings. Sibenik's world and reference are kept for the kD part.
    let mut sibenik_world = None;
    for (name, scene) in &scenes {
        log(&format!("precision and robustness: {name}"));
        let mut s = scene.clone();
        s.image.samples = 1;
        let mut world = World::load(&s)?;
        let reference = oracle_rgb8(&s, world.triangles.as_ref().map(|t| &t.mesh));
        for (variant, robustness) in variants() {
            let relevant = match robustness {
                r if r == Robustness::default() => true,
                r if r.sphere != SphereTest::Stable => !s.spheres.is_empty(),
                r if r.triangle != TriangleTest::Watertight => world.triangles.is_some(),
                _ => true,
            };
            if !relevant {
                continue;
            }
            world.robustness = robustness;
            let (image, seconds) = timed_render(&s, &world, settings.runs);
            let group = if robustness == Robustness::default() {
                "precision"
            } else {
                "robustness"
            };
            report.points.push(ReportPoint {
                group,
                scene: name.clone(),
                config: variant.to_string(),
                seconds,
                diff: compare_rgb8(&image, &reference),
            });
        }
        if name == "sibenik-shadows" {
            world.robustness = Robustness::default();
            sibenik_world = Some((s, world, reference));
        }
    }

    // kD builders on Sibenik: identical images, different times.
    if let Some((scene, world, reference)) = sibenik_world
        && let Some(tris) = &world.triangles
    {
        log("kd builders on sibenik-shadows");
        let tree_file =
            std::env::temp_dir().join(format!("wavefront-report-{}.kd", std::process::id()));
        let mut text = Vec::new();
        tris.tree.tree().write_text(&mut text)?; // the world's tree is the SAH one
        write_file(&tree_file, &text)?;
        for (config, source) in [
            ("midpoint", TreeSource::Midpoint),
            ("sah", TreeSource::Sah),
            ("sah tree file", TreeSource::File(tree_file.clone())),
        ] {
            let mut s = scene.clone();
            s.meshes[0].kdtree = source;
            let start = Instant::now();
            let world = World::load(&s)?;
            let setup = start.elapsed().as_secs_f64();
            let (image, seconds) = timed_render(&s, &world, settings.runs);
            report.points.push(ReportPoint {
                group: "kd",
                scene: "sibenik-shadows".into(),
                config: format!("{config} (load + tree {:.0} ms)", setup * 1e3),
                seconds,
                diff: compare_rgb8(&image, &reference),
            });
        }
        let _ = std::fs::remove_file(&tree_file);
    }
    Ok(report)
}

/// Writes `report.md`, `report.csv` and `error_vs_time.png` into `dir`.
pub fn write(report: &Report, settings: &ReportSettings, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut csv = String::from("group,scene,config,seconds,rmse,psnr_db,pct_over_1,max_levels\n");
    for p in &report.points {
        writeln!(
            csv,
            "{},{:?},{:?},{:.6},{:.5},{:.2},{:.4},{}",
            p.group,
            p.scene,
            p.config,
            p.seconds,
            p.diff.rmse,
            p.diff.psnr,
            p.pct_over_1(),
            p.diff.max
        )?;
    }
    write_file(&dir.join("report.csv"), csv.as_bytes())?;

    let mut md = String::new();
    writeln!(md, "# Error against run time\n")?;
    writeln!(
        md,
        "Scene `{}`, {}×{}; times are the median of {} renders on {} thread(s); errors are against \
         the f64 oracle (convergence: against a {}-sample f64 reference), on the 8-bit output.\n",
        settings.scene.name,
        settings.scene.image.width,
        settings.scene.image.height,
        settings.runs,
        rayon::current_num_threads(),
        settings.reference_samples
    )?;
    writeln!(md, "![error against run time](error_vs_time.png)\n")?;
    writeln!(
        md,
        "| group | scene | configuration | time (ms) | RMSE (levels) | PSNR (dB) | % px > 1/255 | max |"
    )?;
    writeln!(md, "|---|---|---|---:|---:|---:|---:|---:|")?;
    for p in &report.points {
        writeln!(
            md,
            "| {} | {} | {} | {:.1} | {:.4} | {:.1} | {:.4} | {} |",
            p.group,
            p.scene,
            p.config,
            p.seconds * 1e3,
            p.diff.rmse,
            p.diff.psnr,
            p.pct_over_1(),
            p.diff.max
        )?;
    }
    for n in &report.notes {
        writeln!(md, "\n- {n}")?;
    }
    write_file(&dir.join("report.md"), md.as_bytes())?;
    plot(report, &dir.join("error_vs_time.png"))
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    crate::film::write_atomically(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// The log-log scatter of RMSE against time, one colour per group.
fn plot(report: &Report, path: &Path) -> Result<()> {
    use plotters::prelude::*;

    // Identical images have RMSE 0: plot them on a floor line.
    const FLOOR: f64 = 1e-3;
    plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| anyhow::anyhow!("cannot load the plot font"))?;
    let (w, h) = (1000u32, 640u32);
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        let xs: Vec<f64> = report.points.iter().map(|p| p.seconds.max(1e-4)).collect();
        let (x0, x1) = (
            xs.iter().cloned().fold(f64::INFINITY, f64::min) / 1.5,
            xs.iter().cloned().fold(0.0, f64::max) * 1.5,
        );
        let y1 = report
            .points
            .iter()
            .map(|p| p.diff.rmse)
            .fold(1.0, f64::max)
            * 2.0;
        let mut chart = ChartBuilder::on(&root)
            .caption("error against run time", ("sans-serif", 26))
            .margin(16)
            .x_label_area_size(46)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (FLOOR / 2.0..y1).log_scale())
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        chart
            .configure_mesh()
            .x_desc("run time (s, median)")
            .y_desc("RMSE vs f64 reference (levels of 255; floor = identical)")
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        let groups = ["convergence", "precision", "robustness", "kd"];
        let colours = [BLUE, GREEN, RED, MAGENTA];
        for (g, colour) in groups.iter().zip(colours) {
            let pts: Vec<_> = report
                .points
                .iter()
                .filter(|p| p.group == *g)
                .map(|p| {
                    (
                        p.seconds.max(1e-4),
                        p.diff.rmse.max(FLOOR),
                        format!("{} {}", p.scene, p.config),
                    )
                })
                .collect();
            if pts.is_empty() {
                continue;
            }
            if *g == "convergence" {
                chart
                    .draw_series(LineSeries::new(pts.iter().map(|p| (p.0, p.1)), colour))
                    .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
            }
            chart
                .draw_series(pts.iter().map(|p| {
                    EmptyElement::at((p.0, p.1))
                        + Circle::new((0, 0), 5, colour.filled())
                        + Text::new(p.2.clone(), (8, -6), ("sans-serif", 12))
                }))
                .map_err(|e| anyhow::anyhow!("plot: {e}"))?
                .label(*g)
                .legend(move |(x, y)| Circle::new((x, y), 5, colour.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        root.present().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    crate::film::save_rgb8(path, w, h, &rgb)?;
    Ok(())
}
