//! What `track` reports: its `--json` report, `--bake`'s part of it and the frames a warm
//! start moved to another basin.

use crate::{FrameScore, SequenceScore};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What `track --json` prints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackReport {
    /// The pose file written.
    pub poses: PathBuf,
    pub seconds: f64,
    pub evaluations: usize,
    pub init_frame: String,
    /// What the tracker did, frame by frame.
    pub log: Vec<String>,
    pub frames: Vec<FrameScore>,
    pub sequence: SequenceScore,
    /// The version of the pose file's history the result was recorded as.
    #[serde(default)]
    pub pose_version: Option<u64>,
    /// `track --from --keep-basins`: every frame refined within its own basin.
    #[serde(default)]
    pub keep_basins: bool,
    /// `track --from` without `--keep-basins`: the frames it moved to another basin (turned
    /// further from their starting pose than the basin's bound), with the evidence.
    #[serde(default)]
    pub basin_moves: Vec<BasinMoveRow>,
    /// `track --bake`: the frames the outline alone settles, the bake from them and the
    /// frames the baked colours moved to another basin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bake: Option<TrackBakeReport>,
    /// The turns the frames' colours wanted and the video's motion refused, still apart from
    /// the frames' poses: the frames to check first.
    #[serde(default)]
    pub refused_turns: Vec<RefusedTurnRow>,
}

/// A turn a keyframe's colours wanted that the tracker refused because the video's motion
/// from a neighbouring keyframe keeps the frame where it is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefusedTurnRow {
    pub frame: String,
    /// The turn and its evidence (the frame's colours and IoU before and after it).
    pub what: String,
}

/// The lines for people of the refused turns (none for none): what the video cannot settle
/// and how to check it.
pub fn refused_turns_text(rows: &[RefusedTurnRow]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let mut text = format!(
        "{} frame(s) whose colours wanted a turn that the video's motion refused (a chain cannot tell every twin apart: a capsule's outline is the same end over end); look at them (`render` with `side`, `oapply` with `order: model` and `hold: true`):\n",
        rows.len()
    );
    for r in rows {
        text.push_str(&format!("  {}: {}\n", r.frame, r.what));
    }
    text
}

/// What became of `track --bake`'s bake.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackBakeOutcome {
    /// Baked from the settled frames and tracked again with the colours.
    Used,
    /// Too few frames settled by the outline alone: nothing baked, the plain track kept.
    TooFewSettled,
    /// The settled frames disagree with each other, fewer than two agreeing: nothing used,
    /// the plain track kept.
    Refused,
}

/// One keyframe as `track --bake` judged it: does its outline alone settle its basin?
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SettledRow {
    pub frame: String,
    /// The frame's score (gate IoU) at its plain-track pose.
    pub iou: f64,
    /// The best pose of another basin after refinement: how far it turns (degrees) and its
    /// score; `None`: no pose of another basin came near.
    pub rival_deg: Option<f64>,
    pub rival_iou: Option<f64>,
    pub settled: bool,
}

/// `track --bake`'s part of the track report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackBakeReport {
    pub outcome: TrackBakeOutcome,
    /// Every keyframe's verdict.
    pub frames: Vec<SettledRow>,
    /// The frames baked from (the settled ones with an image).
    pub baked_from: Vec<String>,
    /// The fewest settled frames a bake needs.
    pub min_settled: usize,
    /// Texels of the model's surface and how many the settled frames saw (none: nothing baked).
    pub surface_texels: Option<usize>,
    pub seen_texels: Option<usize>,
    /// Settled frames that disagree with the others (the bake refused), the worst first.
    /// Where the bake was used after leaving some out, see `left_out`.
    pub disagreeing: Vec<String>,
    /// Settled frames left out of the bake used because their colours disagreed with the
    /// others' (a pose a few degrees off, or in a twin), in frame order.
    #[serde(default)]
    pub left_out: Vec<String>,
    /// The frames the baked colours moved to another basin (from the plain track's pose).
    pub basin_moves: Vec<BasinMoveRow>,
    /// Where the bake was stored (`--store-bake`); `None`: it lived in memory only.
    pub stored: Option<PathBuf>,
}

