//! Evaluation with the paper's metrics (`formats.md` §5): monocular scale alignment by the
//! median log depth ratio, Chamfer distance between surface samples, rigid pose errors after
//! one Sim(3) gauge per trajectory (HOT3D protocol), articulation errors (iTACO protocol)
//! and end-point errors of carried surface points (ARCTIC protocol), computed for a
//! whole sequence in `sequence`. No file I/O: callers read ground truth and predictions.

pub mod articulation;
pub mod chamfer;
pub mod record;
pub mod rigid;
pub mod scale;
pub mod sequence;

pub use articulation::{axis_angle_error, axis_line_distance, state_error};
pub use chamfer::{chamfer_both, chamfer_distance, sample_surface};
pub use record::{JointRecord, MetricsRecord};
pub use rigid::{gauge_aligned_errors, GaugeErrors};
pub use scale::median_log_depth_scale;
