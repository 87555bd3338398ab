//! `agentstar score`: per-frame and per-sequence scores of the posed model.

use crate::common::{print_json, select_frames, FrameScore, SessionArgs, PASS_IOU};
use agentstar_agent::reports::{FrameAppearance, ScoreReport, SequenceScore};
use agentstar_render::DEFAULT_BAND_PX;
use agentstar_track::appearance::{
    model_agreement, neighbour_consistency, AppearanceConfig, AppearanceFrame,
};
use anyhow::{bail, Result};
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
    /// The gate: on the band IoU (visible region without the ±band-px boundary band of the
    /// observed mask), or on the visible IoU with `--band-px 0`.
    #[arg(long, default_value_t = PASS_IOU)]
    pass_iou: f64,
    /// Half-width in pixels of the band around the observed mask's boundary that the band IoU
    /// excludes (a segmenter's 1–2 px boundary errors); 0 scores no band and gates the visible
    /// IoU. The default is chosen by measurement (docs/scoring.md).
    #[arg(long, default_value_t = DEFAULT_BAND_PX)]
    band_px: f64,
    /// Leave out the appearance figure (photometric consistency with the neighbouring
    /// keyframes; it reads every frame's image).
    #[arg(long)]
    no_appearance: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// The sequence summary of `scores` against `pass_iou`.
pub fn summarise(scores: &[FrameScore], pass_iou: f64) -> SequenceScore {
    SequenceScore::of(scores, pass_iou)
}

