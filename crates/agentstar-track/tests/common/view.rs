//! The tests' camera and masks: a 320×240 pinhole camera, the model's silhouette in it as a
//! target, and keyframes of such targets.

use agentstar_geom::{ObjectModel, PinholeCamera};
use agentstar_render::{PosedModel, ScoreTarget, SilhouetteRenderer};
use agentstar_track::tracker::TrackFrame;
use agentstar_track::update::GenPose;

pub fn camera() -> PinholeCamera {
    PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera")
}

/// The silhouette of `model` at `g` in [`camera`], as a target without hands.
pub fn target_of(model: &ObjectModel, g: &GenPose, scale: f64) -> ScoreTarget {
    let mut r = SilhouetteRenderer::new(320, 240);
    let m = r
        .render(
            &camera(),
            &PosedModel::new(model, &g.states, &g.pose.with_scale(scale)).instances,
        )
        .clone();
    ScoreTarget::new(m, None).expect("target")
}

/// Keyframes named by their index, seen by [`camera`] from a static camera, masks only.
pub fn frames_of(targets: &[ScoreTarget]) -> Vec<TrackFrame<'_>> {
    targets
        .iter()
        .enumerate()
        .map(|(k, t)| TrackFrame {
            name: format!("{k:06}"),
            camera: camera(),
            target: t,
            world_from_camera: None,
            rgb: None,
        })
        .collect()
}
