//! `agentstar export`: the canonical rest model as GLB (one node per part) or URDF.

use crate::common::{open_model, print_json};
use agentstar_data::export::{write_glb, write_urdf};
use anyhow::{bail, Result};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct Args {
    /// A scene script (.rhai), URDF or mesh file.
    #[arg(long)]
    model: PathBuf,
    /// Write a GLB file here.
    #[arg(long)]
    glb: Option<PathBuf>,
    /// Write a URDF (and meshes/) into this directory.
    #[arg(long)]
    urdf: Option<PathBuf>,
    /// Robot name in the URDF.
    #[arg(long, default_value = "object")]
    name: String,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    if a.glb.is_none() && a.urdf.is_none() {
        bail!("nothing to export: give --glb FILE and/or --urdf DIR");
    }
    let m = open_model(&a.model)?;
    let mut written = Vec::new();
    if let Some(p) = &a.glb {
        write_glb(&m.model, p)?;
        written.push(p.clone());
    }
    if let Some(d) = &a.urdf {
        written.push(write_urdf(&m.model, d, &a.name)?);
    }
    if a.json {
        print_json(&json!({"written": written, "parts": m.model.part_names()}))?;
    } else {
        for w in &written {
            println!("wrote {}", w.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
