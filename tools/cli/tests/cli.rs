//! The command line (SPEC §9), run as a separate process in a scratch directory.

use std::path::Path;
use std::process::{Command, Output};

use wavefront_kit::testkit::{self, SCENE_TOKENS, mutate_from};

/// A scratch directory ([`testkit::Scratch`], removed on drop) to run the binary in.
struct Scratch(testkit::Scratch);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(testkit::Scratch::new(&format!("cli-{name}")))
    }

    fn path(&self) -> &Path {
        self.0.path()
    }

    /// Runs the binary with `args` in this directory.
    fn run(&self, args: &[&str]) -> Output {
        self.0
            .command(env!("CARGO_BIN_EXE_wavefront"))
            .args(args)
            .output()
            .expect("cannot run the wavefront binary")
    }

    /// Names of the files in the directory, sorted.
    fn files(&self) -> Vec<String> {
        self.0.files()
    }
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `args`, which must fail cleanly: non-zero exit, one `error:` line on stderr, no panic,
/// and no new file in the directory (no output, no `*.partial`). Returns the error line.
fn assert_clean_failure(dir: &Scratch, args: &[&str]) -> String {
    let before = dir.files();
    let o = dir.run(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} succeeded; stderr: {err}");
    assert!(
        !err.contains("panicked"),
        "{args:?} panicked instead of reporting an error:\n{err}"
    );
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(
        lines.len(),
        1,
        "{args:?}: expected one line on stderr:\n{err}"
    );
    assert!(
        lines[0].starts_with("error:"),
        "{args:?}: stderr does not start with `error:`:\n{err}"
    );
    assert_eq!(dir.files(), before, "{args:?} left files behind");
    lines[0].to_owned()
}

#[test]
fn render_without_arguments_writes_out_png() {
    let dir = Scratch::new("default");
    let o = dir.run(&["render"]);
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    assert_eq!(dir.files(), vec!["out.png"]);
    let img = image::open(dir.path().join("out.png")).expect("out.png is not a readable image");
    assert_eq!((img.width(), img.height()), (512, 512));
    assert_eq!(
        image::ImageFormat::from_path(dir.path().join("out.png")).unwrap(),
        image::ImageFormat::Png
    );
    let bytes = std::fs::read(dir.path().join("out.png")).unwrap();
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not PNG data");
}

#[test]
fn render_to_ppm_writes_binary_p6() {
    let dir = Scratch::new("ppm");
    let o = dir.run(&["render", "spheres", "-o", "x.ppm"]);
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    assert_eq!(dir.files(), vec!["x.ppm"]);
    let bytes = std::fs::read(dir.path().join("x.ppm")).unwrap();
    assert!(bytes.starts_with(b"P6"), "not a binary PPM");
    let header_and_pixels = 512 * 512 * 3;
    assert!(bytes.len() > header_and_pixels && bytes.len() < header_and_pixels + 64);
}

#[test]
fn plan_lists_depths_0_to_2_and_no_kd_tree_stage() {
    let dir = Scratch::new("plan");
    let o = dir.run(&["plan", "spheres"]);
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    let out = stdout(&o);
    for depth in 0..=2 {
        assert!(
            out.contains(&format!("depth {depth}:")),
            "no depth {depth}:\n{out}"
        );
    }
    assert!(!out.contains("depth 3"), "{out}");
    let stage_lines: Vec<&str> = out.lines().filter(|l| l.starts_with("depth")).collect();
    for l in &stage_lines {
        let l = l.to_lowercase();
        assert!(
            !l.contains("kd") && !l.contains("kdtree"),
            "kD stage in: {l}"
        );
    }
    assert!(stage_lines[0].contains("generate") && stage_lines[0].contains("reflect"));
    assert!(!stage_lines[2].contains("reflect"), "{out}");
    assert!(out.contains("no kD tree"), "{out}");
    assert!(dir.files().is_empty(), "plan wrote files");
}

#[test]
fn stats_print_a_line_for_each_stage() {
    let dir = Scratch::new("stats");
    let o = dir.run(&["render", "--stats", "--depth", "1"]);
    assert!(o.status.success(), "stderr: {}", stderr(&o));
    let out = stdout(&o);
    for label in ["generate", "intersect", "shade", "shadow", "reflect"] {
        assert!(
            out.lines()
                .any(|l| l.split_whitespace().nth(1) == Some(label)),
            "no stats line for {label}:\n{out}"
        );
    }
}

#[test]
fn a_missing_scene_file_is_a_clean_error() {
    let dir = Scratch::new("missing");
    let line = assert_clean_failure(&dir, &["render", "nonexistent.toml"]);
    assert!(line.contains("nonexistent.toml"), "{line}");
}

