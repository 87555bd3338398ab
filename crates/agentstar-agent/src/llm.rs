//! Model clients: OpenAI-compatible chat completions (OpenAI, and local servers such as
//! vLLM, llama.cpp and Ollama through a base URL) and Anthropic's Messages API, with images
//! inline, native tool calls, and retries with backoff.
//!
//! Keys come only from the environment (`AGENTSTAR_API_KEY`, else `OPENAI_API_KEY` or
//! `ANTHROPIC_API_KEY`) and are never written anywhere.

use crate::tools::ToolSpec;
use base64::Engine;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::Duration;

/// Which wire protocol a model speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    OpenAi,
    Anthropic,
}

/// A model endpoint.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelConfig {
    pub protocol: Protocol,
    /// The provider as written (`openai`, `anthropic`, `ollama`, `vllm`, `llamacpp`, `local`).
    pub provider: String,
    pub model: String,
    pub base_url: String,
    pub api_key: Option<String>,
    /// Per request.
    pub timeout: Duration,
    /// Attempts after the first for transport errors, timeouts, 429 and 5xx, and malformed
    /// tool calls.
    pub retries: u32,
    /// First backoff; doubled at each retry.
    pub backoff: Duration,
    pub max_reply_tokens: u32,
}

impl ModelConfig {
    /// Parses `PROVIDER:MODEL` (`openai:gpt-4.1`, `anthropic:claude-sonnet-4-5`,
    /// `ollama:qwen2.5vl`, `vllm:…`, `llamacpp:…`, `local:…`); `base_url` overrides the
    /// provider's default. The key is read from the environment.
    pub fn parse(spec: &str, base_url: Option<&str>) -> Result<ModelConfig, String> {
        let (provider, model) = spec.split_once(':').ok_or_else(|| {
            format!("`{spec}`: write PROVIDER:MODEL, e.g. openai:gpt-4.1, anthropic:claude-sonnet-4-5, ollama:qwen2.5vl")
        })?;
        if model.trim().is_empty() {
            return Err(format!("`{spec}`: the model name is empty"));
        }
        let (protocol, default_url, key_var) = match provider {
            "openai" => (Protocol::OpenAi, "https://api.openai.com/v1", Some("OPENAI_API_KEY")),
            "anthropic" => (Protocol::Anthropic, "https://api.anthropic.com", Some("ANTHROPIC_API_KEY")),
            "ollama" => (Protocol::OpenAi, "http://localhost:11434/v1", None),
            "vllm" => (Protocol::OpenAi, "http://localhost:8000/v1", None),
            "llamacpp" => (Protocol::OpenAi, "http://localhost:8080/v1", None),
            "local" => (Protocol::OpenAi, "http://localhost:8000/v1", None),
            other => {
                return Err(format!(
                    "unknown provider `{other}`: openai, anthropic, ollama, vllm, llamacpp or local (any OpenAI-compatible server, with --base-url)"
                ))
            }
        };
        let api_key = std::env::var("AGENTSTAR_API_KEY")
            .ok()
            .or_else(|| key_var.and_then(|v| std::env::var(v).ok()))
            .filter(|k| !k.trim().is_empty());
        if api_key.is_none() && matches!(provider, "openai" | "anthropic") && base_url.is_none() {
            return Err(format!(
                "no API key: set {} (or AGENTSTAR_API_KEY) in the environment",
                key_var.unwrap_or("AGENTSTAR_API_KEY")
            ));
        }
        Ok(ModelConfig {
            protocol,
            provider: provider.to_string(),
            model: model.to_string(),
            base_url: base_url
                .unwrap_or(default_url)
                .trim_end_matches('/')
                .to_string(),
            api_key,
            timeout: Duration::from_secs(300),
            retries: 4,
            backoff: Duration::from_millis(1000),
            max_reply_tokens: 4096,
        })
    }
}

/// Part of a message.
#[derive(Debug, Clone, PartialEq)]
pub enum Part {
    Text(String),
    /// A PNG or JPEG, base64; `path` names it when it is dropped from the context.
    Image {
        mime: String,
        data_b64: String,
        path: PathBuf,
    },
}

impl Part {
    /// Reads an image file.
    pub fn image(path: &std::path::Path) -> std::io::Result<Part> {
        let bytes = std::fs::read(path)?;
        let mime = if path.extension().is_some_and(|e| e == "jpg" || e == "jpeg") {
            "image/jpeg"
        } else {
            "image/png"
        };
        Ok(Part::Image {
            mime: mime.into(),
            data_b64: base64::engine::general_purpose::STANDARD.encode(bytes),
            path: path.to_path_buf(),
        })
    }
}

