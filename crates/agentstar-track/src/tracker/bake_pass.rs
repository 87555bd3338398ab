//! `track --bake`: the model's colours baked from the keyframes whose basin the outline alone
//! settles, and the passes that weigh colours run again with them for the other frames.
//!
//! A frame is settled when no pose of another basin explains its mask nearly as well: every
//! twin the tracker weighs (flips, principal half-turns, hinge swaps) and every turn about
//! the model's principal axes ([`TURN_STEP_DEG`] apart), placed on the mask as the appearance
//! pass places them and the best refined in a basin's window (those that slope back into the
//! frame's own basin are none), either ends within [`REJECTED_BASIN_DEG`] of the frame's pose
//! (the bound past which the appearance pass counts a pose as another basin: a flip, a
//! half-turn, not a pose beside it) or scores under the frame's own pose by more than
//! [`CHOICE_KEEP`] — the margin within which the sequence-level choice keeps a basin to weigh.
//! A mug whose handle is in view is settled there (when its outline also tells top from
//! bottom: the hard suite's printed mug is the same upside down); with the handle hidden,
//! every turn about the body ties, and it is not. A can is settled nowhere (its outline is
//! the same upside down and under any turn about its axis): baking cannot break a symmetry
//! every frame shares, and the report says so instead of guessing.
//!
//! The bake ([`crate::bake`]) checks the settled frames against each other: a frame whose
//! colours disagree with the others' is left out and the rest baked again (baked from a
//! wrong pose, the error is locked into the colours), and the bake is refused when fewer
//! than [`MIN_SETTLED`] agree; with fewer than [`MIN_SETTLED`] settled frames nothing is
//! baked. Otherwise the warm start
//! ([`track_from_video`]) runs on the baked model from the plain track's poses, the settled
//! frames anchored, and names each frame it moved to another basin.

use super::*;
use crate::axis::SymmetryAxis;
use crate::bake::{bake, Bake, BakeConfig, BakeFrame};
use crate::hypotheses::{principal_axes, twin_candidates};
use crate::temporal::angle_deg;
use agentstar_render::BitMask;

/// Fewest settled frames to bake from: the bake checks each frame against the others, and
/// one frame alone cannot be checked.
pub const MIN_SETTLED: usize = 2;

/// Rivals of a frame's pose refined after placing (the best placed first): a frame whose
/// best few placed rivals all refine clearly under its pose is settled.
const RIVALS_REFINED: usize = 4;

/// What the outline alone says of one frame's basin at its tracked pose.
#[derive(Debug, Clone, PartialEq)]
pub struct SettledFrame {
    pub frame: usize,
    /// The frame's score (gate IoU) at its pose.
    pub iou: f64,
    /// The best pose of another basin (at least [`REJECTED_BASIN_DEG`] away) after refinement: its
    /// rotation from the frame's pose (degrees) and its score; `None`: none came within
    /// [`SETTLE_NEAR`] when placed.
    pub rival: Option<(f64, f64)>,
    /// No rival within [`CHOICE_KEEP`] of the frame's score, and the frame's score at least
    /// the tracker's own threshold for a frame it doubts ([`TrackConfig::drop_threshold`]).
    pub settled: bool,
}

/// What `track --bake` did after the plain track.
#[derive(Debug, Clone)]
pub enum BakeOutcome {
    /// Fewer than [`MIN_SETTLED`] frames settled: nothing baked, the plain result kept.
    TooFewSettled,
    /// The settled frames' colours disagree and fewer than [`MIN_SETTLED`] agree with the
    /// others: nothing used, the plain result kept (the last bake tried, its disagreeing
    /// frames named).
    Refused(Bake),
    /// Baked and used: the warm start on the baked model, its frames moved to other basins.
    Used(Bake, Box<WarmStart>),
}

/// The settled frames, the outcome, and the baked model when it was used.
#[derive(Debug, Clone)]
pub struct BakePass {
    pub settled: Vec<SettledFrame>,
    /// Settled frames left out of the bake because their colours disagreed with the
    /// others' (in frame order): the bake used is made from the rest.
    pub left_out: Vec<usize>,
    pub outcome: BakeOutcome,
    /// The model coloured by the bake (for a caller that stores it), when used.
    pub baked_model: Option<ObjectModel>,
}

impl BakePass {
    /// The settled frames (in frame order): those baked from, and those left out.
    pub fn settled_frames(&self) -> Vec<usize> {
        self.settled
            .iter()
            .filter(|s| s.settled)
            .map(|s| s.frame)
            .collect()
    }
}

