//! The axis pass: the angle about a round body's axis chosen for the whole sequence at once
//! ([`crate::axis`]), after the last appearance pass.

use super::*;
use crate::appearance::{model_has_appearance, AppearanceFrame};
use crate::axis::{body_axis, choose_turns, AngleGrid, Steps};
use crate::temporal::signed_deg;
use crate::update::GenPose;
use crate::TrackError;

/// The grid steps of [`axis_pass`]: round the circle, then around the coarse choice.
pub(super) const AXIS_COARSE_DEG: f64 = 10.0;
pub(super) const AXIS_FINE_DEG: f64 = 2.0;

/// Where the model has a round body ([`body_axis`]: a can, a bottle, a mug's body) and colours
/// of its own ([`model_has_appearance`]: a label part, a badge), the angle about the body's
/// axis chosen for all frames together by their colours ([`choose_turns`]): every
/// [`AXIS_COARSE_DEG`] round the circle, then every [`AXIS_FINE_DEG`] around that. Each frame
/// takes only the turns that keep its IoU within [`APPEARANCE_TIE`] (a can: every turn; a
/// mug: those that keep its handle where the mask has it, or hidden); at a keyframe of a body
/// whose outline is round, a turn that loses it has its joints fitted again first
/// ([`refit_states`]: a lever on a frustum turned 30° shows as the lever at another angle). `fixed` frames keep their pose. Whether
/// the pass ran (the model has such an axis and some frame could turn). Frames at different
/// joint states (a can's lever moving) all turn about the body's axis at rest.
///
/// Where the body's outline is round ([`Searcher::round_outline_axis`]), the model's colours
/// count as painted ([`super::judge_model_colours`]) and the in-between frames have colours,
/// the choice is over every video frame ([`Steps::Video`]): each gap's
/// frames at the poses a chain from the keyframe before carries them to ([`follow`]), each
/// compared with its neighbours a few degrees away and with the model's own colours, the
/// chain's motion kept up to a steady correction. A keyframe whose print is hidden then takes
/// its angle from the frames after it that show the print. Only the keyframes' turns are kept.
pub(super) fn axis_pass(
    s: &Searcher<'_>,
    (frames, between): (&[TrackFrame<'_>], &[Vec<TrackFrame<'_>>]),
    (poses, scores): (&mut [GenPose], &mut [f64]),
    fixed: &[bool],
    log: &mut Log<'_>,
) -> Result<bool, TrackError> {
    if poses.is_empty() || !model_has_appearance(s.model) {
        return Ok(false);
    }
    let n = frames.len().min(poses.len());
    // The frames the pass chooses over: the keyframes alone, or, where the in-between frames
    // have colours, every video frame in temporal order (each gap's frames at the poses a
    // chain from the keyframe before carries there).
    let round = s.round_outline_axis().is_some();
    // Over the video only where the model's colours count as painted: judged no likeness of
    // the frames (weighed by where their boundaries fall), their weak pull at every video
    // frame outweighs the frames' agreement with each other (the hard suite's labelled can,
    // seed 17: keyframe 000000 turned 176° off, 2026-12-06).
    let painted = s
        .model_colours
        .read()
        .map(|m| *m == crate::appearance::ModelColours::AsPainted)
        .unwrap_or(false);
    // A faceted body ([`crate::axis::faceted_axis`]: its faces show the turn in every mask)
    // with video between its keyframes: the sequence choice weighed the steady motion through
    // every frame between ([`video_fit`]), and the keyframes' colours alone are weaker
    // evidence (general suite gen-1, an octagonal prism with a badge: keyframes the choice
    // put right turned 40° and 90° off by this pass, 2026-12-06). A mug's turn shows only
    // where its handle does: the pass runs.
    if !round
        && between.iter().any(|g| !g.is_empty())
        && crate::axis::faceted_axis(s.model, &s.model.tree.rest_states()).is_some()
    {
        return Ok(false);
    }
    let video = round && painted && between.iter().flatten().any(|f| f.rgb.is_some());
    let flat: Vec<TrackFrame<'_>> = if video {
        between.iter().flatten().cloned().collect()
    } else {
        vec![]
    };
    let cs = if flat.is_empty() {
        None
    } else {
        Some(Searcher::new(s.model, s.scale, &flat, &s.cfg)?)
    };
    // Per frame of the sequence: the frame, its searcher, its keyframe's index (None for an
    // in-between frame), its pose and IoU.
    let mut seq: Vec<(&TrackFrame<'_>, &Searcher<'_>, Option<usize>)> = Vec::new();
    let mut seq_poses: Vec<GenPose> = Vec::new();
    let mut seq_scores: Vec<f64> = Vec::new();
    let typical = typical_visible(frames);
    for k in 0..n {
        seq.push((&frames[k], s, Some(k)));
        seq_poses.push(poses[k].clone());
        seq_scores.push(scores[k]);
        let (Some(cs), Some(gap)) = (&cs, between.get(k)) else {
            continue;
        };
        if k + 1 >= n || gap.is_empty() {
            continue;
        }
        let path: Vec<&TrackFrame<'_>> = gap.iter().collect();
        let seed = s.cfg.seed + 6_000_011 * (k as u64 + 1);
        let followed = follow(
            cs,
            &frames[k],
            &poses[k],
            &path,
            &frames[k + 1],
            typical,
            seed,
        )?;
        for (f, (g, _)) in gap.iter().zip(followed.poses) {
            let own = cs.problem_of(f, &g).evaluator().combined(&g);
            seq.push((f, cs, None));
            seq_poses.push(g);
            seq_scores.push(own);
        }
    }
    let seq_fixed: Vec<bool> = seq.iter().map(|e| e.2.is_some_and(|k| fixed[k])).collect();
    // One axis for every frame (the steps' colours compare two frames turned alike): the
    // body's at the frames' joint states where they share them, else at rest
    // ([`Searcher::round_body`]), the body being the parts no joint moves.
    let first = &seq_poses[0];
    let axis = if seq_poses.iter().all(|g| g.states == first.states) {
        body_axis(s.model, &first.states)
    } else {
        s.round_body().copied()
    };
    let Some(axis) = axis else {
        if let Some(cs) = &cs {
            s.absorb_evals(cs);
        }
        return Ok(false);
    };
    let colours: Vec<Option<AppearanceFrame<'_>>> = seq.iter().map(|e| e.0.appearance()).collect();
    if colours.iter().all(Option::is_none) {
        return Ok(false);
    }
    let m = seq.len();
    let mut turned = vec![0.0; m];
    let mut could_turn = false;
    // Each frame's IoU as the pass began: every grid's turns are held within the tie of it,
    // not of the last grid's choice (which may already have spent the tie).
    let began: Vec<f64> = seq_scores.clone();
    // The steps a chain followed: into each in-between frame (from the keyframe it started
    // at, or the frame before), not into the keyframe it arrives at.
    let measured: Vec<bool> = seq.iter().map(|e| e.2.is_none()).collect();
    let steps = if cs.is_some() {
        Steps::Video {
            measured: &measured,
        }
    } else {
        Steps::Keyframes
    };
    for grid in [
        AngleGrid::circle(AXIS_COARSE_DEG),
        AngleGrid::around(AXIS_FINE_DEG, AXIS_COARSE_DEG),
    ] {
        // Every turn of every frame on the masks, its joints fitted again: the pose, and
        // whether it keeps the frame's IoU.
        let evaluated = std::sync::atomic::AtomicUsize::new(0);
        let candidates: Vec<Vec<(GenPose, f64)>> = (0..m)
            .into_par_iter()
            .map(|i| {
                let (frame, searcher, _) = seq[i];
                let problem = searcher.problem_of(frame, &seq_poses[i]);
                let mut ev = problem.evaluator();
                let mut count = 0usize;
                let row = grid
                    .angles_deg
                    .iter()
                    .map(|&deg| {
                        if deg == 0.0 || seq_fixed[i] {
                            return (seq_poses[i].clone(), seq_scores[i]);
                        }
                        let g = axis.turn(&seq_poses[i], s.scale, deg);
                        let sc = ev.combined(&g);
                        count += 1;
                        // Joints fitted again only where the body is round (its turn shows
                        // only through what its joints hold: a prism's outline shows it
                        // itself), where the turn alone loses the IoU, and at keyframes: an
                        // in-between frame whose lever the mask sees keeps the turn the chain
                        // measured by it.
                        if !round || sc >= began[i] - APPEARANCE_TIE || seq[i].2.is_none() {
                            return (g, sc);
                        }
                        refit_states(
                            &s.model.tree,
                            &mut |g| {
                                count += 1;
                                ev.combined(g)
                            },
                            (g, sc),
                        )
                    })
                    .collect();
                evaluated.fetch_add(count, std::sync::atomic::Ordering::Relaxed);
                row
            })
            .collect();
        let placed: Vec<Vec<f64>> = candidates
            .iter()
            .map(|row| row.iter().map(|c| c.1).collect())
            .collect();
        s.evals
            .fetch_add(evaluated.into_inner(), std::sync::atomic::Ordering::Relaxed);
        let allowed: Vec<Vec<bool>> = placed
            .iter()
            .zip(began.iter())
            .zip(&seq_fixed)
            .map(|((row, &own), &fixed)| {
                row.iter()
                    .map(|&sc| !fixed && sc >= own - APPEARANCE_TIE)
                    .collect()
            })
            .collect();
        if allowed.iter().all(|row| row.iter().skip(1).all(|&a| !a)) {
            continue;
        }
        could_turn = true;
        let turns = choose_turns(
            s.model,
            s.scale,
            (&s.appearance_cfg(), steps),
            &colours,
            &seq_poses,
            &allowed,
            // A step's difference of turns comes signed (−10° for the circle's 350°).
            &|i: usize, deg: f64| match grid
                .angles_deg
                .iter()
                .position(|&a| signed_deg(a - deg).abs() < 1e-6)
            {
                Some(k) => candidates[i][k].0.clone(),
                None => axis.turn(&seq_poses[i], s.scale, deg),
            },
            &grid,
        );
        for (i, &deg) in turns.iter().enumerate() {
            let Some(k) = grid.angles_deg.iter().position(|&a| a == deg) else {
                continue;
            };
            if k == 0 || seq_fixed[i] || !allowed[i][k] {
                continue;
            }
            seq_poses[i] = candidates[i][k].0.clone();
            seq_scores[i] = placed[i][k];
            turned[i] += deg;
        }
    }
    if let Some(cs) = &cs {
        s.absorb_evals(cs);
    }
    if !could_turn {
        return Ok(false);
    }
    let mut moved: Vec<String> = Vec::new();
    for (i, e) in seq.iter().enumerate() {
        let Some(k) = e.2 else {
            continue;
        };
        poses[k] = seq_poses[i].clone();
        scores[k] = seq_scores[i];
        if signed_deg(turned[i]).abs() > 0.5 * AXIS_FINE_DEG {
            moved.push(format!("{} {:+.0}°", frames[k].name, signed_deg(turned[i])));
        }
    }
    let over = if cs.is_some() {
        format!(
            "over all {m} video frames (each with its neighbours in the video, its print against the model's)"
        )
    } else {
        "over all frames".to_string()
    };
    log.push(format!(
        "axis: the model's round body turns about its {}; the angles about it chosen by colour {over} (turns about that axis, which leave the outline alike: the print decides, not a change of basin): {}",
        crate::temporal::axis_label(&[axis.axis.x, axis.axis.y, axis.axis.z]),
        if moved.is_empty() {
            "every keyframe kept".to_string()
        } else {
            format!("turned {}", moved.join(", "))
        }
    ));
    log.all_poses(poses);
    Ok(true)
}