#[test]
fn an_unknown_built_in_is_a_clean_error() {
    let dir = Scratch::new("unknown");
    let line = assert_clean_failure(&dir, &["render", "teapot"]);
    assert!(
        line.contains("teapot") && line.contains("spheres"),
        "{line}"
    );
}

#[test]
fn malformed_toml_names_file_and_line() {
    let dir = Scratch::new("malformed");
    std::fs::write(
        dir.path().join("bad.toml"),
        "[image]\nwidth = 512\nheight = = 3\n",
    )
    .unwrap();
    let line = assert_clean_failure(&dir, &["render", "bad.toml"]);
    assert!(line.contains("bad.toml:3"), "file:line missing: {line}");
}

#[test]
fn zero_samples_is_a_clean_error() {
    let dir = Scratch::new("samples");
    let line = assert_clean_failure(&dir, &["render", "--samples", "0"]);
    assert!(line.contains("--samples"), "{line}");
}

#[test]
fn a_directory_as_the_scene_says_its_cause_once() {
    let dir = Scratch::new("dirscene");
    let scene = std::env::temp_dir();
    let line = assert_clean_failure(&dir, &["render", scene.to_str().unwrap()]);
    assert!(line.starts_with("error: cannot read scene file "), "{line}");
    // Each part of the chain once: `error: what failed: why`, never `…: why: why`.
    let parts: Vec<&str> = line.trim_start_matches("error: ").split(": ").collect();
    for (i, part) in parts.iter().enumerate() {
        assert!(
            !parts[i + 1..].contains(part),
            "{part:?} repeated in: {line}"
        );
    }
    assert_eq!(parts.len(), 2, "what failed, then the OS error: {line}");
}

#[test]
fn an_out_of_range_wave_size_is_a_clean_error() {
    let dir = Scratch::new("wave");
    for n in ["0", "1000000000000"] {
        let line = assert_clean_failure(&dir, &["render", "--wave-samples", n]);
        assert!(line.contains("--wave-samples"), "{line}");
    }
}

#[test]
fn zero_threads_is_a_clean_error() {
    let dir = Scratch::new("threads");
    let line = assert_clean_failure(&dir, &["render", "--threads", "0"]);
    assert!(line.contains("--threads"), "{line}");
}

#[test]
fn an_unsupported_output_format_is_a_clean_error() {
    let dir = Scratch::new("jpg");
    let line = assert_clean_failure(&dir, &["render", "-o", "x.jpg"]);
    assert!(line.contains("x.jpg"), "{line}");
}

#[test]
fn output_into_a_missing_directory_is_a_clean_error() {
    let dir = Scratch::new("nodir");
    let line = assert_clean_failure(&dir, &["render", "-o", "nodir/x.png"]);
    assert!(line.contains("nodir"), "{line}");
}

#[test]
fn a_missing_mesh_says_where_to_put_it() {
    let dir = Scratch::new("mesh");
    let line = assert_clean_failure(&dir, &["render", "sibenik", "--mesh", "/nonexistent.obj"]);
    assert!(line.contains("/nonexistent.obj"), "{line}");
    assert!(
        line.contains("../shared/data/sibenik/sibenik.obj"),
        "does not say where the mesh belongs: {line}"
    );
}

