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

/// The README's walk-through, with a frame folder in place of the video (no ffmpeg here):
/// a segmenter's masks, a static camera, a model, tracking, the report.
#[test]
fn the_readme_walk_through_goes_from_frames_and_masks_to_a_report() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let s = |path: &Path| path.to_str().expect("utf8").to_string();
    // A phone-like clip: frames, plus masks as a segmenter writes them (other names).
    let o = agentstar(&[
        "synth",
        &s(&p("clip")),
        "--object",
        "box",
        "--frames",
        "10",
        "--seed",
        "7",
    ]);
    assert!(o.status.success(), "{}", text(&o));
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