/// Which frames the outline alone settles at `poses` (see the module's description).
pub fn settled_frames(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    poses: &[GenPose],
    cfg: &TrackConfig,
) -> Result<Vec<SettledFrame>, TrackError> {
    if poses.len() != frames.len() {
        return Err(TrackError::Invalid(format!(
            "{} poses for {} frames",
            poses.len(),
            frames.len()
        )));
    }
    let s = Searcher::new(model, scale, frames, cfg)?;
    frames
        .iter()
        .zip(poses)
        .enumerate()
        .map(|(i, (frame, pose))| settled_one(&s, frame, i, pose))
        .collect()
}

fn settled_one(
    s: &Searcher<'_>,
    frame: &TrackFrame<'_>,
    i: usize,
    pose: &GenPose,
) -> Result<SettledFrame, TrackError> {
    let problem = s.problem_of(frame, pose);
    let iou = problem.evaluator().combined(pose);
    let apart = |g: &GenPose| angle_deg(&(g.pose.rotation * pose.pose.rotation.inverse()));
    let mut candidates = twin_candidates(s.model, s.scale, pose);
    if let Some((centre, axes)) = principal_axes(s.model, &pose.states) {
        let steps = (360.0 / TURN_STEP_DEG).round() as usize;
        for axis in axes {
            let turn = SymmetryAxis { centre, axis };
            candidates
                .extend((1..steps).map(|m| turn.turn(pose, s.scale, m as f64 * TURN_STEP_DEG)));
        }
    }
    candidates.retain(|g| apart(g) >= REJECTED_BASIN_DEG);
    // Each placed as turned, or moved back onto the mask where that scores higher (a turn
    // about an axis off the outline shifts it).
    let stats = mask_stats(frame.target);
    let pivot = posed_extent(s.model, &pose.states).0;
    let mut placed: Vec<(GenPose, f64)> = candidates
        .par_iter()
        .map_init(
            || problem.evaluator(),
            |ev, g| {
                let raw = ev.combined(g);
                match stats {
                    Some(stats) if raw < iou - APPEARANCE_TIE => {
                        let (moved, sc) = realign(s.model, frame, s.scale, g, stats, pivot);
                        if sc > raw {
                            (moved, sc)
                        } else {
                            (g.clone(), raw)
                        }
                    }
                    _ => (g.clone(), raw),
                }
            },
        )
        .collect();
    s.evals
        .fetch_add(4 * placed.len(), std::sync::atomic::Ordering::Relaxed);
    placed.retain(|(_, sc)| *sc >= iou - SETTLE_NEAR);
    placed.sort_by(|a, b| b.1.total_cmp(&a.1));
    placed.truncate(RIVALS_REFINED);
    // Refined in the window of a whole basin: a turn that only slopes back toward the
    // frame's pose (a mug turned 30° with its handle in view) returns there and is no rival.
    let refined: Vec<Result<(GenPose, f64), TrackError>> = placed
        .par_iter()
        .enumerate()
        .map(|(k, (g, _))| {
            s.refine(
                frame,
                g,
                &s.basin_window(),
                s.cfg.seed + 9_973 * (i as u64 + 1) + k as u64,
            )
        })
        .collect();
    let mut rival: Option<(f64, f64)> = None;
    for r in refined {
        let (g, sc) = r?;
        let deg = apart(&g);
        if deg >= REJECTED_BASIN_DEG && rival.is_none_or(|(_, best)| sc > best) {
            rival = Some((deg, sc));
        }
    }
    let settled = iou >= s.cfg.drop_threshold && rival.is_none_or(|(_, sc)| sc < iou - CHOICE_KEEP);
    Ok(SettledFrame {
        frame: i,
        iou,
        rival,
        settled,
    })
}

/// One line for people on a frame's settledness.
pub fn settled_line(f: &SettledFrame, name: &str) -> String {
    let rival = match f.rival {
        Some((deg, sc)) => format!("best rival {deg:.0}° away at IoU {sc:.4}"),
        None => "no rival near".to_string(),
    };
    format!(
        "{name}: {} (IoU {:.4}, {rival})",
        if f.settled { "settled" } else { "not settled" },
        f.iou
    )
}

