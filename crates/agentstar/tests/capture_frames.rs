//! `capture from-video` on folders of frames: frames keep their numbers and times, masks are
//! matched by file stem only, and out-of-range options are refused before anything is
//! written.

mod support;

use agentstar_data::capture::Capture;
use std::path::Path;
use support::{agentstar, s, text};

const W: u32 = 32;
const H: u32 = 24;

/// A frame whose colour encodes `n`.
fn frame(path: &Path, n: u32) {
    image::RgbImage::from_pixel(W, H, image::Rgb([(n % 256) as u8, 100, 200]))
        .save(path)
        .expect("frame");
}

/// A mask whose object is `n % 20 + 1` pixels wide, so that each frame's mask is told apart.
fn mask(path: &Path, n: u32) {
    image::GrayImage::from_fn(W, H, |x, y| {
        image::Luma([if x <= n % 20 && y < 10 { 255 } else { 0 }])
    })
    .save(path)
    .expect("mask");
}

/// The width of a capture mask's object (what `mask` encoded).
fn mask_code(cap: &Capture, i: usize) -> usize {
    (cap.load_mask(i).expect("mask").count() / 10) as usize
}

fn from_video(frames: &Path, masks: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "capture".to_string(),
        "from-video".into(),
        s(frames),
        "--masks".into(),
        s(masks),
        "--fov".into(),
        "60".into(),
        "--out".into(),
        s(out),
    ];
    args.extend(extra.iter().map(|a| a.to_string()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    agentstar(&args)
}

/// Keyframes named by their video frame (000000.jpg, 000010.jpg, … at 30 fps) keep their
/// names, frame indices and times; `--every 2` takes every 2nd file present and says so.
#[test]
fn a_frame_folder_named_by_video_frame_keeps_its_numbers_and_times() {
    let dir = tempfile::tempdir().expect("tmp");
    let (frames, masks) = (dir.path().join("frames"), dir.path().join("masks"));
    std::fs::create_dir_all(&frames).expect("mkdir");
    std::fs::create_dir_all(&masks).expect("mkdir");
    for n in (0..200).step_by(10) {
        frame(&frames.join(format!("{n:06}.jpg")), n);
        // A segmenter's padding and suffix: matched by number.
        mask(&masks.join(format!("{n:05}_mask.png")), n / 10);
    }
    let out = dir.path().join("cap");
    let o = from_video(&frames, &masks, &out, &["--fps", "30"]);
    assert!(o.status.success(), "{}", text(&o));
    let cap = Capture::open(&out).expect("capture");
    assert_eq!(cap.frames.len(), 20);
    for (k, f) in cap.frames.iter().enumerate() {
        let n = 10 * k as u64;
        assert_eq!(f.name, format!("{n:06}.png"));
        assert_eq!(f.number, n);
        let t = f.time_s.expect("time");
        assert!((t - n as f64 / 30.0).abs() < 1e-9, "{}: {t}", f.name);
        assert_eq!(mask_code(&cap, k), k % 20 + 1, "{}", f.name);
    }
    let kf: Vec<agentstar_data::capture::Keyframe> = serde_json::from_str(
        &std::fs::read_to_string(out.join("tracking/keyframes.json")).expect("keyframes"),
    )
    .expect("keyframes json");
    assert_eq!(kf[3].frame_index, Some(30));
    assert_eq!(kf[3].frame_name, "000030.png");
    // Keyframes 333 ms apart, as filmed: validate finds nothing odd about the times.
    let v = agentstar(&["validate", &s(&out), "--json"]);
    assert!(v.status.success(), "{}", text(&v));
    let r: serde_json::Value = serde_json::from_slice(&v.stdout).expect("json");
    assert_eq!(r["warnings"], serde_json::json!([]), "{r}");
    // Every 2nd frame present: 0, 20, 40, …, with a note that numbers are skipped.
    let out2 = dir.path().join("cap2");
    let o = from_video(&frames, &masks, &out2, &["--every", "2"]);
    assert!(o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--every 2") && err.contains("0, 20, 40"),
        "{err}"
    );
    let cap2 = Capture::open(&out2).expect("capture");
    let names: Vec<&str> = cap2.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names.len(), 10);
    assert_eq!(&names[..3], ["000000.png", "000020.png", "000040.png"]);
    assert!((cap2.frames[1].time_s.expect("time") - 20.0 / 30.0).abs() < 1e-9);
}

