//! The from-video options and frame names, mutated: `--fps`, `--every`, `--max-frames` as a
//! user types them (`NaN`, `1e-300`, `0`, huge or negative numbers) and frame file names
//! (integers, clashes such as `00120`/`120`, numbers past the limit, other names). The
//! options check, the frame numbering, the keyframe choice and its notes answer every input
//! with a value or an error naming it, never a panic or a hang.

#[path = "../../../fuzz/harness.rs"]
mod harness;

use agentstar_import::video::{check_options, CameraSource, FrameFiles, VideoImport};
use std::path::{Path, PathBuf};

/// `key=value` lines set the options; every other line is a frame's file name.
fn run(b: &[u8]) {
    let text = String::from_utf8_lossy(b);
    let mut cfg = VideoImport {
        input: PathBuf::from("frames"),
        masks: PathBuf::from("masks"),
        hands: None,
        every: 1,
        max_frames: None,
        cameras: CameraSource::Fov(60.0),
        fps: None,
        between: None,
    };
    let mut names = vec![];
    for line in text.lines() {
        match line.split_once('=') {
            Some(("fps", v)) => cfg.fps = v.trim().parse().ok(),
            Some(("every", v)) => cfg.every = v.trim().parse().unwrap_or(0),
            Some(("max", v)) => cfg.max_frames = v.trim().parse().ok(),
            Some(("between", v)) => cfg.between = v.trim().parse().ok(),
            _ if !line.is_empty() && !line.contains('/') => names.push(PathBuf::from(line)),
            _ => {}
        }
    }
    if check_options(&cfg).is_err() {
        return;
    }
    if let Ok(frames) = FrameFiles::numbered(Path::new("frames"), names) {
        let kept = frames.keyframe_indices(cfg.every, cfg.max_frames);
        assert!(kept.iter().all(|&i| i < frames.paths.len()));
        if let Some(stride) = cfg.between {
            let between = FrameFiles::between_indices(&kept, stride);
            assert!(between
                .iter()
                .all(|i| !kept.contains(i) && *i < frames.paths.len()));
            assert!(between.windows(2).all(|w| w[0] < w[1]));
        }
        let _ = frames.notes(cfg.every);
    }
}

#[test]
fn video_options_and_frame_names_never_panic() {
    harness::fuzz(vec![("video_options", Box::new(run) as harness::Run)], 6);
}
