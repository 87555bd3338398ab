//! The appearance passes (silhouette twins turned by their colours against the frames
//! tracked before) and the consistency pass over temporal outliers.

use super::*;
use crate::appearance::ReferenceView;
use crate::hypotheses::{principal_axes, PRUNE_SLACK};
use crate::temporal::angle_deg;
use crate::update::{apply_object_rotation, GenPose};
use crate::TrackError;
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{UnitQuaternion, Vector3};

/// Rounds of [`appearance_pass`], and the frames each frame is compared with in it.
pub(super) const APPEARANCE_ROUNDS: usize = 2;
pub(super) const APPEARANCE_REFS: usize = 3;

/// The appearance term once more over the final poses: every searching pass after the
/// propagation (the consistency pass, the sequence choice's polish) ranks by the masks alone,
/// and about an axis of symmetry (a can's) a refinement turns the pose freely, so each frame
/// is settled again ([`Searcher::settle`]) against up to [`APPEARANCE_REFS`] frames between
/// it and the first tracked frame, settled before it in the same round (so a correction
/// carries outward, and a block of frames turned alike cannot hold a frame at its edge),
/// and the frames that see the same side of the object ([`covisible`]).
///
/// After the sequence choice, `rejected` holds per frame the basins it weighed and did not
/// take: those lying [`REJECTED_BASIN_DEG`] or more from the frame's pose as the pass began
/// are barred to [`Searcher::settle`] (no turn lands within half that of one). The choice
/// judged such a basin on the
/// colours of both neighbouring steps, the model's own colours and the motion; one frame's
/// colours against a few references are weaker evidence (hard suite labelcan, seeds 18
/// and 19: the final pass turned the choice's keyframes 85 and 90 upside down again on NCC
/// gains of 0.05–0.11, each losing 0.005 IoU).
pub(super) fn appearance_pass(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    (poses, scores): (&mut [GenPose], &mut [f64]),
    fixed: &[bool],
    init: usize,
    rejected: &[Vec<GenPose>],
    log: &mut Log<'_>,
) {
    let n = frames.len();
    // The rotations the pass starts from (the sequence choice's, when `rejected` is given):
    // the distance to a rejected basin is measured from these, so that two turns in two
    // rounds cannot walk a frame into one.
    let chosen: Vec<UnitQuaternion> = poses.iter().map(|g| g.pose.rotation).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| (i.abs_diff(init), i));
    for _ in 0..APPEARANCE_ROUNDS {
        let mut changed = 0;
        for &i in &order {
            if fixed[i] {
                continue;
            }
            // The frames between this one and the first, settled before it in this pass.
            let toward: Vec<usize> = if i > init {
                (1..=APPEARANCE_REFS)
                    .filter_map(|d| i.checked_sub(d))
                    .filter(|&k| k >= init)
                    .collect()
            } else {
                (1..=APPEARANCE_REFS)
                    .map(|d| i + d)
                    .filter(|&k| k <= init && k < n)
                    .collect()
            };
            // And the frames that see the same side of the object, wherever they are in the
            // sequence: after a step of 100–150° the neighbours share little surface with
            // this frame, a frame several steps away may share most of it.
            let mut toward = toward;
            for k in covisible(s, &poses[i], poses, i) {
                if !toward.contains(&k) {
                    toward.push(k);
                }
            }
            let refs: Vec<ReferenceView<'_>> = toward
                .into_iter()
                .filter_map(|k| {
                    ReferenceView::new(s.model, s.scale, frames[k].appearance()?, &poses[k])
                })
                .collect();
            // The basins the choice did not take, far enough from the pose the pass began
            // with to be another basin (a flip, a half-turn), not one beside it.
            let barred: Vec<UnitQuaternion> = rejected
                .get(i)
                .into_iter()
                .flatten()
                .map(|r| r.pose.rotation)
                .filter(|r| r.angle_to(&chosen[i]) >= REJECTED_BASIN_DEG.to_radians())
                .collect();
            if let Some((g, sc, text)) = s.settle(&frames[i], &poses[i], scores[i], &refs, &barred)
            {
                let line = if !leaves_the_chain(s, frames, poses, i, &g) {
                    format!("{}: {text} (final appearance pass)", frames[i].name)
                } else if let Some((from, to)) =
                    model_colours_overrule(s, &frames[i], &poses[i], &g)
                {
                    format!(
                        "{}: {text}: taken against the video's motion from a neighbour: the model's own colours prefer it ({from:.2} → {to:.2}) (final appearance pass)",
                        frames[i].name
                    )
                } else {
                    log.push(format!(
                        "{}: {text}: not taken, the video's motion from a neighbour keeps the frame where it is",
                        frames[i].name
                    ));
                    log.refused.push(RefusedTurn {
                        frame: i,
                        what: text,
                        pose: g,
                    });
                    continue;
                };
                log.push(line);
                poses[i] = g;
                scores[i] = sc;
                changed += 1;
            }
        }
        if changed == 0 {
            break;
        }
    }
}

