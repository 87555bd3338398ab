//! `agentstar validate CAPTURE`: every problem of a capture at once.

use crate::common::print_json;
use agentstar_data::capture::Capture;
use anyhow::Result;
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(after_help = "Example:\n  agentstar validate cap")]
pub struct Args {
    /// The capture directory (holding capture.json).
    capture: PathBuf,
    /// Print JSON instead of text.
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let problems = Capture::validate(&a.capture);
    let summary = match Capture::open(&a.capture) {
        Ok(c) => Some((
            (c.frames.len(), c.between.len()),
            c.manifest.image_size,
            c.frames[c.ref_index].name.clone(),
            c.notes.clone(),
            c.warnings.clone(),
        )),
        Err(_) => None,
    };
    if a.json {
        print_json(&json!({
            "capture": a.capture,
            "valid": problems.is_empty(),
            "problems": problems.iter().map(|p| json!({"path": p.path, "message": p.message})).collect::<Vec<_>>(),
            "frames": summary.as_ref().map(|s| s.0 .0),
            "between_frames": summary.as_ref().map(|s| s.0 .1),
            "image_size": summary.as_ref().map(|s| s.1),
            "ref_frame": summary.as_ref().map(|s| s.2.clone()),
            "notes": summary.as_ref().map(|s| s.3.clone()).unwrap_or_default(),
            "warnings": summary.as_ref().map(|s| s.4.clone()).unwrap_or_default(),
        }))?;
    } else if problems.is_empty() {
        if let Some(((n, between), [w, h], r, notes, warnings)) = &summary {
            let between = match between {
                0 => String::new(),
                b => format!(" and {b} in-between frames"),
            };
            println!(
                "valid: {} ({n} frames{between}, {w}×{h}, reference {r})",
                a.capture.display()
            );
            for note in notes {
                println!("note: {note}");
            }
            for warning in warnings {
                println!("warning: {warning}");
            }
        }
    } else {
        println!(
            "invalid: {} has {} problem(s)",
            a.capture.display(),
            problems.len()
        );
        for p in &problems {
            println!("  {p}");
        }
    }
    Ok(if problems.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
