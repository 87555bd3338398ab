//! The one serialisable record of a sequence's metrics: what `eval --json` prints, what the
//! benchmark stores per sequence and `batch gather` tables, each beside its own context
//! (a run's paths, a suite's sequence id and wall time). Built from [`SequenceMetrics`] by
//! `From`, so the three never copy fields by hand or rename them.

use crate::sequence::{JointMetrics, SequenceMetrics};
use serde::{Deserialize, Serialize};

/// One ground-truth joint's articulation errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointRecord {
    pub gt_joint: String,
    pub pred_joint: Option<String>,
    /// How the predicted joint was matched to it (`name`, `nearest moving parts`,
    /// `unmatched`, …).
    #[serde(default)]
    pub matched_by: String,
    /// True for a revolute ground-truth joint, false for a prismatic one.
    #[serde(default)]
    pub revolute: bool,
    /// The angle between the axes, radians. (Benchmark files before 2026-12-04 called it
    /// `axis_rad`.)
    #[serde(alias = "axis_rad")]
    pub axis_angle_rad: Option<f64>,
    /// The distance between the axis lines, metres (revolute joints only; `position_m`
    /// before 2026-12-04).
    #[serde(alias = "position_m")]
    pub axis_distance_m: Option<f64>,
    /// The joint state's error: radians (revolute) or metres (prismatic; `state` before
    /// 2026-12-04).
    #[serde(alias = "state")]
    pub state_error: Option<f64>,
}

impl From<&JointMetrics> for JointRecord {
    fn from(j: &JointMetrics) -> JointRecord {
        JointRecord {
            gt_joint: j.gt_joint.clone(),
            pred_joint: j.pred_joint.clone(),
            matched_by: j.matched_by.to_string(),
            revolute: j.revolute,
            axis_angle_rad: j.axis_angle_rad,
            axis_distance_m: j.axis_distance_m,
            state_error: j.state_error,
        }
    }
}

/// A sequence's metrics (`formats.md` §5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetricsRecord {
    pub frames: usize,
    pub scale_alignment: f64,
    pub epe_cm: Option<f64>,
    /// Query points the EPE was measured on.
    #[serde(default)]
    pub epe_points: usize,
    pub chamfer_cm: Option<f64>,
    #[serde(default)]
    pub cd_moving_cm: Option<f64>,
    #[serde(default)]
    pub cd_static_cm: Option<f64>,
    /// The iTACO table's squared Chamfer (m²) on the whole object, the moving parts and the
    /// static part.
    pub cd_w_m2: Option<f64>,
    pub cd_m_m2: Option<f64>,
    pub cd_s_m2: Option<f64>,
    pub rotation_mean_deg: Option<f64>,
    pub rotation_median_deg: Option<f64>,
    pub translation_mean_cm: Option<f64>,
    pub translation_median_cm: Option<f64>,
    pub joints: Vec<JointRecord>,
}

impl From<&SequenceMetrics> for MetricsRecord {
    fn from(m: &SequenceMetrics) -> MetricsRecord {
        let rigid = m.rigid.as_ref();
        MetricsRecord {
            frames: m.frames,
            scale_alignment: m.scale_alignment,
            epe_cm: m.epe_cm,
            epe_points: m.epe_points,
            chamfer_cm: m.chamfer_cm,
            cd_moving_cm: m.cd_moving_cm,
            cd_static_cm: m.cd_static_cm,
            cd_w_m2: m.cd_sq_whole_m2,
            cd_m_m2: m.cd_sq_moving_m2,
            cd_s_m2: m.cd_sq_static_m2,
            rotation_mean_deg: rigid.map(|r| r.rotation_mean_deg),
            rotation_median_deg: rigid.map(|r| r.rotation_median_deg),
            translation_mean_cm: rigid.map(|r| r.translation_mean_cm),
            translation_median_cm: rigid.map(|r| r.translation_median_cm),
            joints: m.joints.iter().map(JointRecord::from).collect(),
        }
    }
}

impl MetricsRecord {
    /// The mean of a joint figure over the joints that have it.
    pub fn joint_mean(&self, f: impl Fn(&JointRecord) -> Option<f64>) -> Option<f64> {
        let v: Vec<f64> = self.joints.iter().filter_map(f).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_joint_record_reads_the_names_older_benchmark_files_used() {
        let old = r#"{"gt_joint":"lid","pred_joint":"lid","revolute":true,"axis_rad":0.01,"position_m":0.002,"state":0.03}"#;
        let j: JointRecord = serde_json::from_str(old).expect("old record");
        assert_eq!(j.axis_angle_rad, Some(0.01));
        assert_eq!(j.axis_distance_m, Some(0.002));
        assert_eq!(j.state_error, Some(0.03));
        assert!(j.revolute);
        let again: JointRecord =
            serde_json::from_str(&serde_json::to_string(&j).expect("json")).expect("new record");
        assert_eq!(again, j);
    }

    #[test]
    fn the_joint_mean_skips_joints_without_the_figure() {
        let joint = |s: Option<f64>| JointRecord {
            gt_joint: "j".into(),
            pred_joint: None,
            matched_by: "unmatched".into(),
            revolute: true,
            axis_angle_rad: None,
            axis_distance_m: None,
            state_error: s,
        };
        let r = MetricsRecord {
            frames: 2,
            scale_alignment: 1.0,
            epe_cm: None,
            epe_points: 0,
            chamfer_cm: None,
            cd_moving_cm: None,
            cd_static_cm: None,
            cd_w_m2: None,
            cd_m_m2: None,
            cd_s_m2: None,
            rotation_mean_deg: None,
            rotation_median_deg: None,
            translation_mean_cm: None,
            translation_median_cm: None,
            joints: vec![joint(Some(0.2)), joint(None), joint(Some(0.4))],
        };
        assert!((r.joint_mean(|j| j.state_error).expect("mean") - 0.3).abs() < 1e-12);
        assert_eq!(r.joint_mean(|j| j.axis_angle_rad), None);
    }
}
