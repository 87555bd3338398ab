//! The requests of `turntable` and `pose-diff`, as the MCP tools of the same names take them
//! and the commands flatten them.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The joint states a turntable shows.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct TurntableArgs {
    /// Joint states to show: `representative` (each joint's min, median and max over the
    /// keyframes; the default), `all` (every distinct state: many sheets), keyframes in
    /// the frame grammar (`000010,000040`), or states given outright (degrees, canonical
    /// units; joints not named at rest): `hinge:90|hinge:0;drawer:0.2`, one sheet each, also
    /// before any pose is tracked.
    #[arg(long)]
    #[schemars(length(min = 1, max = 4000))]
    pub states: Option<String>,
}

impl TurntableArgs {
    /// The states to show (`representative` when none are named).
    pub fn states(&self) -> &str {
        self.states
            .as_deref()
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .unwrap_or("representative")
    }
}

/// The two keyframes whose poses `pose-diff` compares.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct PoseDiffArgs {
    #[arg(long, help = "The first keyframe.")]
    #[schemars(length(min = 1))]
    pub a: String,
    #[arg(long, help = "The second keyframe.")]
    #[schemars(length(min = 1))]
    pub b: String,
}
