//! The shape tools against the real binary: `fit_shape` over MCP recovers two deliberately
//! wrong proportions of a known model and leaves the others as they are; a scene edit that
//! moves the bounding-box centre keeps every keyframe's IoU.

mod support;

use agentstar_reports::fit::FitReport;
use agentstar_reports::ScoreReport;
use serde_json::json;
use std::path::Path;
use support::{
    agentstar, assert_failed_saying, init_run, on_poses, s, score_of, synth_object, text, McpClient,
};

/// The synthetic box (`agentstar synth --object box`) with its proportions as parameters:
/// the true values are width 1.0, depth 0.7, body height 0.48.
fn box_script(width: &str, depth: &str, height: &str) -> String {
    format!(
        r##"// The box with a hinged lid, its proportions as parameters.
let w = param("width", {width}, 0.8, 1.2);
let d = param("depth", {depth}, 0.5, 0.9);
let h = param("height", {height}, 0.35, 0.7);
let body = box(w, d, h, 0.02) - box(w - 0.08, d - 0.08, h + 0.02).translate(0, 0, 0.06);
part("body", body.translate(0, 0, 0.2 - h / 2).color("#c8553d"));
part("lid", box(w, d, 0.06, 0.01).translate(0, 0, 0.23).color("#f2d0a4"));
joint(#{{ name: "lid_hinge", type: "revolute", child: "lid", origin: [0, d / 2, 0.2], axis: [-1, 0, 0], limit: [0, 110] }});
"##
    )
}

/// A capture of the synthetic box and a run on it whose scene is `script`, with the true
/// poses committed.
fn run_with(dir: &Path, frames: usize, script: &str) -> (std::path::PathBuf, std::path::PathBuf) {
    let (cap, run) = (dir.join("cap"), dir.join("run"));
    let n = frames.to_string();
    let o = synth_object(
        &s(&cap),
        "box",
        &["--frames", &n, "--seed", "3", "--no-hands"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let scene = dir.join("start.rhai");
    std::fs::write(&scene, script).expect("write scene");
    init_run(&run, &cap, Some((&scene, "0.24")));
    std::fs::copy(cap.join("model/pose.json"), run.join("pose.json")).expect("true poses");
    (cap, run)
}

fn score(cap: &Path, model: &Path, poses: &Path) -> Vec<f64> {
    let r: ScoreReport = score_of(&s(cap), &s(model), &s(poses), None);
    r.frames.iter().map(|f| f.gate()).collect()
}

/// The value of `param("name", VALUE, …)` in a script.
fn param_value(script: &str, name: &str) -> f64 {
    let key = format!("param(\"{name}\", ");
    let at = script
        .find(&key)
        .unwrap_or_else(|| panic!("no {name} in {script}"))
        + key.len();
    script[at..]
        .split(',')
        .next()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{name}: {script}"))
}

#[test]
fn fit_shape_recovers_two_wrong_proportions_and_holds_the_rest() {
    let dir = tempfile::tempdir().expect("tmp");
    // Depth 15% short, body height 20% tall; the width is right.
    let (cap, run) = run_with(dir.path(), 6, &box_script("1.0", "0.595", "0.576"));
    // A parameter the script does not declare is named, with those it does.
    let o = on_poses(
        "fit-shape",
        &s(&cap),
        &s(&run.join("scene.rhai")),
        &s(&run.join("pose.json")),
        &[
            "--params",
            "depth,lenght",
            "--out",
            &s(&dir.path().join("x")),
        ],
    );
    assert_failed_saying(&o, &["no parameter `lenght`", "width, depth, height"]);
    let (mut c, _) = McpClient::initialised(&run);
    c.call(2, "fit_shape", json!({"params": ["depth", "height"]}));
    let (resp, _) = c.response(2);
    let result = &resp["result"];
    assert_eq!(result["isError"], false, "{resp}");
    let r: FitReport =
        serde_json::from_value(result["structuredContent"].clone()).expect("fit report");
    let body = McpClient::text_of(&resp);
    let depth = r.params.iter().find(|p| p.name == "depth").expect("depth");
    let height = r
        .params
        .iter()
        .find(|p| p.name == "height")
        .expect("height");
    assert!(
        (depth.after / 0.7 - 1.0).abs() < 0.02 && (height.after / 0.48 - 1.0).abs() < 0.02,
        "depth {} (0.7), height {} (0.48)\n{body}",
        depth.after,
        height.after
    );
    assert!(r.iou_mean_after > r.iou_mean_before + 0.01, "{body}");
    assert_eq!(r.held.len(), 1);
    assert_eq!((r.held[0].name.as_str(), r.held[0].value), ("width", 1.0));
    // The scene is a new version with the fitted values as its defaults, the width as written.
    let scene = std::fs::read_to_string(run.join("scene.rhai")).expect("scene");
    assert!(
        (param_value(&scene, "depth") - depth.after).abs() < 1e-5,
        "{scene}"
    );
    assert!(
        (param_value(&scene, "height") - height.after).abs() < 1e-5,
        "{scene}"
    );
    assert!(scene.contains("param(\"width\", 1.0, 0.8, 1.2)"), "{scene}");
    assert!(run.join(".agentstar/scenes/0002.rhai").is_file());
    // The refined poses are pose.json, and score there as the fit said.
    let now = score(&cap, &run.join("scene.rhai"), &run.join("pose.json"));
    let mean = now.iter().sum::<f64>() / now.len() as f64;
    assert!(
        (mean - r.iou_mean_after).abs() < 1e-6,
        "{mean} vs {}",
        r.iou_mean_after
    );
    // Each frame's band IoU in the fit's report is the gate's figure as `score` reads it.
    let scored: ScoreReport = score_of(
        &s(&cap),
        &s(&run.join("scene.rhai")),
        &s(&run.join("pose.json")),
        None,
    );
    for (f, sf) in r.frames.iter().zip(&scored.frames) {
        let band = f.iou_band_after.expect("band IoU in the fit report");
        assert!(
            (band - sf.gate()).abs() < 1e-6,
            "{}: fit says band {band}, score {}",
            f.frame,
            sf.gate()
        );
    }
    // The before/after sheet came back as an image, under the size a VLM reads.
    let images: Vec<_> = result["content"]
        .as_array()
        .expect("content")
        .iter()
        .filter(|b| b["type"] == "image")
        .collect();
    assert!(!images.is_empty(), "{resp}");
    let sheet = image::open(&r.sheets[0]).expect("sheet");
    assert!(
        sheet.width() <= 1568 && sheet.height() <= 1568,
        "{}×{}",
        sheet.width(),
        sheet.height()
    );
    // The step is a shape step: the turntable gate applies after it.
    c.call(3, "finish", json!({}));
    let (fin, _) = c.response(3);
    assert!(McpClient::text_of(&fin).contains("turntable"), "{fin}");
}

/// A fixed proportion the fitted parameter does not set (the box's width, 15% short, with
/// only its height fitted): `fit_shape` returns the residuals grouped by viewing direction,
/// and they name X as the axis the frames want longer, relative to the others.
#[test]
fn fit_shape_names_the_fixed_proportion_its_parameters_cannot_reach() {
    let dir = tempfile::tempdir().expect("tmp");
    let (_cap, run) = run_with(dir.path(), 6, &box_script("0.85", "0.7", "0.48"));
    let (mut c, _) = McpClient::initialised(&run);
    c.call(2, "fit_shape", json!({"params": ["height"], "rounds": 2}));
    let (resp, _) = c.response(2);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    let body = McpClient::text_of(&resp);
    let r: FitReport =
        serde_json::from_value(resp["result"]["structuredContent"].clone()).expect("report");
    let v = r.views.as_ref().expect("residuals by viewing direction");
    let [x, y, z] = v.all.want;
    let (x, y, z) = (x.expect("x"), y.expect("y"), z.expect("z"));
    // X is wanted about 1 / 0.85 − 1 = 18% longer than the others (the common part is the
    // scale, which silhouettes do not say).
    assert!(x - y > 0.08 && x - z > 0.08, "{x} {y} {z}\n{body}");
    assert!(!v.groups.is_empty(), "{body}");
    assert!(
        v.verdict.iter().any(|l| l.contains("longer along X")),
        "{:?}\n{body}",
        v.verdict
    );
    eprintln!("{body}");
    assert!(body.contains("residuals by viewing direction"), "{body}");
    assert!(body.contains("face-on to"), "{body}");
    assert!(body.contains("longer along X"), "{body}");
    // The height cannot make X longer against Y: the reply names what no fitted parameter
    // makes (play-test 15), along X.
    assert!(
        r.unmet.iter().any(|u| u.axis == "X" && u.want > 0.03),
        "{:?}\n{body}",
        r.unmet
    );
    assert!(
        body.contains("no fitted parameter makes what the frames want along X +"),
        "{body}"
    );
}

/// A parameter the masks cannot set (the height of a thin label on the box's front, whose
/// outline moves only by the label's 4-thousandths lip) is named as such, beside one they
/// can (the box's height), which is not (play-test 16 fitted a band's height on a can and
/// believed it).
#[test]
fn fit_shape_names_a_parameter_the_masks_cannot_set() {
    let dir = tempfile::tempdir().expect("tmp");
    let script = format!(
        "{}let lz = param(\"label_z\", 0.0, -0.08, 0.08);\npart(\"label\", box(0.3, 0.004, 0.12).translate(0, -d / 2 - 0.002, 0.2 - h / 2 + lz).color(\"#335c67\"));\n",
        box_script("1.0", "0.7", "0.48")
    );
    let (_cap, run) = run_with(dir.path(), 6, &script);
    let (mut c, _) = McpClient::initialised(&run);
    c.call(
        2,
        "fit_shape",
        json!({"params": ["height", "label_z"], "rounds": 1}),
    );
    let (resp, _) = c.response(2);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    let body = McpClient::text_of(&resp);
    let r: FitReport =
        serde_json::from_value(resp["result"]["structuredContent"].clone()).expect("report");
    let unseen: Vec<&str> = r.unseen.iter().map(|u| u.name.as_str()).collect();
    assert_eq!(unseen, ["label_z"], "{body}");
    assert!(r.unseen[0].iou_span < 0.002, "{:?}", r.unseen);
    assert!(body.contains("the masks cannot set `label_z`"), "{body}");
}

#[test]
fn a_scene_edit_that_moves_the_centre_keeps_every_keyframes_iou() {
    let dir = tempfile::tempdir().expect("tmp");
    let original = box_script("1.0", "0.7", "0.48");
    let (cap, run) = run_with(dir.path(), 6, &original);
    let before = score(&cap, &run.join("scene.rhai"), &run.join("pose.json"));
    assert!(before.iter().all(|&v| v > 0.97), "{before:?}");
    let old_poses = dir.path().join("old_pose.json");
    std::fs::copy(run.join("pose.json"), &old_poses).expect("copy");
    // Thinner walls (a wider cavity), and every part moved, as re-centring does: the
    // bounding-box centre moves by about 4 cm at this scale.
    let edited = original
        .replace(
            "box(w - 0.08, d - 0.08, h + 0.02)",
            "box(w - 0.07, d - 0.07, h + 0.02)",
        )
        .replace(
            ".color(\"#c8553d\")",
            ".translate(0.1, -0.12, 0.07).color(\"#c8553d\")",
        )
        .replace(
            ".color(\"#f2d0a4\")",
            ".translate(0.1, -0.12, 0.07).color(\"#f2d0a4\")",
        )
        .replace(
            "origin: [0, d / 2, 0.2]",
            "origin: [0.1, d / 2 - 0.12, 0.27]",
        );
    assert_ne!(edited, original);
    let (mut c, _) = McpClient::initialised(&run);
    c.call(2, "scene_write", json!({"script": edited}));
    let (resp, _) = c.response(2);
    let body = McpClient::text_of(&resp);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    assert!(body.contains("canonical origin moved"), "{body}");
    let after = score(&cap, &run.join("scene.rhai"), &run.join("pose.json"));
    for (k, (b, a)) in before.iter().zip(&after).enumerate() {
        assert!(
            (b - a).abs() <= 0.005,
            "keyframe {k}: IoU {b:.4} before, {a:.4} after\n{body}"
        );
    }
    // Without the compensation the same edit costs far more.
    let stale = score(&cap, &run.join("scene.rhai"), &old_poses);
    let worst = before
        .iter()
        .zip(&stale)
        .map(|(b, a)| b - a)
        .fold(0.0, f64::max);
    assert!(worst > 0.05, "{stale:?}");
    // The edit left the model off centre and the check said so; writing it again (a comment
    // added) does not repeat that warning, and says one is kept.
    assert!(body.contains("warning: bounding-box centre"), "{body}");
    c.call(
        3,
        "scene_write",
        json!({"script": format!("// again\n{edited}")}),
    );
    let (resp, _) = c.response(3);
    let again = McpClient::text_of(&resp);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    assert!(!again.contains("warning: bounding-box centre"), "{again}");
    assert!(
        again.contains("1 warning(s) as in the scene this replaced, not repeated"),
        "{again}"
    );
    assert_eq!(
        resp["result"]["structuredContent"]["warnings"]
            .as_array()
            .map(Vec::len),
        Some(1),
        "{resp}"
    );
}

/// `pose.json` with its scale (and every translation) multiplied by `k`: the same
/// silhouettes at a wrong scale.
fn rescaled(poses: &Path, k: f64, out: &Path) -> f64 {
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(poses).expect("read")).expect("json");
    let truth = v["scale"].as_f64().expect("scale");
    v["scale"] = json!(truth * k);
    for (_, f) in v["frames"].as_object_mut().expect("frames").iter_mut() {
        if let Some(p) = f.get_mut("object_pose").filter(|p| p.is_object()) {
            let t: Vec<f64> = p["translation"]
                .as_array()
                .expect("t")
                .iter()
                .map(|x| x.as_f64().expect("n") * k)
                .collect();
            p["translation"] = json!(t);
            if p.get("scale").is_some() {
                p["scale"] = json!(truth * k);
            }
        }
    }
    std::fs::write(out, serde_json::to_vec(&v).expect("json")).expect("write");
    truth
}

/// `OBJECT` moved by `MOTION` in 6 keyframes of 160×120 without hands (seed 2), in `out`.
fn synth_small(out: &Path, object: &str, motion: &str) {
    let mut args = vec!["--motion", motion, "--frames", "6", "--size", "160x120"];
    args.extend(["--no-hands", "--seed", "2"]);
    let o = synth_object(&s(out), object, &args);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn scale_comes_back_from_depth_parallax_and_a_stated_size() {
    let dir = tempfile::tempdir().expect("tmp");
    let cap = dir.path().join("cap");
    // A static microwave, an orbiting metric camera, depth (as iTACO has).
    synth_small(&cap, "microwave", "static-orbit");
    let model = cap.join("model/scene.rhai");
    let wrong = dir.path().join("wrong.json");
    let truth = rescaled(&cap.join("model/pose.json"), 0.8, &wrong);
    // `agentstar scale` on a capture, its model and poses.
    let scale_cli = |cap: &Path, model: &Path, poses: &Path, extra: &[&str]| {
        on_poses("scale", &s(cap), &s(model), &s(poses), extra)
    };
    let report_of = |o: std::process::Output| -> agentstar_reports::fit::ScaleReport {
        assert!(o.status.success(), "{}", text(&o));
        serde_json::from_slice(&o.stdout).unwrap_or_else(|_| panic!("{}", text(&o)))
    };
    let estimate = |extra: &[&str]| {
        let mut extra = extra.to_vec();
        extra.push("--json");
        report_of(scale_cli(&cap, &model, &wrong, &extra))
    };
    let depth = estimate(&["--from", "depth"]);
    assert!(
        (depth.scale_after / truth - 1.0).abs() < 0.03,
        "depth: {} vs {truth}: {depth:?}",
        depth.scale_after
    );
    let parallax = estimate(&["--from", "parallax"]);
    assert!(
        (parallax.scale_after / truth - 1.0).abs() < 0.05,
        "parallax: {} vs {truth}: {parallax:?}",
        parallax.scale_after
    );
    // "The microwave is this long": its longest side in metres.
    let size = estimate(&[
        "--from",
        "size",
        "--axis",
        "longest",
        "--metres",
        &format!("{truth}"),
    ]);
    let longest = {
        let o = agentstar(&["check", &s(&model), "--json"]);
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("check json");
        v["canonical"]["longest_side"]
            .as_f64()
            .or_else(|| v["longest_side"].as_f64())
            .expect("longest side")
    };
    assert!(
        (size.scale_after - truth / longest).abs() < 1e-9,
        "{size:?}"
    );
    // Sound estimates are not flagged weak.
    for e in [&depth, &parallax, &size] {
        assert!(!e.weak, "{e:?}");
    }
    // An object turned in a hand moves in the world: parallax is weak there, and says why
    // (the capture has no depth: the last check uses it too).
    let held = dir.path().join("held");
    synth_small(&held, "box", "handheld");
    let (held_model, held_poses) = (held.join("model/scene.rhai"), held.join("model/pose.json"));
    let r = report_of(scale_cli(
        &held,
        &held_model,
        &held_poses,
        &["--from", "parallax", "--json"],
    ));
    assert!(
        r.weak && r.notes.iter().any(|n| n.contains("moves in the world")),
        "{r:?}"
    );
    // Rescaling in place keeps every silhouette: the IoU is what it was.
    let before = score(&cap, &model, &wrong);
    let o = scale_cli(&cap, &model, &wrong, &["--from", "depth", "--write"]);
    assert!(o.status.success(), "{}", text(&o));
    let after = score(&cap, &model, &wrong);
    for (b, a) in before.iter().zip(&after) {
        assert!((b - a).abs() < 1e-3, "{before:?} vs {after:?}");
    }
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&wrong).expect("read")).expect("json");
    assert!((v["scale"].as_f64().expect("scale") / truth - 1.0).abs() < 0.03);
    // A capture without depth (the hand-held box's) says what to use instead.
    let o = scale_cli(&held, &held_model, &held_poses, &["--from", "depth"]);
    assert_failed_saying(&o, &["no keyframe has depth"]);
}

/// `agentstar scale --from hand`: the hands' palm breadth against the adult prior puts a
/// hand-held laptop (no depth, a moving object: no other route applies) back at its scale
/// from poses at 0.6 of it, within the uncertainty the report states; a capture without
/// hands says what to use instead.
#[test]
fn scale_comes_back_from_the_hands_within_its_stated_uncertainty() {
    let dir = tempfile::tempdir().expect("tmp");
    let synth = |out: &Path, object: &str, hands: bool| {
        let mut args = vec!["--motion", "handheld", "--frames", "10"];
        args.extend(["--size", "320x240", "--seed", "5"]);
        if !hands {
            args.push("--no-hands");
        }
        let o = synth_object(&s(out), object, &args);
        assert!(o.status.success(), "{}", text(&o));
    };
    // The laptop (0.3 m) is drawn with full-size hands: a palm of 8.5 cm.
    assert_eq!(agentstar_synth::hand::hand_scale_for(0.3), 1.0);
    let cap = dir.path().join("laptop");
    synth(&cap, "laptop", true);
    let model = cap.join("model/scene.rhai");
    let wrong = dir.path().join("wrong.json");
    let truth = rescaled(&cap.join("model/pose.json"), 0.6, &wrong);
    let scale_cli = |cap: &Path, poses: &Path, model: &Path| {
        on_poses(
            "scale",
            &s(cap),
            &s(model),
            &s(poses),
            &["--from", "hand", "--json"],
        )
    };
    let o = scale_cli(&cap, &wrong, &model);
    assert!(o.status.success(), "{}", text(&o));
    let r: agentstar_reports::fit::ScaleReport =
        serde_json::from_slice(&o.stdout).unwrap_or_else(|_| panic!("{}", text(&o)));
    let u = r
        .uncertainty
        .expect("the hand route states its uncertainty");
    let error = r.scale_after / truth - 1.0;
    eprintln!(
        "hand: {:.4} m per unit vs {truth} ({:+.1}%), ± {:.1}% over {} frames, palms {:?} px",
        r.scale_after,
        100.0 * error,
        100.0 * u,
        r.samples,
        r.frames.iter().map(|f| f.palm_px).collect::<Vec<_>>()
    );
    assert!(r.samples >= 3, "{r:?}");
    assert!(u > 0.05 && u < 0.2, "{r:?}");
    // Within the stated 95% range (two standard deviations), and nearer the truth than the
    // start (40% short). Measured 2026-12-04: −20.7% at ± 17.7%: the synthetic hand's palm
    // is 8.5 cm (the prior says 7.9) and it sits half the object's radius in front of it.
    assert!(error.abs() <= 2.0 * u, "{error} vs ± {u}: {r:?}");
    assert!(error.abs() < 0.3, "{r:?}");
    assert!(r
        .frames
        .iter()
        .all(|f| f.palm_px.is_some_and(|p| p >= 10.0)));
    let notes = r.notes.join("\n");
    assert!(
        notes.contains("--from depth")
            && notes.contains("parallax")
            && notes.contains("--from size"),
        "{notes}"
    );
    // Without hand masks: a clear error, naming the other routes.
    let bare = dir.path().join("bare");
    synth(&bare, "laptop", false);
    let o = scale_cli(
        &bare,
        &bare.join("model/pose.json"),
        &bare.join("model/scene.rhai"),
    );
    assert_failed_saying(&o, &["hand mask", "depth"]);
}

#[test]
fn scene_write_reads_a_script_from_a_file_in_the_run_and_nowhere_else() {
    let dir = tempfile::tempdir().expect("tmp");
    let original = box_script("1.0", "0.7", "0.48");
    let (_cap, run) = run_with(dir.path(), 2, &original);
    let edited = box_script("1.1", "0.7", "0.48");
    std::fs::write(run.join("draft.rhai"), &edited).expect("draft");
    let outside = dir.path().join("outside.rhai");
    std::fs::write(&outside, &edited).expect("outside");
    std::fs::write(run.join("empty.rhai"), "  \n").expect("empty");
    // Over the 256 KiB a script may hold (a comment line repeated).
    std::fs::write(run.join("huge.rhai"), "// padding\n".repeat(30_000)).expect("huge");
    let (mut c, _) = McpClient::initialised(&run);
    // Refused, and the scene left as it was: a file outside the run, both arguments,
    // neither, an empty file, a missing one, one too long.
    let refused = [
        (json!({"path": s(&outside)}), "outside the run"),
        (json!({"path": "draft.rhai", "script": edited}), "not both"),
        (json!({}), "give `script`"),
        (json!({"path": "empty.rhai"}), "is empty"),
        (json!({"path": "nowhere.rhai"}), "no such file"),
        (json!({"path": "huge.rhai"}), "at most 262144"),
    ];
    for (id, (args, says)) in refused.iter().enumerate() {
        let id = id as u64 + 2;
        c.call(id, "scene_write", args.clone());
        let (resp, _) = c.response(id);
        let body = McpClient::text_of(&resp);
        assert_eq!(resp["result"]["isError"], true, "{args}: {resp}");
        assert!(body.contains(says), "{args}: {body}");
        let scene = std::fs::read_to_string(run.join("scene.rhai")).expect("scene");
        assert_eq!(scene, original, "{args} changed the scene");
    }
    // Relative to the run directory: the scene becomes the file's script.
    c.call(20, "scene_write", json!({"path": "draft.rhai"}));
    let (resp, _) = c.response(20);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    let scene = std::fs::read_to_string(run.join("scene.rhai")).expect("scene");
    assert_eq!(scene, edited);
}

/// The translations of every frame of a pose file.
fn translations(poses: &Path) -> Vec<Vec<f64>> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(poses).expect("poses")).expect("json");
    let mut frames: Vec<(String, Vec<f64>)> = v["frames"]
        .as_object()
        .expect("frames")
        .iter()
        .map(|(k, f)| {
            (
                k.clone(),
                f["object_pose"]["translation"]
                    .as_array()
                    .expect("translation")
                    .iter()
                    .map(|t| t.as_f64().expect("number"))
                    .collect(),
            )
        })
        .collect();
    frames.sort_by(|a, b| a.0.cmp(&b.0));
    frames.into_iter().map(|f| f.1).collect()
}

