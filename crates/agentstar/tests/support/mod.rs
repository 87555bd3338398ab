//! Helpers shared by the binary's integration tests: running the executable, small
//! synthetic captures and runs, an MCP client over stdio, golden files, and a mock model
//! server (`model`).
#![allow(dead_code)]

pub mod model;

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `agentstar ARGS` to completion.
pub fn agentstar(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_agentstar"))
        .args(args)
        .output()
        .expect("run agentstar")
}

/// Runs `agentstar ARGS` to completion with extra environment variables.
pub fn agentstar_in(env: &[(&str, &str)], args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_agentstar"));
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("run agentstar")
}

/// A path as a borrowed `&str` argument.
pub fn path_str(path: &Path) -> &str {
    path.to_str().expect("utf8")
}

/// A command's stdout and stderr, for assertion messages.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A path as a `&str` argument.
pub fn s(path: &Path) -> String {
    path.to_str().expect("utf8").to_string()
}

/// The built-in example (6 frames) in `dir`: its capture, model and poses.
pub fn example(dir: &Path) -> (String, String, String) {
    let o = agentstar(&["example", dir.to_str().expect("utf8"), "--frames", "6"]);
    assert!(o.status.success(), "{}", text(&o));
    let cap = dir.join("capture").display().to_string();
    let model = dir.join("run/scene.rhai").display().to_string();
    let poses = dir.join("run/pose.json").display().to_string();
    (cap, model, poses)
}

/// A command's stdout parsed as its typed report, asserting that it succeeded.
pub fn json_of<T: serde::de::DeserializeOwned>(o: &Output) -> T {
    assert!(o.status.success(), "{}", text(o));
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(o)))
}

/// `agentstar VERB --capture CAP --model MODEL --poses POSES ARGS…` run to completion (the
/// shape of every command that reads a capture, a model and its poses).
pub fn on_poses(verb: &str, cap: &str, model: &str, poses: &str, args: &[&str]) -> Output {
    let mut all = vec![verb, "--capture", cap, "--model", model, "--poses", poses];
    all.extend_from_slice(args);
    agentstar(&all)
}

/// `agentstar track CAP --model MODEL --scale-from POSES --out OUT --evals 1200 --json`
/// (the known model tracked from scratch at the true scale), its report (`TrackReport`, or
/// `serde_json::Value`; generic so that this module links nothing of ours).
pub fn track_known<T: serde::de::DeserializeOwned>(
    cap: &str,
    model: &str,
    scale_from: &str,
    out: &Path,
) -> T {
    json_of(&agentstar(&[
        "track",
        cap,
        "--model",
        model,
        "--scale-from",
        scale_from,
        "--out",
        out.to_str().expect("utf8"),
        "--evals",
        "1200",
        "--json",
    ]))
}

/// `agentstar score --capture CAP --model MODEL --poses POSES [--frames F] --json`, its
/// report (`ScoreReport`). Its status is not asserted: `score` exits 1 when a frame is
/// under the gate, and still prints its report.
pub fn score_of<T: serde::de::DeserializeOwned>(
    cap: &str,
    model: &str,
    poses: &str,
    frames: Option<&str>,
) -> T {
    let mut args = vec!["--json"];
    if let Some(f) = frames {
        args.extend(["--frames", f]);
    }
    let o = on_poses("score", cap, model, poses, &args);
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(&o)))
}

/// `agentstar eval --capture CAP --model MODEL --poses POSES --samples N --json`, its report
/// (`EvalReport`).
pub fn eval_of<T: serde::de::DeserializeOwned>(
    cap: &str,
    model: &str,
    poses: &str,
    samples: usize,
) -> T {
    let n = samples.to_string();
    json_of(&on_poses(
        "eval",
        cap,
        model,
        poses,
        &["--samples", &n, "--json"],
    ))
}

/// `agentstar synth OUT --object OBJECT ARGS…` run to completion.
pub fn synth_object(out: &str, object: &str, args: &[&str]) -> Output {
    let mut all = vec!["synth", out, "--object", object];
    all.extend_from_slice(args);
    agentstar(&all)
}

