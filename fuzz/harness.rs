//! The mutation fuzzer shared by the fuzz tests (`crates/agentstar-data/tests/fuzz.rs`,
//! `crates/agentstar-agent/tests/fuzz_replies.rs`), included with `#[path]`: a seeded
//! generator, the mutations, the committed corpus, and the time-bounded runner.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A single input that takes longer than this is reported as a hang.
pub const SLOW: Duration = Duration::from_secs(10);

pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        // splitmix64
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
}

const TOKENS: &[&str] = &[
    "NaN",
    "-Infinity",
    "1e300",
    "-1e300",
    "-1",
    "0",
    "-0",
    "1e-320",
    "4294967296",
    "18446744073709551616",
    "[]",
    "{}",
    "null",
    "true",
    "\"\"",
    "\"../../etc/passwd\"",
    "\"/dev/zero\"",
    "[0,0]",
    "[-1,-1]",
    "[1e300,1e300,0,0]",
    "[0,0,0,0]",
    "\u{feff}",
    "\"\\u0000\"",
    ",",
    "]",
    "}",
    "\"",
    ":",
    "<",
    ">",
    "/>",
    "<link name=\"a\"/>",
    "<joint",
    "</robot>",
    "&amp;",
    "sphere(1, 100000, 100000)",
    "loop {}",
    "part(\"a\", box(1,1,1));",
    "fn f(){f()} f();",
    "- box(1,1,1)",
    ".translate(1e300,0,0)",
    "joint(#{})",
    "\n",
    "\r\n",
    "\t",
    "\u{1F600}",
    "9999999999",
    "\x00",
    "\u{ff}",
];

pub fn mutate(rng: &mut Rng, seeds: &[Vec<u8>], base: &[u8]) -> Vec<u8> {
    let mut d = base.to_vec();
    let rounds = 1 + rng.below(8);
    for _ in 0..rounds {
        let len = d.len();
        match rng.below(9) {
            0 if len > 0 => {
                let i = rng.below(len);
                d[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                d[i] = [0u8, 0xff, 0x7f, 0x80, b'"', b'[', b'-', b'9', b'0', b'e'][rng.below(10)];
            }
            2 if len > 0 => {
                let i = rng.below(len);
                let n = 1 + rng.below((len - i).min(64));
                d.drain(i..i + n);
            }
            3 if len > 0 => {
                let i = rng.below(len);
                let n = 1 + rng.below((len - i).min(256));
                let chunk = d[i..i + n].to_vec();
                let at = rng.below(d.len() + 1);
                d.splice(at..at, chunk);
            }
            4 => {
                let t = TOKENS[rng.below(TOKENS.len())].as_bytes();
                let at = rng.below(len + 1);
                d.splice(at..at, t.iter().copied());
            }
            5 if len > 0 => {
                // Replace a number-looking run with a token.
                let i = rng.below(len);
                let mut j = i;
                while j < len && (d[j].is_ascii_digit() || b".-+e".contains(&d[j])) {
                    j += 1;
                }
                let t = TOKENS[rng.below(TOKENS.len())].as_bytes();
                d.splice(i..j.max(i), t.iter().copied());
            }
            6 if len > 0 => d.truncate(rng.below(len)),
            7 if !seeds.is_empty() => {
                let other = &seeds[rng.below(seeds.len())];
                if !other.is_empty() && len > 0 {
                    let cut = rng.below(len);
                    let from = rng.below(other.len());
                    d.truncate(cut);
                    d.extend_from_slice(&other[from..]);
                }
            }
            _ if len > 1 => {
                // Overwrite a little-endian word (lengths, counts and offsets in binary formats).
                let i = rng.below(len - 1);
                let v: u16 = [0, 1, 0xffff, 0x7fff, 0x8000][rng.below(5)];
                d[i..i + 2].copy_from_slice(&v.to_le_bytes());
            }
            _ => {}
        }
        if d.len() > 4 << 20 {
            d.truncate(4 << 20);
        }
    }
    d
}

pub fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus")
}

