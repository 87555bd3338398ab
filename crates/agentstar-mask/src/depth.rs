//! Observed depth of one keyframe.

/// Observed planar depth for one frame, in the capture's units, with per-pixel confidence.
/// Both vectors are row-major, `width × height` long.
#[derive(Debug, Clone)]
pub struct DepthObservation {
    pub width: u32,
    pub height: u32,
    /// Planar depth; non-finite or ≤ 0 means invalid.
    pub depth: Vec<f32>,
    /// Confidence in [0, 1] (all 1 when the source has none).
    pub confidence: Vec<f32>,
}
