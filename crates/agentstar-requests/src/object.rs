//! The object-frame pose verbs' requests: what `osweep`, `oapply` and `oapply-all` search,
//! as the MCP tools of the same names take it and the commands flatten it (each command
//! adds its tuning flags and the session's inputs). The candidate sheet's `crop` and `zoom`
//! are not here: the tools take each request as `WithSheet<…>` ([`crate::sheet`]), and the
//! commands read them among the options every search verb shares.

use crate::FRAMES;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// How `osweep` and `oapply` rank their rows.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum RowOrder {
    /// By the mask (the combined IoU score), best first: the default.
    #[default]
    Iou,
    /// By the frame's colours against the model's own (the `model` figure), best first;
    /// rows without that figure last, ties by the mask. Among rows whose outlines tie, the
    /// basin the print settles comes first.
    Model,
}

/// Where `osweep` searches: a preset or grid ranges, in some keyframes.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct OsweepArgs {
    #[arg(long, help = FRAMES)]
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// A preset: `z:flip`, `z:quarters`, `z:octants`, `so3:24`. Give this or `ranges`.
    #[arg(long)]
    pub opreset: Option<String>,
    /// Grid ranges over rx, ry, rz (degrees) and joints: `rz:-180,180,9;rx:-15,15,3`, each
    /// `dof:lower,upper,steps` with `steps` grid values from lower to upper, both included.
    /// The grid is then refined around its best points (finer spacing) and every candidate
    /// refined locally before ranking: each row names its grid start and, after `→`, the
    /// rotation (one rotation vector, as `oapply` reads it) and joint states it was refined to.
    /// Give this or `opreset`.
    #[arg(long)]
    pub ranges: Option<String>,
    /// How the rows are ranked: `iou` (the mask; default) or `model` (the frame's colours
    /// against the model's own, best first): to find among many rows the one the print
    /// settles where the outlines tie. Read each row's IoU before committing it.
    #[arg(long, value_enum)]
    pub order: Option<RowOrder>,
    /// Keep each grid point's turn as asked, as `oapply`'s `hold` does: the refinement moves
    /// the position and the joints as far as usual, the rotation at most 3°. With `order:
    /// model`, a grid of turns about a round body's axis ranked by the print, which the
    /// mask alone would pull back to the frame's pose.
    #[arg(long)]
    #[serde(default)]
    pub hold: bool,
}

/// Where an `osweep` searches: its preset or its grid ranges ([`OsweepArgs::region`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region<'a> {
    Preset(&'a str),
    Ranges(&'a str),
}

impl OsweepArgs {
    /// The region to search: exactly one of `opreset` and `ranges`. The region is the
    /// caller's decision: there is no default grid, and two at once are refused. The
    /// command and the tool both ask this before anything is searched.
    pub fn region(&self) -> Result<Region<'_>, String> {
        match (self.opreset.as_deref(), self.ranges.as_deref()) {
            (Some(preset), None) => Ok(Region::Preset(preset)),
            (None, Some(ranges)) => Ok(Region::Ranges(ranges)),
            (None, None) => Err("osweep needs a region and searched nothing: give `opreset` (`z:flip`, `z:quarters`, `z:octants`, `so3:24`) or `ranges` (`rz:-180,180,9;rx:-15,15,3`), and `frames` (default: every keyframe)".into()),
            (Some(_), Some(_)) => {
                Err("osweep takes `opreset` or `ranges`, not both: nothing was searched".into())
            }
        }
    }
}

/// What `oapply` scores: a set of object-frame rotations, in some keyframes.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct OapplyArgs {
    #[arg(long, help = FRAMES)]
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// `flips`, `swaps` (for each hinge, the half-turn that puts its two sides in each
    /// other's place: a laptop's lid and base), `folds` (the turns that map the model's
    /// outline onto itself about its own n-fold axes: a square prism's quarter turns, a
    /// triangular prism's thirds, and the half-turns across them, each about the axis
    /// through the section's centroid), or candidates separated by `|`, terms by `;`:
    /// `identity|flip:x|rz:90;rx:10|swaps`; a term `JOINT:value` sets a joint in that
    /// candidate (degrees, or canonical units for a prismatic joint): `flip:x;hinge:115`.
    #[arg(long)]
    pub set: Option<String>,
    /// Keep each candidate's turn as asked: its refinement still moves the position and the
    /// joints as far as usual, but the rotation at most 3°. For a turn that
    /// the mask alone would undo while you know it is right (a print or a part the outline
    /// does not show: a turn about a nearly round body's axis).
    #[arg(long)]
    #[serde(default)]
    pub hold: bool,
    /// How the rows are ranked: `iou` (the mask; default) or `model` (the frame's colours
    /// against the model's own, best first). Read each row's IoU before committing it.
    #[arg(long, value_enum)]
    pub order: Option<RowOrder>,
}

impl OapplyArgs {
    /// How far a held candidate's refinement may turn it ([`OapplyArgs::hold`]).
    pub const HOLD_TURN_DEG: f64 = 3.0;

    /// The set when none is named.
    pub const DEFAULT_SET: &'static str = "flips|swaps|folds";

    /// The set to score.
    pub fn set(&self) -> &str {
        self.set
            .as_deref()
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .unwrap_or(Self::DEFAULT_SET)
    }
}

/// The one rotation `oapply-all` applies, to every keyframe or a block of them.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct OapplyAllArgs {
    /// One rotation: `rz:90;rx:10` (rotation vector, degrees) or `flip:x|y|z`.
    #[arg(long)]
    #[schemars(length(min = 1))]
    pub rotation: String,
    #[arg(long, help = FRAMES)]
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
}
