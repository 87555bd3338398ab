//! One sequence tracked by one method and evaluated with the paper's metrics.

use crate::misses::{misses, Misses};
use crate::BenchError;
use agentstar_data::gt::{model_ground_truth, GroundTruth};
use agentstar_eval::sequence::{evaluate, EvalConfig, GtSequence, PredSequence, SequenceMetrics};
use agentstar_eval::{gauge_aligned_errors, MetricsRecord};
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::UnitQuaternion;
use agentstar_render::ScoreTarget;
use agentstar_synth::SynthCapture;
use agentstar_track::tracker::{
    track_independent, track_video, TrackConfig, TrackFrame, TrackSwitches,
};
use agentstar_track::GenPose;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// How the poses are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Method {
    /// The automatic tracker with its temporal consistency pass.
    #[serde(rename = "tracker")]
    Tracker,
    /// The tracker without the consistency pass (the paper's "no temporal").
    #[serde(rename = "no-temporal")]
    NoTemporal,
    /// Per-frame differential evolution over the whole pose space from an uninformed start,
    /// with the known model (the paper's "GT mesh + VLM-free opt.").
    #[serde(rename = "vlm-free")]
    VlmFree,
}

impl Method {
    pub const ALL: [Method; 3] = [Method::Tracker, Method::NoTemporal, Method::VlmFree];
    pub fn as_str(&self) -> &'static str {
        match self {
            Method::Tracker => "tracker",
            Method::NoTemporal => "no-temporal",
            Method::VlmFree => "vlm-free",
        }
    }
    pub fn parse(s: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.as_str() == s)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct RunConfig {
    pub seed: u64,
    /// Evaluations of each local search of the tracker.
    pub local_evals: usize,
    /// Evaluations of the VLM-free baseline's global search, per frame.
    pub vlm_free_evals: usize,
    /// Surface samples per mesh for Chamfer distances.
    pub samples: usize,
    /// The tracker ends with the sequence-level choice ([`TrackConfig::sequence_choice`]).
    pub sequence_choice: bool,
    /// The tracker sees the frames' colours (the appearance term); off: masks alone.
    pub appearance: bool,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            seed: 17,
            local_evals: 2400,
            vlm_free_evals: 8000,
            samples: 10_000,
            sequence_choice: true,
            appearance: true,
        }
    }
}

/// Everything measured on one sequence with one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SequenceResult {
    /// What the result is about (its fields stand at the top level of the JSON).
    #[serde(flatten)]
    pub info: RunInfo,
    pub iou_mean: f64,
    pub iou_min: f64,
    /// The paper's metrics (the record `eval` prints and `batch gather` tables).
    #[serde(flatten)]
    pub metrics: MetricsRecord,
    /// The errors reduced by the object's listed symmetries (HOT3D/BOP): per frame, the
    /// ground truth is replaced by its symmetric equivalent nearest the prediction. `None`
    /// when the object lists no symmetry (then the reduced errors are the raw ones).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub symmetry_reduced: Option<ReducedErrors>,
    /// How hard the capture is: object rotation between keyframes and hand coverage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub capture_stats: Option<CaptureStats>,
    /// The keyframes more than [`crate::misses::MISS_DEG`] off (after the symmetries), and
    /// which evidence preferred the truth there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub misses: Option<Misses>,
}

/// Errors after symmetry reduction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReducedErrors {
    /// The symmetries considered (rotations of the base part's frame, identity excluded).
    pub symmetries: usize,
    pub epe_cm: Option<f64>,
    pub rotation_mean_deg: Option<f64>,
    pub rotation_median_deg: Option<f64>,
    pub translation_mean_cm: Option<f64>,
    pub translation_median_cm: Option<f64>,
}

/// Figures of a synthetic capture's difficulty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureStats {
    /// Object rotation in the world between consecutive keyframes, degrees.
    pub step_mean_deg: f64,
    pub step_max_deg: f64,
    /// The largest fraction of the object's silhouette hidden by hands in a keyframe.
    pub hand_coverage_max: f64,
    pub width: u32,
    pub height: u32,
}

