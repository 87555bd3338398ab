//! Baking a model's colours from the video: `agentstar bake` on a synthetic printed mug
//! given as an uncoloured model, the bake picked up by the other commands, refusals, bad
//! inputs, and the MCP tool.

mod support;

use agentstar_reports::{BakeReport, ScoreReport};
use serde_json::json;
use std::path::{Path, PathBuf};
use support::{
    agentstar, assert_failed_saying, init_run, json_of, on_poses, s, synth_object, text, McpClient,
};

/// The hard suite's printed mug (8 keyframes, 240×180) in `DIR/cap`, and in `DIR/run` its
/// true model with the badge painted the mug's colour (an uncoloured model) and its true
/// poses.
fn uncoloured_mug(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let cap = dir.join("cap");
    let o = synth_object(
        &s(&cap),
        "printmug",
        &["--frames", "8", "--size", "240x180", "--seed", "1"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let run = dir.join("run");
    std::fs::create_dir_all(&run).expect("run");
    let script = std::fs::read_to_string(cap.join("model/scene.rhai")).expect("scene");
    assert!(
        script.contains("#14339a"),
        "the badge's colour moved: {script}"
    );
    let scene = run.join("scene.rhai");
    std::fs::write(&scene, script.replace("#14339a", "#e9e4d8")).expect("write scene");
    let poses = run.join("pose.json");
    std::fs::copy(cap.join("model/pose.json"), &poses).expect("poses");
    (cap, scene, poses)
}

fn score(cap: &Path, scene: &Path, poses: &Path) -> ScoreReport {
    let o = on_poses("score", &s(cap), &s(scene), &s(poses), &["--json"]);
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(&o)))
}

/// `agentstar bake` on a capture, model and pose file, with `extra` arguments.
fn bake(cap: &Path, scene: &Path, poses: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "bake".to_string(),
        "--capture".into(),
        s(cap),
        "--model".into(),
        s(scene),
        "--poses".into(),
        s(poses),
    ];
    args.extend(extra.iter().map(|a| a.to_string()));
    agentstar(&args.iter().map(String::as_str).collect::<Vec<_>>())
}

fn bake_files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.contains(".bake"))
        .collect();
    v.sort();
    v
}

#[test]
fn a_bake_from_true_poses_gives_an_uncoloured_mug_its_print_and_score_uses_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, scene, poses) = uncoloured_mug(dir.path());
    // The true model, its badge a part of its own colour: the agreement to reach.
    let truth = score(&cap, &cap.join("model/scene.rhai"), &poses);
    let true_nccs: Vec<f64> = truth
        .appearance
        .iter()
        .filter_map(|a| a.model_ncc)
        .collect();
    let true_mean = true_nccs.iter().sum::<f64>() / true_nccs.len().max(1) as f64;
    // One colour: no model agreement to score.
    let before = score(&cap, &scene, &poses);
    assert!(
        before.appearance.iter().all(|a| a.model_ncc.is_none()),
        "{:?}",
        before.appearance
    );
    let o = bake(&cap, &scene, &poses, &["--json"]);
    let r: BakeReport = json_of(&o);
    assert!(r.disagreeing.is_empty(), "{:?}", r.frames);
    assert_eq!(r.frames.len(), 8);
    // The inside of the cup and its bottom are never in view.
    assert!(r.seen_fraction > 0.4, "{}", r.seen_fraction);
    let file = r.bake_file.expect("written");
    assert_eq!(file, scene.with_file_name("scene.bake.json"));
    assert!(r.atlas.expect("atlas").is_file());
    let stored = agentstar_data::bakefile::read_bake(&file).expect("bake file");
    assert_eq!(stored.frames.len(), 8);
    // Every command loading the model now has its print: the frames agree with it.
    let after = score(&cap, &scene, &poses);
    let nccs: Vec<f64> = after
        .appearance
        .iter()
        .filter_map(|a| a.model_ncc)
        .collect();
    assert_eq!(nccs.len(), 8, "{:?}", after.appearance);
    let mean = nccs.iter().sum::<f64>() / nccs.len() as f64;
    // The frames agree with the baked print at least as well as with the true model's
    // badge part: the share of their colours it explains beyond shading (2026-12-05: 0.18
    // baked, −0.02 true: the painted badge is not the model's badge part).
    assert!(
        mean > 0.1 && mean >= true_mean - 0.05,
        "model agreement {mean:.2} (true model {true_mean:.2}): {nccs:?}"
    );

    // The shape changes: the bake is stale, said so, and not used.
    let script = std::fs::read_to_string(&scene).expect("scene");
    std::fs::write(
        &scene,
        script.replace("cylinder(0.32, 0.8)", "cylinder(0.33, 0.8)"),
    )
    .expect("edit");
    let o = on_poses("score", &s(&cap), &s(&scene), &s(&poses), &["--json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("scene.bake.json is stale"),
        "no stale warning: {err}"
    );
    let stale: ScoreReport = serde_json::from_slice(&o.stdout).expect("score");
    assert!(stale.appearance.iter().all(|a| a.model_ncc.is_none()));
}

