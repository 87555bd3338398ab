//! `run.json`: where an agent run's inputs are (the capture, the model, the pose file) and
//! what its `finish` gate accepts. Read by the agent harness, `pose`, `report` and `demo`.

use crate::{DataError, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `run.json`: where a run's inputs are. Relative paths are relative to the run directory.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RunFile {
    pub capture: PathBuf,
    #[serde(default = "default_model")]
    pub model: PathBuf,
    #[serde(default = "default_poses")]
    pub poses: PathBuf,
    /// What `finish` accepts.
    #[serde(default)]
    pub finish: FinishPolicy,
}

/// What the `finish` tool accepts (`run.json`'s `finish`; every field optional).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FinishPolicy {
    /// The largest share of keyframes that may be under the IoU gate, even with reasons.
    pub max_share_under_gate: f64,
    /// An `occlusion` reason is accepted when at least this share of the rendered model
    /// is hidden, percent.
    pub min_occlusion_percent: f64,
    /// Whether `finish` needs a fresh `mechanism_pick` of the declared arm for every
    /// revolute joint of the current scene (on by default; runs without it read as on).
    pub mechanism_check: bool,
}

impl Default for FinishPolicy {
    fn default() -> Self {
        FinishPolicy {
            max_share_under_gate: 0.25,
            min_occlusion_percent: 30.0,
            mechanism_check: true,
        }
    }
}

pub fn default_model() -> PathBuf {
    "scene.rhai".into()
}
pub fn default_poses() -> PathBuf {
    "pose.json".into()
}

impl RunFile {
    /// Reads `RUN/run.json` with its paths resolved against the run directory.
    pub fn read(run: &Path) -> Result<Option<RunFile>> {
        let p = run.join("run.json");
        if !p.is_file() {
            return Ok(None);
        }
        let mut rf: RunFile = serde_json::from_str(&crate::read_text(&p)?)
            .map_err(|e| DataError::invalid(&p, format!("not a run file: {e}")))?;
        let f = rf.finish;
        if !(0.0..=1.0).contains(&f.max_share_under_gate)
            || !(0.0..=100.0).contains(&f.min_occlusion_percent)
        {
            return Err(DataError::invalid(
                &p,
                format!(
                    "finish.max_share_under_gate must be in [0, 1] and finish.min_occlusion_percent in [0, 100] (they are {} and {})",
                    f.max_share_under_gate, f.min_occlusion_percent
                ),
            ));
        }
        for path in [&mut rf.capture, &mut rf.model, &mut rf.poses] {
            if path.is_relative() {
                *path = run.join(&*path);
            }
        }
        Ok(Some(rf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mechanism_check_is_on_unless_run_json_turns_it_off() {
        // A run.json from before the check reads as on.
        let old: RunFile =
            serde_json::from_str(r#"{"capture": "cap", "finish": {"max_share_under_gate": 0.5}}"#)
                .expect("old run.json");
        assert!(old.finish.mechanism_check);
        assert_eq!(old.finish.max_share_under_gate, 0.5);
        let none: RunFile = serde_json::from_str(r#"{"capture": "cap"}"#).expect("run.json");
        assert!(none.finish.mechanism_check);
        let off: RunFile =
            serde_json::from_str(r#"{"capture": "cap", "finish": {"mechanism_check": false}}"#)
                .expect("run.json");
        assert!(!off.finish.mechanism_check);
        assert_eq!(off.finish.min_occlusion_percent, 30.0);
    }
}
