//! Keeping `pose.json` in step with the scene: after a shape step, joints the new scene
//! added start at rest in every frame, joints it removed are dropped, and the joint
//! definitions and part names are the new scene's. When the edit moved the canonical origin
//! under the held part (the largest part in view, or one the caller names:
//! [`agentstar_geom::held_part`]), every written pose is carried by the shift
//! ([`agentstar_geom::origin_shift_holding`]), so that part stays where it was in every
//! image and an edit costs a local refinement, not a re-track. (Play-test: a cabinet grown
//! evenly was carried so as to keep its small handle in place, not its body.)

use crate::history::PoseHistory;
use crate::history::Result;
use crate::posefile::{joint_json, pose_json, PoseFile};
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{origin_shift_holding, HeldPart, ObjectModel};
use std::path::Path;

/// Shifts of the origin under this many canonical units are left alone (float noise).
const SHIFT_TOLERANCE: f64 = 1e-7;

/// Updates the pose file at `poses` to the model at `scene` (under the pose file's lock,
/// recorded in its history as `command` when anything changed); `before` is the model the
/// poses were made for with the part to hold in place, when it is known (then a moved
/// origin is compensated). Returns what changed and the version recorded.
pub fn reconcile(
    scene: &Path,
    poses: &Path,
    before: Option<(&ObjectModel, &HeldPart)>,
    command: &str,
) -> Result<(Vec<String>, Option<u64>)> {
    let model = crate::scenefile::load_model(scene)?.model;
    PoseHistory::new(poses).update_if_changed(command, |pf| Ok(reconcile_file(before, &model, pf)))
}

/// Carries every written pose of `pf` from `before` to `model` when the origin moved under
/// the `held` part; returns what changed.
pub fn carry_origin(
    before: &ObjectModel,
    model: &ObjectModel,
    pf: &mut PoseFile,
    held: &HeldPart,
) -> Vec<String> {
    let Some(shift) = origin_shift_holding(before, model, &held.name) else {
        return vec![];
    };
    if !shift.moved(SHIFT_TOLERANCE) {
        return vec![];
    }
    let mut n = 0;
    for entry in pf.frames.values_mut() {
        let Some(p) = &entry.object_pose else {
            continue;
        };
        let Ok(pose) = ObjectPose::from_wxyz(p.quaternion, p.translation) else {
            continue;
        };
        entry.object_pose = Some(pose_json(&shift.carry(&pose, pf.scale), p.scale));
        n += 1;
    }
    let s = shift.shift;
    vec![format!(
        "the canonical origin moved by ({:.4}, {:.4}, {:.4}) under part `{}` ({}; {}); {n} pose(s) carried so that part stays where it was in every image",
        s.x,
        s.y,
        s.z,
        held.name,
        held.why,
        if shift.share > 0.0 {
            "moved whole or on its unchanged side"
        } else {
            "by its bounds, as its mesh changed"
        }
    )]
}

/// Gives `pf` the scale `scale`: every written translation is multiplied by the ratio to
/// the old scale and every rotation kept, so each pose renders the same silhouette (every
/// point moves along its ray) and only metric quantities change.
pub fn rescale(pf: &mut PoseFile, scale: f64) -> std::result::Result<(), String> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(format!(
            "the scale must be positive and finite, got {scale}"
        ));
    }
    let ratio = scale / pf.scale;
    for entry in pf.frames.values_mut() {
        if let Some(p) = entry.object_pose.as_mut() {
            p.translation = p.translation.map(|t| t * ratio);
            if p.scale.is_some() {
                p.scale = Some(scale);
            }
        }
    }
    pf.scale = scale;
    Ok(())
}

