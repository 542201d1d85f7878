//! Issue 21, item 6: the command line fuzzed in-process. Seeded mutations of valid command lines
//! (tokens replaced, dropped, doubled, swapped, spliced from another line, cut short, a character
//! flipped, huge / negative / non-finite numbers) go through the real clap parser and, for
//! `render`, `plan`, `info` and `bench`, through the checks a command makes before any work
//! (scene and `--set`/`--size` overrides, output format, tile / frame plan, thread count, wave size,
//! memory estimates). Every case must parse or fail with a clap error, and every check must pass
//! or fail with a one-line error: never a panic. Nothing is rendered or written.
//!
//! `WAVEFRONT_FUZZ_CASES` (default 10,000) and `WAVEFRONT_FUZZ_SEED` (default 21) as in
//! `tests/fuzz.rs`: `WAVEFRONT_FUZZ_CASES=1000000 cargo test --release -p wavefront-cli --bin
//! wavefront fuzz` is the longer run.

use std::ffi::OsString;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::{Duration, Instant};
use wavefront_kit::fuzz::Rng;

use anyhow::Result;
use clap::Parser;

use crate::{Cli, Command, MAX_WAVE_SAMPLES, check_threads, plan, scene_from};

/// Valid command lines the mutations start from.
const LINES: &[&str] = &[
    "render spheres -o out.png --threads 2 --wave-samples 4096 --samples 4 --depth 3 --no-shadows -q",
    "render spheres -o out.ppm --size 64x48 --set image.width=32 --set render.max_depth=2 --stats",
    "render sibenik -o f.exr --kdtree sah --mask --shadows",
    "render spheres -o t.png --tile 2/4 --skip-existing",
    "render spheres -o p.png --pixel-bounds 0,8,0,8 --frames 1-3 --no-cache",
    "plan spheres --samples 2 --shadows --kdtree midpoint",
    "info spheres --json --depth 2 --size 16x16",
    "bench spheres --threads 1 --repeat 2 --samples 1 --no-cache --json",
    "kdtree build m.obj -o t.kd --method midpoint --threads 1 --json",
    "kdtree check t.kd --mesh m.obj",
    "merge a.png b.png -o m.png",
    "farm slurm spheres --tiles 4 -o f.png --frames 1-2 --frames-per-task 1",
];

/// Tokens a mutation may put in: numbers at and past every edge, option names, odd strings.
const TOKENS: &[&str] = &[
    "0",
    "1",
    "-1",
    "4294967296",
    "18446744073709551616",
    "1e308",
    "1e-308",
    "nan",
    "inf",
    "-inf",
    "268435456",
    "1024",
    "1025",
    "0x10",
    "",
    " ",
    "=",
    "-",
    "--",
    "---",
    "-o",
    "--threads",
    "--wave-samples",
    "--samples",
    "--depth",
    "--size",
    "--set",
    "--tile",
    "--frames",
    "--pixel-bounds",
    "--kdtree",
    "--mesh",
    "--cache",
    "--no-cache",
    "--shadows",
    "--no-shadows",
    "--repeat",
    "-q",
    "--help",
    "--version",
    "0x0",
    "100000x100000",
    "65536x1",
    "1x",
    "x1",
    "image.width=0",
    "image.width=1e9",
    "render.max_depth=-1",
    "camera.fov_y=nan",
    "a=b",
    "=",
    "0/0",
    "5/4",
    "1/0",
    "3-1",
    "1-",
    "-5",
    "0,0,0,0",
    "8,0,0,8",
    "1,2,3",
    "a.exr",
    "a.jpg",
    "/dev/null",
    "/",
    ".",
    "..",
    "none",
    "sah",
    "midpoint",
    "sibenik",
    "spheres",
    "nosuch",
];

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// One to three mutations of a random valid line.
fn mutate(rng: &mut Rng) -> Vec<String> {
    let words = |line: &str| -> Vec<String> { line.split(' ').map(str::to_string).collect() };
    let mut args = words(LINES[rng.below(LINES.len())]);
    for _ in 0..1 + rng.below(3) {
        let n = args.len();
        let i = rng.below(n);
        let token = TOKENS[rng.below(TOKENS.len())].to_string();
        match rng.below(9) {
            0 => args[i] = token,
            1 if n > 1 => {
                args.remove(i);
            }
            2 => args.insert(i, token),
            3 => args.insert(i, args[i].clone()),
            4 => args.swap(i, rng.below(n)),
            5 => args.truncate(i.max(1)),
            6 => {
                let other = words(LINES[rng.below(LINES.len())]);
                let j = rng.below(other.len());
                args.truncate(i.max(1));
                args.extend_from_slice(&other[j..]);
            }
            7 if !args[i].is_empty() => {
                let mut bytes = args[i].clone().into_bytes();
                let k = rng.below(bytes.len());
                bytes[k] = b"09-=x,/.e "[rng.below(10)];
                args[i] = String::from_utf8_lossy(&bytes).into_owned();
            }
            _ => args.push(token),
        }
    }
    args
}

