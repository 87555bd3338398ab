//! Every tool's command line parses: each tool of the registry is called on a small run with
//! a stand-in for the `agentstar` executable that records its arguments and fails, and every
//! recorded command line is parsed with the binary's own parser ([`crate::Cli`]). A field of
//! a tool's request that the command does not take, or a value the command reads as an
//! option, fails here.

use crate::{cmd, Cli, Command};
use agentstar_agent::run::RunDir;
use agentstar_agent::tools::{registry, Toolbox};
use clap::Parser;
use serde_json::{json, Value};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn run_cli(args: &[&str]) {
    let cli = Cli::try_parse_from(std::iter::once("agentstar").chain(args.iter().copied()))
        .unwrap_or_else(|e| panic!("{args:?}: {e}"));
    let result = match cli.command {
        Command::Synth(a) => cmd::synth::run(a),
        Command::Init(a) => cmd::agent::run_init(a),
        _ => panic!("only synth and init set the run up"),
    };
    result.unwrap_or_else(|e| panic!("{args:?}: {e:#}"));
}

/// A stand-in executable: writes its arguments (NUL-separated) to a new file in `log` and
/// exits 3.
fn recorder(dir: &Path, log: &Path) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let exe = dir.join("agentstar-recorder");
    std::fs::write(
        &exe,
        format!(
            "#!/bin/sh\nf=$(mktemp '{}/call.XXXXXX')\nprintf '%s\\0' \"$@\" > \"$f\"\nexit 3\n",
            log.display()
        ),
    )
    .expect("write recorder");
    std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    exe
}

/// The command lines recorded since the last call (and removes them).
fn recorded(log: &Path) -> Vec<Vec<String>> {
    let mut calls = vec![];
    for entry in std::fs::read_dir(log).expect("log dir") {
        let path = entry.expect("entry").path();
        let bytes = std::fs::read(&path).expect("read call");
        std::fs::remove_file(&path).expect("remove call");
        let args: Vec<String> = bytes
            .split(|b| *b == 0)
            .filter(|a| !a.is_empty())
            .map(|a| String::from_utf8(a.to_vec()).expect("utf8"))
            .collect();
        calls.push(args);
    }
    calls
}

/// Arguments for every tool: each field a tool takes, with values that reach its command.
fn samples() -> BTreeMap<&'static str, Vec<Value>> {
    BTreeMap::from([
        ("task", vec![json!({})]),
        ("scene_read", vec![json!({})]),
        (
            "scene_write",
            vec![json!({"script": "part(\"body\", box(1.0, 0.6, 0.4));", "hold": "body"})],
        ),
        ("scene_restore", vec![json!({"version": 1})]),
        (
            "bake",
            vec![
                json!({}),
                json!({"frames": "all", "force": true, "model": "scene.rhai"}),
            ],
        ),
        (
            "fit_shape",
            vec![
                json!({"params": ["width"], "frames": "all", "rounds": 2, "evals": 20, "hold": "body"}),
            ],
        ),
        (
            "render",
            vec![
                json!({"frames": "all", "views": "overlay,compare"}),
                json!({"frames": "-1"}),
            ],
        ),
        (
            "frames",
            vec![json!({"frames": "all", "margin": 0.5, "zoom": 2.0, "outline": "mask"})],
        ),
        ("score", vec![json!({"frames": "all"})]),
        ("turntable", vec![json!({"states": "all"})]),
        ("mechanism", vec![json!({}), json!({"joints": "lid_hinge"})]),
        (
            "mechanism_pick",
            vec![
                json!({"picks": {"lid_hinge": {"arm": "A", "evidence": "at 18 deg the lid lifts; at 55 deg it stands; at 92 deg it is upright"}}}),
            ],
        ),
        (
            "track",
            vec![
                json!({}),
                json!({"from": "pose.json", "anchors": "all", "scale": 0.25}),
                json!({"from": "pose.json", "keep_basins": true}),
            ],
        ),
        (
            "scale",
            vec![
                json!({"method": "size", "axis": "longest", "metres": 0.3, "frames": "all"}),
                json!({"method": "hand", "frames": "0..3"}),
            ],
        ),
        (
            "sweep",
            vec![
                json!({"frames": "all", "ranges": "yaw:-10,10", "strategy": "grid", "evals": 100}),
                json!({"frames": "--", "ranges": "-1"}),
                json!({"frames": "0", "ranges": "yaw:-5,5", "crop": "10,10,60,50", "zoom": 4}),
            ],
        ),
        ("apply", vec![json!({"frame": "all", "order": "yaw:5"})]),
        (
            "osweep",
            vec![
                json!({"frames": "all", "opreset": "z:flip"}),
                json!({"ranges": "rz:-180,180,9"}),
            ],
        ),
        (
            "oapply",
            vec![
                json!({"frames": "all", "set": "flips|swaps"}),
                json!({"frames": "0", "crop": "mask", "zoom": 2.5}),
            ],
        ),
        (
            "oapply_all",
            vec![json!({"rotation": "flip:x", "frames": "all", "crop": "0,0,30,20"})],
        ),
        (
            "pose_commit",
            vec![
                json!({"report": "pose.json", "frames": "all"}),
                json!({"report": "pose.json", "label": "flip:x"}),
            ],
        ),
        (
            "pose_history",
            vec![json!({"last": 5}), json!({"frame": "000000", "last": 5})],
        ),
        ("pose_restore", vec![json!({"version": 0, "frames": "all"})]),
        ("temporal", vec![json!({"sort_by": "rotation"})]),
        ("pose_diff", vec![json!({"a": "000000", "b": "000001"})]),
        ("critic", vec![json!({"frame": "000000"})]),
        ("notes", vec![json!({"text": "a note"})]),
        ("finish", vec![json!({})]),
    ])
}

