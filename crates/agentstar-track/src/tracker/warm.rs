//! The warm start: tracking from given poses (`track --from`), with anchors kept exactly,
//! and either free to move a frame to another basin (reporting each frame it moved) or
//! keeping every frame in its own basin ([`BasinPolicy`]).

use super::*;
use crate::hypotheses::PRUNE_SLACK;
use crate::objective::FrameProblem;
use crate::space::joint_default;
use crate::temporal::angle_deg;
use crate::update::GenPose;
use crate::TrackError;
use agentstar_geom::{ObjectModel, UnitQuaternion};

/// The rotation a frame may turn from its starting pose and stay in its basin: half the
/// nearest twin the tracker weighs. Twins are half-turns (flips, principal half-turns, hinge
/// swaps) and, for a body whose cross-section repeats, quarter turns about a principal axis
/// ([`crate::hypotheses::basins`]): a pose under 45° from its start is nearer the start than
/// any quarter turn of it, so no flip or twin is reached.
pub const BASIN_ROTATION_DEG: f64 = 45.0;

/// How far a joint may move from its starting state and stay in its basin: 30° for a
/// revolute joint, a sixth of the range (30/180) for a prismatic one, just over the reach
/// of the polish ([`crate::hypotheses::LocalWindow::polish`]: 20° in its first pass, 28.8°
/// over all four).
pub const BASIN_JOINT_DEG: f64 = 30.0;

/// What `track --from` may do with a frame's basin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BasinPolicy {
    /// Any pass may move a frame to another basin (a flip, a twin, a carried neighbour's
    /// pose); every frame moved beyond [`BASIN_ROTATION_DEG`] is reported ([`BasinMove`]).
    #[default]
    Search,
    /// Local refinement only: each frame is polished around its own pose and carried poses
    /// are taken only within its basin; no wide search, and none of the passes over the
    /// sequence (consistency, sequence choice, appearance, axis), which exist to move frames
    /// between basins. Every frame ends within [`BASIN_ROTATION_DEG`] of its starting
    /// rotation and each joint within [`BASIN_JOINT_DEG`] (a frame whose refinement ends
    /// beyond keeps its starting pose).
    Keep,
}

/// A frame the warm start moved to another basin: further than [`BASIN_ROTATION_DEG`] from
/// its starting rotation.
#[derive(Debug, Clone, PartialEq)]
pub struct BasinMove {
    pub frame: usize,
    /// The rotation from the starting pose to the result, degrees.
    pub rotation_deg: f64,
    /// The score (gate IoU) at the starting pose and at the result.
    pub iou_before: f64,
    pub iou_after: f64,
    /// The pass that moved it (the first after which it stayed beyond the bound).
    pub pass: String,
    /// For a round body ([`crate::axis::outline_axis`]): the rotation leaving out its turn
    /// about the body's axis, degrees; within [`BASIN_ROTATION_DEG`] the frame turned about
    /// the axis only, which keeps its outline (the print decided).
    pub across_axis_deg: Option<f64>,
}

/// A warm start's result: the track, and the frames it moved to another basin.
#[derive(Debug, Clone, PartialEq)]
pub struct WarmStart {
    pub result: TrackResult,
    pub basin_moves: Vec<BasinMove>,
}

/// Where `pose` left the basin of `start`: the rotation beyond [`BASIN_ROTATION_DEG`] or a
/// joint beyond [`BASIN_JOINT_DEG`] (a prismatic joint: that share of 180° of its range);
/// `None` within it.
pub fn outside_basin(model: &ObjectModel, start: &GenPose, pose: &GenPose) -> Option<String> {
    let turned = angle_deg(&(pose.pose.rotation * start.pose.rotation.inverse()));
    if turned > BASIN_ROTATION_DEG {
        return Some(format!("turned {turned:.1}° (over {BASIN_ROTATION_DEG}°)"));
    }
    for (j, jd) in model.tree.joints().iter().enumerate() {
        let (Some(&a), Some(&b)) = (start.states.get(j), pose.states.get(j)) else {
            continue;
        };
        let moved = (jd.to_interface(b) - jd.to_interface(a)).abs();
        let bound = if jd.kind.is_angular() {
            BASIN_JOINT_DEG
        } else {
            let (lo, hi) = joint_default(&model.tree, j);
            BASIN_JOINT_DEG / 180.0 * (hi - lo).abs()
        };
        if moved > bound + 1e-9 {
            return Some(format!(
                "joint `{}` moved {moved:.3} (over {bound:.3})",
                jd.name
            ));
        }
    }
    None
}

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
    track_from_with(
        model,
        scale,
        frames,
        (start, anchors),
        BasinPolicy::Search,
        cfg,
        observe,
    )
    .map(|w| w.result)
}

