//! In-between frames (`formats.md` §2) end to end: a clip whose frames between keyframes are
//! kept goes through `capture from-video`, `validate`, `track` (which follows them),
//! `score`, `report` and `eval`; keyframe tools see the keyframes only. The dataset
//! importers keep them on request and `track` follows them there too.

#[path = "../../agentstar-import/tests/datasets/mod.rs"]
mod datasets;
mod support;

use serde_json::Value;
use std::path::Path;
use support::{agentstar, assert_failed_saying, json_of, on_poses, s, synth_object, text};

/// Copies the PNG files of `from` into `to` (a new folder).
fn copy_pngs(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("dir");
    for entry in std::fs::read_dir(from).expect("read dir") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "png") {
            std::fs::copy(&path, to.join(path.file_name().expect("name"))).expect("copy");
        }
    }
}

/// `capture from-video DIR/frames --masks DIR/masks --every N … --out DIR/OUT`, with the
/// in-between options and the camera given in `extra`.
fn from_video(dir: &Path, every: &str, extra: &[&str], out: &str) -> std::process::Output {
    let (frames, masks, out) = (
        s(&dir.join("frames")),
        s(&dir.join("masks")),
        s(&dir.join(out)),
    );
    let mut args = vec![
        "capture",
        "from-video",
        &frames,
        "--masks",
        &masks,
        "--every",
        every,
    ];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--out", &out]);
    agentstar(&args)
}

#[test]
fn a_clip_with_in_between_frames_goes_from_video_to_report() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    // 5 keyframes 5 video frames apart, the 4 frames between each pair kept: 21 frames.
    let o = synth_object(
        &s(&p("clip")),
        "box",
        &[
            "--motion",
            "handheld",
            "--frames",
            "5",
            "--size",
            "160x120",
            "--seed",
            "3",
            "--between",
            "4",
            "--no-depth",
        ],
    );
    assert!(o.status.success(), "synth: {}", text(&o));
    let v = json_of::<Value>(&agentstar(&["validate", &s(&p("clip")), "--json"]));
    assert_eq!(v["valid"], true, "{v}");
    assert_eq!(v["frames"], 5, "{v}");
    assert_eq!(v["between_frames"], 16, "{v}");
    // The same frames and masks as a frame folder, cut again by from-video.
    copy_pngs(&p("clip/frames"), &p("frames"));
    copy_pngs(&p("clip/mask_object"), &p("masks"));
    let o = from_video(
        dir.path(),
        "5",
        &["--between", "--intrinsics", "152,152,80,60"],
        "cap",
    );
    assert!(o.status.success(), "from-video: {}", text(&o));
    let v = json_of::<Value>(&agentstar(&["validate", &s(&p("cap")), "--json"]));
    assert_eq!(v["valid"], true, "{v}");
    assert_eq!(
        (v["frames"].clone(), v["between_frames"].clone()),
        (5.into(), 16.into())
    );
    // A stride keeps fewer: every 2nd frame after each keyframe.
    let o = from_video(
        dir.path(),
        "5",
        &["--between", "2", "--intrinsics", "152,152,80,60"],
        "cap2",
    );
    assert!(o.status.success(), "from-video --between 2: {}", text(&o));
    let v = json_of::<Value>(&agentstar(&["validate", &s(&p("cap2")), "--json"]));
    assert_eq!(v["between_frames"], 8, "{v}");
    // Tracked through the video, the in-between poses written too.
    let model = s(&p("clip/model/scene.rhai"));
    let truth = s(&p("clip/model/pose.json"));
    let o = agentstar(&[
        "track",
        &s(&p("cap")),
        "--model",
        &model,
        "--scale-from",
        &truth,
        "--write-between",
        "--out",
        &s(&p("run/pose.json")),
        "--json",
    ]);
    assert!(o.status.success(), "track: {}", text(&o));
    let report: Value = json_of(&o);
    assert_eq!(
        report["frames"].as_array().map(Vec::len),
        Some(5),
        "keyframes scored"
    );
    let log = report["log"].to_string();
    assert!(log.contains("followed 4 in-between frame(s)"), "{log}");
    let poses: Value =
        serde_json::from_str(&std::fs::read_to_string(p("run/pose.json")).expect("read"))
            .expect("json");
    let frames = poses["frames"].as_object().expect("frames");
    let between: Vec<&String> = frames
        .iter()
        .filter(|(_, e)| e["between"] == true)
        .map(|(k, _)| k)
        .collect();
    assert_eq!(between.len(), 16, "{between:?}");
    assert_eq!(frames.len(), 21);
    // A warm start follows the video too (from the poses it refines), and reads a pose file
    // holding in-between poses as keyframe poses only.
    let o = agentstar(&[
        "track",
        &s(&p("cap")),
        "--model",
        &model,
        "--from",
        &s(&p("run/pose.json")),
        "--out",
        &s(&p("warm/pose.json")),
        "--json",
    ]);
    assert!(o.status.success(), "track --from: {}", text(&o));
    let warm: Value = json_of(&o);
    assert!(
        warm["log"]
            .to_string()
            .contains("followed the video across 4 gap(s)"),
        "{}",
        warm["log"]
    );
    // Keyframe tools read the keyframes' poses and leave the in-between ones alone.
    let o = on_poses(
        "score",
        &s(&p("cap")),
        &model,
        &s(&p("run/pose.json")),
        &["--json"],
    );
    let scored: Value = json_of(&o);
    assert_eq!(
        scored["frames"].as_array().map(Vec::len),
        Some(5),
        "{scored}"
    );
    assert!(
        text(&o).contains("16 in-between frame(s) besides its 5 keyframes"),
        "{}",
        text(&o)
    );
    std::fs::copy(&model, p("run/scene.rhai")).expect("model");
    let o = agentstar(&["report", &s(&p("run")), "--capture", &s(&p("cap"))]);
    assert!(o.status.success(), "report: {}", text(&o));
    // On the synthetic clip itself (it has ground truth), tracking through the video and
    // keyframes alone both reach the truth; eval reads the keyframes.
    for (label, extra) in [("video", None), ("keyframes", Some("--no-between"))] {
        let out = p(&format!("{label}/pose.json"));
        let mut args = vec![
            "track".to_string(),
            s(&p("clip")),
            "--model".into(),
            model.clone(),
            "--scale-from".into(),
            truth.clone(),
            "--out".into(),
            s(&out),
        ];
        args.extend(extra.map(String::from));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = agentstar(&args);
        assert!(o.status.success(), "track ({label}): {}", text(&o));
        let o = on_poses("eval", &s(&p("clip")), &model, &s(&out), &["--json"]);
        assert!(o.status.success(), "eval ({label}): {}", text(&o));
        let e: Value = json_of(&o);
        assert_eq!(e["frames"], 5, "{e}");
        let epe = e["epe_cm"].as_f64().expect("epe");
        let rotation = e["rotation_mean_deg"].as_f64().expect("rotation");
        eprintln!("{label}: EPE {epe:.3} cm, rotation {rotation:.2}° mean");
        // Following the video reaches the truth; keyframes alone are only required to run
        // (on this clip they landed 1.01 cm and 6.5° off on 2026-12-04).
        if label == "video" {
            assert!(
                epe < 1.0 && rotation < 3.0,
                "{label}: EPE {epe} cm, {rotation}°"
            );
        }
    }
}

