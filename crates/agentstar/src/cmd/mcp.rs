//! `agentstar mcp RUN`: the tool catalogue over the Model Context Protocol (stdio), for
//! coding agents (Claude Code, Codex, …). Every call is a step in the run's ledger, so the
//! report's timeline shows what the agent did. Images come back inline and as file paths;
//! a tool's typed report comes back as `structuredContent`.
//!
//! Every request is answered: stdin is read through a bounded front ([`bounded_stdio`]) that
//! answers a line over [`MAX_REQUEST_BYTES`] or a line that is not JSON with a JSON-RPC
//! error instead of dropping it; arguments are checked against the tool's generated schema
//! before it runs (a tool error the model can read).

use crate::cmd::agent::{mcp_config_json, mcp_config_toml};
use agentstar_agent::agent::{record_step, StepRecord};
use agentstar_agent::run::RunDir;
use agentstar_agent::task::mcp_instructions;
use agentstar_agent::tools::{catalogue, find, with_activity, Activity, Toolbox};
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
    start: std::time::Instant,
    offset_s: f64,
}

impl ServerHandler for Server {
    fn get_info(&self) -> ServerConfig {
        ServerConfig::new(ServerCapabilities::builder().enable_tools().build())
            .with_instructions(mcp_instructions(self.toolbox.offers(
                <agentstar_agent::tools::Critic as agentstar_agent::tools::Tool>::NAME,
            )))
            .with_server_info(Implementation::new("agentstar", env!("CARGO_PKG_VERSION")))
    }

    async fn list_tools(
        &self,
        _request: Option<PaginatedRequestParams>,
        _context: RequestContext<RoleServer>,
    ) -> Result<ListToolsResult, ErrorData> {
        Ok(ListToolsResult::with_all_items(
            mcp_tools()
                .into_iter()
                .filter(|t| self.toolbox.offers(&t.name))
                .collect(),
        ))
    }

    async fn call_tool(
        &self,
        request: CallToolRequestParams,
        context: RequestContext<RoleServer>,
    ) -> Result<CallToolResponse, ErrorData> {
        let name = request.name.to_string();
        let spec = find(&name).ok_or_else(|| {
            ErrorData::invalid_params(
                format!(
                    "there is no tool `{name}`; the tools are {}",
                    catalogue()
                        .iter()
                        .map(|t| t.name)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                None,
            )
        })?;
        let args = serde_json::Value::Object(request.arguments.unwrap_or_default());
        let step = self.toolbox.run.next_step().map_err(|e| {
            ErrorData::internal_error(format!("allocating a step number: {e}"), None)
        })?;
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
        // What the tool's child command says it is doing (the tracker: a line per frame).
        let activity = Activity::default();
        let act = activity.clone();
        // The step is recorded where the tool ran, not after the answer is awaited: a client
        // that disconnects mid-call (the await is then dropped) still leaves the step of the
        // change the tool made in the ledger, since the runtime waits for blocking work.
        let (kind, time_origin, offset_s) = (spec.kind, self.start, self.offset_s);
        let work = tokio::task::spawn_blocking(move || {
            let out = with_activity(&act, || toolbox.call(&n, &a, step));
            if let Err(e) = record_step(
                &toolbox.run,
                StepRecord {
                    step,
                    time_s: offset_s + time_origin.elapsed().as_secs_f64(),
                    kind,
                    tool: &n,
                    args: &a,
                    agent: None,
                },
                &out,
            ) {
                eprintln!("agentstar mcp: could not write the ledger: {e}");
            }
            out
        });
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
                            ProgressNotificationParam::new(token.clone(), k as f64).with_message(
                                match activity.last_line() {
                                    l if l.is_empty() => format!("{name}: running for {k} s"),
                                    l => format!("{name}: running for {k} s; {l}"),
                                },
                            ),
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
        let mut result = if out.is_error {
            CallToolResult::error(content)
        } else {
            CallToolResult::success(content)
        };
        result.structured_content = out.structured.clone();
        Ok(result.into())
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
        start: std::time::Instant::now(),
        offset_s: state.elapsed_s,
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let (input, output, writer) = bounded_stdio();
        let service = server
            .serve((input, output))
            .await
            .context("starting the MCP server on stdio")?;
        service.waiting().await.context("serving MCP")?;
        // The service's last answers are still in the pipe: write them out before leaving.
        let _ = tokio::time::timeout(std::time::Duration::from_secs(10), writer).await;
        anyhow::Ok(())
    })?;
    Ok(ExitCode::SUCCESS)
}

