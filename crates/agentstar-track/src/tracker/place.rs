//! Placing a model on a mask: rotations to start from, moments, centroid and area
//! alignment, carrying a pose between frames and extrapolating motion, diverse picks.

use super::*;
use crate::objective::FrameProblem;
use crate::temporal::angle_deg;
use crate::update::GenPose;
use crate::TrackError;
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{ObjectModel, Point3, UnitQuaternion, Vector3};
use agentstar_optim::Rng;
use agentstar_render::{BitMask, ScoreTarget};

pub(super) fn haar_rotations(n: usize, seed: u64) -> Vec<UnitQuaternion> {
    let mut rng = Rng::new(seed);
    let mut v = vec![UnitQuaternion::identity()];
    while v.len() < n.max(1) {
        let q = agentstar_geom::nalgebra::Quaternion::new(
            rng.normal(),
            rng.normal(),
            rng.normal(),
            rng.normal(),
        );
        if q.norm() > 1e-6 {
            v.push(UnitQuaternion::from_quaternion(q));
        }
    }
    v
}

pub(super) fn mask_stats(target: &ScoreTarget) -> Option<(f64, f64, f64)> {
    let (n, sx, sy) = moments(target.mask(), None, None);
    (n > 0.0).then(|| (sx / n, sy / n, n))
}

/// Pixel count and sums of pixel-centre coordinates of `mask` (within `keep` when given),
/// reading only `rows` (inclusive) when given: whole words at a time, set bits only.
pub(super) fn moments(
    mask: &BitMask,
    keep: Option<&BitMask>,
    rows: Option<(u32, u32)>,
) -> (f64, f64, f64) {
    let (y0, y1) = rows.unwrap_or((0, mask.height().saturating_sub(1)));
    let (mut n, mut sx, mut sy) = (0u64, 0u64, 0u64);
    for y in y0..=y1.min(mask.height().saturating_sub(1)) {
        let (mut row_n, mut row_sx) = (0u64, 0u64);
        for (k, &word) in mask.row(y).iter().enumerate() {
            let mut bits = match keep {
                Some(kp) => word & kp.row(y)[k],
                None => word,
            };
            while bits != 0 {
                row_sx += 64 * k as u64 + bits.trailing_zeros() as u64;
                row_n += 1;
                bits &= bits - 1;
            }
        }
        n += row_n;
        sx += row_sx;
        sy += row_n * y as u64;
    }
    if mask.height() == 0 {
        return (0.0, 0.0, 0.0);
    }
    // Pixel centres sit half a pixel in.
    let n = n as f64;
    (n, sx as f64 + 0.5 * n, sy as f64 + 0.5 * n)
}

/// The pivot (centre of the posed bounds) and half the bounds' diagonal at `states`: what
/// [`place`] needs of the model, computed once per joint state for a covering (a pass over
/// every vertex; 12% of a 17k-triangle model's tracking time when it ran per hypothesis).
pub(super) fn posed_extent(model: &ObjectModel, states: &[f64]) -> (Point3, f64) {
    let b = model.posed_bounds(states);
    (b.center(), b.extent().norm() * 0.5)
}

/// Places a rotation and joint state on the mask: pivot on the mask centroid, depth from
/// the ratio of rendered to observed area (two corrections). Returns the pose and its score.
pub(super) fn place(
    model: &ObjectModel,
    frame: &TrackFrame<'_>,
    scale: f64,
    rotation: UnitQuaternion,
    states: &[f64],
    stats: (f64, f64, f64),
    extent: Option<(Point3, f64)>,
) -> (GenPose, f64) {
    let cam = &frame.camera;
    let (pivot, half_diagonal) = extent.unwrap_or_else(|| posed_extent(model, states));
    let radius = (half_diagonal * scale).max(1e-9);
    let (cx, cy, area) = stats;
    let r_px = (area / std::f64::consts::PI).sqrt().max(1.0);
    let z = cam.fx * radius / r_px;
    align(
        model,
        frame,
        scale,
        (rotation, states),
        stats,
        pivot,
        (z, (cx, cy)),
    )
}

/// Moves `pose` onto the mask as [`place`] does (its pivot's image onto the mask centroid,
/// its depth by the ratio of areas), starting from where the pose puts it: a turn about an
/// axis off the object's outline (a mug's, through a centroid the handle pulls aside) shifts
/// the outline, and this brings it back without a search. Returns the pose and its score.
pub(super) fn realign(
    model: &ObjectModel,
    frame: &TrackFrame<'_>,
    scale: f64,
    pose: &GenPose,
    stats: (f64, f64, f64),
    pivot: Point3,
) -> (GenPose, f64) {
    let cam = &frame.camera;
    let c = pose.pose.rotation * (pivot.coords * scale) + pose.pose.translation;
    let z = c.z.max(1e-9);
    let centre = (cam.fx * c.x / z + cam.cx, cam.fy * c.y / z + cam.cy);
    let rotation = pose.pose.rotation;
    align(
        model,
        frame,
        scale,
        (rotation, &pose.states),
        stats,
        pivot,
        (z, centre),
    )
}

