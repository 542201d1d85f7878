//! `wavefront farm slurm`: job scripts for a Slurm cluster — a job array over tiles (plus a merge
//! job that runs only if every tile succeeded) or over chunks of frames — written, printed, or
//! submitted with `sbatch --parsable`.
//!
//! The merge job depends on the array with `--dependency=afterok:<array id>` and carries
//! `--kill-on-invalid-dep=yes`: when a tile fails, the dependency can never be met and Slurm
//! cancels the merge instead of leaving it pending forever. The merge itself also refuses an
//! incomplete set of tiles, so a merged image exists only when every tile rendered.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};

use crate::frames::{FrameRange, frame_path, has_frame_placeholder};
use crate::{SceneArgs, scene_from};

/// Render-farm back ends.
#[derive(Subcommand)]
pub enum FarmCommand {
    /// Write Slurm job scripts (a job array over tiles or frame chunks, and a merge job for
    /// tiles); `--print` shows them, `--submit` submits them with sbatch. Options after `--` go to
    /// every sbatch call (e.g. `-- --partition=render --time=30`); `--merge-sbatch` ones to the
    /// merge job only.
    Slurm(SlurmArgs),
}

/// Arguments of `farm slurm`.
#[derive(Args)]
pub struct SlurmArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Split each image into N tiles of rows (one array task each) and merge them afterwards.
    #[arg(long, value_name = "N")]
    tiles: Option<u32>,
    /// Frames A to B of the scene's camera path (inclusive).
    #[arg(long, value_name = "A-B|N")]
    frames: Option<String>,
    /// Frames rendered by one array task (without --tiles); the world is loaded once per task.
    #[arg(long, value_name = "M")]
    frames_per_task: Option<u32>,
    /// The final image (with --frames: a path with a run of # for the frame number).
    #[arg(short, long)]
    output: PathBuf,
    /// Where the job scripts and logs go (default: beside OUTPUT, named after it, `.slurm`).
    #[arg(long)]
    job_dir: Option<PathBuf>,
    /// The wavefront binary the jobs run (default: this one).
    #[arg(long)]
    wavefront: Option<PathBuf>,
    /// Pass --skip-existing to the render tasks (a resubmitted frame range or tile set resumes).
    #[arg(long)]
    skip_existing: bool,
    /// An sbatch option for the merge job only (repeatable), after the options after `--`, so
    /// it overrides them there (e.g. `--merge-sbatch=--cpus-per-task=1`).
    #[arg(long, value_name = "OPTION", allow_hyphen_values = true)]
    merge_sbatch: Vec<String>,
    /// Print the scripts and the sbatch commands; write nothing.
    #[arg(long, conflicts_with = "submit")]
    print: bool,
    /// Write the scripts and submit them (sbatch --parsable); print the job ids.
    #[arg(long)]
    submit: bool,
    /// Options for every sbatch call, after `--`.
    #[arg(last = true, value_name = "SBATCH OPTIONS")]
    sbatch: Vec<String>,
}

/// What the array tasks do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Work {
    /// `n` tiles of each frame (of `frames`, or the scene's one image); task `i` renders tile
    /// `i mod n` of frame `first + i div n`.
    Tiles {
        /// Tiles per image.
        n: u32,
        /// The frames (`None`: the scene's single image).
        frames: Option<FrameRange>,
    },
    /// Frames in chunks of `per_task`; task `i` renders frames `first + i·per_task` onwards.
    Frames {
        /// The frames.
        range: FrameRange,
        /// Frames per task.
        per_task: u32,
    },
}

/// Everything the scripts are made from; every path absolute.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlurmPlan {
    /// The binary the jobs run.
    pub wavefront: PathBuf,
    /// Scene and overrides, as `render` arguments.
    pub scene_args: Vec<String>,
    /// The final image path (template with `#` for frames).
    pub output: PathBuf,
    /// Where scripts and logs go.
    pub job_dir: PathBuf,
    /// What the tasks do.
    pub work: Work,
    /// Pass `--skip-existing` to render tasks.
    pub skip_existing: bool,
}

/// The generated job scripts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Scripts {
    /// The job array script.
    pub render: String,
    /// Array tasks.
    pub tasks: u32,
    /// The merge script (tiles only).
    pub merge: Option<String>,
}

