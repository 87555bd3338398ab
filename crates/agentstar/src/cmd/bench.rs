//! `agentstar bench`: run the automatic tracker (and the paper's agent-free ablations) over a
//! synthetic suite, evaluate with the paper's metrics, print the tables with wall time per
//! sequence; check or record accuracy tolerances.

use crate::cmd::synth::write_synth;
use crate::common::{print_json, write_tracked_poses};
use agentstar_bench::suite::{
    general_suite_over, parse_seed_range, GENERAL_CAPTURE_SEEDS, GENERAL_MAX_CAPTURES,
    GENERAL_OBJECT_SEEDS, SUITES,
};
use agentstar_bench::table::tables;
use agentstar_bench::tolerance::{check, record, ToleranceFile};
use agentstar_bench::{run_sequence_observed, suite, Method, RunConfig, SequenceResult};
use anyhow::{anyhow, bail, Context, Result};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar bench --suite quick --check bench/quick-tolerances.json\n  agentstar bench --suite full --results bench/full.md --out /tmp/bench-runs"
)]
pub struct Args {
    /// The suite: quick (CI), full, hard (by hand: 7 × 20 keyframes at 640×480; use --methods
    /// tracker), general (by hand: 24 generated objects × 3 seeds in the hard suite's captures)
    /// or sfm (cameras by structure from motion for a 191-frame 640×480 clip in a textured
    /// room: time per stage and camera errors; needs COLMAP).
    #[arg(long, default_value = "quick")]
    suite: String,
    /// Methods, comma separated: tracker, no-temporal, vlm-free.
    #[arg(long, default_value = "tracker,no-temporal,vlm-free")]
    methods: String,
    /// Only these objects of the suite (comma separated; the general suite's are gen-N).
    #[arg(long)]
    only: Option<String>,
    /// The general suite over these generator seeds instead of its own 0..24 (START..END):
    /// objects no one has looked at, as `--objects 24..48`.
    #[arg(long, value_name = "START..END")]
    objects: Option<String>,
    /// The general suite with this many captures of each object instead of 3 (1 to 10).
    #[arg(long, value_name = "K")]
    captures: Option<usize>,
    /// Write every capture and every method's pose.json under this directory.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Add a row per sequence to the metric tables.
    #[arg(long)]
    per_sequence: bool,
    /// Fail (exit 1) when a figure breaks the tolerances in this file.
    #[arg(long)]
    check: Option<PathBuf>,
    /// Record tolerances from this run into this file.
    #[arg(long)]
    record: Option<PathBuf>,
    /// Write the tables (Markdown, with date and machine) and the results (same name, .json).
    #[arg(long)]
    results: Option<PathBuf>,
    /// Evaluations per local search of the tracker.
    #[arg(long, default_value_t = 2400)]
    evals: usize,
    /// Seed of the trackers' searches.
    #[arg(long, default_value_t = 17)]
    seed: u64,
    /// The tracker leaves out the sequence-level choice at the end (twins of every frame, one
    /// basin per frame by dynamic programming over the sequence; on by default).
    #[arg(long)]
    no_sequence_choice: bool,
    /// The tracker sees the masks alone, not the frames' colours (no appearance term).
    #[arg(long)]
    no_appearance: bool,
    /// Synthesise K in-between frames between consecutive keyframes of every sequence (the
    /// same keyframes, K + 1 video frames apart), which the tracker follows.
    #[arg(long, default_value_t = 0, value_name = "K")]
    between: usize,
    /// Every sequence with this many keyframes instead of its suite's (quick 8, full 15,
    /// hard and general 20); the same objects, motion kind and capture settings. With
    /// `--keyframes 15 --between 9` a hard sequence is a 150-frame hand-held clip at
    /// 640×480 with keyframes every 10 frames (141 frames tracked: none after the last
    /// keyframe).
    #[arg(long, value_name = "N")]
    keyframes: Option<usize>,
    /// Print the results as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// The sfm suite: frames of the clip (every one needs a camera).
    #[arg(long, default_value_t = 191)]
    sfm_clip_frames: usize,
    /// The sfm suite: frame width and height in pixels.
    #[arg(long, default_value = "640x480")]
    sfm_size: String,
    /// The sfm suite: the orbit's sweep in degrees.
    #[arg(long, default_value_t = 90.0)]
    sfm_orbit_deg: f64,
    /// The sfm suite: keyframes every this many frames.
    #[arg(long, default_value_t = 10)]
    sfm_every: usize,
    /// The sfm suite: at most this many frames reconstructed (the others registered).
    #[arg(long, default_value_t = agentstar_sfm::DEFAULT_RECONSTRUCT_MAX)]
    sfm_max_frames: usize,
    /// The sfm suite: the most SIFT features per frame.
    #[arg(long, default_value_t = agentstar_sfm::DEFAULT_MAX_FEATURES)]
    sfm_max_features: usize,
    /// The sfm suite: matching overlap within the reconstructed frames.
    #[arg(long, default_value_t = agentstar_sfm::DEFAULT_OVERLAP)]
    sfm_overlap: usize,
    /// The sfm suite: SIFT on the CPU even where COLMAP has a GPU.
    #[arg(long)]
    sfm_no_gpu: bool,
}