/// Names that are not integers are numbered 0, 1, 2, … in natural order, with a note on
/// stderr and in capture.json.
#[test]
fn frames_with_names_that_are_not_integers_are_numbered_in_order_with_a_note() {
    let dir = tempfile::tempdir().expect("tmp");
    let (frames, masks) = (dir.path().join("frames"), dir.path().join("masks"));
    std::fs::create_dir_all(&frames).expect("mkdir");
    std::fs::create_dir_all(&masks).expect("mkdir");
    for (k, name) in ["shot_2", "shot_10", "shot_11"].iter().enumerate() {
        frame(&frames.join(format!("{name}.png")), k as u32);
        mask(&masks.join(format!("{name}.png")), k as u32);
    }
    let out = dir.path().join("cap");
    let o = from_video(&frames, &masks, &out, &["--fps", "10", "--json"]);
    assert!(o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("not all integers") && err.contains("numbered 0 to 2"),
        "{err}"
    );
    let cap = Capture::open(&out).expect("capture");
    let names: Vec<&str> = cap.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["000000.png", "000001.png", "000002.png"]);
    for (k, f) in cap.frames.iter().enumerate() {
        assert!((f.time_s.expect("time") - k as f64 / 10.0).abs() < 1e-9);
        // Natural order: shot_2 before shot_10; each with its own mask.
        assert_eq!(mask_code(&cap, k), k + 1);
    }
    let source = cap.manifest.source.as_ref().expect("source");
    assert!(
        source["frame_numbers"]
            .as_str()
            .is_some_and(|n| n.starts_with("assumed") && n.contains("shot_2")),
        "{source}"
    );
    assert_eq!(source["fps"], 10.0);
}

/// Masks named one frame later than the frames used to be matched half by name and half by
/// order (two frames got one mask, exit 0); now the frame without its own mask is named with
/// the mask folder, and nothing is written. The same for hand masks.
#[test]
fn masks_are_matched_by_stem_only_and_a_frame_without_its_own_mask_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = |n: &str| dir.path().join(n);
    for d in [
        "frames",
        "late",
        "masks",
        "hands_late",
        "hands_some",
        "twice",
    ] {
        std::fs::create_dir_all(p(d)).expect("mkdir");
    }
    for n in 0..4u32 {
        frame(&p("frames").join(format!("{n:06}.png")), n);
        mask(&p("late").join(format!("{:06}.png", n + 1)), n + 1);
        mask(&p("masks").join(format!("{n:06}.png")), n);
        mask(&p("hands_late").join(format!("{:06}.png", n + 1)), n + 1);
        mask(&p("twice").join(format!("{n:06}.png")), n);
    }
    let o = from_video(&p("frames"), &p("late"), &p("cap"), &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let t = text(&o);
    assert!(
        t.contains("no mask for frame") && t.contains("000000.png") && t.contains(&s(&p("late"))),
        "{t}"
    );
    assert!(!p("cap").exists());
    // Two masks for one frame are named, not chosen between.
    mask(&p("twice").join("2.png"), 9);
    let o = from_video(&p("frames"), &p("twice"), &p("cap"), &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("2 masks") && text(&o).contains("000002.png"),
        "{}",
        text(&o)
    );
    assert!(!p("cap").exists());
    // Hand masks one frame later: the names do not line up.
    let hands = s(&p("hands_late"));
    let o = from_video(&p("frames"), &p("masks"), &p("cap"), &["--hands", &hands]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("000000.png") && text(&o).contains(&hands),
        "{}",
        text(&o)
    );
    assert!(!p("cap").exists());
    // Hand masks for some frames only: the others show no hands, and a note says which.
    mask(&p("hands_some").join("000001_hand.png"), 7);
    let some = s(&p("hands_some"));
    let o = from_video(&p("frames"), &p("masks"), &p("cap"), &["--hands", &some]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("3 of the 4 frames have no hand mask"),
        "{}",
        text(&o)
    );
    let cap = Capture::open(&p("cap")).expect("capture");
    assert!(!cap.hand_path(0).exists());
    assert_eq!(
        cap.load_mask(0).expect("mask").count(),
        10,
        "frame 0 keeps its own mask"
    );
    assert!(cap.hand_path(1).exists());
}

