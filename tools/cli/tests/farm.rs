//! Regions, tiles, frames and merging through the command line (SPEC §10, §11), and the Slurm
//! job scripts (without Slurm: `farm slurm --print` and the written scripts).

use std::path::Path;
use std::process::{Command, Output};

use wavefront_kit::testkit;

/// A scratch directory ([`testkit::Scratch`], removed on drop) to run the binary in.
struct Scratch(testkit::Scratch);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(testkit::Scratch::new(&format!("farm-{name}")))
    }

    fn path(&self) -> &Path {
        self.0.path()
    }

    fn command(&self, args: &[&str]) -> Command {
        let mut c = self.0.command(env!("CARGO_BIN_EXE_wavefront"));
        c.args(args)
            .env_remove("SLURM_ARRAY_TASK_ID")
            .env_remove("JOB_COMPLETION_INDEX");
        c
    }

    fn run(&self, args: &[&str]) -> Output {
        self.command(args).output().expect("cannot run wavefront")
    }

    /// Runs `args`, which must succeed; returns stdout.
    fn ok(&self, args: &[&str]) -> String {
        let o = self.run(args);
        assert!(
            o.status.success(),
            "{args:?} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    }

    fn read(&self, name: &str) -> Vec<u8> {
        std::fs::read(self.0.join(name)).unwrap_or_else(|e| panic!("cannot read {name}: {e}"))
    }

    fn write(&self, name: &str, text: &str) {
        std::fs::write(self.0.join(name), text).unwrap();
    }

    /// Every file and directory under the scratch directory, sorted.
    fn files(&self) -> Vec<String> {
        fn walk(dir: &Path, base: &Path, out: &mut Vec<String>) {
            for e in std::fs::read_dir(dir).unwrap() {
                let p = e.unwrap().path();
                out.push(p.strip_prefix(base).unwrap().to_string_lossy().into_owned());
                if p.is_dir() {
                    walk(&p, base, out);
                }
            }
        }
        let mut out = vec![];
        walk(self.0.path(), self.0.path(), &mut out);
        out.sort();
        out
    }

    /// Runs `args`, which must fail cleanly: non-zero exit, one `error:` line, no panic, no new
    /// file. Returns the error line.
    fn fails(&self, args: &[&str]) -> String {
        self.fails_with(self.command(args), args)
    }

    fn fails_with(&self, mut command: Command, args: &[&str]) -> String {
        let before = self.files();
        let o = command.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{args:?}: expected one line:\n{err}");
        assert!(lines[0].starts_with("error: "), "{err}");
        assert_eq!(self.files(), before, "{args:?} left files behind");
        lines[0].to_owned()
    }
}

const SPHERES: &str = include_str!("../../../scenes/spheres.toml");

/// Scene A at 96 × 64 with a camera path over frames 0..=3.
fn path_scene() -> String {
    wavefront_kit::testkit::spheres_camera_path_toml(0.0, (96, 64))
}

#[test]
fn three_uneven_tiles_merge_into_the_single_render_byte_for_byte() {
    let s = Scratch::new("tiles");
    s.ok(&["render", "spheres", "-o", "full.png"]);
    // 512 rows in 3 tiles: 170, 171 and 171 rows.
    for k in 0..3 {
        s.ok(&[
            "render",
            "spheres",
            "--tile",
            &format!("{k}/3"),
            "-o",
            &format!("t{k}.png"),
        ]);
    }
    let t1 = image::open(s.path().join("t1.png")).unwrap();
    assert_eq!(
        (t1.width(), t1.height()),
        (512, 171),
        "a tile has its region's size"
    );
    // Merge in any order.
    s.ok(&["merge", "t2.png", "t0.png", "t1.png", "-o", "merged.png"]);
    assert!(
        s.read("merged.png") == s.read("full.png"),
        "merged tiles differ"
    );
}

#[test]
fn pixel_bounds_rectangles_merge_into_the_single_render_byte_for_byte() {
    let s = Scratch::new("rects");
    let settings = ["--samples", "4", "--depth", "3"];
    let render = |bounds: Option<&str>, out: &str, extra: &[&str]| {
        let mut args = vec!["render", "spheres", "-o", out];
        args.extend(settings);
        args.extend(extra);
        if let Some(b) = bounds {
            args.extend(["--pixel-bounds", b]);
        }
        s.ok(&args);
    };
    render(None, "full.png", &[]);
    // A rectangle in the middle, the columns either side of it, and the rows above and below;
    // rendered with other thread counts and wave sizes, which change nothing.
    let rects = [
        (
            "100,301,57,400",
            &["--threads", "1", "--wave-samples", "1000"][..],
        ),
        ("0,100,57,400", &["--threads", "2"][..]),
        ("301,512,57,400", &[][..]),
        ("0,512,0,57", &["--wave-samples", "333"][..]),
        ("0,512,400,512", &[][..]),
    ];
    for (i, (bounds, extra)) in rects.iter().enumerate() {
        render(Some(bounds), &format!("r{i}.png"), extra);
    }
    let r0 = image::open(s.path().join("r0.png")).unwrap();
    assert_eq!((r0.width(), r0.height()), (201, 343));
    s.ok(&[
        "merge",
        "r0.png",
        "r1.png",
        "r2.png",
        "r3.png",
        "r4.png",
        "-o",
        "merged.png",
    ]);
    assert!(
        s.read("merged.png") == s.read("full.png"),
        "merged rectangles differ"
    );
    // The same tile from another thread count and wave size is the same file.
    render(Some("100,301,57,400"), "again.png", &[]);
    assert!(
        s.read("again.png") == s.read("r0.png"),
        "a tile depends on threads or waves"
    );
}

#[test]
fn merge_refuses_missing_overlapping_foreign_and_unreadable_tiles() {
    let s = Scratch::new("refuse");
    for k in 0..4 {
        s.ok(&[
            "render",
            "spheres",
            "--tile",
            &format!("{k}/4"),
            "-o",
            &format!("t{k}.png"),
        ]);
    }
    s.ok(&[
        "render",
        "spheres",
        "--samples",
        "2",
        "--tile",
        "1/4",
        "-o",
        "other.png",
    ]);
    s.ok(&[
        "render",
        "spheres",
        "--pixel-bounds",
        "0,512,100,200",
        "-o",
        "band.png",
    ]);
    s.ok(&["render", "spheres", "-o", "plain.png"]);
    s.write("junk.png", "not a png");

    let e = s.fails(&["merge", "t0.png", "t1.png", "t3.png", "-o", "m.png"]);
    assert!(
        e.contains("missing tile") && e.contains("0,512,256,384"),
        "{e}"
    );
    let e = s.fails(&[
        "merge", "t0.png", "t1.png", "t2.png", "t3.png", "band.png", "-o", "m.png",
    ]);
    assert!(e.contains("overlapping tiles t0.png and band.png"), "{e}");
    let e = s.fails(&[
        "merge", "t0.png", "t1.png", "t1.png", "t2.png", "t3.png", "-o", "m.png",
    ]);
    assert!(e.contains("overlapping tiles t1.png and t1.png"), "{e}");
    let e = s.fails(&[
        "merge",
        "t0.png",
        "other.png",
        "t2.png",
        "t3.png",
        "-o",
        "m.png",
    ]);
    assert!(e.contains("foreign tile other.png"), "{e}");
    let e = s.fails(&[
        "merge", "t0.png", "junk.png", "t2.png", "t3.png", "-o", "m.png",
    ]);
    assert!(e.contains("unreadable tile junk.png"), "{e}");
    let e = s.fails(&[
        "merge", "t0.png", "gone.png", "t2.png", "t3.png", "-o", "m.png",
    ]);
    assert!(e.contains("unreadable tile gone.png"), "{e}");
    let e = s.fails(&["merge", "plain.png", "-o", "m.png"]);
    assert!(e.contains("plain.png: not a wavefront tile"), "{e}");
    // A failed merge leaves an existing output alone.
    s.ok(&[
        "merge", "t0.png", "t1.png", "t2.png", "t3.png", "-o", "m.png",
    ]);
    let before = s.read("m.png");
    s.fails(&["merge", "t0.png", "t1.png", "-o", "m.png"]);
    assert!(s.read("m.png") == before);
}

#[test]
fn a_changed_mesh_file_makes_its_tiles_foreign() {
    let s = Scratch::new("mesh");
    let obj = "v -1 -1 -3\nv 1 -1 -3\nv 0 1 -3\nf 1 2 3\n";
    s.write("tri.obj", obj);
    let scene = SPHERES.split("[[plane]]").next().unwrap().to_owned()
        + "[[mesh]]\npath = \"tri.obj\"\nmaterial = \"red\"\n";
    s.write("tri.toml", &scene);
    s.ok(&["render", "tri.toml", "--tile", "0/2", "-o", "a.png"]);
    // The same triangle, other bytes: the fingerprint hashes the mesh file itself.
    s.write("tri.obj", &format!("# moved nothing\n{obj}"));
    s.ok(&["render", "tri.toml", "--tile", "1/2", "-o", "b.png"]);
    let e = s.fails(&["merge", "a.png", "b.png", "-o", "m.png"]);
    assert!(e.contains("foreign tile"), "{e}");
    s.ok(&["render", "tri.toml", "--tile", "0/2", "-o", "a.png"]);
    s.ok(&["merge", "a.png", "b.png", "-o", "m.png"]);
    s.ok(&["render", "tri.toml", "-o", "full.png"]);
    assert!(s.read("m.png") == s.read("full.png"));
}

#[test]
fn a_frame_range_loads_the_mesh_once() {
    let s = Scratch::new("once");
    s.write("tri.obj", "v -1 -1 -3\nv 1 -1 -3\nv 0 1 -3\nf 1 2 3\n");
    let scene = path_scene().split("[[plane]]").next().unwrap().to_owned()
        + "[[mesh]]\npath = \"tri.obj\"\nmaterial = \"red\"\n";
    s.write("tri.toml", &scene);
    let out = s.ok(&[
        "render", "tri.toml", "--frames", "0-3", "--stats", "-o", "f#.png",
    ]);
    assert_eq!(out.matches("mesh: 1 triangles").count(), 1, "{out}");
    assert_eq!(out.matches("wrote f").count(), 4, "{out}");
}

#[test]
fn tile_n_reads_slurm_then_kubernetes_indices() {
    let s = Scratch::new("env");
    s.ok(&["render", "spheres", "--tile", "1/3", "-o", "k1.png"]);
    s.ok(&["render", "spheres", "--tile", "2/3", "-o", "k2.png"]);
    let run = |var: &str, value: &str, out: &str| {
        let o = s
            .command(&["render", "spheres", "--tile", "3", "-o", out])
            .env(var, value)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run("SLURM_ARRAY_TASK_ID", "1", "slurm.png");
    run("JOB_COMPLETION_INDEX", "2", "k8s.png");
    assert!(s.read("slurm.png") == s.read("k1.png"));
    assert!(s.read("k8s.png") == s.read("k2.png"));
    let e = s.fails(&["render", "spheres", "--tile", "3", "-o", "x.png"]);
    assert!(e.contains("SLURM_ARRAY_TASK_ID"), "{e}");
    let mut c = s.command(&["render", "spheres", "--tile", "3", "-o", "x.png"]);
    c.env("SLURM_ARRAY_TASK_ID", "3");
    let e = s.fails_with(c, &["--tile 3 with task 3"]);
    assert!(e.contains("below 3"), "{e}");
}

#[test]
fn bad_regions_and_frame_ranges_are_one_line_errors_without_output() {
    let s = Scratch::new("bad");
    s.write("path.toml", &path_scene());
    let cases: &[(&[&str], &str)] = &[
        (&["--tile", "5/4"], "below 4"),
        (&["--tile", "0/0"], "at least 1"),
        (&["--tile", "0/600"], "one tile per row"),
        (&["--tile", "x/2"], "--tile"),
        (
            &["--pixel-bounds", "0,600,0,10"],
            "outside the 512x512 image",
        ),
        (&["--pixel-bounds", "10,5,0,1"], "x0 < x1"),
        (&["--pixel-bounds", "0,1,2"], "four integers"),
        (
            &["--pixel-bounds", "0,1,0,1", "--tile", "0/2"],
            "cannot be combined",
        ),
        (&["--frames", "0-3"], "no camera path"),
    ];
    for (args, expected) in cases {
        let mut all = vec!["render", "spheres", "-o", "x.png"];
        all.extend(*args);
        let e = s.fails(&all);
        assert!(e.contains(expected), "{args:?}: {e}");
    }
    let cases: &[(&[&str], &str)] = &[
        (&["--frames", "3-1", "-o", "f_#.png"], "after the last"),
        (
            &["--frames", "0-9", "-o", "f_#.png"],
            "camera keys for frames 0..=3",
        ),
        (&["--frames", "a", "-o", "f_#.png"], "--frames"),
        (&["--frames", "0-3", "-o", "f.png"], "no run of #"),
    ];
    for (args, expected) in cases {
        let mut all = vec!["render", "path.toml"];
        all.extend(*args);
        let e = s.fails(&all);
        assert!(e.contains(expected), "{args:?}: {e}");
    }
    // A key that is degenerate in the file names the file, line and key.
    s.write(
        "bad.toml",
        &path_scene().replace("fov_y = 60.0", "fov_y = 180.0"),
    );
    let e = s.fails(&["render", "bad.toml", "-o", "x.png"]);
    assert!(
        e.contains("bad.toml:") && e.contains("camera.key[1].fov_y"),
        "{e}"
    );
}

#[test]
fn a_frame_range_renders_in_one_process_and_resumes_with_skip_existing() {
    let s = Scratch::new("frames");
    s.write("path.toml", &path_scene());
    let out = s.ok(&["render", "path.toml", "--frames", "0-3", "-o", "f_##.png"]);
    assert_eq!(
        out.lines().filter(|l| l.starts_with("wrote f_")).count(),
        4,
        "{out}"
    );
    for f in 0..4 {
        // Each frame is the single-frame render of that frame.
        let one = format!("one_{f}.png");
        s.ok(&[
            "render",
            "path.toml",
            "--frames",
            &f.to_string(),
            "-o",
            &one,
        ]);
        assert!(s.read(&format!("f_0{f}.png")) == s.read(&one), "frame {f}");
    }
    assert!(s.read("f_00.png") != s.read("f_01.png"), "the camera moves");
    // Without a range the scene shows its first key.
    s.ok(&["render", "path.toml", "-o", "default.png"]);
    assert!(s.read("default.png") == s.read("f_00.png"));
    // Resume: only the missing frame is rendered.
    std::fs::remove_file(s.path().join("f_02.png")).unwrap();
    let out = s.ok(&[
        "render",
        "path.toml",
        "--frames",
        "0-3",
        "--skip-existing",
        "-o",
        "f_##.png",
    ]);
    assert_eq!(out.matches("skipped").count(), 3, "{out}");
    assert!(out.contains("wrote f_02.png"), "{out}");
    assert!(s.read("f_02.png") == s.read("one_2.png"));
    // Tiles of a frame merge into that frame.
    for k in 0..2 {
        let t = format!("t{k}_#.png");
        s.ok(&[
            "render",
            "path.toml",
            "--frames",
            "2",
            "--tile",
            &format!("{k}/2"),
            "-o",
            &t,
        ]);
    }
    s.ok(&["merge", "t0_2.png", "t1_2.png", "-o", "m.png"]);
    assert!(s.read("m.png") == s.read("one_2.png"));
    // Tiles of different frames do not merge.
    s.ok(&[
        "render",
        "path.toml",
        "--frames",
        "1",
        "--tile",
        "1/2",
        "-o",
        "t1_1.png",
    ]);
    let e = s.fails(&["merge", "t0_2.png", "t1_1.png", "-o", "m2.png"]);
    assert!(e.contains("foreign tile"), "{e}");
}

#[test]
fn farm_slurm_prints_or_writes_scripts_without_slurm() {
    let s = Scratch::new("slurm");
    s.write("path.toml", &path_scene());
    let out = s.ok(&[
        "farm",
        "slurm",
        "spheres",
        "--tiles",
        "4",
        "-o",
        "out/a.png",
        "--print",
    ]);
    assert!(out.contains("#SBATCH --array=0-3"), "{out}");
    assert!(out.contains("--tile 4"), "{out}");
    assert!(out.contains("#SBATCH --kill-on-invalid-dep=yes"), "{out}");
    assert!(out.contains("--dependency=afterok:"), "{out}");
    assert!(
        s.files().iter().all(|f| f == "path.toml"),
        "--print wrote files"
    );
    // A built-in's mesh is pinned to an absolute path (tasks may start elsewhere).
    let mut c = s.command(&[
        "farm", "slurm", "sibenik", "--tiles", "2", "-o", "b.png", "--print",
    ]);
    let out = c
        .env("WAVEFRONT_SIBENIK", "rel/sibenik.obj")
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&out.stdout);
    let mesh = s.path().join("rel/sibenik.obj");
    assert!(
        out.contains(&format!(
            "render sibenik --mesh {} --tile 2",
            mesh.display()
        )),
        "{out}"
    );

    // Without --print or --submit the scripts are written and the directories made.
    let out = s.ok(&[
        "farm",
        "slurm",
        "path.toml",
        "--frames",
        "0-3",
        "--frames-per-task",
        "3",
        "-o",
        "frames/f_###.png",
        "--",
        "--time=10",
    ]);
    assert!(out.contains("sbatch --parsable --time=10"), "{out}");
    let script = String::from_utf8(s.read("frames/f.slurm/render.sbatch")).unwrap();
    assert!(script.contains("#SBATCH --array=0-1"), "{script}");
    let path = s.path().join("path.toml");
    assert!(
        script.contains(&path.display().to_string()),
        "scene path not absolute: {script}"
    );
    assert!(!s.path().join("frames/f.slurm/merge.sbatch").exists());

    let cases: &[(&[&str], &str)] = &[
        (&["spheres", "--tiles", "0", "-o", "a.png"], "--tiles 0"),
        (&["spheres", "--tiles", "513", "-o", "a.png"], "1..=512"),
        (&["spheres", "-o", "a.png"], "nothing to farm out"),
        (
            &[
                "spheres",
                "--tiles",
                "2",
                "--frames-per-task",
                "2",
                "-o",
                "a.png",
            ],
            "without --tiles",
        ),
        (
            &[
                "path.toml",
                "--frames",
                "0-3",
                "--frames-per-task",
                "0",
                "-o",
                "f_#.png",
            ],
            "at least 1",
        ),
        (
            &["path.toml", "--frames", "0-3", "-o", "f.png"],
            "no run of #",
        ),
        (&["path.toml", "--frames", "0-7", "-o", "f_#.png"], "0..=3"),
        (
            &["nonexistent.toml", "--tiles", "2", "-o", "a.png"],
            "nonexistent.toml",
        ),
    ];
    for (args, expected) in cases {
        let mut all = vec!["farm", "slurm"];
        all.extend(*args);
        let e = s.fails(&all);
        assert!(e.contains(expected), "{args:?}: {e}");
    }
}
