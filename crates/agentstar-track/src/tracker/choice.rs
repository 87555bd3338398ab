//! The sequence-level choice: every frame's basins and twins weighed by dynamic programming
//! over frames, with temporal and appearance step costs.

use super::*;
use crate::appearance::{
    appearance_each, model_agreement, model_has_appearance, AppearanceFrame, ReferenceView,
};
use crate::axis::{body_axis, AngleGrid};
use crate::hypotheses::{refine_each_above, same_basin, twin_candidates, LocalWindow, PRUNE_SLACK};
use crate::objective::FrameProblem;
use crate::sequence::cheapest_path;
use crate::temporal::angle_deg;
use crate::update::GenPose;
use crate::TrackError;

/// The sequence-level choice's units: a hypothesis this much IoU under its frame's best
/// costs one unit; a step of this many degrees (rotation through the cameras, or any joint)
/// costs one unit, growing with its square, and so does this share of the depth in
/// translation. Alternatives placed within `CHOICE_SCREEN` of a frame's score are refined
/// (all of them under the gate); refined ones within `CHOICE_KEEP` of the frame's best are
/// kept as hypotheses.
///
/// The translation unit: a hand moves an object 6–7% of the depth between keyframes on the
/// hard suite (at most 13%), a fraction of a unit; at 0.2 (its value before 2026-12-03) a
/// plain bottle mostly under a hand was placed 18 cm deeper in one keyframe and 9 cm in the
/// next, those poses' IoU 0.011 and 0.005 over the truth's outweighing the jumps.
/// At 0.1 (and with the neighbours' poses carried in as hypotheses) both came back (0.36 and
/// 1.55 cm off), and no other sequence of the suite changed.
pub(super) const CHOICE_IOU_UNIT: f64 = 0.005;
pub(super) const CHOICE_STEP_DEG: f64 = 60.0;
pub(super) const CHOICE_STEP_DEPTH: f64 = 0.1;
pub(super) const CHOICE_SCREEN: f64 = 0.15;
pub(super) const CHOICE_KEEP: f64 = 0.03;
/// Rotation steps beyond this cost alike: a hand turns an object by 100–150° between
/// keyframes, and then the half-turn twin can be the nearer pose (printmug's first keyframe:
/// a true step of 143°, its twin's 116°, so the quadratic cost chose the twin); past this
/// the masks and colours decide. 120° put that keyframe back in its twin (hard suite,
/// 2026-12-02).
pub(super) const CHOICE_STEP_CAP_DEG: f64 = 90.0;
/// Across a gap a chain followed, a step's rotation is measured from the chain's motion: one
/// unit per 15° off it (a chain that kept its basin lands within a few degrees; a twin is 90°
/// or more away), capped at 120°, so that a twin costs up to 64 units, an IoU shortfall of
/// 0.32: only a frame whose mask clearly wants another basin leaves the chain's.
pub(super) const CHAIN_STEP_DEG: f64 = 15.0;
pub(super) const CHAIN_STEP_CAP_DEG: f64 = 120.0;
/// Frames scoring under this (the IoU gate) have every twin refined, in the wide window.
pub(super) const CHOICE_SUSPECT: f64 = agentstar_render::GATE_IOU;

/// A neighbour's pose carried into a frame is searched as a hypothesis of its own when the
/// frame's pose lies this share of the depth away from it, or turned past
/// [`CHOICE_STEP_CAP_DEG`]: a hand moves an object a few centimetres between keyframes at
/// half a metre (the hard suite's steps: 6–7% of the depth on average, 13% at most).
pub(super) const CHOICE_FAR_SHIFT: f64 = 0.1;

