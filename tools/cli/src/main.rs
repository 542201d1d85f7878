//! The `wavefront` command line (SPEC §9): argument parsing, I/O and printing only.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use wavefront::accel::kdtree::{BuildMethod, KdTree};
use wavefront::mesh::TriangleMesh;
use wavefront::output::{ImageFormat, ImageMeta, ImageStream};
use wavefront::scene::overrides::Overrides;
use wavefront::schedule::{MAX_WAVE_SAMPLES, Progress as ProgressObserver};
use wavefront::{Pipeline, RenderOptions, Scene, Stats, World, load_scene, render_into};

#[derive(Parser)]
#[command(
    name = "wavefront",
    version,
    about = "A data-oriented wavefront ray tracer"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file or built-in scene (spheres, sibenik, sibenik-shadows) to PNG or PPM.
    Render(RenderArgs),
    /// Print the stage pipeline a scene runs, depth by depth, without rendering.
    Plan(SceneArgs),
    /// Build or check kD trees in the text format of SPEC §6.
    #[command(subcommand)]
    Kdtree(KdtreeCommand),
    /// Measure error against run time; write report.md, report.csv and error_vs_time.png.
    Report(ReportArgs),
    /// Time each stage kernel alone on a snapshot of its input queue (and a full frame).
    Bench(BenchArgs),
}

