//! `agentstar mcp RUN`: the tool catalogue over the Model Context Protocol (stdio), for
//! coding agents (Claude Code, Codex, …). Every call is a step in the run's ledger, so the
//! report's timeline shows what the agent did. Images come back inline and as file paths.

use crate::cmd::agent::{mcp_config_json, mcp_config_toml};
use agentstar_agent::agent::{record_step, StepRecord};
use agentstar_agent::run::RunDir;
use agentstar_agent::task::MCP_INSTRUCTIONS;
use agentstar_agent::tools::{catalogue, Toolbox};
use anyhow::{bail, Context, Result};
use base64::Engine;
use rmcp::model::{
    CallToolRequestParams, CallToolResponse, CallToolResult, ContentBlock as Content,
    Implementation, ListToolsResult, PaginatedRequestParams, ProgressNotificationParam,
    ServerCapabilities, ServerConfig, Tool,
};
use rmcp::service::RequestContext;
use rmcp::{ErrorData, RoleServer, ServerHandler, ServiceExt};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar mcp run1                       (stdio; started by your MCP client)\n  agentstar mcp run1 --print-config claude > run1/.mcp.json\n  agentstar mcp run1 --print-config codex >> ~/.codex/config.toml"
)]
pub struct Args {
    /// The run directory (made by `agentstar init`).
    run: PathBuf,
    /// Print the configuration snippet for a client (claude or codex) and exit.
    #[arg(long)]
    print_config: Option<String>,
    /// A model for the critic tool (PROVIDER:MODEL; also AGENTSTAR_CRITIC).
    #[arg(long)]
    critic: Option<String>,
}

/// The tools as MCP describes them.
pub fn mcp_tools() -> Vec<Tool> {
    catalogue()
        .into_iter()
        .map(|t| {
            let schema = t.schema.as_object().cloned().unwrap_or_default();
            Tool::new(t.name, t.description, Arc::new(schema))
        })
        .collect()
}

struct Server {
    toolbox: Arc<Toolbox>,
    step: AtomicU64,
    start: std::time::Instant,
    offset_s: f64,
}

impl ServerHandler for Server {
    fn get_info(&self) -> ServerConfig {
        ServerConfig::new(ServerCapabilities::builder().enable_tools().build())
            .with_instructions(MCP_INSTRUCTIONS)
            .with_server_info(Implementation::new("agentstar", env!("CARGO_PKG_VERSION")))
    }

    async fn list_tools(
        &self,
        _request: Option<PaginatedRequestParams>,
        _context: RequestContext<RoleServer>,
    ) -> Result<ListToolsResult, ErrorData> {
        Ok(ListToolsResult::with_all_items(mcp_tools()))
    }

    async fn call_tool(
        &self,
        request: CallToolRequestParams,
        context: RequestContext<RoleServer>,
    ) -> Result<CallToolResponse, ErrorData> {
        let name = request.name.to_string();
        let spec = catalogue()
            .into_iter()
            .find(|t| t.name == name)
            .ok_or_else(|| ErrorData::invalid_params(format!("there is no tool `{name}`"), None))?;
        let args = serde_json::Value::Object(request.arguments.unwrap_or_default());
        let step = self.step.fetch_add(1, Ordering::SeqCst) + 1;
        let toolbox = self.toolbox.clone();
        let (a, n) = (args.clone(), name.clone());
        // Long tools report progress while they run (when the client asked for it): once
        // at the start, then every second.
        let token = context.meta.get_progress_token();
        if let Some(token) = &token {
            let _ = context
                .peer
                .notify_progress(
                    ProgressNotificationParam::new(token.clone(), 0.0)
                        .with_message(format!("{name}: started")),
                )
                .await;
        }
        let work = tokio::task::spawn_blocking(move || toolbox.call(&n, &a, step));
        let ticker = token.map(|token| {
            let peer = context.peer.clone();
            let name = name.clone();
            tokio::spawn(async move {
                let mut k = 0u32;
                loop {
                    tokio::time::sleep(std::time::Duration::from_secs(1)).await;
                    k += 1;
                    let _ = peer
                        .notify_progress(
                            ProgressNotificationParam::new(token.clone(), k as f64)
                                .with_message(format!("{name}: running for {k} s")),
                        )
                        .await;
                }
            })
        });
        let out = work
            .await
            .map_err(|e| ErrorData::internal_error(format!("the tool stopped: {e}"), None))?;
        if let Some(t) = ticker {
            t.abort();
        }
        if let Err(e) = record_step(
            &self.toolbox.run,
            StepRecord {
                step,
                time_s: self.offset_s + self.start.elapsed().as_secs_f64(),
                kind: spec.kind,
                tool: &name,
                args: &args,
                agent: None,
            },
            &out,
        ) {
            eprintln!("agentstar mcp: could not write the ledger: {e}");
        }
        let mut text = out.text.clone();
        if !out.images.is_empty() {
            text.push_str("\n\nimages (also inline below):\n");
            for p in &out.images {
                text.push_str(&format!("- {}\n", p.display()));
            }
        }
        let mut content = vec![Content::text(text)];
        for p in &out.images {
            if let Ok(bytes) = std::fs::read(p) {
                content.push(Content::image(
                    base64::engine::general_purpose::STANDARD.encode(bytes),
                    "image/png",
                ));
            }
        }
        Ok(if out.is_error {
            CallToolResult::error(content)
        } else {
            CallToolResult::success(content)
        }
        .into())
    }
}

pub fn run(a: Args) -> Result<ExitCode> {
    let run = RunDir::open(&a.run)?;
    if let Some(client) = &a.print_config {
        let exe = std::env::current_exe().context("finding the agentstar executable")?;
        let dir = run.dir.canonicalize().unwrap_or(run.dir.clone());
        match client.as_str() {
            "claude" => println!(
                "{}",
                serde_json::to_string_pretty(&mcp_config_json(&exe, &dir))?
            ),
            "codex" => print!("{}", mcp_config_toml(&exe, &dir)),
            other => bail!("--print-config {other}: claude or codex"),
        }
        return Ok(ExitCode::SUCCESS);
    }
    let state = run.state()?;
    let mut toolbox = Toolbox::new(
        std::env::current_exe().context("finding the agentstar executable")?,
        run,
    );
    let critic = a
        .critic
        .clone()
        .or_else(|| std::env::var("AGENTSTAR_CRITIC").ok());
    if let Some(c) = critic {
        let cfg =
            agentstar_agent::llm::ModelConfig::parse(&c, None).map_err(|e| anyhow::anyhow!(e))?;
        toolbox.critic = Some(Box::new(move |frame, images| {
            agentstar_agent::critic::criticise(&cfg, frame, images)
        }));
    }
    let server = Server {
        toolbox: Arc::new(toolbox),
        step: AtomicU64::new(state.steps),
        start: std::time::Instant::now(),
        offset_s: state.elapsed_s,
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let service = server
            .serve(rmcp::transport::stdio())
            .await
            .context("starting the MCP server on stdio")?;
        service.waiting().await.context("serving MCP")?;
        anyhow::Ok(())
    })?;
    Ok(ExitCode::SUCCESS)
}