/// Where the model's own colours count as painted (judged a likeness of the frames,
/// [`super::judge_model_colours`]) and prefer `to` over `from` by more than the appearance
/// term's margin: their agreement at `from` and at `to`. Such colours are evidence of where
/// the print lies whatever the other frames' poses, unlike the frames' colours against
/// each other, and a chain's motion does not outweigh them: a chain through an end-on view
/// of a capsule or a can, whose outline is a circle there, may come out end over end (a
/// generated capsule with a lever and a label, play-test 2026-12-06: keyframe 000110 left
/// 164° off, its colours' turn refused as leaving the chain). `None` otherwise, and
/// whenever the colours count only where their boundaries fall (a model painted "about
/// this colour").
pub(super) fn model_colours_overrule(
    s: &Searcher<'_>,
    frame: &TrackFrame<'_>,
    from: &GenPose,
    to: &GenPose,
) -> Option<(f64, f64)> {
    let cfg = s.appearance_cfg();
    if cfg.model_colours != ModelColours::AsPainted {
        return None;
    }
    let app = frame.appearance()?;
    let agreement =
        |g: &GenPose| crate::appearance::model_agreement(s.model, s.scale, &app, g, &cfg).ncc;
    let (a, b) = (agreement(from)?, agreement(to)?);
    (b > a + cfg.margin).then_some((a, b))
}

/// Whether turning frame `i` to `to` takes it out of the basin the video between it and a
/// neighbouring keyframe carries ([`Searcher::carried`] across a gap a chain followed): `to`
/// lies [`REJECTED_BASIN_DEG`] farther from every chained neighbour's pose carried here than
/// the frame's pose does. One frame's colours against a few references do not outweigh the
/// motion two chains measured (hard suite labelcan with in-between frames, seed 17: the final
/// pass turned keyframe 170 upside down on an NCC gain of 0.09 that cost 0.003 IoU, after
/// the sequence choice had put it back).
pub(super) fn leaves_the_chain(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    poses: &[GenPose],
    i: usize,
    to: &GenPose,
) -> bool {
    let n = frames.len();
    let chained: Vec<usize> = [
        i.checked_sub(1).filter(|&j| s.gap(j).is_some()),
        (i + 1 < n && s.gap(i).is_some()).then_some(i + 1),
    ]
    .into_iter()
    .flatten()
    .collect();
    !chained.is_empty()
        && chained.iter().all(|&j| {
            let predicted = s.carried(frames, poses, j, i).pose.rotation;
            s.off_chain(&predicted, &to.pose.rotation)
                > s.off_chain(&predicted, &poses[i].pose.rotation) + REJECTED_BASIN_DEG.to_radians()
        })
}

/// Frames whose cameras see the object from within this angle of one another share most of
/// its visible surface.
pub(super) const COVISIBLE_DEG: f64 = 60.0;
/// Frames taken per direction of view ([`covisible`]).
pub(super) const COVISIBLE_PER_VIEW: usize = 2;

