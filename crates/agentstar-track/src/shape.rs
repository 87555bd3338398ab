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
//! proportions, it does not re-track). Then a residual-guided step: with the poses held, a
//! pose's depth has absorbed the size error, so growing one axis alone may not raise the IoU
//! although the silhouettes want it (play-test 15). The frames' residuals grouped by view
//! ([`crate::proportion`]) say what size change along X, Y, Z they want beyond a common
//! scale; the parameters' effect on the model's extents is measured by building at ±a
//! small step, a bounded least-squares step is solved for, and the trial is kept only when
//! its refined poses raise the mean IoU. What no free parameter can change is reported
//! ([`UnmetAxis`]). Rounds stop when the values settle.
//!
//! The guard against the paper's failure mode (flat, silhouette-like geometry that games
//! IoU from a few views) is in what may move: only the named parameters, only within the
//! bounds the script gives them; every other part of the model is what the script says.

use crate::hypotheses::{refine_local, LocalWindow};
use crate::objective::FrameProblem;
use crate::update::GenPose;
use crate::TrackError;
use agentstar_geom::nalgebra::{DMatrix, DVector};
use agentstar_geom::{origin_shift, ObjectModel, PinholeCamera};
use agentstar_optim::{nelder_mead, NelderMeadConfig};
use agentstar_render::{PosedModel, ScoreTarget, SilhouetteRenderer};
use rayon::prelude::*;

/// The probe of a parameter's effect on the model's extents: this share of its range.
const PROBE_SHARE: f64 = 0.01;
/// A wanted size change (beyond the common scale) smaller than this is within what mask
/// boundaries say: not asked of the parameters, not reported as unmet.
const MIN_WANT: f64 = 0.01;
/// The shares of the solved step the guided step tries, in order, until one raises the IoU.
const GUIDED_SHARES: [f64; 2] = [1.0, 0.5];
/// Guided steps a round takes at most, each from the last one kept.
const GUIDED_STEPS_PER_ROUND: usize = 3;

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
    /// Try the residual-guided step in every round (off: the held-pose search alone).
    pub guided: bool,
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
            guided: true,
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
    /// The round's last residual-guided step (`None`: off).
    pub guided: Option<GuidedStep>,
}

/// A size change along one model axis (0 X, 1 Y, 2 Z) that the frames want, beyond a common
/// scale, and that no free parameter makes: `want` relative (0.017: 1.7% longer).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnmetAxis {
    pub axis: usize,
    pub want: f64,
}

/// What one residual-guided step did.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidedStep {
    /// The relative size changes along X, Y, Z the frames wanted (`None`: not measurable).
    pub wanted: [Option<f64>; 3],
    /// The values tried (the last share tried); `None` when the step was zero.
    pub values: Option<Vec<f64>>,
    /// The mean visible IoU of the trial with its poses refined.
    pub iou_refined: Option<f64>,
    /// Whether the trial was kept (it raised the mean IoU).
    pub taken: bool,
    /// What the frames want and the free parameters cannot make.
    pub unmet: Vec<UnmetAxis>,
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
    /// What the last guided step found no free parameter could make.
    pub unmet: Vec<UnmetAxis>,
    /// Per parameter (in order), how far the mean visible IoU moves when it alone is set to
    /// either end of its range, the others at their fitted values and the poses held: what
    /// the masks can say of it.
    pub iou_span: Vec<f64>,
}

