//! Ground truth for evaluation (`formats.md` §4, `agentstar-gt/1`): rigid parts with a pose
//! per frame (part frame → camera, metres), optional joints with per-frame states, optional
//! symmetries. Paths are relative to `gt.json`.

use crate::meshio::load_mesh;
use crate::{read_text, DataError, Result};
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::TriMesh;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub const FORMAT: &str = "agentstar-gt/1";

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct GtPartFile {
    pub mesh: String,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct GtPose {
    pub quaternion: [f64; 4],
    pub translation: [f64; 3],
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq, Default)]
pub struct GtFrame {
    pub parts: BTreeMap<String, GtPose>,
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
        let file: GtFile = serde_json::from_str(&text)
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
