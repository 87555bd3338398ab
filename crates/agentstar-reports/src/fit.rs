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
    /// The round's last residual-guided step; absent in older reports and with it off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guided: Option<GuidedRow>,
}

/// A residual-guided step: the size change along X, Y, Z the frames wanted at the best
/// shape so far, the values that step tried, the mean visible IoU with its poses refined,
/// and whether it was kept (it raised the mean).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuidedRow {
    pub wanted: [Option<f64>; 3],
    pub values: Option<Vec<f64>>,
    pub iou_refined: Option<f64>,
    pub taken: bool,
}

/// A size change along one model axis that the frames want beyond a common scale and no
/// fitted parameter makes (relative: 0.017 is 1.7% longer).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnmetAxis {
    /// `X`, `Y` or `Z`.
    pub axis: String,
    pub want: f64,
}

/// The line naming the wanted size changes no fitted parameter makes; `None` when there are
/// none.
pub fn unmet_line(unmet: &[UnmetAxis]) -> Option<String> {
    (!unmet.is_empty()).then(|| {
        format!(
            "no fitted parameter makes what the frames want along {} (beyond a common scale): declare a `param` that sets that size and fit it, or change it by hand (scene_write), then track from pose.json.\n",
            unmet
                .iter()
                .map(|u| format!("{} {}", u.axis, percent(u.want)))
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

/// What a group of frames wants of the model's size along X, Y and Z: relative changes
/// (0.08: 8% longer), `None` along an axis these frames cannot tell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisWants {
    pub want: [Option<f64>; 3],
    pub equations: usize,
}

/// Frames grouped by the model axis they see face-on (`X`, `Y`, `Z`, or `oblique`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewGroup {
    pub face_on: String,
    pub frames: Vec<String>,
    pub wants: AxisWants,
}

/// Residuals of the fitted silhouettes against the masks grouped by viewing direction:
/// the observed extent over the model's along each projected model axis, solved for the
/// relative size changes each group of frames wants (`agentstar_track::proportion`). Only
/// differences between the axes mean something: a uniform change is the scale.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewResiduals {
    pub all: AxisWants,
    pub groups: Vec<ViewGroup>,
    /// What this says in words: which axis the frames want longer or shorter, and which
    /// fixed proportion that points at; empty when the axes agree within
    /// [`PROPORTION_NOTE_SHARE`].
    pub verdict: Vec<String>,
}

/// Axes whose wanted changes differ by less than this share are said to agree.
pub const PROPORTION_NOTE_SHARE: f64 = 0.03;

const AXIS_NAMES: [&str; 3] = ["X", "Y", "Z"];

fn percent(v: f64) -> String {
    format!("{:+.1}%", 100.0 * v)
}

impl AxisWants {
    /// "X +8.0%, Y +0.1%, Z −6.0%" over the determined axes.
    pub fn line(&self) -> String {
        let parts: Vec<String> = AXIS_NAMES
            .iter()
            .zip(self.want)
            .filter_map(|(n, w)| w.map(|w| format!("{n} {}", percent(w))))
            .collect();
        if parts.is_empty() {
            "nothing measurable".into()
        } else {
            parts.join(", ")
        }
    }
}

impl ViewResiduals {
    /// The verdict from the wanted changes of all frames and of each group: the axis the
    /// frames want longest against the one they want shortest, relative to each other.
    pub fn verdict_of(all: &AxisWants, groups: &[ViewGroup]) -> Vec<String> {
        let known: Vec<(usize, f64)> = all
            .want
            .iter()
            .enumerate()
            .filter_map(|(b, w)| w.map(|w| (b, w)))
            .collect();
        if known.len() < 2 {
            return vec![];
        }
        let (long, short) = (
            known.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1)),
            known.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1)),
        );
        let (Some((l, lw)), Some((s, sw))) = (long, short) else {
            return vec![];
        };
        let ratio = (1.0 + lw) / (1.0 + sw).max(1e-6);
        if ratio - 1.0 < PROPORTION_NOTE_SHARE {
            return vec![];
        }
        let evidence: Vec<String> = groups
            .iter()
            .filter_map(|g| {
                let (a, b) = (g.wants.want[l]?, g.wants.want[s]?);
                Some(format!(
                    "{} frame(s) {}: {} {} against {} {}",
                    g.frames.len(),
                    g.label(),
                    AXIS_NAMES[l],
                    percent(a),
                    AXIS_NAMES[s],
                    percent(b)
                ))
            })
            .collect();
        vec![format!(
            "the frames want the model longer along {} ({}) than along {} ({}): the proportion {}:{} is off by ×{:.3}{}",
            AXIS_NAMES[l],
            percent(lw),
            AXIS_NAMES[s],
            percent(sw),
            AXIS_NAMES[l],
            AXIS_NAMES[s],
            ratio,
            if evidence.is_empty() {
                String::new()
            } else {
                format!(" ({})", evidence.join("; "))
            }
        )]
    }
}