/// Two corrections of a pose given by its rotation, its pivot's depth `z` and image point
/// `centre`: the render's centroid (outside the hands) onto the mask's, the areas matched.
pub(super) fn align(
    model: &ObjectModel,
    frame: &TrackFrame<'_>,
    scale: f64,
    (rotation, states): (UnitQuaternion, &[f64]),
    (cx, cy, area): (f64, f64, f64),
    pivot: Point3,
    (mut z, mut centre): (f64, (f64, f64)),
) -> (GenPose, f64) {
    let cam = &frame.camera;
    let problem_pose = |z: f64, centre: (f64, f64)| {
        let c_cam = Vector3::new(
            (centre.0 - cam.cx) / cam.fx * z,
            (centre.1 - cam.cy) / cam.fy * z,
            z,
        );
        ObjectPose::new(rotation, c_cam - rotation * (pivot.coords * scale))
    };
    let base = GenPose {
        pose: problem_pose(z, centre),
        states: states.to_vec(),
    };
    let problem = FrameProblem::new(model, *cam, frame.target, scale, base);
    let mut ev = problem.evaluator();
    let mut r = crate::objective::pooled_renderer(cam.width, cam.height);
    for _ in 0..2 {
        let pose = problem_pose(z, centre);
        let inst = agentstar_render::PosedModel::new(model, states, &pose.with_scale(scale));
        // Only the render outside the hands can match the visible mask.
        r.render(cam, &inst.instances);
        let (rendered, sx, sy) = moments(r.mask(), frame.target.keep(), r.rows());
        if rendered < 1.0 {
            break;
        }
        // Move the render's centroid onto the mask's and match the areas.
        let (rx, ry) = (sx / rendered, sy / rendered);
        centre = (centre.0 + (cx - rx), centre.1 + (cy - ry));
        z *= (rendered / area).sqrt();
    }
    crate::objective::return_renderer(r);
    let g = GenPose {
        pose: problem_pose(z, centre),
        states: states.to_vec(),
    };
    let s = ev.combined(&g);
    (g, s)
}

/// A pose with the score it was searched by.
pub(super) type Scored = (GenPose, f64);

pub(super) fn transfer(
    pose: &ObjectPose,
    from: &TrackFrame<'_>,
    to: &TrackFrame<'_>,
) -> ObjectPose {
    match (from.world_from_camera, to.world_from_camera) {
        (Some(a), Some(b)) => agentstar_geom::pose::seed_from_reference(&b, &a, pose),
        _ => *pose,
    }
}

/// `g` carried from `from`'s camera into `to`'s ([`transfer`]), its joint states kept.
pub(super) fn carry(g: &GenPose, from: &TrackFrame<'_>, to: &TrackFrame<'_>) -> GenPose {
    GenPose {
        pose: transfer(&g.pose, from, to),
        states: g.states.clone(),
    }
}

/// [`extrapolate`] into frame `to` from `before` (the pose of `before_frame`, carried through
/// `via`, the frame between) and `carried`, `via`'s pose already carried into `to`.
pub(super) fn extrapolate_through(
    before: &GenPose,
    before_frame: &TrackFrame<'_>,
    via: &TrackFrame<'_>,
    to: &TrackFrame<'_>,
    carried: &GenPose,
    tree: &agentstar_geom::KinematicTree,
) -> GenPose {
    let before_here = carry(&carry(before, before_frame, via), via, to);
    extrapolate(&before_here, carried, tree)
}

