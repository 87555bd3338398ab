//! A run's ledger, `ledger.jsonl`: one JSON object per step (tool, arguments, summary,
//! scores, images written, scene and pose versions), appended as the run goes.
//!
//! Appending writes one whole line with a single `write` on a file opened for appending and
//! syncs it, so a crash leaves at most one truncated last line; the reader skips such a line
//! and says so, and every earlier step stays readable (a run resumes from them). The next
//! append starts a new line after a truncated one, so the step after a crash is kept.

use crate::{DataError, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

/// One step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LedgerEntry {
    /// 1, 2, 3, … in the order taken.
    pub step: u64,
    /// Seconds since the run started.
    pub time_s: f64,
    /// `shape`, `pose`, `diagnostic`, `note` or `system`.
    pub kind: String,
    /// The tool (`sweep`, `scene_edit`, `track`, …).
    pub tool: String,
    #[serde(default, skip_serializing_if = "serde_json::Value::is_null")]
    pub args: serde_json::Value,
    #[serde(default)]
    pub summary: String,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub scores: BTreeMap<String, f64>,
    /// Images the step produced, relative to the run directory.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub images: Vec<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_version: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_version: Option<u64>,
}

/// Appends one entry as a line.
pub fn append(path: &Path, entry: &LedgerEntry) -> Result<()> {
    let mut line = serde_json::to_string(entry)
        .map_err(|e| DataError::invalid(path, format!("cannot encode a ledger entry: {e}")))?;
    line.push('\n');
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .read(true)
        .append(true)
        .open(path)
        .map_err(|e| DataError::io(path, e))?;
    // A line cut short by a crash has no newline: without one here this entry would be
    // glued to it and lost with it. (Two writers that both see it add an empty line, which
    // the reader skips.)
    if ends_mid_line(&mut f).map_err(|e| DataError::io(path, e))? {
        line.insert(0, '\n');
    }
    f.write_all(line.as_bytes())
        .and_then(|_| f.sync_data())
        .map_err(|e| DataError::io(path, e))
}

/// Whether `f` is not empty and its last byte is not a newline.
fn ends_mid_line(f: &mut std::fs::File) -> std::io::Result<bool> {
    use std::io::{Read, Seek, SeekFrom};
    if f.metadata()?.len() == 0 {
        return Ok(false);
    }
    f.seek(SeekFrom::End(-1))?;
    let mut last = [0u8; 1];
    f.read_exact(&mut last)?;
    Ok(last[0] != b'\n')
}

/// Reads a ledger: the entries, and a note for each line that could not be read (a
/// truncated last line after a crash, or a line that is not an entry).
pub fn read(path: &Path) -> Result<(Vec<LedgerEntry>, Vec<String>)> {
    let text = crate::read_text(path)?;
    let mut entries = vec![];
    let mut notes = vec![];
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<LedgerEntry>(line) {
            Ok(e) => entries.push(e),
            Err(e) => notes.push(format!("{}: line {} skipped ({e})", path.display(), i + 1)),
        }
    }
    Ok((entries, notes))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(step: u64) -> LedgerEntry {
        LedgerEntry {
            step,
            time_s: step as f64 * 1.5,
            kind: "pose".into(),
            tool: "sweep".into(),
            args: serde_json::json!({"frame": "000010.png"}),
            summary: "best IoU 0.97".into(),
            scores: BTreeMap::from([("iou".to_string(), 0.97)]),
            images: vec!["images/sweep_1.png".into()],
            scene_version: Some(1),
            pose_version: Some(step),
        }
    }

    #[test]
    fn entries_round_trip_and_a_truncated_last_line_is_skipped() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("ledger.jsonl");
        append(&p, &entry(1)).expect("append");
        append(&p, &entry(2)).expect("append");
        let mut text = std::fs::read_to_string(&p).expect("read");
        text.push_str("{\"step\": 3, \"time_s\": 4.5, \"kin");
        std::fs::write(&p, text).expect("write");
        let (entries, notes) = read(&p).expect("read");
        assert_eq!(entries, vec![entry(1), entry(2)]);
        assert_eq!(notes.len(), 1);
        assert!(notes[0].contains("line 3"), "{notes:?}");
        // The step after the crash starts its own line and is kept (it was glued to the
        // cut line and lost with it).
        append(&p, &entry(4)).expect("append");
        let (entries, notes) = read(&p).expect("read");
        assert_eq!(entries, vec![entry(1), entry(2), entry(4)]);
        assert_eq!(notes.len(), 1, "{notes:?}");
    }
}