/// The tools that run a command (the rest work in-process: the task, the notes, a pose
/// restore; the critic needs a model).
const RUN_A_COMMAND: &[&str] = &[
    "bake",
    "scene_read",
    "scene_write",
    "scene_restore",
    "fit_shape",
    "render",
    "frames",
    "score",
    "turntable",
    "mechanism",
    "track",
    "scale",
    "sweep",
    "apply",
    "osweep",
    "oapply",
    "oapply_all",
    "pose_commit",
    "pose_history",
    "temporal",
    "pose_diff",
    "finish",
];

#[test]
fn every_tools_command_line_parses_with_the_binarys_parser() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (cap, run, log) = (
        dir.path().join("cap"),
        dir.path().join("run"),
        dir.path().join("log"),
    );
    std::fs::create_dir_all(&log).expect("log dir");
    let s = |p: &Path| p.display().to_string();
    run_cli(&[
        "synth",
        &s(&cap),
        "--object",
        "box",
        "--frames",
        "3",
        "--size",
        "160x120",
        "--seed",
        "7",
    ]);
    run_cli(&[
        "init",
        &s(&run),
        "--capture",
        &s(&cap),
        "--scene",
        &s(&cap.join("model/scene.rhai")),
        "--scale",
        "0.24",
    ]);
    let tb = Toolbox::new(recorder(dir.path(), &log), RunDir::open(&run).expect("run"));
    let samples = samples();
    let names: BTreeSet<&str> = registry().iter().map(|t| t.name).collect();
    let sampled: BTreeSet<&str> = samples.keys().copied().collect();
    assert_eq!(names, sampled, "every tool needs sample arguments here");
    let mut ran = BTreeSet::new();
    let mut failures = vec![];
    let mut step = 1;
    for (tool, calls) in &samples {
        for args in calls {
            let out = tb.call(tool, args, step);
            step += 1;
            for argv in recorded(&log) {
                ran.insert(*tool);
                if let Err(e) = Cli::try_parse_from(
                    std::iter::once("agentstar".to_string()).chain(argv.clone()),
                ) {
                    failures.push(format!("{tool} {args}: {argv:?}\n{e}"));
                }
            }
            assert!(
                !out.text.contains("usage:") && !out.text.contains("Usage:"),
                "{tool} {args}: {}",
                out.text
            );
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
    let expected: BTreeSet<&str> = RUN_A_COMMAND.iter().copied().collect();
    assert_eq!(ran, expected, "the tools that ran a command");
}
