//! Importing a video through ffmpeg.

mod support;

use std::path::Path;
use support::{agentstar, json_of, synth_object, text};

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
    let o = synth_object(
        &s(&p("clip")),
        "mug",
        &["--frames", "4", "--size", "160x120", "--seed", "2"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let clip = agentstar_data::capture::Capture::open(&p("clip")).expect("clip");
    // The frames as a lossless video; the masks as a segmenter names them (by the frame's
    // index in the video, its own padding and suffix).
    std::fs::create_dir_all(p("seq")).expect("mkdir");
    std::fs::create_dir_all(p("masks")).expect("mkdir");
    for k in 0..clip.frames.len() {
        std::fs::copy(clip.frame_path(k), p("seq").join(format!("f{k}.png"))).expect("copy");
        std::fs::copy(
            clip.mask_path(k),
            p("masks").join(format!("{k:05}_sam.png")),
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
    let v: serde_json::Value = json_of(&agentstar(&[
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
    ]));
    assert_eq!(v["frames"], 4);
    // A video's frames are named by their index in it: nothing was assumed.
    assert_eq!(v["notes"], serde_json::json!([]), "{v}");
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