/// A tool call the model made.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolCall {
    pub id: String,
    pub name: String,
    pub arguments: Value,
}

/// One message of the conversation.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    User(Vec<Part>),
    Assistant {
        text: String,
        calls: Vec<ToolCall>,
    },
    ToolResult {
        call_id: String,
        name: String,
        parts: Vec<Part>,
        is_error: bool,
    },
}

/// The model's reply.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Reply {
    pub text: String,
    pub calls: Vec<ToolCall>,
    pub input_tokens: u64,
    pub output_tokens: u64,
}

/// Why a request failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LlmError {
    /// Worth retrying: transport errors, timeouts, 5xx, replies that are not JSON or hold
    /// no message.
    #[error("{0}")]
    Transient(String),
    /// HTTP 429; `retry_after` is the server's `Retry-After`, when it sent one.
    #[error("{message}")]
    RateLimited {
        message: String,
        retry_after: Option<Duration>,
    },
    /// The reply held a tool call whose arguments are not a JSON object.
    #[error("malformed tool call: {0}")]
    Malformed(String),
    /// Not worth retrying (401, 400, …).
    #[error("{0}")]
    Fatal(String),
    /// Every attempt failed; `failures` names each kind of failure seen with its count.
    #[error("{attempts} attempt(s) failed ({}); last: {last}", .failures.iter().map(|(k, n)| format!("{k} ×{n}")).collect::<Vec<_>>().join(", "))]
    GaveUp {
        attempts: u32,
        failures: Vec<(String, u32)>,
        last: Box<LlmError>,
    },
}

impl LlmError {
    /// A short name of the kind of failure, for counting them.
    pub fn kind(&self) -> String {
        match self {
            LlmError::Transient(m) => {
                if let Some(status) = m
                    .split("HTTP ")
                    .nth(1)
                    .and_then(|r| r.split(':').next())
                    .filter(|c| c.chars().all(|ch| ch.is_ascii_digit()))
                {
                    format!("HTTP {status}")
                } else if m.contains("not JSON") {
                    "reply not JSON".into()
                } else if m.contains("no choices") || m.contains("no content") {
                    "reply without a message".into()
                } else {
                    "transport error".into()
                }
            }
            LlmError::RateLimited { .. } => "HTTP 429 (rate limited)".into(),
            LlmError::Malformed(_) => "malformed tool call".into(),
            LlmError::Fatal(_) => "fatal error".into(),
            LlmError::GaveUp { .. } => "gave up".into(),
        }
    }
}

/// The longest `Retry-After` honoured; a server asking for more is waited on this long and
/// then asked again (the attempt still counts).
pub const MAX_RETRY_AFTER: Duration = Duration::from_secs(300);

/// `Retry-After` as seconds (`3`, `1.5`) or an HTTP date, as a wait from `now`.
pub fn parse_retry_after(value: &str, now: std::time::SystemTime) -> Option<Duration> {
    let v = value.trim();
    if let Ok(secs) = v.parse::<f64>() {
        return (secs.is_finite() && secs >= 0.0)
            .then(|| Duration::from_secs_f64(secs.min(MAX_RETRY_AFTER.as_secs_f64())));
    }
    let when = parse_http_date(v)?;
    Some(
        when.duration_since(now)
            .unwrap_or(Duration::ZERO)
            .min(MAX_RETRY_AFTER),
    )
}

/// An IMF-fixdate (`Sun, 06 Nov 1994 08:49:37 GMT`), the form HTTP servers send.
fn parse_http_date(v: &str) -> Option<std::time::SystemTime> {
    let parts: Vec<&str> = v.split_whitespace().collect();
    let [_, day, month, year, time, "GMT"] = parts.as_slice() else {
        return None;
    };
    let day: i64 = day.parse().ok()?;
    let year: i64 = year.parse().ok()?;
    let month = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ]
    .iter()
    .position(|m| m == month)? as i64
        + 1;
    let hms: Vec<i64> = time
        .split(':')
        .map(|t| t.parse().ok())
        .collect::<Option<_>>()?;
    let [h, mi, sec] = hms.as_slice() else {
        return None;
    };
    if !(1..=31).contains(&day) || *h > 23 || *mi > 59 || *sec > 60 || year < 1970 {
        return None;
    }
    // Days from the civil date (Howard Hinnant's algorithm).
    let (y, m) = if month <= 2 {
        (year - 1, month + 9)
    } else {
        (year, month - 3)
    };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * m + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    let secs = days * 86_400 + h * 3600 + mi * 60 + sec;
    Some(std::time::UNIX_EPOCH + Duration::from_secs(u64::try_from(secs).ok()?))
}

