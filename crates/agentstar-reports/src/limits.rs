//! Joints piled at one end of their limit over the keyframes, as `temporal` and `turntable`
//! report them, and the ones an agent has acknowledged: a warning acknowledged (the same
//! joint, the same end of its limit, the same keyframes) is summarised in one line instead
//! of repeated; a new one still warns in full.

use serde::{Deserialize, Serialize};

/// Which end of a joint's limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LimitEnd {
    Lower,
    Upper,
}

impl LimitEnd {
    pub fn as_str(self) -> &'static str {
        match self {
            LimitEnd::Lower => "lower",
            LimitEnd::Upper => "upper",
        }
    }
}

/// A joint whose state sits at one end of its limit in many keyframes, not all: the limit
/// may be too tight, the axis reversed or the part built in the wrong place.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointAtLimit {
    pub joint: String,
    pub end: LimitEnd,
    /// The limit there, interface units (degrees, model units).
    pub bound: f64,
    /// The keyframes at it, in order.
    pub frames: Vec<String>,
    /// Keyframes in all.
    pub keyframes: usize,
}

/// Keyframes a warning names before it writes `…`.
const FRAMES_SHOWN: usize = 6;

impl JointAtLimit {
    /// The warning in full.
    pub fn warning(&self) -> String {
        let shown: Vec<&str> = self
            .frames
            .iter()
            .take(FRAMES_SHOWN)
            .map(String::as_str)
            .collect();
        format!(
            "joint `{}` sits at its {} limit {} in {} of {} keyframes ({}{}): the limit may be too tight, the axis reversed, or the part built in the wrong place; check it in the frames and with a turntable at the joint's min, median and max",
            self.joint,
            self.end.as_str(),
            self.bound,
            self.frames.len(),
            self.keyframes,
            shown.join(", "),
            if self.frames.len() > shown.len() { ", …" } else { "" }
        )
    }

    /// The same warning: the same joint, the same end and bound, the same keyframes.
    pub fn same_as(&self, other: &JointAtLimit) -> bool {
        self.joint == other.joint
            && self.end == other.end
            && (self.bound - other.bound).abs() <= 1e-9 * self.bound.abs().max(1.0)
            && self.frames == other.frames
    }
}

/// The joint-limit warnings an agent acknowledged (a run keeps them in
/// `.agentstar/limits_acknowledged.json`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AcknowledgedLimits {
    pub acknowledged: Vec<JointAtLimit>,
}

impl AcknowledgedLimits {
    pub fn covers(&self, found: &JointAtLimit) -> bool {
        self.acknowledged.iter().any(|a| a.same_as(found))
    }

    /// Acknowledges `found`; how many were not acknowledged before.
    pub fn acknowledge(&mut self, found: &[JointAtLimit]) -> usize {
        let mut added = 0;
        for f in found {
            if !self.covers(f) {
                self.acknowledged.push(f.clone());
                added += 1;
            }
        }
        added
    }

    /// The lines a reply shows for `found`: each warning not acknowledged in full, then the
    /// acknowledged ones (if any) in one short line.
    pub fn lines(&self, found: &[JointAtLimit]) -> Vec<String> {
        let (known, new): (Vec<&JointAtLimit>, Vec<&JointAtLimit>) =
            found.iter().partition(|f| self.covers(f));
        let mut out: Vec<String> = new.iter().map(|f| f.warning()).collect();
        if !known.is_empty() {
            let named: Vec<String> = known
                .iter()
                .map(|f| {
                    format!(
                        "`{}` at its {} limit in {} of {}",
                        f.joint,
                        f.end.as_str(),
                        f.frames.len(),
                        f.keyframes
                    )
                })
                .collect();
            out.push(format!(
                "joint-limit warning(s) acknowledged, unchanged: {}",
                named.join("; ")
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lid_at(end: LimitEnd, frames: &[&str]) -> JointAtLimit {
        JointAtLimit {
            joint: "lid".into(),
            end,
            bound: if end == LimitEnd::Lower { 0.0 } else { 120.0 },
            frames: frames.iter().map(|f| f.to_string()).collect(),
            keyframes: 8,
        }
    }

    #[test]
    fn an_acknowledged_warning_is_summarised_and_a_different_one_still_warns() {
        let lower = lid_at(LimitEnd::Lower, &["000000", "000002", "000004"]);
        let mut acked = AcknowledgedLimits::default();
        // Nothing acknowledged: the warning in full.
        assert_eq!(acked.lines(std::slice::from_ref(&lower)), [lower.warning()]);
        assert!(lower.warning().starts_with(
            "joint `lid` sits at its lower limit 0 in 3 of 8 keyframes (000000, 000002, 000004)"
        ));
        assert_eq!(acked.acknowledge(std::slice::from_ref(&lower)), 1);
        assert_eq!(acked.acknowledge(std::slice::from_ref(&lower)), 0);
        // Acknowledged: one short line, not the warning.
        let lines = acked.lines(std::slice::from_ref(&lower));
        assert_eq!(
            lines,
            ["joint-limit warning(s) acknowledged, unchanged: `lid` at its lower limit in 3 of 8"]
        );
        // The other end, or the same end in other keyframes, still warns in full.
        let upper = lid_at(LimitEnd::Upper, &["000001", "000003", "000005"]);
        let more = lid_at(LimitEnd::Lower, &["000000", "000002", "000004", "000006"]);
        let lines = acked.lines(&[lower.clone(), upper.clone(), more.clone()]);
        assert_eq!(lines.len(), 3, "{lines:?}");
        assert_eq!(lines[0], upper.warning());
        assert_eq!(lines[1], more.warning());
        assert!(lines[2].contains("acknowledged"), "{lines:?}");
        // Another joint too.
        let drawer = JointAtLimit {
            joint: "drawer".into(),
            ..lower.clone()
        };
        assert_eq!(
            acked.lines(std::slice::from_ref(&drawer)),
            [drawer.warning()]
        );
    }

    #[test]
    fn the_record_reads_back_and_refuses_unknown_fields() {
        let mut acked = AcknowledgedLimits::default();
        acked.acknowledge(&[lid_at(LimitEnd::Upper, &["a", "b", "c"])]);
        let text = serde_json::to_string(&acked).expect("json");
        assert!(text.contains("\"end\":\"upper\""), "{text}");
        assert_eq!(
            serde_json::from_str::<AcknowledgedLimits>(&text).expect("reads back"),
            acked
        );
        assert!(
            serde_json::from_str::<AcknowledgedLimits>(r#"{"acknowledged":[],"x":1}"#).is_err()
        );
    }
}
