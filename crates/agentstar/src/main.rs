//! The `agentstar` command: flags, wiring and output. The work lives in the library crates.
//! Results go to stdout (a short summary, or JSON with `--json`); logs go to stderr.

mod cmd;
mod common;
#[cfg(test)]
mod tool_args;

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
    /// The main job on a built-in capture: synthesise it, track it with the known model, evaluate, print the table.
    Demo(cmd::demo::Args),
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
    /// Bake the model's colours from the keyframes at the committed poses into a texture atlas beside the model file, which every command then loads with it.
    Bake(cmd::bake::Args),
    /// Render turntables (8 views on a sphere) of the model, once per distinct joint state.
    Turntable(cmd::turntable::Args),
    /// The mechanism check: each joint swept about its declared axis and about the negated axis, as two blind arms A and B, from views off the swing plane.
    Mechanism(cmd::mechanism::Args),
    /// Export the model: GLB (one node per part) or URDF with OBJ meshes.
    Export(cmd::export::Args),
    /// Search camera-frame increments and joint states for one or more frames (differential evolution or grid).
    Sweep(cmd::search::SweepArgs),
    /// Score one explicit camera-frame order.
    Apply(cmd::search::ApplyArgs),
    /// Search object-frame rotations per frame (grid or presets such as z:flip, so3:N).
    Osweep(cmd::search::OsweepArgs),
    /// Score a set of object-frame rotations per frame (e.g. flips).
    Oapply(cmd::search::OapplyArgs),
    /// Apply one shared object-frame rotation to every frame (a model built the wrong way round).
    #[command(name = "oapply-all")]
    OapplyAll(cmd::search::OapplyAllArgs),
    /// Commit a candidate to pose.json, list versions, restore one.
    #[command(subcommand)]
    Pose(cmd::pose::PoseCommand),
    /// Temporal residuals: rotation, translation and radial velocity and acceleration, joints.
    Temporal(cmd::temporal::Args),
    /// The residual between two frames' poses.
    #[command(name = "pose-diff")]
    PoseDiff(cmd::temporal::DiffArgs),
    /// Track every keyframe of a capture with a known model, no agent.
    Track(cmd::track::Args),
    /// Fit named `param(...)` values of a scene script against the committed poses (poses refined locally), with before/after comparisons.
    #[command(name = "fit-shape")]
    FitShape(cmd::fit::Args),
    /// Estimate metres per model unit from depth, the parallax of moving metric cameras or a stated size; rescale the poses (rotations kept).
    Scale(cmd::scale::Args),
    /// The paper's metrics against the capture's ground truth: scale alignment, EPE, Chamfer, pose and articulation errors.
    Eval(cmd::eval::Args),
    /// Write a seeded synthetic capture with ground truth (objects modelled on ARCTIC, HOT3D, iTACO).
    Synth(cmd::synth::Args),
    /// Print a shell completion script (bash, zsh, fish, powershell, elvish) on stdout.
    #[command(
        after_help = "Example:\n  agentstar completions bash > ~/.local/share/bash-completion/completions/agentstar"
    )]
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// Make captures from other sources: a video or frames, BOP scenes, HOT3D and ARCTIC sequences.
    #[command(subcommand)]
    Capture(cmd::capture::CaptureCommand),
    /// Make a run directory for an agent: a starting scene, pose.json, TASK.md, NOTES.md and a ledger.
    Init(cmd::agent::InitArgs),
    /// Run an agent on a run: the built-in loop with a model behind an API, or Claude Code / Codex over MCP.
    Run(cmd::agent::RunArgs),
    /// Serve the tools of a run over the Model Context Protocol (stdio) for coding agents.
    Mcp(cmd::mcp::Args),
    /// One self-contained HTML page of a run: keyframes with overlays, a 3-D view, plots, the agent's steps.
    Report(cmd::report::Args),
    /// Track a synthetic suite (and the agent-free ablations), evaluate, print the paper's tables with wall times.
    Bench(cmd::bench::Args),
    /// Batches: one job per capture on Slurm (a job array) or here; status, resubmission, the paper's tables over all runs.
    #[command(subcommand)]
    Batch(cmd::batch::BatchCommand),
}