#[test]
fn a_frame_turned_into_its_twin_is_refused_by_name_and_nothing_is_written() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, scene, poses) = uncoloured_mug(dir.path());
    // Frame 000015's pose turned half way about the mug's axis (model z).
    let mut pf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&poses).expect("poses")).expect("json");
    let q = &mut pf["frames"]["000015.png"]["object_pose"]["quaternion"];
    let [w, x, y, z] = [0, 1, 2, 3].map(|i| q[i].as_f64().expect("q"));
    // q · (0, 0, 0, 1): a half-turn about the object's own z.
    *q = json!([-z, y, -x, w]);
    std::fs::write(&poses, pf.to_string()).expect("write poses");
    let o = bake(&cap, &scene, &poses, &[]);
    assert!(!o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    // That frame alone, although two others share most of their texels with it; the set
    // that agrees is every other frame.
    let (refusal, agreeing) = err
        .split_once("The largest set that agrees:")
        .expect("a set");
    assert!(
        refusal.contains("bake refused: frame(s) 000015.png (") && !refusal.contains("000030.png"),
        "{err}"
    );
    assert!(
        agreeing.contains("--frames 000000.png,000005.png,000010.png,000020.png,000025.png,000030.png,000035.png."),
        "{err}"
    );
    assert!(bake_files(&scene.with_file_name("")).is_empty());
    // Left out, the rest bake.
    let r: BakeReport = json_of(&bake(
        &cap,
        &scene,
        &poses,
        &["--frames", "000000..000010,000020..000035", "--json"],
    ));
    assert!(
        r.disagreeing.is_empty() && r.frames.len() == 7,
        "{:?}",
        r.frames
    );
}

#[test]
fn bad_inputs_are_named_and_leave_nothing_behind() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, scene, poses) = uncoloured_mug(dir.path());
    let run = scene.with_file_name("");
    let bake = |poses: &Path| bake(&cap, &scene, poses, &[]);
    let missing = run.join("nope.json");
    let o = bake(&missing);
    assert_failed_saying(&o, &["nope.json"]);
    // A pose that is not a number.
    let text_of_poses = std::fs::read_to_string(&poses).expect("poses");
    let nan = run.join("nan.json");
    let pf: serde_json::Value = serde_json::from_str(&text_of_poses).expect("json");
    let t = pf["frames"]["000005.png"]["object_pose"]["translation"][0]
        .as_f64()
        .expect("t");
    std::fs::write(&nan, text_of_poses.replacen(&t.to_string(), "NaN", 1)).expect("write");
    let o = bake(&nan);
    assert_failed_saying(&o, &["nan.json", "NaN"]);
    assert!(bake_files(&run).is_empty(), "{:?}", bake_files(&run));
}

#[test]
fn the_bake_tool_writes_beside_the_runs_model_and_refuses_a_model_outside_the_run() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, scene, _) = uncoloured_mug(dir.path());
    let run = dir.path().join("agent");
    init_run(&run, &cap, Some((&scene, "0.12")));
    // The true poses, committed.
    let o = agentstar(&[
        "pose",
        "commit",
        "--poses",
        &s(&run.join("pose.json")),
        "--report",
        &s(&cap.join("model/pose.json")),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let (mut c, _) = McpClient::initialised(&run);
    for (id, path, says) in [
        (2, "/etc/passwd", "outside the run"),
        (
            3,
            s(&cap.join("model/scene.rhai")).leak() as &str,
            "outside the run directory",
        ),
    ] {
        c.call(id, "bake", json!({"model": path}));
        let (r, _) = c.response(id);
        assert_eq!(r["result"]["isError"], true, "{r}");
        assert!(McpClient::text_of(&r).contains(says), "{r}");
    }
    assert!(bake_files(&cap.join("model")).is_empty());
    c.call(4, "bake", json!({}));
    let (r, _) = c.response(4);
    assert_ne!(r["result"]["isError"], true, "{r}");
    assert!(McpClient::text_of(&r).contains("wrote"), "{r}");
    assert!(run.join("scene.bake.json").is_file());
    let report: BakeReport =
        serde_json::from_value(r["result"]["structuredContent"].clone()).expect("report");
    assert!(report.pose_version.is_some(), "{report:?}");
}
