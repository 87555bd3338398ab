//! The run report: self-contained, rendering in headless Chromium, and the README's
//! walk-through from frames and masks to a report.

#[path = "../../agentstar-report/tests/browser/mod.rs"]
mod browser;
mod support;

use browser::{chromium, run_chromium, view_pixels, viewer_dom};
use std::path::Path;
use support::{agentstar, json_of, on_poses, synth_box, text};

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
    // Each keyframe says which side of the model faces the camera.
    assert_eq!(
        html.matches("toward the camera (").count(),
        4,
        "no facing line"
    );
    assert!(html.contains("Agent steps") && html.contains("evaluated against the ground truth"));
    assert!(html.contains("data:image/jpeg;base64,"));
    // The report command itself, with a ledger whose last line a crash cut short.
    let ledger = run.join("ledger.jsonl");
    let mut l = std::fs::read_to_string(&ledger).expect("ledger");
    l.push_str("{\"step\": 99, \"ti");
    std::fs::write(&ledger, l).expect("write");
    let page2 = dir.path().join("again.html");
    let v: serde_json::Value = json_of(&agentstar(&[
        "report",
        run.to_str().expect("utf8"),
        "--out",
        page2.to_str().expect("utf8"),
        "--json",
    ]));
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
    let dom = viewer_dom(&bin, &page);
    for view in ["data-cam-pixels", "data-orbit-pixels"] {
        let px = view_pixels(&dom, view);
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
    let o = on_poses(
        "export",
        &s(&p("cap")),
        &s(&p("run/scene.rhai")),
        &s(&p("run/pose.json")),
        &["--animated-glb", &s(&p("run/motion.glb"))],
    );
    assert!(o.status.success(), "{}", text(&o));
}
