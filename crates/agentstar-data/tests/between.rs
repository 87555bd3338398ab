//! In-between frames (`formats.md` §2): a capture whose `keyframes` key names the frames that
//! are tracked, scored and shown; the others are read, validated and kept apart.

mod common;

use agentstar_data::capture::Capture;
use agentstar_data::capture_writer::{write_capture, CaptureInfo, FrameOut};
use agentstar_data::posefile::{FrameEntry, PoseFile, PoseJson};
use agentstar_geom::pose::Rigid;
use agentstar_geom::{KinematicTree, PinholeCamera};
use agentstar_mask::BitMask;
use common::problems;
use image::RgbImage;
use std::path::Path;

const W: u32 = 40;
const H: u32 = 30;

/// Seven frames 0..=60 (stems 10 apart); keyframes 0, 30 and 60 unless `keyframes` says.
fn video(dir: &Path, keyframes: Option<Vec<String>>) {
    let camera = PinholeCamera::new(50.0, 50.0, 20.0, 15.0, W, H).expect("camera");
    let rigid = Rigid::identity();
    let rgb = RgbImage::from_pixel(W, H, image::Rgb([90, 90, 90]));
    let mask = BitMask::from_fn(W, H, |x, _| x < 20);
    let names: Vec<String> = (0..7).map(|k| format!("{:06}.png", 10 * k)).collect();
    let frames: Vec<FrameOut<'_>> = names
        .iter()
        .enumerate()
        .map(|(k, name)| FrameOut {
            name,
            frame_index: Some(10 * k as i64),
            time_s: Some(10.0 * k as f64 / 30.0),
            camera: &camera,
            world_from_camera: &rigid,
            rgb: &rgb,
            mask: &mask,
            hand: None,
            depth_m: None,
        })
        .collect();
    let info = CaptureInfo {
        keyframes,
        ..CaptureInfo::default()
    };
    write_capture(dir, &frames, &info, |_| Ok(())).expect("write");
}

fn names(frames: &[agentstar_data::capture::Frame]) -> Vec<&str> {
    frames.iter().map(|f| f.name.as_str()).collect()
}

fn manifest_edit(dir: &Path, edit: impl Fn(&mut serde_json::Value)) {
    let path = dir.join("capture.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("read")).expect("json");
    edit(&mut v);
    std::fs::write(&path, v.to_string()).expect("write");
}

#[test]
fn keyframes_are_what_tools_index_and_in_between_frames_are_kept_apart() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("cap");
    let keys = vec![
        "000000.png".to_string(),
        "000030".into(),
        "000060.png".into(),
    ];
    video(&dir, Some(keys));
    assert_eq!(problems(&dir), "");
    let c = Capture::open(&dir).expect("open");
    assert_eq!(names(&c.frames), ["000000.png", "000030.png", "000060.png"]);
    assert_eq!(
        names(&c.between),
        ["000010.png", "000020.png", "000040.png", "000050.png"]
    );
    assert_eq!(c.frames[c.ref_index].name, "000000.png");
    let gap: Vec<&str> = c
        .between_keyframes(1)
        .iter()
        .map(|f| f.name.as_str())
        .collect();
    assert_eq!(gap, ["000040.png", "000050.png"]);
    assert!(c.between_keyframes(2).is_empty());
    let order: Vec<(u64, Option<usize>)> = c
        .video()
        .iter()
        .map(|v| (v.frame.number, v.keyframe))
        .collect();
    assert_eq!(
        order,
        [
            (0, Some(0)),
            (10, None),
            (20, None),
            (30, Some(1)),
            (40, None),
            (50, None),
            (60, Some(2))
        ]
    );
    // Keyframe selection never reaches an in-between frame.
    // Named anyway, the refusal says what it is and the keyframes it lies between.
    for named in ["000010", "000010.png", "10", "000000..000040"] {
        let err = c.select(Some(named)).expect_err(named).to_string();
        assert!(
            err.contains("in-between frame") && err.contains("000000.png and 000030.png")
                || err.contains("between keyframes 000030.png and 000060.png"),
            "{named}: {err}"
        );
        assert!(err.contains("3 keyframes and 4 in-between frames"), "{err}");
    }
    // A frame the capture does not have at all is still refused with the keyframes listed.
    let err = c.select(Some("000070")).expect_err("none").to_string();
    assert!(
        err.contains("unknown frame `000070`") && err.contains("000060.png"),
        "{err}"
    );
    assert_eq!(c.select(None).expect("all"), [0, 1, 2]);
    assert!(c.between_note().expect("note").contains("4 in-between"));
    // The same frames without the key: every frame a keyframe, as before.
    let plain = tmp.path().join("plain");
    video(&plain, None);
    let p = Capture::open(&plain).expect("open");
    assert_eq!(p.frames.len(), 7);
    assert!(p.between.is_empty() && p.between_note().is_none());
    let text = std::fs::read_to_string(plain.join("capture.json")).expect("read");
    assert!(!text.contains("keyframes"), "{text}");
}