impl TrackBakeReport {
    /// The bake's lines for a person or a model: which keyframes settled, what became of the
    /// bake and the frames it moved (`track --bake` prints them; the `track` tool replies
    /// with them). Where it was stored is the caller's to say.
    pub fn lines(&self) -> Vec<String> {
        let settled: Vec<&str> = self
            .frames
            .iter()
            .filter(|f| f.settled)
            .map(|f| f.frame.as_str())
            .collect();
        let mut lines = vec![format!(
            "bake: {} of {} keyframe(s) settled by the outline alone{}",
            settled.len(),
            self.frames.len(),
            if settled.is_empty() {
                String::new()
            } else {
                format!(" ({})", settled.join(", "))
            }
        )];
        match self.outcome {
            TrackBakeOutcome::TooFewSettled => lines.push(format!(
                "bake: nothing baked ({} needed): every other keyframe's outline is explained as well by another basin (a symmetry of the shape that only colours can break); the plain track is kept",
                self.min_settled
            )),
            TrackBakeOutcome::Refused => lines.push(format!(
                "bake: refused: settled keyframe(s) {} disagree with the others; the plain track is kept",
                self.disagreeing.join(", ")
            )),
            TrackBakeOutcome::Used => {
                if !self.left_out.is_empty() {
                    lines.push(format!(
                        "bake: left out {}: their colours disagree with the other settled keyframes' (a pose a few degrees off, or in a twin)",
                        self.left_out.join(", ")
                    ));
                }
                lines.push(format!(
                    "bake: baked from {} ({} of {} texels seen); {} keyframe(s) moved to another basin by the baked colours{}",
                    self.baked_from.join(", "),
                    self.seen_texels.unwrap_or(0),
                    self.surface_texels.unwrap_or(0),
                    self.basin_moves.len(),
                    if self.basin_moves.is_empty() { "" } else { ":" }
                ));
                lines.extend(self.basin_moves.iter().map(|m| format!("  {}", m.line())));
            }
        }
        lines
    }
}

/// A frame `track --from` moved to another basin.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BasinMoveRow {
    pub frame: String,
    /// The rotation from its starting pose to the tracked one, degrees.
    pub rotation_deg: f64,
    /// The bound it passed (the basin's half-width), degrees.
    pub bound_deg: f64,
    /// The gate IoU at its starting pose and at the tracked one.
    pub iou_before: f64,
    pub iou_after: f64,
    /// The tracker's pass that moved it.
    pub pass: String,
    /// For a round body (an outline symmetric about an axis of the model): the same rotation
    /// leaving out its turn about that axis, degrees. Within the bound, the frame turned about
    /// the axis only: its outline is the one it had, and the print (or a part off the axis)
    /// decided.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub across_axis_deg: Option<f64>,
}

impl BasinMoveRow {
    /// Whether the frame turned about its round body's axis only ([`Self::across_axis_deg`]
    /// within the bound).
    pub fn about_round_axis(&self) -> bool {
        self.across_axis_deg.is_some_and(|a| a <= self.bound_deg)
    }

    /// One line for people: `000003.png: turned 179.2° (bound 45°), IoU 0.41 → 0.99, by …`;
    /// a turn about a round body's axis says so.
    pub fn line(&self) -> String {
        let turn = match self.across_axis_deg {
            Some(across) if self.about_round_axis() => format!(
                "turned {:.1}° about the body's round axis ({across:.1}° across it: the outline is the same, the print or a part off the axis decided)",
                self.rotation_deg
            ),
            _ => format!(
                "turned {:.1}° from its starting pose (bound {}°)",
                self.rotation_deg, self.bound_deg
            ),
        };
        format!(
            "{}: {turn}, IoU {:.4} → {:.4}, by {}",
            self.frame, self.iou_before, self.iou_after, self.pass
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(across_axis_deg: Option<f64>) -> BasinMoveRow {
        BasinMoveRow {
            frame: "000024.png".into(),
            rotation_deg: 92.0,
            bound_deg: 45.0,
            iou_before: 0.97,
            iou_after: 0.98,
            pass: "the appearance pass".into(),
            across_axis_deg,
        }
    }

    #[test]
    fn a_turn_about_a_round_axis_only_says_so_and_a_turn_across_it_is_a_basin_move() {
        // A round body turned about its axis: the same outline (play-test, 2026-12-05: such a
        // turn read as a move to another basin).
        let about = row(Some(1.5));
        assert!(about.about_round_axis());
        let line = about.line();
        assert!(
            line.contains("about the body's round axis") && line.contains("1.5° across it"),
            "{line}"
        );
        // Across the axis beyond the bound, or no round axis at all: the plain move.
        for r in [row(Some(60.0)), row(None)] {
            assert!(!r.about_round_axis());
            let line = r.line();
            assert!(
                line.contains("turned 92.0° from its starting pose (bound 45°)"),
                "{line}"
            );
        }
        // Reports written before the field read as no round axis, and it is left out of
        // those without one.
        let old = r#"{"frame": "000003.png", "rotation_deg": 179.2, "bound_deg": 45.0,
            "iou_before": 0.41, "iou_after": 0.99, "pass": "the sequence choice"}"#;
        let parsed: BasinMoveRow = serde_json::from_str(old).expect("an older report");
        assert_eq!(parsed.across_axis_deg, None);
        let json = serde_json::to_string(&row(None)).expect("json");
        assert!(!json.contains("across_axis_deg"), "{json}");
    }
}
