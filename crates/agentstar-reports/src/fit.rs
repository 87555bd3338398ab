//! The reports of the shape tools: what `agentstar fit-shape` writes (`fit.json`, and on
//! stdout with `--json`) and the `fit_shape` tool reads back.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// One fitted parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitParam {
    pub name: String,
    pub before: f64,
    pub after: f64,
    pub min: f64,
    pub max: f64,
    /// True when the fitted value sits within 2% of the range of a bound (widen the bound
    /// if the frames say so, or look for a different error). The search samples the range,
    /// so an optimum past the bound ends near it, not on it: play-test 9's gap ended at
    /// 1.1% of its range from 0, unflagged at the earlier 0.5%.
    pub at_bound: bool,
}

/// A declared parameter the fit left as it was.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldParam {
    pub name: String,
    pub value: f64,
}

/// One keyframe's visible IoU before and after, and its band IoU after (what the gate reads).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitFrame {
    pub frame: String,
    pub iou_before: f64,
    pub iou_after: f64,
    /// The band IoU after the fit (the visible IoU without the ±2 px band around the observed
    /// mask's outline: the gate's figure, as `score` prints it); absent in older reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iou_band_after: Option<f64>,
}

impl FitFrame {
    /// The figure the IoU gate reads: the band IoU, or the visible IoU in older reports.
    pub fn gate_after(&self) -> f64 {
        self.iou_band_after.unwrap_or(self.iou_after)
    }
}

/// One round of the fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitRoundRow {
    pub values: Vec<f64>,
    /// Mean visible IoU with the poses held, then with the poses refined.
    pub iou_held: f64,
    pub iou_refined: f64,
    pub builds: usize,
}

/// What `fit-shape` did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitReport {
    pub params: Vec<FitParam>,
    pub held: Vec<HeldParam>,
    pub frames: Vec<FitFrame>,
    pub iou_mean_before: f64,
    pub iou_mean_after: f64,
    pub iou_min_before: f64,
    pub iou_min_after: f64,
    pub rounds: Vec<FitRoundRow>,
    /// How far the canonical origin moved from the starting model to the fitted one; the
    /// poses of frames outside the fit are carried by it.
    pub origin_shift: [f64; 3],
    /// The script with the fitted values written into its `param(...)` calls.
    pub scene: PathBuf,
    /// Every frame's pose for the fitted script (fitted frames refined, others carried).
    pub poses: PathBuf,
    /// Before/after silhouette comparisons.
    pub sheets: Vec<PathBuf>,
    pub builds: usize,
    pub evaluations: usize,
    pub seconds: f64,
    /// True when the fitted script and poses were written over the inputs (`--write`).
    pub written: bool,
    /// The part kept in place when the poses were carried to each shape, and why it
    /// (`--hold`, or the part most in view).
    #[serde(default)]
    pub held_part: Option<String>,
}

impl FitReport {
    pub fn read(path: &std::path::Path) -> crate::Result<FitReport> {
        let text = agentstar_data::read_text(path)?;
        serde_json::from_str(&text)
            .map_err(|e| agentstar_data::DataError::invalid(path, format!("not a fit report: {e}")))
    }
}

/// How `agentstar scale` measured the scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum ScaleMethod {
    /// Observed over rendered depth (the capture has depth).
    Depth,
    /// Metric cameras that move around an object that stays put.
    Parallax,
    /// A size the agent states along one model axis.
    Size,
}

/// One keyframe's figure in a scale estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleFrame {
    pub frame: String,
    /// Its own ratio (depth), or the object origin's distance from the common point after
    /// the fit, metres (parallax).
    pub value: f64,
}

/// What `agentstar scale` found (and on stdout with `--json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleReport {
    pub method: ScaleMethod,
    /// Metres per model unit in the pose file, and as estimated.
    pub scale_before: f64,
    pub scale_after: f64,
    /// `scale_after / scale_before`: every translation is multiplied by it, rotations kept.
    pub ratio: f64,
    pub frames: Vec<ScaleFrame>,
    /// Relative spread of the estimate (see the method).
    pub spread: f64,
    /// Pixels (depth), frames (parallax) or 1 (size).
    pub samples: usize,
    pub notes: Vec<String>,
    /// True when the estimate's own checks warn (frames that disagree, a short baseline, an
    /// object that wanders in the world): the notes say which.
    #[serde(default)]
    pub weak: bool,
    /// The rescaled pose file (`--out`), when one was written.
    pub poses: Option<PathBuf>,
    /// True when the rescaled poses were written over the input (`--write`).
    pub written: bool,
}
