//! Evaluation with the paper's metrics (`formats.md` §5): monocular scale alignment by the
//! median log depth ratio, Chamfer distance between surface samples, rigid pose errors after
//! one Sim(3) gauge per trajectory (HOT3D protocol), articulation errors (iTACO protocol)
//! and end-point errors of carried surface points (ARCTIC protocol). Pure computation: the
//! callers render, read files and match joints.

pub mod articulation;
pub mod chamfer;
pub mod rigid;
pub mod scale;
pub mod sequence;

pub use articulation::{axis_angle_error, axis_line_distance, state_error};
pub use chamfer::{chamfer_distance, sample_surface};
pub use rigid::{gauge_aligned_errors, GaugeErrors};
pub use scale::median_log_depth_scale;

/// End-point error: mean distance between corresponding points over all frames.
/// `pairs[f]` holds (ground truth, prediction) points of frame `f`.
pub fn end_point_error(
    pairs: &[Vec<(agentstar_geom::Point3, agentstar_geom::Point3)>],
) -> Option<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    for frame in pairs {
        for (g, p) in frame {
            sum += (g - p).norm();
            n += 1;
        }
    }
    (n > 0).then(|| sum / n as f64)
}