/// The frames (other than `own`) whose cameras see the object from nearest the directions
/// `pose` and its half-turns about the model's principal axes see it from (within
/// [`COVISIBLE_DEG`], up to [`COVISIBLE_PER_VIEW`] each, nearest first): references that
/// share surface with the pose and with each of its twins, so that colours can judge between
/// them even where the neighbours in time saw another side.
pub(super) fn covisible(
    s: &Searcher<'_>,
    pose: &GenPose,
    poses: &[GenPose],
    own: usize,
) -> Vec<usize> {
    // The camera's centre in the object's frame, as a direction from the object.
    let view = |g: &GenPose| -> Vector3 {
        let p = &g.pose;
        let v = p.rotation.inverse() * (-p.translation);
        v / v.norm().max(1e-12)
    };
    let mut views = vec![view(pose)];
    if let Some((centre, axes)) = principal_axes(s.model, &pose.states) {
        views.extend(axes.iter().map(|a| {
            let q = UnitQuaternion::from_axis_angle(
                &agentstar_geom::nalgebra::Unit::new_normalize(*a),
                std::f64::consts::PI,
            );
            view(&GenPose {
                pose: apply_object_rotation(&pose.pose, s.scale, &centre, &q),
                states: pose.states.clone(),
            })
        }));
    }
    let mut out: Vec<usize> = Vec::new();
    for v in &views {
        let mut near: Vec<(f64, usize)> = poses
            .iter()
            .enumerate()
            .filter(|&(k, _)| k != own)
            .map(|(k, g)| (v.dot(&view(g)).clamp(-1.0, 1.0).acos().to_degrees(), k))
            .filter(|&(deg, _)| deg <= COVISIBLE_DEG)
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (_, k) in near.into_iter().take(COVISIBLE_PER_VIEW) {
            if !out.contains(&k) {
                out.push(k);
            }
        }
    }
    out
}

