//! The reports of the image commands (`render`, `turntable` with `--json`), written by the
//! binary and read by the tools, so the files a tool names and the counts it states are
//! the ones the command wrote.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// One frame of `render`: its files and scores, and the frames view's crop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderFrame {
    pub frame: String,
    pub files: Vec<PathBuf>,
    pub iou_visible: Option<f64>,
    /// The frames view's crop in frame pixels: x0, y0, width, height.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crop: Option<[u32; 4]>,
    /// Output pixels per frame pixel of the frames view (after the size limits).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zoom: Option<f64>,
    /// Which side of the model and of each part faces the camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub facing: Option<FrameFacing>,
}

/// A part's side toward the camera in one frame, in its own axes (its joints applied).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartFacing {
    pub part: String,
    /// The signed axis nearest the ray to the camera: `+X`, `-X`, `+Y`, `-Y`, `+Z`, `-Z`.
    pub toward: String,
    /// Degrees between that axis and the ray to the camera.
    pub angle_deg: f64,
    /// True when its joints move it from its rest place in this frame.
    pub moved: bool,
    /// Its pixels in view in the frame's render (not hidden by other parts).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixels_seen: Option<u64>,
}

/// Which side of the posed model faces the camera in one frame: the model's signed axis
/// nearest the ray from its centre to the camera, the angle of each of +X, +Y, +Z to that
/// ray (0°/180° face-on, 90° edge-on), and each part's own side.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameFacing {
    pub frame: String,
    pub toward: String,
    pub angle_deg: f64,
    pub axis_angles_deg: [f64; 3],
    pub parts: Vec<PartFacing>,
    /// The same in words, one line.
    pub line: String,
}

/// One line per frame: "FRAME: +Z toward the camera (12° off the ray …)".
pub fn facing_lines(facing: &[FrameFacing]) -> String {
    let mut t = String::new();
    if !facing.is_empty() {
        t.push_str("side toward the camera (model axes; 0°/180° face-on, 90° edge-on):\n");
    }
    for f in facing {
        t.push_str(&format!("  {}: {}\n", f.frame, f.line));
    }
    t
}

/// What `render --json` prints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderReport {
    pub out: PathBuf,
    pub frames: Vec<RenderFrame>,
    /// Every sheet written (overlay sheets, then frames sheets), pages in order; only
    /// files that exist.
    pub sheets: Vec<PathBuf>,
    pub notes: Vec<String>,
}

/// One joint state a turntable shows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurntableState {
    /// `rest`, `min`, `median`, `max` or a frame stem.
    pub label: String,
    /// Why this state: `rest`, `min`, `median`, `max` or the keyframe's name.
    pub source: String,
    /// Joint states in interface units (degrees, model units).
    pub joints: BTreeMap<String, f64>,
    pub sheets: Vec<PathBuf>,
}

/// What `turntable --json` prints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TurntableReport {
    pub states: Vec<TurntableState>,
    /// Every sheet written, in order.
    pub sheets: Vec<PathBuf>,
    /// Every file written (the sheets, and the single views with `--each`).
    pub files: Vec<PathBuf>,
    /// Joint limits that alias.
    pub warnings: Vec<String>,
    /// Joints piled at a limit over the keyframes.
    #[serde(default)]
    pub at_limit: Vec<crate::limits::JointAtLimit>,
}
