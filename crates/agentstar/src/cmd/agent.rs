//! `agentstar init RUN --capture C` and `agentstar run RUN --model PROVIDER:MODEL` (the
//! built-in agent loop) or `--agent claude|codex` (an external coding agent over MCP).

use crate::common::print_json;
use agentstar_agent::agent::{run_agent, Budget, Session, Stop};
use agentstar_agent::llm::ModelConfig;
use agentstar_agent::run::{init_run, RunDir};
use agentstar_agent::tools::{Kind, ToolOutput, Toolbox};
use anyhow::{anyhow, bail, Context, Result};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar init run1 --capture cap --scale 0.25\n  agentstar run run1 --model anthropic:claude-sonnet-4-5"
)]
pub struct InitArgs {
    /// The run directory to make (new, or empty).
    run: PathBuf,
    /// The capture to work on.
    #[arg(long)]
    capture: PathBuf,
    /// A scene script to start from (default: one box to replace).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Metres per model unit to start with (the object's longest side, roughly).
    #[arg(long, default_value_t = 0.2)]
    scale: f64,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run_init(a: InitArgs) -> Result<ExitCode> {
    let scene = match &a.scene {
        Some(p) => Some(agentstar_data::read_text(p)?),
        None => None,
    };
    let run = init_run(&a.run, &a.capture, scene.as_deref(), a.scale)?;
    if a.json {
        print_json(
            &json!({"run": run.dir, "capture": run.capture, "scene": run.scene,
            "poses": run.poses, "task": run.task_path()}),
        )?;
    } else {
        println!(
            "made run {} for {}\n  read {} (the task), then:\n  agentstar run {} --model PROVIDER:MODEL   (or --agent claude|codex, or `agentstar mcp {}` in your MCP client)",
            a.run.display(),
            run.capture.display(),
            run.task_path().display(),
            agentstar_data::shell_quote(&a.run),
            agentstar_data::shell_quote(&a.run)
        );
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(clap::Args)]
#[command(
    after_help = "Models: openai:MODEL, anthropic:MODEL (keys from OPENAI_API_KEY / ANTHROPIC_API_KEY or\nAGENTSTAR_API_KEY), and OpenAI-compatible local servers: ollama:MODEL, vllm:MODEL, llamacpp:MODEL,\nlocal:MODEL --base-url URL. A stopped run (budget, model error, crash) resumes from its ledger\nwith the same command.\n\nExamples:\n  agentstar run run1 --model anthropic:claude-sonnet-4-5 --max-steps 150\n  agentstar run run1 --model ollama:qwen2.5vl --critic ollama:qwen2.5vl\n  agentstar run run1 --agent claude"
)]
pub struct RunArgs {
    /// The run directory (made by `agentstar init`).
    run: PathBuf,
    /// The model of the built-in loop: PROVIDER:MODEL.
    #[arg(long, conflicts_with = "agent")]
    model: Option<String>,
    /// An external coding agent instead: claude or codex (served our tools over MCP).
    #[arg(long)]
    agent: Option<String>,
    /// The base URL of an OpenAI-compatible or Anthropic server.
    #[arg(long)]
    base_url: Option<String>,
    /// A model for the critic (PROVIDER:MODEL); without one the critic is skipped.
    #[arg(long)]
    critic: Option<String>,
    /// Tool calls in this session, all agents together.
    #[arg(long, default_value_t = 200)]
    max_steps: u64,
    /// Wall time of this session, minutes.
    #[arg(long, default_value_t = 240.0)]
    max_minutes: f64,
    /// Input plus output tokens of this session.
    #[arg(long, default_value_t = 4_000_000)]
    max_tokens: u64,
    /// Seconds to wait for one model reply.
    #[arg(long, default_value_t = 300)]
    request_timeout: u64,
    /// Retries of a failed model request (with exponential backoff from 1 s).
    #[arg(long, default_value_t = 4)]
    retries: u32,
    /// First backoff between retries, milliseconds.
    #[arg(long, default_value_t = 1000)]
    backoff_ms: u64,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

fn exe() -> Result<PathBuf> {
    std::env::current_exe().context("finding the agentstar executable")
}

pub fn run_run(a: RunArgs) -> Result<ExitCode> {
    let run = RunDir::open(&a.run)?;
    if let Some(agent) = &a.agent {
        return external_agent(&run, agent);
    }
    let spec = a
        .model
        .as_deref()
        .ok_or_else(|| anyhow!("give --model PROVIDER:MODEL (or --agent claude|codex)"))?;
    let mut model = ModelConfig::parse(spec, a.base_url.as_deref()).map_err(|e| anyhow!(e))?;
    model.timeout = std::time::Duration::from_secs(a.request_timeout.max(1));
    model.retries = a.retries;
    model.backoff = std::time::Duration::from_millis(a.backoff_ms);
    if !(a.max_minutes.is_finite() && a.max_minutes > 0.0) {
        bail!("--max-minutes {}: a positive number", a.max_minutes);
    }
    let state = run.state()?;
    if state.finished {
        println!(
            "{} is finished (its ledger records a passing `finish`); nothing to do",
            a.run.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let mut toolbox = Toolbox::new(exe()?, run.clone());
    if let Some(c) = &a.critic {
        let critic = ModelConfig::parse(c, a.base_url.as_deref()).map_err(|e| anyhow!(e))?;
        toolbox.critic = Some(Box::new(move |frame, images| {
            agentstar_agent::critic::criticise(&critic, frame, images)
        }));
    }
    let budget = Budget {
        max_steps: a.max_steps,
        max_wall_s: a.max_minutes * 60.0,
        max_tokens: a.max_tokens,
        ..Budget::default()
    };
    let session = Session::new(model, budget, state.steps, state.elapsed_s);
    eprintln!(
        "run {}: {} with {} (step {} onwards; budgets: {} steps, {:.0} min, {} tokens)",
        a.run.display(),
        if state.steps == 0 {
            "starting"
        } else {
            "resuming"
        },
        spec,
        state.steps + 1,
        a.max_steps,
        a.max_minutes,
        a.max_tokens
    );
    let outcome = run_agent(&session, &toolbox, None, "agent")?;
    let (reason, code) = match &outcome.stop {
        Stop::Finished => ("finished: the gates hold".to_string(), 0),
        Stop::Budget(b) => (format!("stopped: {b}; resume with the same command"), 3),
        Stop::ModelError(e) => (format!("stopped: {e}; resume with the same command"), 4),
    };
    let end = run.state()?.steps;
    agentstar_agent::agent::record_step(
        &run,
        agentstar_agent::agent::StepRecord {
            step: end,
            time_s: state.elapsed_s + outcome.wall_s,
            kind: Kind::Note,
            tool: "stop",
            args: &json!({"model": spec}),
            agent: None,
        },
        &ToolOutput {
            text: format!("{reason} ({})", session.spend()),
            scores: [
                ("input_tokens".to_string(), outcome.input_tokens as f64),
                ("output_tokens".to_string(), outcome.output_tokens as f64),
            ]
            .into_iter()
            .collect(),
            ..Default::default()
        },
    )?;
    if a.json {
        print_json(
            &json!({"run": a.run, "stop": reason, "finished": outcome.stop == Stop::Finished,
            "steps": outcome.steps, "input_tokens": outcome.input_tokens,
            "output_tokens": outcome.output_tokens, "seconds": outcome.wall_s}),
        )?;
    } else {
        println!("{}: {reason}", a.run.display());
        println!("  spent: {}", session.spend());
        println!(
            "  report: agentstar report {}",
            agentstar_data::shell_quote(&a.run)
        );
    }
    Ok(ExitCode::from(code))
}

/// The MCP configuration for an external agent, written where it reads it, and the agent
/// started when installed.
fn external_agent(run: &RunDir, agent: &str) -> Result<ExitCode> {
    let exe = exe()?;
    let dir = run
        .dir
        .canonicalize()
        .with_context(|| format!("{}", run.dir.display()))?;
    let prompt = "Read TASK.md and do the task with the agentstar MCP tools. Keep notes with the `notes` tool. Stop when `finish` says the gates hold.";
    let (bin, install, args): (&str, &str, Vec<String>) = match agent {
        "claude" => {
            let cfg = mcp_config_json(&exe, &dir);
            agentstar_data::atomic::write_atomic(
                &dir.join(".mcp.json"),
                serde_json::to_string_pretty(&cfg)?.as_bytes(),
            )?;
            agentstar_data::atomic::write_atomic(
                &dir.join("CLAUDE.md"),
                b"Read TASK.md: it is your task. Use the agentstar MCP tools for every step.\n",
            )?;
            (
                "claude",
                "npm install -g @anthropic-ai/claude-code",
                vec![
                    "-p".into(),
                    prompt.into(),
                    "--mcp-config".into(),
                    dir.join(".mcp.json").display().to_string(),
                    "--allowedTools".into(),
                    "mcp__agentstar".into(),
                ],
            )
        }
        "codex" => {
            agentstar_data::atomic::write_atomic(
                &dir.join("AGENTS.md"),
                b"Read TASK.md: it is your task. Use the agentstar MCP tools for every step.\n",
            )?;
            agentstar_data::atomic::write_atomic(
                &dir.join("codex-mcp.toml"),
                mcp_config_toml(&exe, &dir).as_bytes(),
            )?;
            (
                "codex",
                "npm install -g @openai/codex",
                vec![
                    "exec".into(),
                    "-c".into(),
                    format!(
                        "mcp_servers.agentstar.command={:?}",
                        exe.display().to_string()
                    ),
                    "-c".into(),
                    format!(
                        "mcp_servers.agentstar.args=[\"mcp\", {:?}]",
                        dir.display().to_string()
                    ),
                    prompt.into(),
                ],
            )
        }
        other => bail!("--agent {other}: claude or codex"),
    };
    let probe = agentstar_import::process::output_within(
        std::process::Command::new(bin).arg("--version"),
        agentstar_import::process::PROBE_LIMIT,
    );
    let config = format!(
        "The MCP configuration is written in {} (or print it with `agentstar mcp {} --print-config {agent}`)",
        dir.display(),
        dir.display()
    );
    match probe {
        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => bail!(
            "`{bin} --version` {e}: `{bin}` is installed but does not answer; check it in a shell, then run this again. {config}"
        ),
        Ok(o) if !o.status.success() => bail!(
            "`{bin} --version` failed ({}): {}; reinstall it ({install}), then run this again. {config}",
            o.status,
            String::from_utf8_lossy(&o.stderr).trim()
        ),
        Err(_) => bail!(
            "`{bin}` is not installed: install it ({install}), then run this again. {config}"
        ),
        Ok(_) => {}
    }
    eprintln!("starting {bin} in {}", dir.display());
    let status = std::process::Command::new(bin)
        .args(&args)
        .current_dir(&dir)
        .status()
        .with_context(|| format!("running {bin}"))?;
    Ok(if status.success() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// `{"mcpServers": {"agentstar": {"command": …, "args": ["mcp", RUN]}}}` (Claude Code).
pub fn mcp_config_json(exe: &Path, run: &Path) -> serde_json::Value {
    json!({"mcpServers": {"agentstar": {"command": exe, "args": ["mcp", run]}}})
}

/// `[mcp_servers.agentstar]` (Codex's config.toml).
pub fn mcp_config_toml(exe: &Path, run: &Path) -> String {
    format!(
        "[mcp_servers.agentstar]\ncommand = {:?}\nargs = [\"mcp\", {:?}]\n",
        exe.display().to_string(),
        run.display().to_string()
    )
}