fn openai_body(cfg: &ModelConfig, system: &str, messages: &[Message], tools: &[ToolSpec]) -> Value {
    let mut out = vec![json!({"role": "system", "content": system})];
    let content = |parts: &[Part]| -> Vec<Value> {
        parts
            .iter()
            .map(|p| match p {
                Part::Text(t) => json!({"type": "text", "text": t}),
                Part::Image { mime, data_b64, .. } => json!({"type": "image_url",
                    "image_url": {"url": format!("data:{mime};base64,{data_b64}")}}),
            })
            .collect()
    };
    for m in messages {
        match m {
            Message::User(parts) => out.push(json!({"role": "user", "content": content(parts)})),
            Message::Assistant { text, calls } => {
                let mut a = json!({"role": "assistant", "content": text});
                if !calls.is_empty() {
                    a["tool_calls"] = calls
                        .iter()
                        .map(|c| {
                            json!({"id": c.id, "type": "function",
                            "function": {"name": c.name, "arguments": c.arguments.to_string()}})
                        })
                        .collect();
                }
                out.push(a);
            }
            Message::ToolResult {
                call_id,
                parts,
                is_error,
                ..
            } => {
                // Tool messages carry text only; images follow as a user message.
                let text: Vec<&str> = parts
                    .iter()
                    .filter_map(|p| {
                        if let Part::Text(t) = p {
                            Some(t.as_str())
                        } else {
                            None
                        }
                    })
                    .collect();
                let prefix = if *is_error { "ERROR: " } else { "" };
                out.push(json!({"role": "tool", "tool_call_id": call_id,
                    "content": format!("{prefix}{}", text.join("\n"))}));
                let images: Vec<Part> = parts
                    .iter()
                    .filter(|p| matches!(p, Part::Image { .. }))
                    .cloned()
                    .collect();
                if !images.is_empty() {
                    let mut c = vec![
                        json!({"type": "text", "text": format!("Images from tool call {call_id}:")}),
                    ];
                    c.extend(content(&images));
                    out.push(json!({"role": "user", "content": c}));
                }
            }
        }
    }
    json!({
        "model": cfg.model,
        "messages": out,
        "max_tokens": cfg.max_reply_tokens,
        "tools": tools.iter().map(|t| json!({"type": "function", "function": {
            "name": t.name, "description": t.description, "parameters": t.schema}})).collect::<Vec<_>>(),
    })
}

fn anthropic_body(
    cfg: &ModelConfig,
    system: &str,
    messages: &[Message],
    tools: &[ToolSpec],
) -> Value {
    let content = |parts: &[Part]| -> Vec<Value> {
        parts
            .iter()
            .map(|p| match p {
                Part::Text(t) => json!({"type": "text", "text": t}),
                Part::Image { mime, data_b64, .. } => json!({"type": "image",
                    "source": {"type": "base64", "media_type": mime, "data": data_b64}}),
            })
            .collect()
    };
    let mut out: Vec<Value> = vec![];
    for m in messages {
        let (role, blocks): (&str, Vec<Value>) = match m {
            Message::User(parts) => ("user", content(parts)),
            Message::Assistant { text, calls } => {
                let mut b = vec![];
                if !text.is_empty() {
                    b.push(json!({"type": "text", "text": text}));
                }
                for c in calls {
                    b.push(json!({"type": "tool_use", "id": c.id, "name": c.name, "input": c.arguments}));
                }
                ("assistant", b)
            }
            Message::ToolResult {
                call_id,
                parts,
                is_error,
                ..
            } => (
                "user",
                vec![json!({"type": "tool_result", "tool_use_id": call_id,
                    "content": content(parts), "is_error": is_error})],
            ),
        };
        // Consecutive messages of one role merge (the API wants them alternating).
        match out.last_mut() {
            Some(last) if last["role"] == role => {
                if let Some(arr) = last["content"].as_array_mut() {
                    arr.extend(blocks);
                }
            }
            _ => out.push(json!({"role": role, "content": blocks})),
        }
    }
    json!({
        "model": cfg.model,
        "max_tokens": cfg.max_reply_tokens,
        // The system prompt (the task document and notes) is the same from call to call:
        // marked for the server's prompt cache.
        "system": [{"type": "text", "text": system, "cache_control": {"type": "ephemeral"}}],
        "messages": out,
        "tools": tools.iter().map(|t| json!({"name": t.name, "description": t.description,
            "input_schema": t.schema})).collect::<Vec<_>>(),
    })
}

