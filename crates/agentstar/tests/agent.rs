//! The built-in agent loop against a mock model server: a whole run, failures and resuming,
//! pose sub-agents, and external agents' configuration.

mod support;

use std::path::Path;
use support::model::{
    malformed_tool_call, mock_model, model_run, model_run_command, tool_call, Act,
};
use support::{agentstar, ledger_tools, on_poses, score_of, small_run, synth_box, text};

#[test]
fn the_agent_loop_builds_tracks_and_passes_the_gates_against_a_mock_model() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    synth_box(&p("cap"), 10, false);
    let o = agentstar(&[
        "init",
        &s(&p("run")),
        "--capture",
        &s(&p("cap")),
        "--scale",
        "0.24",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(p("run/TASK.md").is_file() && p("run/NOTES.md").is_file());
    // A scripted model cannot look at the mechanism sheets (tests/mechanism.rs does).
    support::mechanism_check_off(&p("run"));
    let known = std::fs::read_to_string(p("cap/model/scene.rhai")).expect("scene");
    let model = mock_model(vec![
        // A server error and a reply slower than the timeout: both retried.
        Act::Json(500, serde_json::json!({"error": "overloaded"})),
        Act::Slow(2500, serde_json::json!({})),
        tool_call("c1", "render", serde_json::json!({"frames": "000000"})),
        tool_call(
            "c2",
            "scene_write",
            serde_json::json!({"script": "part(\"body\", box(1, 0.6"}),
        ),
        tool_call("c3", "scene_write", serde_json::json!({"script": known})),
        tool_call("c4", "track", serde_json::json!({})),
        tool_call("c5", "turntable", serde_json::json!({})),
        tool_call("c6", "temporal", serde_json::json!({})),
        tool_call(
            "c7",
            "notes",
            serde_json::json!({"text": "a box with a hinged lid"}),
        ),
        tool_call("c8", "finish", serde_json::json!({"summary": "done"})),
    ]);
    let o = model_run(
        &p("run"),
        &model,
        &[
            "--request-timeout",
            "1",
            "--retries",
            "3",
            "--backoff-ms",
            "10",
            "--json",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["finished"], true, "{v}");
    assert_eq!(v["steps"], 8);
    let reqs = model.requests();
    assert_eq!(reqs.len(), 10, "two failed attempts, then eight steps");
    // The request after `render` carries the rendered images.
    let after_render = reqs[3].to_string();
    assert!(
        after_render.contains("data:image/png;base64,"),
        "no image sent"
    );
    // The broken scene's diagnostic went back to the model, and the loop went on.
    let after_bad = reqs[4]["messages"].as_array().expect("messages").clone();
    let diag = after_bad
        .iter()
        .rfind(|m| m["role"] == "tool")
        .expect("tool message")["content"]
        .as_str()
        .expect("text")
        .to_string();
    assert!(
        diag.starts_with("ERROR: the scene was not changed"),
        "{diag}"
    );
    // The system prompt is the task document with the notes.
    assert!(reqs[9]["messages"][0]["content"]
        .as_str()
        .expect("system")
        .contains("a box with a hinged lid"));
    assert_eq!(
        ledger_tools(&p("run")),
        [
            "init",
            "render",
            "scene_write",
            "scene_write",
            "track",
            "turntable",
            "temporal",
            "notes",
            "finish",
            "stop"
        ]
    );
    // The run holds the model and poses that pass the gate, and two scene versions.
    let o = on_poses(
        "score",
        &s(&p("cap")),
        &s(&p("run/scene.rhai")),
        &s(&p("run/pose.json")),
        &[],
    );
    assert!(o.status.success(), "{}", text(&o));
    assert!(p("run/.agentstar/scenes/0002.rhai").is_file());
    // A finished run says so and does nothing; its report shows the steps.
    let o = model_run(&p("run"), &model, &[]);
    assert!(
        o.status.success() && text(&o).contains("finished"),
        "{}",
        text(&o)
    );
    let o = agentstar(&["report", &s(&p("run"))]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(p("run/report.html")).expect("report");
    assert!(html.contains("scene_write") && html.contains("the scene was not changed"));
}

#[test]
fn a_failing_model_stops_cleanly_and_the_run_resumes_within_its_budget() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    small_run(dir.path(), 3, false);
    let poses_before = std::fs::read(p("run/pose.json")).expect("poses");
    // 1. Malformed tool calls, retried, then a clean stop.
    let model = mock_model(vec![
        malformed_tool_call(),
        malformed_tool_call(),
        malformed_tool_call(),
    ]);
    let o = model_run(&p("run"), &model, &["--retries", "2", "--backoff-ms", "5"]);
    assert_eq!(o.status.code(), Some(4), "{}", text(&o));
    assert!(text(&o).contains("malformed"), "{}", text(&o));
    assert_eq!(model.requests().len(), 3);
    assert_eq!(ledger_tools(&p("run")), ["init", "stop"]);
    assert_eq!(
        std::fs::read(p("run/pose.json")).expect("poses"),
        poses_before
    );
    // 2. Resumed with a step budget of 2: two steps, then a budget stop.
    let model = mock_model(vec![
        tool_call("a", "score", serde_json::json!({})),
        tool_call(
            "b",
            "render",
            serde_json::json!({"frames": "all", "views": "compare"}),
        ),
        tool_call("c", "score", serde_json::json!({})),
    ]);
    let o = model_run(&p("run"), &model, &["--max-steps", "2"]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(text(&o).contains("step budget"), "{}", text(&o));
    assert_eq!(
        ledger_tools(&p("run")),
        ["init", "stop", "score", "render", "stop"]
    );
    // The run is consistent: its poses still score, its capture still validates.
    let _: serde_json::Value = score_of(
        &s(&p("cap")),
        &s(&p("run/scene.rhai")),
        &s(&p("run/pose.json")),
        None,
    );
    // 3. Resumed again: the model is told where the run stands.
    let model = mock_model(vec![tool_call(
        "d",
        "notes",
        serde_json::json!({"text": "resumed"}),
    )]);
    let o = model_run(&p("run"), &model, &["--retries", "0"]);
    assert_eq!(o.status.code(), Some(4), "{}", text(&o));
    let first = model.requests()[0].to_string();
    assert!(
        first.contains("resuming this run after 2 step(s)"),
        "{first}"
    );
    assert!(
        first.contains("render"),
        "the resume summary lists the earlier steps"
    );
}

#[test]
fn pose_sub_agents_work_their_windows_in_parallel_and_report_back() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    small_run(dir.path(), 4, true);
    let finish = || {
        tool_call(
            "w",
            "finish",
            serde_json::json!({"summary": "checked the flips"}),
        )
    };
    let model = mock_model(vec![
        tool_call(
            "d",
            "delegate_pose",
            serde_json::json!({"windows": ["000000..000005", "000010..000015"],
                "brief": "The poses are near the right basin; check flips about z."}),
        ),
        // Each window's agent answers once (in whichever order they ask).
        finish(),
        finish(),
        tool_call("n", "notes", serde_json::json!({"text": "windows back"})),
    ]);
    let o = model_run(&p("run"), &model, &["--retries", "0"]);
    // The script ends before the gates: a model error stop, with every step recorded.
    assert_eq!(o.status.code(), Some(4), "{}", text(&o));
    let reqs = model.requests();
    let briefed: Vec<&serde_json::Value> = reqs
        .iter()
        .filter(|r| {
            r["messages"][0]["content"]
                .as_str()
                .is_some_and(|c| c.contains("check flips about z"))
        })
        .collect();
    assert_eq!(
        briefed.len(),
        2,
        "each window's agent has its own context and the brief"
    );
    let mut windows: Vec<String> = briefed
        .iter()
        .map(|r| {
            r["messages"][1]["content"][0]["text"]
                .as_str()
                .expect("opening")
                .to_string()
        })
        .collect();
    windows.sort();
    assert!(
        windows[0].contains("000000.png, 000005.png")
            && windows[1].contains("000010.png, 000015.png"),
        "{windows:?}"
    );
    // The orchestrator heard back from both windows.
    let back = reqs[3].to_string();
    assert!(
        back.contains("window 1 (000000..000005): Finished")
            && back.contains("window 2 (000010..000015): Finished"),
        "{back}"
    );
    let ledger = std::fs::read_to_string(p("run/ledger.jsonl")).expect("ledger");
    let agents: Vec<String> = ledger
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["tool"] == "finish")
        .map(|v| {
            v["args"]["agent"]
                .as_str()
                .expect("agent label")
                .to_string()
        })
        .collect();
    assert_eq!(agents.len(), 2, "{ledger}");
}

#[test]
fn external_agents_get_their_configuration_and_keys_stay_out_of_the_run() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    small_run(dir.path(), 2, false);
    // The configuration snippets name this executable and the run.
    let o = agentstar(&["mcp", &s(&p("run")), "--print-config", "claude"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["mcpServers"]["agentstar"]["args"][0], "mcp");
    let o = agentstar(&["mcp", &s(&p("run")), "--print-config", "codex"]);
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("[mcp_servers.agentstar]"));
    // Without the agent installed: the configuration is written and the message says what
    // to install (PATH holds nothing here).
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_agentstar"))
        .args(["run", &s(&p("run")), "--agent", "claude"])
        .env("PATH", dir.path())
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("npm install -g @anthropic-ai/claude-code"),
        "{}",
        text(&o)
    );
    assert!(p("run/.mcp.json").is_file() && p("run/CLAUDE.md").is_file());
    // A key given in the environment is used but never written into the run.
    let model = mock_model(vec![tool_call("a", "score", serde_json::json!({}))]);
    let o = model_run_command(&p("run"), &model, &["--retries", "0"])
        .env("AGENTSTAR_API_KEY", "sk-secret-0123456789")
        .output()
        .expect("run");
    assert_eq!(o.status.code(), Some(4), "{}", text(&o));
    for entry in std::fs::read_dir(p("run")).expect("dir").flatten() {
        if entry.path().is_file() {
            let content = std::fs::read(entry.path()).expect("read");
            assert!(
                !String::from_utf8_lossy(&content).contains("sk-secret-0123456789"),
                "the key was written into {}",
                entry.path().display()
            );
        }
    }
}

/// Issue 35: every child process has a deadline. An agent whose `--version` never answers
/// (a fake `claude` on PATH that sleeps) is stopped at the probe's limit (30 s) and named,
/// instead of hanging `run --agent`.
#[cfg(unix)]
#[test]
fn an_agent_that_does_not_answer_its_version_probe_is_stopped_and_named() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().expect("tmp");
    small_run(dir.path(), 2, false);
    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).expect("bin");
    let fake = bin.join("claude");
    std::fs::write(&fake, "#!/bin/sh\nexec sleep 600\n").expect("fake");
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_else(|_| "/usr/bin:/bin".into())
    );
    let start = std::time::Instant::now();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_agentstar"))
        .args([
            "run",
            dir.path().join("run").to_str().expect("utf8"),
            "--agent",
            "claude",
        ])
        .env("PATH", path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run");
    // Past twice the limit the harness itself is stuck: stop it and fail.
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > std::time::Duration::from_secs(90) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("run --agent hung on a version probe that never answers");
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let o = child.wait_with_output().expect("output");
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("`claude --version` did not finish within 30 s")
            && text(&o).contains("does not answer"),
        "{}",
        text(&o)
    );
}
