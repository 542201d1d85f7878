//! `--set KEY=VALUE` and `--size WxH` (SPEC §16) render exactly what the edited scene file
//! renders, and bad settings are errors naming the setting.

use wavefront_kit::testkit::{Scratch, project_root};

fn run(dir: &Scratch, args: &[&str]) -> std::process::Output {
    let mut c = dir.command(env!("CARGO_BIN_EXE_wavefront"));
    c.args(args)
        .output()
        .expect("cannot run the wavefront binary")
}

fn ok(dir: &Scratch, args: &[&str]) -> Vec<u8> {
    let o = run(dir, args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let out = args[args.iter().position(|a| *a == "-o").unwrap() + 1];
    std::fs::read(dir.path().join(out)).unwrap()
}

/// Scene A as shipped, with a look-at camera (so the window follows the image's aspect).
fn scene() -> String {
    let text = std::fs::read_to_string(project_root().join("scenes/spheres.toml")).unwrap();
    let explicit = "u = [1.0, 0.0, 0.0]
v = [0.0, 1.0, 0.0]
w = [0.0, 0.0, 1.0]
window = { l = -0.1, r = 0.1, b = -0.1, t = 0.1 }
distance = 0.1";
    assert!(text.contains(explicit), "scenes/spheres.toml changed");
    text.replace(
        explicit,
        "look_at = [0.0, 0.0, -7.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 90.0",
    )
}

#[test]
fn settings_render_as_the_edited_file() {
    let dir = Scratch::new("settings");
    let text = scene();
    std::fs::write(dir.path().join("a.toml"), &text).unwrap();
    let edited = text
        .replace("width = 512\nheight = 512", "width = 96\nheight = 64")
        .replace("max_depth = 2", "max_depth = 1")
        .replace(
            "position = [-4.0, 4.0, -3.0]",
            "position = [4.0, 4.0, -3.0]",
        )
        .replace(
            "ks = [0.0, 0.0, 0.0]\np = 0.0\nalpha = 0.5",
            "ks = [0.0, 0.0, 0.0]\np = 0.0\nalpha = 0.25",
        );
    assert_ne!(
        edited.matches("alpha = 0.25").count(),
        0,
        "the floor's alpha line changed"
    );
    std::fs::write(dir.path().join("b.toml"), &edited).unwrap();
    let set = ok(
        &dir,
        &[
            "render",
            "a.toml",
            "--size",
            "96x64",
            "--set",
            "render.max_depth=1",
            "--set",
            "light.0.position=[4.0, 4.0, -3.0]",
            "--set",
            "material.floor.alpha=0.25",
            "-o",
            "set.ppm",
        ],
    );
    let file = ok(&dir, &["render", "b.toml", "-o", "file.ppm"]);
    assert!(set == file, "--set/--size differ from the edited file");
    let plain = ok(
        &dir,
        &["render", "a.toml", "--size", "96x64", "-o", "plain.ppm"],
    );
    assert!(plain != set, "the settings changed the image");
    // A setting that is the file's own value changes nothing.
    let same = ok(
        &dir,
        &[
            "render",
            "a.toml",
            "--size",
            "96x64",
            "--set",
            "image.samples=1",
            "-o",
            "same.ppm",
        ],
    );
    assert!(same == plain);
}

#[test]
fn bad_settings_name_the_setting() {
    let dir = Scratch::new("bad-settings");
    std::fs::write(dir.path().join("a.toml"), scene()).unwrap();
    let cases: [(&[&str], &str); 7] = [
        (
            &["--set", "render.maxdepth=1"],
            "--set render.maxdepth=1: maxdepth: unknown field",
        ),
        (
            &["--set", "light.3.position=[1,2,3]"],
            "--set light.3.position=[1,2,3]: light.3: the scene has 1",
        ),
        (
            &["--set", "sphere.0.radius=-1"],
            "sphere[0].radius: -1 must be > 0",
        ),
        (&["--set", "render.max_depth=hello"], "is not a TOML value"),
        (&["--set", "render"], "expected KEY=VALUE"),
        (&["--size", "0x10"], "--size 0x10"),
        (&["--size", "640"], "expected WIDTHxHEIGHT"),
    ];
    for (args, expect) in cases {
        let mut all = vec!["render", "a.toml"];
        all.extend_from_slice(args);
        all.extend_from_slice(&["-o", "x.png"]);
        let o = run(&dir, &all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(expect),
            "{args:?}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "one line: {err}");
        assert!(!dir.path().join("x.png").exists());
    }
    let o = run(
        &dir,
        &[
            "render",
            "spheres",
            "--set",
            "render.max_depth=1",
            "-o",
            "x.png",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("not a scene file"), "{err}");
    // A built-in takes --size.
    let o = run(
        &dir,
        &["render", "spheres", "--size", "64x32", "-o", "s.png"],
    );
    assert!(o.status.success());
    let png = image::open(dir.path().join("s.png")).unwrap();
    assert_eq!((png.width(), png.height()), (64, 32));
}
