//! The `wavefront` command line (SPEC §9): argument parsing, I/O and printing only.

/// `println!` that returns an error ("cannot write to stdout": a closed pipe, a full disk) from
/// the enclosing function instead of panicking (`wavefront plan … | head -0`).
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
            .map_err(|e| anyhow::Error::new(e).context("cannot write to stdout"))?
    }};
}

/// `print!` as [`outln!`] is `println!`.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($arg)*)
            .map_err(|e| anyhow::Error::new(e).context("cannot write to stdout"))?
    }};
}

mod farm;
mod feedback;
mod frames;
#[cfg(test)]
mod fuzz_args;
mod info;
mod merge;
mod plan;
mod tile;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};

use wavefront::accel::kdtree::BuildMethod;
use wavefront::film::output::{ImageFormat, ImageMeta, ImageStream, PartialFile};
use wavefront::mesh::ObjMesh;
use wavefront::scene::overrides::Overrides;
use wavefront::scene::set::Setting;
use wavefront::schedule::{MAX_WAVE_SAMPLES, Progress as ProgressObserver};
use wavefront::world::frame::RenderFrame;
use wavefront::{
    Pipeline, RenderOptions, Scene, Stage, Stats, World, load_scene, load_scene_with, render,
    render_into,
};

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
    /// Render a scene file or built-in scene (spheres, sibenik, sibenik-shadows, many-spheres) to
    /// PNG or PPM.
    Render(RenderArgs),
    /// Print the stage pipeline a scene runs, depth by depth, without rendering.
    Plan(SceneArgs),
    /// Describe a scene or a mesh: triangles, vertices, bounds, materials and their faces,
    /// lights, the camera and the pipeline.
    Info(InfoArgs),
    /// Build or check kD trees in the text format of SPEC §6.
    #[command(subcommand)]
    Kdtree(KdtreeCommand),
    /// Measure error against run time; write report.md, report.csv and error_vs_time.png.
    Report(ReportArgs),
    /// Time each stage kernel alone on a snapshot of its input queue (and a full frame).
    Bench(BenchArgs),
    /// Merge tiles (`render --tile`, `--pixel-bounds`) into the full image, byte-identical to a
    /// single render; writes nothing unless the tiles cover every pixel exactly once.
    Merge(merge::MergeArgs),
    /// Write (and submit) render-farm jobs.
    #[command(subcommand)]
    Farm(farm::FarmCommand),
}

/// Arguments of `info`.
#[derive(Args)]
struct InfoArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// One JSON object instead of text.
    #[arg(long)]
    json: bool,
}

/// Where the tree cache lives (render, bench, kdtree build).
#[derive(Args, Clone, Default)]
struct CacheArgs {
    /// Tree cache folder (default: $XDG_CACHE_HOME/wavefront or ~/.cache/wavefront).
    #[arg(long, value_name = "DIR", conflicts_with = "no_cache")]
    cache: Option<PathBuf>,
    /// Neither read nor write the tree cache.
    #[arg(long)]
    no_cache: bool,
}

