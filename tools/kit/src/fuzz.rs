//! The seeded fuzz harness of the input parsers' suites (`tests/fuzz.rs`, the CLI's tile and
//! argument fuzzing): the core's seeded [`Rng`], byte-level mutations of a valid file, and [`fuzz`],
//! which runs `WAVEFRONT_FUZZ_CASES` mutated cases (default 10,000) from `WAVEFRONT_FUZZ_SEED`
//! (default 21) under a watchdog that aborts, naming the case, when one takes longer than
//! `WAVEFRONT_FUZZ_CASE_SECONDS` (default 20).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

pub use wavefront::sampling::Rng;

/// Cases per parser (`WAVEFRONT_FUZZ_CASES`, default 10,000).
pub fn cases() -> u64 {
    std::env::var("WAVEFRONT_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000)
}

/// The seed (`WAVEFRONT_FUZZ_SEED`, default 21); each parser mixes in its own name.
pub fn seed(parser: &str) -> u64 {
    let base: u64 = std::env::var("WAVEFRONT_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(21);
    parser.bytes().fold(base ^ 0x9e37_79b9_7f4a_7c15, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

/// Tokens inserted or written over bytes: numbers at and past the edges, and words of every
/// format.
const TOKENS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e39",
    "1e-45",
    "1e-400",
    "-0",
    "0",
    "-1",
    "4294967296",
    "18446744073709551616",
    "-9223372036854775808",
    "3.4028236e38",
    "1e",
    ".",
    "=",
    "[",
    "]",
    "{",
    "}",
    "\"",
    ",",
    "#",
    "\n",
    "\r",
    "\0",
    " ",
    "\\",
    "/",
    "//",
    "f",
    "v",
    "vn",
    "vt",
    "f 1",
    "f 1 2",
    "f 0 1 2",
    "f -9 1 2",
    "newmtl",
    "Kd",
    "Ns",
    "illum 99",
    "inner",
    "leaf",
    "[[sphere]]",
    "[[mesh]]",
    "[image]",
    "width = 0",
    "radius = -1",
    "\u{1F600}",
];

/// One random mutation of `bytes`.
pub fn mutate(rng: &mut Rng, bytes: &mut Vec<u8>) {
    let len = bytes.len();
    let at = rng.below(len + 1);
    match rng.below(7) {
        // Flip 1 to 8 bits.
        0 if len > 0 => {
            for _ in 0..=rng.below(8) {
                let i = rng.below(len);
                bytes[i] ^= 1 << rng.below(8);
            }
        }
        // Truncate.
        1 => bytes.truncate(at),
        // Splice: a piece of the file copied over another place.
        2 if len > 0 => {
            let from = rng.below(len);
            let n = rng.below(64).min(len - from);
            let piece = bytes[from..from + n].to_vec();
            let end = (at + rng.below(64)).min(len);
            bytes.splice(at..end, piece);
        }
        // A token replaces a short range.
        3 => {
            let end = (at + rng.below(12)).min(len);
            let t = TOKENS[rng.below(TOKENS.len())].as_bytes().to_vec();
            bytes.splice(at..end, t);
        }
        // A token is inserted.
        4 => {
            let t = TOKENS[rng.below(TOKENS.len())].as_bytes().to_vec();
            bytes.splice(at..at, t);
        }
        // A run of one random byte.
        5 => {
            let b = rng.next_u64() as u8;
            let n = 1 + rng.below(32);
            bytes.splice(at..at, std::iter::repeat_n(b, n));
        }
        // A range deleted.
        _ => {
            let end = (at + rng.below(32)).min(len);
            bytes.drain(at..end);
        }
    }
}

/// A watchdog for one parser's loop: if a case runs longer than the limit, it prints the case
/// and aborts the test process (a hang is a failure, not a test that never ends).
struct Watchdog {
    /// Milliseconds since `start` at which the current case began.
    began: Arc<AtomicU64>,
    /// The current case number.
    case: Arc<AtomicU64>,
    done: Arc<AtomicBool>,
    start: Instant,
}

impl Watchdog {
    fn new(parser: &'static str) -> Watchdog {
        let limit: u64 = std::env::var("WAVEFRONT_FUZZ_CASE_SECONDS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(20);
        let w = Watchdog {
            began: Arc::new(AtomicU64::new(0)),
            case: Arc::new(AtomicU64::new(0)),
            done: Arc::new(AtomicBool::new(false)),
            start: Instant::now(),
        };
        let (began, case, done, start) = (w.began.clone(), w.case.clone(), w.done.clone(), w.start);
        std::thread::spawn(move || {
            while !done.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(200));
                let now = start.elapsed().as_millis() as u64;
                if now.saturating_sub(began.load(Ordering::Relaxed)) > limit * 1000 {
                    eprintln!(
                        "fuzz {parser}: case {} (seed {}) still running after {limit} s: a hang",
                        case.load(Ordering::Relaxed),
                        seed(parser)
                    );
                    std::process::abort();
                }
            }
        });
        w
    }

    fn case(&self, i: u64) {
        self.case.store(i, Ordering::Relaxed);
        self.began
            .store(self.start.elapsed().as_millis() as u64, Ordering::Relaxed);
    }
}

impl Drop for Watchdog {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Relaxed);
    }
}

/// Runs `check` on `cases()` mutations (1 to 4 each) of `valid`, reporting the case of a panic.
pub fn fuzz(parser: &'static str, valid: &[u8], mut check: impl FnMut(&[u8])) {
    let mut rng = Rng(seed(parser));
    let watchdog = Watchdog::new(parser);
    for i in 0..cases() {
        watchdog.case(i);
        let mut bytes = valid.to_vec();
        for _ in 0..=rng.below(4) {
            mutate(&mut rng, &mut bytes);
        }
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| check(&bytes)));
        if result.is_err() {
            panic!(
                "fuzz {parser}: case {i} (seed {}) panicked on {:?}",
                seed(parser),
                String::from_utf8_lossy(&bytes)
            );
        }
    }
}
