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
    let log = std::sync::Mutex::new(Vec::<(f64, String)>::new());
    let (r, poses) = run_sequence_observed(
        &capture,
        Method::Tracker,
        &RunConfig::default(),
        &|line: &str| {
            if bar.position() < bar.length().unwrap_or(0) {
                bar.inc(1);
            }
            bar.set_message(line.to_string());
            if let Ok(mut l) = log.lock() {
                l.push((t0.elapsed().as_secs_f64(), line.to_string()));
            }
        },
    )?;
    bar.finish_and_clear();
    let run_dir = out.join("run");
    std::fs::create_dir_all(&run_dir).with_context(|| format!("creating {}", run_dir.display()))?;
    let scene = run_dir.join("scene.rhai");
    agentstar_data::atomic::write_atomic(&scene, capture.object.script.as_bytes())?;
    let pose_path = run_dir.join("pose.json");
    let cap = crate::common::open_capture(&cap_dir)?;
    write_tracked_poses(&cap, &capture.model.tree, capture.scale, &poses, &pose_path)?;
    // The run's record: where its capture is, a ledger of what was done, the report.
    agentstar_data::atomic::write_atomic(
        &run_dir.join("run.json"),
        serde_json::to_string_pretty(&agentstar_data::runfile::RunFile {
            capture: "../capture".into(),
            model: "scene.rhai".into(),
            poses: "pose.json".into(),
            finish: Default::default(),
        })?
        .as_bytes(),
    )?;
    let steps = log.into_inner().unwrap_or_default();
    let session = crate::common::Session::open(&cap_dir, &scene, &pose_path)?;
    write_overlay_sheet(&session, &run_dir.join("images").join("overlays.png"))?;
    write_demo_ledger(&run_dir, &describe(&capture), &steps, &r)?;
    let report = run_dir.join("report.html");
    crate::cmd::report::write_report(
        &session,
        &scene,
        &run_dir,
        Some(&cap_dir.join("gt.json")),
        &report,
        640,
        format!("agentstar demo: {} tracked with its known model", a.object),
    )?;
    let total = t0.elapsed().as_secs_f64();
    if a.json {
        print_json(
            &json!({"capture": cap_dir, "model": scene, "poses": pose_path,
            "report": report, "seconds_total": total, "result": r}),
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
        r.info.seconds,
        r.info.evaluations,
        total
    );
    println!("  report:  {} (open it in a browser)", report.display());
    println!();
    print!("{}", result_table(&r));
    println!();
    println!(
        "next: agentstar render --capture {c} --model {m} --poses {p} --out {o}",
        c = agentstar_data::shell_quote(&cap_dir),
        m = agentstar_data::shell_quote(&scene),
        p = agentstar_data::shell_quote(&pose_path),
        o = agentstar_data::shell_quote(&out.join("views"))
    );
    Ok(ExitCode::SUCCESS)
}

/// The demo's ledger: the synthesis, each line the tracker logged, and the evaluation with
/// a contact sheet of the overlays.
fn write_demo_ledger(
    run_dir: &std::path::Path,
    described: &str,
    steps: &[(f64, String)],
    r: &agentstar_bench::SequenceResult,
) -> Result<()> {
    use agentstar_data::ledger::{append, LedgerEntry};
    let path = run_dir.join("ledger.jsonl");
    let entry = |step: u64, time_s: f64, kind: &str, tool: &str, summary: String| LedgerEntry {
        step,
        time_s,
        kind: kind.into(),
        tool: tool.into(),
        args: serde_json::Value::Null,
        summary,
        scores: Default::default(),
        images: vec![],
        scene_version: Some(1),
        pose_version: None,
    };
    append(
        &path,
        &entry(
            1,
            0.0,
            "system",
            "synth",
            format!("synthesised {described}"),
        ),
    )?;
    let mut n = 1;
    for (t, line) in steps {
        n += 1;
        append(&path, &entry(n, *t, "pose", "track", line.clone()))?;
    }
    let mut last = entry(
        n + 1,
        steps.last().map_or(0.0, |s| s.0),
        "diagnostic",
        "eval",
        "evaluated against the ground truth".into(),
    );
    last.pose_version = Some(1);
    last.scores.insert("iou_mean".into(), r.iou_mean);
    last.scores.insert("iou_min".into(), r.iou_min);
    if let Some(v) = r.metrics.epe_cm {
        last.scores.insert("epe_cm".into(), v);
    }
    if let Some(v) = r.metrics.chamfer_cm {
        last.scores.insert("chamfer_cm".into(), v);
    }
    last.images.push("images/overlays.png".into());
    Ok(append(&path, &last)?)
}

/// A contact sheet of the model drawn over every keyframe.
fn write_overlay_sheet(s: &crate::common::Session, path: &std::path::Path) -> Result<()> {
    use agentstar_render::views::{contact_sheet, overlay, ShadeOptions};
    let mut tiles = vec![];
    for (i, f) in s.capture.frames.iter().enumerate() {
        let (_, shaded) = s.render_shaded(i, ShadeOptions { outlines: true });
        tiles.push((
            f.name.clone(),
            overlay(&s.capture.load_frame(i)?, &shaded, 0.6),
        ));
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let cols = (tiles.len() as f64).sqrt().ceil() as usize;
    agentstar_data::images::save_png_rgb(
        &contact_sheet(&tiles, cols.max(1), "tracked model over the keyframes"),
        path,
    )?;
    Ok(())
}
