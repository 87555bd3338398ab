//! Models whose part `lid` turns on one revolute joint, `hinge`, the shape many tests build
//! (the tests of `agentstar-eval` and `agentstar-render` include this file by path).
#![allow(dead_code)]

use agentstar_geom::kinematics::{JointDef, JointKind};
use agentstar_geom::{KinematicTree, ObjectModel, Part, Vector3};

/// `parts` with the one named `lid` on a revolute joint `hinge` about `axis` through
/// `origin`, opening from 0 to `max_deg`.
pub fn with_lid_hinge(
    parts: Vec<Part>,
    origin: Vector3,
    axis: Vector3,
    max_deg: f64,
) -> ObjectModel {
    let hinge = JointDef {
        name: "hinge".into(),
        kind: JointKind::Revolute,
        parent: None,
        child: vec!["lid".into()],
        origin,
        axis,
        limit: Some((0.0, max_deg)),
    };
    let names: Vec<String> = parts.iter().map(|p| p.name.clone()).collect();
    ObjectModel {
        tree: KinematicTree::new(vec![hinge], &names).expect("tree"),
        parts,
    }
}