fn parse_openai(v: &Value) -> Result<Reply, LlmError> {
    let msg = &v["choices"][0]["message"];
    if msg.is_null() {
        return Err(LlmError::Transient(format!(
            "the reply has no choices[0].message: {}",
            truncate(&v.to_string(), 300)
        )));
    }
    let mut calls = vec![];
    for c in msg["tool_calls"].as_array().into_iter().flatten() {
        let name = c["function"]["name"].as_str().unwrap_or("").to_string();
        let raw = c["function"]["arguments"].as_str().unwrap_or("");
        let arguments: Value = if raw.trim().is_empty() {
            json!({})
        } else {
            serde_json::from_str(raw).map_err(|e| {
                LlmError::Malformed(format!(
                    "`{name}` arguments are not JSON ({e}): {}",
                    truncate(raw, 200)
                ))
            })?
        };
        if !arguments.is_object() || name.is_empty() {
            return Err(LlmError::Malformed(format!(
                "`{name}` arguments are not an object: {raw}"
            )));
        }
        calls.push(ToolCall {
            id: c["id"].as_str().unwrap_or("call").to_string(),
            name,
            arguments,
        });
    }
    Ok(Reply {
        text: msg["content"].as_str().unwrap_or("").to_string(),
        calls,
        input_tokens: v["usage"]["prompt_tokens"].as_u64().unwrap_or(0),
        output_tokens: v["usage"]["completion_tokens"].as_u64().unwrap_or(0),
    })
}

fn parse_anthropic(v: &Value) -> Result<Reply, LlmError> {
    let blocks = v["content"].as_array().ok_or_else(|| {
        LlmError::Transient(format!(
            "the reply has no content: {}",
            truncate(&v.to_string(), 300)
        ))
    })?;
    let mut r = Reply {
        input_tokens: v["usage"]["input_tokens"].as_u64().unwrap_or(0),
        output_tokens: v["usage"]["output_tokens"].as_u64().unwrap_or(0),
        ..Reply::default()
    };
    for b in blocks {
        match b["type"].as_str() {
            Some("text") => r.text.push_str(b["text"].as_str().unwrap_or("")),
            Some("tool_use") => {
                let name = b["name"].as_str().unwrap_or("").to_string();
                if !b["input"].is_object() || name.is_empty() {
                    return Err(LlmError::Malformed(format!(
                        "`{name}` input is not an object"
                    )));
                }
                r.calls.push(ToolCall {
                    id: b["id"].as_str().unwrap_or("call").to_string(),
                    name,
                    arguments: b["input"].clone(),
                });
            }
            _ => {}
        }
    }
    Ok(r)
}

fn truncate(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        format!("{}…", s.chars().take(n).collect::<String>())
    }
}

/// The most a model server's reply body may hold. A reply holds at most the requested
/// tokens, a few MiB of JSON; past this the server or a proxy misbehaves, and the reply is
/// refused (not retried: another attempt would read as much again).
pub const MAX_REPLY_BYTES: u64 = 64 << 20;