/// Samples over each joint's range in [`refit_states`]' first round; its second searches
/// around the best as finely again.
const REFIT_SAMPLES: usize = 12;

/// `pose` (scoring `score`) with each joint's state searched again, one joint after another,
/// for the best `score_of`: every [`REFIT_SAMPLES`]th of its range (a continuous joint's
/// turn), then as many steps around the best, a twelfth as far apart. A body turned about its
/// axis moves what its joints hold across the mask (a lever on a frustum turned 30° shows
/// as the lever at another angle); the turn is judged with the joints where the mask puts
/// them. The pose is returned unchanged where no state scores better.
fn refit_states(
    tree: &agentstar_geom::KinematicTree,
    score_of: &mut dyn FnMut(&GenPose) -> f64,
    (pose, score): (GenPose, f64),
) -> (GenPose, f64) {
    let mut best = (pose, score);
    for (j, joint) in tree.joints().iter().enumerate() {
        if !joint.kind.has_state() || j >= best.0.states.len() {
            continue;
        }
        let (lo, hi) = match joint.limit {
            Some((lo, hi)) => (joint.to_internal(lo), joint.to_internal(hi)),
            None => (-std::f64::consts::PI, std::f64::consts::PI),
        };
        if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        let step = (hi - lo) / (REFIT_SAMPLES - 1) as f64;
        let fine = step / REFIT_SAMPLES as f64;
        let half = REFIT_SAMPLES as f64 / 2.0;
        for round in 0..2 {
            // Round 0 over the whole range, round 1 around the best of it.
            let centre = best.0.states[j];
            let values: Vec<f64> = (0..REFIT_SAMPLES)
                .map(|k| match round {
                    0 => lo + step * k as f64,
                    _ => (centre + fine * (k as f64 - half)).clamp(lo, hi),
                })
                .collect();
            for v in values {
                let mut g = best.0.clone();
                g.states[j] = v;
                let sc = score_of(&g);
                if sc > best.1 {
                    best = (g, sc);
                }
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::pose::ObjectPose;
    use agentstar_geom::{JointDef, JointKind, KinematicTree, UnitQuaternion, Vector3};

    #[test]
    fn joints_fitted_again_find_the_state_the_score_wants_and_keep_the_pose_otherwise() {
        let joint = |name: &str, child: &str, limit: Option<(f64, f64)>| JointDef {
            name: name.into(),
            kind: if limit.is_some() {
                JointKind::Revolute
            } else {
                JointKind::Continuous
            },
            parent: None,
            child: vec![child.into()],
            origin: Vector3::zeros(),
            axis: Vector3::y(),
            limit,
        };
        let names: Vec<String> = ["body", "lever", "lid"].map(String::from).to_vec();
        let tree = KinematicTree::new(
            vec![
                joint("hinge", "lever", Some((0.0, 60.0))),
                joint("spin", "lid", None),
            ],
            &names,
        )
        .expect("tree");
        let pose = GenPose {
            pose: ObjectPose::new(UnitQuaternion::identity(), Vector3::new(0.0, 0.0, 1.0)),
            states: vec![0.1, 0.0],
        };
        // The score peaks at the lever at 37° and the lid at −100°, neither on the first
        // round's samples.
        let want = [37f64.to_radians(), -100f64.to_radians()];
        let mut calls = 0;
        let mut score = |g: &GenPose| {
            calls += 1;
            -(g.states[0] - want[0]).abs() - (g.states[1] - want[1]).abs()
        };
        let start = score(&pose);
        let (fitted, sc) = refit_states(&tree, &mut score, (pose.clone(), start));
        for (got, want) in fitted.states.iter().zip(want) {
            assert!(
                // Half the second round's step: 360° / 11 / 12 / 2 for the continuous joint.
                (got - want).abs() < 1.4f64.to_radians(),
                "{:.2}° against {:.2}°",
                got.to_degrees(),
                want.to_degrees()
            );
        }
        assert!(sc > start);
        assert_eq!(fitted.pose, pose.pose);
        assert_eq!(calls, 1 + 2 * 2 * REFIT_SAMPLES);
        // Where no state scores better the pose comes back as it was.
        let (kept, kept_score) = refit_states(&tree, &mut |_| 0.0, (pose.clone(), 0.0));
        assert_eq!((kept, kept_score), (pose, 0.0));
    }
}
