//! The render farm on a real Slurm cluster: `.ci/slurm/cluster.sh` starts a throwaway
//! single-node cluster (munged, slurmctld, slurmd as background daemons, no systemd), then
//! `wavefront farm slurm --submit` runs
//!
//! - a 4-tile job array plus its merge job: the merged image must be byte-identical to `render`;
//! - a 4-frame range in 2 array tasks: every frame byte-identical to a local `render --frames`;
//! - a 4-tile array whose tile 2 cannot be written: the merge job must end (cancelled or failed,
//!   never pending) and no merged image may exist.
//!
//! Without `sbatch` and `slurmctld` the test says so and passes, unless
//! `WAVEFRONT_REQUIRE_SLURM=1` (CI sets it after `.ci/slurm/install.sh`), where it fails.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// Environment variable that turns missing Slurm from a skip into a failure.
const REQUIRE_SLURM_ENV: &str = "WAVEFRONT_REQUIRE_SLURM";

/// How long the jobs may take in all before the test gives up (a bound, not a measurement).
const JOB_DEADLINE: Duration = Duration::from_secs(100);

fn project_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Finds `name` on PATH or in the sbin directories (where Debian puts the daemons).
fn find_program(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin", "/sbin", "/usr/local/sbin"].map(PathBuf::from))
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// A running throwaway cluster; stopped (every daemon by its PID) when dropped.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn script() -> PathBuf {
        project_root().join(".ci/slurm/cluster.sh")
    }

    fn start(dir: PathBuf) -> Cluster {
        let _ = std::fs::remove_dir_all(&dir);
        let out = Command::new("bash")
            .arg(Self::script())
            .arg("start")
            .arg(&dir)
            .env("PATH", path_with_sbin())
            .output()
            .expect("cannot run .ci/slurm/cluster.sh");
        let cluster = Cluster {
            conf: dir.join("slurm.conf"),
            dir,
        };
        assert!(
            out.status.success(),
            "the Slurm cluster did not start:\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        cluster
    }

    /// A command with this cluster's configuration.
    fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf)
            .env("PATH", path_with_sbin());
        c
    }

    /// `JobState` of every record of job `id` (one per array task for an array).
    fn job_states(&self, id: &str) -> Vec<String> {
        self.job_field(id, "JobState")
    }

    /// The job names of job `id`'s records.
    fn job_names(&self, id: &str) -> Vec<String> {
        self.job_field(id, "JobName")
    }

    /// The value of `field` in every record `scontrol show job id` prints.
    fn job_field(&self, id: &str, field: &str) -> Vec<String> {
        let out = self
            .command("scontrol")
            .args(["show", "job", id])
            .output()
            .expect("cannot run scontrol");
        let prefix = format!("{field}=");
        String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .filter_map(|w| w.strip_prefix(prefix.as_str()))
            .map(str::to_owned)
            .collect()
    }

    /// Waits until no record of any job in `ids` is pending, configuring or running.
    fn wait(&self, ids: &[&str], deadline: Instant) {
        let busy = |s: &String| {
            matches!(
                s.as_str(),
                "PENDING" | "CONFIGURING" | "RUNNING" | "COMPLETING" | "SUSPENDED" | "REQUEUED"
            )
        };
        loop {
            let states: Vec<(String, Vec<String>)> = ids
                .iter()
                .map(|id| (id.to_string(), self.job_states(id)))
                .collect();
            if states
                .iter()
                .all(|(_, s)| !s.is_empty() && !s.iter().any(busy))
            {
                return;
            }
            if Instant::now() > deadline {
                let _ = self.command("scontrol").args(["show", "job"]).status();
                panic!(
                    "jobs still unfinished after {JOB_DEADLINE:?}: {states:?}\n{}",
                    self.log_tail()
                );
            }
            std::thread::sleep(Duration::from_millis(250));
        }
    }

    fn log_tail(&self) -> String {
        let log = std::fs::read_to_string(self.dir.join("log/slurmctld.log")).unwrap_or_default();
        let lines: Vec<&str> = log.lines().collect();
        lines[lines.len().saturating_sub(30)..].join("\n")
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(Self::script())
            .arg("stop")
            .arg(&self.dir)
            .status();
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

fn path_with_sbin() -> std::ffi::OsString {
    let mut dirs: Vec<PathBuf> =
        std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()).collect();
    dirs.extend(["/usr/sbin", "/sbin"].map(PathBuf::from));
    std::env::join_paths(dirs).expect("PATH")
}