/// One request, no retries.
fn request_once(cfg: &ModelConfig, body: &Value) -> Result<Reply, LlmError> {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .timeout_global(Some(cfg.timeout))
        .http_status_as_error(false)
        .build()
        .into();
    let (url, req) = match cfg.protocol {
        Protocol::OpenAi => {
            let url = format!("{}/chat/completions", cfg.base_url);
            let mut r = agent.post(&url).header("content-type", "application/json");
            if let Some(k) = &cfg.api_key {
                r = r.header("authorization", &format!("Bearer {k}"));
            }
            (url, r)
        }
        Protocol::Anthropic => {
            let url = format!("{}/v1/messages", cfg.base_url);
            let mut r = agent
                .post(&url)
                .header("content-type", "application/json")
                .header("anthropic-version", "2023-06-01");
            if let Some(k) = &cfg.api_key {
                r = r.header("x-api-key", k);
            }
            (url, r)
        }
    };
    let mut resp = req
        .send_json(body)
        .map_err(|e| LlmError::Transient(format!("{url}: {e}")))?;
    let status = resp.status().as_u16();
    let retry_after = resp
        .headers()
        .get("retry-after")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| parse_retry_after(v, std::time::SystemTime::now()));
    let too_large = || {
        LlmError::Fatal(format!(
            "{url}: the reply is larger than the limit of {} MiB (a misbehaving server or proxy); not retried",
            MAX_REPLY_BYTES >> 20
        ))
    };
    let declared = resp
        .headers()
        .get("content-length")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    if declared.is_some_and(|n| n > MAX_REPLY_BYTES) {
        return Err(too_large());
    }
    let text = resp
        .body_mut()
        .with_config()
        .limit(MAX_REPLY_BYTES)
        .read_to_string()
        .map_err(|e| match e {
            ureq::Error::BodyExceedsLimit(_) => too_large(),
            e => LlmError::Transient(format!("{url}: reading the reply: {e}")),
        })?;
    if status == 429 {
        return Err(LlmError::RateLimited {
            message: format!("{url}: HTTP 429: {}", truncate(&text, 300)),
            retry_after,
        });
    }
    if status >= 500 {
        return Err(LlmError::Transient(format!(
            "{url}: HTTP {status}: {}",
            truncate(&text, 300)
        )));
    }
    if status >= 400 {
        return Err(LlmError::Fatal(format!(
            "{url}: HTTP {status}: {}",
            truncate(&text, 500)
        )));
    }
    parse_reply(cfg.protocol, &text).map_err(|e| match e {
        LlmError::Transient(m) => LlmError::Transient(format!("{url}: {m}")),
        other => other,
    })
}

/// A model server's reply body, as text, in the protocol's form.
pub fn parse_reply(protocol: Protocol, text: &str) -> Result<Reply, LlmError> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| LlmError::Transient(format!("the reply is not JSON ({e})")))?;
    match protocol {
        Protocol::OpenAi => parse_openai(&v),
        Protocol::Anthropic => parse_anthropic(&v),
    }
}

/// Asks the model, retrying transient failures and malformed tool calls with exponential
/// backoff (or the server's `Retry-After` on a 429, when longer). `on_retry` hears each
/// failure before its retry. When every attempt fails the error is
/// [`LlmError::GaveUp`], which names every kind of failure seen.
pub fn complete(
    cfg: &ModelConfig,
    system: &str,
    messages: &[Message],
    tools: &[ToolSpec],
    on_retry: &dyn Fn(u32, &LlmError),
) -> Result<Reply, LlmError> {
    complete_with(cfg, system, messages, tools, on_retry, &|d| {
        std::thread::sleep(d)
    })
}