/// The largest request line the server reads (a whole scene script is at most
/// `MAX_SCRIPT_CHARS`, far under it).
pub const MAX_REQUEST_BYTES: usize = 4 * 1024 * 1024;

/// The `id` of a request line, read from its first bytes without parsing all of it (for
/// answering a line too long to parse).
fn scan_id(head: &[u8]) -> serde_json::Value {
    let text = String::from_utf8_lossy(head);
    let Some(at) = text.find("\"id\"") else {
        return serde_json::Value::Null;
    };
    let rest = text[at + 4..].trim_start();
    let Some(rest) = rest.strip_prefix(':') else {
        return serde_json::Value::Null;
    };
    let rest = rest.trim_start();
    // A number or a string, whichever the token is.
    let mut de = serde_json::Deserializer::from_str(rest).into_iter::<serde_json::Value>();
    match de.next() {
        Some(Ok(v @ (serde_json::Value::Number(_) | serde_json::Value::String(_)))) => v,
        _ => serde_json::Value::Null,
    }
}

fn error_line(id: serde_json::Value, code: i64, message: String) -> Vec<u8> {
    let mut line = serde_json::to_vec(&serde_json::json!({
        "jsonrpc": "2.0", "id": id, "error": {"code": code, "message": message}
    }))
    .unwrap_or_default();
    line.push(b'\n');
    line
}

/// What the front does with one line of stdin.
#[derive(Debug, PartialEq)]
enum Front {
    /// Pass it to the MCP service.
    Forward,
    /// Answer it with this error line.
    Answer(Vec<u8>),
    /// Blank: nothing.
    Skip,
}

/// A `tools/call` whose `arguments` are not an object (a string, a list, a number) is
/// answered here with JSON-RPC's invalid params (-32602), naming what was given: the
/// service's request type cannot hold it and would answer "method not found".
fn bad_tool_arguments(request: &serde_json::Value) -> Option<Vec<u8>> {
    if request.get("method").and_then(|m| m.as_str()) != Some("tools/call") {
        return None;
    }
    let params = request.get("params")?;
    let what = match params.get("arguments") {
        None | Some(serde_json::Value::Null) | Some(serde_json::Value::Object(_)) => return None,
        Some(serde_json::Value::String(_)) => "a string",
        Some(serde_json::Value::Array(_)) => "a list",
        Some(serde_json::Value::Number(_)) => "a number",
        Some(serde_json::Value::Bool(_)) => "a boolean",
    };
    let tool = params.get("name").and_then(|n| n.as_str()).unwrap_or("?");
    Some(error_line(
        request.get("id").cloned().unwrap_or(serde_json::Value::Null),
        -32602,
        format!(
            "invalid params: the arguments of `{tool}` must be a JSON object of named arguments, not {what}"
        ),
    ))
}

fn judge(line: &[u8]) -> Front {
    let body = line.strip_suffix(b"\n").unwrap_or(line);
    let body = body.strip_suffix(b"\r").unwrap_or(body);
    if body.iter().all(u8::is_ascii_whitespace) {
        return Front::Skip;
    }
    match serde_json::from_slice::<serde_json::Value>(body) {
        Ok(request) => match bad_tool_arguments(&request) {
            Some(answer) => Front::Answer(answer),
            None => Front::Forward,
        },
        Err(e) => Front::Answer(error_line(
            serde_json::Value::Null,
            -32700,
            format!("parse error: the request is not JSON ({e})"),
        )),
    }
}