/// Quotes `s` for bash: as is when it is plainly safe, else in single quotes.
pub fn shell_quote(s: &str) -> String {
    let safe = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
    if safe {
        s.to_owned()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

fn quote_path(p: &Path) -> String {
    shell_quote(&p.to_string_lossy())
}

impl SlurmPlan {
    /// Tile `k`'s file for an image written to `output` (a template when frames are rendered):
    /// `<output stem>.tiles/tile_<k>.<ext>` beside it: EXR tiles for an `.exr` image (its
    /// linear radiance), PNG tiles otherwise.
    pub fn tile_path(output: &Path, k: &str) -> PathBuf {
        Self::tile_dir(output).join(format!("tile_{k}.{}", Self::tile_extension(output)))
    }

    /// The tiles' file extension for `output`: `exr` for an `.exr` image, else `png`.
    pub fn tile_extension(output: &Path) -> &'static str {
        if wavefront::film::output::is_exr(output) {
            "exr"
        } else {
            "png"
        }
    }

    /// The directory holding an image's tiles.
    pub fn tile_dir(output: &Path) -> PathBuf {
        let stem = output.file_stem().unwrap_or_default().to_string_lossy();
        output.with_file_name(format!("{stem}.tiles"))
    }

    /// The default job directory for `output`: `<stem without #>.slurm` beside it.
    pub fn default_job_dir(output: &Path) -> PathBuf {
        let stem = output.file_stem().unwrap_or_default().to_string_lossy();
        let stem = stem.replace('#', "");
        let stem = stem.trim_end_matches(['_', '-', '.']);
        let stem = if stem.is_empty() { "wavefront" } else { stem };
        output.with_file_name(format!("{stem}.slurm"))
    }

    /// The directories the jobs write into, which must exist before they run.
    pub fn output_dirs(&self) -> Vec<PathBuf> {
        let mut dirs = vec![self.job_dir.clone()];
        let parent = |p: &Path| p.parent().map(Path::to_path_buf).unwrap_or_default();
        match &self.work {
            Work::Tiles { frames: None, .. } => {
                dirs.push(parent(&self.output));
                dirs.push(Self::tile_dir(&self.output));
            }
            Work::Tiles {
                frames: Some(range),
                ..
            } => {
                for f in range.frames() {
                    let out = frame_path(&self.output, f);
                    dirs.push(parent(&out));
                    dirs.push(Self::tile_dir(&out));
                }
            }
            Work::Frames { range, .. } => {
                for f in range.frames() {
                    dirs.push(parent(&frame_path(&self.output, f)));
                }
            }
        }
        dirs.dedup();
        dirs
    }

    /// The job scripts.
    pub fn scripts(&self) -> Scripts {
        let exe = quote_path(&self.wavefront);
        let scene: Vec<String> = self.scene_args.iter().map(|a| shell_quote(a)).collect();
        let scene = scene.join(" ");
        let skip = if self.skip_existing {
            " --skip-existing"
        } else {
            ""
        };
        let log = |name: &str| quote_path(&self.job_dir.join(name));
        let mut render = String::from("#!/bin/bash\n");
        let tasks = match &self.work {
            Work::Tiles { n, frames } => n * frames.map_or(1, |r| r.len()),
            Work::Frames { range, per_task } => range.len().div_ceil(*per_task),
        };
        let _ = writeln!(
            render,
            "# Written by `wavefront farm slurm`: {} array task(s).",
            tasks
        );
        let _ = writeln!(render, "#SBATCH --job-name=wavefront-render");
        let _ = writeln!(render, "#SBATCH --array=0-{}", tasks - 1);
        let _ = writeln!(render, "#SBATCH --output={}", log("render-%A_%a.log"));
        render.push_str("set -euo pipefail\n");
        render.push_str("task=${SLURM_ARRAY_TASK_ID:?run this script as a Slurm job array}\n");
        render.push_str(
            "threads=()\nif [ -n \"${SLURM_CPUS_PER_TASK:-}\" ]; then \
             threads=(--threads \"$SLURM_CPUS_PER_TASK\"); fi\n",
        );
        let mut merge = None;
        match &self.work {
            Work::Tiles { n, frames: None } => {
                // `--tile N` reads the tile index from SLURM_ARRAY_TASK_ID itself.
                let tile = quote_path(&Self::tile_dir(&self.output).join("tile_"));
                let ext = Self::tile_extension(&self.output);
                let _ = writeln!(
                    render,
                    "exec {exe} render {scene} --tile {n}{skip} \"${{threads[@]}}\" \
                     -o {tile}\"$task\".{ext}"
                );
                merge = Some(self.merge_script(*n, std::slice::from_ref(&self.output)));
            }
            Work::Tiles {
                n,
                frames: Some(range),
            } => {
                let tile = quote_path(&Self::tile_dir(&self.output).join("tile_"));
                let _ = writeln!(
                    render,
                    "k=$((task % {n}))\nframe=$(({} + task / {n}))",
                    range.first
                );
                let ext = Self::tile_extension(&frame_path(&self.output, range.first));
                let _ = writeln!(
                    render,
                    "exec {exe} render {scene} --frames \"$frame\" --tile \"$k/{n}\"{skip} \
                     \"${{threads[@]}}\" -o {tile}\"$k\".{ext}"
                );
                let outputs: Vec<PathBuf> = range
                    .frames()
                    .map(|f| frame_path(&self.output, f))
                    .collect();
                merge = Some(self.merge_script(*n, &outputs));
            }
            Work::Frames { range, per_task } => {
                let _ = writeln!(
                    render,
                    "first=$(({} + task * {per_task}))\nlast=$((first + {per_task} - 1))\n\
                     if [ \"$last\" -gt {} ]; then last={}; fi",
                    range.first, range.last, range.last
                );
                let _ = writeln!(
                    render,
                    "exec {exe} render {scene} --frames \"$first-$last\"{skip} \
                     \"${{threads[@]}}\" -o {}",
                    quote_path(&self.output)
                );
            }
        }
        Scripts {
            render,
            tasks,
            merge,
        }
    }

    /// The merge job: one `merge` per image, of its `n` tiles.
    fn merge_script(&self, n: u32, outputs: &[PathBuf]) -> String {
        let exe = quote_path(&self.wavefront);
        let mut s = String::from("#!/bin/bash\n");
        let _ = writeln!(
            s,
            "# Written by `wavefront farm slurm`: merges {n} tiles into each of {} image(s).\n\
             # Submit with --dependency=afterok:<render array id>; it is cancelled if a tile fails.",
            outputs.len()
        );
        s.push_str("#SBATCH --job-name=wavefront-merge\n#SBATCH --kill-on-invalid-dep=yes\n");
        let _ = writeln!(
            s,
            "#SBATCH --output={}",
            quote_path(&self.job_dir.join("merge-%j.log"))
        );
        s.push_str("set -euo pipefail\n");
        for out in outputs {
            let tiles: Vec<String> = (0..n)
                .map(|k| quote_path(&Self::tile_path(out, &k.to_string())))
                .collect();
            let _ = writeln!(s, "{exe} merge {} -o {}", tiles.join(" "), quote_path(out));
        }
        s
    }

    /// The sbatch command lines that submit `render` and `merge` from the job directory:
    /// `sbatch` options go to both, `merge_sbatch` ones to the merge job only, after them.
    pub fn submit_commands(
        &self,
        sbatch: &[String],
        merge_sbatch: &[String],
        has_merge: bool,
    ) -> String {
        let quoted = |opts: &[String]| -> String {
            opts.iter()
                .map(|a| format!(" {}", shell_quote(a)))
                .collect()
        };
        let extra = quoted(sbatch);
        let render = quote_path(&self.job_dir.join("render.sbatch"));
        let mut s = format!("array=$(sbatch --parsable{extra} {render})\n");
        if has_merge {
            let merge = quote_path(&self.job_dir.join("merge.sbatch"));
            let _ = writeln!(
                s,
                "sbatch --parsable --dependency=afterok:\"${{array%%;*}}\" \
                 --kill-on-invalid-dep=yes{extra}{} {merge}",
                quoted(merge_sbatch)
            );
        }
        s
    }
}

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
}