/// Searches again every frame that is a temporal outlier or scores below a neighbour, from
/// its neighbours: their poses carried through the cameras, extrapolated at constant
/// velocity from either side, and their interpolation. Keeps whatever scores best.
pub(super) fn consistency(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    poses: &mut [GenPose],
    scores: &mut [f64],
    fixed: &[bool],
    log: &mut Log<'_>,
) -> Result<(), TrackError> {
    let n = frames.len();
    let tree = &s.model.tree;
    let step = |poses: &[GenPose], a: usize, b: usize| {
        angle_deg(
            &(poses[b].pose.rotation * s.carried(frames, poses, a, b).pose.rotation.inverse()),
        )
    };
    // Three rounds of narrow searches, and more (up to one per frame, so a good pose can
    // travel the whole sequence) while wide searches from better neighbours still move poses.
    // A frame whose neighbourhood (the frames its seeds come from) did not change in the
    // last round would be searched from the same seeds again: only the others are.
    let mut stale = vec![true; n];
    for round in 0..(n as u64).max(3) {
        let mut moved = vec![false; n];
        let mut steps: Vec<f64> = (1..n).map(|i| step(poses, i - 1, i)).collect();
        steps.sort_by(f64::total_cmp);
        let limit = (3.0 * steps.get(steps.len() / 2).copied().unwrap_or(0.0)).max(25.0);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]));
        let mut changed = 0;
        let mut changed_wide = 0;
        for i in order {
            let neighbours: Vec<usize> = [i.checked_sub(1), (i + 1 < n).then_some(i + 1)]
                .into_iter()
                .flatten()
                .collect();
            let best_neighbour = neighbours
                .iter()
                .map(|&j| scores[j])
                .fold(f64::NEG_INFINITY, f64::max);
            let outlier = i >= 1
                && i + 1 < n
                && step(poses, i - 1, i) > limit
                && step(poses, i, i + 1) > limit;
            if fixed[i] || !stale[i] || (!outlier && scores[i] >= best_neighbour - 0.001) {
                continue;
            }
            let mut seeds: Vec<GenPose> = neighbours
                .iter()
                .map(|&j| s.carried(frames, poses, j, i))
                .collect();
            if i >= 2 {
                seeds.push(extrapolate(
                    &s.carried(frames, poses, i - 2, i),
                    &s.carried(frames, poses, i - 1, i),
                    tree,
                ));
            }
            if i + 2 < n {
                seeds.push(extrapolate(
                    &s.carried(frames, poses, i + 2, i),
                    &s.carried(frames, poses, i + 1, i),
                    tree,
                ));
            }
            if i >= 1 && i + 1 < n {
                let (l, r) = (
                    s.carried(frames, poses, i - 1, i),
                    s.carried(frames, poses, i + 1, i),
                );
                let mut states: Vec<f64> = l
                    .states
                    .iter()
                    .zip(&r.states)
                    .map(|(a, b)| 0.5 * (a + b))
                    .collect();
                tree.clamp_states(&mut states);
                seeds.push(GenPose {
                    pose: ObjectPose::new(
                        l.pose.rotation.slerp(&r.pose.rotation, 0.5),
                        (l.pose.translation + r.pose.translation) * 0.5,
                    ),
                    states,
                });
            }
            // A neighbour clearly better than this frame may be a whole inter-frame step
            // away (the frame sits in a wrong basin): search its carried pose with the
            // tracking step's window, not the narrow polish.
            let results: Vec<Result<(GenPose, f64), TrackError>> = seeds
                .par_iter()
                .enumerate()
                .map(|(k, g)| {
                    // Only a seed that ends above this frame's score moves it.
                    s.polish_above(
                        &frames[i],
                        g,
                        s.cfg.seed + 65537 * (i as u64 + 1) + 97 * round + k as u64,
                        scores[i] - PRUNE_SLACK,
                    )
                })
                .collect();
            let mut found = best_of(results)?;
            let mut wide_won = false;
            // A neighbour clearly better than this frame, and the narrow search from it not
            // reaching it: this frame sits in a wrong basin a whole step away. The wide
            // search around the better neighbour's carried pose.
            let j = neighbours
                .iter()
                .copied()
                .max_by(|&a, &b| scores[a].total_cmp(&scores[b]))
                .unwrap_or(i);
            let here = found.as_ref().map_or(scores[i], |r| r.1.max(scores[i]));
            // Or, on the band IoU, the neighbour right and this frame not (its visible IoU a
            // little under the neighbour's, but a few degrees off: a segmenter's noise and the
            // hands make visible IoUs differ by more than that).
            let band_gap = || {
                let g = found.as_ref().map_or(&poses[i], |r| &r.0);
                s.band_iou(&frames[i], i, g) < RESCUE_BAND
                    && s.band_iou(&frames[j], j, &poses[j]) >= RESCUE_BAND
            };
            if best_neighbour > here + FAR_MARGIN || (best_neighbour > here && band_gap()) {
                let from = s.carried(frames, poses, j, i);
                let seed = s.cfg.seed + 65537 * (i as u64 + 1) + 97 * round + 50;
                // Only a pose above this frame's score (and the narrow searches') moves it.
                let floor = here - PRUNE_SLACK;
                let wide = s.wide(&frames[i], &from, &from, (seed, seed), floor)?;
                if let Some(w) = wide.filter(|w| found.as_ref().is_none_or(|f| w.1 > f.1)) {
                    found = Some(w);
                    wide_won = true;
                }
            }
            if let Some((g, sc)) = found.filter(|r| r.1 > scores[i] + 1e-4) {
                log.push(format!(
                    "{}: searched again from its neighbours{}, IoU {:.4} → {sc:.4}",
                    frames[i].name,
                    if outlier { " (temporal outlier)" } else { "" },
                    scores[i]
                ));
                poses[i] = g;
                scores[i] = sc;
                moved[i] = true;
                changed += 1;
                changed_wide += usize::from(wide_won);
            }
        }
        if changed == 0 || (round >= 2 && changed_wide == 0) {
            break;
        }
        stale = (0..n)
            .map(|i| (i.saturating_sub(2)..(i + 3).min(n)).any(|j| j != i && moved[j]))
            .collect();
    }
    Ok(())
}
