//! The model clients and the critic against a model server on loopback that replays
//! scripted answers: retries with backoff on 5xx and timeouts, no retry on 401, both wire
//! protocols, and the critic's JSON checked.

mod support;

use agentstar_agent::llm::{complete, LlmError, Message, ModelConfig, Part, Protocol};
use serde_json::{json, Value};
use std::io::Write;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Every request the server saw: path and body.
type Seen = Arc<Mutex<Vec<(String, Value)>>>;

/// (status, body, delay ms) per request, in order; every request body is kept.
fn server(script: Vec<(u16, Value, u64)>) -> (String, Seen) {
    let (listener, url) = support::listen();
    let seen = Arc::new(Mutex::new(vec![]));
    let script = Arc::new(Mutex::new(std::collections::VecDeque::from(script)));
    let s2 = seen.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let (seen, script) = (s2.clone(), script.clone());
            std::thread::spawn(move || {
                let mut stream = stream;
                let (path, body) = support::read_request(&stream);
                seen.lock()
                    .expect("lock")
                    .push((path, serde_json::from_slice(&body).unwrap_or(Value::Null)));
                let next = script.lock().expect("lock").pop_front();
                let (status, v, delay) = next.unwrap_or((500, json!({"error": "exhausted"}), 0));
                std::thread::sleep(Duration::from_millis(delay));
                let t = v.to_string();
                let _ = write!(
                    stream,
                    "HTTP/1.1 {status} X\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{t}",
                    t.len()
                );
            });
        }
    });
    (url, seen)
}

fn config(protocol: Protocol, url: &str) -> ModelConfig {
    ModelConfig {
        protocol,
        provider: "local".into(),
        model: "mock".into(),
        base_url: url.into(),
        api_key: Some("k-test".into()),
        timeout: Duration::from_millis(700),
        retries: 3,
        backoff: Duration::from_millis(5),
        max_reply_tokens: 64,
    }
}

fn openai_text(t: &str) -> Value {
    json!({"choices": [{"message": {"content": t}}], "usage": {"prompt_tokens": 3, "completion_tokens": 1}})
}

#[test]
fn transient_failures_are_retried_and_fatal_ones_are_not() {
    let (url, seen) = server(vec![
        (500, json!({"error": "boom"}), 0),
        (429, json!({"error": "slow down"}), 0),
        (200, openai_text("late"), 1500),
        (200, openai_text("hello"), 0),
    ]);
    let retries = Mutex::new(vec![]);
    let r = complete(
        &config(Protocol::OpenAi, &format!("{url}/v1")),
        "sys",
        &[Message::User(vec![Part::Text("hi".into())])],
        &[],
        &|n, e| retries.lock().expect("lock").push((n, e.to_string())),
    )
    .expect("reply");
    assert_eq!(r.text, "hello");
    assert_eq!(seen.lock().expect("lock").len(), 4);
    assert_eq!(seen.lock().expect("lock")[0].0, "/v1/chat/completions");
    let r = retries.lock().expect("lock").clone();
    assert_eq!(r.iter().map(|x| x.0).collect::<Vec<_>>(), [1, 2, 3]);
    assert!(r[0].1.contains("500") && r[1].1.contains("429"), "{r:?}");
    // 401: told at once, not retried.
    let (url, seen) = server(vec![(401, json!({"error": "bad key"}), 0)]);
    let e = complete(&config(Protocol::OpenAi, &url), "s", &[], &[], &|_, _| {}).expect_err("401");
    assert!(
        matches!(e, LlmError::Fatal(ref m) if m.contains("401")),
        "{e}"
    );
    assert_eq!(seen.lock().expect("lock").len(), 1);
}

#[test]
fn anthropic_messages_round_trip_with_images_and_tool_calls() {
    let (url, seen) = server(vec![(
        200,
        json!({"content": [{"type": "text", "text": "let me look"},
            {"type": "tool_use", "id": "t1", "name": "render", "input": {"frames": "all"}}],
            "usage": {"input_tokens": 50, "output_tokens": 7}}),
        0,
    )]);
    let img = Part::Image {
        mime: "image/png".into(),
        data_b64: "iVBORw0KGgo=".into(),
        path: "a.png".into(),
    };
    let r = complete(
        &config(Protocol::Anthropic, &url),
        "the task",
        &[Message::User(vec![Part::Text("look".into()), img])],
        &agentstar_agent::tools::catalogue(),
        &|_, _| {},
    )
    .expect("reply");
    assert_eq!(
        (r.calls[0].name.as_str(), r.input_tokens, r.output_tokens),
        ("render", 50, 7)
    );
    let (path, body) = seen.lock().expect("lock")[0].clone();
    assert_eq!(path, "/v1/messages");
    assert_eq!(body["system"][0]["text"], "the task");
    assert_eq!(body["system"][0]["cache_control"]["type"], "ephemeral");
    assert_eq!(
        body["messages"][0]["content"][1]["source"]["media_type"],
        "image/png"
    );
    assert!(body["tools"]
        .as_array()
        .expect("tools")
        .iter()
        .any(|t| t["name"] == "sweep"));
}

#[test]
fn the_critic_returns_checked_json_and_rejects_prose() {
    let dir = tempfile::tempdir().expect("tmp");
    let png = dir.path().join("f.png");
    image_bytes(&png);
    let good = json!({"realism": 0.8, "identity": 0.6, "discrepancies": [
        {"tag": "joint_state", "severity": "high", "where": "lid", "direction": "open the lid further"}]});
    let (url, seen) = server(vec![
        (200, openai_text(&format!("```json\n{good}\n```")), 0),
        (200, openai_text("The lid looks wrong."), 0),
    ]);
    let cfg = config(Protocol::OpenAi, &url);
    let out = agentstar_agent::critic::criticise(&cfg, "000010.png", std::slice::from_ref(&png))
        .expect("critic");
    let v: Value = serde_json::from_str(&out).expect("json");
    assert_eq!(v["discrepancies"][0]["tag"], "joint_state");
    let sent = seen.lock().expect("lock")[0].1.to_string();
    assert!(sent.contains("data:image/png;base64,") && sent.contains("000010.png"));
    let e = agentstar_agent::critic::criticise(&cfg, "000010.png", &[png]).expect_err("prose");
    assert!(e.contains("did not answer JSON"), "{e}");
}

/// A tiny valid PNG.
fn image_bytes(path: &std::path::Path) {
    // 1×1 grey PNG.
    const PNG: [u8; 67] = [
        0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44,
        0x52, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x08, 0x00, 0x00, 0x00, 0x00, 0x3a,
        0x7e, 0x9b, 0x55, 0x00, 0x00, 0x00, 0x0a, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x68,
        0x00, 0x00, 0x00, 0x82, 0x00, 0x81, 0x4c, 0x17, 0xd7, 0xdf, 0x00, 0x00, 0x00, 0x00, 0x49,
        0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82,
    ];
    std::fs::write(path, PNG).expect("png");
}