/// `track --bake` after a plain track: finds the settled frames at `plain`'s poses, bakes
/// the model's colours from them ([`bake`]; `hands`: each frame's hand mask), and where the
/// bake is made and agrees, tracks again from `plain` on the baked model with the settled
/// frames anchored ([`track_from_video`], [`BasinPolicy::Search`]). The model's own colours
/// stay where no settled frame saw the surface; where one did, the video's replace them.
#[allow(clippy::too_many_arguments)]
pub fn track_with_bake(
    model: &ObjectModel,
    scale: f64,
    (frames, between): (&[TrackFrame<'_>], &[Vec<TrackFrame<'_>>]),
    hands: &[Option<BitMask>],
    plain: &TrackResult,
    cfg: &TrackConfig,
    bake_cfg: &BakeConfig,
    observe: &dyn TrackObserver,
) -> Result<BakePass, TrackError> {
    let settled = settled_frames(model, scale, frames, &plain.poses, cfg)?;
    for f in &settled {
        observe.line(&format!("bake: {}", settled_line(f, &frames[f.frame].name)));
    }
    let chosen: Vec<usize> = settled
        .iter()
        .filter(|f| f.settled && frames[f.frame].rgb.is_some())
        .map(|f| f.frame)
        .collect();
    if chosen.len() < MIN_SETTLED {
        observe.line(&format!(
            "bake: {} frame(s) settled by the outline alone (with an image), {MIN_SETTLED} needed: nothing baked, the plain track kept",
            chosen.len()
        ));
        return Ok(BakePass {
            settled,
            left_out: Vec::new(),
            outcome: BakeOutcome::TooFewSettled,
            baked_model: None,
        });
    }
    // Baked from the settled frames; those whose colours disagree with the others' (a pose
    // a few degrees off carries the print's edges elsewhere, a twin all of it) are left out
    // and the rest baked again, until the frames agree or too few are left.
    let bake_from = |chosen: &[usize]| -> Result<Bake, TrackError> {
        let bake_frames: Vec<BakeFrame<'_>> = chosen
            .iter()
            .filter_map(|&i| {
                let f = &frames[i];
                Some(BakeFrame {
                    name: &f.name,
                    camera: &f.camera,
                    rgb: f.rgb?,
                    mask: f.target.mask(),
                    hand: hands.get(i).and_then(Option::as_ref),
                    pose: &plain.poses[i],
                })
            })
            .collect();
        bake(model, scale, &bake_frames, bake_cfg)
    };
    let mut chosen = chosen;
    let mut left_out: Vec<usize> = Vec::new();
    let mut b = bake_from(&chosen)?;
    if !b.disagreeing().is_empty() {
        let names: Vec<String> = b
            .disagreeing()
            .iter()
            .map(|f| format!("{} ({:.0})", f.name, f.residual.unwrap_or(0.0)))
            .collect();
        let agreeing = b.agreeing();
        if agreeing.len() < MIN_SETTLED {
            observe.line(&format!(
                "bake: refused: settled frame(s) {} disagree with the others (median colour difference in 8-bit units) and fewer than {MIN_SETTLED} agree: nothing used, the plain track kept",
                names.join(", ")
            ));
            return Ok(BakePass {
                settled,
                left_out,
                outcome: BakeOutcome::Refused(b),
                baked_model: None,
            });
        }
        left_out = (0..chosen.len())
            .filter(|k| !agreeing.contains(k))
            .map(|k| chosen[k])
            .collect();
        chosen = agreeing.iter().map(|&k| chosen[k]).collect();
        let left: Vec<&str> = left_out.iter().map(|&i| frames[i].name.as_str()).collect();
        observe.line(&format!(
            "bake: settled frame(s) {} disagree with the others (median colour difference in 8-bit units): {} left out, baked again from the {} that agree",
            names.join(", "),
            left.join(", "),
            chosen.len()
        ));
        b = bake_from(&chosen)?;
    }
    left_out.sort_unstable();
    observe.line(&format!(
        "bake: baked from {} settled frame(s), {} of {} texels seen; tracking again with the baked colours, the frames baked from anchored",
        chosen.len(),
        b.seen_texels,
        b.surface_texels
    ));
    let baked = b.apply(model)?;
    let warm = track_from_video(
        &baked,
        scale,
        (frames, between),
        (&plain.poses, &chosen),
        BasinPolicy::Search,
        cfg,
        observe,
    )?;
    Ok(BakePass {
        settled,
        left_out,
        outcome: BakeOutcome::Used(b, Box::new(warm)),
        baked_model: Some(baked),
    })
}