/// What a result is about, beside its metrics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    pub id: String,
    pub object: String,
    pub family: String,
    pub motion: String,
    /// The method's name (`tracker`, `no-temporal`, `vlm-free`) or a label for a user's runs.
    pub method: String,
    /// Wall time of the tracking (not the synthesis or the evaluation), seconds.
    pub seconds: f64,
    pub evaluations: usize,
}

impl SequenceResult {
    /// A result from a sequence's metrics and per-frame gate IoUs.
    pub fn from_metrics(
        info: RunInfo,
        iou: &[f64],
        m: &SequenceMetrics,
        seq: &GtSequence,
    ) -> SequenceResult {
        let mut metrics = MetricsRecord::from(m);
        for (j, g) in metrics.joints.iter_mut().zip(&seq.joints) {
            j.revolute = g.revolute;
        }
        SequenceResult {
            info,
            iou_mean: iou.iter().sum::<f64>() / iou.len().max(1) as f64,
            iou_min: iou.iter().cloned().fold(f64::INFINITY, f64::min),
            metrics,
            symmetry_reduced: None,
            capture_stats: None,
            misses: None,
        }
    }

    /// A named figure, for tolerances and tables.
    pub fn metric(&self, name: &str) -> Option<f64> {
        let m = &self.metrics;
        match name {
            "iou_mean" => Some(self.iou_mean),
            "iou_min" => Some(self.iou_min),
            "epe_cm" => m.epe_cm,
            "chamfer_cm" => m.chamfer_cm,
            "rotation_mean_deg" => m.rotation_mean_deg,
            "rotation_median_deg" => m.rotation_median_deg,
            "translation_mean_cm" => m.translation_mean_cm,
            "translation_median_cm" => m.translation_median_cm,
            "cd_w_m2" => m.cd_w_m2,
            "cd_m_m2" => m.cd_m_m2,
            "cd_s_m2" => m.cd_s_m2,
            "joint_axis_rad" => m.joint_mean(|j| j.axis_angle_rad),
            "joint_state" => m.joint_mean(|j| j.state_error),
            "sym_epe_cm" => self
                .symmetry_reduced
                .as_ref()
                .map_or(m.epe_cm, |r| r.epe_cm),
            "sym_rotation_mean_deg" => self
                .symmetry_reduced
                .as_ref()
                .map_or(m.rotation_mean_deg, |r| r.rotation_mean_deg),
            "sym_rotation_median_deg" => self
                .symmetry_reduced
                .as_ref()
                .map_or(m.rotation_median_deg, |r| r.rotation_median_deg),
            _ => None,
        }
    }
}

/// Tracks a synthetic capture with `method` (the known model and scale, as the paper's
/// agent-free variants) and evaluates the result against its ground truth.
pub fn run_sequence(
    capture: &SynthCapture,
    method: Method,
    cfg: &RunConfig,
) -> Result<(SequenceResult, Vec<GenPose>), BenchError> {
    run_sequence_observed(capture, method, cfg, &|_| {})
}

