//! The axis pass: the angle about a round body's axis chosen for the whole sequence at once
//! ([`crate::axis`]), after the last appearance pass.

use super::*;
use crate::appearance::{model_has_appearance, AppearanceFrame};
use crate::axis::{body_axis, choose_turns, AngleGrid};
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
/// mug: those that keep its handle where the mask has it, or hidden). `fixed` frames keep
/// their pose. Whether the pass ran (the model has such an axis and some frame could turn).
/// Frames at different joint states (a can's lever moving) all turn about the body's axis
/// at rest.
pub(super) fn axis_pass(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    (poses, scores): (&mut [GenPose], &mut [f64]),
    fixed: &[bool],
    log: &mut Log<'_>,
) -> Result<bool, TrackError> {
    let Some(first) = poses.first() else {
        return Ok(false);
    };
    if !model_has_appearance(s.model) {
        return Ok(false);
    }
    // One axis for every frame (the steps' colours compare two frames turned alike): the
    // body's at the frames' joint states where they share them, else at rest
    // ([`Searcher::round_body`]), the body being the parts no joint moves.
    let axis = if poses.iter().all(|g| g.states == first.states) {
        body_axis(s.model, &first.states)
    } else {
        s.round_body().copied()
    };
    let Some(axis) = axis else {
        return Ok(false);
    };
    let colours: Vec<Option<AppearanceFrame<'_>>> =
        frames.iter().map(TrackFrame::appearance).collect();
    if colours.iter().all(Option::is_none) {
        return Ok(false);
    }
    let mut turned = vec![0.0; frames.len()];
    let mut could_turn = false;
    // Each frame's IoU as the pass began: every grid's turns are held within the tie of it,
    // not of the last grid's choice (which may already have spent the tie).
    let began: Vec<f64> = scores.to_vec();
    for grid in [
        AngleGrid::circle(AXIS_COARSE_DEG),
        AngleGrid::around(AXIS_FINE_DEG, AXIS_COARSE_DEG),
    ] {
        // Every turn of every frame on the masks: which keep its IoU, and their scores.
        let placed: Vec<Vec<f64>> = (0..frames.len())
            .into_par_iter()
            .map(|i| {
                let problem = s.problem_of(&frames[i], &poses[i]);
                let mut ev = problem.evaluator();
                grid.angles_deg
                    .iter()
                    .map(|&deg| {
                        if deg == 0.0 || fixed[i] {
                            scores[i]
                        } else {
                            ev.combined(&axis.turn(&poses[i], s.scale, deg))
                        }
                    })
                    .collect()
            })
            .collect();
        let evaluated = fixed.iter().filter(|&&f| !f).count() * (grid.angles_deg.len() - 1);
        s.evals
            .fetch_add(evaluated, std::sync::atomic::Ordering::Relaxed);
        let allowed: Vec<Vec<bool>> = placed
            .iter()
            .zip(began.iter())
            .zip(fixed)
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
            &s.appearance_cfg(),
            &colours,
            poses,
            &allowed,
            &axis,
            &grid,
        );
        for (i, &deg) in turns.iter().enumerate() {
            let Some(k) = grid.angles_deg.iter().position(|&a| a == deg) else {
                continue;
            };
            if k == 0 || fixed[i] || !allowed[i][k] {
                continue;
            }
            poses[i] = axis.turn(&poses[i], s.scale, deg);
            scores[i] = placed[i][k];
            turned[i] += deg;
        }
    }
    if !could_turn {
        return Ok(false);
    }
    let moved: Vec<String> = turned
        .iter()
        .enumerate()
        .filter(|(_, &deg)| signed_deg(deg).abs() > 0.5 * AXIS_FINE_DEG)
        .map(|(i, &deg)| format!("{} {:+.0}°", frames[i].name, signed_deg(deg)))
        .collect();
    log.push(format!(
        "axis: the model's round body turns about its {}; the angles about it chosen by colour over all frames (turns about that axis, which leave the outline alike: the print decides, not a change of basin): {}",
        crate::temporal::axis_label(&[axis.axis.x, axis.axis.y, axis.axis.z]),
        if moved.is_empty() {
            "every frame kept".to_string()
        } else {
            format!("turned {}", moved.join(", "))
        }
    ));
    log.all_poses(poses);
    Ok(true)
}