#[test]
fn report_writes_markdown_csv_and_plot() {
    let s = Scratch::new("report");
    let out = s.run(&[
        "report",
        "spheres",
        "--size",
        "32",
        "--reference-samples",
        "4",
        "--runs",
        "1",
        "--mesh",
        "missing/sibenik.obj",
        "-o",
        "rep",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = s.path().join("rep");
    let csv = std::fs::read_to_string(dir.join("report.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(
        rows.iter()
            .filter(|r| r.starts_with("convergence,"))
            .count(),
        5,
        "{csv}"
    );
    assert!(rows.iter().any(|r| r.starts_with("precision,")), "{csv}");
    assert!(rows.iter().any(|r| r.contains("fixed epsilon")), "{csv}");
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(
        md.contains("error_vs_time.png") && md.contains("Sibenik parts skipped"),
        "{md}"
    );
    let plot = image::open(dir.join("error_vs_time.png")).unwrap();
    assert_eq!((plot.width(), plot.height()), (1400, 1000));
}

/// Scene A as shipped, the base of the mutations.
const SPHERES: &str = include_str!("../../../scenes/spheres.toml");

#[test]
fn the_cli_rejects_mutated_scenes_cleanly() {
    let scratch = Scratch::new("mutated");
    let dir = scratch.path().to_path_buf();
    let mut rejected = 0;
    // A fixed, seeded selection of mutations, each through the real binary.
    for k in 0..40usize {
        let text = mutate_from(
            SCENE_TOKENS,
            SPHERES,
            (k % 3) as u8,
            k * 7919,
            k * 31,
            k * 13,
        );
        let scene = dir.join(format!("s{k}.toml"));
        std::fs::write(&scene, &text).unwrap();
        let out = dir.join(format!("o{k}.png"));
        let run = Command::new(env!("CARGO_BIN_EXE_wavefront"))
            .env("XDG_CACHE_HOME", dir.join("cache"))
            .args([
                "render",
                scene.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
                "--samples",
                "1",
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(
            !stderr.contains("panicked"),
            "panic on mutation {k}: {stderr}"
        );
        if run.status.success() {
            assert!(out.exists(), "success without an image on mutation {k}");
        } else {
            rejected += 1;
            assert_eq!(run.status.code(), Some(1), "{stderr}");
            assert!(stderr.starts_with("error: "), "{stderr}");
            assert_eq!(stderr.trim_end().lines().count(), 1, "one line: {stderr}");
            assert!(!out.exists(), "output left behind on mutation {k}");
        }
    }
    assert!(
        rejected > 5,
        "the mutations must produce errors to test ({rejected})"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
        .collect();
    assert!(leftovers.is_empty(), "partial files left: {leftovers:?}");
}

#[test]
fn without_a_terminal_a_successful_render_prints_nothing_unless_asked() {
    let dir = Scratch::new("quiet-pipe");
    let o = dir.run(&["render", "-o", "a.png", "--samples", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stderr(&o), "", "stderr is a pipe: errors only");
    assert_eq!(stdout(&o), "");
    let o = dir.run(&["render", "-o", "b.png", "--stats"]);
    let err = stderr(&o);
    assert!(
        err.starts_with("wrote b.png: 512x512, 1 spp, ") && err.trim_end().ends_with("Mrays/s"),
        "--stats asks for the summary line: {err}"
    );
}

/// Runs the binary under a pseudo-terminal (util-linux `script`) in `dir`; returns what the
/// terminal showed.
fn run_in_terminal(dir: &Scratch, args: &str) -> String {
    let command = format!("{} {args}", env!("CARGO_BIN_EXE_wavefront"));
    let o = Command::new("script")
        .args(["-qec", &command, "/dev/null"])
        .current_dir(dir.path())
        .output()
        .expect("util-linux `script` runs the binary under a pseudo-terminal");
    assert!(o.status.success(), "{}", stderr(&o));
    stdout(&o)
}

#[test]
fn on_a_terminal_a_render_ends_with_one_summary_line_and_quiet_silences_it() {
    let dir = Scratch::new("terminal");
    let shown = run_in_terminal(&dir, "render -o a.png --samples 4");
    let lines: Vec<&str> = shown
        .lines()
        .filter(|l| l.contains("wrote a.png"))
        .collect();
    assert_eq!(lines.len(), 1, "one summary line: {shown:?}");
    assert!(lines[0].contains("512x512, 4 spp"), "{shown:?}");
    let quiet = run_in_terminal(&dir, "render -o b.png --quiet");
    assert!(!quiet.contains("wrote"), "--quiet: {quiet:?}");
    assert!(dir.path().join("b.png").exists());
}

#[test]
fn exr_tiles_merge_into_the_single_linear_render() {
    let dir = Scratch::new("exr-tiles");
    for args in [
        vec!["render", "--samples", "2", "-o", "full.exr"],
        vec!["render", "--samples", "2", "--tile", "0/3", "-o", "t0.exr"],
        vec!["render", "--samples", "2", "--tile", "1/3", "-o", "t1.exr"],
        vec!["render", "--samples", "2", "--tile", "2/3", "-o", "t2.exr"],
        vec!["merge", "t2.exr", "t0.exr", "t1.exr", "-o", "merged.exr"],
    ] {
        let o = dir.run(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
    let full = wavefront::film::output::read_exr(&dir.path().join("full.exr")).unwrap();
    let merged = wavefront::film::output::read_exr(&dir.path().join("merged.exr")).unwrap();
    assert_eq!(full.size, (512, 512));
    assert!(
        merged.pixels == full.pixels,
        "merged EXR tiles differ from the single render"
    );
    // EXR tiles cannot become a PNG: a clean error, no file.
    let line = assert_clean_failure(
        &dir,
        &["merge", "t0.exr", "t1.exr", "t2.exr", "-o", "m.png"],
    );
    assert!(line.contains("m.png") && line.contains(".exr"), "{line}");
}
