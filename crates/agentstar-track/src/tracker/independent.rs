//! The per-frame global baseline: every frame searched on its own (no temporal term).

use super::*;
use crate::objective::FrameProblem;
use crate::search::{sweep, SweepConfig};
use crate::space::{joint_ranges, pose_ranges, SearchSpace};
use crate::TrackError;
use agentstar_geom::{ObjectModel, UnitQuaternion};

/// The "VLM-free" baseline of the paper's ablation: every frame on its own, differential
/// evolution over the whole pose space (every rotation, the joints' full ranges, ±10% of the
/// image around the mask, ±30% in depth) from an uninformed start (identity rotation, joints
/// at rest, placed on the mask by centroid and area), then the tracker's local refinement of
/// the winner. No neighbour, no temporal pass. `evals_per_frame` bounds the global search;
/// `observe` receives each frame's log line as it is written.
pub fn track_independent(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    cfg: &TrackConfig,
    evals_per_frame: usize,
    observe: &dyn TrackObserver,
) -> Result<TrackResult, TrackError> {
    on_stand_in(model, scale, frames, cfg, &[], observe, |searched| {
        track_independent_on(searched, scale, frames, cfg, evals_per_frame, observe)
    })
}

pub(super) fn track_independent_on(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    cfg: &TrackConfig,
    evals_per_frame: usize,
    observe: &dyn TrackObserver,
) -> Result<TrackResult, TrackError> {
    let s = Searcher::new(model, scale, frames, cfg)?;
    let rest = model.tree.rest_states();
    let mut poses = Vec::with_capacity(frames.len());
    let mut scores = Vec::with_capacity(frames.len());
    let mut log = Log::new(observe);
    for (i, frame) in frames.iter().enumerate() {
        let Some(stats) = mask_stats(frame.target) else {
            return Err(TrackError::Invalid(format!(
                "frame {} has an empty object mask",
                frame.name
            )));
        };
        let (start, _) = place(
            model,
            frame,
            scale,
            UnitQuaternion::identity(),
            &rest,
            stats,
            None,
        );
        let problem = FrameProblem::new(model, frame.camera, frame.target, scale, start.clone());
        let mut ranges = pose_ranges(180.0, 0.1, 0.3);
        ranges.extend(joint_ranges(&model.tree));
        let space = SearchSpace {
            ranges,
            notes: vec![],
        };
        let r = sweep(
            &problem,
            &space,
            &SweepConfig {
                restarts: 6,
                total_evals: evals_per_frame.max(60),
                seed: cfg.seed + 7919 * i as u64,
                ..SweepConfig::default()
            }
            .scipy_stop(),
        )?;
        s.evals
            .fetch_add(r.n_evals, std::sync::atomic::Ordering::Relaxed);
        let top = r
            .ranked
            .into_iter()
            .next()
            .ok_or_else(|| TrackError::Invalid("empty search".into()))?;
        let (g, sc) = s.polish(frame, &top.pose, cfg.seed + 104_729 * (i as u64 + 1))?;
        let (g, sc) = if sc >= top.score.combined {
            (g, sc)
        } else {
            (top.pose, top.score.combined)
        };
        log.push(format!(
            "{}: independent global search, IoU {sc:.4}",
            frame.name
        ));
        poses.push(g);
        scores.push(sc);
    }
    Ok(TrackResult {
        poses,
        scores,
        init_frame: 0,
        log: log.lines,
        evaluations: s.evals.into_inner(),
        between: vec![],
        choice: None,
        refused_turns: vec![],
    })
}