/// Builds the plan from the command line, checking the scene, tiles and frames first.
fn plan(args: &SlurmArgs) -> Result<SlurmPlan> {
    let scene = scene_from(&args.scene)?;
    let height = scene.image.height;
    let frames = args
        .frames
        .as_deref()
        .map(str::parse::<FrameRange>)
        .transpose()?;
    if let Some(range) = frames {
        // The same checks `render --frames` makes, before anything is submitted.
        let part = crate::plan::PartArgs {
            frames: args.frames.clone(),
            ..Default::default()
        };
        crate::plan::RenderPlan::new(&scene, &part, &args.output, |_| None)?;
        debug_assert!(range.len() == 1 || has_frame_placeholder(&args.output));
    }
    let work = match (args.tiles, frames, args.frames_per_task) {
        (Some(_), _, Some(_)) => {
            bail!("--frames-per-task applies to frame ranges without --tiles")
        }
        (Some(n), frames, None) => {
            if n == 0 || n > height {
                bail!("invalid --tiles {n}: must be in 1..={height} (at most one tile per row)");
            }
            Work::Tiles { n, frames }
        }
        (None, Some(range), per_task) => {
            let per_task = per_task.unwrap_or(1);
            if per_task == 0 {
                bail!("invalid --frames-per-task 0: must be at least 1");
            }
            Work::Frames { range, per_task }
        }
        (None, None, _) => bail!("nothing to farm out: give --tiles N and/or --frames A-B"),
    };
    let mut scene_args = vec![];
    let a = &args.scene;
    let builtin = wavefront::scene::builtin::builtin(&a.scene).is_some();
    scene_args.push(if builtin {
        a.scene.clone()
    } else {
        absolute(Path::new(&a.scene))?
            .to_string_lossy()
            .into_owned()
    });
    // A built-in finds its mesh from the working directory (or $WAVEFRONT_SIBENIK): pin it.
    let mesh = match (&a.mesh, builtin, scene.meshes.first()) {
        (None, true, Some(m)) => Some(m.path.clone()),
        (mesh, _, _) => mesh.clone(),
    };
    let mut flag = |name: &str, value: Option<String>| {
        if let Some(v) = value {
            scene_args.push(name.to_owned());
            scene_args.push(v);
        }
    };
    flag("--samples", a.samples.map(|n| n.to_string()));
    flag("--depth", a.depth.map(|n| n.to_string()));
    flag(
        "--kdtree",
        a.kdtree.as_ref().map(|k| match k.as_str() {
            "sah" | "midpoint" => k.clone(),
            file => absolute(Path::new(file))
                .map_or(file.to_owned(), |p| p.to_string_lossy().into_owned()),
        }),
    );
    flag(
        "--mesh",
        mesh.map(|m| absolute(&m).unwrap_or(m).to_string_lossy().into_owned()),
    );
    if a.no_shadows {
        scene_args.push("--no-shadows".into());
    } else if a.shadows {
        scene_args.push("--shadows".into());
    }
    if a.mask {
        scene_args.push("--mask".into());
    }
    let output = absolute(&args.output)?;
    let wavefront = match &args.wavefront {
        Some(p) => absolute(p)?,
        None => std::env::current_exe().context("cannot find the wavefront binary")?,
    };
    let job_dir = match &args.job_dir {
        Some(d) => absolute(d)?,
        None => SlurmPlan::default_job_dir(&output),
    };
    Ok(SlurmPlan {
        wavefront,
        scene_args,
        output,
        job_dir,
        work,
        skip_existing: args.skip_existing,
    })
}

