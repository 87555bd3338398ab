//! The video refinement: every keyframe's pose refined on its own mask together with the
//! in-between frames of the gaps beside it, each placed on the steady motion
//! ([`steady_between`]) that joins the keyframe's candidate pose to its neighbour's.
//!
//! Why (2026-12-06): where a keyframe's mask ties (an octagonal prism seen near a face, a
//! round body whose lever shows edge-on), the tracker's searches end anywhere along the
//! tie, 5–25° from the truth, and the truth is among none of the sequence choice's
//! hypotheses (the general suite's "absent" misses). The in-between frames beside the
//! keyframe see the object from the directions the motion turns it through, which break the
//! tie; the steady motion ties them to the keyframe's pose.
//!
//! The score of a candidate: half its own mask's, half the mean over the in-between frames
//! of both gaps, each weighed by the share of the way the keyframe's pose carries it (1 at
//! the keyframe, 0 at the neighbour: where the steady motion is furthest from a hand's,
//! mid-gap, the keyframe counts half). In-between frames are taken as evenly spaced in time,
//! as [`video_fit`] takes them.

use super::*;
use crate::hypotheses::{cma_pass_by, rebased, CmaBudget};
use agentstar_geom::Point3;

/// The box the video refinement searches around a keyframe's pose: 20° (the "absent"
/// misses lie 5–25° off), 4% shift, 6% depth, 20° of joint. Its `evals` is unused: the
/// budget is [`VIDEO_CMA`]'s.
const VIDEO_WINDOW: LocalWindow = LocalWindow {
    angle_deg: 20.0,
    shift: 0.04,
    depth: 0.06,
    joint_deg: 20.0,
    evals: 0,
};

/// The CMA-ES climb of the video refinement: its first step a quarter of the box (5°), and
/// its evaluations per searched dimension.
const VIDEO_CMA: CmaBudget = CmaBudget {
    step: 0.25,
    per_dof: 100,
};

/// Sweeps over the keyframes (each refines the even keyframes, then the odd ones, each
/// against its neighbours' latest poses) until none turns more than [`VIDEO_SETTLED_DEG`] in
/// a sweep, at most this many (each a CMA-ES run per keyframe of [`VIDEO_CMA`]'s budget): a
/// keyframe's pose moves its neighbours' paths, so a turn
/// set right at one keyframe lets its neighbours follow in the next sweep.
const VIDEO_ROUNDS: usize = 2;

/// A sweep in which no keyframe turns more than this (degrees) ends the video refinement.
const VIDEO_SETTLED_DEG: f64 = 1.0;

/// Seeds of the video refinement: keyframe `i`'s in round `r` is the tracker's seed plus
/// this times `(r + 1) · (i + 1)`.
const VIDEO_SEED_STRIDE: u64 = 5_000_011;

/// How much of its own mask's score (IoU) a keyframe may give up for the video beside it.
const VIDEO_OWN_TIE: f64 = 0.005;

/// One in-between frame joined to a keyframe: the frame, its target at half resolution,
/// the share of the gap from the earlier keyframe, and the neighbour's keyframe and pose.
struct Joined<'f, 'a> {
    here: &'f TrackFrame<'a>,
    problem: FrameProblem<'a>,
    t: f64,
    /// The keyframe's weight on this frame: how far along the steady motion the keyframe's
    /// pose carries it (1 at the keyframe, 0 at the neighbour).
    weight: f64,
    /// The neighbour's keyframe, pose and the model's pivot at its joint states.
    neighbour: (&'f TrackFrame<'a>, GenPose, Point3),
    /// Whether the neighbour comes first (the gap before the keyframe).
    neighbour_first: bool,
}

/// Every keyframe but the `fixed` ones refined on its own mask and the in-between frames
/// beside it (see the module's note); a keyframe's pose moves only where the joint score
/// rises and its own mask's score falls by at most [`VIDEO_OWN_TIE`]. Returns whether any
/// keyframe moved.
pub(super) fn video_pass(
    s: &Searcher<'_>,
    (frames, between): (&[TrackFrame<'_>], &[Vec<TrackFrame<'_>>]),
    (poses, scores): (&mut [GenPose], &mut [f64]),
    fixed: &[bool],
    log: &mut Log<'_>,
) -> Result<bool, TrackError> {
    let n = frames.len();
    if n < 2 || between.iter().all(|g| g.is_empty()) {
        return Ok(false);
    }
    let halved: Vec<Vec<ScoreTarget>> = between
        .iter()
        .map(|g| g.iter().map(|f| f.target.halved()).collect())
        .collect();
    // A round outline's turn about its axis is held, as every refinement holds it, unless
    // a part a joint moves shows it (a lever, a handle: at some keyframe's joint states).
    let turn_shown = s.round_outline_axis().is_some_and(|axis| {
        poses.iter().any(|g| {
            crate::axis::reach_spread_all(s.model, &g.states, &axis) > crate::axis::OUTLINE_SPREAD
        })
    });
    let start: Vec<GenPose> = poses.to_vec();
    let mut sweeps = 0;
    for round in 0..VIDEO_ROUNDS {
        sweeps += 1;
        let before_sweep: Vec<GenPose> = poses.to_vec();
        for parity in 0..2 {
            let current: Vec<GenPose> = poses.to_vec();
            let refined: Vec<Option<(GenPose, f64)>> = (0..n)
                .into_par_iter()
                .map(|i| {
                    if i % 2 != parity || fixed.get(i).copied().unwrap_or(false) {
                        return Ok(None);
                    }
                    let seed = s.cfg.seed + VIDEO_SEED_STRIDE * (round as u64 + 1) * (i as u64 + 1);
                    refine_on_video(s, (frames, between, &halved), &current, i, turn_shown, seed)
                })
                .collect::<Result<_, TrackError>>()?;
            for (i, r) in refined.into_iter().enumerate() {
                if let Some((p, own)) = r {
                    poses[i] = p;
                    scores[i] = own;
                }
            }
        }
        if largest_turn_deg(&before_sweep, poses) < VIDEO_SETTLED_DEG {
            break;
        }
    }
    let count = start
        .iter()
        .zip(poses.iter())
        .filter(|(a, b)| a != b)
        .count();
    let most = largest_turn_deg(&start, poses);
    let turn = if turn_shown {
        ", the turn about the round outline's axis free (a jointed part shows it)"
    } else {
        ""
    };
    log.push(format!(
        "video refinement{turn}: {count} of {n} keyframe(s) moved on their own masks and the in-between frames beside them, at most {most:.1}° ({sweeps} sweep(s))"
    ));
    Ok(count > 0)
}

