//! The report of `agentstar mechanism --json`: per articulated joint, the two blind arms
//! (the joint swept about its declared axis and about the negated axis) as sheets, the
//! states shown, and which label is the declared axis. The harness keeps that last field
//! to itself: the text and images an agent sees never say which arm is declared.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A joint state (or any figure) as the sheets' labels and the tools' text write it, so an
/// agent can cite it back: at most three decimals, no trailing zeros, no `-0`.
pub fn state_text(v: f64) -> String {
    let t = format!("{v:.3}");
    let t = t.trim_end_matches('0').trim_end_matches('.');
    if t == "-0" {
        "0".into()
    } else {
        t.to_string()
    }
}

/// A blind arm label.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ArmLabel {
    A,
    B,
}

impl ArmLabel {
    pub fn as_str(self) -> &'static str {
        match self {
            ArmLabel::A => "A",
            ArmLabel::B => "B",
        }
    }

    /// The other label.
    pub fn other(self) -> ArmLabel {
        match self {
            ArmLabel::A => ArmLabel::B,
            ArmLabel::B => ArmLabel::A,
        }
    }
}

/// One viewpoint of a joint's sheets, in the model's canonical frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanismView {
    /// Unit direction from the object towards the eye.
    pub direction: [f64; 3],
    /// Angle between the line of sight and the swing plane (the plane the axis is normal
    /// to), degrees: 90 looks along the axis, 0 is edge-on.
    pub off_swing_plane_deg: f64,
}

/// The keyframe that shows the joint's part most open and in view, cropped around its mask,
/// for comparison: openness (the joint's distance from its held state) weighed by the share
/// of the part's pixels in view that no hand covers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanismFrame {
    pub frame: String,
    /// The joint's state there in interface units (degrees, model units).
    pub state: f64,
    pub image: PathBuf,
    /// The parts the joint moves (its own and those of the joints below it).
    #[serde(default)]
    pub parts: Vec<String>,
    /// The share (0 to 1) of those parts' rendered pixels in view there that the hand mask
    /// leaves uncovered (0 where they show no pixel).
    #[serde(default)]
    pub part_in_view_share: f64,
    /// The most open keyframe, where it is not the one shown: its hands hide more of the
    /// parts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub more_open: Option<MechanismFramePassedOver>,
}

/// A keyframe more open than the one shown, passed over because less of the part is in view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanismFramePassedOver {
    pub frame: String,
    /// The joint's state there in interface units.
    pub state: f64,
    /// As [`MechanismFrame::part_in_view_share`].
    pub part_in_view_share: f64,
}

/// One joint swept through its range twice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanismJoint {
    pub joint: String,
    /// `revolute`, `continuous` or `prismatic`.
    pub kind: String,
    /// `deg` or `units` (model units).
    pub unit: String,
    /// The declared axis, as the scene writes it.
    pub axis: [f64; 3],
    /// The range swept, interface units (a continuous joint sweeps a full turn).
    pub range: [f64; 2],
    /// The states shown, interface units, in sheet order; the first and last are the
    /// range's ends, the others interior.
    pub states: Vec<f64>,
    /// Sheets of arm A (pages in order): one row per view, one column per state.
    pub sheets_a: Vec<PathBuf>,
    /// Sheets of arm B.
    pub sheets_b: Vec<PathBuf>,
    pub views: Vec<MechanismView>,
    /// The keyframe that shows the joint's part most open and in view, when the poses say.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<MechanismFrame>,
    /// The label of the arm about the declared axis (the other is about its negation):
    /// decided by a seeded coin per joint. Never shown to the agent.
    pub declared: ArmLabel,
}

impl MechanismJoint {
    /// The states strictly inside the range.
    pub fn interior(&self) -> &[f64] {
        match self.states.len() {
            0..=2 => &[],
            n => &self.states[1..n - 1],
        }
    }

    /// The sheets of `label`.
    pub fn sheets(&self, label: ArmLabel) -> &[PathBuf] {
        match label {
            ArmLabel::A => &self.sheets_a,
            ArmLabel::B => &self.sheets_b,
        }
    }
}

/// What `mechanism --json` prints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanismReport {
    pub out: PathBuf,
    /// The coin's seed.
    pub seed: u64,
    /// Where the other joints are held: `rest` or a keyframe's name.
    pub hold: String,
    pub joints: Vec<MechanismJoint>,
    /// Joints not swept and why (fixed joints, joints not asked for).
    pub notes: Vec<String>,
}