impl CacheArgs {
    /// The cache to use, if any (none when no folder is known).
    fn cache(&self) -> Option<wavefront::accel::cache::TreeCache> {
        if self.no_cache {
            return None;
        }
        self.cache
            .clone()
            .or_else(wavefront::accel::cache::TreeCache::default_dir)
            .map(wavefront::accel::cache::TreeCache::new)
    }
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
    #[command(flatten)]
    cache: CacheArgs,
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
    #[arg(long, conflicts_with = "no_shadows")]
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
    /// Image size, WIDTHxHEIGHT (sets image.width and image.height).
    #[arg(long, value_name = "WxH")]
    size: Option<String>,
    /// Set a scene-file key by its dotted path to a TOML value, e.g. `render.max_depth=3`,
    /// `light.0.position=[1,2,3]` (repeatable; checked as the file's own keys are).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output image (.png, .ppm or .exr).
    #[arg(short, long, default_value = "out.png")]
    output: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Print per-stage statistics (rays in, rays out, time, Mrays/s).
    #[arg(long)]
    stats: bool,
    /// No progress and no summary line: errors only.
    #[arg(long, short)]
    quiet: bool,
    /// Upper bound on samples traced per wave (bounds memory; 1 to 2^28).
    #[arg(long, default_value_t = wavefront::schedule::DEFAULT_WAVE_SAMPLES)]
    wave_samples: usize,
    #[command(flatten)]
    part: plan::PartArgs,
    #[command(flatten)]
    cache: CacheArgs,
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
        /// Worker threads of the build (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Print one JSON object (triangles, threads, load_seconds, build_seconds, ...) instead
        /// of text.
        #[arg(long)]
        json: bool,
        /// The tree cache the built tree is also stored in (never read: build always builds).
        #[command(flatten)]
        cache: CacheArgs,
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

/// Most worker threads `--threads` takes: more is a typo, not a machine (rayon would spend
/// seconds starting them before failing).
const MAX_THREADS: usize = 1024;

/// `--threads N`, checked: 1 to [`MAX_THREADS`].
fn check_threads(threads: Option<usize>) -> Result<Option<usize>> {
    match threads {
        Some(n) if !(1..=MAX_THREADS).contains(&n) => {
            bail!("invalid setting --threads: {n} is out of range 1..={MAX_THREADS}")
        }
        t => Ok(t),
    }
}

/// Memory a wave takes per sample, rounded up from a measurement (`--wave-samples 16777216`
/// peaked at 3.7 GB: 220 bytes a sample, for the ray, hit and shadow queues and the sample
/// buffer).
const WAVE_BYTES_PER_SAMPLE: u64 = 256;

/// Memory an EXR output takes per pixel of the rows it holds: the stream's rows (12 bytes of
/// linear RGB), the encoder's copy and its compressed blocks (12 each), and slack.
const EXR_BYTES_PER_PIXEL: u64 = 48;

/// The memory this machine has available (`MemAvailable` of `/proc/meminfo`), if known.
fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses a setting whose memory (`bytes`, estimated before anything is allocated) exceeds what
/// the machine has available, saying how much and why; no check where that is not known.
fn check_memory(setting: &str, what: &str, bytes: u64) -> Result<()> {
    if let Some(available) = available_memory()
        && bytes > available
    {
        bail!(
            "invalid setting {setting}: {what} needs about {} of memory, more than the {} available",
            wavefront::input::size(bytes),
            wavefront::input::size(available)
        );
    }
    Ok(())
}

/// On SIGINT, SIGTERM or SIGHUP: remove this process's temporary output files (old outputs stay
/// intact) and end with the shell's code for the signal (128 + its number).
fn remove_partials_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        return; // without a handler, the default action ends the process as before
    };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            wavefront::film::output::remove_partials();
            std::process::exit(128 + signal);
        }
    });
}

