//! `pose.json` (`formats.md` §3), compatible with the reference harness's state JSON: one
//! shared scale, joint definitions, and per frame the committed `object_pose`, the joint
//! states (a sibling of the pose, never nested) and `moved`.

use crate::capture::Capture;
use crate::{read_text, DataError, Result};
use agentstar_geom::kinematics::{JointDef, JointKind};
use agentstar_geom::pose::{seed_from_reference, GenPose, ObjectPose};
use agentstar_geom::{KinematicTree, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

pub const FRAME_CONVENTION: &str = "camera_opencv (+X right, +Y down, +Z forward)";
pub const CANONICAL: &str = "+Z up, centred at origin, longest side ~1";
/// How `object_pose` reads, stated in every file we write: a play-test agent had to guess the
/// quaternion's order.
pub const POSE_CONVENTION: &str = "quaternion [w, x, y, z] (scalar first) and translation (m) take canonical points (parts placed by the frame's joints), times scale, into the camera frame: p_cam = R(q) (scale p) + t";

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PoseJson {
    pub quaternion: [f64; 4],
    pub translation: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
pub struct FrameEntry {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object_pose: Option<PoseJson>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub joints: BTreeMap<String, f64>,
    #[serde(default)]
    pub moved: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view_index: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_c2w: Option<[[f64; 4]; 4]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<serde_json::Value>,
    /// An in-between frame's pose (`formats.md` §2), written by `track --write-between`:
    /// never read as a keyframe's, and dropped when keyframe poses are written again.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub between: bool,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct JointDefJson {
    pub name: String,
    #[serde(rename = "type")]
    pub kind: String,
    #[serde(default)]
    pub parent: Option<String>,
    pub child: ChildSpec,
    #[serde(default)]
    pub origin: [f64; 3],
    #[serde(default = "default_axis")]
    pub axis: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limit: Option<[f64; 2]>,
}

fn default_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// `child` is a part name or a list of part names.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum ChildSpec {
    One(String),
    Many(Vec<String>),
}

impl ChildSpec {
    pub fn names(&self) -> Vec<String> {
        match self {
            ChildSpec::One(s) => vec![s.clone()],
            ChildSpec::Many(v) => v.clone(),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PoseFile {
    #[serde(default = "frame_convention")]
    pub frame_convention: String,
    #[serde(default = "canonical")]
    pub canonical: String,
    /// [`POSE_CONVENTION`]; files without it (the reference harness's) read the same.
    #[serde(default = "pose_convention")]
    pub pose_convention: String,
    pub scale: f64,
    pub reference_frame: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parts: Option<Vec<String>>,
    #[serde(default)]
    pub joint_defs: Vec<JointDefJson>,
    pub frames: BTreeMap<String, FrameEntry>,
}

fn frame_convention() -> String {
    FRAME_CONVENTION.into()
}
fn canonical() -> String {
    CANONICAL.into()
}
fn pose_convention() -> String {
    POSE_CONVENTION.into()
}

/// The generalised pose of one frame, resolved (internal-unit joint states), and where it
/// came from.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePose {
    pub generalised: GenPose,
    /// True when the pose came from the reference frame through the cameras.
    pub seeded: bool,
    pub moved: bool,
}

/// Where a tracking run that writes `out` keeps its poses while it runs (`pose.json` →
/// `pose.partial.json`): the `track` command writes it, the agent's `track` tool points to it
/// when a run stops.
pub fn partial_path(out: &Path) -> std::path::PathBuf {
    out.with_extension("partial.json")
}

pub fn joint_json(j: &JointDef) -> JointDefJson {
    JointDefJson {
        name: j.name.clone(),
        kind: j.kind.as_str().into(),
        parent: j.parent.clone(),
        child: if j.child.len() == 1 {
            ChildSpec::One(j.child[0].clone())
        } else {
            ChildSpec::Many(j.child.clone())
        },
        origin: j.origin.into(),
        axis: j.axis.into(),
        limit: j.limit.map(|(a, b)| [a, b]),
    }
}

pub fn pose_json(p: &ObjectPose, scale: Option<f64>) -> PoseJson {
    PoseJson {
        quaternion: p.quaternion_wxyz(),
        translation: p.translation.into(),
        scale,
    }
}

impl PoseFile {
    pub fn read(path: &Path) -> Result<PoseFile> {
        let text = read_text(path)?;
        let pf: PoseFile = crate::parse_json(&text).map_err(|e: String| {
            let hint = if e.contains("unknown field `joints`") {
                " (joints are a sibling of object_pose, not nested inside it)"
            } else {
                ""
            };
            DataError::invalid(path, format!("invalid pose file: {e}{hint}"))
        })?;
        pf.check().map_err(|m| DataError::invalid(path, m))?;
        Ok(pf)
    }

    pub fn write(&self, path: &Path) -> Result<()> {
        self.check()
            .map_err(|m| DataError::invalid(path, format!("refusing to write: {m}")))?;
        crate::atomic::write_json(path, self)
    }

    fn check(&self) -> std::result::Result<(), String> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(format!("scale {} must be positive and finite", self.scale));
        }
        for (name, f) in &self.frames {
            if let Some(p) = &f.object_pose {
                ObjectPose::from_wxyz(p.quaternion, p.translation)
                    .map_err(|e| format!("frame `{name}`: object_pose: {e}"))?;
                if let Some(s) = p.scale {
                    if !(s.is_finite() && s > 0.0) {
                        return Err(format!(
                            "frame `{name}`: object_pose.scale {s} must be positive and finite"
                        ));
                    }
                    if (s - self.scale).abs() > 1e-6 * self.scale {
                        return Err(format!(
                            "frame `{name}`: object_pose.scale {s} differs from the shared scale {}; pose.json has one scale for every frame",
                            self.scale
                        ));
                    }
                }
            }
            if let Some((j, v)) = f.joints.iter().find(|(_, v)| !v.is_finite()) {
                return Err(format!(
                    "frame `{name}`: joint `{j}` has non-finite state {v}"
                ));
            }
        }
        Ok(())
    }

    /// Joint definitions as the geometry layer's type.
    pub fn joint_defs(&self) -> std::result::Result<Vec<JointDef>, String> {
        self.joint_defs
            .iter()
            .map(|j| {
                let kind = JointKind::parse(&j.kind).ok_or_else(|| {
                    format!(
                        "joint `{}`: unknown type \"{}\" (use {})",
                        j.name,
                        j.kind,
                        JointKind::NAMES.join(", ")
                    )
                })?;
                Ok(JointDef {
                    name: j.name.clone(),
                    kind,
                    parent: j.parent.clone(),
                    child: j.child.names(),
                    origin: Vector3::from(j.origin),
                    axis: Vector3::from(j.axis),
                    limit: j.limit.map(|l| (l[0], l[1])),
                })
            })
            .collect()
    }

    /// A new pose file with every frame of `capture` at `pose` relative to the reference
    /// (others seeded through the cameras), all joints at rest.
    pub fn initial(
        capture: &Capture,
        tree: &KinematicTree,
        scale: f64,
        reference_pose: &ObjectPose,
    ) -> PoseFile {
        let ref_name = capture.frames[capture.ref_index].name.clone();
        let mut frames = BTreeMap::new();
        let rest = tree.states_to_interface(&tree.rest_states());
        frames.insert(
            ref_name.clone(),
            FrameEntry {
                object_pose: Some(pose_json(reference_pose, Some(scale))),
                joints: rest,
                moved: false,
                ..Default::default()
            },
        );
        PoseFile {
            frame_convention: FRAME_CONVENTION.into(),
            canonical: CANONICAL.into(),
            pose_convention: POSE_CONVENTION.into(),
            scale,
            reference_frame: ref_name,
            parts: None,
            joint_defs: tree.joints().iter().map(joint_json).collect(),
            frames,
        }
    }

    /// Resolves every capture frame's generalised pose. A frame with a written pose uses it;
    /// a frame without one is seeded from the reference frame through the cameras
    /// (`inv(c2w_k) · c2w_ref`) and takes the reference's joint states unless it has its own.
    /// Joint states are checked against the model's joints (complete, within limits).
    pub fn resolve(
        &self,
        capture: &Capture,
        tree: &KinematicTree,
    ) -> std::result::Result<Vec<FramePose>, String> {
        for (name, entry) in &self.frames {
            let in_between = capture
                .between
                .iter()
                .any(|f| f.name == *name || f.stem == *name);
            if entry.between && !in_between {
                return Err(format!(
                    "frame `{name}` is marked `between` but is not an in-between frame of the capture"
                ));
            }
            if !in_between && capture.frame_index(name).is_none() {
                return Err(format!("frame `{name}` is not in the capture"));
            }
        }
        let entry_for = |name: &str, stem: &str| {
            self.frames
                .get(name)
                .or_else(|| {
                    self.frames
                        .iter()
                        .find(|(k, _)| {
                            Path::new(k).file_stem().and_then(|s| s.to_str()) == Some(stem)
                        })
                        .map(|(_, v)| v)
                })
                .filter(|e| !e.between)
        };
        let ri = capture.frame_index(&self.reference_frame).ok_or_else(|| {
            format!(
                "reference_frame `{}` is not in the capture",
                self.reference_frame
            )
        })?;
        let rf = &capture.frames[ri];
        let ref_entry = entry_for(&rf.name, &rf.stem)
            .ok_or_else(|| format!("the reference frame `{}` has no entry", rf.name))?;
        let ref_pose_json = ref_entry
            .object_pose
            .as_ref()
            .ok_or_else(|| format!("the reference frame `{}` must have an object_pose", rf.name))?;
        let ref_pose = ObjectPose::from_wxyz(ref_pose_json.quaternion, ref_pose_json.translation)
            .map_err(|e| e.to_string())?;
        let ref_states = tree
            .states_from_interface(&ref_entry.joints)
            .map_err(|e| format!("frame `{}`: {e}", rf.name))?;
        let mut out = Vec::with_capacity(capture.frames.len());
        for f in &capture.frames {
            let entry = entry_for(&f.name, &f.stem);
            let (pose, seeded) = match entry.and_then(|e| e.object_pose.as_ref()) {
                Some(p) => (
                    ObjectPose::from_wxyz(p.quaternion, p.translation)
                        .map_err(|e| format!("frame `{}`: {e}", f.name))?,
                    false,
                ),
                None => (
                    seed_from_reference(&f.world_from_camera, &rf.world_from_camera, &ref_pose),
                    true,
                ),
            };
            let states = match entry {
                Some(e) if !e.joints.is_empty() => tree
                    .states_from_interface(&e.joints)
                    .map_err(|e| format!("frame `{}`: {e}", f.name))?,
                _ => ref_states.clone(),
            };
            out.push(FramePose {
                generalised: GenPose::new(pose, states),
                seeded,
                moved: entry.is_some_and(|e| e.moved),
            });
        }
        Ok(out)
    }

    /// Writes `poses` for every frame (full precision), keeping joint definitions in sync.
    /// In-between frames' poses written before are dropped: they followed the keyframe poses
    /// being replaced.
    pub fn set_frames(&mut self, capture: &Capture, tree: &KinematicTree, poses: &[FramePose]) {
        self.joint_defs = tree.joints().iter().map(joint_json).collect();
        self.frames.retain(|_, e| !e.between);
        for (f, p) in capture.frames.iter().zip(poses) {
            let e = self.frames.entry(f.name.clone()).or_default();
            e.object_pose = Some(pose_json(&p.generalised.pose, Some(self.scale)));
            e.joints = tree.states_to_interface(&p.generalised.states);
            e.moved = p.moved;
        }
    }

    /// Adds in-between frames' poses (`"between": true`) after [`PoseFile::set_frames`].
    pub fn set_between<'a>(
        &mut self,
        tree: &KinematicTree,
        poses: impl IntoIterator<Item = (&'a str, &'a GenPose)>,
    ) {
        for (name, p) in poses {
            self.frames.insert(
                name.to_string(),
                FrameEntry {
                    object_pose: Some(pose_json(&p.pose, Some(self.scale))),
                    joints: tree.states_to_interface(&p.states),
                    between: true,
                    ..Default::default()
                },
            );
        }
    }
}