/// [`track_from`] under a [`BasinPolicy`], with the frames it moved to another basin (none
/// under [`BasinPolicy::Keep`]). `(start, anchors)`: the starting poses and the frames kept
/// exactly.
pub fn track_from_with(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    (start, anchors): (&[GenPose], &[usize]),
    policy: BasinPolicy,
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<WarmStart, TrackError> {
    track_from_video(
        model,
        scale,
        (frames, &[]),
        (start, anchors),
        policy,
        cfg,
        observe,
    )
}

/// [`track_from_with`] with the video between keyframes (`between[g]`: the in-between frames
/// between keyframes g and g + 1, as [`track_video`] takes them): outside
/// [`BasinPolicy::Keep`], each gap's video is followed from its first keyframe's refined pose
/// and the motion it measured enters the passes over the sequence ([`Searcher::carried`]).
pub fn track_from_video(
    model: &ObjectModel,
    scale: f64,
    (frames, between): (&[TrackFrame<'_>], &[Vec<TrackFrame<'_>>]),
    (start, anchors): (&[GenPose], &[usize]),
    policy: BasinPolicy,
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<WarmStart, TrackError> {
    let mut passes = Vec::new();
    let mut result = on_stand_in(model, scale, frames, cfg, anchors, observe, |searched| {
        let (r, p) = track_from_on(
            searched, scale, frames, between, start, anchors, policy, cfg, observe,
        )?;
        passes = p;
        Ok(r)
    })?;
    let score_at = |i: usize, g: &GenPose| {
        FrameProblem::new(model, frames[i].camera, frames[i].target, scale, g.clone())
            .evaluator()
            .combined(g)
    };
    let mut basin_moves = Vec::new();
    // The round body's axis, in the object's frame, where the outline has one.
    let round_axis = crate::axis::outline_axis(model, &model.tree.rest_states());
    for i in 0..frames.len().min(start.len()) {
        if anchors.contains(&i) {
            continue;
        }
        let Some(why) = outside_basin(model, &start[i], &result.poses[i]) else {
            continue;
        };
        if policy == BasinPolicy::Keep {
            // The refinement ended beyond the bound (the polish on a dense model's own
            // mesh adds to the stand-in's): the frame keeps its starting pose.
            result.log.push(format!(
                "{}: kept its starting pose: its refinement {why}, out of its basin",
                frames[i].name
            ));
            observe.line(result.log.last().map_or("", String::as_str));
            result.poses[i] = start[i].clone();
            result.scores[i] = score_at(i, &start[i]);
            continue;
        }
        let rotation_deg =
            angle_deg(&(result.poses[i].pose.rotation * start[i].pose.rotation.inverse()));
        if rotation_deg <= BASIN_ROTATION_DEG {
            // Moved in a joint only: the rotation's basin is kept (the report is of turns).
            continue;
        }
        let within = |q: &UnitQuaternion| {
            angle_deg(&(q * start[i].pose.rotation.inverse())) <= BASIN_ROTATION_DEG
        };
        // The pass after the last one that left it within the bound.
        let last_within = passes
            .iter()
            .rposition(|(_, rots): &(String, Vec<UnitQuaternion>)| rots.get(i).is_some_and(within));
        let pass = match last_within {
            None => passes.first().map(|p| p.0.clone()),
            Some(k) => passes.get(k + 1).map(|p| p.0.clone()),
        }
        .unwrap_or_else(|| "the polish on the model's own mesh".to_string());
        let turn = start[i].pose.rotation.inverse() * result.poses[i].pose.rotation;
        let across_axis_deg = round_axis
            .as_ref()
            .map(|a| crate::axis::angle_across(&turn, &a.axis).to_degrees());
        let m = BasinMove {
            frame: i,
            rotation_deg,
            iou_before: score_at(i, &start[i]),
            iou_after: result.scores[i],
            pass,
            across_axis_deg,
        };
        let line = match m.across_axis_deg {
            Some(across) if across <= BASIN_ROTATION_DEG => format!(
                "{}: turned {:.1}° about the body's round axis only ({across:.1}° across it: the same outline), IoU {:.4} → {:.4}, by {}",
                frames[i].name, m.rotation_deg, m.iou_before, m.iou_after, m.pass
            ),
            _ => format!(
                "{}: moved to another basin: turned {:.1}° from its starting pose (over {BASIN_ROTATION_DEG}°), IoU {:.4} → {:.4}, by {}",
                frames[i].name, m.rotation_deg, m.iou_before, m.iou_after, m.pass
            ),
        };
        observe.line(&line);
        result.log.push(line);
        basin_moves.push(m);
    }
    Ok(WarmStart {
        result,
        basin_moves,
    })
}

/// Every frame's rotation after each pass of a warm start, by the pass's name.
type Passes = Vec<(String, Vec<UnitQuaternion>)>;

#[allow(clippy::too_many_arguments)]
fn track_from_on(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    between: &[Vec<TrackFrame<'_>>],
    start: &[GenPose],
    anchors: &[usize],
    policy: BasinPolicy,
    cfg: &TrackConfig,
    observe: &dyn TrackObserver,
) -> Result<(TrackResult, Passes), TrackError> {
    let keep = policy == BasinPolicy::Keep;
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
                if keep && outside_basin(model, &start[i], &g).is_some() {
                    // (The polish's reach is under the bound: kept should it ever not be.)
                    return Ok((at_start, start[i].clone(), at_start));
                }
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
    let rotations = |poses: &[GenPose]| poses.iter().map(|g| g.pose.rotation).collect();
    let mut passes: Passes = vec![("the polish of its own pose".to_string(), rotations(&poses))];
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
        let carried = carry(&poses[prev_i], &frames[prev_i], &frames[i]);
        let mut seeds = vec![carried.clone()];
        let prev2 = prev_i as isize - dir;
        if prev2 >= 0 && (prev2 as usize) < n {
            let p2 = prev2 as usize;
            seeds.push(extrapolate_through(
                &poses[p2],
                &frames[p2],
                &frames[prev_i],
                &frames[i],
                &carried,
                &model.tree,
            ));
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
        if !keep && reached.max(scores[i]) < scores[prev_i] - FAR_MARGIN {
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
        // Keeping basins, a carried pose is taken only within the frame's own basin.
        if let Some((g, sc)) = found
            .filter(|r| r.1 >= scores[i] - CARRY_TIE)
            .filter(|r| !keep || outside_basin(model, &start[i], &r.0).is_none())
        {
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
    passes.push((
        "the carry from its neighbour on the anchor's side".to_string(),
        rotations(&poses),
    ));
    let first = anchors.first().copied().unwrap_or(0);
    let mut choice = None;
    if keep {
        log.push(format!(
            "basins kept: every frame refined within its own basin (under {BASIN_ROTATION_DEG}° of rotation and {BASIN_JOINT_DEG}° of joint from its starting pose); the wide search and the passes that move frames between basins (consistency, sequence choice, appearance, axis) did not run"
        ));
    } else {
        follow_gaps(&s, frames, between, &poses, &mut log)?;
        choice = after_propagation(
            &s,
            (frames, between),
            (&mut poses, &mut scores),
            &fixed,
            &[],
            first,
            &mut log,
        )?;
        passes.extend(
            log.passes
                .iter()
                .map(|(name, rots)| (name.to_string(), rots.clone())),
        );
    }
    log.phases_line();
    let init_frame = anchors.first().copied().unwrap_or_else(|| {
        (0..n)
            .max_by(|&a, &b| scores[a].total_cmp(&scores[b]))
            .unwrap_or(0)
    });
    let refused_turns = still_refused(log.refused, &poses);
    Ok((
        TrackResult {
            poses,
            scores,
            init_frame,
            log: log.lines,
            evaluations: s.evals.into_inner(),
            between: vec![],
            choice,
            refused_turns,
        },
        passes,
    ))
}

/// Follows the video of every gap that has in-between frames from its first keyframe's pose
/// ([`follow`]), polishes the arrival at the next keyframe, and records the motion measured
/// ([`Searcher::set_gap`]); the keyframes' poses are not changed here.
fn follow_gaps(
    s: &Searcher<'_>,
    frames: &[TrackFrame<'_>],
    between: &[Vec<TrackFrame<'_>>],
    poses: &[GenPose],
    log: &mut Log<'_>,
) -> Result<(), TrackError> {
    let flat: Vec<TrackFrame<'_>> = between.iter().flatten().cloned().collect();
    if flat.is_empty() {
        return Ok(());
    }
    let cs = Searcher::new(s.model, s.scale, &flat, &s.cfg)?;
    let typical = typical_visible(frames);
    let mut followed = 0;
    for (g, gap) in between
        .iter()
        .enumerate()
        .take(frames.len().saturating_sub(1))
    {
        if gap.is_empty() {
            continue;
        }
        let path: Vec<&TrackFrame<'_>> = gap.iter().collect();
        let seed = s.cfg.seed + 3_000_029 * (g as u64 + 1);
        let chain = follow(
            &cs,
            &frames[g],
            &poses[g],
            &path,
            &frames[g + 1],
            typical,
            seed,
        )?;
        let arrivals: Vec<&GenPose> = chain.arrival.iter().collect();
        if let Some((arrival, _)) = polished_arrival(s, &frames[g + 1], &arrivals, seed)? {
            s.set_gap(g, Gap::between(frames, g, &poses[g], &arrival));
            followed += 1;
        }
    }
    s.absorb_evals(&cs);
    log.push(format!(
        "followed the video across {followed} gap(s) between keyframes from the refined poses: the passes below carry poses by the motion measured"
    ));
    log.phase("video", s);
    Ok(())
}