/// Runs `farm`.
pub fn run(cmd: FarmCommand) -> Result<()> {
    let FarmCommand::Slurm(args) = cmd;
    let plan = plan(&args)?;
    let scripts = plan.scripts();
    let render_file = plan.job_dir.join("render.sbatch");
    let merge_file = plan.job_dir.join("merge.sbatch");
    if args.print {
        outln!("# ==> {} <==\n{}", render_file.display(), scripts.render);
        if let Some(m) = &scripts.merge {
            outln!("# ==> {} <==\n{m}", merge_file.display());
        }
        out!(
            "# ==> submit <==\n{}",
            plan.submit_commands(&args.sbatch, &args.merge_sbatch, scripts.merge.is_some())
        );
        return Ok(());
    }
    for dir in plan.output_dirs() {
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create directory {}", dir.display()))?;
    }
    let write = |path: &Path, text: &str| {
        wavefront::film::output::write_atomically(path, text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))
    };
    write(&render_file, &scripts.render)?;
    if let Some(m) = &scripts.merge {
        write(&merge_file, m)?;
    }
    if !args.submit {
        outln!(
            "wrote {}{}; submit with:",
            render_file.display(),
            if scripts.merge.is_some() {
                format!(" and {}", merge_file.display())
            } else {
                String::new()
            }
        );
        out!(
            "{}",
            plan.submit_commands(&args.sbatch, &args.merge_sbatch, scripts.merge.is_some())
        );
        return Ok(());
    }
    let array = sbatch(&args.sbatch, &[], &render_file)?;
    outln!("render: {array} (job array of {} tasks)", scripts.tasks);
    if scripts.merge.is_some() {
        let dependency = [
            format!("--dependency=afterok:{array}"),
            "--kill-on-invalid-dep=yes".to_owned(),
        ];
        let options = [args.sbatch.as_slice(), &args.merge_sbatch].concat();
        match sbatch(&options, &dependency, &merge_file) {
            Ok(merge) => {
                outln!("merge: {merge} (after every render task succeeds; cancelled if one fails)")
            }
            Err(e) => {
                // Without its merge the array would render for nothing.
                let cancelled = Command::new("scancel")
                    .arg(&array)
                    .status()
                    .is_ok_and(|s| s.success());
                let what = if cancelled {
                    "cancelled"
                } else {
                    "could not cancel"
                };
                return Err(e.context(format!(
                    "cannot submit the merge job ({what} render job {array})"
                )));
            }
        }
    }
    Ok(())
}