/// Stdin and stdout for the MCP service, with a front that bounds each request line and
/// answers what the service would drop (over-long lines, lines that are not JSON). Both
/// directions go through pipes so that the front's answers and the service's never
/// interleave within a line.
fn bounded_stdio() -> (
    tokio::io::DuplexStream,
    tokio::io::DuplexStream,
    tokio::task::JoinHandle<()>,
) {
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt};
    let (service_in, mut feed) = tokio::io::duplex(1 << 20);
    let (service_out, drain) = tokio::io::duplex(1 << 20);
    let (answers, mut answered) = tokio::sync::mpsc::unbounded_channel::<Vec<u8>>();
    tokio::spawn(async move {
        let mut stdin = tokio::io::BufReader::new(tokio::io::stdin());
        let mut line: Vec<u8> = Vec::new();
        let mut head: Vec<u8> = Vec::new();
        let mut oversized = false;
        loop {
            let chunk = match stdin.fill_buf().await {
                Ok([]) => break,
                Ok(c) => c,
                Err(e) => {
                    eprintln!("agentstar mcp: reading stdin: {e}");
                    break;
                }
            };
            let newline = chunk.iter().position(|b| *b == b'\n');
            let take = newline.map_or(chunk.len(), |i| i + 1);
            if oversized {
                if head.len() < 4096 {
                    let n = (4096 - head.len()).min(take);
                    head.extend_from_slice(&chunk[..n]);
                }
            } else if line.len() + take > MAX_REQUEST_BYTES {
                oversized = true;
                head = std::mem::take(&mut line);
                head.truncate(4096);
                let n = (4096 - head.len()).min(take);
                head.extend_from_slice(&chunk[..n]);
            } else {
                line.extend_from_slice(&chunk[..take]);
            }
            stdin.consume(take);
            if newline.is_none() {
                continue;
            }
            if oversized {
                let _ = answers.send(error_line(
                    scan_id(&head),
                    -32600,
                    format!("the request is over {MAX_REQUEST_BYTES} bytes and was not read"),
                ));
                oversized = false;
                head.clear();
                continue;
            }
            match judge(&line) {
                Front::Forward => {
                    if feed.write_all(&line).await.is_err() {
                        break;
                    }
                }
                Front::Answer(a) => {
                    let _ = answers.send(a);
                }
                Front::Skip => {}
            }
            line.clear();
        }
        // End of input: the service sees it and stops.
        let _ = feed.shutdown().await;
    });
    let writer = tokio::spawn(async move {
        let mut stdout = tokio::io::stdout();
        let mut from_service = tokio::io::BufReader::new(drain);
        let mut buf: Vec<u8> = Vec::new();
        let mut service_open = true;
        loop {
            tokio::select! {
                // Cancel safe: a partial line stays in `buf` for the next round.
                r = from_service.read_until(b'\n', &mut buf), if service_open => {
                    match r {
                        Ok(0) | Err(_) => service_open = false,
                        Ok(_) => {
                            if buf.ends_with(b"\n") {
                                if stdout.write_all(&buf).await.is_err() || stdout.flush().await.is_err() {
                                    return;
                                }
                                buf.clear();
                            }
                        }
                    }
                }
                a = answered.recv() => {
                    match a {
                        Some(a) => {
                            if stdout.write_all(&a).await.is_err() || stdout.flush().await.is_err() {
                                return;
                            }
                        }
                        None if !service_open => break,
                        None => {
                            // The front is done; keep draining the service.
                            while let Ok(n) = from_service.read_until(b'\n', &mut buf).await {
                                if n == 0 {
                                    break;
                                }
                                if stdout.write_all(&buf).await.is_err() {
                                    return;
                                }
                                buf.clear();
                                let _ = stdout.flush().await;
                            }
                            break;
                        }
                    }
                }
            }
        }
        let _ = stdout.flush().await;
    });
    (service_in, service_out, writer)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_front_answers_what_the_service_would_drop() {
        assert_eq!(judge(b"{\"jsonrpc\": \"2.0\"}\n"), Front::Forward);
        assert_eq!(judge(b"  \r\n"), Front::Skip);
        let Front::Answer(a) = judge(b"{\"jsonrpc\": \n") else {
            panic!("not answered")
        };
        let v: serde_json::Value = serde_json::from_slice(&a).expect("json");
        assert_eq!(v["error"]["code"], -32700);
        assert_eq!(
            scan_id(b"{\"jsonrpc\":\"2.0\", \"id\" : 17, \"params\": {\"x\": \"aaaa"),
            17
        );
        assert_eq!(scan_id(b"{\"id\":\"req-3\",\"method\""), "req-3");
        assert_eq!(
            scan_id(b"{\"method\": \"tools/call\""),
            serde_json::Value::Null
        );
    }
}
