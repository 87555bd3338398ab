//! The automatic tracker: fits every keyframe's pose and joint states for a known model
//! from masks alone. A global initialisation of the frame with the most visible mask (a
//! covering of rotations and joint states, each placed on the mask by centroid and area,
//! then differential evolution from the best hypotheses); propagation through the sequence
//! from the neighbours (through the cameras and by constant velocity), with a wide search
//! (flips and a covering around the seed) whenever the score drops; a final consistency pass
//! that searches temporal outliers again from their neighbours.
//!
//! Where things are: this file holds the types ([`TrackFrame`], [`TrackConfig`],
//! [`TrackResult`]), the entry points and the order of the passes (`track_on`);
//! `searcher.rs` the searcher every pass uses (refinement, the global search, twins, rescue,
//! the wide search, settling); `place.rs` placing a model on a mask; one file per pass:
//! `appearance_pass.rs` (and the consistency pass), `choice.rs` (the sequence-level choice),
//! `axis_pass.rs`, `video_pass.rs` (every keyframe refined on the in-between frames beside
//! it), `polish_pass.rs` (the last polish), `warm.rs` (`track_from`), `independent.rs` (the
//! per-frame baseline),
//! `bake_pass.rs` (`track --bake`: the settled frames, the bake, the warm start on it). Each
//! pass keeps its constants beside it; those several passes read are in `tuning.rs`.

use crate::appearance::{AppearanceFrame, ModelColours, ReferenceView};
use crate::hypotheses::{LocalWindow, PRUNE_SLACK};
use crate::objective::FrameProblem;
use crate::update::GenPose;
use crate::TrackError;
use agentstar_geom::pose::Rigid;
use agentstar_geom::{ObjectModel, PinholeCamera};
use agentstar_render::ScoreTarget;
use rayon::prelude::*;

mod appearance_pass;
mod axis_pass;
mod bake_pass;
mod chain;
mod choice;
mod independent;
mod place;
mod polish_pass;
mod searcher;
#[cfg(test)]
mod tests;
mod tuning;
mod video_pass;
mod warm;

use appearance_pass::*;
use axis_pass::*;
pub use bake_pass::*;
use chain::*;
use choice::*;
pub use independent::*;
use place::*;
use polish_pass::*;
use searcher::*;
use tuning::*;
use video_pass::*;
pub use warm::*;

/// One frame to track.
#[derive(Debug, Clone)]
pub struct TrackFrame<'a> {
    pub name: String,
    pub camera: PinholeCamera,
    pub target: &'a ScoreTarget,
    pub world_from_camera: Option<Rigid>,
    /// The frame's colour image (RGB, 8 bits, row-major, `camera.width × camera.height`), for
    /// the appearance term ([`crate::appearance`]); `None` tracks from the masks alone.
    pub rgb: Option<&'a [u8]>,
}

impl TrackFrame<'_> {
    /// The frame as the appearance term sees it, when it has a colour image.
    pub(crate) fn appearance(&self) -> Option<AppearanceFrame<'_>> {
        self.rgb.map(|rgb| AppearanceFrame {
            camera: &self.camera,
            rgb,
            mask: self.target.mask(),
        })
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct TrackConfig {
    pub seed: u64,
    /// Rotations in the initial covering.
    pub rotations: usize,
    /// Samples per joint in the initial covering.
    pub joint_samples: usize,
    /// Evaluations of each local search.
    pub local_evals: usize,
    /// A frame whose score falls under this, or this far under its neighbour's, gets a wide search.
    pub drop_threshold: f64,
    pub drop_margin: f64,
    /// Search temporal outliers again at the end.
    pub consistency_pass: bool,
    /// Start from this frame instead of the one with the largest visible mask.
    pub init_frame: Option<usize>,
    /// Choose one basin per frame for the whole sequence at the end (twins of every frame
    /// refined, then dynamic programming over frames; [`crate::sequence`]). On by default:
    /// on the hard suite it took mean rotation errors down on 5 of 7 sequences
    /// (bench/hard-2026-12-02c-sequence-choice.md), and the quick suite is unchanged.
    pub sequence_choice: bool,
    /// Let the frames' colours enter the tracking: the sequence-level choice (photometric
    /// consistency between hypotheses of neighbouring frames), the appearance passes and the
    /// axis pass about a round body's axis; frames without an image use the masks alone.
    pub appearance: bool,
    /// With in-between frames: also return every in-between frame's pose, followed from the
    /// final keyframe poses ([`TrackResult::between`]).
    pub between_poses: bool,
    /// Polish every keyframe's pose once more at the end, where it scores higher
    /// ([`crate::hypotheses::polish_last`]; a few degrees, no other basin).
    pub last_polish: bool,
}

impl Default for TrackConfig {
    fn default() -> Self {
        TrackConfig {
            seed: 17,
            rotations: 240,
            joint_samples: 3,
            local_evals: 2400,
            drop_threshold: 0.92,
            drop_margin: 0.04,
            consistency_pass: true,
            init_frame: None,
            sequence_choice: true,
            appearance: true,
            between_poses: false,
            last_polish: true,
        }
    }
}

