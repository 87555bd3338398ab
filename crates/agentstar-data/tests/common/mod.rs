//! Helpers shared by this crate's capture tests.
#![allow(dead_code)]

use agentstar_data::capture::Capture;
use std::path::Path;

/// Every problem `Capture::validate` finds in the capture at `dir`, one a line.
pub fn problems(dir: &Path) -> String {
    Capture::validate(dir)
        .iter()
        .map(|p| p.to_string())
        .collect::<Vec<_>>()
        .join("\n")
}