/// Runs `sbatch --parsable [extra] [dependency] script` and returns the job id.
fn sbatch(extra: &[String], dependency: &[String], script: &Path) -> Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(dependency)
        .args(extra)
        .arg(script)
        .output()
        .context("cannot run sbatch (is Slurm installed and on PATH?)")?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        bail!(
            "sbatch {} failed ({}): {}",
            script.display(),
            out.status,
            stderr.trim().replace('\n', "; ")
        );
    }
    // `--parsable` prints `id` or `id;cluster`.
    let id = stdout.trim().split(';').next().unwrap_or("").to_owned();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        bail!(
            "sbatch {} printed no job id: {:?}",
            script.display(),
            stdout.trim()
        );
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(work: Work) -> SlurmPlan {
        SlurmPlan {
            wavefront: "/opt/wf/bin/wavefront".into(),
            scene_args: vec!["/data/my scene.toml".into(), "--samples".into(), "4".into()],
            output: "/out/frame_####.png".into(),
            job_dir: "/out/frame.slurm".into(),
            work,
            skip_existing: false,
        }
    }

    #[test]
    fn quoting_leaves_plain_words_and_protects_the_rest() {
        assert_eq!(shell_quote("/a/b-c_d.png"), "/a/b-c_d.png");
        assert_eq!(shell_quote("my scene.toml"), "'my scene.toml'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
        assert_eq!(shell_quote("$HOME"), "'$HOME'");
        assert_eq!(shell_quote(""), "''");
    }

    #[test]
    fn a_tile_array_uses_the_task_id_and_a_merge_that_cannot_hang() {
        let mut p = plan(Work::Tiles { n: 4, frames: None });
        p.output = "/out/a.png".into();
        let s = p.scripts();
        assert_eq!(s.tasks, 4);
        assert!(s.render.starts_with("#!/bin/bash\n"), "{}", s.render);
        assert!(s.render.contains("#SBATCH --array=0-3\n"), "{}", s.render);
        assert!(
            s.render.contains(
                "exec /opt/wf/bin/wavefront render '/data/my scene.toml' --samples 4 --tile 4 \
                 \"${threads[@]}\" -o /out/a.tiles/tile_\"$task\".png"
            ),
            "{}",
            s.render
        );
        let merge = s.merge.unwrap();
        assert!(
            merge.contains("#SBATCH --kill-on-invalid-dep=yes"),
            "{merge}"
        );
        assert!(
            merge.contains(
                "/opt/wf/bin/wavefront merge /out/a.tiles/tile_0.png /out/a.tiles/tile_1.png \
                 /out/a.tiles/tile_2.png /out/a.tiles/tile_3.png -o /out/a.png"
            ),
            "{merge}"
        );
        let submit = p.submit_commands(&["--partition=x y".into()], &[], true);
        assert!(
            submit.contains(
                "--dependency=afterok:\"${array%%;*}\" --kill-on-invalid-dep=yes \
                 '--partition=x y' /out/frame.slurm/merge.sbatch"
            ),
            "{submit}"
        );
        assert_eq!(
            p.output_dirs(),
            [
                PathBuf::from("/out/frame.slurm"),
                "/out".into(),
                "/out/a.tiles".into()
            ]
        );
    }

    #[test]
    fn tiles_of_several_frames_pair_each_task_with_a_frame_and_a_tile() {
        let p = plan(Work::Tiles {
            n: 3,
            frames: Some(FrameRange { first: 5, last: 6 }),
        });
        let s = p.scripts();
        assert_eq!(s.tasks, 6);
        assert!(
            s.render
                .contains("k=$((task % 3))\nframe=$((5 + task / 3))")
        );
        assert!(
            s.render.contains(
                "--frames \"$frame\" --tile \"$k/3\" \"${threads[@]}\" \
                 -o '/out/frame_####.tiles/tile_'\"$k\".png"
            ),
            "{}",
            s.render
        );
        let merge = s.merge.unwrap();
        assert!(
            merge.contains("/out/frame_0006.tiles/tile_2.png -o /out/frame_0006.png"),
            "{merge}"
        );
        assert_eq!(merge.matches(" merge ").count(), 2, "{merge}");
    }

    #[test]
    fn frame_chunks_cover_the_range_and_clip_the_last_task() {
        let mut p = plan(Work::Frames {
            range: FrameRange {
                first: 10,
                last: 14,
            },
            per_task: 2,
        });
        p.skip_existing = true;
        let s = p.scripts();
        assert_eq!(s.tasks, 3);
        assert!(s.merge.is_none());
        assert!(s.render.contains("#SBATCH --array=0-2\n"));
        assert!(
            s.render.contains("first=$((10 + task * 2))"),
            "{}",
            s.render
        );
        assert!(
            s.render
                .contains("if [ \"$last\" -gt 14 ]; then last=14; fi")
        );
        assert!(
            s.render.contains(
                "--frames \"$first-$last\" --skip-existing \"${threads[@]}\" \
                 -o '/out/frame_####.png'"
            ),
            "{}",
            s.render
        );
        assert!(!p.submit_commands(&[], &[], false).contains("merge"));
    }

    #[test]
    fn the_default_job_dir_is_named_after_the_output() {
        let d = |o: &str| SlurmPlan::default_job_dir(Path::new(o));
        assert_eq!(d("/o/frame_####.png"), PathBuf::from("/o/frame.slurm"));
        assert_eq!(d("/o/a.png"), PathBuf::from("/o/a.slurm"));
        assert_eq!(d("/o/####.png"), PathBuf::from("/o/wavefront.slurm"));
    }

    #[test]
    fn skip_existing_reaches_the_tile_tasks() {
        for frames in [None, Some(FrameRange { first: 5, last: 6 })] {
            let mut p = plan(Work::Tiles { n: 4, frames });
            p.skip_existing = true;
            let s = p.scripts();
            let line = s.render.lines().find(|l| l.starts_with("exec ")).unwrap();
            assert!(line.contains(" --skip-existing "), "{line}");
        }
    }

    #[test]
    fn an_exr_image_is_rendered_as_exr_tiles_and_merged_from_them() {
        let mut p = plan(Work::Tiles { n: 2, frames: None });
        p.output = "/out/a.exr".into();
        let s = p.scripts();
        assert!(
            s.render.contains("-o /out/a.tiles/tile_\"$task\".exr"),
            "{}",
            s.render
        );
        let merge = s.merge.unwrap();
        assert!(
            merge.contains("merge /out/a.tiles/tile_0.exr /out/a.tiles/tile_1.exr -o /out/a.exr"),
            "{merge}"
        );
        let mut p = plan(Work::Tiles {
            n: 2,
            frames: Some(FrameRange { first: 1, last: 2 }),
        });
        p.output = "/out/f_##.exr".into();
        let s = p.scripts();
        assert!(s.render.contains("\"$k\".exr"), "{}", s.render);
        assert!(
            s.merge
                .unwrap()
                .contains("/out/f_02.tiles/tile_1.exr -o /out/f_02.exr"),
            "each frame merges its own EXR tiles"
        );
    }

    #[test]
    fn merge_only_options_go_to_the_merge_job_after_the_common_ones() {
        let p = plan(Work::Tiles { n: 2, frames: None });
        let submit = p.submit_commands(
            &["--time=60".into(), "--cpus-per-task=8".into()],
            &["--cpus-per-task=1".into()],
            true,
        );
        let (render, merge) = submit.split_once('\n').unwrap();
        assert!(render.contains("--time=60 --cpus-per-task=8 "), "{render}");
        assert!(!render.contains("--cpus-per-task=1"), "{render}");
        assert!(
            merge.contains("--time=60 --cpus-per-task=8 --cpus-per-task=1 "),
            "{merge}"
        );
    }
}