#[test]
fn track_reads_the_in_between_frames_colours_for_the_axis_pass_over_the_video() {
    // A can printed on half its side, 4 keyframes with 4 frames kept between each pair: the
    // axis pass chooses the angle about the can's axis over all 16 video frames. Without
    // the appearance term no image is read, and neither pass runs.
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let o = synth_object(
        &s(&p("clip")),
        "labelcan",
        &[
            "--motion",
            "hard-held",
            "--frames",
            "4",
            "--size",
            "160x120",
            "--seed",
            "5",
            "--between",
            "4",
        ],
    );
    assert!(o.status.success(), "synth: {}", text(&o));
    let track = |out: &str, extra: &[&str]| {
        let (clip, model, truth, out) = (
            s(&p("clip")),
            s(&p("clip/model/scene.rhai")),
            s(&p("clip/model/pose.json")),
            s(&p(out)),
        );
        let mut args = vec![
            "track",
            &clip,
            "--model",
            &model,
            "--scale-from",
            &truth,
            "--out",
            &out,
            "--json",
        ];
        args.extend_from_slice(extra);
        let o = agentstar(&args);
        assert!(o.status.success(), "track {extra:?}: {}", text(&o));
        json_of::<Value>(&o)["log"].to_string()
    };
    let log = track("run/pose.json", &[]);
    assert!(log.contains("over all 16 video frames"), "{log}");
    let log = track("plain/pose.json", &["--no-appearance"]);
    assert!(!log.contains("axis:"), "{log}");
}