/// [`run_sequence`], handing each line of the tracker's log to `observe` as it is written.
pub fn run_sequence_observed(
    capture: &SynthCapture,
    method: Method,
    cfg: &RunConfig,
    observe: &(dyn Fn(&str) + Sync),
) -> Result<(SequenceResult, Vec<GenPose>), BenchError> {
    let id = capture.id();
    let targets: Vec<ScoreTarget> = capture
        .frames
        .iter()
        .map(|f| ScoreTarget::new(f.mask.clone(), f.hand.clone()))
        .collect::<Result<_, _>>()
        .map_err(|e| BenchError::Invalid(format!("{id}: {e}")))?;
    // Track the cameras as the written capture stores them, so the figures are what
    // `agentstar track` gets from the files.
    let frames: Vec<TrackFrame<'_>> = capture
        .frames
        .iter()
        .zip(&targets)
        .map(|(f, t)| {
            let (camera, world_from_camera) =
                agentstar_data::capture_writer::as_stored(&capture.camera, &f.world_from_camera)
                    .map_err(|e| BenchError::Invalid(format!("{id}: {e}")))?;
            Ok(TrackFrame {
                name: f.name.clone(),
                camera,
                target: t,
                world_from_camera: Some(world_from_camera),
                rgb: cfg.appearance.then(|| f.rgb.as_raw().as_slice()),
            })
        })
        .collect::<Result<_, BenchError>>()?;
    // The in-between frames, gap by gap (gap g: between keyframes g and g + 1), as the
    // tracker follows them.
    let between_targets: Vec<ScoreTarget> = capture
        .between
        .iter()
        .map(|f| ScoreTarget::new(f.mask.clone(), f.hand.clone()))
        .collect::<Result<_, _>>()
        .map_err(|e| BenchError::Invalid(format!("{id}: {e}")))?;
    let mut between: Vec<Vec<TrackFrame<'_>>> =
        vec![Vec::new(); capture.frames.len().saturating_sub(1)];
    for (f, t) in capture.between.iter().zip(&between_targets) {
        let Some(g) = capture
            .frames
            .windows(2)
            .position(|w| w[0].frame_index < f.frame_index && f.frame_index < w[1].frame_index)
        else {
            continue;
        };
        let (camera, world_from_camera) =
            agentstar_data::capture_writer::as_stored(&capture.camera, &f.world_from_camera)
                .map_err(|e| BenchError::Invalid(format!("{id}: {e}")))?;
        between[g].push(TrackFrame {
            name: f.name.clone(),
            camera,
            target: t,
            world_from_camera: Some(world_from_camera),
            rgb: cfg.appearance.then(|| f.rgb.as_raw().as_slice()),
        });
    }
    let tcfg = TrackConfig::from(TrackSwitches {
        seed: cfg.seed,
        local_evals: cfg.local_evals,
        temporal: method == Method::Tracker,
        sequence_choice: cfg.sequence_choice,
        appearance: cfg.appearance,
    });
    let t0 = Instant::now();
    let tracked = match method {
        Method::Tracker | Method::NoTemporal => track_video(
            &capture.model,
            capture.scale,
            &frames,
            &between,
            &tcfg,
            &|l: &str| observe(l),
        ),
        Method::VlmFree => track_independent(
            &capture.model,
            capture.scale,
            &frames,
            &tcfg,
            cfg.vlm_free_evals,
            &|l: &str| observe(l),
        ),
    }
    .map_err(|source| BenchError::Track {
        id: id.clone(),
        source,
    })?;
    let seconds = t0.elapsed().as_secs_f64();

    let truth: Vec<_> = capture
        .frames
        .iter()
        .map(|f| (f.name.clone(), f.camera_from_object, f.states.clone()))
        .collect();
    let pred = PredSequence {
        model: &capture.model,
        scale: capture.scale,
        poses: tracked.poses.clone(),
    };
    let (m, seq) = evaluate_against(capture, &truth, &pred, cfg)?;
    let reduced = symmetry_reduced_truth(&truth, &pred.poses, &capture.symmetries);
    let misses = misses(
        capture,
        &frames.iter().map(|f| f.camera).collect::<Vec<_>>(),
        &targets,
        &reduced
            .iter()
            .map(|(_, pose, states)| GenPose {
                pose: *pose,
                states: states.clone(),
            })
            .collect::<Vec<_>>(),
        &pred.poses,
        tracked.choice.as_ref(),
    );
    let symmetry_reduced = if capture.symmetries.is_empty() {
        None
    } else {
        let (r, _) = evaluate_against(capture, &reduced, &pred, cfg)?;
        Some(ReducedErrors {
            symmetries: capture.symmetries.len(),
            epe_cm: r.epe_cm,
            rotation_mean_deg: r.rigid.as_ref().map(|g| g.rotation_mean_deg),
            rotation_median_deg: r.rigid.as_ref().map(|g| g.rotation_median_deg),
            translation_mean_cm: r.rigid.as_ref().map(|g| g.translation_mean_cm),
            translation_median_cm: r.rigid.as_ref().map(|g| g.translation_median_cm),
        })
    };
    let result = SequenceResult::from_metrics(
        RunInfo {
            id,
            object: capture.object.name.to_string(),
            family: capture.object.family.as_str().into(),
            motion: capture.motion.as_str().into(),
            method: method.as_str().into(),
            seconds,
            evaluations: tracked.evaluations,
        },
        &tracked.scores,
        &m,
        &seq,
    );
    let steps = capture.step_angles_deg();
    let result = SequenceResult {
        symmetry_reduced,
        capture_stats: Some(CaptureStats {
            step_mean_deg: steps.iter().sum::<f64>() / steps.len().max(1) as f64,
            step_max_deg: steps.iter().cloned().fold(0.0, f64::max),
            hand_coverage_max: capture
                .frames
                .iter()
                .map(|f| f.hand_coverage)
                .fold(0.0, f64::max),
            width: capture.camera.width,
            height: capture.camera.height,
        }),
        misses: Some(misses),
        ..result
    };
    Ok((result, tracked.poses))
}

