//! Frame ranges (`--frames A-B` or `--frames N`) and output paths whose runs of `#` become the
//! zero-padded frame number (SPEC §10).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use anyhow::{Result, bail};

/// An inclusive range of frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    /// First frame.
    pub first: u32,
    /// Last frame (inclusive).
    pub last: u32,
}

impl FrameRange {
    /// The frames, in order.
    pub fn frames(&self) -> impl Iterator<Item = u32> + use<> {
        self.first..=self.last
    }

    /// Number of frames.
    pub fn len(&self) -> u32 {
        self.last - self.first + 1
    }
}

impl fmt::Display for FrameRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.first == self.last {
            write!(f, "{}", self.first)
        } else {
            write!(f, "{}-{}", self.first, self.last)
        }
    }
}

impl FromStr for FrameRange {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<FrameRange> {
        let number = |t: &str| {
            t.trim().parse::<u32>().map_err(|_| {
                anyhow::anyhow!(
                    "invalid --frames {s:?}: expected A-B or N (non-negative integers, A ≤ B)"
                )
            })
        };
        let range = match s.split_once('-') {
            Some((a, b)) => FrameRange {
                first: number(a)?,
                last: number(b)?,
            },
            None => {
                let n = number(s)?;
                FrameRange { first: n, last: n }
            }
        };
        if range.first > range.last {
            bail!(
                "invalid --frames {s:?}: the first frame {} is after the last {}",
                range.first,
                range.last
            );
        }
        Ok(range)
    }
}

/// True when `path` has a run of `#` to replace with a frame number.
pub fn has_frame_placeholder(path: &Path) -> bool {
    path.to_string_lossy().contains('#')
}

/// `template` with each run of `#` replaced by `frame`, zero-padded to the run's length
/// (`frame_####.png`, 42 → `frame_0042.png`; a longer number is written whole).
pub fn frame_path(template: &Path, frame: u32) -> PathBuf {
    let text = template.to_string_lossy();
    let mut out = String::with_capacity(text.len() + 4);
    let mut run = 0;
    for c in text.chars().chain(std::iter::once('\0')) {
        if c == '#' {
            run += 1;
            continue;
        }
        if run > 0 {
            out.push_str(&format!("{frame:0run$}"));
            run = 0;
        }
        if c != '\0' {
            out.push(c);
        }
    }
    PathBuf::from(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_inclusive_and_reject_reversed_or_junk() {
        assert_eq!(
            "3-7".parse::<FrameRange>().unwrap(),
            FrameRange { first: 3, last: 7 }
        );
        assert_eq!("5".parse::<FrameRange>().unwrap().len(), 1);
        assert_eq!("0-4".parse::<FrameRange>().unwrap().frames().count(), 5);
        let e = "7-3".parse::<FrameRange>().unwrap_err().to_string();
        assert!(e.contains("after the last"), "{e}");
        for bad in ["", "a-b", "-3", "3-", "1-2-3", "-1"] {
            assert!(bad.parse::<FrameRange>().is_err(), "{bad}");
        }
    }

    #[test]
    fn hash_runs_become_zero_padded_frame_numbers() {
        let p = |t: &str, f| frame_path(Path::new(t), f).to_string_lossy().into_owned();
        assert_eq!(p("out/frame_####.png", 42), "out/frame_0042.png");
        assert_eq!(p("f#.png", 123), "f123.png");
        assert_eq!(p("d##/t_###.png", 7), "d07/t_007.png");
        assert_eq!(p("plain.png", 7), "plain.png");
        assert!(has_frame_placeholder(Path::new("a_##.png")));
        assert!(!has_frame_placeholder(Path::new("a.png")));
    }
}