/// The hand-held box with hands, seed 7 (the demo's clip), `frames` keyframes, at 160×120
/// when `small` (else 320×240), written to `out`.
pub fn synth_box(out: &Path, frames: usize, small: bool) {
    let n = frames.to_string();
    let mut args = vec!["--frames", &n, "--seed", "7"];
    if small {
        args.extend(["--size", "160x120"]);
    }
    let o = synth_object(path_str(out), "box", &args);
    assert!(o.status.success(), "{}", text(&o));
}

/// A small synthetic capture `DIR/cap` (the hand-held box, 160×120) and a run `DIR/run` on
/// it, started from the known scene at its scale or from the default box.
pub fn small_run(dir: &Path, frames: usize, known_scene: bool) {
    let (cap, run) = (dir.join("cap"), dir.join("run"));
    synth_box(&cap, frames, true);
    let scene = cap.join("model/scene.rhai");
    init_run(&run, &cap, known_scene.then_some((scene.as_path(), "0.24")));
}

/// `small_run` from the known scene, with the capture's true poses copied into the run's
/// `pose.json`; returns the run.
pub fn small_run_at_truth(dir: &Path, frames: usize) -> PathBuf {
    small_run(dir, frames, true);
    let run = dir.join("run");
    std::fs::copy(dir.join("cap/model/pose.json"), run.join("pose.json")).expect("true poses");
    run
}

/// `agentstar init RUN --capture CAP [--scene SCENE --scale SCALE]`, asserting that it
/// succeeded.
pub fn init_run(run: &Path, cap: &Path, scene_at_scale: Option<(&Path, &str)>) {
    let mut args = vec!["init", path_str(run), "--capture", path_str(cap)];
    if let Some((scene, scale)) = scene_at_scale {
        args.extend(["--scene", path_str(scene), "--scale", scale]);
    }
    let o = agentstar(&args);
    assert!(o.status.success(), "init {}: {}", run.display(), text(&o));
}

/// Writes to `to` a copy of the pose file `from` with every translation moved by `dx`
/// metres along x.
pub fn shifted_poses(from: &Path, to: &Path, dx: f64) {
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(from).expect("pose.json")).expect("json");
    for f in v["frames"].as_object_mut().expect("frames").values_mut() {
        let x = f["object_pose"]["translation"][0].as_f64().expect("x");
        f["object_pose"]["translation"][0] = serde_json::Value::from(x + dx);
    }
    std::fs::write(to, serde_json::to_string_pretty(&v).expect("json")).expect("write");
}

/// Asserts that a command failed and that its output says every one of `needles`; the
/// message names the missing one and shows the output.
pub fn assert_failed_saying(o: &Output, needles: &[&str]) {
    let t = text(o);
    assert!(!o.status.success(), "the command succeeded: {t}");
    for needle in needles {
        assert!(t.contains(needle), "missing `{needle}` in: {t}");
    }
}