/// Whether `to` lies far from `from` (both in one frame's camera): see [`CHOICE_FAR_SHIFT`].
pub(super) fn far_step(from: &GenPose, to: &GenPose) -> bool {
    let depth = from.pose.translation.z.abs().max(1e-9);
    (to.pose.translation - from.pose.translation).norm() / depth > CHOICE_FAR_SHIFT
        || angle_deg(&(to.pose.rotation * from.pose.rotation.inverse())) > CHOICE_STEP_CAP_DEG
}

/// A frame of the video between keyframes counts toward a pair's [`video_fit`] at most this
/// IoU under the best pair's there: a frame the steady motion cannot explain (the hand
/// turned the object faster in the middle of the gap, a segmenter's miss) costs every pair
/// alike past it.
pub(super) const VIDEO_FIT_CAP: f64 = 0.05;
/// The in-between frames of one gap weigh this much against a keyframe's own IoU: they are
/// as real as a keyframe's mask, but the steady motion only approximates a hand's, and their
/// masks are searched at half the resolution.
pub(super) const VIDEO_FIT_WEIGHT: f64 = 0.5;
/// A pair of the chosen path whose [`video_fit`] lies within this of its gap's best pair is
/// what the video shows: its motion becomes the gap's ([`Gap`]).
pub(super) const VIDEO_JOINED: f64 = 5.0;

/// `cost[i][a][b]`: how far hypothesis `a` at keyframe `i − 1` and `b` at keyframe `i`,
/// joined by the steadiest motion ([`steady_between`]), miss the masks of the video between
/// them: over the gap's in-between frames, each pair's IoU short of the best pair's at that
/// frame (at most [`VIDEO_FIT_CAP`]), in units of [`CHOICE_IOU_UNIT`], times
/// [`VIDEO_FIT_WEIGHT`]. Empty where the gap has no in-between frames.
///
/// A chain's measured motion ([`Gap`]) joins whatever pair lies in the basins it carried;
/// where the outline hardly shows a turn (a prism's faces, a lever under a hand) a chain can
/// drift a face or two across a gap, and then it charges the right pair. The steady motion
/// tests both ends against every frame between them: a pair whose ends sit in different
/// twins turns the object through poses the masks between do not show. A pair whose ends
/// are the same twin of the truth scores as the truth does; colours tell those apart.
pub(super) fn video_fit(
    s: &Searcher<'_>,
    (frames, between): (&[TrackFrame<'_>], &[Vec<TrackFrame<'_>>]),
    hyps: &[Vec<(GenPose, f64)>],
) -> Vec<Vec<Vec<f64>>> {
    let n = frames.len().min(hyps.len());
    (0..n)
        .into_par_iter()
        .map(|i| {
            let Some(path) = i.checked_sub(1).and_then(|g| between.get(g)) else {
                return vec![];
            };
            if path.is_empty() {
                return vec![];
            }
            let (ha, hb) = (&hyps[i - 1], &hyps[i]);
            let Some((first, _)) = ha.first() else {
                return vec![];
            };
            let m = path.len();
            let mut cost = vec![vec![0.0; hb.len()]; ha.len()];
            let mut evaluated = 0usize;
            for (j, here) in path.iter().enumerate() {
                let t = (j + 1) as f64 / (m + 1) as f64;
                let problem =
                    FrameProblem::new(s.model, here.camera, here.target, s.scale, first.clone());
                let mut ev = problem.evaluator();
                let iou: Vec<Vec<f64>> = ha
                    .iter()
                    .map(|(a, _)| {
                        hb.iter()
                            .map(|(b, _)| {
                                let g = steady_between(
                                    s.model,
                                    s.scale,
                                    (&frames[i - 1], a),
                                    (&frames[i], b),
                                    here,
                                    t,
                                );
                                ev.combined(&g)
                            })
                            .collect()
                    })
                    .collect();
                evaluated += ha.len() * hb.len();
                let best = iou
                    .iter()
                    .flatten()
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max);
                for (row, r) in cost.iter_mut().zip(&iou) {
                    for (c, x) in row.iter_mut().zip(r) {
                        *c += (best - x).min(VIDEO_FIT_CAP) / CHOICE_IOU_UNIT * VIDEO_FIT_WEIGHT;
                    }
                }
            }
            s.evals
                .fetch_add(evaluated, std::sync::atomic::Ordering::Relaxed);
            cost
        })
        .collect()
}