/// The largest turn between two sets of poses of the same frames, in degrees.
fn largest_turn_deg(before: &[GenPose], after: &[GenPose]) -> f64 {
    before
        .iter()
        .zip(after)
        .map(|(a, b)| a.pose.rotation.angle_to(&b.pose.rotation).to_degrees())
        .fold(0.0, f64::max)
}

/// Keyframe `i` refined on its mask and the in-between frames of the gaps beside it, the
/// other keyframes at `poses`: the new pose and its own mask's score, or nothing where it
/// does not move (no video beside it, no gain, or its own mask gives up too much).
fn refine_on_video(
    s: &Searcher<'_>,
    (frames, between, halved): (
        &[TrackFrame<'_>],
        &[Vec<TrackFrame<'_>>],
        &[Vec<ScoreTarget>],
    ),
    poses: &[GenPose],
    i: usize,
    turn_shown: bool,
    seed: u64,
) -> Result<Option<(GenPose, f64)>, TrackError> {
    let mut joined: Vec<Joined<'_, '_>> = Vec::new();
    let mut join = |g: usize, neighbour: usize, neighbour_first: bool| {
        let (Some(path), Some(targets)) = (between.get(g), halved.get(g)) else {
            return;
        };
        let m = path.len();
        for (j, (here, target)) in path.iter().zip(targets).enumerate() {
            let t = (j + 1) as f64 / (m + 1) as f64;
            let problem = FrameProblem::new(
                s.model,
                here.camera.halved(),
                target,
                s.scale,
                poses[i].clone(),
            );
            joined.push(Joined {
                here,
                problem,
                t,
                weight: if neighbour_first { t } else { 1.0 - t },
                neighbour: (
                    &frames[neighbour],
                    poses[neighbour].clone(),
                    s.model.pivot(&poses[neighbour].states),
                ),
                neighbour_first,
            });
        }
    };
    if i > 0 {
        join(i - 1, i - 1, true);
    }
    if i + 1 < frames.len() {
        join(i, i + 1, false);
    }
    if joined.is_empty() {
        return Ok(None);
    }
    let frame = &frames[i];
    let mut problem = s.problem_of(frame, &poses[i]);
    if turn_shown {
        problem = problem.with_held_axis(None);
    }
    let mut own = problem.evaluator();
    let mut evaluators: Vec<_> = joined.iter().map(|j| j.problem.evaluator()).collect();
    let video_weight = joined.iter().map(|j| j.weight).sum::<f64>();
    let own_last = std::cell::Cell::new(0.0);
    // A rigid model's pivot, or the keyframe's at its states (a search mostly keeps them).
    let pivot_held = Some((poses[i].states.clone(), s.model.pivot(&poses[i].states)));
    let mut score = |g: &GenPose, soft: bool| -> f64 {
        let mine = if soft {
            own.soft_combined(g)
        } else {
            own.combined(g)
        };
        own_last.set(mine);
        let mut sum = 0.0;
        // The candidate's pivot, once for every frame (a walk over the model's vertices).
        let pivot = match &pivot_held {
            Some((states, p)) if *states == g.states => *p,
            _ => s.model.pivot(&g.states),
        };
        for (jn, ev) in joined.iter().zip(evaluators.iter_mut()) {
            let (nf, np, npivot) = (jn.neighbour.0, &jn.neighbour.1, jn.neighbour.2);
            let (neighbour, keyframe) = ((nf, np, npivot), (frame, g, pivot));
            let (earlier, later) = if jn.neighbour_first {
                (neighbour, keyframe)
            } else {
                (keyframe, neighbour)
            };
            let path = steady_between_pivots(s.model, s.scale, earlier, later, jn.here, jn.t);
            let x = if soft {
                ev.soft_combined(&path)
            } else {
                ev.combined(&path)
            };
            sum += jn.weight * x;
        }
        (mine + sum / video_weight) / 2.0
    };
    let before = score(&poses[i], false);
    let own_before = own_last.get();
    let (p, space) = rebased(&problem, &poses[i], &VIDEO_WINDOW, 1.0);
    let (pose, after, n) = cma_pass_by(&p, &space, seed, VIDEO_CMA, &mut score)?;
    let own_after = own_last.get();
    s.evals.fetch_add(
        (n + 1) * (1 + joined.len()),
        std::sync::atomic::Ordering::Relaxed,
    );
    if after > before && own_after >= own_before - VIDEO_OWN_TIE {
        Ok(Some((pose, own_after)))
    } else {
        Ok(None)
    }
}
