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
use glam::DVec3;

use crate::oracle::{ImageDiff, compare_rgb8, render_oracle};
use wavefront::mesh::ObjMesh;
use wavefront::scene::builtin::{sibenik, sibenik_mesh_path};
use wavefront::scene::{OffsetMethod, Robustness, Scene, SphereTest, TreeSource, TriangleTest};
use wavefront::{RenderOptions, World, render};

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

/// The scene's meshes in f64 world coordinates, for the oracle.
fn oracle_meshes(scene: &Scene) -> Result<Vec<ObjMesh>> {
    scene
        .meshes
        .iter()
        .map(|m| ObjMesh::read(&m.path).context("cannot load the oracle's mesh"))
        .collect()
}

fn oracle_rgb8(scene: &Scene, meshes: &[ObjMesh]) -> Vec<u8> {
    render_oracle(scene, meshes).to_rgb8(scene.image.gamma as f64)
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
    let meshes = oracle_meshes(base)?;
    let label = base.name.clone();

    // Convergence: the sweep against a many-sample f64 reference.
    log(&format!(
        "convergence: {} spp reference (f64 oracle)",
        settings.reference_samples
    ));
    let mut reference_scene = base.clone();
    reference_scene.image.samples = settings.reference_samples;
    let reference = oracle_rgb8(&reference_scene, &meshes);
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
        base.translated(DVec3::splat(1e4)),
    ));

    // Each scene is loaded once and its oracle reference rendered once; the variants only switch
    // the world's numerical settings. Sibenik's world and reference are kept for the kD part.
    let mut sibenik_world = None;
    for (name, scene) in &scenes {
        log(&format!("precision and robustness: {name}"));
        let mut s = scene.clone();
        s.image.samples = 1;
        let mut world = World::load(&s)?;
        let reference = oracle_rgb8(&s, &oracle_meshes(&s)?);
        for (variant, robustness) in variants() {
            let relevant = match robustness {
                r if r == Robustness::default() => true,
                r if r.sphere != SphereTest::Stable => !s.spheres.is_empty(),
                r if r.triangle != TriangleTest::Watertight => world.triangles().is_some(),
                _ => true,
            };
            if !relevant {
                continue;
            }
            world = world.with_robustness(robustness);
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
            world = world.with_robustness(Robustness::default());
            sibenik_world = Some((s, world, reference));
        }
    }

    // kD builders on Sibenik: identical images, different times.
    if let Some((scene, world, reference)) = sibenik_world
        && let Some(tris) = world.triangles()
    {
        log("kd builders on sibenik-shadows");
        let tree_file =
            std::env::temp_dir().join(format!("wavefront-report-{}.kd", std::process::id()));
        let mut text = Vec::new();
        tris.tree().write_text_in(&mut text, world.frame())?; // the world's (SAH) tree, in world coordinates
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
    wavefront::film::output::write_atomically(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// The log-log scatter of RMSE against time, one colour per group.
/// A tick value without trailing noise: `0.25`, `3`, `1e-3`.
fn compact(x: f64) -> String {
    if x != 0.0 && (x.abs() < 1e-2 || x.abs() >= 1e4) {
        format!("{x:.0e}")
    } else {
        let s = format!("{x:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// The report's figure: one panel per group (convergence, precision, robustness, kD builders),
/// each on log-log axes with units; every point is named in a key beside its plot (marker colour,
/// configuration, time, RMSE) instead of a label next to it, so no text can overlap.
fn plot(report: &Report, path: &Path) -> Result<()> {
    use plotters::prelude::*;

    // Identical images have RMSE 0: plot them on a floor line.
    const FLOOR: f64 = 1e-3;
    let fail = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot: {e}");
    plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| anyhow::anyhow!("cannot load the plot font"))?;
    let (w, h) = (1400u32, 1000u32);
    let mut rgb = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        let (title, body) = root.split_vertically(44);
        title
            .titled(
                "error against run time (512 x 512 unless noted; RMSE against the f64 oracle)",
                ("sans-serif", 24),
            )
            .map_err(|e| fail(&e))?;
        let panels = body.split_evenly((2, 2));
        let groups = [
            ("convergence", "convergence: samples per pixel"),
            ("precision", "precision: f32 wavefront vs f64"),
            ("robustness", "robustness: numerical variants"),
            ("kd", "kD builders (same image, different cost)"),
        ];
        let palette = [
            RGBColor(31, 119, 180),
            RGBColor(255, 127, 14),
            RGBColor(44, 160, 44),
            RGBColor(214, 39, 40),
            RGBColor(148, 103, 189),
            RGBColor(140, 86, 75),
            RGBColor(227, 119, 194),
            RGBColor(127, 127, 127),
            RGBColor(188, 189, 34),
            RGBColor(23, 190, 207),
        ];
        for (panel, (group, caption)) in panels.iter().zip(groups) {
            let pts: Vec<&ReportPoint> =
                report.points.iter().filter(|p| p.group == group).collect();
            if pts.is_empty() {
                panel
                    .titled(&format!("{caption}: not measured"), ("sans-serif", 18))
                    .map_err(|e| fail(&e))?;
                continue;
            }
            // The plot on the left, its key (one line per point) on the right: nothing overlaps.
            let (width, _) = panel.dim_in_pixel();
            let (area, key) = panel.split_horizontally(width * 11 / 20);
            let xs: Vec<f64> = pts.iter().map(|p| p.seconds.max(1e-4)).collect();
            let x0 = xs.iter().cloned().fold(f64::INFINITY, f64::min) / 2.0;
            let x1 = xs.iter().cloned().fold(0.0, f64::max) * 2.0;
            let y1 = pts.iter().map(|p| p.diff.rmse).fold(1.0, f64::max) * 3.0;
            let mut chart = ChartBuilder::on(&area)
                .caption(caption, ("sans-serif", 17))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(64)
                .build_cartesian_2d((x0..x1).log_scale(), (FLOOR / 2.0..y1).log_scale())
                .map_err(|e| fail(&e))?;
            chart
                .configure_mesh()
                .x_desc("run time (s, median)")
                .y_desc("RMSE (levels of 255)")
                .x_labels(6)
                .y_labels(6)
                .x_label_formatter(&|x| compact(*x))
                .y_label_formatter(&|y| compact(*y))
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(|e| fail(&e))?;
            if group == "convergence" {
                let line = pts
                    .iter()
                    .map(|p| (p.seconds.max(1e-4), p.diff.rmse.max(FLOOR)));
                chart
                    .draw_series(LineSeries::new(line, palette[7]))
                    .map_err(|e| fail(&e))?;
            }
            let font = ("sans-serif", 12).into_font();
            key.draw(&Text::new(
                "point: configuration; time, RMSE",
                (4, 40),
                font.clone(),
            ))
            .map_err(|e| fail(&e))?;
            for (i, p) in pts.iter().enumerate() {
                let colour = palette[i % palette.len()];
                let at = (p.seconds.max(1e-4), p.diff.rmse.max(FLOOR));
                chart
                    .draw_series(std::iter::once(Circle::new(at, 5, colour.filled())))
                    .map_err(|e| fail(&e))?;
                let y = 64 + 36 * i as i32;
                key.draw(&Circle::new((10, y + 6), 5, colour.filled()))
                    .map_err(|e| fail(&e))?;
                let name = format!("{} {}", p.scene, p.config);
                let figures = format!("{:.3} s, RMSE {:.3}", p.seconds, p.diff.rmse);
                key.draw(&Text::new(name, (22, y), font.clone()))
                    .map_err(|e| fail(&e))?;
                key.draw(&Text::new(figures, (22, y + 16), font.clone()))
                    .map_err(|e| fail(&e))?;
            }
        }
        root.present().map_err(|e| fail(&e))?;
    }
    wavefront::film::output::save_rgb8(path, w, h, &rgb)?;
    Ok(())
}
