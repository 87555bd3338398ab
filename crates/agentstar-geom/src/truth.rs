//! Ground truth of a sequence in memory, as the evaluator reads it: rigid part meshes with
//! a pose per keyframe and the joints between them with a state per keyframe. Read from
//! `gt.json` by `agentstar-data` (`GroundTruth::sequence`) or built by the synthetic
//! captures; consumed by `agentstar-eval`.

use crate::pose::ObjectPose;
use crate::{TriMesh, UnitQuaternion, Vector3};

/// BOP's `max_sym_disc_step` (the BOP toolkit's default, also HOT3D's): the most that the
/// point furthest from a continuous symmetry's axis may travel between consecutive listed
/// rotations, as a fraction of the object's diameter.
pub const BOP_MAX_SYM_DISC_STEP: f64 = 0.01;

/// The rotations (identity excluded) that stand for a continuous rotational symmetry about
/// `axis` in a list of symmetries, as BOP discretises one: ⌈π / [`BOP_MAX_SYM_DISC_STEP`]⌉
/// equal turns in all, identity included (315 turns 1.14° apart), so that reducing an
/// error by the list leaves at most 0.57° about the axis. A coarser list would leave the
/// rest of the nearest turn in the reduced rotation error.
pub fn continuous_symmetry(axis: &nalgebra::Unit<Vector3>) -> Vec<UnitQuaternion> {
    let turns = (std::f64::consts::PI / BOP_MAX_SYM_DISC_STEP).ceil() as usize;
    (1..turns)
        .map(|k| {
            UnitQuaternion::from_axis_angle(axis, std::f64::consts::TAU * k as f64 / turns as f64)
        })
        .collect()
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_continuous_symmetry_is_listed_as_bop_discretises_it() {
        let axis = nalgebra::Unit::new_normalize(Vector3::new(0.0, 1.0, 1.0));
        let list = continuous_symmetry(&axis);
        // ⌈π / 0.01⌉ = 315 turns, identity left out.
        assert_eq!(list.len(), 314);
        for q in &list {
            let (a, angle) = q.axis_angle().expect("not the identity");
            assert!(angle > 0.0);
            assert!((a.dot(&axis) - 1.0).abs() < 1e-12 || (a.dot(&axis) + 1.0).abs() < 1e-12);
        }
        // Any turn about the axis lies within half a step (0.57°) of a listed one or the
        // identity.
        let step_deg = 360.0 / 315.0;
        for k in 0..720 {
            let turn = UnitQuaternion::from_axis_angle(&axis, (k as f64 * 0.5).to_radians());
            let nearest = std::iter::once(UnitQuaternion::identity())
                .chain(list.iter().copied())
                .map(|s| s.angle_to(&turn).to_degrees())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest <= 0.5 * step_deg + 1e-9, "{k}: {nearest}");
        }
    }
}