/// Issue 34 items 3 and 9b over MCP. A body grown evenly and meshed anew (its bevel's
/// segments changed) with a small handle on its face, which moves out: the edit holds the
/// body, the part most in view, so no pose moves (the largest part that could vote was the
/// handle, and every pose was carried by its move); `hold` names another part; a part named
/// that is not in both scripts is refused and nothing changes. And a part sunk inside the
/// body's solid floor draws a warning naming both parts.
#[test]
fn a_scene_edit_holds_the_part_most_in_view_or_the_named_one_and_names_hidden_parts() {
    let dir = tempfile::tempdir().expect("tmp");
    let handle =
        "part(\"handle\", box(0.04, 0.1, 0.1).translate(w / 2 + 0.02, 0, 0.1).color(\"#333333\"));\n";
    let original = format!("{}{handle}", box_script("1.0", "0.7", "0.48"));
    let (_cap, run) = run_with(dir.path(), 3, &original);
    let poses = run.join("pose.json");
    let start = translations(&poses);
    let grown = original
        .replace("param(\"width\", 1.0,", "param(\"width\", 1.1,")
        .replace("box(w, d, h, 0.02)", "box(w, d, h, 0.02, 3)");
    assert_ne!(grown, original);
    let (mut c, _) = McpClient::initialised(&run);
    c.call(2, "scene_write", json!({"script": grown}));
    let (resp, _) = c.response(2);
    let body = McpClient::text_of(&resp);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    assert!(
        body.contains("Held in place: part `body` (the largest part in view:"),
        "{body}"
    );
    // No pose moved; the version the edit made is said with what it changed (play-test 15:
    // "pose.json unchanged" beside a new pose version).
    assert!(!body.contains("canonical origin moved"), "{body}");
    assert!(
        body.contains("pose.json version 1: parts listed: body, lid, handle."),
        "{body}"
    );
    assert_eq!(translations(&poses), start, "{body}");
    // Holding the handle, the edit back moves every pose by the handle's move (5 cm of
    // model along x: 1.2 cm at this scale).
    c.call(
        3,
        "scene_write",
        json!({"script": original, "hold": "handle"}),
    );
    let (resp, _) = c.response(3);
    let body = McpClient::text_of(&resp);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    assert!(
        body.contains("Held in place: part `handle` (named)"),
        "{body}"
    );
    assert!(body.contains("under part `handle` (named"), "{body}");
    let carried = translations(&poses);
    for (a, b) in start.iter().zip(&carried) {
        let moved: f64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>()
            .sqrt();
        assert!((moved - 0.05 * 0.24).abs() < 1e-6, "{moved} {body}");
    }
    // A part named that is not in both scripts: refused, the scene unchanged.
    let scene_before = std::fs::read_to_string(run.join("scene.rhai")).expect("scene");
    c.call(4, "scene_write", json!({"script": grown, "hold": "knob"}));
    let (resp, _) = c.response(4);
    assert_eq!(resp["result"]["isError"], true, "{resp}");
    let refused = McpClient::text_of(&resp);
    assert!(
        refused.contains("the scene was not changed: `hold`: part `knob`")
            && refused.contains("body, lid, handle"),
        "{refused}"
    );
    assert_eq!(
        std::fs::read_to_string(run.join("scene.rhai")).expect("scene"),
        scene_before
    );
    // A weight sunk in the body's floor (z -0.24 to -0.19 before the body's own offset).
    let weighted = format!(
        "{original}part(\"weight\", box(0.3, 0.3, 0.02).translate(0, 0, -0.215 + 0.2 - h / 2));\n"
    );
    c.call(5, "scene_write", json!({"script": weighted}));
    let (resp, _) = c.response(5);
    let body = McpClient::text_of(&resp);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    assert!(
        body.contains("part `weight` lies entirely inside part `body`"),
        "{body}"
    );
    // Not said of the handle, which stands out of the body.
    assert!(!body.contains("part `handle` lies"), "{body}");
}
