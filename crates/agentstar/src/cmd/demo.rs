//! `agentstar demo OUT`: the main job on a built-in capture, offline. Synthesises an
//! articulated capture with hands (a box whose lid opens while it turns in the hand), tracks
//! it with the known model, evaluates against the ground truth and prints the table.

use crate::cmd::synth::{describe, write_synth};
use crate::common::{print_json, write_tracked_poses};
use agentstar_bench::table::result_table;
use agentstar_bench::{run_sequence_observed, Method, RunConfig};
use agentstar_synth::{synthesize, SynthConfig};
use anyhow::{bail, Context, Result};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

/// Marks a directory the demo wrote, so that a second run may replace it.
const MARKER: &str = ".agentstar-demo";

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar demo /tmp/agentstar-demo\n  agentstar eval --capture /tmp/agentstar-demo/capture --model /tmp/agentstar-demo/run/scene.rhai --poses /tmp/agentstar-demo/run/pose.json"
)]
pub struct Args {
    /// Directory to write into (capture/ and run/); replaced if an earlier demo wrote it.
    out: PathBuf,
    /// Object of the synthetic library.
    #[arg(long, default_value = "box")]
    object: String,
    /// Number of keyframes.
    #[arg(long, default_value_t = 10)]
    frames: usize,
    /// Seed of the synthetic capture.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let out = &a.out;
    if out.exists() {
        let empty = std::fs::read_dir(out)
            .with_context(|| format!("reading {}", out.display()))?
            .next()
            .is_none();
        if !empty {
            if !out.join(MARKER).is_file() {
                bail!(
                    "{} exists and was not written by `agentstar demo`; choose a new directory",
                    out.display()
                );
            }
            std::fs::remove_dir_all(out).with_context(|| format!("replacing {}", out.display()))?;
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    agentstar_data::atomic::write_atomic(&out.join(MARKER), b"written by agentstar demo\n")?;
    let t0 = std::time::Instant::now();
    let capture = synthesize(&SynthConfig {
        object: a.object.clone(),
        frames: a.frames,
        seed: a.seed,
        ..SynthConfig::default()
    })?;
    let cap_dir = out.join("capture");
    write_synth(&cap_dir, &capture)?;
    eprintln!("demo: synthesised {}", describe(&capture));
    eprintln!("demo: tracking with the known model …");
    let bar = crate::common::progress(capture.frames.len(), "track");
    let (r, poses) = run_sequence_observed(
        &capture,
        Method::Tracker,
        &RunConfig::default(),
        &|line: &str| {
            if bar.position() < bar.length().unwrap_or(0) {
                bar.inc(1);
            }
            bar.set_message(line.to_string());
        },
    )?;
    bar.finish_and_clear();
    let run_dir = out.join("run");
    let scene = run_dir.join("scene.rhai");
    agentstar_data::atomic::write_atomic(&scene, capture.object.script.as_bytes())?;
    let pose_path = run_dir.join("pose.json");
    let cap = crate::common::open_capture(&cap_dir)?;
    write_tracked_poses(&cap, &capture.model.tree, capture.scale, &poses, &pose_path)?;
    let total = t0.elapsed().as_secs_f64();
    if a.json {
        print_json(
            &json!({"capture": cap_dir, "model": scene, "poses": pose_path,
            "seconds_total": total, "result": r}),
        )?;
        return Ok(ExitCode::SUCCESS);
    }
    println!("demo written to {}", out.display());
    println!("  capture: {} ({})", cap_dir.display(), describe(&capture));
    println!(
        "  model:   {} (the known model; scale {} m)",
        scene.display(),
        capture.scale
    );
    println!(
        "  poses:   {} (tracked in {:.1} s, {} evaluations; {:.1} s in all)",
        pose_path.display(),
        r.seconds,
        r.evaluations,
        total
    );
    println!();
    print!("{}", result_table(&r));
    println!();
    println!(
        "next: agentstar render --capture {c} --model {m} --poses {p} --out {o}",
        c = cap_dir.display(),
        m = scene.display(),
        p = pose_path.display(),
        o = out.join("views").display()
    );
    Ok(ExitCode::SUCCESS)
}