/// A line about this machine for recorded results.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!(
        "{cpu}, {threads} threads, {} {}",
        std::env::consts::OS,
        std::env::consts::ARCH
    )
}

pub fn today() -> String {
    agentstar_import::process::output_within(
        std::process::Command::new("date").arg("+%Y-%m-%d"),
        agentstar_import::process::PROBE_LIMIT,
    )
    .ok()
    .and_then(|o| String::from_utf8(o.stdout).ok())
    .map(|s| s.trim().to_string())
    .filter(|s| !s.is_empty())
    .unwrap_or_else(|| "unknown date".into())
}

pub fn run(a: Args) -> Result<ExitCode> {
    if a.suite == "sfm" {
        let (w, h) = a
            .sfm_size
            .split_once('x')
            .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
            .ok_or_else(|| anyhow!("--sfm-size {}: WIDTHxHEIGHT, e.g. 640x480", a.sfm_size))?;
        return crate::cmd::bench_sfm::run(&crate::cmd::bench_sfm::SfmBench {
            frames: a.sfm_clip_frames,
            width: w,
            height: h,
            keyframe_every: a.sfm_every,
            orbit_deg: a.sfm_orbit_deg,
            seed: a.seed,
            settings: crate::cmd::bench_sfm::settings(
                a.sfm_max_frames,
                a.sfm_max_features,
                a.sfm_overlap,
                !a.sfm_no_gpu,
            ),
            out: a.out.clone(),
            results: a.results.clone(),
            json: a.json,
        });
    }
    let mut specs = suite(&a.suite).ok_or_else(|| {
        anyhow!(
            "unknown suite `{}`; choose one of {}, sfm",
            a.suite,
            SUITES.join(", ")
        )
    })?;
    if a.objects.is_some() || a.captures.is_some() {
        if a.suite != "general" {
            bail!(
                "--objects and --captures choose the general suite's objects; this is the {} suite",
                a.suite
            );
        }
        let objects = match &a.objects {
            Some(text) => parse_seed_range(text).map_err(|e| anyhow!("--objects: {e}"))?,
            None => GENERAL_OBJECT_SEEDS,
        };
        let captures = a.captures.unwrap_or(GENERAL_CAPTURE_SEEDS);
        if !(1..=GENERAL_MAX_CAPTURES).contains(&captures) {
            bail!("--captures {captures}: between 1 and {GENERAL_MAX_CAPTURES}");
        }
        specs = general_suite_over(objects, captures);
    }
    if let Some(only) = &a.only {
        let keep: Vec<&str> = only.split(',').map(str::trim).collect();
        specs.retain(|s| keep.contains(&s.synth.object.as_str()));
        if specs.is_empty() {
            bail!(
                "--only {only}: no sequence of the {} suite has those objects",
                a.suite
            );
        }
    }
    if a.keyframes.is_some_and(|n| n < 2) {
        bail!("--keyframes must be at least 2 (a sequence to track)");
    }
    for spec in &mut specs {
        spec.synth.between = a.between;
        if let Some(n) = a.keyframes {
            spec.synth.frames = n;
        }
    }
    let methods: Vec<Method> = a
        .methods
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            Method::parse(s).ok_or_else(|| {
                anyhow!(
                    "unknown method `{s}`; choose from {}",
                    Method::ALL.map(|m| m.as_str()).join(", ")
                )
            })
        })
        .collect::<Result<_>>()?;
    if methods.is_empty() {
        bail!("--methods is empty");
    }
    if let (Some(r), Some(t)) = (&a.results, &a.record) {
        if r.with_extension("json") == *t {
            bail!(
                "--results {} writes {} too; record the tolerances elsewhere",
                r.display(),
                t.display()
            );
        }
    }
    let tolerances: Option<ToleranceFile> = match &a.check {
        Some(p) => Some(
            serde_json::from_str(&agentstar_data::read_text(p)?)
                .with_context(|| format!("{}: not a tolerance file", p.display()))?,
        ),
        None => None,
    };
    let cfg = RunConfig {
        seed: a.seed,
        local_evals: a.evals,
        sequence_choice: !a.no_sequence_choice,
        appearance: !a.no_appearance,
        ..RunConfig::default()
    };
    let mut results: Vec<SequenceResult> = Vec::new();
    let total = specs.len() * methods.len();
    let bar = crate::common::progress(total, "bench");
    for spec in &specs {
        let capture = agentstar_synth::synthesize(&spec.synth)?;
        let id = capture.id();
        if let Some(out) = &a.out {
            write_synth(&out.join(&id).join("capture"), &capture)
                .with_context(|| format!("writing {id}"))?;
        }
        for &method in &methods {
            bar.suspend(|| {
                eprintln!(
                    "bench [{}/{total}] {id} with {} …",
                    results.len() + 1,
                    method.as_str()
                )
            });
            bar.set_message(format!("{id} ({})", method.as_str()));
            let (r, poses) = run_sequence_observed(&capture, method, &cfg, &|line: &str| {
                bar.set_message(format!("{id}: {line}"));
                bar.suspend(|| eprintln!("bench   {id}: {line}"));
            })?;
            bar.inc(1);
            bar.suspend(|| {
                eprintln!(
                    "bench   {:.1} s, IoU mean {:.4}, EPE {} cm, rot. median {} °",
                    r.info.seconds,
                    r.iou_mean,
                    r.metrics.epe_cm.map_or("–".into(), |v| format!("{v:.2}")),
                    r.metrics
                        .rotation_median_deg
                        .map_or("–".into(), |v| format!("{v:.2}"))
                )
            });
            if let Some(out) = &a.out {
                let cap_dir = out.join(&id).join("capture");
                let cap = crate::common::open_capture(&cap_dir)?;
                write_tracked_poses(
                    &cap,
                    &capture.model.tree,
                    capture.scale,
                    &poses,
                    &out.join(&id).join(method.as_str()).join("pose.json"),
                )?;
            }
            results.push(r);
        }
    }
    bar.finish_and_clear();
    let mut md = tables(&results, a.per_sequence);
    if a.suite == "hard" {
        md.push('\n');
        md.push_str(&agentstar_bench::table::hard_table(&results));
    }
    if a.suite == "general" {
        md.push('\n');
        md.push_str(&agentstar_bench::table::general_table(&results));
    }
    if a.suite == "hard" || a.suite == "general" {
        md.push('\n');
        md.push_str(&agentstar_bench::table::misses_table(&results));
    }
    let header = format!(
        "## agentstar bench: {} suite, {} sequence(s), methods {}\n\nRecorded {} on {}; tracker with the appearance term {}, sequence-level choice {}{}{}.\n\n",
        a.suite,
        specs.len(),
        methods
            .iter()
            .map(|m| m.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        today(),
        machine(),
        if a.no_appearance { "off" } else { "on" },
        if a.no_sequence_choice { "off" } else { "on" },
        a.keyframes
            .map_or(String::new(), |n| format!("; {n} keyframes a sequence")),
        if a.between > 0 {
            format!("; {} in-between frames between keyframes", a.between)
        } else {
            String::new()
        },
    );
    if let Some(p) = &a.results {
        agentstar_data::atomic::write_atomic(p, format!("{header}{md}").as_bytes())?;
        agentstar_data::atomic::write_json(
            &p.with_extension("json"),
            &json!({"suite": a.suite, "date": today(), "machine": machine(), "results": results}),
        )?;
    }
    if let Some(p) = &a.record {
        let file = record(&results, &a.suite, &format!("{} on {}", today(), machine()));
        agentstar_data::atomic::write_json(p, &file)?;
        eprintln!("bench: recorded tolerances in {}", p.display());
    }
    if a.json {
        print_json(&json!({"suite": a.suite, "results": results}))?;
    } else {
        print!("{header}{md}");
    }
    if let Some(t) = &tolerances {
        let violations = check(&results, t);
        if !violations.is_empty() {
            eprintln!(
                "bench: {} figure(s) regressed past the tolerances of {}:",
                violations.len(),
                a.check
                    .as_ref()
                    .map_or(String::new(), |p| p.display().to_string())
            );
            for v in &violations {
                eprintln!("  {v}");
            }
            return Ok(ExitCode::from(1));
        }
        eprintln!("bench: every figure within the recorded tolerances");
    }
    Ok(ExitCode::SUCCESS)
}
