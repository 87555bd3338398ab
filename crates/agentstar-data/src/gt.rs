//! Ground truth for evaluation (`formats.md` §4, `agentstar-gt/1`): rigid parts with a pose
//! per frame (part frame → camera, metres), optional joints with per-frame states, optional
//! symmetries. Paths are relative to `gt.json`.

use crate::meshio::load_mesh;
use crate::posefile::PoseJson;
use crate::{read_text, DataError, Result};
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::truth::{GtJoint as SequenceJoint, GtSequence};
use agentstar_geom::{TriMesh, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub const FORMAT: &str = "agentstar-gt/1";

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct GtPartFile {
    pub mesh: String,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
pub struct GtFrame {
    /// Each part's pose in the camera frame (`pose.json`'s wire pose, without a scale).
    pub parts: BTreeMap<String, PoseJson>,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct GtJoint {
    pub name: String,
    #[serde(rename = "type")]
    pub kind: String,
    pub parent: String,
    pub child: String,
    pub axis: [f64; 3],
    #[serde(default)]
    pub origin: [f64; 3],
    /// Radians (revolute) or metres (prismatic), per frame.
    #[serde(default)]
    pub states: BTreeMap<String, f64>,
}

/// `gt.json` as written.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct GtFile {
    pub format: String,
    #[serde(default = "metres")]
    pub units: String,
    pub base_part: String,
    pub parts: BTreeMap<String, GtPartFile>,
    pub frames: BTreeMap<String, GtFrame>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<GtJoint>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub symmetries: Vec<[f64; 4]>,
}

fn metres() -> String {
    "m".into()
}

/// Ground truth loaded: meshes read, poses checked.
#[derive(Debug, Clone)]
pub struct GroundTruth {
    pub path: PathBuf,
    pub file: GtFile,
    /// Part meshes in their own frames (metres), sorted by name.
    pub meshes: BTreeMap<String, TriMesh>,
}

impl GroundTruth {
    pub fn load(path: &Path) -> Result<GroundTruth> {
        let text = read_text(path)?;
        let file: GtFile = crate::parse_json(&text)
            .map_err(|e| DataError::invalid(path, format!("invalid ground truth: {e}")))?;
        let bad = |m: String| DataError::invalid(path, m);
        if file.format != FORMAT {
            return Err(bad(format!(
                "unknown format \"{}\"; expected \"{FORMAT}\"",
                file.format
            )));
        }
        if file.units != "m" {
            return Err(bad(format!(
                "units \"{}\" are not supported; ground truth is in metres (\"m\")",
                file.units
            )));
        }
        if !file.parts.contains_key(&file.base_part) {
            return Err(bad(format!(
                "base_part `{}` is not among the parts",
                file.base_part
            )));
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut meshes = BTreeMap::new();
        for (name, p) in &file.parts {
            let m =
                load_mesh(&dir.join(&p.mesh)).map_err(|e| bad(format!("part `{name}`: {e}")))?;
            meshes.insert(name.clone(), m);
        }
        for (frame, f) in &file.frames {
            for (part, pose) in &f.parts {
                if !file.parts.contains_key(part) {
                    return Err(bad(format!("frame `{frame}`: unknown part `{part}`")));
                }
                ObjectPose::from_wxyz(pose.quaternion, pose.translation)
                    .map_err(|e| bad(format!("frame `{frame}`, part `{part}`: {e}")))?;
            }
        }
        for j in &file.joints {
            if !file.parts.contains_key(&j.parent) || !file.parts.contains_key(&j.child) {
                return Err(bad(format!(
                    "joint `{}`: parent `{}` and child `{}` must be parts",
                    j.name, j.parent, j.child
                )));
            }
            let norm = (j.axis[0].powi(2) + j.axis[1].powi(2) + j.axis[2].powi(2)).sqrt();
            if !(norm.is_finite() && norm > 1e-9) || j.origin.iter().any(|v| !v.is_finite()) {
                return Err(bad(format!(
                    "joint `{}`: axis {:?} must be a finite, non-zero vector (and origin finite)",
                    j.name, j.axis
                )));
            }
            if let Some((f, v)) = j.states.iter().find(|(_, v)| !v.is_finite()) {
                return Err(bad(format!(
                    "joint `{}`: state {v} in frame `{f}` is not finite",
                    j.name
                )));
            }
            if !matches!(j.kind.as_str(), "revolute" | "prismatic" | "continuous") {
                return Err(bad(format!(
                    "joint `{}`: type \"{}\" must be revolute, continuous or prismatic",
                    j.name, j.kind
                )));
            }
        }
        Ok(GroundTruth {
            path: path.to_path_buf(),
            file,
            meshes,
        })
    }

    /// The pose of `part` in `frame` (part frame → camera), if given.
    pub fn pose(&self, frame: &str, part: &str) -> Option<ObjectPose> {
        let p = self.file.frames.get(frame)?.parts.get(part)?;
        ObjectPose::from_wxyz(p.quaternion, p.translation).ok()
    }
}

/// Ground truth of an object model moved through frames: each part's mesh scaled to metres
/// in its rest frame, each part's pose per frame (`camera_from_object` with the scale,
/// composed with the part's forward kinematics, scale divided out), and the joints with
/// axis and origin in the parent part's frame (the parent joint's moving part, or the base
/// part), states in radians or metres. Mesh paths are `gt_meshes/<part>.obj`.
pub fn model_ground_truth(
    model: &agentstar_geom::ObjectModel,
    scale: f64,
    frames: &[(String, ObjectPose, Vec<f64>)],
    symmetries: &[agentstar_geom::UnitQuaternion],
) -> (GtFile, BTreeMap<String, TriMesh>) {
    use agentstar_geom::pose::Similarity;
    let mut parts = BTreeMap::new();
    let mut meshes = BTreeMap::new();
    for p in &model.parts {
        let m = (*p.mesh).clone().transformed(
            &(agentstar_geom::Matrix3::identity() * scale),
            &agentstar_geom::Vector3::zeros(),
        );
        parts.insert(
            p.name.clone(),
            GtPartFile {
                mesh: format!("gt_meshes/{}.obj", p.name),
            },
        );
        meshes.insert(p.name.clone(), m);
    }
    let tree = &model.tree;
    let base = (0..model.parts.len())
        .find(|&i| tree.part_joint(i).is_none())
        .unwrap_or(0);
    let mut gt_frames = BTreeMap::new();
    for (name, pose, states) in frames {
        let cam = pose.with_scale(scale);
        let mut f = GtFrame::default();
        for (p, a) in model.parts.iter().zip(tree.part_transforms(states)) {
            let full = cam.compose(&Similarity::from_rigid(&a));
            f.parts.insert(
                p.name.clone(),
                PoseJson {
                    quaternion: agentstar_geom::pose::quat_to_wxyz(&full.rotation),
                    translation: full.translation.into(),
                    scale: None,
                },
            );
        }
        gt_frames.insert(name.clone(), f);
    }
    let joints = tree
        .joints()
        .iter()
        .enumerate()
        .filter(|(_, j)| j.kind.has_state() && !j.child.is_empty())
        .map(|(k, j)| {
            // The parent part: one moved by the parent joint, or the base part.
            let parent = j
                .parent
                .as_deref()
                .and_then(|pj| tree.joint_index(pj))
                .and_then(|pj| (0..model.parts.len()).find(|&i| tree.part_joint(i) == Some(pj)))
                .unwrap_or(base);
            GtJoint {
                name: j.name.clone(),
                kind: j.kind.as_str().into(),
                parent: model.parts[parent].name.clone(),
                child: j.child[0].clone(),
                axis: j.axis.normalize().into(),
                origin: (j.origin * scale).into(),
                states: frames
                    .iter()
                    .map(|(n, _, s)| {
                        let v = if j.kind.is_angular() {
                            s[k]
                        } else {
                            s[k] * scale
                        };
                        (n.clone(), v)
                    })
                    .collect(),
            }
        })
        .collect();
    let file = GtFile {
        format: FORMAT.into(),
        units: "m".into(),
        base_part: model.parts[base].name.clone(),
        parts,
        frames: gt_frames,
        joints,
        symmetries: symmetries
            .iter()
            .map(agentstar_geom::pose::quat_to_wxyz)
            .collect(),
    };
    (file, meshes)
}

impl GroundTruth {
    /// The ground truth of `frames` (frame names, in order) in the evaluator's form. Fails,
    /// naming the file, when a frame lacks a part's pose or a joint's state.
    pub fn sequence(&self, frames: &[String]) -> Result<GtSequence> {
        let bad = |m: String| DataError::invalid(&self.path, m);
        let names: Vec<String> = self.meshes.keys().cloned().collect();
        let index = |n: &str| {
            names
                .iter()
                .position(|x| x == n)
                .ok_or_else(|| bad(format!("unknown part `{n}`")))
        };
        let mut poses = Vec::with_capacity(frames.len());
        for f in frames {
            let mut row = Vec::with_capacity(names.len());
            for n in &names {
                row.push(
                    self.pose(f, n)
                        .ok_or_else(|| bad(format!("frame `{f}` has no pose for part `{n}`")))?,
                );
            }
            poses.push(row);
        }
        let joints = self
            .file
            .joints
            .iter()
            .map(|j| {
                let states = frames
                    .iter()
                    .map(|f| {
                        j.states.get(f).copied().ok_or_else(|| {
                            bad(format!("joint `{}` has no state for frame `{f}`", j.name))
                        })
                    })
                    .collect::<Result<Vec<f64>>>()?;
                Ok(SequenceJoint {
                    name: j.name.clone(),
                    revolute: j.kind != "prismatic",
                    parent: index(&j.parent)?,
                    child: index(&j.child)?,
                    axis: Vector3::from(j.axis),
                    origin: Vector3::from(j.origin),
                    states,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(GtSequence {
            base_part: index(&self.file.base_part)?,
            meshes: self.meshes.values().cloned().collect(),
            part_names: names,
            poses,
            joints,
        })
    }

    /// Ground truth held in memory (as if loaded from `path`, which names it in messages).
    pub fn from_parts(path: &Path, file: GtFile, meshes: BTreeMap<String, TriMesh>) -> Self {
        GroundTruth {
            path: path.to_path_buf(),
            file,
            meshes,
        }
    }

    /// Writes `gt.json` and its meshes into `dir`, atomically file by file.
    pub fn write(&self, dir: &Path) -> Result<()> {
        for (name, p) in &self.file.parts {
            if let Some(m) = self.meshes.get(name) {
                crate::atomic::write_atomic(
                    &dir.join(&p.mesh),
                    crate::meshio::obj_text(m, name).as_bytes(),
                )?;
            }
        }
        crate::atomic::write_json(&dir.join("gt.json"), &self.file)
    }
}
