//! Ground truth of a sequence in memory, as the evaluator reads it: rigid part meshes with
//! a pose per keyframe and the joints between them with a state per keyframe. Read from
//! `gt.json` by `agentstar-data` (`GroundTruth::sequence`) or built by the synthetic
//! captures; consumed by `agentstar-eval`.

use crate::pose::ObjectPose;
use crate::{TriMesh, Vector3};

/// One ground-truth joint, in its parent part's frame (metres, radians).
#[derive(Debug, Clone)]
pub struct GtJoint {
    pub name: String,
    pub revolute: bool,
    pub parent: usize,
    pub child: usize,
    pub axis: Vector3,
    pub origin: Vector3,
    /// Per keyframe.
    pub states: Vec<f64>,
}

/// Ground truth of a sequence: part meshes (metres, own frames) and their poses per keyframe.
#[derive(Debug, Clone)]
pub struct GtSequence {
    pub part_names: Vec<String>,
    pub meshes: Vec<TriMesh>,
    pub base_part: usize,
    /// `poses[frame][part]`: part frame → camera.
    pub poses: Vec<Vec<ObjectPose>>,
    pub joints: Vec<GtJoint>,
}