type Truth = Vec<(String, ObjectPose, Vec<f64>)>;

/// The ground truth `truth` of a capture in the evaluator's form, and the metrics of `pred`
/// against it.
fn evaluate_against(
    capture: &SynthCapture,
    truth: &Truth,
    pred: &PredSequence<'_>,
    cfg: &RunConfig,
) -> Result<(SequenceMetrics, GtSequence), BenchError> {
    let id = capture.id();
    let (file, meshes) =
        model_ground_truth(&capture.model, capture.scale, truth, &capture.symmetries);
    let gt = GroundTruth::from_parts(
        std::path::Path::new(&format!("synthetic:{id}/gt.json")),
        file,
        meshes,
    );
    let names: Vec<String> = truth.iter().map(|t| t.0.clone()).collect();
    let seq = gt
        .sequence(&names)
        .map_err(|e| BenchError::GroundTruth(e.to_string()))?;
    let cams = vec![capture.camera; capture.frames.len()];
    let m = evaluate(
        &seq,
        pred,
        &cams,
        &EvalConfig {
            samples: cfg.samples,
            ..EvalConfig::default()
        },
    );
    Ok((m, seq))
}

/// The ground truth reduced by `symmetries` (rotations of the object's canonical frame about
/// its origin that map it onto itself, in shape and appearance): per frame, the equivalent
/// true pose `R·S` (the HOT3D/BOP convention), chosen together with the one gauge per
/// trajectory the errors are measured after (`R_gt·S ≈ R·G`, [`gauge_aligned_errors`]): the
/// symmetric truths and the gauge that fit the prediction best, by alternating the two
/// (each frame's nearest `R·S` to `R·G`, then the gauge of those) from two starts, no gauge
/// and the gauge of the unreduced truth, the lower mean rotation error kept. Chosen before
/// the gauge, a frame whose prediction sits about as far from two symmetric truths picks
/// either, and the gauge of a mixed choice fits none of them.
pub fn symmetry_reduced_truth(
    truth: &[(String, ObjectPose, Vec<f64>)],
    pred: &[GenPose],
    symmetries: &[UnitQuaternion],
) -> Truth {
    let group: Vec<UnitQuaternion> = std::iter::once(UnitQuaternion::identity())
        .chain(symmetries.iter().copied())
        .collect();
    let predicted: Vec<ObjectPose> = pred.iter().map(|p| p.pose).collect();
    let reduced = |picks: &[usize]| -> Vec<ObjectPose> {
        truth
            .iter()
            .zip(picks)
            .map(|((_, gt, _), &k)| ObjectPose::new(gt.rotation * group[k], gt.translation))
            .collect()
    };
    // The gauge of a choice and its mean rotation error (rotations only: scale and depth
    // do not enter them).
    let gauge_of = |picks: &[usize]| -> (f64, UnitQuaternion) {
        gauge_aligned_errors(&reduced(picks), &predicted, 1.0, 1.0)
            .map_or((f64::INFINITY, UnitQuaternion::identity()), |e| {
                (e.rotation_mean_deg, e.gauge_rotation)
            })
    };
    let picks_for = |gauge: &UnitQuaternion| -> Vec<usize> {
        truth
            .iter()
            .zip(&predicted)
            .map(|((_, gt, _), p)| {
                let target = p.rotation * gauge;
                (0..group.len())
                    .min_by(|&a, &b| {
                        (gt.rotation * group[a])
                            .angle_to(&target)
                            .total_cmp(&(gt.rotation * group[b]).angle_to(&target))
                    })
                    .unwrap_or(0)
            })
            .collect()
    };
    let unreduced = vec![0; truth.len()];
    let mut best: Option<(f64, Vec<usize>)> = None;
    for start in [UnitQuaternion::identity(), gauge_of(&unreduced).1] {
        let mut picks = picks_for(&start);
        for _ in 0..8 {
            let next = picks_for(&gauge_of(&picks).1);
            if next == picks {
                break;
            }
            picks = next;
        }
        let (cost, _) = gauge_of(&picks);
        if best.as_ref().is_none_or(|(b, _)| cost < *b - 1e-9) {
            best = Some((cost, picks));
        }
    }
    let picks = best.map_or(unreduced, |(_, p)| p);
    truth
        .iter()
        .zip(reduced(&picks))
        .map(|((name, _, states), pose)| (name.clone(), pose, states.clone()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::Vector3;

    /// Ten true rotations, a two-fold symmetry about Z, and a prediction in a canonical frame
    /// turned a quarter about Z from the truth's (as far from one symmetric truth as from the
    /// other), with a degree or two of noise per frame.
    #[test]
    fn the_symmetric_truth_is_chosen_with_the_gauge_not_before_it() {
        let half = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
        let quarter =
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        let truth: Truth = (0..10)
            .map(|k| {
                let t = k as f64;
                let r = UnitQuaternion::from_euler_angles(0.3 * t, -0.2 * t + 0.1, 0.7 * t);
                (
                    format!("{k:06}"),
                    ObjectPose::new(r, Vector3::new(0.0, 0.0, 0.5)),
                    vec![],
                )
            })
            .collect();
        let noisy = |k: usize, offset: UnitQuaternion| -> GenPose {
            let t = k as f64;
            let noise = UnitQuaternion::from_euler_angles(
                (1.5 * (1.3 * t).sin()).to_radians(),
                (1.5 * (0.7 * t).cos()).to_radians(),
                (2.0 * (2.1 * t).sin()).to_radians(),
            );
            GenPose {
                pose: ObjectPose::new(truth[k].1.rotation * offset * noise, truth[k].1.translation),
                states: vec![],
            }
        };
        let error = |reduced: &Truth, pred: &[GenPose]| -> f64 {
            let gt: Vec<ObjectPose> = reduced.iter().map(|t| t.1).collect();
            let p: Vec<ObjectPose> = pred.iter().map(|g| g.pose).collect();
            gauge_aligned_errors(&gt, &p, 1.0, 1.0)
                .expect("errors")
                .rotation_mean_deg
        };
        // A quarter turn off: every frame's nearest symmetric truth before the gauge is a
        // toss-up; with the gauge, one choice for all and the noise left.
        let pred: Vec<GenPose> = (0..10).map(|k| noisy(k, quarter)).collect();
        let reduced = symmetry_reduced_truth(&truth, &pred, &[half]);
        let picked: Vec<bool> = reduced
            .iter()
            .zip(&truth)
            .map(|(r, t)| r.1.rotation.angle_to(&t.1.rotation) > 1.0)
            .collect();
        assert!(
            picked.iter().all(|&p| p == picked[0]),
            "one symmetric truth for every frame: {picked:?}"
        );
        let e = error(&reduced, &pred);
        assert!(e < 3.0, "{e:.2}° after reduction");
        // The prediction in the other symmetric truth in half the frames: each is reduced
        // to its own.
        let pred: Vec<GenPose> = (0..10)
            .map(|k| {
                noisy(
                    k,
                    if k % 2 == 0 {
                        UnitQuaternion::identity()
                    } else {
                        half
                    },
                )
            })
            .collect();
        let reduced = symmetry_reduced_truth(&truth, &pred, &[half]);
        let e = error(&reduced, &pred);
        assert!(e < 3.0, "{e:.2}° after reduction");
        // Without symmetries the truth stays as it is.
        let reduced = symmetry_reduced_truth(&truth, &pred, &[]);
        assert!(reduced.iter().zip(&truth).all(|(r, t)| r.1 == t.1));
    }
}
