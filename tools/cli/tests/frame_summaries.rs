//! `render --frames` prints one summary per frame with that frame's own time, not the time since
//! the command started.

use std::time::Instant;

use wavefront_kit::testkit::{Scratch, spheres_camera_path_toml};

#[test]
fn each_frames_summary_gives_that_frames_time() {
    let dir = Scratch::new("frame-summaries");
    let scene = dir.path().join("path.toml");
    std::fs::write(&scene, spheres_camera_path_toml(0.0, (96, 64))).unwrap();
    let start = Instant::now();
    let o = dir
        .command(env!("CARGO_BIN_EXE_wavefront"))
        .args(["render", "path.toml", "--frames", "0-3", "--samples", "16"])
        .args(["--stats", "--no-cache", "-o", "f_#.png"])
        .output()
        .expect("cannot run the wavefront binary");
    let wall = start.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // `wrote f_0.png: 96x64, 16 spp, 0.01 s, 3.2 Mrays/s`
    let seconds: Vec<f64> = err
        .lines()
        .filter(|l| l.starts_with("wrote f_"))
        .map(|l| {
            let s = l.split(", ").nth(2).and_then(|s| s.strip_suffix(" s"));
            s.and_then(|s| s.parse().ok())
                .unwrap_or_else(|| panic!("no seconds in {l:?}"))
        })
        .collect();
    assert_eq!(seconds.len(), 4, "{err}");
    // Frames' own times add up to at most the whole command's; times since the start would add
    // up to about (4 + 3 + 2 + 1) / 4 of it. (Printed to 0.01 s: allow that per frame.)
    let sum: f64 = seconds.iter().sum();
    assert!(
        sum <= wall + 0.005 * seconds.len() as f64,
        "summaries add up to {sum:.3} s of a {wall:.3} s command: {err}"
    );
}