/// A parameter whose whole range moves the mean visible IoU by less than this is one the
/// masks cannot set: a tenth of the gate's margin (1 − 0.98). Its fitted value is whatever the
/// search left, and the fit's reply says so (play-test 16: a band's height on a can, which
/// the outline shows only by the band's 0.004 lip, was fitted and believed).
pub const UNSEEN_IOU: f64 = 0.002;

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
    let mut unmet = vec![];
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
            let (refined, n) = refine_all(&trial_model, frames, &trial_poses, scale, cfg, round)?;
            trial_poses = refined;
            evaluations += n;
        }
        let iou_refined = mean(&frame_ious(&trial_model, frames, &trial_poses, scale));
        evaluations += 2 * frames.len();
        let start_values = values.clone();
        let mut taken = false;
        if iou_refined >= best_mean {
            best_mean = iou_refined;
            values = trial_values.clone();
            model = trial_model;
            poses = trial_poses;
            taken = true;
        }
        // (c) The step the residuals ask for, from the best so far, again from its result
        // while it raises the IoU (the refined poses absorb part of each step).
        let mut guided = None;
        for _ in 0..if cfg.guided {
            GUIDED_STEPS_PER_ROUND
        } else {
            0
        } {
            let g = guided_step(
                build,
                params,
                frames,
                scale,
                cfg,
                round,
                (&values, &model, &poses),
                best_mean,
            )?;
            builds += g.builds;
            evaluations += g.evaluations;
            unmet = g.step.unmet.clone();
            let kept = g.kept.is_some();
            if let Some((v, m, p, iou)) = g.kept {
                best_mean = iou;
                values = v;
                model = m;
                poses = p;
                taken = true;
            }
            guided = Some(g.step);
            if !kept {
                break;
            }
        }
        rounds.push(FitRound {
            values: trial_values,
            iou_held,
            iou_refined,
            builds: n_builds + 1,
            guided,
        });
        if !taken {
            break;
        }
        let moved = values
            .iter()
            .zip(&start_values)
            .zip(&spans)
            .map(|((a, b), s)| (a - b).abs() / s)
            .fold(0.0, f64::max);
        if round > 0 && moved < cfg.tolerance {
            break;
        }
    }
    let after = frame_ious(&model, frames, &poses, scale);
    let fitted_mean = mean(&after);
    let iou_span: Vec<f64> = (0..params.len())
        .map(|k| {
            [params[k].min, params[k].max]
                .iter()
                .filter_map(|&end| {
                    let mut v = values.clone();
                    v[k] = end;
                    let m = build(&v).ok()?;
                    let held = carried(&model, &m, &poses, scale, cfg.held.as_deref());
                    Some((mean(&frame_ious(&m, frames, &held, scale)) - fitted_mean).abs())
                })
                .fold(0.0, f64::max)
        })
        .collect();
    builds += 2 * params.len();
    evaluations += 2 * params.len() * frames.len();
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
        unmet,
        iou_span,
    })
}