/// [`complete`] with the waits between attempts made through `sleep` (tests record them).
pub fn complete_with(
    cfg: &ModelConfig,
    system: &str,
    messages: &[Message],
    tools: &[ToolSpec],
    on_retry: &dyn Fn(u32, &LlmError),
    sleep: &dyn Fn(Duration),
) -> Result<Reply, LlmError> {
    let body = match cfg.protocol {
        Protocol::OpenAi => openai_body(cfg, system, messages, tools),
        Protocol::Anthropic => anthropic_body(cfg, system, messages, tools),
    };
    let mut failures: Vec<(String, u32)> = Vec::new();
    let mut attempt = 0;
    loop {
        let e = match request_once(cfg, &body) {
            Ok(r) => return Ok(r),
            Err(e) => e,
        };
        let kind = e.kind();
        match failures.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, n)) => *n += 1,
            None => failures.push((kind, 1)),
        }
        if matches!(e, LlmError::Fatal(_)) || attempt >= cfg.retries {
            // A first failure that is fatal is reported as it is.
            if attempt == 0 {
                return Err(e);
            }
            return Err(LlmError::GaveUp {
                attempts: attempt + 1,
                failures,
                last: Box::new(e),
            });
        }
        on_retry(attempt + 1, &e);
        let backoff = cfg.backoff * 2u32.saturating_pow(attempt);
        let wait = match &e {
            LlmError::RateLimited {
                retry_after: Some(d),
                ..
            } => backoff.max(*d),
            _ => backoff,
        };
        sleep(wait);
        attempt += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(p: Protocol) -> ModelConfig {
        ModelConfig {
            protocol: p,
            provider: "local".into(),
            model: "m".into(),
            base_url: "http://127.0.0.1:1".into(),
            api_key: None,
            timeout: Duration::from_secs(1),
            retries: 0,
            backoff: Duration::from_millis(1),
            max_reply_tokens: 100,
        }
    }

    fn conversation() -> Vec<Message> {
        let img = Part::Image {
            mime: "image/png".into(),
            data_b64: "AAAA".into(),
            path: "x.png".into(),
        };
        vec![
            Message::User(vec![Part::Text("begin".into())]),
            Message::Assistant {
                text: "looking".into(),
                calls: vec![
                    ToolCall {
                        id: "c1".into(),
                        name: "render".into(),
                        arguments: json!({"frames": "all"}),
                    },
                    ToolCall {
                        id: "c2".into(),
                        name: "score".into(),
                        arguments: json!({}),
                    },
                ],
            },
            Message::ToolResult {
                call_id: "c1".into(),
                name: "render".into(),
                parts: vec![Part::Text("ok".into()), img],
                is_error: false,
            },
            Message::ToolResult {
                call_id: "c2".into(),
                name: "score".into(),
                parts: vec![Part::Text("bad".into())],
                is_error: true,
            },
        ]
    }

    #[test]
    fn openai_requests_carry_tool_results_and_their_images() {
        let b = openai_body(
            &cfg(Protocol::OpenAi),
            "sys",
            &conversation(),
            &crate::tools::catalogue(),
        );
        let m = b["messages"].as_array().expect("messages");
        assert_eq!(m[0]["role"], "system");
        assert_eq!(
            m[2]["tool_calls"][0]["function"]["arguments"],
            "{\"frames\":\"all\"}"
        );
        assert_eq!(m[3]["role"], "tool");
        assert_eq!(m[4]["role"], "user");
        assert!(m[4]["content"][1]["image_url"]["url"]
            .as_str()
            .expect("url")
            .starts_with("data:image/png;base64,AAAA"));
        assert_eq!(m[5]["content"], "ERROR: bad");
        assert_eq!(
            b["tools"].as_array().expect("tools").len(),
            crate::tools::catalogue().len()
        );
    }

    #[test]
    fn anthropic_requests_alternate_roles_and_merge_tool_results() {
        let b = anthropic_body(&cfg(Protocol::Anthropic), "sys", &conversation(), &[]);
        let m = b["messages"].as_array().expect("messages");
        let roles: Vec<&str> = m
            .iter()
            .map(|x| x["role"].as_str().expect("role"))
            .collect();
        assert_eq!(roles, ["user", "assistant", "user"]);
        assert_eq!(m[2]["content"].as_array().expect("c").len(), 2);
        assert_eq!(m[2]["content"][0]["content"][1]["source"]["data"], "AAAA");
        assert_eq!(m[2]["content"][1]["is_error"], true);
    }

    #[test]
    fn replies_parse_and_malformed_arguments_are_named() {
        let ok = json!({"choices": [{"message": {"content": "", "tool_calls": [
            {"id": "a", "function": {"name": "score", "arguments": "{}"}}]}}],
            "usage": {"prompt_tokens": 10, "completion_tokens": 2}});
        let r = parse_openai(&ok).expect("reply");
        assert_eq!((r.calls[0].name.as_str(), r.input_tokens), ("score", 10));
        let bad = json!({"choices": [{"message": {"tool_calls": [
            {"id": "a", "function": {"name": "sweep", "arguments": "{\"frames\": "}}]}}]});
        match parse_openai(&bad) {
            Err(LlmError::Malformed(m)) => assert!(m.contains("sweep"), "{m}"),
            other => panic!("{other:?}"),
        }
        let a = json!({"content": [{"type": "text", "text": "hi"}, {"type": "tool_use", "id": "t", "name": "render", "input": {}}],
            "usage": {"input_tokens": 5, "output_tokens": 1}});
        let r = parse_anthropic(&a).expect("reply");
        assert_eq!((r.text.as_str(), r.calls.len()), ("hi", 1));
    }

    #[test]
    fn model_specs_parse_with_local_servers_needing_no_key() {
        let c = ModelConfig::parse("ollama:qwen2.5vl", None).expect("ollama");
        assert_eq!(
            (c.protocol, c.base_url.as_str()),
            (Protocol::OpenAi, "http://localhost:11434/v1")
        );
        let c = ModelConfig::parse("local:m", Some("http://127.0.0.1:9/v1/")).expect("local");
        assert_eq!(c.base_url, "http://127.0.0.1:9/v1");
        assert!(ModelConfig::parse("gpt-4", None).is_err());
        assert!(ModelConfig::parse("acme:x", None)
            .expect_err("unknown")
            .contains("unknown provider"));
    }
}