/// Turns the mechanism gate off in `RUN/run.json` (`finish.mechanism_check: false`), for
/// tests of the other gates on the box, whose lid is a revolute joint. A server reads the
/// policy when it starts.
pub fn mechanism_check_off(run: &Path) {
    let rf = run.join("run.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&rf).expect("run.json")).expect("json");
    v["finish"]["mechanism_check"] = serde_json::json!(false);
    std::fs::write(&rf, v.to_string()).expect("write run.json");
}

/// The ledger's entries.
pub fn ledger(run: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(run.join("ledger.jsonl"))
        .expect("ledger")
        .lines()
        .map(|l| serde_json::from_str(l).expect("ledger line"))
        .collect()
}

/// The tools of the ledger's entries, in order.
pub fn ledger_tools(run: &Path) -> Vec<String> {
    ledger(run)
        .iter()
        .map(|v| v["tool"].as_str().expect("tool").to_string())
        .collect()
}

/// Set to update every golden file and snapshot from what the code produces now (the
/// renderer's golden images use the same variable).
pub const UPDATE_ENV: &str = "AGENTSTAR_BLESS";

/// Compares `now` with the golden file `tests/snapshots/NAME` (written when
/// `AGENTSTAR_BLESS` is set, the one variable that rewrites every golden file).
pub fn assert_snapshot(name: &str, now: &str) {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/snapshots")
        .join(name);
    if std::env::var_os(UPDATE_ENV).is_some() {
        std::fs::write(&path, now).expect("write snapshot");
    }
    let committed = std::fs::read_to_string(&path)
        .unwrap_or_else(|_| panic!("tests/snapshots/{name} ({UPDATE_ENV}=1 writes it)"));
    assert_eq!(
        now, committed,
        "tests/snapshots/{name} changed: review it, then {UPDATE_ENV}=1"
    );
}

/// A minimal MCP client over the child's stdio: JSON-RPC lines.
pub struct McpClient {
    child: std::process::Child,
    stdin: Option<std::process::ChildStdin>,
    lines: std::io::Lines<std::io::BufReader<std::process::ChildStdout>>,
}

impl McpClient {
    pub fn start(run: &Path) -> McpClient {
        let mut child = Command::new(env!("CARGO_BIN_EXE_agentstar"))
            .args(["mcp", run.to_str().expect("utf8")])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("start mcp");
        let stdin = child.stdin.take().expect("stdin");
        let lines = std::io::BufReader::new(child.stdout.take().expect("stdout")).lines();
        McpClient {
            child,
            stdin: Some(stdin),
            lines,
        }
    }

    /// Starts a server on `run` and initialises the session; returns the initialize result.
    pub fn initialised(run: &Path) -> (McpClient, serde_json::Value) {
        let mut c = McpClient::start(run);
        c.send(serde_json::json!({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
            "protocolVersion": "2025-06-18", "capabilities": {}, "clientInfo": {"name": "test", "version": "0"}}}));
        let (init, _) = c.response(1);
        c.send(serde_json::json!({"jsonrpc": "2.0", "method": "notifications/initialized"}));
        (c, init)
    }

    pub fn send(&mut self, v: serde_json::Value) {
        self.send_raw(v.to_string().as_bytes());
    }

    /// Writes `bytes` and a newline as one request line.
    pub fn send_raw(&mut self, bytes: &[u8]) {
        let stdin = self.stdin.as_mut().expect("stdin open");
        stdin.write_all(bytes).expect("write");
        stdin.write_all(b"\n").expect("write");
        stdin.flush().expect("flush");
    }

    /// Sends `tools/call` of `name` with `args` as request `id` (without waiting).
    pub fn call(&mut self, id: u64, name: &str, args: serde_json::Value) {
        self.send(
            serde_json::json!({"jsonrpc": "2.0", "id": id, "method": "tools/call",
            "params": {"name": name, "arguments": args}}),
        );
    }

    /// The next message.
    pub fn next(&mut self) -> serde_json::Value {
        let line = self.lines.next().expect("the server closed").expect("line");
        serde_json::from_str(&line).expect("json")
    }

    /// The response to request `id` (notifications before it are returned too).
    pub fn response(&mut self, id: u64) -> (serde_json::Value, Vec<serde_json::Value>) {
        let mut notes = vec![];
        loop {
            let v = self.next();
            if v["id"] == id {
                return (v, notes);
            }
            notes.push(v);
        }
    }

    /// Responses to every id in `ids`, in any order, keyed by id.
    pub fn responses(&mut self, ids: &[u64]) -> std::collections::BTreeMap<u64, serde_json::Value> {
        let mut got = std::collections::BTreeMap::new();
        while got.len() < ids.len() {
            let v = self.next();
            if let Some(id) = v["id"].as_u64().filter(|id| ids.contains(id)) {
                got.insert(id, v);
            }
        }
        got
    }

    /// The text of a tool result's first content block.
    pub fn text_of(result: &serde_json::Value) -> String {
        result["result"]["content"][0]["text"]
            .as_str()
            .unwrap_or_default()
            .to_string()
    }
}

impl McpClient {
    /// Closes the server's stdin (a client that goes away) and waits, bounded, for the server
    /// to exit.
    pub fn hang_up(&mut self) -> std::process::ExitStatus {
        drop(self.stdin.take());
        let t0 = std::time::Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("wait") {
                return status;
            }
            assert!(
                t0.elapsed() < std::time::Duration::from_secs(180),
                "the MCP server did not exit after its client went away"
            );
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    }
}

impl McpClient {
    /// Kills the server (`kill -9`) with its stdin still open, and reaps it.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for McpClient {
    fn drop(&mut self) {
        drop(self.stdin.take());
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