/// Every frame's pose refined locally for `model` (seeded by the round and the frame), and
/// the evaluations spent.
fn refine_all(
    model: &ObjectModel,
    frames: &[ShapeFrame<'_>],
    poses: &[GenPose],
    scale: f64,
    cfg: &ShapeFitConfig,
    round: usize,
) -> Result<(Vec<GenPose>, usize), TrackError> {
    let refined: Vec<Result<(GenPose, usize), TrackError>> = frames
        .par_iter()
        .zip(poses)
        .enumerate()
        .map(|(k, (f, g))| {
            let p = FrameProblem::new(model, f.camera, f.target, scale, g.clone());
            let seed = cfg.seed + 7919 * round as u64 + k as u64;
            refine_local(&p, g, &cfg.window, seed).map(|(pose, _, n)| (pose, n))
        })
        .collect();
    let mut evaluations = 0;
    let poses = refined
        .into_iter()
        .map(|r| {
            r.map(|(g, n)| {
                evaluations += n;
                g
            })
        })
        .collect::<Result<_, _>>()?;
    Ok((poses, evaluations))
}

/// The relative size changes along X, Y, Z the frames want of `model` at `poses`: the
/// silhouettes' residuals against the masks over all frames ([`crate::proportion`]).
pub fn size_wants(
    model: &ObjectModel,
    frames: &[ShapeFrame<'_>],
    poses: &[GenPose],
    scale: f64,
) -> [Option<f64>; 3] {
    shape_view_residuals(model, frames, poses, scale).all.want
}

/// The silhouettes of `model` at `poses` against the frames' masks, grouped by viewing
/// direction ([`crate::proportion::view_residuals`]).
pub fn shape_view_residuals(
    model: &ObjectModel,
    frames: &[ShapeFrame<'_>],
    poses: &[GenPose],
    scale: f64,
) -> crate::proportion::ViewResiduals {
    let silhouettes: Vec<agentstar_render::BitMask> = frames
        .par_iter()
        .zip(poses)
        .map(|(f, g)| {
            let posed = PosedModel::new(model, &g.states, &g.pose.with_scale(scale));
            SilhouetteRenderer::new(f.camera.width, f.camera.height)
                .render(&f.camera, &posed.instances)
                .clone()
        })
        .collect();
    let views: Vec<crate::proportion::ViewFrame<'_>> = frames
        .iter()
        .zip(poses)
        .zip(&silhouettes)
        .map(|((f, g), sil)| {
            let bounds = model.posed_bounds(&g.states);
            crate::proportion::ViewFrame {
                name: f.name.clone(),
                camera: f.camera,
                mask: f.target.mask(),
                keep: f.target.keep(),
                silhouette: sil,
                camera_from_object: g.pose.with_scale(scale),
                centre: bounds.center(),
                size: bounds.extent(),
            }
        })
        .collect();
    crate::proportion::view_residuals(&views)
}

/// How each parameter changes the model's extents along X, Y, Z, relative to them, per unit
/// of the parameter (central differences of [`PROBE_SHARE`] of its range, one-sided at a
/// bound; at the first frame's joint states). `None` for a parameter whose probes do not
/// build. Also the builds spent.
fn extent_jacobian(
    build: &ModelBuilder<'_>,
    params: &[ShapeParam],
    values: &[f64],
    states: &[f64],
) -> (Vec<Option<[f64; 3]>>, usize) {
    let extent = |v: &[f64]| build(v).ok().map(|m| m.posed_bounds(states).extent());
    let Some(base) = extent(values) else {
        return (vec![None; params.len()], 1);
    };
    let columns = params
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let h = PROBE_SHARE * (p.max - p.min);
            let (lo, hi) = ((values[i] - h).max(p.min), (values[i] + h).min(p.max));
            let at = |x: f64| {
                let mut v = values.to_vec();
                v[i] = x;
                extent(&v)
            };
            let (a, b) = (at(lo)?, at(hi)?);
            let mut col = [0.0; 3];
            for axis in 0..3 {
                if base[axis] > 1e-12 {
                    col[axis] = (b[axis] - a[axis]) / ((hi - lo) * base[axis]);
                }
            }
            Some(col)
        })
        .collect();
    (columns, 1 + 2 * params.len())
}

/// A guided step and what it cost; `kept` holds the values, model, refined poses and mean
/// IoU when it raised the IoU over `best_mean`.
struct Guided {
    step: GuidedStep,
    kept: Option<(Vec<f64>, ObjectModel, Vec<GenPose>, f64)>,
    builds: usize,
    evaluations: usize,
}

/// The parameter change whose extent change best gives the sizes `wanted` (relative, along
/// X, Y, Z) up to a common scale, by least squares over the measured axes, clamped to the
/// bounds; and the wanted changes left unmet beyond [`MIN_WANT`]. Where some are unmet and
/// more than two axes are measured, the step is solved again without one of the unmet axes
/// that no parameter changes, so that a change no parameter makes does not pull the common scale, and with it the
/// parameters, away from what the other axes say. Which one: the axis whose leaving out
/// needs the smallest change of the parameters (relative to their ranges), the first axis on
/// a tie — of two explanations the frames cannot tell apart, the one that keeps the model as
/// it is.
fn solve_step(
    params: &[ShapeParam],
    values: &[f64],
    jacobian: &[Option<[f64; 3]>],
    wanted: [Option<f64>; 3],
) -> (Vec<f64>, Vec<UnmetAxis>) {
    let axes: Vec<usize> = (0..3).filter(|&b| wanted[b].is_some()).collect();
    if axes.len() < 2 {
        return (vec![0.0; params.len()], vec![]);
    }
    let step = solve_over(params, values, jacobian, wanted, &axes);
    let unmet = unmet_after(params, jacobian, wanted, &axes, &step);
    if axes.len() <= 2 || unmet.is_empty() {
        return (step, unmet);
    }
    let size = |step: &[f64]| -> f64 {
        step.iter()
            .zip(params)
            .map(|(d, p)| (d / (p.max - p.min).max(1e-12)).powi(2))
            .sum()
    };
    let mut best: Option<(f64, Vec<f64>)> = None;
    // Only an axis no parameter changes can be left out: one a parameter does change is
    // unmet because a bound stopped it, and the step must still go as far as it can.
    let untouched = |b: usize| jacobian.iter().flatten().all(|c| c[b].abs() <= 1e-9);
    for u in unmet.iter().filter(|u| untouched(u.axis)) {
        let rest: Vec<usize> = axes.iter().copied().filter(|&b| b != u.axis).collect();
        let candidate = solve_over(params, values, jacobian, wanted, &rest);
        let cost = size(&candidate);
        if best.as_ref().is_none_or(|(c, _)| cost < *c - 1e-12) {
            best = Some((cost, candidate));
        }
    }
    (best.map_or(step, |(_, s)| s), unmet)
}

/// The least-squares step over the measured axes `axes` (at least two), clamped.
fn solve_over(
    params: &[ShapeParam],
    values: &[f64],
    jacobian: &[Option<[f64; 3]>],
    wanted: [Option<f64>; 3],
    axes: &[usize],
) -> Vec<f64> {
    let mut step = vec![0.0; params.len()];
    let free: Vec<usize> = (0..params.len())
        .filter(|&i| jacobian[i].is_some_and(|c| axes.iter().any(|&b| c[b].abs() > 1e-9)))
        .collect();
    // Columns: each free parameter in units of its range (so the solve's minimum norm
    // weighs them alike), then the common scale.
    let a = DMatrix::from_fn(axes.len(), free.len() + 1, |r, c| {
        if c < free.len() {
            let i = free[c];
            jacobian[i].map_or(0.0, |j| j[axes[r]]) * (params[i].max - params[i].min)
        } else {
            1.0
        }
    });
    let b = DVector::from_fn(axes.len(), |r, _| wanted[axes[r]].unwrap_or(0.0));
    if let Ok(x) = a.svd(true, true).solve(&b, 1e-9) {
        for (c, &i) in free.iter().enumerate() {
            let p = &params[i];
            let target = values[i] + x[c] * (p.max - p.min);
            if target.is_finite() {
                step[i] = target.clamp(p.min, p.max) - values[i];
            }
        }
    }
    step
}

/// What `step` leaves of each wanted change along `axes`, the common scale fitted again,
/// where it is at least [`MIN_WANT`].
fn unmet_after(
    params: &[ShapeParam],
    jacobian: &[Option<[f64; 3]>],
    wanted: [Option<f64>; 3],
    axes: &[usize],
    step: &[f64],
) -> Vec<UnmetAxis> {
    let left = |b: usize| -> f64 {
        wanted[b].unwrap_or(0.0)
            - (0..params.len())
                .map(|i| jacobian[i].map_or(0.0, |j| j[b]) * step[i])
                .sum::<f64>()
    };
    let common = axes.iter().map(|&b| left(b)).sum::<f64>() / axes.len() as f64;
    axes.iter()
        .map(|&b| UnmetAxis {
            axis: b,
            want: left(b) - common,
        })
        .filter(|u| u.want.abs() >= MIN_WANT)
        .collect()
}

/// The residual-guided step from `at` (values, model, poses): what the frames want, the
/// parameter change that makes it, and that trial with its poses refined, kept when its mean
/// IoU rises over `best_mean` (a full step, then a half).
#[allow(clippy::too_many_arguments)]
fn guided_step(
    build: &ModelBuilder<'_>,
    params: &[ShapeParam],
    frames: &[ShapeFrame<'_>],
    scale: f64,
    cfg: &ShapeFitConfig,
    round: usize,
    at: (&[f64], &ObjectModel, &[GenPose]),
    best_mean: f64,
) -> Result<Guided, TrackError> {
    let (values, model, poses) = at;
    let wanted = size_wants(model, frames, poses, scale);
    let states = poses.first().map(|g| g.states.clone()).unwrap_or_default();
    let (jacobian, mut builds) = extent_jacobian(build, params, values, &states);
    let (step, unmet) = solve_step(params, values, &jacobian, wanted);
    let mut evaluations = frames.len();
    let mut out = GuidedStep {
        wanted,
        values: None,
        iou_refined: None,
        taken: false,
        unmet,
    };
    let spans = params.iter().map(|p| p.max - p.min);
    let largest = step
        .iter()
        .zip(spans)
        .map(|(d, s)| d.abs() / s)
        .fold(0.0, f64::max);
    if largest < 1e-6 {
        return Ok(Guided {
            step: out,
            kept: None,
            builds,
            evaluations,
        });
    }
    for share in GUIDED_SHARES {
        let trial: Vec<f64> = values
            .iter()
            .zip(&step)
            .zip(params)
            .map(|((v, d), p)| (v + share * d).clamp(p.min, p.max))
            .collect();
        builds += 1;
        let Ok(trial_model) = build(&trial) else {
            continue;
        };
        let mut trial_poses = carried(model, &trial_model, poses, scale, cfg.held.as_deref());
        if cfg.refine_poses {
            let (refined, n) = refine_all(&trial_model, frames, &trial_poses, scale, cfg, round)?;
            trial_poses = refined;
            evaluations += n;
        }
        let iou = mean(&frame_ious(&trial_model, frames, &trial_poses, scale));
        evaluations += frames.len();
        out.values = Some(trial.clone());
        out.iou_refined = Some(iou);
        if iou > best_mean {
            out.taken = true;
            return Ok(Guided {
                step: out,
                kept: Some((trial, trial_model, trial_poses, iou)),
                builds,
                evaluations,
            });
        }
    }
    Ok(Guided {
        step: out,
        kept: None,
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

    /// The six views (roll, pitch, yaw in radians) the fits below see their object from.
    const VIEWS: [(f64, f64, f64); 6] = [
        (0.3, 0.2, 0.4),
        (-0.5, 0.1, 1.2),
        (0.9, -0.3, -0.6),
        (0.2, 0.7, 2.4),
        (-1.1, 0.4, 0.2),
        (0.6, -0.8, -1.9),
    ];

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
        let targets: Vec<ScoreTarget> = VIEWS
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
        let frames: Vec<ShapeFrame<'_>> = VIEWS
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
    fn a_size_the_held_poses_absorbed_is_found_by_the_residual_guided_step() {
        // The truth is 1.04 × 0.6 × 0.4; the model 1.0 × 0.6 × 0.4, its length along X free
        // on [0.9, 1.15]. The poses were tracked on the short model: each frame's depth and
        // place have absorbed what they could of the missing length (the turns are right).
        let slab = |x: f64| -> Result<ObjectModel, String> {
            let body = cuboid(x, 0.6, 0.4).map_err(|e| e.to_string())?;
            Ok(ObjectModel {
                tree: KinematicTree::rigid(1),
                parts: vec![Part::new("body", body, [0.5; 3])],
            })
        };
        let (true_x, start_x) = (1.04, 1.0);
        let truth = slab(true_x).expect("truth");
        let camera = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
        let scale = 0.2;
        let true_poses: Vec<GenPose> = VIEWS
            .iter()
            .map(|&(r, p, y)| GenPose {
                pose: ObjectPose::new(
                    UnitQuaternion::from_euler_angles(r, p, y),
                    Vector3::new(0.0, 0.0, 0.6),
                ),
                states: vec![],
            })
            .collect();
        let targets: Vec<ScoreTarget> = true_poses
            .iter()
            .map(|g| {
                let posed = PosedModel::new(&truth, &[], &g.pose.with_scale(scale));
                let mask = SilhouetteRenderer::new(320, 240)
                    .render(&camera, &posed.instances)
                    .clone();
                ScoreTarget::new(mask, None).expect("target")
            })
            .collect();
        let short = slab(start_x).expect("short");
        let window = LocalWindow {
            angle_deg: 0.2,
            shift: 0.03,
            depth: 0.1,
            joint_deg: 0.0,
            evals: 800,
        };
        let frames: Vec<ShapeFrame<'_>> = true_poses
            .iter()
            .zip(&targets)
            .enumerate()
            .map(|(k, (g, t))| {
                let p = FrameProblem::new(&short, camera, t, scale, g.clone());
                let (tracked, _, _) = refine_local(&p, g, &window, 5 + k as u64).expect("track");
                ShapeFrame {
                    name: format!("{k:06}.png"),
                    camera,
                    target: t,
                    pose: tracked,
                }
            })
            .collect();
        let build = |v: &[f64]| slab(v[0]);
        let params = [ShapeParam {
            name: "length_x".into(),
            start: start_x,
            min: 0.9,
            max: 1.15,
        }];
        let fit = |guided: bool| {
            let cfg = ShapeFitConfig {
                guided,
                ..ShapeFitConfig::default()
            };
            fit_shape(&build, &params, &frames, scale, &cfg).expect("fit")
        };
        // The frames want X longer than Y and Z.
        let wants = size_wants(
            &short,
            &frames,
            &frames.iter().map(|f| f.pose.clone()).collect::<Vec<_>>(),
            scale,
        );
        let (x, y, z) = (
            wants[0].expect("x"),
            wants[1].expect("y"),
            wants[2].expect("z"),
        );
        assert!(x > y + 0.005 && x > z + 0.005, "{wants:?}");
        let held_only = fit(false);
        let guided = fit(true);
        // The held-pose search alone stays where it started.
        assert!(
            (held_only.values[0] - start_x).abs() < 0.005,
            "{:?}",
            held_only.rounds
        );
        // The guided step goes most of the way to the truth, and the fit is better for it.
        assert!(
            (guided.values[0] - true_x).abs() < 0.5 * (true_x - start_x),
            "{:?}",
            guided.rounds
        );
        assert!(mean(&guided.after) > mean(&held_only.after), "{guided:?}");
        assert!(guided.rounds[0]
            .guided
            .as_ref()
            .is_some_and(|g| g.wanted[0].is_some()));
        assert!(guided.unmet.is_empty(), "{:?}", guided.unmet);
    }

    #[test]
    fn a_wanted_size_no_parameter_makes_is_named() {
        // Only the height (Z) is free: relative 1/0.4 of Z's extent per unit.
        let params = [ShapeParam {
            name: "height".into(),
            start: 0.4,
            min: 0.3,
            max: 0.5,
        }];
        let jacobian = [Some([0.0, 0.0, 1.0 / 0.4])];
        // X and Y want 3% more than Z: Z shrinks by 3% (0.012), nothing is left unmet.
        let (step, unmet) = solve_step(
            &params,
            &[0.4],
            &jacobian,
            [Some(0.03), Some(0.03), Some(0.0)],
        );
        assert!((step[0] + 0.012).abs() < 1e-9, "{step:?}");
        assert!(unmet.is_empty(), "{unmet:?}");
        // X wants 3% more than Y, Z unmeasured: no free parameter changes X against Y. The
        // common scale takes half, and the rest is named on both axes.
        let (step, unmet) = solve_step(&params, &[0.4], &jacobian, [Some(0.03), Some(0.0), None]);
        assert_eq!(step, vec![0.0]);
        let named: Vec<(usize, f64)> = unmet.iter().map(|u| (u.axis, u.want)).collect();
        assert_eq!(named.len(), 2, "{named:?}");
        assert!(
            (named[0].1 - 0.015).abs() < 1e-9 && named[0].0 == 0,
            "{named:?}"
        );
        assert!(
            (named[1].1 + 0.015).abs() < 1e-9 && named[1].0 == 1,
            "{named:?}"
        );
        // One measured axis says nothing beyond the scale.
        let (step, unmet) = solve_step(&params, &[0.4], &jacobian, [None, None, Some(-0.2)]);
        assert_eq!(step, vec![0.0]);
        assert!(unmet.is_empty());
        // X wants 8% more than Y and Z, which agree: X is unmet, and the height is not
        // pulled by it (the step is solved again over Y and Z).
        let (step, unmet) = solve_step(
            &params,
            &[0.4],
            &jacobian,
            [Some(0.08), Some(0.0), Some(0.0)],
        );
        assert!(step[0].abs() < 1e-9, "{step:?}");
        assert_eq!(unmet.first().map(|u| u.axis), Some(0), "{unmet:?}");
        // A step past a bound is clamped to it.
        let (step, _) = solve_step(
            &params,
            &[0.4],
            &jacobian,
            [Some(0.5), Some(0.5), Some(0.0)],
        );
        assert!((step[0] + 0.1).abs() < 1e-9, "{step:?}");
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
