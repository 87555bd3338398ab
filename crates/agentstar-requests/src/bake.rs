//! The request of `bake`, as the MCP tool of the same name takes it (beside the model it
//! bakes) and the command flattens it.

use crate::FRAMES;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Which keyframes a bake gathers colours from, and whether it stores a bake whose frames
/// disagree.
#[derive(clap::Args, Debug, Clone, PartialEq, Default, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct BakeArgs {
    /// Keyframes to bake from (default: every keyframe with a written pose).
    #[arg(long, help = FRAMES)]
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Store the bake although some frames disagree with the others (their colours land
    /// on other texels than the rest put them: a pose in a twin, a wrong pose); without
    /// it such a bake is refused, naming the frames.
    #[arg(long)]
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub force: bool,
}
