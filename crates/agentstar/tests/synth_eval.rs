//! Synthetic captures, the paper's metrics, the demo and the benchmark's tolerances.

mod support;

use agentstar_reports::{EvalReport, ScoreReport, TrackReport};
use support::{
    agentstar, eval_of, example, json_of, on_poses, score_of, synth_object, text, track_known,
};

#[test]
fn eval_scores_ground_truth_as_zero_and_tracking_as_small() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let truth: EvalReport = eval_of(&cap, &model, &poses, 3000);
    for (k, v) in [
        ("epe_cm", truth.metrics.epe_cm),
        ("rotation_mean_deg", truth.metrics.rotation_mean_deg),
        ("translation_mean_cm", truth.metrics.translation_mean_cm),
    ] {
        assert!(v.expect(k) < 1e-3, "{k}: {v:?}");
    }
    // Independent samples of the same surfaces: the sampling floor only.
    assert!(truth.metrics.chamfer_cm.expect("cd") < 1.0, "{truth:?}");
    assert_eq!(truth.metrics.joints[0].matched_by, "child part name");
    let tracked = dir.path().join("tracked.json");
    let _: TrackReport = track_known(&cap, &model, &poses, &tracked);
    let tracked = tracked.display().to_string();
    let v: EvalReport = eval_of(&cap, &model, &tracked, 3000);
    assert!(
        v.metrics.epe_cm.expect("epe") < 1.0 && v.metrics.rotation_mean_deg.expect("rot") < 2.0,
        "{v:?}"
    );
    // A missing ground truth is named.
    let o = on_poses(
        "eval",
        &cap,
        &model,
        &tracked,
        &["--gt", "/nonexistent/gt.json"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("/nonexistent/gt.json"), "{}", text(&o));
}