#[test]
fn bad_keyframe_lists_and_missing_in_between_files_are_named() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("cap");
    video(&dir, Some(vec!["000000.png".into(), "000060.png".into()]));
    manifest_edit(&dir, |v| {
        v["keyframes"] = serde_json::json!(["000000.png", "000070.png"])
    });
    let p = problems(&dir);
    assert!(
        p.contains("capture.json") && p.contains("`000070.png`"),
        "{p}"
    );
    manifest_edit(&dir, |v| {
        v["keyframes"] = serde_json::json!(["000000.png", "000000"])
    });
    assert!(problems(&dir).contains("twice"), "{}", problems(&dir));
    manifest_edit(&dir, |v| v["keyframes"] = serde_json::json!([]));
    assert!(problems(&dir).contains("`keyframes` is empty"));
    manifest_edit(&dir, |v| {
        v["keyframes"] = serde_json::json!(["000000.png", "000060.png"]);
        v["ref_frame"] = serde_json::json!("000020.png");
    });
    let p = problems(&dir);
    assert!(
        p.contains("ref_frame `000020.png` is an in-between frame"),
        "{p}"
    );
    manifest_edit(&dir, |v| v["ref_frame"] = serde_json::json!("000060.png"));
    assert_eq!(problems(&dir), "");
    // An in-between frame needs what a keyframe needs: its mask, named.
    std::fs::remove_file(dir.join("mask_object/000020.png")).expect("rm");
    let p = problems(&dir);
    assert!(p.contains("mask_object/000020.png"), "{p}");
    // ... and an in-between frame's mask may be empty (a hand over it), a keyframe's not.
    let empty = BitMask::new(W, H);
    agentstar_data::images::save_png_gray(
        &agentstar_data::images::mask_to_gray(&empty),
        &dir.join("mask_object/000020.png"),
    )
    .expect("save");
    assert_eq!(problems(&dir), "");
    std::fs::copy(
        dir.join("mask_object/000020.png"),
        dir.join("mask_object/000060.png"),
    )
    .expect("copy");
    let p = problems(&dir);
    assert!(p.contains("000060.png: the object mask is empty"), "{p}");
}

#[test]
fn pose_files_may_carry_in_between_poses_which_are_never_keyframes() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path().join("cap");
    video(
        &dir,
        Some(vec![
            "000000.png".into(),
            "000030.png".into(),
            "000060.png".into(),
        ]),
    );
    let c = Capture::open(&dir).expect("open");
    let tree = KinematicTree::new(vec![], &["body".to_string()]).expect("tree");
    let start = agentstar_geom::pose::ObjectPose::new(
        agentstar_geom::UnitQuaternion::identity(),
        agentstar_geom::Vector3::new(0.0, 0.0, 1.0),
    );
    let mut pf = PoseFile::initial(&c, &tree, 0.2, &start);
    let shifted = PoseJson {
        quaternion: [1.0, 0.0, 0.0, 0.0],
        translation: [0.5, 0.0, 1.0],
        scale: None,
    };
    pf.frames.insert(
        "000010.png".into(),
        FrameEntry {
            object_pose: Some(shifted.clone()),
            between: true,
            ..FrameEntry::default()
        },
    );
    let resolved = pf.resolve(&c, &tree).expect("resolves");
    assert_eq!(resolved.len(), 3, "keyframes only");
    assert!(resolved
        .iter()
        .all(|p| p.generalised.pose.translation.x == 0.0));
    // Written again for the keyframes, the stale in-between poses go.
    let poses = resolved.clone();
    pf.set_frames(&c, &tree, &poses);
    assert!(!pf.frames.contains_key("000010.png"));
    // A keyframe marked `between` is an error naming it.
    pf.frames.insert(
        "000030.png".into(),
        FrameEntry {
            object_pose: Some(shifted),
            between: true,
            ..FrameEntry::default()
        },
    );
    let e = pf.resolve(&c, &tree).expect_err("keyframe marked between");
    assert!(e.contains("000030.png") && e.contains("between"), "{e}");
}
