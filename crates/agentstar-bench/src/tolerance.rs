//! Accuracy tolerances: recorded from a run (each figure with a margin) and checked against
//! later runs, so that a change that makes the tracker worse fails CI.

use crate::run::SequenceResult;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Figures that must stay under their recorded bound, with the absolute floor of each margin.
pub const UPPER: [(&str, f64); 6] = [
    ("epe_cm", 0.5),
    ("chamfer_cm", 0.3),
    ("rotation_median_deg", 1.0),
    ("translation_median_cm", 0.5),
    ("joint_axis_rad", 0.03),
    ("joint_state", 0.03),
];
/// Figures that must stay over their recorded bound, with the margin.
pub const LOWER: [(&str, f64); 1] = [("iou_mean", 0.02)];

/// The bounds of one sequence and method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tolerance {
    pub id: String,
    pub method: String,
    pub max: BTreeMap<String, f64>,
    pub min: BTreeMap<String, f64>,
}

/// A tolerance file (`bench/<suite>.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToleranceFile {
    pub suite: String,
    /// Where and when the bounds were recorded.
    pub recorded: String,
    pub entries: Vec<Tolerance>,
}

/// Bounds from `results`: an upper bound of twice the figure plus the floor, a lower bound of
/// the figure less the margin.
pub fn record(results: &[SequenceResult], suite: &str, recorded: &str) -> ToleranceFile {
    let mut entries: Vec<Tolerance> = results
        .iter()
        .map(|r| Tolerance {
            id: r.info.id.clone(),
            method: r.info.method.clone(),
            max: UPPER
                .iter()
                .filter_map(|&(name, floor)| {
                    r.metric(name).map(|v| (name.to_string(), 2.0 * v + floor))
                })
                .collect(),
            min: LOWER
                .iter()
                .filter_map(|&(name, margin)| {
                    r.metric(name).map(|v| (name.to_string(), v - margin))
                })
                .collect(),
        })
        .collect();
    entries.sort_by(|a, b| (&a.id, &a.method).cmp(&(&b.id, &b.method)));
    ToleranceFile {
        suite: suite.into(),
        recorded: recorded.into(),
        entries,
    }
}

/// Every bound that `results` break, as sentences; a recorded sequence that did not run
/// is a violation too. Empty when all hold.
pub fn check(results: &[SequenceResult], file: &ToleranceFile) -> Vec<String> {
    let mut out = Vec::new();
    for t in &file.entries {
        let Some(r) = results
            .iter()
            .find(|r| r.info.id == t.id && r.info.method == t.method)
        else {
            out.push(format!(
                "{} ({}): recorded in the tolerances but not run",
                t.id, t.method
            ));
            continue;
        };
        let bounds = t.max.iter().map(|(n, b)| (n, b, true));
        for (name, bound, upper) in bounds.chain(t.min.iter().map(|(n, b)| (n, b, false))) {
            let broken = match r.metric(name) {
                Some(v) if upper && v > *bound => {
                    format!("{name} = {v:.4} exceeds its bound {bound:.4}")
                }
                Some(v) if !upper && v < *bound => {
                    format!("{name} = {v:.4} is under its bound {bound:.4}")
                }
                Some(_) => continue,
                None => format!("{name} was not computed (bound {bound:.4})"),
            };
            out.push(format!("{} ({}): {broken}", t.id, t.method));
        }
    }
    out
}
