//! `scale`'s choices, as its command parses them, its tool takes them and its report records
//! them: one type each.

use serde::{Deserialize, Serialize};

/// How `agentstar scale` measured the scale.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum ScaleMethod {
    /// Observed over rendered depth (the capture has depth).
    Depth,
    /// Metric cameras that move around an object that stays put.
    Parallax,
    /// A size the agent states along one model axis.
    Size,
    /// The hands' apparent palm breadth against an adult-hand prior, the hand at the
    /// object's depth (hand masks, no depth): the weakest route, with its uncertainty.
    Hand,
}

impl ScaleMethod {
    /// The name the command line, the tool and the report use.
    pub fn as_str(self) -> &'static str {
        match self {
            ScaleMethod::Depth => "depth",
            ScaleMethod::Parallax => "parallax",
            ScaleMethod::Size => "size",
            ScaleMethod::Hand => "hand",
        }
    }
}

/// A model axis a stated size is along.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, schemars::JsonSchema, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum SizeAxis {
    X,
    Y,
    Z,
    Longest,
}