#[test]
fn synth_writes_a_valid_capture_whose_truth_scores_perfectly() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("cab");
    let v: serde_json::Value = json_of(&synth_object(
        out.to_str().expect("utf8"),
        "cabinet",
        &[
            "--frames", "4", "--size", "160x120", "--seed", "5", "--json",
        ],
    ));
    assert_eq!(v["motion"], "static-orbit");
    let cap = out.display().to_string();
    let o = agentstar(&["validate", &cap, "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    // The capture says what made it, not what is in it: the object and its scale are the
    // truth's (`gt.json`, `model/`), out of an agent's sight.
    let manifest = std::fs::read_to_string(out.join("capture.json")).expect("capture.json");
    assert!(
        manifest.contains("agentstar synth")
            && !manifest.contains("cabinet")
            && !manifest.contains("scale_m"),
        "{manifest}"
    );
    assert!(
        out.join("depth/000000.npz").is_file(),
        "the orbit has depth"
    );
    let model = out.join("model/scene.rhai").display().to_string();
    let poses = out.join("model/pose.json").display().to_string();
    let v: ScoreReport = score_of(&cap, &model, &poses, None);
    assert_eq!(v.sequence.min_iou_visible, 1.0, "{v:?}");
    let v: EvalReport = eval_of(&cap, &model, &poses, 2000);
    assert!(v.metrics.epe_cm.expect("epe") < 1e-3, "{v:?}");
    assert_eq!(v.metrics.joints.len(), 2);
    // Two runs in a batch give the paper's tables, one row per sequence.
    let batch = dir.path().join("runs.json");
    std::fs::write(
        &batch,
        serde_json::json!([
            {"capture": "cab", "model": "cab/model/scene.rhai", "poses": "cab/model/pose.json", "label": "truth"},
            {"capture": "cab", "model": "cab/model/scene.rhai", "poses": "cab/model/pose.json", "label": "again", "family": "itaco"}
        ])
        .to_string(),
    )
    .expect("write");
    let o = agentstar(&[
        "eval",
        "--batch",
        batch.to_str().expect("utf8"),
        "--per-sequence",
        "--samples",
        "2000",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let t = String::from_utf8_lossy(&o.stdout);
    assert!(
        t.contains("iTACO-like") && t.contains("| truth |") && t.contains("| again |"),
        "{t}"
    );
    // `--batch --json` prints each run as `eval --json` does (one function writes both).
    let o = agentstar(&[
        "eval",
        "--batch",
        batch.to_str().expect("utf8"),
        "--samples",
        "2000",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let b: agentstar_reports::EvalBatchReport =
        serde_json::from_slice(&o.stdout).expect("batch report");
    let mut single = v.clone();
    assert_eq!(b.results.len(), 2);
    assert_eq!(b.results[1].family, "itaco");
    single.label = "truth".into();
    let first = &b.results[0];
    assert_eq!(
        (
            first.metrics.epe_cm,
            first.metrics.chamfer_cm,
            first.metrics.joints.clone(),
            &first.label
        ),
        (
            single.metrics.epe_cm,
            single.metrics.chamfer_cm,
            single.metrics.joints.clone(),
            &single.label
        )
    );
    // The destination is not overwritten, and a bad object is named with the library.
    let o = synth_object(&cap, "cabinet", &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("not empty"), "{}", text(&o));
    let o = synth_object(dir.path().join("x").to_str().expect("utf8"), "teapot", &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("teapot") && text(&o).contains("laptop"),
        "{}",
        text(&o)
    );
    assert!(!dir.path().join("x").exists(), "nothing written");
    let o = agentstar(&["synth", "--list"]);
    assert!(
        o.status.success() && text(&o).contains("microwave"),
        "{}",
        text(&o)
    );
}

#[test]
fn demo_tracks_and_evaluates_the_built_in_capture() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("demo");
    let v: serde_json::Value =
        json_of(&agentstar(&["demo", out.to_str().expect("utf8"), "--json"]));
    assert!(v["result"]["epe_cm"].as_f64().expect("epe") < 1.0, "{v}");
    assert!(v["result"]["iou_mean"].as_f64().expect("iou") > 0.97, "{v}");
    assert!(out.join("run/pose.json").is_file() && out.join("capture/gt.json").is_file());
    // A second run replaces its own output; a foreign directory is refused.
    let o = agentstar(&["demo", out.to_str().expect("utf8"), "--frames", "3"]);
    assert!(o.status.success(), "{}", text(&o));
    let foreign = dir.path().join("foreign");
    std::fs::create_dir_all(&foreign).expect("mkdir");
    std::fs::write(foreign.join("keep.txt"), "mine").expect("write");
    let o = agentstar(&["demo", foreign.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(foreign.join("keep.txt").is_file());
}

#[test]
fn bench_checks_tolerances_and_fails_on_regression() {
    let dir = tempfile::tempdir().expect("tmp");
    let tol = dir.path().join("tol.json");
    let tol_s = tol.to_str().expect("utf8");
    let bench = |verb: &str| {
        agentstar(&[
            "bench",
            "--suite",
            "quick",
            "--only",
            "microwave",
            "--methods",
            "tracker",
            verb,
            tol_s,
            "--evals",
            "600",
        ])
    };
    let o = bench("--record");
    assert!(o.status.success(), "{}", text(&o));
    let t = String::from_utf8_lossy(&o.stdout);
    assert!(
        t.contains("iTACO-like") && t.contains("microwave-static-orbit-s3"),
        "{t}"
    );
    let o = bench("--check");
    assert!(o.status.success(), "{}", text(&o));
    // Tighten a bound below what the tracker reaches: the check fails and says which.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&tol).expect("read")).expect("json");
    v["entries"][0]["max"]["epe_cm"] = serde_json::json!(0.0);
    std::fs::write(&tol, v.to_string()).expect("write");
    let o = bench("--check");
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("epe_cm"), "{}", text(&o));
    let o = agentstar(&["bench", "--suite", "nightly"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("quick, full"), "{}", text(&o));
}
