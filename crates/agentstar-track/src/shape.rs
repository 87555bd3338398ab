//! Fitting named shape parameters against committed poses: the scene declares parameters
//! with bounds (`param("depth", 0.6, 0.4, 0.9)`), the caller supplies a closure from the
//! values of the parameters it names to an [`ObjectModel`] (so this crate knows nothing of
//! scripts), and the fit moves only those parameters, only within their bounds, to raise
//! the mean visible IoU over the chosen keyframes.
//!
//! Each round searches the parameters with the poses held (bounded Nelder–Mead in box
//! fractions; a pose made for the round's starting model is carried to each trial model by
//! [`origin_shift`], so re-centring geometry costs nothing), then refines every frame's pose
//! locally around where it was for the new model (a small box: the fit corrects
//! proportions, it does not re-track). Rounds stop when the values settle.
//!
//! The guard against the paper's failure mode (flat, silhouette-like geometry that games
//! IoU from a few views) is in what may move: only the named parameters, only within the
//! bounds the script gives them; every other part of the model is what the script says.

use crate::hypotheses::{refine_local, LocalWindow};
use crate::objective::FrameProblem;
use crate::update::GenPose;
use crate::TrackError;
use agentstar_geom::{origin_shift, ObjectModel, PinholeCamera};
use agentstar_optim::{nelder_mead, NelderMeadConfig};
use agentstar_render::ScoreTarget;
use rayon::prelude::*;

/// Builds the model for the values of the named parameters (in the order of the
/// [`ShapeParam`] list); an error is a trial the fit cannot use.
pub type ModelBuilder<'b> = dyn Fn(&[f64]) -> Result<ObjectModel, String> + Sync + 'b;

/// One parameter to fit: where it starts and its bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeParam {
    pub name: String,
    pub start: f64,
    pub min: f64,
    pub max: f64,
}

/// One keyframe of the fit: its camera, its target and its committed pose.
#[derive(Debug, Clone)]
pub struct ShapeFrame<'a> {
    pub name: String,
    pub camera: PinholeCamera,
    pub target: &'a ScoreTarget,
    pub pose: GenPose,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ShapeFitConfig {
    /// Rounds of (parameters with poses held, then poses refined).
    pub rounds: usize,
    /// Model builds of each round's parameter search.
    pub evals_per_round: usize,
    /// Refine the poses after each round (off: the poses stay as committed).
    pub refine_poses: bool,
    /// The box of the pose refinement.
    pub window: LocalWindow,
    pub seed: u64,
    /// Stop when no parameter moved by more than this share of its range in a round.
    pub tolerance: f64,
    /// The part kept in place when the poses are carried to each trial shape
    /// ([`agentstar_geom::origin_shift_holding`]); `None`: the largest part that votes
    /// ([`origin_shift`]).
    pub held: Option<String>,
}

impl Default for ShapeFitConfig {
    fn default() -> Self {
        ShapeFitConfig {
            rounds: 3,
            evals_per_round: 60,
            refine_poses: true,
            window: LocalWindow {
                angle_deg: 6.0,
                shift: 0.02,
                depth: 0.04,
                joint_deg: 10.0,
                evals: 500,
            },
            seed: 17,
            tolerance: 0.002,
            held: None,
        }
    }
}

/// What one round did.
#[derive(Debug, Clone, PartialEq)]
pub struct FitRound {
    pub values: Vec<f64>,
    /// Mean visible IoU with the poses held, after the parameter search.
    pub iou_held: f64,
    /// Mean visible IoU after the poses were refined.
    pub iou_refined: f64,
    pub builds: usize,
}