pub fn run(a: Args) -> Result<ExitCode> {
    if !(a.band_px.is_finite() && a.band_px >= 0.0 && a.band_px <= 64.0) {
        bail!(
            "--band-px {}: give a width in pixels from 0 to 64",
            a.band_px
        );
    }
    let mut s = a.session.open()?;
    s.band_px = a.band_px;
    let frames = select_frames(&s.capture, a.frames.as_deref())?;
    let scores: Vec<FrameScore> = frames
        .par_iter()
        .map(|&i| s.score(i, a.depth_weight))
        .collect::<Result<_>>()?;
    let summary = summarise(&scores, a.pass_iou);
    let appearance = if a.no_appearance {
        vec![]
    } else {
        appearance(&s, &frames)?
    };
    if a.json {
        print_json(&ScoreReport {
            frames: scores,
            sequence: summary.clone(),
            appearance,
        })?;
    } else {
        print_table(&scores, &summary, &appearance);
    }
    Ok(if summary.below_gate.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// Each selected frame's appearance figure ([`neighbour_consistency`]), from every frame's
/// image and mask (a frame whose image cannot be read, or is not its camera's size, has no
/// figure and is no reference). Empty when no frame has an image.
fn appearance(s: &crate::common::Session, selected: &[usize]) -> Result<Vec<FrameAppearance>> {
    let cap = &s.capture;
    let inputs: Vec<Option<(image::RgbImage, agentstar_render::BitMask)>> = (0..cap.frames.len())
        .into_par_iter()
        .map(|i| crate::common::appearance_inputs(cap, i))
        .collect::<Result<_>>()?;
    if inputs.iter().all(Option::is_none) {
        return Ok(vec![]);
    }
    let frames: Vec<Option<AppearanceFrame<'_>>> = inputs
        .iter()
        .zip(&cap.frames)
        .map(|(x, f)| {
            x.as_ref().map(|(img, mask)| AppearanceFrame {
                camera: &f.camera,
                rgb: img.as_raw(),
                mask,
            })
        })
        .collect();
    let poses: Vec<_> = (0..cap.frames.len()).map(|i| s.gen_pose(i)).collect();
    let cfg = AppearanceConfig::default();
    Ok(selected
        .par_iter()
        .map(|&i| {
            let a = neighbour_consistency(&s.model.model, s.scale(), &frames, &poses, i, &cfg);
            let model_ncc = frames[i]
                .as_ref()
                .and_then(|f| model_agreement(&s.model.model, s.scale(), f, &poses[i], &cfg).ncc);
            FrameAppearance {
                frame: cap.frames[i].name.clone(),
                ncc: a.ncc,
                pairs: a.pairs,
                model_ncc,
            }
        })
        .collect())
}

pub fn print_table(scores: &[FrameScore], summary: &SequenceScore, appearance: &[FrameAppearance]) {
    let has_depth = scores.iter().any(|s| s.depth_mae.is_some());
    let band = summary.band_px;
    print!("{:<14} {:>11}", "frame", "iou_visible");
    if band.is_some() {
        print!(" {:>9}", "iou_band");
    }
    print!(
        " {:>8} {:>9} {:>9} {:>8}",
        "iou_raw", "render_px", "mask_px", "hand_px"
    );
    if has_depth {
        print!(" {:>10} {:>9}", "depth_canon", "combined");
    }
    let has_appearance = appearance.len() == scores.len();
    let has_model = has_appearance && appearance.iter().any(|a| a.model_ncc.is_some());
    if has_appearance {
        print!(" {:>6}", "ncc");
    }
    if has_model {
        print!(" {:>6}", "model");
    }
    println!();
    for (k, s) in scores.iter().enumerate() {
        let mark = if s.gate() < summary.pass_iou {
            "  <"
        } else {
            ""
        };
        print!(
            "{:<14} {:>11}",
            s.frame,
            s.iou_visible.map_or("n/a".into(), |v| format!("{v:.4}"))
        );
        if band.is_some() {
            print!(
                " {:>9}",
                s.iou_band.map_or("n/a".into(), |v| format!("{v:.4}"))
            );
        }
        print!(
            " {:>8.4} {:>9} {:>9} {:>8}",
            s.iou_raw, s.render_px, s.mask_px, s.hand_px
        );
        if has_depth {
            print!(
                " {:>10} {:>9.4}",
                s.depth_mae_canon
                    .map_or("n/a".into(), |v| format!("{v:.4}")),
                s.combined
            );
        }
        if has_appearance {
            print!(
                " {:>6}",
                appearance[k]
                    .ncc
                    .map_or("n/a".into(), |v| format!("{v:.2}"))
            );
        }
        if has_model {
            print!(
                " {:>6}",
                appearance[k]
                    .model_ncc
                    .map_or("n/a".into(), |v| format!("{v:.2}"))
            );
        }
        println!("{mark}");
    }
    let band_text = match (band, summary.mean_iou_band, summary.min_iou_band) {
        (Some(px), Some(mean), Some(min)) => {
            format!(
                "; band IoU (±{px} px boundary excluded, the gate) mean {mean:.4}, min {min:.4}"
            )
        }
        _ => String::new(),
    };
    println!(
        "sequence: {} frames, IoU visible mean {:.4}, median {:.4}, min {:.4} ({}){band_text}; {} below {:.2}",
        summary.frames,
        summary.mean_iou_visible,
        summary.median_iou_visible,
        summary.min_iou_visible,
        summary.worst_frame,
        summary.below_gate.len(),
        summary.pass_iou
    );
    let with: Vec<&FrameAppearance> = appearance.iter().filter(|a| a.ncc.is_some()).collect();
    if let Some(low) = with
        .iter()
        .min_by(|a, b| a.ncc.unwrap_or(0.0).total_cmp(&b.ncc.unwrap_or(0.0)))
    {
        let mean = with.iter().filter_map(|a| a.ncc).sum::<f64>() / with.len() as f64;
        println!(
            "appearance: NCC of each frame's colours with its neighbouring keyframes' at these poses, mean {mean:.2}, lowest {:.2} ({}); {} of {} frames with evidence",
            low.ncc.unwrap_or(0.0),
            low.frame,
            with.len(),
            appearance.len()
        );
    } else if !appearance.is_empty() {
        println!(
            "appearance: no evidence (no frame's colours vary enough on the model to compare)"
        );
    }
}