pub fn seeds(target: &str) -> Vec<Vec<u8>> {
    let dir = corpus_dir().join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("corpus {}: {e}", dir.display()))
        .map(|e| e.expect("entry").path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    let out: Vec<Vec<u8>> = files
        .iter()
        .map(|p| std::fs::read(p).expect("seed"))
        .collect();
    assert!(!out.is_empty(), "no seeds in {}", dir.display());
    out
}

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

pub type Run = Box<dyn Fn(&[u8])>;

/// Runs every target for its share of `AGENTSTAR_FUZZ_SECS` (default `default_secs`) and
/// fails on any panic or slow case, naming the saved input.
///
/// With `AGENTSTAR_FUZZ_CASES=N` (CI), every target runs a budget of cases instead: its
/// seeds, then mutations up to N cases in all, the same inputs on any machine for a seed.
/// `AGENTSTAR_FUZZ_SECS` (default 300 then) is a ceiling on the whole run, split between
/// the targets; a target that reaches its share stops there and the report says so.
pub fn fuzz(all: Vec<(&'static str, Run)>, default_secs: u64) {
    let case_budget = std::env::var("AGENTSTAR_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse::<u64>().ok());
    let default_secs = if case_budget.is_some() {
        300
    } else {
        default_secs
    };
    let total = Duration::from_secs(env_u64("AGENTSTAR_FUZZ_SECS", default_secs));
    let seed = env_u64("AGENTSTAR_FUZZ_SEED", 16);
    let only: Option<Vec<String>> = std::env::var("AGENTSTAR_FUZZ_ONLY")
        .ok()
        .map(|v| v.split(',').map(str::to_string).collect());
    let mut all = all;
    if let Some(only) = &only {
        all.retain(|(n, _)| only.iter().any(|o| o == n));
    }
    let per_target = total / all.len().max(1) as u32;
    let findings_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/fuzz-findings");
    let mut findings = Vec::new();
    let mut report = Vec::new();
    // Panics are caught and counted; the default hook would print each one.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    for (ti, (name, run)) in all.iter().enumerate() {
        let corpus = seeds(name);
        let mut rng = Rng(seed ^ (ti as u64).wrapping_mul(0x9E37_79B9));
        let start = Instant::now();
        let (mut cases, mut slowest) = (0u64, Duration::ZERO);
        // Every seed as it is first, then mutations until the target's share of time is spent.
        let more = |cases: u64| match case_budget {
            Some(n) => cases < corpus.len() as u64 || (cases < n && start.elapsed() < per_target),
            None => cases < corpus.len() as u64 || start.elapsed() < per_target,
        };
        while more(cases) {
            let input = if (cases as usize) < corpus.len() {
                corpus[cases as usize].clone()
            } else {
                let base = &corpus[rng.below(corpus.len())];
                mutate(&mut rng, &corpus, base)
            };
            let t = Instant::now();
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(&input)));
            let took = t.elapsed();
            slowest = slowest.max(took);
            cases += 1;
            let what = match outcome {
                Err(p) => Some(format!(
                    "panic: {}",
                    p.downcast_ref::<String>()
                        .cloned()
                        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default()
                )),
                Ok(()) if took > SLOW => Some(format!("took {took:?}")),
                Ok(()) => None,
            };
            if let Some(what) = what {
                let dir = findings_dir.join(name);
                let _ = std::fs::create_dir_all(&dir);
                let file = dir.join(format!("case-{seed}-{cases}"));
                if findings.len() < 20 {
                    let _ = std::fs::write(&file, &input);
                }
                findings.push(format!("{name}: {what} ({})", file.display()));
            }
        }
        let short = match case_budget {
            Some(n) if cases < n => format!(" (stopped at its time share, {n} budgeted)"),
            _ => String::new(),
        };
        report.push(format!(
            "{name}: {cases} cases in {:.1} s, slowest {:.0} ms{short}",
            start.elapsed().as_secs_f64(),
            slowest.as_secs_f64() * 1e3
        ));
    }
    std::panic::set_hook(hook);
    eprintln!("fuzz (seed {seed}):\n  {}", report.join("\n  "));
    assert!(
        findings.is_empty(),
        "{} finding(s):\n{}",
        findings.len(),
        findings[..findings.len().min(20)].join("\n")
    );
}
