//! `agentstar capture …`: captures from other sources.

use crate::common::print_json;
use agentstar_data::bop::{import_bop, BopImport};
use anyhow::Result;
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Subcommand)]
pub enum CaptureCommand {
    /// One object of a BOP scene (also HOT3D clips converted to BOP) as capture/v1 with gt.json.
    #[command(
        after_help = "Example:\n  agentstar capture from-bop ycbv/test/000048 --models ycbv/models --obj-id 1 --out cap48 --every 5"
    )]
    FromBop(FromBopArgs),
}

#[derive(clap::Args)]
pub struct FromBopArgs {
    /// The BOP scene directory (scene_gt.json, scene_camera.json, rgb/, mask_visib/).
    scene: PathBuf,
    /// The dataset's models directory (obj_XXXXXX.ply in millimetres, models_info.json).
    #[arg(long)]
    models: PathBuf,
    /// The object to import.
    #[arg(long)]
    obj_id: u32,
    /// Where to write the capture (a new directory).
    #[arg(long)]
    out: PathBuf,
    /// Keep every N-th image holding the object.
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// Import depth/ too (16-bit PNGs with scene_camera depth_scale).
    #[arg(long)]
    depth: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(c: CaptureCommand) -> Result<ExitCode> {
    match c {
        CaptureCommand::FromBop(a) => {
            let n = import_bop(
                &BopImport {
                    scene: a.scene.clone(),
                    models: a.models.clone(),
                    obj_id: a.obj_id,
                    every: a.every,
                    depth: a.depth,
                },
                &a.out,
            )?;
            if a.json {
                print_json(&json!({"capture": a.out, "frames": n, "gt": a.out.join("gt.json")}))?;
            } else {
                println!(
                    "wrote {} ({n} frames of object {} from {}, with gt.json)",
                    a.out.display(),
                    a.obj_id,
                    a.scene.display()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}