#[derive(Debug, Clone)]
pub struct ShapeFit {
    /// The fitted values, in the order of the parameters.
    pub values: Vec<f64>,
    /// Each frame's visible IoU before (the starting model and poses) and after.
    pub before: Vec<f64>,
    pub after: Vec<f64>,
    /// The poses for the fitted model (refined, or carried when refinement is off).
    pub poses: Vec<GenPose>,
    /// The fitted model.
    pub model: ObjectModel,
    /// How far the origin moved from the starting model to the fitted one (canonical units;
    /// the poses of frames outside the fit are carried by it).
    pub origin_shift: agentstar_geom::OriginShift,
    pub rounds: Vec<FitRound>,
    pub builds: usize,
    pub evaluations: usize,
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Each frame's visible IoU for `model` at `poses`.
pub fn frame_ious(
    model: &ObjectModel,
    frames: &[ShapeFrame<'_>],
    poses: &[GenPose],
    scale: f64,
) -> Vec<f64> {
    frames
        .par_iter()
        .zip(poses)
        .map(|(f, g)| {
            FrameProblem::new(model, f.camera, f.target, scale, g.clone())
                .evaluator()
                .score(g)
                .gate
        })
        .collect()
}

/// `poses` made for `from`, carried to `to` by the origin shift between them, holding the
/// part `held` in place when it is a part of both.
fn carried(
    from: &ObjectModel,
    to: &ObjectModel,
    poses: &[GenPose],
    scale: f64,
    held: Option<&str>,
) -> Vec<GenPose> {
    let s = held
        .and_then(|h| agentstar_geom::origin_shift_holding(from, to, h))
        .unwrap_or_else(|| origin_shift(from, to));
    poses
        .iter()
        .map(|g| GenPose {
            pose: s.carry(&g.pose, scale),
            states: g.states.clone(),
        })
        .collect()
}

fn check(params: &[ShapeParam], frames: &[ShapeFrame<'_>], scale: f64) -> Result<(), TrackError> {
    if params.is_empty() {
        return Err(TrackError::Spec(
            "name at least one parameter to fit".into(),
        ));
    }
    if frames.is_empty() {
        return Err(TrackError::Spec(
            "the fit needs at least one keyframe".into(),
        ));
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(TrackError::Invalid(format!(
            "the scale must be positive, got {scale}"
        )));
    }
    for p in params {
        if !(p.min.is_finite() && p.max.is_finite() && p.min < p.max) {
            return Err(TrackError::Spec(format!(
                "parameter `{}`: bounds [{}, {}] must be finite with min < max",
                p.name, p.min, p.max
            )));
        }
        if !(p.min..=p.max).contains(&p.start) {
            return Err(TrackError::Spec(format!(
                "parameter `{}`: the start {} lies outside [{}, {}]",
                p.name, p.start, p.min, p.max
            )));
        }
    }
    for (k, p) in params.iter().enumerate() {
        if params[..k].iter().any(|q| q.name == p.name) {
            return Err(TrackError::Spec(format!(
                "parameter `{}` is named twice",
                p.name
            )));
        }
    }
    Ok(())
}

/// Fits the parameters `params` of the model `build` makes against `frames` at `scale`.
/// Never worse than the start: a round whose result scores under the best so far (with its
/// poses refined) is not taken.
pub fn fit_shape(
    build: &ModelBuilder<'_>,
    params: &[ShapeParam],
    frames: &[ShapeFrame<'_>],
    scale: f64,
    cfg: &ShapeFitConfig,
) -> Result<ShapeFit, TrackError> {
    check(params, frames, scale)?;
    let spans: Vec<f64> = params.iter().map(|p| p.max - p.min).collect();
    let to_values = |u: &[f64]| -> Vec<f64> {
        params
            .iter()
            .zip(u)
            .map(|(p, &x)| (p.min + x.clamp(0.0, 1.0) * (p.max - p.min)).clamp(p.min, p.max))
            .collect()
    };
    let mut values: Vec<f64> = params.iter().map(|p| p.start).collect();
    let start_model = build(&values).map_err(|e| {
        TrackError::Invalid(format!("the model does not build at the start values: {e}"))
    })?;
    let start_poses: Vec<GenPose> = frames.iter().map(|f| f.pose.clone()).collect();
    let before = frame_ious(&start_model, frames, &start_poses, scale);
    let mut model = start_model.clone();
    let mut poses = start_poses.clone();
    let mut best_mean = mean(&before);
    let mut rounds = vec![];
    let mut builds = 1usize;
    let mut evaluations = frames.len();
    for round in 0..cfg.rounds.max(1) {
        // (a) The parameters, poses held (carried to each trial model).
        let base_model = model.clone();
        let base_poses = poses.clone();
        let mut n_builds = 0usize;
        let mut n_evals = 0usize;
        let mut objective = |u: &[f64]| -> f64 {
            n_builds += 1;
            let v = to_values(u);
            match build(&v) {
                Ok(m) => {
                    let trial = carried(&base_model, &m, &base_poses, scale, cfg.held.as_deref());
                    n_evals += frames.len();
                    1.0 - mean(&frame_ious(&m, frames, &trial, scale))
                }
                Err(_) => f64::INFINITY,
            }
        };
        let u0: Vec<f64> = values
            .iter()
            .zip(params)
            .map(|(v, p)| (v - p.min) / (p.max - p.min))
            .collect();
        let unit: Vec<(f64, f64)> = vec![(0.0, 1.0); params.len()];
        let nm = nelder_mead(
            &mut objective,
            &unit,
            &u0,
            &NelderMeadConfig {
                max_evals: cfg.evals_per_round.max(params.len() + 2),
                initial_step: if round == 0 { 0.12 } else { 0.04 },
                ftol: 1e-7,
                xtol: 1e-4,
            },
        )?;
        builds += n_builds;
        evaluations += n_evals;
        let trial_values = to_values(&nm.x);
        let trial_model = build(&trial_values).map_err(|e| {
            TrackError::Invalid(format!("the model does not build at {trial_values:?}: {e}"))
        })?;
        builds += 1;
        let mut trial_poses = carried(
            &base_model,
            &trial_model,
            &base_poses,
            scale,
            cfg.held.as_deref(),
        );
        let iou_held = mean(&frame_ious(&trial_model, frames, &trial_poses, scale));
        // (b) Every frame's pose refined locally for the trial model.
        if cfg.refine_poses {
            let refined: Vec<Result<(GenPose, usize), TrackError>> = frames
                .par_iter()
                .zip(&trial_poses)
                .enumerate()
                .map(|(k, (f, g))| {
                    let p = FrameProblem::new(&trial_model, f.camera, f.target, scale, g.clone());
                    let seed = cfg.seed + 7919 * round as u64 + k as u64;
                    refine_local(&p, g, &cfg.window, seed).map(|(pose, _, n)| (pose, n))
                })
                .collect();
            trial_poses = refined
                .into_iter()
                .map(|r| {
                    r.map(|(g, n)| {
                        evaluations += n;
                        g
                    })
                })
                .collect::<Result<_, _>>()?;
        }
        let iou_refined = mean(&frame_ious(&trial_model, frames, &trial_poses, scale));
        evaluations += 2 * frames.len();
        rounds.push(FitRound {
            values: trial_values.clone(),
            iou_held,
            iou_refined,
            builds: n_builds + 1,
        });
        if iou_refined < best_mean {
            break;
        }
        let moved = trial_values
            .iter()
            .zip(&values)
            .zip(&spans)
            .map(|((a, b), s)| (a - b).abs() / s)
            .fold(0.0, f64::max);
        best_mean = iou_refined;
        values = trial_values;
        model = trial_model;
        poses = trial_poses;
        if round > 0 && moved < cfg.tolerance {
            break;
        }
    }
    let after = frame_ious(&model, frames, &poses, scale);
    let shift = cfg
        .held
        .as_deref()
        .and_then(|h| agentstar_geom::origin_shift_holding(&start_model, &model, h))
        .unwrap_or_else(|| origin_shift(&start_model, &model));
    Ok(ShapeFit {
        values,
        before,
        after,
        poses,
        model,
        origin_shift: shift,
        rounds,
        builds,
        evaluations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::pose::ObjectPose;
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::{KinematicTree, Part, UnitQuaternion, Vector3};
    use agentstar_render::{PosedModel, SilhouetteRenderer};

    /// A body width × depth × 0.4 centred on the origin with a handle bar of `handle` height
    /// on its front face (a deeper body moves the handle: the body, the larger part, keeps
    /// the origin where it is).
    fn model(v: &[f64]) -> Result<ObjectModel, String> {
        let (width, depth, handle) = (v[0], v[1], v[2]);
        let body = cuboid(width, depth, 0.4).map_err(|e| e.to_string())?;
        let bar = cuboid(0.08, 0.06, handle)
            .map_err(|e| e.to_string())?
            .translated(Vector3::new(0.0, -depth / 2.0 - 0.03, 0.0));
        Ok(ObjectModel {
            tree: KinematicTree::rigid(2),
            parts: vec![
                Part::new("body", body, [0.5; 3]),
                Part::new("handle", bar, [0.5; 3]),
            ],
        })
    }

    #[test]
    fn two_wrong_proportions_come_back_and_the_others_stay() {
        let truth = [1.0, 0.6, 0.3];
        let true_model = model(&truth).expect("model");
        let camera = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
        let scale = 0.2;
        let rotations = [
            (0.3, 0.2, 0.4),
            (-0.5, 0.1, 1.2),
            (0.9, -0.3, -0.6),
            (0.2, 0.7, 2.4),
            (-1.1, 0.4, 0.2),
            (0.6, -0.8, -1.9),
        ];
        let targets: Vec<ScoreTarget> = rotations
            .iter()
            .map(|&(r, p, y)| {
                let pose = ObjectPose::new(
                    UnitQuaternion::from_euler_angles(r, p, y),
                    Vector3::new(0.0, 0.0, 0.6),
                );
                let posed = PosedModel::new(&true_model, &[], &pose.with_scale(scale));
                let mask = SilhouetteRenderer::new(320, 240)
                    .render(&camera, &posed.instances)
                    .clone();
                ScoreTarget::new(mask, None).expect("target")
            })
            .collect();
        // Poses a little off, as committed poses made with the wrong model would be.
        let frames: Vec<ShapeFrame<'_>> = rotations
            .iter()
            .zip(&targets)
            .enumerate()
            .map(|(k, (&(r, p, y), t))| ShapeFrame {
                name: format!("{k:06}.png"),
                camera,
                target: t,
                pose: GenPose {
                    pose: ObjectPose::new(
                        UnitQuaternion::from_euler_angles(r + 0.02, p - 0.015, y + 0.01),
                        Vector3::new(0.003, -0.002, 0.605),
                    ),
                    states: vec![],
                },
            })
            .collect();
        // Width held at its true value; depth 15% short, handle 20% tall.
        let width = truth[0];
        let build = |v: &[f64]| model(&[width, v[0], v[1]]);
        let params = [
            ShapeParam {
                name: "depth".into(),
                start: 0.6 * 0.85,
                min: 0.4,
                max: 0.8,
            },
            ShapeParam {
                name: "handle".into(),
                start: 0.3 * 1.2,
                min: 0.2,
                max: 0.4,
            },
        ];
        let fit =
            fit_shape(&build, &params, &frames, scale, &ShapeFitConfig::default()).expect("fit");
        let depth_err = (fit.values[0] / truth[1] - 1.0).abs();
        let handle_err = (fit.values[1] / truth[2] - 1.0).abs();
        assert!(
            depth_err < 0.02 && handle_err < 0.02,
            "fitted {:?} vs {:?}; rounds {:?}",
            fit.values,
            &truth[1..],
            fit.rounds
        );
        assert!(mean(&fit.after) > mean(&fit.before) + 0.01, "{fit:?}");
        // The width is what the closure holds: the fitted model's body is 1.0 wide.
        let b = fit.model.parts[0].bounds.extent();
        assert!((b.x - width).abs() < 1e-12);
        for (p, v) in params.iter().zip(&fit.values) {
            assert!((p.min..=p.max).contains(v));
        }
    }

    #[test]
    fn bad_requests_are_named() {
        let t = ScoreTarget::new(agentstar_render::BitMask::new(8, 8), None).expect("t");
        let camera = PinholeCamera::new(8.0, 8.0, 4.0, 4.0, 8, 8).expect("camera");
        let frames = [ShapeFrame {
            name: "a".into(),
            camera,
            target: &t,
            pose: GenPose {
                pose: ObjectPose::identity(),
                states: vec![],
            },
        }];
        let build = |v: &[f64]| model(&[1.0, v[0], 0.3]);
        let p = |start: f64| ShapeParam {
            name: "depth".into(),
            start,
            min: 0.4,
            max: 0.8,
        };
        let cfg = ShapeFitConfig::default();
        let e = fit_shape(&build, &[], &frames, 0.2, &cfg).expect_err("none");
        assert!(e.to_string().contains("at least one parameter"));
        let e = fit_shape(&build, &[p(0.9)], &frames, 0.2, &cfg).expect_err("outside");
        assert!(e.to_string().contains("outside"), "{e}");
        let e = fit_shape(&build, &[p(0.5), p(0.5)], &frames, 0.2, &cfg).expect_err("twice");
        assert!(e.to_string().contains("twice"), "{e}");
    }
}