#[test]
fn bad_in_between_options_are_refused_with_messages() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    let o = synth_object(
        &s(&p("clip")),
        "box",
        &["--frames", "3", "--size", "64x48", "--between", "60"],
    );
    assert_failed_saying(&o, &["between must be 0 to 59"]);
    let o = synth_object(
        &s(&p("clip")),
        "box",
        &[
            "--frames",
            "3",
            "--size",
            "64x48",
            "--between",
            "2",
            "--no-depth",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    copy_pngs(&p("clip/frames"), &p("frames"));
    copy_pngs(&p("clip/mask_object"), &p("masks"));
    // The frame between the first two keyframes loses its mask: named, nothing written.
    std::fs::remove_file(p("masks/000001.png")).expect("rm");
    let o = from_video(dir.path(), "3", &["--between", "--fov", "60"], "cap");
    assert_failed_saying(&o, &["000001", "in-between"]);
    assert!(!p("cap").exists(), "nothing half-written");
    let o = from_video(dir.path(), "3", &["--between", "0", "--fov", "60"], "cap");
    assert_failed_saying(&o, &["between 0"]);
}

/// `validate --json` of a capture: its keyframe and in-between counts.
fn counts(capture: &Path) -> (Value, Value) {
    let v = json_of::<Value>(&agentstar(&["validate", &s(capture), "--json"]));
    assert_eq!(v["valid"], true, "{v}");
    (v["frames"].clone(), v["between_frames"].clone())
}

/// Tracks `capture` with the true `model` (scale 1) and returns the tracker's log, after
/// checking that every keyframe was scored.
fn track_log(capture: &Path, model: &Path, keyframes: usize) -> String {
    let o = agentstar(&[
        "track",
        &s(capture),
        "--model",
        &s(model),
        "--scale",
        "1",
        "--out",
        &s(&capture.with_extension("pose.json")),
        "--json",
    ]);
    assert!(
        o.status.success(),
        "track {}: {}",
        capture.display(),
        text(&o)
    );
    let report: Value = json_of(&o);
    assert_eq!(
        report["frames"].as_array().map(Vec::len),
        Some(keyframes),
        "{report}"
    );
    report["log"].to_string()
}

#[test]
fn dataset_imports_keep_in_between_frames_that_track_follows() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    // BOP: images 0..6, keyframes every 3rd, every image between them kept.
    datasets::write_bop_scene(&p("bop"), &[0, 1, 2, 3, 4, 5, 6]);
    let o = agentstar(&[
        "capture",
        "from-bop",
        &s(&p("bop/scene")),
        "--models",
        &s(&p("bop/models")),
        "--obj-id",
        "3",
        "--every",
        "3",
        "--between",
        "--out",
        &s(&p("bop-cap")),
    ]);
    assert!(o.status.success(), "from-bop: {}", text(&o));
    assert!(
        text(&o).contains("3 keyframes and 4 in-between frames"),
        "{}",
        text(&o)
    );
    assert_eq!(counts(&p("bop-cap")), (3.into(), 4.into()));
    let log = track_log(&p("bop-cap"), &p("bop-cap/gt_meshes/object.obj"), 3);
    assert_eq!(
        log.matches("followed 2 in-between frame(s)").count(),
        2,
        "{log}"
    );
    // HOT3D: 7 frames, keyframes every 3rd, every 2nd frame between them.
    let (hot3d, _) = datasets::hot3d_sequence(&p("hot3d"), 7);
    let q = hot3d.device_from_camera.rotation;
    let t = hot3d.device_from_camera.translation.vector;
    let device_from_camera = format!("{},{},{},{},{},{},{}", q.w, q.i, q.j, q.k, t.x, t.y, t.z);
    let hot3d_args = |every: &str, between: &str, out: &str| {
        agentstar(&[
            "capture",
            "from-hot3d",
            &s(&hot3d.sequence),
            "--models",
            &s(&hot3d.models),
            "--object-uid",
            "1234",
            "--frames",
            &s(&hot3d.frames),
            "--intrinsics",
            "60,60,32,24",
            "--device-from-camera",
            &device_from_camera,
            "--every",
            every,
            "--between",
            between,
            "--out",
            &s(&p(out)),
        ])
    };
    let o = hot3d_args("3", "2", "hot3d-cap");
    assert!(o.status.success(), "from-hot3d: {}", text(&o));
    assert_eq!(counts(&p("hot3d-cap")), (3.into(), 2.into()));
    let log = track_log(&p("hot3d-cap"), &p("hot3d-cap/gt_meshes/object.obj"), 3);
    assert_eq!(
        log.matches("followed 1 in-between frame(s)").count(),
        2,
        "{log}"
    );
    // A stride that reaches the next keyframe is refused before anything is written.
    let o = hot3d_args("3", "3", "hot3d-bad");
    assert_failed_saying(&o, &["--between 3 with --every 3"]);
    assert!(!p("hot3d-bad").exists());
    // ARCTIC: 8 rows, keyframes every 3rd image, every image between them; tracked with the
    // template as a scene (the lid turning about -Z through the origin).
    let (arctic, _, _, _) = datasets::arctic_sequence(&p("arctic"), 8);
    let o = agentstar(&[
        "capture",
        "from-arctic",
        &s(&arctic.root),
        "--subject",
        "s01",
        "--sequence",
        "box_grab_01",
        "--camera",
        "3",
        "--every",
        "3",
        "--between",
        "--out",
        &s(&p("arctic-cap")),
    ]);
    assert!(o.status.success(), "from-arctic: {}", text(&o));
    assert_eq!(counts(&p("arctic-cap")), (3.into(), 4.into()));
    std::fs::write(
        p("box.rhai"),
        "part(\"bottom\", box(0.1, 0.08, 0.04).translate(0, 0, 0.02));\n\
         part(\"top\", box(0.1, 0.08, 0.01).translate(0, 0, 0.045));\n\
         joint(#{ name: \"articulation\", type: \"revolute\", child: \"top\", origin: [0, 0, 0], axis: [0, 0, -1], limit: [0, 180] });\n",
    )
    .expect("scene");
    let log = track_log(&p("arctic-cap"), &p("box.rhai"), 3);
    assert_eq!(
        log.matches("followed 2 in-between frame(s)").count(),
        2,
        "{log}"
    );
}