impl ViewGroup {
    /// "face-on to X", or "seen obliquely".
    pub fn label(&self) -> String {
        if self.face_on == "oblique" {
            "seen obliquely (no axis face-on)".into()
        } else {
            format!("face-on to {}", self.face_on)
        }
    }
}

/// The residuals by viewing direction as lines for a person or a model.
pub fn views_text(v: &ViewResiduals) -> String {
    let mut t = String::from(
        "residuals by viewing direction (observed extent over the model's along its axes, at the fitted poses, as the size change the frames want; a change common to all axes is the scale, which silhouettes do not say):\n",
    );
    for g in &v.groups {
        t.push_str(&format!(
            "  {} ({} frame(s)): {}\n",
            g.label(),
            g.frames.len(),
            g.wants.line()
        ));
    }
    t.push_str(&format!("  all frames: {}\n", v.all.line()));
    for line in &v.verdict {
        t.push_str(&format!("  → {line}\n"));
    }
    t
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
    /// The fitted silhouettes' residuals grouped by viewing direction, at the fitted poses.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub views: Option<ViewResiduals>,
    /// The part kept in place when the poses were carried to each shape, and why it
    /// (`--hold`, or the part most in view).
    #[serde(default)]
    pub held_part: Option<String>,
    /// What the last residual-guided step found no fitted parameter could make.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unmet: Vec<UnmetAxis>,
    /// Parameters the masks cannot set: over their whole range the mean visible IoU moves
    /// less than the fit can tell apart.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unseen: Vec<UnseenParam>,
}

/// A fitted parameter the masks cannot set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnseenParam {
    pub name: String,
    /// The most the mean visible IoU moves with it at either end of its range.
    pub iou_span: f64,
}

/// The line naming the parameters the masks cannot set; `None` when there are none.
pub fn unseen_line(unseen: &[UnseenParam]) -> Option<String> {
    (!unseen.is_empty()).then(|| {
        format!(
            "the masks cannot set {}: over the whole range the mean IoU moves by less than the fit can tell, so the fitted value is what the search left, not a measurement. Set it from the frames' print or details (`frames` with `model: true`, a bake) and leave it out of the fit.\n",
            unseen
                .iter()
                .map(|u| format!("`{}` (IoU ±{:.4})", u.name, u.iou_span))
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

impl FitReport {
    pub fn read(path: &std::path::Path) -> crate::Result<FitReport> {
        let text = agentstar_data::read_text(path)?;
        serde_json::from_str(&text)
            .map_err(|e| agentstar_data::DataError::invalid(path, format!("not a fit report: {e}")))
    }
}

/// How `agentstar scale` measured the scale (the request's type, recorded as it was asked).
pub use agentstar_requests::ScaleMethod;

/// One keyframe's figure in a scale estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleFrame {
    pub frame: String,
    /// Its own ratio (depth, hand), or the object origin's distance from the common point
    /// after the fit, metres (parallax).
    pub value: f64,
    /// With the hand route: the palm's apparent breadth, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub palm_px: Option<f64>,
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
    /// Pixels (depth), frames (parallax, hand) or 1 (size).
    pub samples: usize,
    /// One standard deviation of the ratio, relative, where the route states one (hand:
    /// the palm prior's spread, the frames' spread and where the hand sits on the object).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<f64>,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn wants(x: f64, y: f64, z: Option<f64>) -> AxisWants {
        AxisWants {
            want: [Some(x), Some(y), z],
            equations: 6,
        }
    }

    #[test]
    fn the_verdict_names_the_proportion_the_axes_disagree_on() {
        let groups = vec![ViewGroup {
            face_on: "Z".into(),
            frames: vec!["a".into(), "b".into()],
            wants: wants(0.10, -0.02, None),
        }];
        let v = ViewResiduals::verdict_of(&wants(0.08, -0.02, Some(0.0)), &groups);
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(
            v[0].contains("longer along X (+8.0%) than along Y (-2.0%)"),
            "{v:?}"
        );
        assert!(v[0].contains("X:Y is off by ×1.102"), "{v:?}");
        assert!(
            v[0].contains("2 frame(s) face-on to Z: X +10.0% against Y -2.0%"),
            "{v:?}"
        );
        // A change common to every axis is the scale: no verdict.
        assert!(ViewResiduals::verdict_of(&wants(0.2, 0.2, Some(0.21)), &groups).is_empty());
        // One axis measured says nothing of a proportion.
        let one = AxisWants {
            want: [Some(0.1), None, None],
            equations: 2,
        };
        assert!(ViewResiduals::verdict_of(&one, &[]).is_empty());
    }

    #[test]
    fn unmet_sizes_are_named_with_their_axis_and_change() {
        assert_eq!(unmet_line(&[]), None);
        let line = unmet_line(&[
            UnmetAxis {
                axis: "X".into(),
                want: 0.017,
            },
            UnmetAxis {
                axis: "Z".into(),
                want: -0.012,
            },
        ])
        .expect("line");
        assert!(line.contains("along X +1.7%, Z -1.2%"), "{line}");
    }
}
