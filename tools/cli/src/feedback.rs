//! What `wavefront render` tells a person while it works: a spinner while the scene loads (OBJ,
//! kD tree), a progress bar while it renders, and one summary line at the end — on a terminal
//! only. `--quiet` silences all of it; when stderr is not a terminal nothing is printed but errors,
//! unless `--stats` asks for the summary.

use std::io::IsTerminal;
use std::path::Path;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The feedback policy of one command.
#[derive(Clone, Copy, Debug)]
pub struct Feedback {
    /// Spinners and progress bars (a terminal, not `--quiet`).
    live: bool,
    /// The summary line.
    summary: bool,
}

/// What the summary line reports about one image.
#[derive(Clone, Copy, Debug)]
pub struct Summary<'a> {
    /// Where the image went.
    pub output: &'a Path,
    /// Size in pixels.
    pub width: u32,
    /// Size in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub samples: u32,
    /// Wall time of the whole command so far.
    pub seconds: f64,
    /// Rays traced (camera, reflection and shadow rays).
    pub rays: u64,
}

impl Feedback {
    /// The policy for `--quiet` / `--stats` on this process's stderr.
    pub fn new(quiet: bool, stats: bool) -> Feedback {
        let terminal = std::io::stderr().is_terminal();
        Feedback {
            live: terminal && !quiet,
            summary: !quiet && (terminal || stats),
        }
    }

    /// A spinner with `message` until the returned handle is finished (hidden unless live).
    pub fn spinner(&self, message: String) -> ProgressBar {
        if !self.live {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new_spinner().with_message(message);
        if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} {elapsed}") {
            bar.set_style(style);
        }
        bar.enable_steady_tick(Duration::from_millis(100));
        bar
    }

    /// A render progress bar that appears once a render has run for a second (never unless
    /// live).
    pub fn progress(&self) -> Progress {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {percent:>3}% {elapsed} eta {eta}")
        {
            bar.set_style(style);
        }
        Progress {
            bar,
            start: Instant::now(),
            live: self.live,
        }
    }

    /// Prints the summary line on stderr, if the policy wants it.
    pub fn summary(&self, s: &Summary<'_>) {
        if self.summary {
            eprintln!("{}", summary_line(s));
        }
    }
}

/// `wrote out.png: 512x512, 64 spp, 2.41 s, 13.9 Mrays/s`.
pub fn summary_line(s: &Summary<'_>) -> String {
    let rate = if s.seconds > 0.0 {
        s.rays as f64 / s.seconds / 1e6
    } else {
        0.0
    };
    format!(
        "wrote {}: {}x{}, {} spp, {:.2} s, {:.1} Mrays/s",
        s.output.display(),
        s.width,
        s.height,
        s.samples,
        s.seconds,
        rate
    )
}

/// A render's progress bar.
pub struct Progress {
    bar: ProgressBar,
    start: Instant,
    live: bool,
}

impl Progress {
    /// Pixels done of total.
    pub fn update(&self, done: u64, total: u64) {
        self.bar.set_length(total);
        self.bar.set_position(done);
        if self.live
            && self.bar.is_hidden()
            && self.start.elapsed() > Duration::from_secs(1)
            && done < total
        {
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_names_output_size_samples_time_and_rate() {
        let line = summary_line(&Summary {
            output: Path::new("a.png"),
            width: 512,
            height: 256,
            samples: 4,
            seconds: 2.0,
            rays: 10_000_000,
        });
        assert_eq!(line, "wrote a.png: 512x256, 4 spp, 2.00 s, 5.0 Mrays/s");
    }
}
