//! The `agentstar` command end to end: the built-in example, every subcommand on it, and bad
//! input giving a clear message and a non-zero exit without writing half a file.

use std::path::Path;
use std::process::{Command, Output};

fn agentstar(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_agentstar"))
        .args(args)
        .output()
        .expect("run agentstar")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn example(dir: &Path) -> (String, String, String) {
    let o = agentstar(&["example", dir.to_str().expect("utf8"), "--frames", "6"]);
    assert!(o.status.success(), "{}", text(&o));
    let cap = dir.join("capture").display().to_string();
    let model = dir.join("run/scene.rhai").display().to_string();
    let poses = dir.join("run/pose.json").display().to_string();
    (cap, model, poses)
}

#[test]
fn example_and_every_subcommand_on_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let o = agentstar(&["validate", &cap, "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["valid"], true);
    assert_eq!(v["frames"], 6);

    let o = agentstar(&[
        "score",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["sequence"]["min_iou_visible"], 1.0);
    assert_eq!(v["frames"].as_array().expect("frames").len(), 6);

    let out = dir.path().join("views");
    let o = agentstar(&[
        "render",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--frames",
        "000000..000010",
        "--views",
        "overlay,compare,ids,shaded,depth",
        "--out",
        out.to_str().expect("utf8"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    for f in [
        "overlay_000005.png",
        "compare_000010.png",
        "ids_000000.png",
        "shaded_000005.png",
        "depth_000010.npy",
        "sheet_overlay.png",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    assert!(
        !out.join("overlay_000015.png").exists(),
        "frame selection ignored"
    );

    let tt = dir.path().join("tt");
    let o = agentstar(&[
        "turntable",
        "--model",
        &model,
        "--capture",
        &cap,
        "--poses",
        &poses,
        "--out",
        tt.to_str().expect("utf8"),
        "--size",
        "96",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    // Every frame of the example has its own lid angle: one turntable per state.
    assert_eq!(v["states"].as_array().expect("states").len(), 6);
    assert!(tt.join("turntable_000000_az000_el+20.png").is_file());

    let glb = dir.path().join("object.glb");
    let o = agentstar(&[
        "export",
        "--model",
        &model,
        "--glb",
        glb.to_str().expect("utf8"),
        "--urdf",
        dir.path().join("urdf").to_str().expect("utf8"),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = agentstar(&["check", glb.to_str().expect("utf8"), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["parts"].as_array().expect("parts").len(), 2);
    let o = agentstar(&[
        "check",
        dir.path().join("urdf/object.urdf").to_str().expect("utf8"),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("joint hinge"), "{}", text(&o));
}

#[test]
fn bad_input_fails_clearly() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());

    // A broken capture: every problem listed, exit 1.
    std::fs::remove_file(dir.path().join("capture/mask_object/000005.png")).expect("rm");
    let o = agentstar(&["validate", &cap]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o).contains("missing object mask for frame `000005.png`"),
        "{}",
        text(&o)
    );
    let o = agentstar(&[
        "score",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("problem"), "{}", text(&o));
    std::fs::copy(
        dir.path().join("capture/mask_object/000000.png"),
        dir.path().join("capture/mask_object/000005.png"),
    )
    .expect("restore");

    // A broken scene script: position, suggestion, exit 2.
    let bad_scene = dir.path().join("run/bad.rhai");
    std::fs::write(&bad_scene, "part(\"a\", cilinder(0.5, 1));").expect("w");
    let o = agentstar(&["check", bad_scene.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("did you mean `cylinder`") && text(&o).contains("1:11"),
        "{}",
        text(&o)
    );

    // A NaN pose.
    let bad_pose = dir.path().join("run/bad_pose.json");
    let p = std::fs::read_to_string(&poses).expect("r").replacen(
        "\"translation\": [",
        "\"translation\": [NaN, ",
        1,
    );
    std::fs::write(&bad_pose, p).expect("w");
    let o = agentstar(&[
        "score",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        bad_pose.to_str().expect("utf8"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("bad_pose.json"), "{}", text(&o));

    // Unknown frames and views are named with what is valid.
    let o = agentstar(&[
        "render",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--frames",
        "999999",
        "--out",
        dir.path().join("v").to_str().expect("utf8"),
    ]);
    assert!(text(&o).contains("unknown frame `999999`"), "{}", text(&o));
    let o = agentstar(&[
        "render",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--views",
        "xray",
        "--out",
        dir.path().join("v").to_str().expect("utf8"),
    ]);
    assert!(
        text(&o).contains("unknown view `xray`; views are overlay"),
        "{}",
        text(&o)
    );

    // A failing export leaves no partial file behind.
    let o = agentstar(&[
        "export",
        "--model",
        bad_scene.to_str().expect("utf8"),
        "--glb",
        dir.path().join("x.glb").to_str().expect("utf8"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!dir.path().join("x.glb").exists());
}

#[test]
fn pose_verbs_track_commit_and_diagnose() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let tracked = dir.path().join("tracked.json");
    let o = agentstar(&[
        "track",
        &cap,
        "--model",
        &model,
        "--scale-from",
        &poses,
        "--out",
        tracked.to_str().expect("utf8"),
        "--evals",
        "1200",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert!(
        v["sequence"]["min_iou_visible"].as_f64().expect("min") >= 0.98,
        "{}",
        v["sequence"]
    );
    let tracked = tracked.to_str().expect("utf8").to_string();
    let common = |verb: &str, out: &str| -> Vec<String> {
        vec![
            verb.into(),
            "--capture".into(),
            cap.clone(),
            "--model".into(),
            model.clone(),
            "--poses".into(),
            tracked.clone(),
            "--out".into(),
            dir.path().join(out).display().to_string(),
        ]
    };

    // A flip panel: every frame ranks identity first, every candidate is on the sheet.
    let mut args = common("oapply", "oapply");
    args.extend(["--frames".into(), "000000,000005".into(), "--json".into()]);
    let o = agentstar(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    for f in v["frames"].as_array().expect("frames") {
        assert_eq!(f["ranked"].as_array().expect("ranked").len(), 4);
        assert_eq!(f["ranked"][0]["label"], "identity");
    }

    // Apply a bad order, commit it, see it in the history, restore the original.
    let mut args = common("apply", "apply");
    args.extend([
        "--frame".into(),
        "000005".into(),
        "--order".into(),
        "yaw:25;hinge:5".into(),
    ]);
    let o = agentstar(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("BEST — paste into pose.json frames[\"000005.png\"]"),
        "{}",
        text(&o)
    );
    let report = dir.path().join("apply/apply.json").display().to_string();
    let o = agentstar(&["pose", "commit", "--poses", &tracked, "--report", &report]);
    assert!(o.status.success(), "{}", text(&o));
    let o = agentstar(&[
        "score",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &tracked,
        "--frames",
        "000005",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert!(v["frames"][0]["iou_visible"].as_f64().expect("iou") < 0.95);
    let o = agentstar(&["pose", "history", "--poses", &tracked, "--json"]);
    let h: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(h.as_array().expect("versions").len(), 2);
    let o = agentstar(&["pose", "restore", "--poses", &tracked, "--version", "0"]);
    assert!(o.status.success(), "{}", text(&o));
    let o = agentstar(&[
        "score",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &tracked,
        "--frames",
        "000005",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert!(v["frames"][0]["iou_visible"].as_f64().expect("iou") >= 0.98);

    // A sweep with a bad range spec shows the grammar; a good one writes its three outputs.
    let mut args = common("sweep", "sweep");
    args.extend(["--ranges".into(), "yaw:-10".into()]);
    let o = agentstar(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("dof:lower,upper[,steps]"), "{}", text(&o));
    let mut args = common("sweep", "sweep");
    args.extend([
        "--ranges".into(),
        "yaw:-10,10,5;hinge:0,60,5".into(),
        "--strategy".into(),
        "grid".into(),
    ]);
    let o = agentstar(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", text(&o));
    for f in [
        "sweep.json",
        "sweep.txt",
        "sweep_sheet_000000.png",
        "sweep_heatmap_000000.png",
    ] {
        assert!(dir.path().join("sweep").join(f).is_file(), "missing {f}");
    }

    // Temporal diagnostics and pose differences.
    let o = agentstar(&[
        "temporal",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &tracked,
        "--json",
        "--plot",
        dir.path().join("t.png").to_str().expect("utf8"),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["frames"].as_array().expect("rows").len(), 6);
    assert!(dir.path().join("t.png").is_file());
    let o = agentstar(&[
        "pose-diff",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &tracked,
        "--a",
        "000000",
        "--b",
        "000005",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert!(
        v["rotation_deg"].as_f64().expect("rot") > 1.0
            && v["joints"]["hinge"].as_f64().expect("joint") > 5.0
    );
}

#[test]
fn sweep_scores_explicit_candidates_exactly() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let out = dir.path().join("c").display().to_string();
    let o = agentstar(&[
        "sweep",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--frames",
        "000005",
        "--candidates",
        "yaw:12|hinge:0|roll:0",
        "--out",
        &out,
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let ranked = v["frames"][0]["ranked"].as_array().expect("ranked");
    assert_eq!(ranked.len(), 3);
    // The example's poses are exact, so the zero increment ranks first with IoU 1.
    assert_eq!(ranked[0]["label"], "roll:0");
    assert_eq!(ranked[0]["iou_visible"], 1.0);
    let o = agentstar(&[
        "sweep",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--candidates",
        "rz:90",
        "--out",
        &out,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("use osweep/oapply"), "{}", text(&o));
}

#[test]
fn eval_scores_ground_truth_as_zero_and_tracking_as_small() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let o = agentstar(&[
        "eval",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--samples",
        "3000",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    for k in ["epe_cm", "rotation_mean_deg", "translation_mean_cm"] {
        assert!(v[k].as_f64().expect(k) < 1e-3, "{k}: {}", v[k]);
    }
    // Independent samples of the same surfaces: the sampling floor only.
    assert!(
        v["chamfer_cm"].as_f64().expect("cd") < 1.0,
        "{}",
        v["chamfer_cm"]
    );
    assert_eq!(v["joints"][0]["matched_by"], "child part name");
    let tracked = dir.path().join("tracked.json").display().to_string();
    let o = agentstar(&[
        "track",
        &cap,
        "--model",
        &model,
        "--scale-from",
        &poses,
        "--out",
        &tracked,
        "--evals",
        "1200",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = agentstar(&[
        "eval",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &tracked,
        "--samples",
        "3000",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert!(
        v["epe_cm"].as_f64().expect("epe") < 1.0
            && v["rotation_mean_deg"].as_f64().expect("rot") < 2.0,
        "{v}"
    );
    // A missing ground truth is named.
    let o = agentstar(&[
        "eval",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &tracked,
        "--gt",
        "/nonexistent/gt.json",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("/nonexistent/gt.json"), "{}", text(&o));
}

#[test]
fn synth_writes_a_valid_capture_whose_truth_scores_perfectly() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("cab");
    let o = agentstar(&[
        "synth",
        out.to_str().expect("utf8"),
        "--object",
        "cabinet",
        "--frames",
        "4",
        "--size",
        "160x120",
        "--seed",
        "5",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["motion"], "static-orbit");
    let cap = out.display().to_string();
    let o = agentstar(&["validate", &cap, "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        out.join("depth/000000.npz").is_file(),
        "the orbit has depth"
    );
    let model = out.join("model/scene.rhai").display().to_string();
    let poses = out.join("model/pose.json").display().to_string();
    let o = agentstar(&[
        "score",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["sequence"]["min_iou_visible"], 1.0, "{v}");
    let o = agentstar(&[
        "eval",
        "--capture",
        &cap,
        "--model",
        &model,
        "--poses",
        &poses,
        "--samples",
        "2000",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert!(v["epe_cm"].as_f64().expect("epe") < 1e-3, "{v}");
    assert_eq!(v["joints"].as_array().expect("joints").len(), 2);
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
    // The destination is not overwritten, and a bad object is named with the library.
    let o = agentstar(&["synth", &cap, "--object", "cabinet"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("not empty"), "{}", text(&o));
    let o = agentstar(&[
        "synth",
        dir.path().join("x").to_str().expect("utf8"),
        "--object",
        "teapot",
    ]);
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
    let o = agentstar(&["demo", out.to_str().expect("utf8"), "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
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

#[test]
fn motion_exports_are_valid_gltf_and_posed_meshes() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let glb = dir.path().join("tracked.glb");
    let rest = dir.path().join("rest.glb");
    let posed = dir.path().join("posed");
    let o = agentstar(&[
        "export",
        "--model",
        &model,
        "--glb",
        rest.to_str().expect("utf8"),
        "--capture",
        &cap,
        "--poses",
        &poses,
        "--animated-glb",
        glb.to_str().expect("utf8"),
        "--posed-meshes",
        posed.to_str().expect("utf8"),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(std::fs::read_dir(&posed).expect("posed").count(), 6);
    // The animation reads back to the poses it was made from.
    let read =
        agentstar_data::animation::read_animated_glb(&std::fs::read(&glb).expect("glb"), &glb)
            .expect("read");
    assert_eq!(read.frames.len(), 6);
    assert!(read.joint_states["hinge"]
        .iter()
        .all(|v| (0.0..=120.0).contains(v)));
    // The Khronos validator, where npm could install it (`.ci/run` does).
    let scripts = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts");
    if !scripts.join("node_modules/gltf-validator").is_dir() {
        eprintln!(
            "gltf-validator not installed (cd scripts && npm install): validator check skipped"
        );
        return;
    }
    let o = Command::new("node")
        .arg(scripts.join("validate_gltf.js"))
        .args([&glb, &rest])
        .output()
        .expect("node");
    assert!(o.status.success(), "{}", text(&o));
    let report = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        report.matches("\"errors\":0,\"warnings\":0").count(),
        2,
        "{report}"
    );
}

#[test]
fn point_tracks_land_in_the_masks_and_bop_results_carry_the_poses() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let json_path = dir.path().join("tracks.json");
    let npz_path = dir.path().join("tracks.npz");
    let bop = dir.path().join("bop.csv");
    for (flag, path) in [
        ("--tracks", &json_path),
        ("--tracks", &npz_path),
        ("--bop", &bop),
    ] {
        let o = agentstar(&[
            "export",
            "--model",
            &model,
            "--capture",
            &cap,
            "--poses",
            &poses,
            flag,
            path.to_str().expect("utf8"),
            "--stride",
            "6",
        ]);
        assert!(o.status.success(), "{}", text(&o));
    }
    // The example's poses are its ground truth: every visible tracked point projects into
    // that frame's object mask.
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).expect("read")).expect("json");
    let capture = agentstar_data::capture::Capture::open(Path::new(&cap)).expect("capture");
    let n = t["queries_px"].as_array().expect("queries").len();
    assert!(n > 100, "{n} queries");
    let mut checked = 0;
    for (f, frame) in capture.frames.iter().enumerate() {
        let mask = capture.load_mask(f).expect("mask");
        let hand = capture.load_hand(f).expect("hand");
        for q in 0..n {
            if !t["visible"][f][q].as_bool().expect("bool") {
                continue;
            }
            let p = &t["tracks"][f][q];
            let xyz = agentstar_geom::Point3::new(
                p[0].as_f64().expect("x"),
                p[1].as_f64().expect("y"),
                p[2].as_f64().expect("z"),
            );
            let (u, v) = frame.camera.project(&xyz).expect("in front");
            let (x, y) = (u as u32, v as u32);
            if hand.as_ref().is_some_and(|h| h.get(x, y)) {
                continue;
            }
            assert!(
                mask.get(x, y),
                "{} point {q} at ({u:.1}, {v:.1})",
                frame.name
            );
            checked += 1;
        }
    }
    assert!(checked > 500, "{checked}");
    let arrays = agentstar_data::npz::read_arrays(&npz_path, &["tracks", "visible", "queries"])
        .expect("npz");
    assert_eq!(arrays[0].1.shape, vec![6, n, 3]);
    assert_eq!(arrays[1].1.shape, vec![6, n]);
    // BOP: one row per frame, translation in millimetres.
    let csv = std::fs::read_to_string(&bop).expect("csv");
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "scene_id,im_id,obj_id,score,R,t,time");
    assert_eq!(rows.len(), 7);
    let pf = agentstar_data::posefile::PoseFile::read(Path::new(&poses)).expect("poses");
    let first = &pf.frames[&capture.frames[0].name];
    let t0 = first.object_pose.as_ref().expect("pose").translation;
    let cols: Vec<&str> = rows[1].split(',').collect();
    let t_mm: Vec<f64> = cols[5]
        .split(' ')
        .map(|v| v.parse().expect("f64"))
        .collect();
    for k in 0..3 {
        assert!(
            (t_mm[k] - 1000.0 * t0[k]).abs() < 1e-3,
            "{t_mm:?} vs {t0:?}"
        );
    }
}

#[test]
fn completions_cover_every_subcommand() {
    let o = agentstar(&["completions", "bash"]);
    assert!(o.status.success(), "{}", text(&o));
    let script = String::from_utf8_lossy(&o.stdout);
    for sub in [
        "demo", "synth", "bench", "eval", "track", "export", "from-bop",
    ] {
        assert!(script.contains(sub), "bash completion lacks {sub}");
    }
    let o = agentstar(&["completions", "tcsh"]);
    assert_eq!(o.status.code(), Some(2));
}

/// A headless Chromium, where one is installed (`.ci/run` installs Debian's `chromium` and
/// sets `AGENTSTAR_REQUIRE_CHROMIUM=1`, which turns its absence into a failure).
fn chromium() -> Option<String> {
    let found = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            std::process::Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .map(str::to_string);
    if found.is_none() {
        assert!(
            std::env::var_os("AGENTSTAR_REQUIRE_CHROMIUM").is_none(),
            "AGENTSTAR_REQUIRE_CHROMIUM is set but no chromium is installed"
        );
        eprintln!("chromium not installed (apt install chromium): the browser check is skipped");
    }
    found
}

/// Runs headless Chromium on a page with a time limit; returns stdout (through a file: the
/// DOM dump is larger than a pipe holds).
fn run_chromium(bin: &str, extra: &[&str], page: &Path) -> String {
    let stdout_path = page.with_extension("stdout");
    let stdout = std::fs::File::create(&stdout_path).expect("stdout file");
    let mut child = std::process::Command::new(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-extensions",
            "--no-first-run",
            "--virtual-time-budget=15000",
            "--window-size=1300,1400",
        ])
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .stdout(stdout)
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start chromium");
    let start = std::time::Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed().as_secs() > 120 {
            let _ = child.kill();
            panic!("chromium did not finish in 120 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    String::from_utf8_lossy(&std::fs::read(&stdout_path).expect("stdout")).into_owned()
}

fn body_attr(dom: &str, name: &str) -> Option<String> {
    let body = &dom[dom.find("<body")?..];
    let body = &body[..body.find('>')?];
    let key = format!("{name}=\"");
    let at = body.find(&key)? + key.len();
    Some(body[at..at + body[at..].find('"')?].to_string())
}

#[test]
fn the_demo_report_is_self_contained_and_renders_in_headless_chromium() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("demo");
    let o = agentstar(&["demo", out.to_str().expect("utf8"), "--frames", "4"]);
    assert!(o.status.success(), "{}", text(&o));
    let run = out.join("run");
    let page = run.join("report.html");
    let html = std::fs::read_to_string(&page).expect("report");
    // Offline: no external scripts, styles or images.
    for external in ["src=\"http", "href=\"http", "<link", "@import", "url(http"] {
        assert!(!html.contains(external), "the report references {external}");
    }
    assert_eq!(html.matches("<figure id=\"frame-").count(), 4);
    assert!(html.contains("Agent steps") && html.contains("evaluated against the ground truth"));
    assert!(html.contains("data:image/jpeg;base64,"));
    // The report command itself, with a ledger whose last line a crash cut short.
    let ledger = run.join("ledger.jsonl");
    let mut l = std::fs::read_to_string(&ledger).expect("ledger");
    l.push_str("{\"step\": 99, \"ti");
    std::fs::write(&ledger, l).expect("write");
    let page2 = dir.path().join("again.html");
    let o = agentstar(&[
        "report",
        run.to_str().expect("utf8"),
        "--out",
        page2.to_str().expect("utf8"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["frames"], 4);
    assert!(
        v["ground_truth"]
            .as_str()
            .is_some_and(|g| g.ends_with("gt.json")),
        "{v}"
    );
    let html2 = std::fs::read_to_string(&page2).expect("report");
    assert!(
        html2.contains("line") && html2.contains("skipped"),
        "the cut line is not noted"
    );
    // A directory without run.json needs --capture.
    let bare = dir.path().join("bare");
    std::fs::create_dir_all(&bare).expect("mkdir");
    let o = agentstar(&["report", bare.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("--capture"), "{}", text(&o));
    // In a browser: the viewer starts, both views show the model, no script errors.
    let Some(bin) = chromium() else { return };
    let dom = run_chromium(&bin, &["--dump-dom"], &page);
    assert_eq!(
        body_attr(&dom, "data-viewer").as_deref(),
        Some("ready"),
        "{:?}",
        body_attr(&dom, "data-error-text")
    );
    assert_eq!(
        body_attr(&dom, "data-errors").as_deref(),
        Some("0"),
        "{:?}",
        body_attr(&dom, "data-error-text")
    );
    for view in ["data-cam-pixels", "data-orbit-pixels"] {
        let px: u64 = body_attr(&dom, view)
            .and_then(|v| v.parse().ok())
            .expect(view);
        assert!(px > 200, "{view} = {px}: the 3-D view is empty");
    }
    let shot = dir.path().join("shot.png");
    let arg = format!("--screenshot={}", shot.display());
    run_chromium(&bin, &[&arg], &page);
    let img = image::open(&shot).expect("screenshot").to_rgb8();
    assert_eq!(img.dimensions(), (1300, 1400));
    let mut colours = std::collections::BTreeSet::new();
    for p in img.pixels().step_by(7) {
        colours.insert(p.0);
    }
    assert!(
        colours.len() > 200,
        "the screenshot is nearly blank ({} colours)",
        colours.len()
    );
}

/// The README's walk-through, with a frame folder in place of the video (the video path has
/// its own test): a segmenter's masks, a static camera, a model, tracking, the report.
#[test]
fn the_readme_walk_through_goes_from_frames_and_masks_to_a_report() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    // A phone-like clip: frames, plus masks as a segmenter writes them (other names).
    synth_box(&p("clip"), 10, false);
    let clip = agentstar_data::capture::Capture::open(&p("clip")).expect("clip");
    for (sub, suffix) in [
        ("frames", ""),
        ("mask_object", "_mask"),
        ("mask_hand", "_hand"),
    ] {
        let to = p(&format!("seg_{sub}"));
        std::fs::create_dir_all(&to).expect("mkdir");
        for f in &clip.frames {
            let from = p("clip").join(sub).join(format!("{}.png", f.stem));
            if from.is_file() {
                std::fs::copy(&from, to.join(format!("img{}{suffix}.png", f.number)))
                    .expect("copy");
            }
        }
    }
    let c = &clip.frames[0].camera;
    let k = format!("{},{},{},{}", c.fx, c.fy, c.cx, c.cy);
    // 1. The capture.
    let o = agentstar(&[
        "capture",
        "from-video",
        &s(&p("seg_frames")),
        "--masks",
        &s(&p("seg_mask_object")),
        "--hands",
        &s(&p("seg_mask_hand")),
        "--intrinsics",
        &k,
        "--out",
        &s(&p("cap")),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(agentstar(&["validate", &s(&p("cap"))]).status.success());
    // 2. A model (here the known one) in the run directory.
    std::fs::create_dir_all(p("run")).expect("mkdir");
    std::fs::copy(p("clip/model/scene.rhai"), p("run/scene.rhai")).expect("copy");
    assert!(agentstar(&["check", &s(&p("run/scene.rhai"))])
        .status
        .success());
    // 3. Tracking.
    let o = agentstar(&[
        "track",
        &s(&p("cap")),
        "--model",
        &s(&p("run/scene.rhai")),
        "--scale-from",
        &s(&p("clip/model/pose.json")),
        "--out",
        &s(&p("run/pose.json")),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    // 4. The report.
    let o = agentstar(&[
        "report",
        &s(&p("run")),
        "--capture",
        &s(&p("cap")),
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(p("run/report.html")).expect("report");
    assert_eq!(html.matches("<figure id=\"frame-").count(), 10);
    let mean: f64 = html
        .split("IoU visible</td><td>mean ")
        .nth(1)
        .and_then(|r| r.split(',').next())
        .and_then(|v| v.parse().ok())
        .expect("mean IoU in the summary");
    assert!(mean > 0.95, "tracked mean IoU {mean}");
    // 5. The motion for a simulator.
    let o = agentstar(&[
        "export",
        "--model",
        &s(&p("run/scene.rhai")),
        "--capture",
        &s(&p("cap")),
        "--poses",
        &s(&p("run/pose.json")),
        "--animated-glb",
        &s(&p("run/motion.glb")),
    ]);
    assert!(o.status.success(), "{}", text(&o));
}

/// `ffmpeg`, where installed (`.ci/run` installs it and sets `AGENTSTAR_REQUIRE_FFMPEG=1`,
/// which turns its absence into a failure).
fn ffmpeg() -> bool {
    let found = std::process::Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            std::env::var_os("AGENTSTAR_REQUIRE_FFMPEG").is_none(),
            "AGENTSTAR_REQUIRE_FFMPEG is set but ffmpeg is not installed"
        );
        eprintln!("ffmpeg not installed (apt install ffmpeg): the video check is skipped");
    }
    found
}

#[test]
fn a_video_file_imports_through_ffmpeg_frame_for_frame() {
    if !ffmpeg() {
        return;
    }
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    let o = agentstar(&[
        "synth",
        &s(&p("clip")),
        "--object",
        "mug",
        "--frames",
        "4",
        "--size",
        "160x120",
        "--seed",
        "2",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let clip = agentstar_data::capture::Capture::open(&p("clip")).expect("clip");
    // The frames as a lossless video; the masks as a segmenter names them (by order).
    std::fs::create_dir_all(p("seq")).expect("mkdir");
    std::fs::create_dir_all(p("masks")).expect("mkdir");
    for k in 0..clip.frames.len() {
        std::fs::copy(clip.frame_path(k), p("seq").join(format!("f{k}.png"))).expect("copy");
        std::fs::copy(
            clip.mask_path(k),
            p("masks").join(format!("sam_out_{}.png", 10 + k)),
        )
        .expect("copy");
    }
    let ff = std::process::Command::new("ffmpeg")
        .args(["-v", "error", "-nostdin", "-framerate", "5", "-i"])
        .arg(p("seq").join("f%d.png"))
        .args(["-c:v", "ffv1"])
        .arg(p("clip.mkv"))
        .output()
        .expect("ffmpeg");
    assert!(
        ff.status.success(),
        "{}",
        String::from_utf8_lossy(&ff.stderr)
    );
    let o = agentstar(&[
        "capture",
        "from-video",
        &s(&p("clip.mkv")),
        "--masks",
        &s(&p("masks")),
        "--fov",
        "60",
        "--fps",
        "5",
        "--out",
        &s(&p("cap")),
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["frames"], 4);
    let cap = agentstar_data::capture::Capture::open(&p("cap")).expect("cap");
    for k in 0..4 {
        // Lossless: every pixel of every frame and mask comes back.
        assert_eq!(
            cap.load_frame(k).expect("frame").as_raw(),
            clip.load_frame(k).expect("frame").as_raw(),
            "frame {k}"
        );
        assert_eq!(
            cap.load_mask(k).expect("mask"),
            clip.load_mask(k).expect("mask")
        );
        assert!((cap.frames[k].time_s.expect("time") - k as f64 / 5.0).abs() < 1e-9);
    }
    // Every 2nd frame, masks named after the extracted frames.
    std::fs::create_dir_all(p("masks2")).expect("mkdir");
    for k in [0usize, 2] {
        std::fs::copy(clip.mask_path(k), p("masks2").join(format!("{k:06}.png"))).expect("copy");
    }
    let o = agentstar(&[
        "capture",
        "from-video",
        &s(&p("clip.mkv")),
        "--masks",
        &s(&p("masks2")),
        "--fov",
        "60",
        "--every",
        "2",
        "--out",
        &s(&p("cap2")),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let cap2 = agentstar_data::capture::Capture::open(&p("cap2")).expect("cap2");
    assert_eq!(cap2.frames.len(), 2);
    assert_eq!(
        cap2.load_mask(1).expect("mask"),
        clip.load_mask(2).expect("mask")
    );
    // A file that is not a video is named, and nothing is written.
    std::fs::write(p("bad.mp4"), b"not a video").expect("write");
    let o = agentstar(&[
        "capture",
        "from-video",
        &s(&p("bad.mp4")),
        "--masks",
        &s(&p("masks")),
        "--fov",
        "60",
        "--out",
        &s(&p("cap3")),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("bad.mp4") && text(&o).contains("ffmpeg"),
        "{}",
        text(&o)
    );
    assert!(!p("cap3").exists());
}

/// What the mock model server does with one request.
enum Act {
    /// Answer with this status and JSON body.
    Json(u16, serde_json::Value),
    /// Wait this many milliseconds first (past the client's timeout), then answer.
    Slow(u64, serde_json::Value),
}

/// A model server on loopback that replays scripted answers in order and keeps every
/// request body (OpenAI chat-completions paths).
struct MockModel {
    url: String,
    requests: std::sync::Arc<std::sync::Mutex<Vec<serde_json::Value>>>,
}

fn mock_model(script: Vec<Act>) -> MockModel {
    use std::io::{BufRead, BufReader, Read, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let url = format!("http://{}/v1", listener.local_addr().expect("addr"));
    let requests = std::sync::Arc::new(std::sync::Mutex::new(vec![]));
    let script = std::sync::Arc::new(std::sync::Mutex::new(std::collections::VecDeque::from(
        script,
    )));
    let reqs = requests.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            let reqs = reqs.clone();
            let script = script.clone();
            std::thread::spawn(move || {
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
                let (status, answer) = match act {
                    Some(Act::Json(s, v)) => (s, v),
                    Some(Act::Slow(ms, v)) => {
                        std::thread::sleep(std::time::Duration::from_millis(ms));
                        (200, v)
                    }
                    None => (500, serde_json::json!({"error": "the script is exhausted"})),
                };
                let text = answer.to_string();
                let _ = write!(
                    stream,
                    "HTTP/1.1 {status} X\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{text}",
                    text.len()
                );
            });
        }
    });
    MockModel { url, requests }
}

/// An OpenAI-style reply holding one tool call.
fn tool_call(id: &str, name: &str, args: serde_json::Value) -> Act {
    Act::Json(
        200,
        serde_json::json!({"choices": [{"message": {"role": "assistant", "content": format!("calling {name}"),
            "tool_calls": [{"id": id, "type": "function", "function": {"name": name, "arguments": args.to_string()}}]}}],
            "usage": {"prompt_tokens": 1000, "completion_tokens": 20}}),
    )
}

fn ledger_tools(run: &Path) -> Vec<String> {
    std::fs::read_to_string(run.join("ledger.jsonl"))
        .expect("ledger")
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).expect("ledger line");
            v["tool"].as_str().expect("tool").to_string()
        })
        .collect()
}

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
    let o = agentstar(&[
        "run",
        &s(&p("run")),
        "--model",
        "local:mock",
        "--base-url",
        &model.url,
        "--request-timeout",
        "1",
        "--retries",
        "3",
        "--backoff-ms",
        "10",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["finished"], true, "{v}");
    assert_eq!(v["steps"], 8);
    let reqs = model.requests.lock().expect("lock").clone();
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
    let o = agentstar(&[
        "score",
        "--capture",
        &s(&p("cap")),
        "--model",
        &s(&p("run/scene.rhai")),
        "--poses",
        &s(&p("run/pose.json")),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(p("run/.agentstar/scenes/0002.rhai").is_file());
    // A finished run says so and does nothing; its report shows the steps.
    let o = agentstar(&[
        "run",
        &s(&p("run")),
        "--model",
        "local:mock",
        "--base-url",
        &model.url,
    ]);
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

/// The hand-held box with hands, seed 7 (the demo's clip), `frames` keyframes, at 160×120
/// when `small` (else 320×240), written to `out`.
fn synth_box(out: &Path, frames: usize, small: bool) {
    let n = frames.to_string();
    let mut args = vec![
        "synth",
        out.to_str().expect("utf8"),
        "--object",
        "box",
        "--frames",
        &n,
        "--seed",
        "7",
    ];
    if small {
        args.extend(["--size", "160x120"]);
    }
    let o = agentstar(&args);
    assert!(o.status.success(), "{}", text(&o));
}

/// A small synthetic capture `DIR/cap` (the hand-held box, 160×120) and a run `DIR/run` on
/// it, started from the known scene at its scale or from the default box.
fn small_run(dir: &Path, frames: usize, known_scene: bool) {
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    let (cap, run) = (dir.join("cap"), dir.join("run"));
    synth_box(&cap, frames, true);
    let scene = s(&cap.join("model/scene.rhai"));
    let mut args = vec!["init".to_string(), s(&run), "--capture".into(), s(&cap)];
    if known_scene {
        args.extend(["--scene".into(), scene, "--scale".into(), "0.24".into()]);
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = agentstar(&args);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn a_failing_model_stops_cleanly_and_the_run_resumes_within_its_budget() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    small_run(dir.path(), 3, false);
    let poses_before = std::fs::read(p("run/pose.json")).expect("poses");
    let malformed = || {
        Act::Json(
            200,
            serde_json::json!({"choices": [{"message": {"content": "", "tool_calls": [
            {"id": "x", "type": "function", "function": {"name": "sweep", "arguments": "{\"frames\": "}}]}}]}),
        )
    };
    // 1. Malformed tool calls, retried, then a clean stop.
    let model = mock_model(vec![malformed(), malformed(), malformed()]);
    let o = agentstar(&[
        "run",
        &s(&p("run")),
        "--model",
        "local:mock",
        "--base-url",
        &model.url,
        "--retries",
        "2",
        "--backoff-ms",
        "5",
    ]);
    assert_eq!(o.status.code(), Some(4), "{}", text(&o));
    assert!(text(&o).contains("malformed"), "{}", text(&o));
    assert_eq!(model.requests.lock().expect("lock").len(), 3);
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
    let o = agentstar(&[
        "run",
        &s(&p("run")),
        "--model",
        "local:mock",
        "--base-url",
        &model.url,
        "--max-steps",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(text(&o).contains("step budget"), "{}", text(&o));
    assert_eq!(
        ledger_tools(&p("run")),
        ["init", "stop", "score", "render", "stop"]
    );
    // The run is consistent: its poses still score, its capture still validates.
    let o = agentstar(&[
        "score",
        "--capture",
        &s(&p("cap")),
        "--model",
        &s(&p("run/scene.rhai")),
        "--poses",
        &s(&p("run/pose.json")),
        "--json",
    ]);
    assert!(
        serde_json::from_slice::<serde_json::Value>(&o.stdout).is_ok(),
        "{}",
        text(&o)
    );
    // 3. Resumed again: the model is told where the run stands.
    let model = mock_model(vec![tool_call(
        "d",
        "notes",
        serde_json::json!({"text": "resumed"}),
    )]);
    let o = agentstar(&[
        "run",
        &s(&p("run")),
        "--model",
        "local:mock",
        "--base-url",
        &model.url,
        "--retries",
        "0",
    ]);
    assert_eq!(o.status.code(), Some(4), "{}", text(&o));
    let first = model.requests.lock().expect("lock")[0].to_string();
    assert!(
        first.contains("resuming this run after 2 step(s)"),
        "{first}"
    );
    assert!(
        first.contains("render"),
        "the resume summary lists the earlier steps"
    );
}

/// A minimal MCP client over the child's stdio: JSON-RPC lines.
struct McpClient {
    child: std::process::Child,
    stdin: std::process::ChildStdin,
    lines: std::io::Lines<std::io::BufReader<std::process::ChildStdout>>,
}

impl McpClient {
    fn start(run: &Path) -> McpClient {
        use std::io::BufRead;
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_agentstar"))
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
            stdin,
            lines,
        }
    }

    fn send(&mut self, v: serde_json::Value) {
        use std::io::Write;
        writeln!(self.stdin, "{v}").expect("write");
        self.stdin.flush().expect("flush");
    }

    /// The response to request `id` (notifications before it are returned too).
    fn response(&mut self, id: u64) -> (serde_json::Value, Vec<serde_json::Value>) {
        let mut notes = vec![];
        for line in self.lines.by_ref() {
            let v: serde_json::Value = serde_json::from_str(&line.expect("line")).expect("json");
            if v["id"] == id {
                return (v, notes);
            }
            notes.push(v);
        }
        panic!("the server closed before answering {id}");
    }
}

impl Drop for McpClient {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn the_mcp_server_lists_its_tools_as_snapshotted_and_returns_images() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    small_run(dir.path(), 3, true);
    let mut c = McpClient::start(&p("run"));
    c.send(serde_json::json!({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {
        "protocolVersion": "2025-06-18", "capabilities": {}, "clientInfo": {"name": "test", "version": "0"}}}));
    let (init, _) = c.response(1);
    assert_eq!(init["result"]["serverInfo"]["name"], "agentstar", "{init}");
    c.send(serde_json::json!({"jsonrpc": "2.0", "method": "notifications/initialized"}));
    c.send(serde_json::json!({"jsonrpc": "2.0", "id": 2, "method": "tools/list"}));
    let (list, _) = c.response(2);
    // The whole surface: instructions, names, descriptions, schemas.
    let surface = serde_json::json!({
        "instructions": init["result"]["instructions"],
        "tools": list["result"]["tools"],
    });
    let snapshot = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots/mcp_surface.json");
    let now = serde_json::to_string_pretty(&surface).expect("json") + "\n";
    if std::env::var_os("AGENTSTAR_UPDATE_SNAPSHOTS").is_some() {
        std::fs::write(&snapshot, &now).expect("write snapshot");
    }
    let committed = std::fs::read_to_string(&snapshot)
        .expect("tests/snapshots/mcp_surface.json (AGENTSTAR_UPDATE_SNAPSHOTS=1 writes it)");
    assert_eq!(
        now, committed,
        "the MCP surface changed: review it, then AGENTSTAR_UPDATE_SNAPSHOTS=1"
    );
    // A tool that returns an image, inline and as a file.
    c.send(
        serde_json::json!({"jsonrpc": "2.0", "id": 3, "method": "tools/call", "params": {
        "name": "render", "arguments": {"frames": "000000", "views": "compare"},
        "_meta": {"progressToken": "p1"}}}),
    );
    let (call, notes) = c.response(3);
    // The client asked for progress: the call reports at least its start.
    assert!(
        notes.iter().any(|n| n["method"] == "notifications/progress"
            && n["params"]["progressToken"] == "p1"
            && n["params"]["message"]
                .as_str()
                .is_some_and(|m| m.starts_with("render"))),
        "{notes:?}"
    );
    let content = call["result"]["content"]
        .as_array()
        .expect("content")
        .clone();
    assert_eq!(call["result"]["isError"], false, "{call}");
    let image = content
        .iter()
        .find(|b| b["type"] == "image")
        .expect("an image block");
    assert_eq!(image["mimeType"], "image/png");
    use base64::Engine;
    let png = base64::engine::general_purpose::STANDARD
        .decode(image["data"].as_str().expect("data"))
        .expect("base64");
    assert_eq!(&png[..4], b"\x89PNG");
    let listed = content[0]["text"].as_str().expect("text");
    let path = listed
        .lines()
        .find_map(|l| l.strip_prefix("- "))
        .expect("image paths in the text");
    assert!(Path::new(path).is_file(), "{path}");
    // A bad call is a tool error the model can read, not a protocol failure; both are steps.
    c.send(
        serde_json::json!({"jsonrpc": "2.0", "id": 4, "method": "tools/call", "params": {
        "name": "scene_write", "arguments": {"script": "part(\"x\", sphere("}}}),
    );
    let (bad, _) = c.response(4);
    assert_eq!(bad["result"]["isError"], true, "{bad}");
    assert_eq!(ledger_tools(&p("run")), ["init", "render", "scene_write"]);
}

#[test]
fn pose_sub_agents_work_their_windows_in_parallel_and_report_back() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
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
    let o = agentstar(&[
        "run",
        &s(&p("run")),
        "--model",
        "local:mock",
        "--base-url",
        &model.url,
        "--retries",
        "0",
    ]);
    // The script ends before the gates: a model error stop, with every step recorded.
    assert_eq!(o.status.code(), Some(4), "{}", text(&o));
    let reqs = model.requests.lock().expect("lock").clone();
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
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_agentstar"))
        .args([
            "run",
            &s(&p("run")),
            "--model",
            "local:mock",
            "--base-url",
            &model.url,
            "--retries",
            "0",
        ])
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
