//! `agentstar score`: per-frame and per-sequence scores of the posed model.

use crate::common::{print_json, select_frames, FrameScore, SessionArgs, PASS_IOU};
use agentstar_agent::reports::{ScoreReport, SequenceScore};
use anyhow::Result;
use rayon::prelude::*;
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

/// The sequence summary of `scores` against `pass_iou`.
pub fn summarise(scores: &[FrameScore], pass_iou: f64) -> SequenceScore {
    SequenceScore::of(scores, pass_iou)
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
        print_json(&ScoreReport {
            frames: scores,
            sequence: summary.clone(),
        })?;
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
