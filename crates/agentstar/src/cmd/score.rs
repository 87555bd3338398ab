//! `agentstar score`: per-frame and per-sequence scores of the posed model.

use crate::common::{print_json, select_frames, FrameScore, SessionArgs, PASS_IOU};
use anyhow::Result;
use rayon::prelude::*;
use serde::Serialize;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar score --capture cap --model run/scene.rhai --poses run/pose.json --json"
)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    /// Frames: `all` (default), names, stems or `a..b` ranges.
    #[arg(long)]
    frames: Option<String>,
    /// Weight w of the depth term in `combined = IoU − w · min(depth error in canonical units, 1)`.
    #[arg(long, default_value_t = 0.1)]
    depth_weight: f64,
    /// The gate on the visible-region IoU.
    #[arg(long, default_value_t = PASS_IOU)]
    pass_iou: f64,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// The sequence summary.
#[derive(Debug, Serialize)]
pub struct SequenceScore {
    pub frames: usize,
    pub mean_iou_visible: f64,
    pub median_iou_visible: f64,
    pub min_iou_visible: f64,
    pub worst_frame: String,
    pub pass_iou: f64,
    /// Frames under the gate, worst first.
    pub below_gate: Vec<String>,
}

pub fn summarise(scores: &[FrameScore], pass_iou: f64) -> SequenceScore {
    let mut gates: Vec<f64> = scores.iter().map(FrameScore::gate).collect();
    gates.sort_by(|a, b| a.total_cmp(b));
    let n = gates.len().max(1);
    let worst = scores.iter().min_by(|a, b| a.gate().total_cmp(&b.gate()));
    let mut below: Vec<&FrameScore> = scores.iter().filter(|s| s.gate() < pass_iou).collect();
    below.sort_by(|a, b| a.gate().total_cmp(&b.gate()).then(a.frame.cmp(&b.frame)));
    SequenceScore {
        frames: scores.len(),
        mean_iou_visible: gates.iter().sum::<f64>() / n as f64,
        median_iou_visible: if gates.is_empty() {
            0.0
        } else {
            gates[gates.len() / 2]
        },
        min_iou_visible: gates.first().copied().unwrap_or(0.0),
        worst_frame: worst.map(|w| w.frame.clone()).unwrap_or_default(),
        pass_iou,
        below_gate: below.iter().map(|s| s.frame.clone()).collect(),
    }
}

pub fn run(a: Args) -> Result<ExitCode> {
    let s = a.session.open()?;
    let frames = select_frames(&s.capture, a.frames.as_deref())?;
    let scores: Vec<FrameScore> = frames
        .par_iter()
        .map(|&i| s.score(i, a.depth_weight))
        .collect::<Result<_>>()?;
    let summary = summarise(&scores, a.pass_iou);
    if a.json {
        print_json(&serde_json::json!({"frames": scores, "sequence": summary}))?;
    } else {
        print_table(&scores, &summary);
    }
    Ok(if summary.below_gate.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

pub fn print_table(scores: &[FrameScore], summary: &SequenceScore) {
    let has_depth = scores.iter().any(|s| s.depth_mae.is_some());
    print!(
        "{:<14} {:>11} {:>8} {:>9} {:>9} {:>8}",
        "frame", "iou_visible", "iou_raw", "render_px", "mask_px", "hand_px"
    );
    if has_depth {
        print!(" {:>10} {:>9}", "depth_canon", "combined");
    }
    println!();
    for s in scores {
        let mark = if s.gate() < summary.pass_iou {
            "  <"
        } else {
            ""
        };
        print!(
            "{:<14} {:>11} {:>8.4} {:>9} {:>9} {:>8}",
            s.frame,
            s.iou_visible.map_or("n/a".into(), |v| format!("{v:.4}")),
            s.iou_raw,
            s.render_px,
            s.mask_px,
            s.hand_px
        );
        if has_depth {
            print!(
                " {:>10} {:>9.4}",
                s.depth_mae_canon
                    .map_or("n/a".into(), |v| format!("{v:.4}")),
                s.combined
            );
        }
        println!("{mark}");
    }
    println!(
        "sequence: {} frames, IoU visible mean {:.4}, median {:.4}, min {:.4} ({}); {} below {:.2}",
        summary.frames,
        summary.mean_iou_visible,
        summary.median_iou_visible,
        summary.min_iou_visible,
        summary.worst_frame,
        summary.below_gate.len(),
        summary.pass_iou
    );
}