/// The exit status of a command whose output pipe was closed (`agentstar check … | head`):
/// 128 + SIGPIPE, what a shell shows for a program that the signal ended.
const BROKEN_PIPE_EXIT: i32 = 141;

/// `println!` panics when stdout is a closed pipe. A closed pipe is the reader saying it has
/// read enough: end quietly, as a program ended by SIGPIPE does, instead of exit 101 and a
/// panic message. Every other panic keeps the default report.
fn install_panic_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.contains("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(BROKEN_PIPE_EXIT);
        }
        default(info);
    }));
}

/// Paths and other arguments must be UTF-8: they are written into JSON results, ledgers and
/// reports, which cannot hold other bytes. Refusing them here, before anything runs, means
/// no command stops half-way through (after writing some files) on such a path.
fn non_utf8_argument() -> Option<String> {
    std::env::args_os()
        .enumerate()
        .skip(1)
        .find(|(_, a)| a.to_str().is_none())
        .map(|(i, a)| {
            format!(
                "argument {i} ({}) is not valid UTF-8; agentstar writes paths into JSON and needs them in UTF-8 (rename the file or directory)",
                a.to_string_lossy()
            )
        })
}

fn main() -> ExitCode {
    install_panic_hook();
    if let Some(message) = non_utf8_argument() {
        eprintln!("error: {message}");
        return ExitCode::from(2);
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Example(a) => cmd::example::run(a),
        Command::Validate(a) => cmd::validate::run(a),
        Command::Check(a) => cmd::check::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Score(a) => cmd::score::run(a),
        Command::Bake(a) => cmd::bake::run(a),
        Command::Turntable(a) => cmd::turntable::run(a),
        Command::Mechanism(a) => cmd::mechanism::run(a),
        Command::Export(a) => cmd::export::run(a),
        Command::Sweep(a) => cmd::search::run_sweep(a),
        Command::Apply(a) => cmd::search::run_apply(a),
        Command::Osweep(a) => cmd::search::run_osweep(a),
        Command::Oapply(a) => cmd::search::run_oapply(a),
        Command::OapplyAll(a) => cmd::search::run_oapply_all(a),
        Command::Pose(c) => cmd::pose::run(c),
        Command::Temporal(a) => cmd::temporal::run(a),
        Command::PoseDiff(a) => cmd::temporal::run_diff(a),
        Command::Track(a) => cmd::track::run(a),
        Command::FitShape(a) => cmd::fit::run(a),
        Command::Scale(a) => cmd::scale::run(a),
        Command::Eval(a) => cmd::eval::run(a),
        Command::Synth(a) => cmd::synth::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Batch(c) => cmd::batch::run(c),
        Command::Capture(c) => cmd::capture::run(c),
        Command::Completions { shell } => completions(shell),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Report(a) => cmd::report::run(a),
        Command::Init(a) => cmd::agent::run_init(a),
        Command::Run(a) => cmd::agent::run_run(a),
        Command::Mcp(a) => cmd::mcp::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) if is_broken_pipe(&e) => ExitCode::from(BROKEN_PIPE_EXIT as u8),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

/// Whether an error comes from writing to a closed pipe (anywhere in its chain).
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// `completions SHELL`: the script is made in memory (clap_complete panics when its writer
/// fails) and written with the write's error returned, so that a closed stdout ends quietly.
fn completions(shell: clap_complete::Shell) -> anyhow::Result<ExitCode> {
    use clap::CommandFactory;
    use std::io::Write;
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut Cli::command(), "agentstar", &mut script);
    let mut out = std::io::stdout().lock();
    out.write_all(&script)?;
    out.flush()?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    /// Every subcommand's help ends with an example.
    #[test]
    fn every_command_has_an_example() {
        fn walk(c: &clap::Command, path: &str, missing: &mut Vec<String>) {
            for sub in c.get_subcommands() {
                let p = format!("{path} {}", sub.get_name());
                if sub.has_subcommands() {
                    walk(sub, &p, missing);
                } else if !sub
                    .get_after_help()
                    .is_some_and(|h| h.to_string().contains("Example"))
                {
                    missing.push(p);
                }
            }
        }
        let mut missing = vec![];
        walk(&Cli::command(), "agentstar", &mut missing);
        missing.retain(|m| m != "agentstar help");
        assert!(missing.is_empty(), "no example in: {missing:?}");
    }
}