#[derive(Args)]
struct BenchArgs {
    /// Scene file or built-in name.
    #[arg(default_value = "spheres")]
    scene: String,
    /// Mesh file replacing the scene's mesh path.
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Samples per pixel (the stages are timed on the first wave; the frame on all of it).
    #[arg(long)]
    samples: Option<u32>,
    /// Timed runs per kernel (best taken) and renders per frame (median taken).
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Print one JSON object per line instead of tables.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct ReportArgs {
    /// Scene file or built-in name (Sibenik parts run when its mesh is found).
    #[arg(default_value = "spheres")]
    scene: String,
    /// Output directory.
    #[arg(short, long, default_value = "report")]
    output: PathBuf,
    /// Timed renders per configuration (the median is reported).
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Image width and height (smaller is faster; the reference scenes are 512).
    #[arg(long)]
    size: Option<u32>,
    /// Samples per pixel of the convergence reference.
    #[arg(long, default_value_t = 1024)]
    reference_samples: u32,
    /// Sibenik mesh for the mesh parts.
    #[arg(long)]
    mesh: Option<PathBuf>,
}

#[derive(Args, Clone)]
struct SceneArgs {
    /// Scene file or built-in name.
    #[arg(default_value = "spheres")]
    scene: String,
    /// Samples per pixel.
    #[arg(long)]
    samples: Option<u32>,
    /// Maximum number of reflections after the primary ray.
    #[arg(long)]
    depth: Option<u32>,
    /// Trace shadow rays.
    #[arg(long, overrides_with = "no_shadows")]
    shadows: bool,
    /// Do not trace shadow rays.
    #[arg(long)]
    no_shadows: bool,
    /// kD tree: `sah`, `midpoint` or a tree file.
    #[arg(long)]
    kdtree: Option<String>,
    /// Mesh file replacing the scene's mesh path.
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Render the hit/miss mask instead of shading.
    #[arg(long)]
    mask: bool,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output image (.png or .ppm).
    #[arg(short, long, default_value = "out.png")]
    output: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Print per-stage statistics (rays in, rays out, time, Mrays/s).
    #[arg(long)]
    stats: bool,
    /// Upper bound on samples traced per wave (bounds memory; 1 to 2^28).
    #[arg(long, default_value_t = wavefront::schedule::DEFAULT_WAVE_SAMPLES)]
    wave_samples: usize,
}

#[derive(Clone, Copy, ValueEnum)]
enum Method {
    Sah,
    Midpoint,
}

#[derive(Subcommand)]
enum KdtreeCommand {
    /// Build a tree over an OBJ mesh and write it.
    Build {
        /// The OBJ mesh.
        mesh: PathBuf,
        /// Builder.
        #[arg(long, value_enum, default_value = "sah")]
        method: Method,
        /// Output tree file.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Validate a tree file against its mesh and print its statistics.
    Check {
        /// The tree file.
        tree: PathBuf,
        /// The OBJ mesh it indexes.
        #[arg(long)]
        mesh: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // No subcommand: render the default scene, as `wavefront render` does.
    let command = cli
        .command
        .or_else(|| Cli::parse_from(["wavefront", "render"]).command);
    let result = match command {
        Some(Command::Render(args)) => run_render(args),
        Some(Command::Plan(args)) => run_plan(&args),
        Some(Command::Kdtree(cmd)) => run_kdtree(cmd),
        Some(Command::Bench(args)) => run_bench(&args),
        Some(Command::Report(args)) => run_report(&args),
        None => unreachable!("defaulted to render above"),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn scene_from(args: &SceneArgs) -> Result<Scene> {
    let mut scene = load_scene(&args.scene)?;
    let shadows = match (args.shadows, args.no_shadows) {
        (_, true) => Some(false),
        (true, false) => Some(true),
        _ => None,
    };
    Overrides {
        samples: args.samples,
        depth: args.depth,
        shadows,
        kdtree: args.kdtree.as_deref().map(Overrides::tree_source),
        mesh: args.mesh.clone(),
        mask: args.mask,
    }
    .apply(&mut scene)?;
    Ok(scene)
}

fn run_plan(args: &SceneArgs) -> Result<()> {
    let scene = scene_from(args)?;
    let i = &scene.image;
    println!(
        "scene: {} ({}x{}, {} spp, max_depth {}, shadows {}, {} light(s))",
        scene.name,
        i.width,
        i.height,
        i.samples,
        scene.render.max_depth,
        if scene.render.shadows { "on" } else { "off" },
        scene.lights.len()
    );
    print!("{}", Pipeline::for_scene(&scene));
    Ok(())
}

fn run_render(args: RenderArgs) -> Result<()> {
    let scene = scene_from(&args.scene)?;
    // Refuse a bad output name before any work.
    ImageFormat::from_path(&args.output)?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        if n == 0 {
            bail!("invalid setting --threads: must be at least 1");
        }
        builder = builder.num_threads(n);
    }
    if !(1..=MAX_WAVE_SAMPLES).contains(&args.wave_samples) {
        bail!(
            "invalid setting --wave-samples: {} is out of range 1..={MAX_WAVE_SAMPLES}",
            args.wave_samples
        );
    }
    let pool = builder.build().context("cannot start the thread pool")?;
    let options = RenderOptions {
        wave_samples: args.wave_samples,
        ..RenderOptions::default()
    };
    let start = Instant::now();
    let (stats, world_seconds) = pool.install(|| -> Result<_> {
        let (world, setup) = World::load_timed(&scene)
            .with_context(|| format!("cannot load scene {}", scene.name))?;
        let world_seconds = start.elapsed().as_secs_f64();
        // Rows are encoded and written as their waves finish: memory follows the wave size,
        // not the image size.
        let image = &scene.image;
        let mut out = ImageStream::create(
            &args.output,
            (image.width, image.height),
            image.gamma,
            &ImageMeta::default(),
        )?;
        let bar = Progress::new();
        let mut stats = Stats::default();
        let progress = ProgressObserver(|done, total| bar.update(done, total));
        render_into(&scene, &world, &options, (&mut stats, progress), &mut out);
        bar.finish();
        out.finish()?;
        if args.stats
            && let Some(t) = world.triangles()
        {
            println!(
                "mesh: {} triangles, loaded in {:.1} ms; tree ({:?}) in {:.1} ms",
                t.mesh().len(),
                setup.load_seconds * 1e3,
                t.source(),
                setup.tree_seconds * 1e3
            );
        }
        Ok((stats, world_seconds))
    })?;
    if args.stats {
        println!("{stats}");
        println!(
            "scene {} at {} spp on {} thread(s): setup {:.1} ms, wall {:.1} ms",
            scene.name,
            scene.image.samples,
            pool.current_num_threads(),
            world_seconds * 1e3,
            start.elapsed().as_secs_f64() * 1e3
        );
    }
    Ok(())
}

fn run_bench(args: &BenchArgs) -> Result<()> {
    let mut scene = load_scene(&args.scene)?;
    Overrides {
        mesh: args.mesh.clone(),
        samples: args.samples,
        ..Overrides::default()
    }
    .apply(&mut scene)?;
    let threads = match args.threads {
        Some(0) => bail!("invalid setting --threads: must be at least 1"),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let config = wavefront_kit::bench::BenchConfig {
        threads,
        repeat: args.repeat,
    };
    let report = wavefront_kit::bench::run(&scene, config)
        .with_context(|| format!("cannot benchmark scene {}", scene.name))?;
    if args.json {
        print!("{}", report.json_lines());
        for n in &report.notes {
            eprintln!("note: {n}");
        }
    } else {
        print!("{report}");
    }
    Ok(())
}

fn run_report(args: &ReportArgs) -> Result<()> {
    use wavefront_kit::report::{ReportSettings, measure, write};
    let mut scene = load_scene(&args.scene)?;
    if let Some(n) = args.size {
        if n == 0 || n > wavefront::scene::file::MAX_IMAGE_SIDE {
            bail!(
                "invalid setting --size: {n} is out of range 1..={}",
                wavefront::scene::file::MAX_IMAGE_SIDE
            );
        }
        scene.image.width = n;
        scene.image.height = n;
    }
    if args.reference_samples == 0 || args.reference_samples > wavefront::scene::file::MAX_SAMPLES {
        bail!(
            "invalid setting --reference-samples: must be in 1..={}",
            wavefront::scene::file::MAX_SAMPLES
        );
    }
    let mut settings = ReportSettings::new(scene);
    settings.runs = args.runs.max(1);
    settings.reference_samples = args.reference_samples;
    if let Some(m) = &args.mesh {
        settings.sibenik_mesh = m.clone();
    }
    let report = measure(&settings, |line| eprintln!("{line}"))?;
    write(&report, &settings, &args.output)?;
    println!(
        "wrote {}/report.md, report.csv, error_vs_time.png",
        args.output.display()
    );
    Ok(())
}

/// A progress bar that only appears once a render has run for a second.
struct Progress {
    bar: ProgressBar,
    start: Instant,
}

impl Progress {
    fn new() -> Progress {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {percent:>3}% {elapsed} eta {eta}")
        {
            bar.set_style(style);
        }
        Progress {
            bar,
            start: Instant::now(),
        }
    }

    fn update(&self, done: u64, total: u64) {
        self.bar.set_length(total);
        self.bar.set_position(done);
        if self.bar.is_hidden() && self.start.elapsed() > Duration::from_secs(1) && done < total {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

fn load_mesh(path: &Path) -> Result<TriangleMesh> {
    if !path.exists() {
        return Err(wavefront::scene::builtin::missing_mesh(path).into());
    }
    Ok(TriangleMesh::load_obj(path)?)
}

fn run_kdtree(cmd: KdtreeCommand) -> Result<()> {
    match cmd {
        KdtreeCommand::Build {
            mesh,
            method,
            output,
        } => {
            let m = load_mesh(&mesh)?;
            let start = Instant::now();
            let method = match method {
                Method::Sah => BuildMethod::Sah,
                Method::Midpoint => BuildMethod::Midpoint,
            };
            let tree = KdTree::build(&m, method);
            let build = start.elapsed();
            let mut text = Vec::new();
            tree.write_text(&mut text)
                .context("cannot format the tree")?;
            wavefront::film::write_atomically(&output, &text)
                .with_context(|| format!("cannot write {}", output.display()))?;
            println!(
                "built {method:?} tree over {} triangles in {:.1} ms",
                m.len(),
                build.as_secs_f64() * 1e3
            );
            println!("{}", tree.stats(&m));
            Ok(())
        }
        KdtreeCommand::Check { tree, mesh } => {
            let m = load_mesh(&mesh)?;
            let t = KdTree::load_text(&tree, m.len())?;
            t.validate(&m)
                .map_err(|e| anyhow::anyhow!("{}: invalid tree: {e}", tree.display()))?;
            println!("{}: valid", tree.display());
            println!("{}", t.stats(&m));
            Ok(())
        }
    }
}
