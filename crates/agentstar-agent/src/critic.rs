//! The critic: a separate model call that sees a keyframe, the model drawn over it and a
//! turntable view, and returns JSON: realism and identity scores, and discrepancies tagged
//! `shape`, `pose`, `joint_state` or `joint_definition`, each with a severity and a
//! direction of change (never a precise number).

use crate::llm::{complete, Message, ModelConfig, Part};
use serde_json::Value;
use std::path::PathBuf;

const PROMPT: &str = "You are a strict critic of a 3-D reconstruction. You see, in order: a video keyframe of an object, the reconstructed model drawn over that keyframe (and a silhouette comparison: green agree, red object not covered, blue model outside the object, grey hand), and turntable views of the model. Judge whether the model is the same object in the same pose. Answer with JSON only, no prose: {\"realism\": 0-1, \"identity\": 0-1, \"discrepancies\": [{\"tag\": \"shape\"|\"pose\"|\"joint_state\"|\"joint_definition\", \"severity\": \"low\"|\"medium\"|\"high\", \"where\": \"which part or region\", \"direction\": \"what to change, in words (e.g. lid opens further, handle too thin), never a number\"}]}.";

/// Asks `model` about `frame` with `images`; returns the critic's JSON (checked) as text.
pub fn criticise(model: &ModelConfig, frame: &str, images: &[PathBuf]) -> Result<String, String> {
    let mut parts = vec![Part::Text(format!("Keyframe {frame}."))];
    for p in images {
        parts.push(Part::image(p).map_err(|e| format!("{}: {e}", p.display()))?);
    }
    let reply = complete(model, PROMPT, &[Message::User(parts)], &[], &|_, _| {})
        .map_err(|e| e.to_string())?;
    let text = reply.text.trim();
    let json = text
        .trim_start_matches("```json")
        .trim_start_matches("```")
        .trim_end_matches("```")
        .trim();
    let v: Value = serde_json::from_str(json)
        .map_err(|e| format!("the critic did not answer JSON ({e}): {text}"))?;
    for key in ["realism", "identity"] {
        if !v[key].as_f64().is_some_and(|x| (0.0..=1.0).contains(&x)) {
            return Err(format!("the critic's `{key}` is not a number in 0–1: {v}"));
        }
    }
    if !v["discrepancies"].is_array() {
        return Err(format!("the critic gave no `discrepancies` list: {v}"));
    }
    Ok(serde_json::to_string_pretty(&v).unwrap_or_else(|_| v.to_string()))
}