/// One hypothesis per frame for the whole sequence: every frame's current pose and its twins
/// ([`twin_candidates`]: flips, principal half-turns) that place close enough to matter,
/// refined; then the cheapest path through them ([`cheapest_path`]: the frame's IoU shortfall
/// against the step through the cameras and joint states). Fixed frames keep their pose.
/// Across a gap with in-between frames (`between[g]`: the video between keyframes g and
/// g + 1) a step's turn is weighed by the steady motion through them ([`video_fit`]) instead
/// of a chain's measured motion, and the chosen pair's motion becomes the gap's where the
/// video explains it.
pub(super) fn choose_sequence(
    s: &Searcher<'_>,
    (frames, between): (&[TrackFrame<'_>], &[Vec<TrackFrame<'_>>]),
    (poses, scores): (&mut [GenPose], &mut [f64]),
    fixed: &[bool],
    alternatives: &[Vec<(GenPose, f64)>],
    log: &mut Log<'_>,
) -> Result<(Vec<Vec<GenPose>>, ChoiceTrace), TrackError> {
    let n = frames.len();
    // Each frame's hypotheses on their own (their seeds depend on the frame alone).
    let hyps: Vec<Vec<(GenPose, f64)>> = (0..n)
        .into_par_iter()
        .map(|i| -> Result<Vec<(GenPose, f64)>, TrackError> {
            let mut h = vec![(poses[i].clone(), scores[i])];
            if !fixed[i] {
                let problem = FrameProblem::new(
                    s.model,
                    frames[i].camera,
                    frames[i].target,
                    s.scale,
                    poses[i].clone(),
                );
                let mut ev = problem.evaluator();
                // A frame under the gate may sit in a wrong basin: all its twins, refined in the
                // wide window (a twin of a pose refined in the wrong basin lands off the mask).
                let suspect = scores[i] < CHOICE_SUSPECT;
                let close: Vec<GenPose> = twin_candidates(s.model, s.scale, &poses[i])
                    .into_iter()
                    .filter(|g| suspect || ev.combined(g) >= scores[i] - CHOICE_SCREEN)
                    .collect();
                let window = if suspect {
                    LocalWindow::basin()
                } else {
                    LocalWindow::polish()
                };
                // The frame's own pose is refined in the same window as its twins, so that
                // a twin is never preferred for a fresh refinement its rival did not get (a
                // laptop's keyframe 9° off its optimum, IoU 0.913, against its lid-base twin
                // refined to 0.952, turned the whole sequence into the twin: hard suite
                // twinlaptop, seed 18, 2026-12-04).
                let own = refine_each_above(
                    &problem,
                    std::slice::from_ref(&poses[i]),
                    &window,
                    s.cfg.seed + 2_500_009 * (i as u64 + 1),
                    f64::NEG_INFINITY,
                )?;
                for r in own {
                    s.evals
                        .fetch_add(r.evals, std::sync::atomic::Ordering::Relaxed);
                    if r.score.combined > h[0].1 {
                        h[0] = (r.pose, r.score.combined);
                    }
                }
                // Twins that end under the frame's score by more than CHOICE_KEEP are dropped
                // below: their refinement stops after the first pass.
                let refined = refine_each_above(
                    &problem,
                    &close,
                    &window,
                    s.cfg.seed + 3_000_017 * (i as u64 + 1),
                    scores[i] - CHOICE_KEEP - PRUNE_SLACK,
                )?;
                // A frame placed far from a neighbour (a jump in depth, a turn past the cap)
                // may have been chained from a wrong pose, or its silhouette, mostly under a
                // hand, fits a wrong pose slightly better: the neighbour's pose carried here,
                // refined, is a hypothesis the step cost can prefer.
                let from_neighbours: Vec<GenPose> =
                    [i.checked_sub(1), (i + 1 < n).then_some(i + 1)]
                        .into_iter()
                        .flatten()
                        .map(|j| s.carried(frames, poses, j, i))
                        .filter(|c| far_step(c, &poses[i]))
                        .collect();
                let carried = refine_each_above(
                    &problem,
                    &from_neighbours,
                    &LocalWindow::carried(),
                    s.cfg.seed + 3_500_017 * (i as u64 + 1),
                    scores[i] - CHOICE_KEEP - PRUNE_SLACK,
                )?;
                s.evals.fetch_add(
                    refined.iter().chain(&carried).map(|r| r.evals).sum(),
                    std::sync::atomic::Ordering::Relaxed,
                );
                // The refined twins, the neighbours' poses carried here, then the basins a global
                // search found at this frame during the propagation (its colours may have turned
                // one down that the sequence needs), each unless one already kept is the same
                // ([`same_basin`]: a neighbour's pose carried in to correct a frame's depth may
                // keep its rotation).
                let found = refined
                    .into_iter()
                    .chain(carried)
                    .map(|r| (r.pose, r.score.combined))
                    .chain(alternatives.get(i).into_iter().flatten().cloned());
                for (g, sc) in found {
                    if !h.iter().any(|(b, _)| same_basin(b, &g)) {
                        h.push((g, sc));
                    }
                }
                let best = h.iter().map(|x| x.1).fold(f64::NEG_INFINITY, f64::max);
                // The frame's own pose (first) may be dropped here: then every hypothesis kept is
                // another basin.
                h.retain(|x| x.1 >= best - CHOICE_KEEP);
                if h.is_empty() {
                    h.push((poses[i].clone(), scores[i]));
                }
            }
            Ok(h)
        })
        .collect::<Result<_, _>>()?;
    // A round body with a print (a labelled can, a printed mug): every hypothesis turned about
    // the body's axis to where the frame agrees best with the model's print, so that a twin is
    // weighed at its best angle, and a frame's own pose too (a pass before the choice may have
    // spun it off its print: hard suite labelcan, seed 17, 2026-12-04, three keyframes spun
    // 50° whose half-turn twins then agreed better and were taken). Not a frame a chain
    // reached or left: the chain carried its angle from its neighbour's, consistent with it,
    // where one frame's print alone is noisy (with the video, turning those frames took the
    // hard labelcan from 2.4° and 2.8° mean to 3.6° and 8.0° on seeds 17 and 18, 2026-12-05).
    let hyps: Vec<Vec<(GenPose, f64)>> = if s.cfg.appearance && model_has_appearance(s.model) {
        hyps.into_par_iter()
            .enumerate()
            .map(|(i, h)| match frames[i].appearance() {
                Some(app)
                    if !fixed[i]
                        && i.checked_sub(1).and_then(|g| s.gap(g)).is_none()
                        && s.gap(i).is_none() =>
                {
                    h.into_iter()
                        .map(|(g, sc)| turned_to_print(s, &frames[i], &app, g, sc))
                        .collect()
                }
                _ => h,
            })
            .collect()
    } else {
        hyps
    };
    let alternatives: usize = hyps
        .iter()
        .zip(poses.iter())
        .map(|(h, own)| h.iter().filter(|(g, _)| !same_basin(g, own)).count())
        .sum();
    let trace = |path: Vec<usize>| ChoiceTrace {
        hypotheses: hyps
            .iter()
            .map(|h| h.iter().map(|(g, _)| g.clone()).collect())
            .collect(),
        path,
    };
    if alternatives == 0 {
        log.push("sequence choice: no twin explains any frame as well; poses kept".into());
        return Ok((vec![Vec::new(); n], trace(vec![0; n])));
    }
    // The model's own colours (a label part, a badge), where it has them: each hypothesis
    // against its frame, no other frame needed; `(1 − NCC) / CHOICE_NCC_UNIT` as for a
    // pair of frames, a hypothesis without evidence counting as uncorrelated.
    let model_cost: Vec<Vec<f64>> = if s.cfg.appearance && model_has_appearance(s.model) {
        let cfg = s.appearance_cfg();
        hyps.par_iter()
            .zip(frames.par_iter())
            .map(|(h, f)| match f.appearance() {
                Some(app) => h
                    .iter()
                    .map(|(g, _)| {
                        let ncc = model_agreement(s.model, s.scale, &app, g, &cfg).ncc;
                        (1.0 - ncc.unwrap_or(0.0)) / CHOICE_NCC_UNIT
                    })
                    .collect(),
                None => vec![0.0; h.len()],
            })
            .collect()
    } else {
        hyps.iter().map(|h| vec![0.0; h.len()]).collect()
    };
    let unary: Vec<Vec<f64>> = hyps
        .iter()
        .zip(&model_cost)
        .map(|(h, colour)| {
            let best = h.iter().map(|x| x.1).fold(f64::NEG_INFINITY, f64::max);
            h.iter()
                .zip(colour)
                .map(|(x, c)| (best - x.1) / CHOICE_IOU_UNIT + c)
                .collect()
        })
        .collect();
    // Photometric consistency of every pair of hypotheses of neighbouring frames (in both
    // directions): a pair that puts the frames' colours on the same surface points costs
    // little, one that does not (a half-turn twin of a labelled can) costs up to
    // 1 / CHOICE_NCC_UNIT. Without colour evidence at a step (no images, an untextured
    // object) the step costs only motion.
    let appearance: Vec<Vec<Vec<f64>>> = if s.cfg.appearance {
        pair_appearance(s, frames, &hyps)
    } else {
        vec![]
    };
    // How far each pair across a gap with video misses the in-between frames' masks when
    // joined by the steadiest motion.
    // Not for a round outline: a chain's measured motion already leaves out the turn about
    // its axis, the one turn its masks cannot see and a chain could drift in; the steady
    // motion would weigh that turn through the path it bends, from keyframe turns the print
    // set only to a few degrees (hard suite labelcan with it, 2026-12-06: seed 18 2.5° →
    // 58.5° mean, seed 19 2.8° → 34.6°, a block of keyframes in the wrong basin).
    let video = if s.round_outline_axis().is_some() {
        vec![]
    } else {
        video_fit(s, (frames, between), &hyps)
    };
    // A pair's cost at step i from a per-step table, 0 where the step has none.
    let pair = |table: &[Vec<Vec<f64>>], i: usize, a: usize, b: usize| {
        table
            .get(i)
            .and_then(|m| m.get(a))
            .and_then(|r| r.get(b))
            .copied()
            .unwrap_or(0.0)
    };
    let step = |i: usize, a: usize, b: usize| {
        let steady = pair(&video, i, a, b);
        let colour = pair(&appearance, i, a, b);
        let from = &hyps[i - 1][a].0;
        let to = &hyps[i][b].0;
        let mut carried = transfer(&from.pose, &frames[i - 1], &frames[i]);
        // Across a gap whose video a chain followed, the motion it measured predicts the
        // step to a few degrees, for whichever basin the step starts in.
        let (unit_deg, cap_deg) = match s.gap(i - 1) {
            Some(gap) => {
                carried.rotation = gap.rotation * carried.rotation;
                (CHAIN_STEP_DEG, CHAIN_STEP_CAP_DEG)
            }
            None => (CHOICE_STEP_DEG, CHOICE_STEP_CAP_DEG),
        };
        let off_deg = if s.gap(i - 1).is_some() {
            s.off_chain(&carried.rotation, &to.pose.rotation)
                .to_degrees()
        } else {
            angle_deg(&(to.pose.rotation * carried.rotation.inverse()))
        };
        // Where the video between the two keyframes weighs the pair ([`video_fit`]), it
        // stands in for the motion a chain measured: a chain can drift where the outline
        // hardly shows a turn, the steady motion tests both ends against every frame.
        let rot = if video.get(i).is_some_and(|m| !m.is_empty()) {
            0.0
        } else {
            off_deg.min(cap_deg) / unit_deg
        };
        let joint = from
            .states
            .iter()
            .zip(&to.states)
            .map(|(x, y)| (x - y).abs().to_degrees())
            .fold(0.0, f64::max)
            / CHOICE_STEP_DEG;
        let depth = carried.translation.z.abs().max(1e-9);
        let shift = (to.pose.translation - carried.translation).norm() / depth / CHOICE_STEP_DEPTH;
        rot * rot + joint * joint + shift * shift + colour + steady
    };
    let path = cheapest_path(&unary, &step);
    if path.len() != n {
        return Err(TrackError::Invalid("sequence choice: no path".into()));
    }
    let weighed = trace(path.clone());
    let rejected: Vec<Vec<GenPose>> = hyps
        .iter()
        .zip(&path)
        .map(|(h, &k)| {
            h.iter()
                .enumerate()
                .filter(|&(j, _)| j != k)
                .map(|(_, (g, _))| g.clone())
                .collect()
        })
        .collect();
    let mut changed = Vec::new();
    // Hypotheses within a basin's width of the frame's pose (turned under REJECTED_BASIN_DEG,
    // moved under CHOICE_FAR_SHIFT of the depth) are adjustments, not another basin: counted apart, so
    // that the log names only the frames that moved to another basin (play-test 12 read
    // "changed basin" for all 12 keyframes).
    let mut adjusted = 0;
    for (i, &k) in path.iter().enumerate() {
        if hyps[i][k].0 != poses[i] {
            let (to, from) = (&hyps[i][k].0.pose, &poses[i].pose);
            let depth = from.translation.z.abs().max(1e-9);
            let other_basin = to.rotation.angle_to(&from.rotation)
                >= REJECTED_BASIN_DEG.to_radians()
                || (to.translation - from.translation).norm() / depth > CHOICE_FAR_SHIFT;
            // Then polish: the twin was refined in a window centred where it was placed.
            let (g, sc) = hyps[i][k].clone();
            let seed = s.cfg.seed + 5_000_011 * (i as u64 + 1);
            let (g, sc) = match s.polish(&frames[i], &g, seed)? {
                (p, psc) if psc > sc => (p, psc),
                _ => (g, sc),
            };
            if other_basin {
                changed.push(format!(
                    "{} (IoU {:.4} → {sc:.4}{})",
                    frames[i].name,
                    scores[i],
                    own_cost_line(&hyps[i], &poses[i], &unary[i], &path, i, k, &step)
                ));
            } else {
                adjusted += 1;
            }
            poses[i] = g;
            scores[i] = sc;
        }
    }
    // Each gap whose pair on the path the video between explains (within [`VIDEO_JOINED`] of
    // its best pair): the motion between the two chosen poses is the gap's from here, so that
    // the passes after the choice ([`leaves_the_chain`]) keep to the video's motion rather
    // than a chain's that drifted.
    let (mut video_steps, mut joined) = (0, 0);
    for i in 1..n {
        let Some(m) = video.get(i).filter(|m| !m.is_empty()) else {
            continue;
        };
        video_steps += 1;
        let best = m.iter().flatten().copied().fold(f64::INFINITY, f64::min);
        if m[path[i - 1]][path[i]] <= best + VIDEO_JOINED {
            s.set_gap(i - 1, Gap::between(frames, i - 1, &poses[i - 1], &poses[i]));
            joined += 1;
        }
    }
    let colour_steps = appearance.iter().filter(|m| !m.is_empty()).count();
    log.push(format!(
        "sequence choice: {alternatives} twin hypotheses kept over {n} frames, {}{}; {}{}",
        if colour_steps > 0 {
            format!("appearance compared at {colour_steps} of {} steps", n - 1)
        } else {
            "no appearance evidence (masks alone)".to_string()
        },
        if video_steps > 0 {
            format!(
                ", the steady motion through the video between keyframes at {video_steps} (its motion kept across {joined})"
            )
        } else {
            String::new()
        },
        if changed.is_empty() {
            "every frame keeps its basin".to_string()
        } else {
            format!("changed basin: {}", changed.join(", "))
        },
        if adjusted == 0 {
            String::new()
        } else {
            format!("; {adjusted} frame(s) moved within their basin (under {REJECTED_BASIN_DEG}° and {:.0}% of the depth)", 100.0 * CHOICE_FAR_SHIFT)
        }
    ));
    Ok((rejected, weighed))
}