/// `--fps` 0, NaN, inf, 1e-300 and `--every 0` are refused with the option and the value
/// named, and nothing is written.
#[test]
fn out_of_range_fps_and_every_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().expect("tmp");
    let (frames, masks) = (dir.path().join("frames"), dir.path().join("masks"));
    std::fs::create_dir_all(&frames).expect("mkdir");
    std::fs::create_dir_all(&masks).expect("mkdir");
    for n in 0..2u32 {
        frame(&frames.join(format!("{n:06}.png")), n);
        mask(&masks.join(format!("{n:06}.png")), n);
    }
    let out = dir.path().join("cap");
    for (option, value) in [
        ("--fps", "0"),
        ("--fps", "NaN"),
        ("--fps", "inf"),
        ("--fps", "-30"),
        ("--fps", "1e-300"),
        ("--fps", "1001"),
        ("--every", "0"),
        ("--max-frames", "0"),
    ] {
        let o = from_video(&frames, &masks, &out, &[option, value]);
        assert_eq!(o.status.code(), Some(2), "{option} {value}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr).to_lowercase();
        assert!(
            err.contains(&format!("{option} {}", value.to_lowercase())),
            "{option} {value}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{option} {value} wrote {}", out.display());
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .expect("ls")
            .map(|e| e.expect("entry").file_name())
            .filter(|n| n != "frames" && n != "masks")
            .collect();
        assert!(leftovers.is_empty(), "{option} {value}: {leftovers:?}");
    }
    // The edges of the range are accepted.
    let o = from_video(&frames, &masks, &out, &["--fps", "1000"]);
    assert!(o.status.success(), "{}", text(&o));
    let cap = Capture::open(&out).expect("capture");
    assert!((cap.frames[1].time_s.expect("time") - 0.001).abs() < 1e-12);
}

/// `validate` warns when the times do not fit the frame numbers: keyframes whose names skip
/// ten frames but whose times are one video frame apart (what `from-video` used to write),
/// and times that disagree with the fps the capture states.
#[test]
fn validate_warns_when_times_do_not_fit_the_frame_numbers() {
    let dir = tempfile::tempdir().expect("tmp");
    let (frames, masks) = (dir.path().join("frames"), dir.path().join("masks"));
    std::fs::create_dir_all(&frames).expect("mkdir");
    std::fs::create_dir_all(&masks).expect("mkdir");
    for n in (0..40).step_by(10) {
        frame(&frames.join(format!("{n:06}.png")), n);
        mask(&masks.join(format!("{n:06}.png")), n);
    }
    let out = dir.path().join("cap");
    let o = from_video(&frames, &masks, &out, &["--fps", "30"]);
    assert!(o.status.success(), "{}", text(&o));
    let kf_path = out.join("tracking/keyframes.json");
    let mut kf: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&kf_path).expect("read")).expect("json");
    for (k, row) in kf.iter_mut().enumerate() {
        row["time_s"] = serde_json::json!(k as f64 / 30.0);
    }
    let warned = |label: &str| -> String {
        let v = agentstar(&["validate", &s(&out)]);
        // Warnings do not make a capture invalid.
        assert!(v.status.success(), "{label}: {}", text(&v));
        let t = text(&v);
        assert!(t.contains("warning:"), "{label}: {t}");
        t
    };
    std::fs::write(&kf_path, serde_json::to_string(&kf).expect("json")).expect("write");
    let t = warned("stated fps");
    assert!(t.contains("000010.png") && t.contains("30 fps"), "{t}");
    // Without a stated fps, the one-frame steps between names ten apart still stand out.
    let cj = out.join("capture.json");
    let mut manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cj).expect("read")).expect("json");
    manifest["source"]
        .as_object_mut()
        .expect("source")
        .remove("fps");
    std::fs::write(&cj, manifest.to_string()).expect("write");
    let t = warned("no stated fps");
    assert!(
        t.contains("000010.png") && t.contains("one video frame"),
        "{t}"
    );
    let v = agentstar(&["validate", &s(&out), "--json"]);
    let r: serde_json::Value = serde_json::from_slice(&v.stdout).expect("json");
    assert!(
        r["warnings"].as_array().is_some_and(|w| !w.is_empty()),
        "{r}"
    );
}