fn wavefront(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_wavefront"));
    // Tree-cache entries stay in the scratch directory, not the user's cache.
    c.current_dir(dir).env("XDG_CACHE_HOME", dir.join("cache"));
    c
}

fn check(o: Output, what: &str) -> String {
    assert!(
        o.status.success(),
        "{what} failed:\n{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The job id after `label: ` in `farm slurm --submit`'s output.
fn job_id(stdout: &str, label: &str) -> String {
    stdout
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{label}: ")))
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no {label} job id in:\n{stdout}"))
        .to_owned()
}

/// Scene A at 160 × 120 with a two-key camera path over frames 0..=3.
fn path_scene() -> String {
    wavefront_kit::testkit::spheres_camera_path_toml(0.1, (160, 120))
}

#[test]
fn tiles_and_frames_on_a_slurm_cluster_match_single_renders() {
    let required = std::env::var_os(REQUIRE_SLURM_ENV).is_some_and(|v| v == "1");
    let missing: Vec<&str> = ["sbatch", "scontrol", "slurmctld", "slurmd", "munged"]
        .into_iter()
        .filter(|p| find_program(p).is_none())
        .collect();
    if !missing.is_empty() {
        assert!(
            !required,
            "{} not found and {REQUIRE_SLURM_ENV}=1: run .ci/slurm/install.sh",
            missing.join(", ")
        );
        eprintln!(
            "SKIPPED: {} not found — this test needs Debian's slurmctld, slurmd, slurm-client \
             and munge (.ci/slurm/install.sh installs them)",
            missing.join(", ")
        );
        return;
    }
    let start = Instant::now();
    let pid = std::process::id();
    let work = std::env::temp_dir().join(format!("wavefront-slurm-work-{pid}"));
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).unwrap();
    let cluster = Cluster::start(std::env::temp_dir().join(format!("wavefront-slurm-{pid}")));
    let started = start.elapsed();

    let spheres = project_root().join("scenes/spheres.toml");
    let spheres = spheres.to_str().unwrap();
    std::fs::write(work.join("path.toml"), path_scene()).unwrap();

    let farm = |args: &[&str]| {
        let mut c = cluster.command(env!("CARGO_BIN_EXE_wavefront"));
        c.current_dir(&work).args(["farm", "slurm"]).args(args);
        check(c.output().unwrap(), &format!("farm slurm {args:?}"))
    };
    // A tile that cannot be written: its output path is a directory.
    std::fs::create_dir_all(work.join("broken.tiles/tile_2.png")).unwrap();

    let tiles = farm(&[spheres, "--tiles", "4", "-o", "a.png", "--submit"]);
    let frames = farm(&[
        "path.toml",
        "--frames",
        "0-3",
        "--frames-per-task",
        "2",
        "-o",
        "frames/f_###.png",
        "--submit",
    ]);
    let broken = farm(&[spheres, "--tiles", "4", "-o", "broken.png", "--submit"]);
    // An EXR image: EXR tiles merged into the EXR; tile tasks skip tiles that exist (tile 0 is
    // planted, so its task must leave it alone); merge-only sbatch options.
    std::fs::create_dir_all(work.join("e.tiles")).unwrap();
    check(
        wavefront(&work)
            .args([
                "render",
                spheres,
                "--samples",
                "2",
                "--tile",
                "0/2",
                "-o",
                "e.tiles/tile_0.exr",
            ])
            .output()
            .unwrap(),
        "render --tile 0/2",
    );
    let planted = std::fs::metadata(work.join("e.tiles/tile_0.exr"))
        .unwrap()
        .modified()
        .unwrap();
    let exr = farm(&[
        spheres,
        "--samples",
        "2",
        "--tiles",
        "2",
        "-o",
        "e.exr",
        "--skip-existing",
        "--merge-sbatch=--job-name=wavefront-merge-exr",
        "--submit",
    ]);
    let (exr_array, exr_merge) = (job_id(&exr, "render"), job_id(&exr, "merge"));
    let (tiles_array, tiles_merge) = (job_id(&tiles, "render"), job_id(&tiles, "merge"));
    let frames_array = job_id(&frames, "render");
    let (broken_array, broken_merge) = (job_id(&broken, "render"), job_id(&broken, "merge"));
    assert!(frames.contains("job array of 2 tasks"), "{frames}");

    // The single-machine renders, meanwhile.
    check(
        wavefront(&work)
            .args(["render", spheres, "-o", "single.png"])
            .output()
            .unwrap(),
        "render",
    );
    check(
        wavefront(&work)
            .args(["render", spheres, "--samples", "2", "-o", "single.exr"])
            .output()
            .unwrap(),
        "render -o single.exr",
    );
    check(
        wavefront(&work)
            .args([
                "render",
                "path.toml",
                "--frames",
                "0-3",
                "-o",
                "single_###.png",
            ])
            .output()
            .unwrap(),
        "render --frames",
    );

    let deadline = Instant::now() + JOB_DEADLINE;
    cluster.wait(
        &[
            &tiles_array,
            &tiles_merge,
            &frames_array,
            &broken_array,
            &broken_merge,
            &exr_array,
            &exr_merge,
        ],
        deadline,
    );
    let jobs_done = start.elapsed();

    // Tiles: every task and the merge completed; the merged image is the single render's bytes.
    let states = cluster.job_states(&tiles_array);
    assert_eq!(states, ["COMPLETED"; 4], "tile tasks: {states:?}");
    assert_eq!(cluster.job_states(&tiles_merge), ["COMPLETED"]);
    let merged = std::fs::read(work.join("a.png")).expect("no merged image");
    assert!(
        merged == std::fs::read(work.join("single.png")).unwrap(),
        "the merged image differs from the single render"
    );

    // Frames: two tasks of two frames, each frame the local render's bytes.
    assert_eq!(cluster.job_states(&frames_array), ["COMPLETED"; 2]);
    for f in ["000", "001", "002", "003"] {
        let farmed = std::fs::read(work.join(format!("frames/f_{f}.png")))
            .unwrap_or_else(|e| panic!("frame {f} missing: {e}"));
        let local = std::fs::read(work.join(format!("single_{f}.png"))).unwrap();
        assert!(farmed == local, "frame {f} differs from the local render");
    }

    // EXR: both tasks and the merge completed; the planted tile was skipped, not rewritten; the
    // merged EXR holds the single render's linear pixels; the merge job had its own name.
    assert_eq!(cluster.job_states(&exr_array), ["COMPLETED"; 2]);
    assert_eq!(cluster.job_states(&exr_merge), ["COMPLETED"]);
    let now = std::fs::metadata(work.join("e.tiles/tile_0.exr"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(now, planted, "--skip-existing must reach the tile tasks");
    assert!(
        work.join("e.tiles/tile_1.exr").exists(),
        "EXR tiles for an EXR image"
    );
    let merged = wavefront::film::output::read_exr(&work.join("e.exr")).expect("no merged EXR");
    let single = wavefront::film::output::read_exr(&work.join("single.exr")).unwrap();
    assert_eq!(merged.size, single.size);
    assert!(
        merged.pixels == single.pixels,
        "the merged EXR differs from the single render"
    );
    let name = cluster.job_names(&exr_merge);
    assert_eq!(
        name,
        ["wavefront-merge-exr"],
        "--merge-sbatch reaches the merge job"
    );

    // A failed tile: that task failed, the merge ended without running, nothing was merged.
    let states = cluster.job_states(&broken_array);
    assert_eq!(
        states.iter().filter(|s| *s == "FAILED").count(),
        1,
        "broken tile tasks: {states:?}"
    );
    let merge_state = cluster.job_states(&broken_merge);
    assert!(
        merge_state == ["CANCELLED"] || merge_state == ["FAILED"],
        "the merge after a failed tile ended {merge_state:?}"
    );
    assert!(
        !work.join("broken.png").exists(),
        "a merged image exists although a tile failed"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&work)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
        .collect();
    assert!(leftovers.is_empty(), "partial files: {leftovers:?}");

    drop(cluster);
    eprintln!(
        "slurm: cluster up in {:.1} s, all jobs done after {:.1} s, total {:.1} s",
        started.as_secs_f64(),
        jobs_done.as_secs_f64(),
        start.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&work);
}
