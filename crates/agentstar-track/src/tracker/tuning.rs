//! The tracker's constants that more than one pass reads (each pass keeps its own beside it).

/// Distinct hypotheses of a covering refined by a global search (and the initialisation).
pub(super) const GLOBAL_KEEP: usize = 8;
/// Two poses of one frame whose IoU differ by less than this explain its mask equally for
/// the appearance term (a segmenter's boundary noise moves the IoU of the right pose by
/// about this much).
pub(super) const APPEARANCE_TIE: f64 = 0.005;
/// How much better a neighbour must score for the consistency pass to search from it with
/// the tracking step's window rather than the narrow polish.
pub(super) const FAR_MARGIN: f64 = 0.02;

/// A basin the sequence choice did not take bars [`appearance_pass`]'s turns toward it when
/// it lies this far or farther from the frame's pose (a discrete twin: a flip, a half-turn;
/// not a basin beside the pose that differs in depth or by a few degrees).
pub(super) const REJECTED_BASIN_DEG: f64 = 30.0;