/// The pose at `here`, a video frame a share `t` (0 to 1) of the way from keyframe `from` (at
/// pose `a`) to keyframe `to` (at `b`), on the steadiest motion joining them: the object turns
/// about its pivot (the middle of its posed bounds) at a steady rate through the shortest
/// rotation between the two orientations in the world, its pivot moves on a straight line and
/// its joint states linearly. A hand's motion over the third of a second between keyframes
/// ten video frames apart is close to that. Through the world where all three frames have a
/// camera pose; in the camera's frame (a still camera) otherwise.
pub(super) fn steady_between(
    model: &ObjectModel,
    scale: f64,
    (from, a): (&TrackFrame<'_>, &GenPose),
    (to, b): (&TrackFrame<'_>, &GenPose),
    here: &TrackFrame<'_>,
    t: f64,
) -> GenPose {
    let pivot_a = model.pivot(&a.states);
    let pivot_b = if b.states == a.states {
        pivot_a
    } else {
        model.pivot(&b.states)
    };
    steady_between_pivots(model, scale, (from, a, pivot_a), (to, b, pivot_b), here, t)
}

/// [`steady_between`] with the model's pivot at each keyframe's joint states given (a walk
/// over every vertex each; callers that place many frames between the same keyframes find
/// them once). Between the keyframes the pivot, in the object's frame, moves on the line
/// between the two (where the joint states agree, as they do for a rigid model, it stays).
pub(super) fn steady_between_pivots(
    model: &ObjectModel,
    scale: f64,
    (from, a, pivot_a): (&TrackFrame<'_>, &GenPose, Point3),
    (to, b, pivot_b): (&TrackFrame<'_>, &GenPose, Point3),
    here: &TrackFrame<'_>,
    t: f64,
) -> GenPose {
    let through_world = match (
        from.world_from_camera,
        to.world_from_camera,
        here.world_from_camera,
    ) {
        (Some(wa), Some(wb), Some(wh)) => Some((wa, wb, wh)),
        _ => None,
    };
    let into = |w: &Rigid, p: &ObjectPose| ObjectPose {
        rotation: w.rotation * p.rotation,
        translation: w.rotation * p.translation + w.translation.vector,
    };
    let (wa, wb) = match &through_world {
        Some((ca, cb, _)) => (into(ca, &a.pose), into(cb, &b.pose)),
        None => (a.pose, b.pose),
    };
    let mut states: Vec<f64> = a
        .states
        .iter()
        .zip(&b.states)
        .map(|(x, y)| x + t * (y - x))
        .collect();
    model.tree.clamp_states(&mut states);
    let rotation = (wb.rotation * wa.rotation.inverse()).powf(t) * wa.rotation;
    let centre_a = crate::update::pivot_in_camera(&wa, scale, &pivot_a);
    let centre_b = crate::update::pivot_in_camera(&wb, scale, &pivot_b);
    let centre = centre_a + t * (centre_b - centre_a);
    let pivot = pivot_a.coords + t * (pivot_b.coords - pivot_a.coords);
    let in_world = ObjectPose::new(rotation, centre - rotation * (pivot * scale));
    let pose = match &through_world {
        Some((_, _, wh)) => into(&wh.inverse(), &in_world),
        None => in_world,
    };
    GenPose { pose, states }
}

/// Constant-velocity extrapolation from two previous poses (in the later one's camera).
pub(super) fn extrapolate(
    prev2: &GenPose,
    prev: &GenPose,
    tree: &agentstar_geom::KinematicTree,
) -> GenPose {
    let step = prev.pose.rotation * prev2.pose.rotation.inverse();
    let rotation = step * prev.pose.rotation;
    let translation = prev.pose.translation + (prev.pose.translation - prev2.pose.translation);
    let mut states: Vec<f64> = prev
        .states
        .iter()
        .zip(&prev2.states)
        .map(|(a, b)| a + (a - b))
        .collect();
    tree.clamp_states(&mut states);
    GenPose {
        pose: ObjectPose::new(rotation, translation),
        states,
    }
}

/// The best hypotheses, at most `n`, each at least `min_angle_deg` in rotation (or as far
/// in a joint state) from those taken before it, so that refinements start in different
/// basins rather than around one near-duplicate.
pub(super) fn diverse(hyps: &[(GenPose, f64)], n: usize, min_angle_deg: f64) -> Vec<GenPose> {
    let mut out: Vec<GenPose> = Vec::with_capacity(n);
    for (g, _) in hyps {
        if out.len() >= n {
            break;
        }
        let far = out.iter().all(|o| {
            angle_deg(&(g.pose.rotation * o.pose.rotation.inverse())) >= min_angle_deg
                || g.states
                    .iter()
                    .zip(&o.states)
                    .any(|(a, b)| (a - b).abs().to_degrees() >= min_angle_deg)
        });
        if far {
            out.push(g.clone());
        }
    }
    out
}

/// The best-scoring result of parallel searches, or the first error.
pub(super) fn best_of(
    results: Vec<Result<(GenPose, f64), TrackError>>,
) -> Result<Option<(GenPose, f64)>, TrackError> {
    let mut best: Option<(GenPose, f64)> = None;
    for r in results {
        let r = r?;
        if best.as_ref().is_none_or(|b| r.1 > b.1) {
            best = Some(r);
        }
    }
    Ok(best)
}
