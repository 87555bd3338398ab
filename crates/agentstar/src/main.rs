//! The `agentstar` command: flags, wiring and output. The work lives in the library crates.
//! Results go to stdout (a short summary, or JSON with `--json`); logs go to stderr.

mod cmd;
mod common;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "agentstar",
    version,
    about = "Agentic shape tracking and reconstruction from monocular video: object models as code, a CPU renderer, captures and scores."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write a built-in articulated example (capture, scene, poses) and run render, score, turntable and export on it.
    Example(cmd::example::Args),
    /// Check a capture/v1 directory and report every problem at once.
    Validate(cmd::validate::Args),
    /// Build a model file (scene script, URDF or mesh) and report its parts, joints and canonical frame.
    Check(cmd::check::Args),
    /// Render views of the posed model in chosen frames: overlay, silhouette comparison, part ids, shaded, depth.
    Render(cmd::render::Args),
    /// Score the posed model against the masks: IoU with hands excluded, raw IoU, depth, combined.
    Score(cmd::score::Args),
    /// Render turntables (8 views on a sphere) of the model, once per distinct joint state.
    Turntable(cmd::turntable::Args),
    /// Export the model: GLB (one node per part) or URDF with OBJ meshes.
    Export(cmd::export::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Example(a) => cmd::example::run(a),
        Command::Validate(a) => cmd::validate::run(a),
        Command::Check(a) => cmd::check::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Score(a) => cmd::score::run(a),
        Command::Turntable(a) => cmd::turntable::run(a),
        Command::Export(a) => cmd::export::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