/// The tracker's switches as the `track` command and the benchmark's methods state them, and
/// the one place they become a [`TrackConfig`] (the command-line flags, the bench methods and
/// their ablations agree because they all go through it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrackSwitches {
    pub seed: u64,
    /// Evaluations of each local search.
    pub local_evals: usize,
    /// The temporal passes: the final consistency pass and the sequence-level choice (off:
    /// the "no temporal" ablation, which turns the choice off too).
    pub temporal: bool,
    /// The sequence-level choice (only with `temporal`).
    pub sequence_choice: bool,
    /// The frames' colours (off: the masks alone).
    pub appearance: bool,
}

impl From<TrackSwitches> for TrackConfig {
    fn from(s: TrackSwitches) -> TrackConfig {
        TrackConfig {
            seed: s.seed,
            local_evals: s.local_evals,
            consistency_pass: s.temporal,
            sequence_choice: s.sequence_choice && s.temporal,
            appearance: s.appearance,
            ..TrackConfig::default()
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct TrackResult {
    pub poses: Vec<GenPose>,
    /// Gate IoU per frame.
    pub scores: Vec<f64>,
    pub init_frame: usize,
    /// What the tracker did, frame by frame, for people to read.
    pub log: Vec<String>,
    pub evaluations: usize,
    /// With in-between frames and [`TrackConfig::between_poses`]: each gap's in-between
    /// frames' poses (gap g: between keyframes g and g + 1, in temporal order) and IoU
    /// (`None`: carried at constant velocity, not fitted: hidden or out of view).
    pub between: Vec<Vec<(GenPose, Option<f64>)>>,
    /// What the sequence-level choice weighed, when it ran: for a benchmark to tell a miss
    /// the choice never had a hypothesis for from one it weighed and did not take.
    pub choice: Option<ChoiceTrace>,
    /// The turns the frames' colours wanted and the video's motion refused, each frame's last
    /// one still apart from its final pose ([`RefusedTurn`]): for a person or an agent to
    /// check.
    pub refused_turns: Vec<RefusedTurn>,
}

/// A turn the final appearance pass found a frame's colours preferring and did not take,
/// because the video's motion from a neighbouring keyframe keeps the frame where it is
/// ([`appearance_pass`]'s chain test). The video cannot settle every basin (a capsule's
/// outline is the same end over end), so the refusal is reported, not only logged
/// (play-test 2026-12-06: the one frame left 164° off was refused so, on a line among many).
#[derive(Debug, Clone, PartialEq)]
pub struct RefusedTurn {
    /// The keyframe.
    pub frame: usize,
    /// The turn and its evidence, as the pass wrote it (its colours and IoU before and
    /// after).
    pub what: String,
    /// The pose the colours wanted.
    pub pose: GenPose,
}

/// Of `refused`, each frame's last turn, kept where the frame's final pose (`poses`) still
/// lies half [`REJECTED_BASIN_DEG`] or more from it (a later pass may have taken it).
fn still_refused(refused: Vec<RefusedTurn>, poses: &[GenPose]) -> Vec<RefusedTurn> {
    let mut last: std::collections::BTreeMap<usize, RefusedTurn> = Default::default();
    for r in refused {
        last.insert(r.frame, r);
    }
    last.into_values()
        .filter(|r| {
            poses.get(r.frame).is_some_and(|g| {
                g.pose.rotation.angle_to(&r.pose.pose.rotation)
                    >= 0.5 * REJECTED_BASIN_DEG.to_radians()
            })
        })
        .collect()
}

/// The hypotheses the sequence-level choice weighed per keyframe (the frame's own pose as
/// the choice refined it, its twins, the neighbours' poses carried to it and the basins its
/// global search found, each within the choice's IoU margin of the frame's best, so the
/// frame's own pose may be missing; a round body's turned to its print) and the one its
/// cheapest path took (`path[i]` indexes `hypotheses[i]`), before the path's pick was
/// polished. Poses on the model the search ran on (a stand-in of a dense mesh); passes after
/// the choice may have moved the frames since.
#[derive(Debug, Clone, PartialEq)]
pub struct ChoiceTrace {
    pub hypotheses: Vec<Vec<GenPose>>,
    pub path: Vec<usize>,
}

/// What a tracking run reports as it goes: each line of its log (progress), and the poses
/// found so far, so that a caller can keep them if the run is stopped. A closure over lines
/// is an observer that ignores the poses.
pub trait TrackObserver: Sync {
    fn line(&self, line: &str);
    /// The poses so far, frame by frame (`None`: not tracked yet): after each frame of the
    /// propagation and after each pass over the sequence.
    fn poses(&self, _poses: &[Option<GenPose>]) {}
}

impl<F: Fn(&str) + Sync> TrackObserver for F {
    fn line(&self, line: &str) {
        self(line)
    }
}

/// What the tracker did, line by line, also handed to an observer as it happens (progress),
/// and the time and evaluations of each phase, for the closing line ([`Log::phases`]).
struct Log<'o> {
    lines: Vec<String>,
    /// The turns the appearance pass refused ([`RefusedTurn`]), in the order refused.
    refused: Vec<RefusedTurn>,
    observe: &'o dyn TrackObserver,
    phases: Vec<(&'static str, f64, usize)>,
    phase_start: (std::time::Instant, usize),
    /// Every frame's rotation after each pass that ran, by the pass's name: what a warm start
    /// reads to say which pass moved a frame to another basin ([`Log::pass_done`]).
    passes: Vec<(&'static str, Vec<agentstar_geom::UnitQuaternion>)>,
}

impl<'o> Log<'o> {
    fn new(observe: &'o dyn TrackObserver) -> Self {
        Log {
            lines: Vec::new(),
            refused: Vec::new(),
            observe,
            phases: Vec::new(),
            phase_start: (std::time::Instant::now(), 0),
            passes: Vec::new(),
        }
    }

    /// Records every frame's rotation after the pass `name` (the warm start's report of
    /// frames moved to another basin names the pass that moved them).
    fn pass_done(&mut self, name: &'static str, poses: &[GenPose]) {
        self.passes
            .push((name, poses.iter().map(|g| g.pose.rotation).collect()));
    }

    fn push(&mut self, line: String) {
        self.observe.line(&line);
        self.lines.push(line);
    }

    /// The poses so far, to the observer (after a frame of the propagation).
    fn poses(&self, poses: &[Option<GenPose>]) {
        self.observe.poses(poses);
    }

    /// Every frame's pose, to the observer (after a pass over the whole sequence).
    fn all_poses(&self, poses: &[GenPose]) {
        let some: Vec<Option<GenPose>> = poses.iter().cloned().map(Some).collect();
        self.observe.poses(&some);
    }

    /// Ends a stretch of the phase `name`: its wall time and the evaluations counted since
    /// the last stretch ended are added to the phase's totals.
    fn phase(&mut self, name: &'static str, s: &Searcher<'_>) {
        let evals = s.evals.load(std::sync::atomic::Ordering::Relaxed);
        let (t0, e0) = self.phase_start;
        let (secs, n) = (t0.elapsed().as_secs_f64(), evals.saturating_sub(e0));
        match self.phases.iter_mut().find(|p| p.0 == name) {
            Some(p) => {
                p.1 += secs;
                p.2 += n;
            }
            None => self.phases.push((name, secs, n)),
        }
        self.phase_start = (std::time::Instant::now(), evals);
    }

    /// The closing line: where the time went.
    fn phases_line(&mut self) {
        let parts: Vec<String> = self
            .phases
            .iter()
            .map(|(name, secs, evals)| format!("{name} {secs:.1} s ({evals} evaluations)"))
            .collect();
        if !parts.is_empty() {
            self.push(format!("time: {}", parts.join(", ")));
        }
    }
}

/// Tracks every frame. `scale` is the shared object scale (from the pose file or known).
pub fn track(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    cfg: &TrackConfig,
) -> Result<TrackResult, TrackError> {
    track_observed(model, scale, frames, cfg, &|_: &str| {})
}

/// [`track`], calling `observe` with each line of the log as the tracker writes it (one per
/// frame tracked, one per frame searched again). A dense model is searched on its stand-in
/// ([`crate::standin`]) and every pose polished on the model at the end.
pub fn track_observed(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<TrackResult, TrackError> {
    track_video(model, scale, frames, &[], cfg, observe)
}

/// [`track_observed`] with the video between keyframes: `between[g]` holds the in-between
/// frames between keyframes g and g + 1 in temporal order (empty, or fewer gaps than
/// keyframes minus one: no video there). Each keyframe is reached by following the video
/// from the keyframe before it ([`chain`]), and the motion each chain measured enters the
/// passes over the sequence.
pub fn track_video(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    between: &[Vec<TrackFrame<'_>>],
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<TrackResult, TrackError> {
    // Gap g lies between keyframes g and g + 1: none after the last keyframe.
    if between
        .iter()
        .skip(frames.len().saturating_sub(1))
        .any(|g| !g.is_empty())
    {
        return Err(TrackError::Invalid(format!(
            "{} gaps of in-between frames for {} keyframes",
            between.len(),
            frames.len()
        )));
    }
    on_stand_in(model, scale, frames, cfg, &[], observe, |searched| {
        track_on(searched, scale, frames, between, cfg, observe)
    })
}

fn track_on(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    between: &[Vec<TrackFrame<'_>>],
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<TrackResult, TrackError> {
    let s = Searcher::new(model, scale, frames, cfg)?;
    let mut log = Log::new(observe);
    // The in-between frames' own searcher (their targets at half resolution), when there
    // are any; `typical`: what a keyframe shows of the object.
    let flat_between: Vec<TrackFrame<'_>> = between.iter().flatten().cloned().collect();
    let chain_s = if flat_between.is_empty() {
        None
    } else {
        Some(Searcher::new(model, scale, &flat_between, cfg)?)
    };
    let typical = typical_visible(frames);
    let gap_frames = |g: usize| between.get(g).map_or(&[][..], |v| v.as_slice());
    // The frame with the most visible mask.
    let init = match cfg.init_frame {
        Some(i) if i < frames.len() => i,
        // The most visible mask, discounted by how much of the object the hands may hide.
        _ => (0..frames.len())
            .max_by_key(|&i| {
                let t = frames[i].target;
                let (vis, hidden) = match t.keep() {
                    Some(k) => (t.mask().and(k).count(), k.not().count()),
                    None => (t.mask().count(), 0),
                };
                let score = vis as f64 * vis as f64 / (vis + hidden).max(1) as f64;
                ((score * 16.0) as u64, std::cmp::Reverse(i))
            })
            .unwrap_or(0),
    };
    let rotations = haar_rotations(cfg.rotations, cfg.seed);
    // The window of a search from a neighbour's pose: one inter-frame step away.
    let step_window = LocalWindow {
        angle_deg: 30.0,
        shift: 0.08,
        depth: 0.15,
        joint_deg: 40.0,
        evals: cfg.local_evals,
    };
    let joint_sets = s.joint_grid();
    let hyps = s.covering(&frames[init], &rotations, &joint_sets);
    if hyps.is_empty() {
        return Err(TrackError::Invalid(format!(
            "frame {} has an empty object mask; cannot initialise",
            frames[init].name
        )));
    }
    let top = diverse(&hyps, GLOBAL_KEEP, 30.0);
    let refined: Vec<Result<(GenPose, f64), TrackError>> = top
        .par_iter()
        .enumerate()
        .map(|(k, g)| s.basin(&frames[init], g, cfg.seed + 100 * k as u64))
        .collect();
    let mut refined: Vec<(GenPose, f64)> = refined.into_iter().collect::<Result<_, _>>()?;
    refined.sort_by(|a, b| b.1.total_cmp(&a.1));
    let (mut g0, mut s0) = refined
        .first()
        .cloned()
        .ok_or_else(|| TrackError::Invalid("initialisation found nothing".into()))?;
    // No frame is tracked yet: among basins that explain the mask alike, only the model's
    // own colours (a label part, a badge) can choose.
    let mut chosen = String::new();
    if let Some((k, text)) = s.pick(&frames[init], (&g0, s0), &refined[1..], &[]) {
        (g0, s0) = refined[k + 1].clone();
        chosen = format!("; {text}");
    }
    log.phase("init", &s);
    log.push(format!(
        "init {} ({}): covering of {} hypotheses, best placed {:.3}, refined {:.4}{chosen}",
        frames[init].name,
        if cfg.init_frame == Some(init) {
            "as asked"
        } else {
            "the keyframe with the most of the object in view, after hands"
        },
        hyps.len(),
        hyps[0].1,
        s0
    ));
    let n = frames.len();
    let mut poses: Vec<Option<GenPose>> = vec![None; n];
    let mut scores = vec![0.0; n];
    // The band IoUs of the frames tracked so far: what right poses score on this object.
    let mut bands = vec![s.band_iou(&frames[init], init, &g0)];
    // The basins each frame's global search found, for the sequence-level choice.
    let mut alternatives: Vec<Vec<Scored>> = vec![Vec::new(); n];
    poses[init] = Some(g0);
    scores[init] = s0;
    log.poses(&poses);
    // Forward then backward from the initial frame.
    let order: Vec<(usize, isize)> = ((init + 1)..n)
        .map(|i| (i, -1))
        .chain((0..init).rev().map(|i| (i, 1)))
        .collect();
    for (i, dir) in order {
        let prev_i = (i as isize + dir) as usize;
        let prev = poses[prev_i]
            .clone()
            .ok_or_else(|| TrackError::Invalid("propagation order".into()))?;
        let mut seeds = vec![carry(&prev, &frames[prev_i], &frames[i])];
        let prev2_i = prev_i as isize + dir;
        // The video between the two keyframes, followed from the one tracked.
        let gap = i.min(prev_i);
        let mut chained = None;
        if let (Some(cs), false) = (&chain_s, gap_frames(gap).is_empty()) {
            let mut path: Vec<&TrackFrame<'_>> = gap_frames(gap).iter().collect();
            if dir == 1 {
                path.reverse();
            }
            let followed = follow(
                cs,
                &frames[prev_i],
                &prev,
                &path,
                &frames[i],
                typical,
                cfg.seed + 1_000_003 * (gap as u64 + 1) + (dir == 1) as u64,
            )?;
            seeds = followed.arrival.clone();
            chained = Some(followed);
        } else if prev2_i >= 0 && (prev2_i as usize) < n {
            if let Some(p2) = &poses[prev2_i as usize] {
                let prevt = seeds[0].clone();
                seeds.push(extrapolate_through(
                    p2,
                    &frames[prev2_i as usize],
                    &frames[prev_i],
                    &frames[i],
                    &prevt,
                    &model.tree,
                ));
            }
        }
        let results: Vec<Result<(GenPose, f64), TrackError>> = seeds
            .par_iter()
            .enumerate()
            .map(|(k, g)| {
                let seed = cfg.seed + 7919 * i as u64 + k as u64;
                // Arriving from a chain, the motion predicts the keyframe as it predicted
                // the chain's frames.
                let fit = s.refine(&frames[i], g, &step_window, seed)?;
                Ok(match seeds.last() {
                    Some(predicted) if chained.is_some() => {
                        s.hold_unseen(&frames[i], fit, predicted, CHAIN_HOLD_TIE)
                    }
                    _ => fit,
                })
            })
            .collect();
        let (mut g, mut sc) =
            best_of(results)?.ok_or_else(|| TrackError::Invalid("search found nothing".into()))?;
        let mut how = "local";
        if let Some(followed) = &chained {
            // The motion the chain measured, for the passes over the sequence.
            s.set_gap(gap, Gap::across(frames, (prev_i, &prev), (i, &g)));
            how = "followed";
            let carried = followed.poses.len().saturating_sub(followed.fitted);
            let how_followed = if carried == 0 {
                "each fitted to its mask".to_string()
            } else {
                format!(
                    "{} fitted to their masks, {carried} carried by the motion (masks too hidden, or that no pose near the motion explains)",
                    followed.fitted
                )
            };
            log.push(format!(
                "{} ← {}: followed {} in-between frame(s), {how_followed}",
                frames[i].name,
                frames[prev_i].name,
                followed.poses.len(),
            ));
            if let Some(cs) = &chain_s {
                s.absorb_evals(cs);
            }
            log.phase("video", &s);
        } else if sc < cfg.drop_threshold || sc < scores[prev_i] - cfg.drop_margin {
            if let Some(r) = s
                .wide(
                    &frames[i],
                    &g,
                    &seeds[0],
                    (cfg.seed + i as u64, cfg.seed + 31 * i as u64),
                    sc - PRUNE_SLACK,
                )?
                .filter(|r| r.1 > sc)
            {
                (g, sc) = r;
                how = "wide";
            }
        }
        log.phase("propagation", &s);
        // The frames tracked just before this one, at their poses: the appearance term's
        // references.
        let refs: Vec<ReferenceView<'_>> = if cfg.appearance {
            [
                Some(prev_i),
                Some(prev2_i)
                    .filter(|&k| k >= 0 && (k as usize) < n)
                    .map(|k| k as usize),
            ]
            .into_iter()
            .flatten()
            .filter_map(|k| {
                let p = poses[k].as_ref()?;
                ReferenceView::new(model, scale, frames[k].appearance()?, p)
            })
            .collect()
        } else {
            vec![]
        };
        // Under the band threshold the frame may sit in a wrong basin that no search around
        // its neighbour reaches (a step of 90–150°): the whole rotation space, as at the start.
        let band = s.band_iou(&frames[i], i, &g);
        let mut note = String::new();
        // A keyframe reached through the video keeps the chain's basin unless its mask clearly
        // refuses it (its IoU under the drop threshold, or its band IoU a tie under the band
        // that sends any frame to the global search, [`CHAIN_REFUSED_BELOW`]): a global search
        // there picks by the outline alone, which is what the twins share (the chain's pose
        // stays a hypothesis of the sequence choice).
        let refused = chain_refused(band, &bands);
        let chain_holds = chained.is_some() && sc >= cfg.drop_threshold && !refused;
        let arrival = chained.as_ref().map(|_| (g.clone(), sc));
        if band < rescue_band(&bands) && !chain_holds {
            // The joint grid, and the states found here and at the neighbour: joints move
            // less between keyframes than the base does.
            let mut sets = joint_sets.clone();
            sets.push(g.states.clone());
            sets.push(prev.states.clone());
            let seeds = (
                cfg.seed + 104_729 * (i as u64 + 1),
                cfg.seed + 7_727 * (i as u64 + 1),
            );
            let rescue = s.rescue(&frames[i], (&g, sc), &rotations, sets, vec![], &refs, seeds)?;
            if let Some((r, text)) = rescue.chosen {
                (g, sc) = r;
                how = "global";
                note = format!("; {text}");
                // The gap's motion was measured to the chain's arrival, which the mask refused:
                // it joins the neighbour to a pose no longer held. The video is followed back
                // from the pose taken ([`follow_back`]).
                if let (Some(cs), true) = (&chain_s, chained.is_some()) {
                    let back = follow_back(
                        (&s, cs),
                        (frames, between),
                        (&poses, &scores),
                        (i, &g),
                        dir,
                        typical,
                    )?;
                    s.absorb_evals(cs);
                    note.push_str(&back.describe(frames));
                    for (k, hypothesis) in back.hypotheses {
                        alternatives[k].push(hypothesis);
                    }
                }
            }
            alternatives[i] = rescue.basins;
            alternatives[i].extend(arrival);
            log.phase("global", &s);
        }
        // One step's colours do not outweigh the video's motion: a chained frame is not
        // settled here (the passes over the sequence weigh colours with the chains).
        if cfg.appearance && chained.is_none() {
            if let Some((tg, tsc, text)) = s.settle(&frames[i], &g, sc, &refs, &[]) {
                (g, sc) = (tg, tsc);
                note = format!("{note}; {text}");
            }
            log.phase("appearance", &s);
        }
        log.push(format!(
            "{} from {}: {how} search, IoU {sc:.4}{note}",
            frames[i].name, frames[prev_i].name
        ));
        bands.push(s.band_iou(&frames[i], i, &g));
        poses[i] = Some(g);
        scores[i] = sc;
        log.poses(&poses);
    }
    let mut poses: Vec<GenPose> = poses
        .into_iter()
        .map(|p| p.ok_or_else(|| TrackError::Invalid("a frame was not tracked".into())))
        .collect::<Result<_, _>>()?;
    // The first frame had only the initialisation's search: under the band threshold, the
    // global search again (with its neighbours' joint states), and the wide search around each
    // neighbour's pose carried to it; the neighbours' colours choose among ties.
    if n >= 2 && s.band_iou(&frames[init], init, &poses[init]) < rescue_band(&bands) {
        let neighbours: Vec<usize> = [init.checked_sub(1), Some(init + 1).filter(|&k| k < n)]
            .into_iter()
            .flatten()
            .collect();
        let mut sets = joint_sets.clone();
        sets.push(poses[init].states.clone());
        sets.extend(neighbours.iter().map(|&k| poses[k].states.clone()));
        // And the wide search around each neighbour's pose carried here: they were tracked
        // after the first frame and may be right where it is not.
        let mut carried_wide = Vec::new();
        for &k in &neighbours {
            let carried = carry(&poses[k], &frames[k], &frames[init]);
            let seed = cfg.seed + 65_537 * (k as u64 + 1) + 3;
            carried_wide.extend(s.wide(
                &frames[init],
                &carried,
                &carried,
                (seed, seed),
                f64::NEG_INFINITY,
            )?);
        }
        let refs: Vec<ReferenceView<'_>> = if cfg.appearance {
            neighbours
                .iter()
                .filter_map(|&k| {
                    ReferenceView::new(model, scale, frames[k].appearance()?, &poses[k])
                })
                .collect()
        } else {
            vec![]
        };
        let seeds = (
            cfg.seed + 104_729 * (init as u64 + 1) + 1,
            cfg.seed + 7_727 * (init as u64 + 1) + 1,
        );
        let current = (&poses[init], scores[init]);
        let rescue = s.rescue(
            &frames[init],
            current,
            &rotations,
            sets,
            carried_wide,
            &refs,
            seeds,
        )?;
        if let Some((r, text)) = rescue.chosen {
            log.push(format!(
                "{} (the first frame): global search again, IoU {:.4} → {:.4}; {text}",
                frames[init].name, scores[init], r.1
            ));
            (poses[init], scores[init]) = r;
        }
        // Beside any the video followed back from a later keyframe proposed ([`follow_back`]).
        alternatives[init].extend(rescue.basins);
        log.phase("global", &s);
    }
    log.all_poses(&poses);
    let fixed = vec![false; n];
    let choice = after_propagation(
        &s,
        (frames, between),
        (&mut poses, &mut scores),
        &fixed,
        &alternatives,
        init,
        &mut log,
    )?;
    // Every in-between frame's pose, followed from the final keyframe poses.
    let mut between_poses = Vec::new();
    if let (Some(cs), true) = (&chain_s, cfg.between_poses) {
        for g in 0..n.saturating_sub(1) {
            let path: Vec<&TrackFrame<'_>> = gap_frames(g).iter().collect();
            if path.is_empty() {
                between_poses.push(vec![]);
                continue;
            }
            let seed = cfg.seed + 2_000_003 * (g as u64 + 1);
            let followed = follow(
                cs,
                &frames[g],
                &poses[g],
                &path,
                &frames[g + 1],
                typical,
                seed,
            )?;
            between_poses.push(followed.poses);
        }
        s.absorb_evals(cs);
        log.phase("video", &s);
    }
    log.phases_line();
    let refused_turns = still_refused(log.refused, &poses);
    Ok(TrackResult {
        poses,
        scores,
        init_frame: init,
        log: log.lines,
        evaluations: s.evals.into_inner(),
        between: between_poses,
        choice,
        refused_turns,
    })
}

/// The passes over the whole sequence once every frame has a pose (from the propagation,
/// or a warm start's), as the configuration asks for them: the consistency pass, the
/// sequence-level choice, the last appearance pass (outward from `first`), the axis pass
/// ([`axis_pass`]), the video refinement ([`video_pass`]: with the sequence choice, where
/// the capture has in-between frames) and the last polish; `fixed` frames keep their poses. The observer gets the poses after each
/// pass.
///
/// The axis pass may turn a frame about a round body's axis into a basin the sequence
/// choice weighed and did not take (a half-turn about a can's axis is one of its twins): its
/// evidence, every frame's colours against the model's and every step's, is the choice's own,
/// on a finer grid of turns.
///
/// With colours, an appearance pass also runs before the choice: a can's poses come out of
/// the consistency pass turned 15–130° about its axis (the masks cannot see that turn),
/// and the choice's twins of such a pose match no neighbour's colours, so it kept a block of
/// the can's keyframes upside down (hard suite labelcan, seeds 17, 18, 19: 3.08, 1.47, 1.40
/// cm before this session's changes, 0.72, 0.72, 1.05 after them together).
/// Whether the model's colours are a likeness of the frames', judged once the keyframes are
/// placed, where a chain followed the video between them: over the keyframes whose print is in view (the model's regions explain at least
/// [`crate::appearance::JUDGE_REGIONS_MIN`] of their colours;
/// [`crate::appearance::JUDGE_MIN_FRAMES`] of them at least), the colours as painted must
/// explain at least half of what the regions do ([`crate::appearance::judge_fits`], means over
/// those keyframes,
/// [`crate::appearance::model_colours_faithful`]). Where they do not, every later pass weighs
/// the model's colours as regions ([`ModelColours::AsRegions`]): by where their boundaries
/// fall, not by the colours. A model painted "about this colour" (a script of a printed can
/// with a plain cream label part, red ends where the frames show silver, no lettering) scored
/// its true poses under shading alone (hard suite labelcan, seed 17, keyframes 140–170: −0.33
/// to −0.74, 2026-12-05) and best where it hid its label, while its regions preferred the
/// truth at every one of them (0.11–0.33 against 0.00–0.07). A model painted right explains
/// nearly what its regions do.
fn judge_model_colours(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    poses: &[GenPose],
    log: &mut Log<'_>,
) {
    use crate::appearance::{judge_fits, model_colour_fits, model_has_appearance};
    if !model_has_appearance(s.model) || poses.len() != frames.len() {
        return;
    }
    // Only where the video carries the basins: a chain followed at least one gap. Without
    // it, each keyframe's basin rests on the colours' absolute evidence, and a painting that
    // is no likeness still told the can's ends apart better than its regions do (hard suite
    // labelcan, keyframes only, seeds 17/18/19: 28°, 37°, 29° as painted, 57°, 55°, 60°
    // weighed as regions, 2026-12-05); with the video, the chains carry which end is which and
    // the painting's pull toward hiding its print is what lost the can (19–23° → 2.5–2.9°).
    if (0..frames.len().saturating_sub(1)).all(|g| s.gap(g).is_none()) {
        return;
    }
    let cfg = s.appearance_cfg();
    let fits: Vec<(f64, f64)> = frames
        .par_iter()
        .zip(poses.par_iter())
        .filter_map(|(f, g)| model_colour_fits(s.model, s.scale, &f.appearance()?, g, &cfg))
        .collect();
    s.evals
        .fetch_add(fits.len(), std::sync::atomic::Ordering::Relaxed);
    let Some((judged, painted, regions, shown)) = judge_fits(&fits) else {
        return;
    };
    if judged == ModelColours::AsRegions {
        log.push(format!(
            "the model's colours: no likeness of the frames' (over {shown} keyframe(s) showing its print, as painted they explain {painted:.2} of the colours shading leaves, their regions {regions:.2}); weighed from here by where their boundaries fall, not by their colours"
        ));
        if let Ok(mut m) = s.model_colours.write() {
            *m = judged;
        }
    }
}

fn after_propagation(
    s: &Searcher<'_>,
    (frames, between): (&[TrackFrame<'_>], &[Vec<TrackFrame<'_>>]),
    (poses, scores): (&mut [GenPose], &mut [f64]),
    fixed: &[bool],
    alternatives: &[Vec<(GenPose, f64)>],
    first: usize,
    log: &mut Log<'_>,
) -> Result<Option<ChoiceTrace>, TrackError> {
    let (cfg, n) = (&s.cfg, frames.len());
    if cfg.appearance {
        judge_model_colours(s, frames, poses, log);
    }
    // The basins the sequence choice weighed and did not take, per frame.
    let mut rejected: Vec<Vec<GenPose>> = Vec::new();
    let mut trace = None;
    if cfg.consistency_pass && n >= 2 {
        let before = poses.to_vec();
        consistency(s, frames, poses, scores, fixed, log)?;
        log.phase("consistency", s);
        log.all_poses(poses);
        log.pass_done("the consistency pass", poses);
        // The motions measured by chains from keyframes the pass moved to another basin.
        let (measured, kept) = remeasure_gaps(s, frames, between, &before, poses)?;
        if !(measured.is_empty() && kept.is_empty()) {
            let names = |gaps: &[usize]| -> String {
                gaps.iter()
                    .map(|&g| format!("{}–{}", frames[g].name, frames[g + 1].name))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let mut parts = Vec::new();
            if !measured.is_empty() {
                parts.push(format!("motion measured again across {}", names(&measured)));
            }
            if !kept.is_empty() {
                parts.push(format!(
                    "the motion measured before kept across {} (the video joins the poses from neither end)",
                    names(&kept)
                ));
            }
            log.push(format!(
                "video: the gaps beside keyframes the consistency pass moved to another basin (leaving out turns about a round body's axis) followed again from their new poses: {}",
                parts.join("; ")
            ));
            log.phase("video", s);
        }
    }
    if cfg.sequence_choice && n >= 2 {
        if cfg.appearance {
            appearance_pass(s, frames, (poses, scores), fixed, first, &[], log);
            log.phase("appearance", s);
            log.pass_done("the appearance pass before the sequence choice", poses);
        }
        let (r, t) = choose_sequence(
            s,
            (frames, between),
            (poses, scores),
            fixed,
            alternatives,
            log,
        )?;
        (rejected, trace) = (r, Some(t));
        log.phase("sequence choice", s);
        log.all_poses(poses);
        log.pass_done("the sequence-level choice", poses);
    }
    if cfg.appearance && n >= 2 {
        appearance_pass(s, frames, (poses, scores), fixed, first, &rejected, log);
        log.phase("appearance", s);
        log.pass_done("the appearance pass", poses);
        if axis_pass(s, (frames, between), (poses, scores), fixed, log)? {
            log.phase("axis", s);
            log.pass_done("the axis pass", poses);
        }
    }
    if cfg.sequence_choice && n >= 2 && between.iter().any(|g| !g.is_empty()) {
        // Its time counted whether or not a keyframe moved (else the polish's line has it).
        let moved = video_pass(s, (frames, between), (poses, scores), fixed, log)?;
        log.phase("video refinement", s);
        if moved {
            log.all_poses(poses);
            log.pass_done("the video refinement", poses);
        }
    }
    if cfg.last_polish {
        polish_pass(s, frames, (poses, scores), fixed, log)?;
        log.phase("polish", s);
        log.all_poses(poses);
        log.pass_done("the last polish", poses);
    }
    Ok(trace)
}

/// Runs `search` on the stand-in of a dense `model` ([`crate::standin`]), or on the model
/// itself when it needs none; with a stand-in, every frame but the `fixed` ones is then
/// polished on the model ([`LocalWindow::on_model`]), kept where the polish does not score
/// higher, and scored on the model.
#[allow(clippy::too_many_arguments)]
fn on_stand_in(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    cfg: &TrackConfig,
    fixed: &[usize],
    observe: &dyn TrackObserver,
    search: impl FnOnce(&ObjectModel) -> Result<TrackResult, TrackError>,
) -> Result<TrackResult, TrackError> {
    let Some(standin) = crate::standin::stand_in(model, frames.iter().map(|f| f.target.mask()))
    else {
        return search(model);
    };
    let mut log = Log::new(observe);
    log.push(standin.describe());
    let mut result = search(&standin.model)?;
    let t0 = std::time::Instant::now();
    let s = Searcher::new(model, scale, frames, cfg)?;
    let polished: Vec<(GenPose, f64)> = result
        .poses
        .par_iter()
        .enumerate()
        .map(|(i, g)| {
            let problem =
                FrameProblem::new(model, frames[i].camera, frames[i].target, scale, g.clone());
            let here = problem.evaluator().combined(g);
            if fixed.contains(&i) {
                return Ok((g.clone(), here));
            }
            let (p, sc) = s.refine(
                &frames[i],
                g,
                &LocalWindow::on_model(),
                cfg.seed + 15_485_863 * (i as u64 + 1),
            )?;
            Ok(if sc > here {
                (p, sc)
            } else {
                (g.clone(), here)
            })
        })
        .collect::<Result<_, TrackError>>()?;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let before = mean(&result.scores);
    (result.poses, result.scores) = polished.into_iter().unzip();
    let evals = s.evals.into_inner();
    log.push(format!(
        "polished on the model ({} triangles): IoU mean {before:.4} on the stand-in, {:.4} on the model, {:.1} s ({evals} evaluations)",
        standin.report.triangles_before,
        mean(&result.scores),
        t0.elapsed().as_secs_f64(),
    ));
    log.all_poses(&result.poses);
    let mut lines = std::mem::take(&mut log.lines);
    // The stand-in's line first, as it was written; the polish's last.
    let polish_line = lines.pop();
    lines.append(&mut result.log);
    lines.extend(polish_line);
    result.log = lines;
    result.evaluations += evals;
    Ok(result)
}
