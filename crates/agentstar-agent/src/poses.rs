//! Keeping `pose.json` in step with the scene: after a shape step, joints the new scene
//! added start at rest in every frame, joints it removed are dropped, and the joint
//! definitions and part names are the new scene's.

use crate::Result;
use agentstar_data::posefile::{joint_json, PoseFile};
use std::path::Path;

/// Updates the pose file at `poses` to the model at `scene`; returns what changed.
pub fn reconcile(scene: &Path, poses: &Path) -> Result<Vec<String>> {
    let model = agentstar_data::scenefile::load_model(scene)?.model;
    let tree = &model.tree;
    let mut pf = PoseFile::read(poses)?;
    let rest = tree.states_to_interface(&tree.rest_states());
    let mut changes = vec![];
    let mut added = std::collections::BTreeSet::new();
    let mut removed = std::collections::BTreeSet::new();
    for entry in pf.frames.values_mut() {
        entry.joints.retain(|name, _| {
            let keep = rest.contains_key(name);
            if !keep {
                removed.insert(name.clone());
            }
            keep
        });
        for (name, v) in &rest {
            if !entry.joints.contains_key(name) {
                entry.joints.insert(name.clone(), *v);
                added.insert(name.clone());
            }
        }
    }
    if !added.is_empty() {
        changes.push(format!(
            "joints added at rest: {}",
            added.into_iter().collect::<Vec<_>>().join(", ")
        ));
    }
    if !removed.is_empty() {
        changes.push(format!(
            "joints removed: {}",
            removed.into_iter().collect::<Vec<_>>().join(", ")
        ));
    }
    pf.joint_defs = tree.joints().iter().map(joint_json).collect();
    pf.parts = Some(model.part_names());
    pf.write(poses)?;
    Ok(changes)
}