fn main() -> ExitCode {
    remove_partials_on_signals();
    let cli = Cli::parse();
    // No subcommand: render the default scene, as `wavefront render` does.
    let command = cli
        .command
        .or_else(|| Cli::parse_from(["wavefront", "render"]).command);
    let result = match command {
        Some(Command::Render(args)) => run_render(args),
        Some(Command::Plan(args)) => run_plan(&args),
        Some(Command::Info(args)) => run_info(&args),
        Some(Command::Kdtree(cmd)) => run_kdtree(cmd),
        Some(Command::Bench(args)) => run_bench(&args),
        Some(Command::Report(args)) => run_report(&args),
        Some(Command::Merge(args)) => merge::run(&args),
        Some(Command::Farm(cmd)) => farm::run(cmd),
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
    let mut settings = vec![];
    if let Some(size) = &args.size {
        settings.extend(Setting::size(size)?);
    }
    for s in &args.set {
        settings.push(s.parse::<Setting>()?);
    }
    let mut scene = load_scene_with(&args.scene, &settings)?;
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

fn run_info(args: &InfoArgs) -> Result<()> {
    use std::io::Write as _;
    let info = info::Info::of(scene_from(&args.scene)?)?;
    let text = if args.json {
        format!("{}\n", info.json())
    } else {
        info.text()
    };
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("cannot write to stdout")
}

fn run_plan(args: &SceneArgs) -> Result<()> {
    let scene = scene_from(args)?;
    let i = &scene.image;
    outln!(
        "scene: {} ({}x{}, {} spp, max_depth {}, shadows {}, {} light(s))",
        scene.name,
        i.width,
        i.height,
        i.samples,
        scene.render.max_depth,
        if scene.render.shadows { "on" } else { "off" },
        scene.lights.len()
    );
    out!("{}", Pipeline::for_scene(&scene));
    Ok(())
}

fn run_render(args: RenderArgs) -> Result<()> {
    let scene = scene_from(&args.scene)?;
    let feedback = feedback::Feedback::new(args.quiet, args.stats);
    // Refuse a bad output name before any work.
    let exr = wavefront::film::output::is_exr(&args.output);
    if !exr {
        ImageFormat::from_path(&args.output)?;
    }
    let jobs = plan::RenderPlan::new(&scene, &args.part, &args.output, |v| std::env::var(v).ok())?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = check_threads(args.threads)? {
        builder = builder.num_threads(n);
    }
    if !(1..=MAX_WAVE_SAMPLES).contains(&args.wave_samples) {
        bail!(
            "invalid setting --wave-samples: {} is out of range 1..={MAX_WAVE_SAMPLES}",
            args.wave_samples
        );
    }
    check_memory(
        "--wave-samples",
        &format!("{} samples a wave", args.wave_samples),
        args.wave_samples as u64 * WAVE_BYTES_PER_SAMPLE,
    )?;
    if exr {
        // Streamed: a block row of f32 RGB in the stream and as many in the encoder.
        check_memory(
            &args.output.display().to_string(),
            &format!("a {}-pixel-wide EXR", scene.image.width),
            2 * wavefront::film::output::exr_block_rows() as u64
                * u64::from(scene.image.width)
                * EXR_BYTES_PER_PIXEL,
        )?;
    }
    let pool = builder.build().context("cannot start the thread pool")?;
    let options = RenderOptions {
        wave_samples: args.wave_samples,
        region: jobs.region,
        ..RenderOptions::default()
    };
    let mut todo: Vec<&plan::FrameJob> = Vec::with_capacity(jobs.frames.len());
    for job in &jobs.frames {
        if args.part.skip_existing && job.output.exists() {
            outln!("skipped {} (exists)", job.output.display());
        } else {
            todo.push(job);
        }
    }
    if todo.is_empty() {
        return Ok(());
    }
    let start = Instant::now();
    pool.install(|| -> Result<()> {
        // One mesh load and one tree for every frame; each frame moves them to its own eye.
        let loading = feedback.spinner(format!("loading {}", scene.name));
        let cache = args.cache.cache();
        let (world, setup) = World::load_cached(&scene, cache.as_ref())
            .with_context(|| format!("cannot load scene {}", scene.name))?;
        loading.finish_and_clear();
        for w in &setup.warnings {
            eprintln!("warning: {w}");
        }
        let cache_status = setup.cache.clone();
        let setup = setup.times;
        let world_seconds = start.elapsed().as_secs_f64();
        if args.stats
            && let Some(t) = world.triangles()
        {
            outln!(
                "mesh: {} triangles, loaded in {:.1} ms; tree ({:?}) in {:.1} ms; cache: {:?}",
                t.mesh().len(),
                setup.load_seconds * 1e3,
                t.source(),
                setup.tree_seconds * 1e3,
                cache_status
            );
        }
        let sources = match jobs.region {
            Some(_) => Some(
                crate::tile::SourceDigest::of(&scene)
                    .context("cannot read the scene's files to fingerprint the tile")?,
            ),
            None => None,
        };
        // Each frame's summary counts from the end of the one before (the first from the
        // command's start, so a single image reports the whole command).
        let mut since = start;
        for job in todo {
            // Rendering moves the world to this frame's eye (World::reframed) when it moved.
            let bar = feedback.progress();
            let progress = ProgressObserver(|done, total| bar.update(done, total));
            let stats = match sources {
                // A tile keeps its (region-sized) film to write it with its metadata.
                Some(sources) => {
                    let (film, stats) =
                        render(&job.scene, &world, options.clone(), |done, total| {
                            bar.update(done, total)
                        });
                    plan::save_part(&film, job, jobs.region, sources)?;
                    stats
                }
                // A whole image is encoded row by row (EXR: block row by block row) as its
                // waves finish: memory follows the wave size, not the image size.
                None => {
                    let image = &job.scene.image;
                    let mut out = ImageStream::create(
                        &job.output,
                        (image.width, image.height),
                        image.gamma,
                        &ImageMeta::default(),
                    )?;
                    let mut stats = Stats::default();
                    render_into(
                        &job.scene,
                        &world,
                        &options,
                        (&mut stats, progress),
                        &mut out,
                    );
                    out.finish()?;
                    stats
                }
            };
            bar.finish();
            if jobs.announce && !args.quiet {
                outln!("wrote {}", job.output.display());
            }
            let image = &job.scene.image;
            let rays = stats
                .entries
                .iter()
                .filter(|((_, stage), _)| matches!(stage, Stage::Intersect | Stage::Shadow))
                .map(|(_, e)| e.rays_in)
                .sum();
            feedback.summary(&feedback::Summary {
                output: &job.output,
                width: image.width,
                height: image.height,
                samples: image.samples,
                seconds: since.elapsed().as_secs_f64(),
                rays,
            });
            since = Instant::now();
            if args.stats {
                outln!("{stats}");
                outln!(
                    "scene {} at {} spp on {} thread(s): setup {:.1} ms, wall {:.1} ms",
                    scene.name,
                    scene.image.samples,
                    rayon::current_num_threads(),
                    world_seconds * 1e3,
                    start.elapsed().as_secs_f64() * 1e3
                );
            }
        }
        Ok(())
    })
}

fn run_bench(args: &BenchArgs) -> Result<()> {
    let mut scene = load_scene(&args.scene)?;
    Overrides {
        mesh: args.mesh.clone(),
        samples: args.samples,
        ..Overrides::default()
    }
    .apply(&mut scene)?;
    if args.repeat == 0 {
        bail!("invalid setting --repeat: must be at least 1");
    }
    let threads = match check_threads(args.threads)? {
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let config = wavefront_kit::bench::BenchConfig {
        threads,
        repeat: args.repeat,
        cache: args.cache.cache(),
    };
    let report = wavefront_kit::bench::run(&scene, config)
        .with_context(|| format!("cannot benchmark scene {}", scene.name))?;
    if args.json {
        out!("{}", report.json_lines());
        for n in &report.notes {
            eprintln!("note: {n}");
        }
    } else {
        out!("{report}");
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
    outln!(
        "wrote {}/report.md, report.csv, error_vs_time.png",
        args.output.display()
    );
    Ok(())
}

/// A rayon pool of `threads` threads (all cores when `None`); 0 is an error.
fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = check_threads(threads)? {
        builder = builder.num_threads(n);
    }
    builder.build().context("cannot start the thread pool")
}

/// `kdtree build`: reads the mesh, builds in the frame centred on it, writes the tree file (world
/// coordinates) and stores the mesh and tree in the cache (it never reads the cache).
fn build_tree(
    mesh: &Path,
    method: BuildMethod,
    output: &Path,
    json: bool,
    cache: &CacheArgs,
) -> Result<()> {
    wavefront::world::check_mesh_file(mesh, None)?;
    let start = Instant::now();
    let store = cache.cache();
    let (bytes, sources) = wavefront::world::read_mesh_file(mesh, store.is_some())?;
    wavefront::world::check_mesh_bytes(mesh, &bytes)?;
    let obj = wavefront::mesh::obj_fast::read_bytes(mesh, &bytes)?;
    let load = start.elapsed().as_secs_f64();
    // The entry a render's cache miss builds: the tree in the frame centred on the mesh.
    let triangles = vec![obj.len() as u64];
    let (entry, m, phases) = wavefront::world::centred_entry(obj, triangles, method)?;
    let build = phases.wall_seconds;
    let frame = RenderFrame::at(entry.origin);
    // Streamed to a partial file renamed over the output when complete: the text of a large tree
    // (~330 B a triangle) is never held in memory, and a failed write leaves no file behind.
    let cannot_write = || format!("cannot write {}", output.display());
    let (partial, file) = PartialFile::create(output).with_context(cannot_write)?;
    entry
        .tree
        .write_text_in(file, &frame)
        .with_context(cannot_write)?;
    partial.commit().with_context(cannot_write)?;
    let stats = entry.tree.stats(&m);
    let mut stored = None;
    if let Some(c) = store {
        let key = wavefront::world::cache_key(method, &[bytes], &[sources]);
        match c.store(key, &entry) {
            Ok(path) => stored = Some(path),
            Err(e) => eprintln!(
                "warning: cannot write cache entry {}: {e}",
                c.path_of(key).display()
            ),
        }
    }
    if json {
        let method = match method {
            BuildMethod::Sah => "sah",
            BuildMethod::Midpoint => "midpoint",
        };
        outln!(
            "{{\"mesh\":{},\"method\":\"{method}\",\"triangles\":{},\"threads\":{},\"load_seconds\":{load:.6},\"build_seconds\":{build:.6},\"nodes\":{},\"leaves\":{},\"empty_leaves\":{},\"references\":{},\"max_depth\":{},\"mean_tris_per_leaf\":{:.3},\"max_tris_per_leaf\":{},\"sah_cost\":{:.4},\"phases\":{{\"input_seconds\":{:.6},\"bounds_seconds\":{:.6},\"top_thread_seconds\":{:.6},\"task_thread_seconds\":{:.6},\"tasks\":{}}},\"cache\":{}}}",
            json_string(&mesh.display().to_string()),
            m.len(),
            rayon::current_num_threads(),
            stats.nodes,
            stats.leaves,
            stats.empty_leaves,
            stats.references,
            stats.max_depth,
            stats.mean_tris_per_leaf,
            stats.max_tris_per_leaf,
            stats.sah_cost,
            phases.input_seconds,
            phases.bounds_seconds,
            phases.top_seconds,
            phases.task_seconds,
            phases.tasks,
            stored.map_or("null".to_string(), |p| json_string(
                &p.display().to_string()
            ))
        );
    } else {
        outln!(
            "built {method:?} tree over {} triangles in {:.1} ms (mesh read in {:.1} ms, {} thread(s))",
            m.len(),
            build * 1e3,
            load * 1e3,
            rayon::current_num_threads()
        );
        outln!("{stats}");
    }
    Ok(())
}

/// `s` as a JSON string literal.
fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

fn run_kdtree(cmd: KdtreeCommand) -> Result<()> {
    match cmd {
        KdtreeCommand::Build {
            mesh,
            method,
            output,
            threads,
            json,
            cache,
        } => {
            let pool = thread_pool(threads)?;
            let method = match method {
                Method::Sah => BuildMethod::Sah,
                Method::Midpoint => BuildMethod::Midpoint,
            };
            pool.install(|| build_tree(&mesh, method, &output, json, &cache))
        }
        KdtreeCommand::Check { tree, mesh } => {
            wavefront::world::check_mesh_file(&mesh, None)?;
            let obj = ObjMesh::read(&mesh)?;
            // As `render --kdtree FILE` checks it.
            let (t, m) = wavefront::world::check_tree_file(&tree, &obj.positions, &obj.indices)?;
            outln!("{}: valid", tree.display());
            outln!("{}", t.stats(&m));
            Ok(())
        }
    }
}
