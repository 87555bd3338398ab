//! A model server on loopback for the agent loop's tests: it replays scripted answers to
//! OpenAI chat-completions requests in order and keeps every request body; and the replies
//! a script is made of.

use std::collections::VecDeque;
use std::path::Path;
use std::process::{Command, Output};
use std::sync::{Arc, Mutex};

/// What the mock model server does with one request.
pub enum Act {
    /// Answer with this status and JSON body.
    Json(u16, serde_json::Value),
    /// Wait this many milliseconds first (past the client's timeout), then answer.
    Slow(u64, serde_json::Value),
    /// Answer with this status and a body that need not be JSON.
    Raw(u16, String),
}

/// A running mock model server: its base URL and the request bodies it has had (`null` for
/// a body that was not JSON).
pub struct MockModel {
    pub url: String,
    pub requests: Arc<Mutex<Vec<serde_json::Value>>>,
}

impl MockModel {
    /// The request bodies so far, in the order they came.
    pub fn requests(&self) -> Vec<serde_json::Value> {
        self.requests.lock().expect("lock").clone()
    }
}

/// Starts a server that answers each request with the next act of `script` (HTTP 500 once
/// the script is spent), every connection on its own thread.
pub fn mock_model(script: Vec<Act>) -> MockModel {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let url = format!("http://{}/v1", listener.local_addr().expect("addr"));
    let requests = Arc::new(Mutex::new(vec![]));
    let script = Arc::new(Mutex::new(VecDeque::from(script)));
    let reqs = requests.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(stream) = stream else { continue };
            let (reqs, script) = (reqs.clone(), script.clone());
            std::thread::spawn(move || answer(stream, &reqs, &script));
        }
    });
    MockModel { url, requests }
}

/// Reads one request from `stream`, records its body and writes the script's next answer.
fn answer(
    mut stream: std::net::TcpStream,
    reqs: &Mutex<Vec<serde_json::Value>>,
    script: &Mutex<VecDeque<Act>>,
) {
    use std::io::{BufRead, BufReader, Read, Write};
    let mut reader = BufReader::new(stream.try_clone().expect("clone"));
    let mut len = 0usize;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap_or(0) == 0 {
            return;
        }
        let l = line.trim_end().to_ascii_lowercase();
        if l.is_empty() {
            break;
        }
        if let Some(v) = l.strip_prefix("content-length:") {
            len = v.trim().parse().unwrap_or(0);
        }
    }
    let mut body = vec![0u8; len];
    if reader.read_exact(&mut body).is_err() {
        return;
    }
    let act = {
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap_or_default();
        reqs.lock().expect("lock").push(v);
        script.lock().expect("lock").pop_front()
    };
    let (status, text) = match act {
        Some(Act::Json(s, v)) => (s, v.to_string()),
        Some(Act::Slow(ms, v)) => {
            std::thread::sleep(std::time::Duration::from_millis(ms));
            (200, v.to_string())
        }
        Some(Act::Raw(s, t)) => (s, t),
        None => (500, "{\"error\": \"the script is exhausted\"}".into()),
    };
    let _ = write!(
        stream,
        "HTTP/1.1 {status} X\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{text}",
        text.len()
    );
}

/// An OpenAI-style reply holding one tool call.
pub fn tool_call(id: &str, name: &str, args: serde_json::Value) -> Act {
    Act::Json(
        200,
        serde_json::json!({"choices": [{"message": {"role": "assistant", "content": format!("calling {name}"),
            "tool_calls": [{"id": id, "type": "function", "function": {"name": name, "arguments": args.to_string()}}]}}],
            "usage": {"prompt_tokens": 1000, "completion_tokens": 20}}),
    )
}

/// An OpenAI-style reply holding `n` calls of one tool (ids `c0`, `c1`, …), that says it
/// took `prompt_tokens` prompt tokens.
pub fn tool_calls(n: usize, name: &str, args: serde_json::Value, prompt_tokens: u64) -> Act {
    let calls: Vec<serde_json::Value> = (0..n)
        .map(|i| {
            serde_json::json!({"id": format!("c{i}"), "type": "function",
            "function": {"name": name, "arguments": args.to_string()}})
        })
        .collect();
    Act::Json(
        200,
        serde_json::json!({"choices": [{"message": {"role": "assistant", "content": "",
            "tool_calls": calls}}], "usage": {"prompt_tokens": prompt_tokens, "completion_tokens": 20}}),
    )
}

/// A reply whose one tool call's arguments are cut off mid-JSON.
pub fn malformed_tool_call() -> Act {
    Act::Json(
        200,
        serde_json::json!({"choices": [{"message": {"content": "", "tool_calls": [
        {"id": "x", "type": "function", "function": {"name": "sweep", "arguments": "{\"frames\": "}}]}}]}),
    )
}

/// `agentstar run RUN --model local:mock --base-url MODEL ARGS…`, not yet run.
pub fn model_run_command(run: &Path, model: &MockModel, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_agentstar"));
    c.args(["run", run.to_str().expect("utf8")])
        .args(["--model", "local:mock", "--base-url", &model.url])
        .args(args);
    c
}

/// `agentstar run RUN --model local:mock --base-url MODEL ARGS…` run to completion.
pub fn model_run(run: &Path, model: &MockModel, args: &[&str]) -> Output {
    model_run_command(run, model, args)
        .output()
        .expect("run agentstar")
}