/// One unit of the sequence choice's cost per this much photometric correlation (NCC)
/// missing between a pair of hypotheses of neighbouring frames: a half-turn twin of a
/// labelled can (NCC near 0 against the right pose's 0.6–0.9) costs several units, more than
/// the IoU noise of a segmenter's boundary (0.01 = 2 units), less than a clear silhouette
/// difference (0.03 = 6 units).
pub(super) const CHOICE_NCC_UNIT: f64 = 0.1;

/// `cost[i][a][b]`: the appearance cost of hypothesis `a` at frame `i − 1` followed by `b` at
/// frame `i` (`cost[0]` empty; a step without colour evidence is empty too). Each direction
/// renders one frame's hypothesis and carries its colours into the other frame's hypothesis
/// views; the cost is `(1 − mean NCC) / CHOICE_NCC_UNIT`, a pair without evidence at a step
/// that has some counting as uncorrelated.
pub(super) fn pair_appearance(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    hyps: &[Vec<(GenPose, f64)>],
) -> Vec<Vec<Vec<f64>>> {
    let cfg = s.appearance_cfg();
    let n = frames.len();
    (0..n)
        .into_par_iter()
        .map(|i| {
            if i == 0 {
                return vec![];
            }
            let (Some(fa), Some(fb)) = (frames[i - 1].appearance(), frames[i].appearance()) else {
                return vec![];
            };
            let (Some(va), Some(vb)) = (
                hypothesis_views(s, fa, &hyps[i - 1]),
                hypothesis_views(s, fb, &hyps[i]),
            ) else {
                return vec![];
            };
            // forward[b][a]: hypothesis b of frame i against frame i − 1 at a; backward[a][b].
            let forward: Vec<Vec<Option<f64>>> = hyps[i]
                .iter()
                .map(|(g, _)| {
                    appearance_each(s.model, s.scale, &fb, g, &va, &cfg)
                        .iter()
                        .map(|x| x.ncc)
                        .collect()
                })
                .collect();
            let backward: Vec<Vec<Option<f64>>> = hyps[i - 1]
                .iter()
                .map(|(g, _)| {
                    appearance_each(s.model, s.scale, &fa, g, &vb, &cfg)
                        .iter()
                        .map(|x| x.ncc)
                        .collect()
                })
                .collect();
            let evidence = forward
                .iter()
                .flatten()
                .chain(backward.iter().flatten())
                .any(Option::is_some);
            if !evidence {
                return vec![];
            }
            (0..hyps[i - 1].len())
                .map(|a| {
                    (0..hyps[i].len())
                        .map(|b| {
                            let both: Vec<f64> = [forward[b][a], backward[a][b]]
                                .into_iter()
                                .flatten()
                                .collect();
                            let ncc = if both.is_empty() {
                                0.0
                            } else {
                                both.iter().sum::<f64>() / both.len() as f64
                            };
                            (1.0 - ncc) / CHOICE_NCC_UNIT
                        })
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// One frame rendered at each of its hypotheses, as references for the appearance term.
pub(super) fn hypothesis_views<'a>(
    s: &Searcher<'_>,
    frame: AppearanceFrame<'a>,
    hyps: &[(GenPose, f64)],
) -> Option<Vec<ReferenceView<'a>>> {
    hyps.iter()
        .map(|(g, _)| ReferenceView::new(s.model, s.scale, frame, g))
        .collect()
}

/// `g` (placed at IoU `score`) turned about the model's round body's axis
/// ([`body_axis`], at its joint states) to
/// the angle where the frame's colours agree best with the model's own ([`model_agreement`]):
/// every [`AXIS_COARSE_DEG`] round the circle, then every [`AXIS_FINE_DEG`] around the best,
/// among the turns that keep the IoU within [`APPEARANCE_TIE`] of `score` (a can: every turn;
/// a mug: those that keep its handle where the mask has it, or hidden). `g` itself when the
/// model has no round body, or no turn agrees better.
fn turned_to_print(
    s: &Searcher<'_>,
    frame: &TrackFrame<'_>,
    app: &AppearanceFrame<'_>,
    g: GenPose,
    score: f64,
) -> (GenPose, f64) {
    // The body's axis at the hypothesis's joint states (at rest: the searcher's, found once).
    let axis = if g.states == s.model.tree.rest_states() {
        s.round_body().copied()
    } else {
        body_axis(s.model, &g.states)
    };
    let Some(axis) = axis else {
        return (g, score);
    };
    let cfg = s.appearance_cfg();
    let agreement = |p: &GenPose| model_agreement(s.model, s.scale, app, p, &cfg).ncc;
    let problem = s.problem_of(frame, &g);
    let mut ev = problem.evaluator();
    let mut best = (agreement(&g), g.clone(), score);
    let mut evaluated = 0;
    for grid in [
        AngleGrid::circle(AXIS_COARSE_DEG),
        AngleGrid::around(AXIS_FINE_DEG, AXIS_COARSE_DEG),
    ] {
        let centre = best.1.clone();
        for &deg in grid.angles_deg.iter().filter(|&&d| d != 0.0) {
            let turned = axis.turn(&centre, s.scale, deg);
            let iou = ev.combined(&turned);
            evaluated += 1;
            if iou < score - APPEARANCE_TIE {
                continue;
            }
            let ncc = agreement(&turned);
            if ncc.unwrap_or(f64::NEG_INFINITY) > best.0.unwrap_or(f64::NEG_INFINITY) {
                best = (ncc, turned, iou);
            }
        }
    }
    s.evals
        .fetch_add(evaluated, std::sync::atomic::Ordering::Relaxed);
    (best.1, best.2)
}

/// What the choice weighed at frame `i`, where it took hypothesis `k` over the hypothesis of
/// the frame's own basin (when one was kept): the unary cost (IoU shortfall and the model's
/// colours) and the cost of the steps to the neighbours on the path, for each; so that a log
/// says why a frame moved.
pub(super) fn own_cost_line(
    hyps: &[(GenPose, f64)],
    own: &GenPose,
    unary: &[f64],
    path: &[usize],
    i: usize,
    k: usize,
    step: &dyn Fn(usize, usize, usize) -> f64,
) -> String {
    let Some(o) = hyps.iter().position(|(g, _)| same_basin(g, own)) else {
        return String::new();
    };
    let steps = |at: usize| {
        let before = i.checked_sub(1).map_or(0.0, |p| step(i, path[p], at));
        let after = path.get(i + 1).map_or(0.0, |&next| step(i + 1, at, next));
        before + after
    };
    format!(
        "; cost {:.1} + steps {:.1} against its own basin's {:.1} + {:.1}",
        unary[k],
        steps(k),
        unary[o],
        steps(o)
    )
}
