//! The warm start: tracking from given poses (`track --from`), with anchors kept exactly.

use super::*;
use crate::hypotheses::PRUNE_SLACK;
use crate::objective::FrameProblem;
use crate::temporal::angle_deg;
use crate::update::GenPose;
use crate::TrackError;
use agentstar_geom::ObjectModel;

/// How much better than a frame's own refined pose a pose carried from the neighbour on the
/// anchor's side must score to be taken; within it the carried pose wins (continuity: a
/// twin that explains the mask as well as the carried pose does not break the chain).
pub(super) const CARRY_TIE: f64 = 0.002;

/// Tracks from existing poses (a warm start) instead of from scratch: every frame not in
/// `anchors` is refined around its own pose with the narrow polish; anchors stay exactly as
/// given and are carried outward to their neighbours, frame by frame (the neighbour on the
/// anchor's side through the cameras, and at constant velocity), each carried pose refined
/// and taken when it scores at least as well as the frame's own (within [`CARRY_TIE`]), with
/// the wide search when both fall clearly under the neighbour. The consistency pass then runs
/// with the anchors fixed. Cheap after a shape edit: one polish per frame when nothing moved.
pub fn track_from(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    start: &[GenPose],
    anchors: &[usize],
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<TrackResult, TrackError> {
    on_stand_in(model, scale, frames, cfg, anchors, observe, |searched| {
        track_from_on(searched, scale, frames, start, anchors, cfg, observe)
    })
}

pub(super) fn track_from_on(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    start: &[GenPose],
    anchors: &[usize],
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<TrackResult, TrackError> {
    let s = Searcher::new(model, scale, frames, cfg)?;
    let n = frames.len();
    if start.len() != n {
        return Err(TrackError::Invalid(format!(
            "{} starting poses for {n} frames",
            start.len()
        )));
    }
    let mut fixed = vec![false; n];
    for &a in anchors {
        if a >= n {
            return Err(TrackError::Invalid(format!(
                "anchor {a} is not a frame (there are {n})"
            )));
        }
        fixed[a] = true;
    }
    for (g, f) in start.iter().zip(frames) {
        if g.states.len() != model.tree.joints().len()
            || !g.pose.translation.iter().all(|v| v.is_finite())
        {
            return Err(TrackError::Invalid(format!(
                "frame {}: the starting pose is not a pose of this model ({} joint states for {} joints)",
                f.name,
                g.states.len(),
                model.tree.joints().len()
            )));
        }
    }
    let mut log = Log::new(observe);
    // Each frame's score at its starting pose, and its polished pose (anchors kept).
    let polished: Vec<Result<(f64, GenPose, f64), TrackError>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let p = FrameProblem::new(
                model,
                frames[i].camera,
                frames[i].target,
                scale,
                start[i].clone(),
            );
            let at_start = p.evaluator().combined(&start[i]);
            if fixed[i] {
                Ok((at_start, start[i].clone(), at_start))
            } else {
                let (g, sc) = s.polish(&frames[i], &start[i], cfg.seed + 7919 * i as u64)?;
                Ok((at_start, g, sc))
            }
        })
        .collect();
    let mut poses = Vec::with_capacity(n);
    let mut scores = Vec::with_capacity(n);
    let mut unmoved = 0;
    for (i, r) in polished.into_iter().enumerate() {
        let (at_start, g, sc) = r?;
        let turned = angle_deg(&(g.pose.rotation * start[i].pose.rotation.inverse()));
        let shifted_mm = 1000.0 * (g.pose.translation - start[i].pose.translation).norm();
        if fixed[i] {
            log.push(format!("{}: anchor, kept, IoU {sc:.4}", frames[i].name));
        } else if turned < 0.05 && shifted_mm < 0.05 {
            unmoved += 1;
        } else {
            log.push(format!(
                "{}: refined from its pose, IoU {at_start:.4} → {sc:.4}, turned {turned:.1}°, moved {shifted_mm:.1} mm",
                frames[i].name
            ));
        }
        poses.push(g);
        scores.push(sc);
    }
    if unmoved > 0 {
        log.push(format!(
            "{unmoved} frame(s) kept their starting pose: the polish found nothing better"
        ));
    }
    // Outward from every anchor, nearest frames first, each frame from its neighbour on the
    // side of its nearest anchor.
    let mut order: Vec<(usize, usize, isize)> = Vec::new();
    for i in (0..n).filter(|&i| !fixed[i]) {
        let left = (0..i).rev().find(|&a| fixed[a]).map(|a| (i - a, 1isize));
        let right = (i + 1..n).find(|&a| fixed[a]).map(|a| (a - i, -1isize));
        let nearest = match (left, right) {
            (Some(l), Some(r)) => Some(if r.0 < l.0 { r } else { l }),
            (l, r) => l.or(r),
        };
        if let Some((d, dir)) = nearest {
            // `dir` points from the anchor towards the frame; its neighbour is i − dir.
            order.push((d, i, dir));
        }
    }
    order.sort();
    for (_, i, dir) in order {
        let prev_i = (i as isize - dir) as usize;
        let carried = GenPose {
            pose: transfer(&poses[prev_i].pose, &frames[prev_i], &frames[i]),
            states: poses[prev_i].states.clone(),
        };
        let mut seeds = vec![carried.clone()];
        let prev2 = prev_i as isize - dir;
        if prev2 >= 0 && (prev2 as usize) < n {
            let p2 = prev2 as usize;
            let p2t = GenPose {
                pose: transfer(
                    &transfer(&poses[p2].pose, &frames[p2], &frames[prev_i]),
                    &frames[prev_i],
                    &frames[i],
                ),
                states: poses[p2].states.clone(),
            };
            seeds.push(extrapolate(&p2t, &carried, &model.tree));
        }
        let results: Vec<Result<(GenPose, f64), TrackError>> = seeds
            .par_iter()
            .enumerate()
            .map(|(k, g)| {
                s.polish(
                    &frames[i],
                    g,
                    cfg.seed + 104_729 * (i as u64 + 1) + k as u64,
                )
            })
            .collect();
        let mut found = best_of(results)?;
        let reached = found.as_ref().map_or(f64::NEG_INFINITY, |r| r.1);
        if reached.max(scores[i]) < scores[prev_i] - FAR_MARGIN {
            let seed = cfg.seed + 65537 * (i as u64 + 1);
            if let Some(w) = s
                .wide(
                    &frames[i],
                    &carried,
                    &carried,
                    (seed, seed),
                    reached.max(scores[i] - CARRY_TIE) - PRUNE_SLACK,
                )?
                .filter(|w| w.1 > reached)
            {
                found = Some(w);
            }
        }
        if let Some((g, sc)) = found.filter(|r| r.1 >= scores[i] - CARRY_TIE) {
            let moved = angle_deg(&(g.pose.rotation * poses[i].pose.rotation.inverse()));
            log.push(format!(
                "{}: carried from {} (anchor side), IoU {:.4} → {sc:.4}, {moved:.1}° from its refined pose",
                frames[i].name, frames[prev_i].name, scores[i]
            ));
            poses[i] = g;
            scores[i] = sc;
        }
    }
    log.phase("warm start", &s);
    log.all_poses(&poses);
    let first = anchors.first().copied().unwrap_or(0);
    after_propagation(
        &s,
        frames,
        (&mut poses, &mut scores),
        &fixed,
        &[],
        first,
        &mut log,
    )?;
    log.phases_line();
    let init_frame = anchors.first().copied().unwrap_or_else(|| {
        (0..n)
            .max_by(|&a, &b| scores[a].total_cmp(&scores[b]))
            .unwrap_or(0)
    });
    Ok(TrackResult {
        poses,
        scores,
        init_frame,
        log: log.lines,
        evaluations: s.evals.into_inner(),
        between: vec![],
    })
}