/// Brings `pf` in step with `model`; returns what changed.
fn reconcile_file(
    before: Option<(&ObjectModel, &HeldPart)>,
    model: &ObjectModel,
    pf: &mut PoseFile,
) -> Vec<String> {
    let tree = &model.tree;
    let rest = tree.states_to_interface(&tree.rest_states());
    let mut changes = match before {
        Some((b, held)) => carry_origin(b, model, pf, held),
        None => vec![],
    };
    let mut added = std::collections::BTreeSet::new();
    let mut removed = std::collections::BTreeSet::new();
    let mut clamped: std::collections::BTreeMap<String, usize> = Default::default();
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
        // States outside a changed limit are brought to its nearest end.
        for j in tree.joints() {
            if let (Some((lo, hi)), Some(v)) = (j.limit, entry.joints.get_mut(&j.name)) {
                if *v < lo || *v > hi {
                    *v = v.clamp(lo, hi);
                    *clamped.entry(j.name.clone()).or_default() += 1;
                }
            }
        }
    }
    let joints_touched = !added.is_empty() || !removed.is_empty();
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
    for (name, n) in &clamped {
        changes.push(format!("{name} brought into its limit in {n} frame(s)"));
    }
    // The header: what changed there is said too (play-test 15: a new part bumped the pose
    // version while the reply said pose.json was unchanged).
    let defs: Vec<_> = tree.joints().iter().map(joint_json).collect();
    let redefined: Vec<&str> = defs
        .iter()
        .filter(|d| {
            pf.joint_defs
                .iter()
                .find(|o| o.name == d.name)
                .is_some_and(|o| o != *d)
        })
        .map(|d| d.name.as_str())
        .collect();
    if !redefined.is_empty() {
        changes.push(format!(
            "joint definitions updated (origin, axis, limits or parts): {}",
            redefined.join(", ")
        ));
    }
    let joints_named = |defs: &[crate::posefile::JointDefJson]| {
        defs.iter().map(|d| d.name.clone()).collect::<Vec<_>>()
    };
    if joints_named(&pf.joint_defs) != joints_named(&defs)
        && !joints_touched
        && redefined.is_empty()
    {
        changes.push(format!(
            "joints listed: {}",
            if defs.is_empty() {
                "none".to_string()
            } else {
                joints_named(&defs).join(", ")
            }
        ));
    }
    let parts = model.part_names();
    match &pf.parts {
        Some(old) if *old != parts => {
            let new: Vec<&str> = parts
                .iter()
                .filter(|p| !old.contains(p))
                .map(String::as_str)
                .collect();
            let gone: Vec<&str> = old
                .iter()
                .filter(|p| !parts.contains(p))
                .map(String::as_str)
                .collect();
            changes.push(match (new.is_empty(), gone.is_empty()) {
                (true, true) => "parts listed in the scene's order".to_string(),
                (false, true) => format!("parts listed, added: {}", new.join(", ")),
                (true, false) => format!("parts listed, removed: {}", gone.join(", ")),
                (false, false) => format!(
                    "parts listed, added: {}; removed: {}",
                    new.join(", "),
                    gone.join(", ")
                ),
            });
        }
        None => changes.push(format!("parts listed: {}", parts.join(", "))),
        Some(_) => {}
    }
    pf.joint_defs = defs;
    pf.parts = Some(parts);
    changes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_new_scene_adds_drops_and_clamps_joints_in_every_frame() {
        let dir = tempfile::tempdir().expect("tmp");
        let scene = dir.path().join("scene.rhai");
        let poses = dir.path().join("pose.json");
        std::fs::write(&scene, "part(\"base\", box(1, 1, 0.2));\npart(\"lid\", box(1, 1, 0.05).translate(0, 0, 0.2));\npart(\"door\", box(0.1, 1, 0.5).translate(0.6, 0, 0));\njoint(#{ name: \"hinge\", type: \"revolute\", child: \"lid\", origin: [0, 0.5, 0.1], axis: [1, 0, 0], limit: [0, 60] });\njoint(#{ name: \"swing\", type: \"revolute\", child: \"door\", origin: [0.6, 0.5, 0], axis: [0, 0, 1], limit: [0, 90] });").expect("w");
        let pf = serde_json::json!({
            "frame_convention": "camera_opencv", "canonical": "+Z up", "scale": 0.2,
            "reference_frame": "a.png", "joint_defs": [],
            "frames": {
                "a.png": {"object_pose": {"quaternion": [1, 0, 0, 0], "translation": [0, 0, 1]}, "joints": {"hinge": 100.0, "old": 3.0}},
                "b.png": {"joints": {"hinge": 30.0}}
            }
        });
        std::fs::write(&poses, pf.to_string()).expect("w");
        let (changes, version) = reconcile(&scene, &poses, None, "test").expect("reconcile");
        // The file as it was is version 0, the reconciled one version 1.
        assert_eq!(version, Some(1));
        assert_eq!(
            changes,
            [
                "joints added at rest: swing",
                "joints removed: old",
                "hinge brought into its limit in 1 frame(s)",
                "parts listed: base, lid, door"
            ]
        );
        let back = PoseFile::read(&poses).expect("read");
        assert_eq!(back.frames["a.png"].joints["hinge"], 60.0);
        assert_eq!(back.frames["b.png"].joints["hinge"], 30.0);
        assert_eq!(back.frames["b.png"].joints["swing"], 0.0);
        assert_eq!(back.joint_defs.len(), 2);
        // Nothing to change: nothing written, no version.
        assert_eq!(
            reconcile(&scene, &poses, None, "again").expect("again"),
            (vec![], None)
        );
    }

    #[test]
    fn a_new_part_or_a_moved_hinge_is_said_when_it_makes_a_version() {
        // Play-test 15: a printed patch added to the scene bumped the pose version while the
        // reply said pose.json was unchanged. Every version reconcile records says why.
        let dir = tempfile::tempdir().expect("tmp");
        let scene = dir.path().join("scene.rhai");
        let poses = dir.path().join("pose.json");
        let lid = "part(\"base\", box(1, 1, 0.2));\npart(\"lid\", box(1, 1, 0.05).translate(0, 0, 0.2));\n";
        let hinge = |y: f64| {
            format!("joint(#{{ name: \"hinge\", type: \"revolute\", child: \"lid\", origin: [0, {y}, 0.1], axis: [1, 0, 0], limit: [0, 60] }});\n")
        };
        std::fs::write(&scene, format!("{lid}{}", hinge(0.5))).expect("w");
        let pf = serde_json::json!({
            "frame_convention": "camera_opencv", "canonical": "+Z up", "scale": 0.2,
            "reference_frame": "a.png", "joint_defs": [],
            "frames": {"a.png": {"object_pose": {"quaternion": [1, 0, 0, 0], "translation": [0, 0, 1]}, "joints": {"hinge": 10.0}}}
        });
        std::fs::write(&poses, pf.to_string()).expect("w");
        let (_, v) = reconcile(&scene, &poses, None, "first").expect("first");
        assert!(v.is_some());
        // A part added, no joint touched: the part is named with the version.
        std::fs::write(
            &scene,
            format!(
                "{lid}part(\"patch\", box(0.2, 0.2, 0.01).translate(0, 0, 0.11));\n{}",
                hinge(0.5)
            ),
        )
        .expect("w");
        let (changes, v) = reconcile(&scene, &poses, None, "patch").expect("patch");
        assert!(v.is_some());
        assert_eq!(changes, ["parts listed, added: patch"]);
        // The hinge moved: its definition is named.
        std::fs::write(
            &scene,
            format!(
                "{lid}part(\"patch\", box(0.2, 0.2, 0.01).translate(0, 0, 0.11));\n{}",
                hinge(0.4)
            ),
        )
        .expect("w");
        let (changes, v) = reconcile(&scene, &poses, None, "hinge").expect("hinge");
        assert!(v.is_some());
        assert_eq!(
            changes,
            ["joint definitions updated (origin, axis, limits or parts): hinge"]
        );
        // The same scene again: nothing said, no version.
        assert_eq!(
            reconcile(&scene, &poses, None, "again").expect("again"),
            (vec![], None)
        );
    }
}
