//! `agentstar score`: per-frame and per-sequence scores of the posed model.

use crate::common::OpenSession as _;
use crate::common::{print_json, select_frames, FrameScore, SessionArgs, PASS_IOU};
use agentstar_render::DEFAULT_BAND_PX;
use agentstar_reports::{
    score_table, FrameAppearance, ModelColoursVerdict, ScoreReport, SequenceScore,
};
use agentstar_track::appearance::{
    judge_fits, model_colour_fits, neighbour_consistency, AppearanceConfig, AppearanceFrame,
    ModelColours,
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

/// One frame's full render, read: which side faces the camera, and each part's pixels in
/// view outside the hands with how many of them lie off the object mask.
type FrameRender = (
    Option<agentstar_reports::view::FrameFacing>,
    Vec<(u64, u64)>,
);

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
    // Per frame, one read of its masks and one full render at its pose: its scores, which
    // side faces the camera, and where each part sits against the object's mask.
    let n_parts = s.model.model.parts.len();
    let per_frame: Vec<(FrameScore, FrameRender)> = frames
        .par_iter()
        .map(|&i| {
            let inputs = s.target(i)?;
            let buffers = s.render_buffers(i);
            let score = s.score_on(i, &inputs, Some(&buffers), a.depth_weight)?;
            let target = &inputs.0;
            let hand = target.keep().map(|k| k.not());
            Ok((
                score,
                (
                    s.facing_in(i, &buffers),
                    buffers.part_pixels_off_mask(n_parts, target.mask(), hand.as_ref()),
                ),
            ))
        })
        .collect::<Result<_>>()?;
    let (scores, per_frame): (Vec<FrameScore>, Vec<FrameRender>) = per_frame.into_iter().unzip();
    let summary = summarise(&scores, a.pass_iou);
    let appearance = if a.no_appearance {
        vec![]
    } else {
        appearance(&s, &frames)?
    };
    let facing: Vec<_> = per_frame.iter().filter_map(|(f, _)| f.clone()).collect();
    let tree = &s.model.model.tree;
    let jointed: Vec<bool> = (0..n_parts)
        .map(|k| (0..tree.joints().len()).any(|j| tree.parts_moved_by(j).contains(&k)))
        .collect();
    let parts: Vec<(String, bool)> = s
        .model
        .model
        .parts
        .iter()
        .zip(jointed)
        .map(|(p, j)| (p.name.clone(), j))
        .collect();
    let counts: Vec<(String, Vec<(u64, u64)>)> = frames
        .iter()
        .zip(per_frame)
        .map(|(&i, (_, c))| (s.capture.frames[i].name.clone(), c))
        .collect();
    let parts_off_mask = agentstar_reports::parts::parts_off_mask(&counts, &parts);
    let model_colours = model_colours_verdict(&appearance);
    if a.json {
        print_json(&ScoreReport {
            frames: scores,
            sequence: summary.clone(),
            appearance,
            facing,
            model_colours,
            parts_off_mask,
        })?;
    } else {
        print!(
            "{}",
            score_table(&scores, &summary, &appearance, model_colours.as_ref())
        );
        print!("{}", agentstar_reports::view::facing_lines(&facing));
        print!(
            "{}",
            agentstar_reports::parts::parts_off_mask_text(&parts_off_mask)
        );
    }
    Ok(if summary.below_gate.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// The model's colours judged over the frames' figures as the tracker judges them
/// ([`judge_fits`] on each frame's `model_ncc` and `model_regions`).
fn model_colours_verdict(appearance: &[FrameAppearance]) -> Option<ModelColoursVerdict> {
    let fits: Vec<(f64, f64)> = appearance
        .iter()
        .filter_map(|a| Some((a.model_ncc?, a.model_regions?)))
        .collect();
    let (judged, painted, regions, keyframes) = judge_fits(&fits)?;
    Some(ModelColoursVerdict {
        keyframes,
        painted,
        regions,
        likeness: judged == ModelColours::AsPainted,
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
            // Both figures from one rendering: as painted (`model_agreement`'s) and as regions.
            let fits = frames[i]
                .as_ref()
                .and_then(|f| model_colour_fits(&s.model.model, s.scale(), f, &poses[i], &cfg));
            let (model_ncc, model_regions) = (fits.map(|f| f.0), fits.map(|f| f.1));
            FrameAppearance {
                frame: cap.frames[i].name.clone(),
                ncc: a.ncc,
                pairs: a.pairs,
                model_ncc,
                model_regions,
            }
        })
        .collect())
}

/// The score table without appearance figures (what `track` and `example` print).
pub fn print_table(scores: &[FrameScore], summary: &SequenceScore) {
    print!("{}", score_table(scores, summary, &[], None));
}