/// What a command checks before any work (nothing is rendered or written).
fn preflight(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Render(args)) => {
            let scene = scene_from(&args.scene)?;
            if !wavefront::film::output::is_exr(&args.output) {
                wavefront::film::output::ImageFormat::from_path(&args.output)?;
            }
            plan::RenderPlan::new(&scene, &args.part, &args.output, |_| None)?;
            check_threads(args.threads)?;
            if !(1..=MAX_WAVE_SAMPLES).contains(&args.wave_samples) {
                anyhow::bail!("invalid setting --wave-samples");
            }
            crate::check_memory(
                "--wave-samples",
                "a wave",
                args.wave_samples as u64 * crate::WAVE_BYTES_PER_SAMPLE,
            )?;
        }
        Some(Command::Plan(args)) => {
            scene_from(&args)?;
        }
        Some(Command::Info(args)) => {
            scene_from(&args.scene)?;
        }
        Some(Command::Bench(args)) => {
            check_threads(args.threads)?;
        }
        _ => {}
    }
    Ok(())
}

#[test]
fn mutated_command_lines_parse_or_fail_cleanly() {
    let cases = env_u64("WAVEFRONT_FUZZ_CASES", 10_000);
    let seed = env_u64("WAVEFRONT_FUZZ_SEED", 21);
    let limit = Duration::from_secs(env_u64("WAVEFRONT_FUZZ_CASE_SECONDS", 20));
    let mut rng = Rng(seed ^ 0xc11);
    let (mut parsed, mut checked) = (0u64, 0u64);
    for case in 0..cases {
        let args = mutate(&mut rng);
        let argv: Vec<OsString> = std::iter::once("wavefront".into())
            .chain(args.iter().map(OsString::from))
            .collect();
        let start = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| match Cli::try_parse_from(&argv) {
            // Help, version and usage errors: clap's own multi-line text, rendered without panic.
            Err(e) => {
                let _ = e.render().to_string();
                Ok(false)
            }
            Ok(cli) => preflight(cli).map(|()| true).map_err(|e| format!("{e:#}")),
        }));
        let what = format!("seed {seed} case {case}: {args:?}");
        assert!(
            start.elapsed() < limit,
            "{what}: took {:?}",
            start.elapsed()
        );
        match outcome {
            Err(_) => panic!("{what}: panicked"),
            Ok(Err(e)) => {
                parsed += 1;
                assert!(
                    !e.contains('\n') && !e.is_empty(),
                    "{what}: not one line: {e}"
                );
            }
            Ok(Ok(true)) => {
                parsed += 1;
                checked += 1;
            }
            Ok(Ok(false)) => {}
        }
    }
    eprintln!("{cases} cases: {parsed} parsed, {checked} passed every check");
    // The mutations reach the checks, not only clap's errors.
    assert!(parsed > cases / 10, "only {parsed} of {cases} parsed");
    assert!(
        checked > cases / 20,
        "only {checked} of {cases} passed every check"
    );
}
