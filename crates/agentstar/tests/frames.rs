//! The one frame grammar (`Capture::select`) as every command takes it: names, stems, frame
//! numbers, ranges, `all`; unknown frames and empty selections are errors that list the
//! frames.

mod support;

use agentstar_reports::ScoreReport;
use support::{on_poses, s, small_run, small_run_at_truth, text};

#[test]
fn frames_are_selected_by_names_stems_numbers_and_ranges() {
    let dir = tempfile::tempdir().expect("tmp");
    small_run(dir.path(), 3, true);
    let (cap, run) = (dir.path().join("cap"), dir.path().join("run"));
    let score = |spec: &str| {
        on_poses(
            "score",
            &s(&cap),
            &s(&run.join("scene.rhai")),
            &s(&run.join("pose.json")),
            &["--frames", spec, "--json"],
        )
    };
    let names = |spec: &str| -> Vec<String> {
        let o = score(spec);
        // `score` exits 1 when a frame is under the gate; its report is printed either way.
        assert!(
            o.status.code().is_some_and(|c| c <= 1),
            "{spec}: {}",
            text(&o)
        );
        let r: ScoreReport = serde_json::from_slice(&o.stdout).expect("score report");
        // The appearance figure stands beside each selected frame's IoU, in the same order.
        let beside: Vec<&str> = r.appearance.iter().map(|a| a.frame.as_str()).collect();
        let framed: Vec<&str> = r.frames.iter().map(|f| f.frame.as_str()).collect();
        assert_eq!(beside, framed, "{spec}");
        r.frames.into_iter().map(|f| f.frame).collect()
    };
    let all = ["000000.png", "000005.png", "000010.png"];
    assert_eq!(names("all"), all);
    assert_eq!(names("000000..000010"), all);
    // Reversed ranges, names and numbers; temporal order, no repeats.
    assert_eq!(names("000010.png..0"), all);
    assert_eq!(names("5"), ["000005.png"]);
    assert_eq!(names("000010, 000000.png, 0"), ["000000.png", "000010.png"]);
    for bad in ["000000..nope", "000003", ","] {
        let o = score(bad);
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", text(&o));
        assert!(
            text(&o).contains("000000.png") || text(&o).contains("names no frame"),
            "{bad}: {}",
            text(&o)
        );
    }
}

/// The directory a view tool's reply names ("… in DIR; …").
fn reply_dir(body: &str) -> std::path::PathBuf {
    let after = body
        .split(" in ")
        .nth(1)
        .unwrap_or_else(|| panic!("{body}"));
    std::path::PathBuf::from(after.split(';').next().expect("dir").trim())
}

/// `render` and `frames` take one crop and zoom (issue 34 item 4): a box of frame pixels
/// shown at ×4 is exactly those pixels of the whole view, every view and sheet takes it,
/// `frames` puts the model in its colours beside the crop, and `render` and `score` say
/// which side of the model faces the camera.
#[test]
fn render_and_frames_zoom_into_a_box_and_say_which_side_faces_the_camera() {
    use serde_json::json;
    use support::McpClient;
    let dir = tempfile::tempdir().expect("tmp");
    let run = small_run_at_truth(dir.path(), 3);
    let (mut c, _) = McpClient::initialised(&run);
    let call = |c: &mut McpClient, id: u64, tool: &str, args: serde_json::Value| {
        c.call(id, tool, args);
        let (resp, _) = c.response(id);
        (resp["result"]["isError"] == true, McpClient::text_of(&resp))
    };
    let (err, whole) = call(
        &mut c,
        2,
        "render",
        json!({"frames": "000000", "views": "overlay"}),
    );
    assert!(!err, "{whole}");
    let full = image::open(reply_dir(&whole).join("overlay_000000.png"))
        .expect("overlay")
        .to_rgb8();
    assert_eq!(full.dimensions(), (160, 120));
    assert!(
        whole.contains("000000.png: ") && whole.contains("toward the camera ("),
        "{whole}"
    );
    let (err, body) = call(
        &mut c,
        3,
        "render",
        json!({"frames": "000000", "views": "overlay,compare,ids", "zoom": 4.0, "crop": "40,30,60,45"}),
    );
    assert!(!err, "{body}");
    assert!(
        body.contains("crop at (40, 30), 20×15 frame pixels, zoom 4.00"),
        "{body}"
    );
    let out = reply_dir(&body);
    let zoomed = image::open(out.join("overlay_000000.png"))
        .expect("overlay")
        .to_rgb8();
    assert_eq!(zoomed.dimensions(), (80, 60));
    for y in 0..60 {
        for x in 0..80 {
            assert_eq!(
                zoomed.get_pixel(x, y),
                full.get_pixel(40 + x / 4, 30 + y / 4),
                "({x}, {y})"
            );
        }
    }
    // The sheets show the box too: its 20 px at ×8 (the most a tile enlarges), where the
    // crop around the mask fills a tile's 400 px.
    let sheet = image::open(out.join("sheet_compare.png")).expect("sheet");
    let tile = 20 * agentstar_render::frames::MAX_ZOOM as u32;
    assert!(
        sheet.width() >= tile && sheet.width() < tile + 60,
        "{}×{}",
        sheet.width(),
        sheet.height()
    );
    // `frames` with the model beside the crop, at the same crop and zoom.
    let (err, body) = call(
        &mut c,
        4,
        "frames",
        json!({"frames": "000000", "crop": "40,30,60,45", "zoom": 4.0, "model": true}),
    );
    assert!(!err, "{body}");
    assert!(
        body.contains("crop at (40, 30), 20×15 frame pixels, zoom 4.00")
            && body.contains("pixel (u, v) is frame pixel (x + u / zoom, y + v / zoom)"),
        "{body}"
    );
    let side = image::open(reply_dir(&body).join("side_000000.png"))
        .expect("side")
        .to_rgb8();
    let gap = agentstar_render::views::SIDE_GAP_PX;
    assert_eq!(side.dimensions(), (80 + gap + 80, 60));
    // The right half is the model in its colours: not the white background everywhere.
    let model_px = (0..60)
        .flat_map(|y| (80 + gap..160 + gap).map(move |x| (x, y)))
        .filter(|&(x, y)| side.get_pixel(x, y).0 != [255, 255, 255])
        .count();
    assert!(model_px > 200, "{model_px}");
    // A box outside the frame is refused, naming the frame's size.
    let (err, body) = call(
        &mut c,
        5,
        "render",
        json!({"frames": "000000", "crop": "500,500,600,600"}),
    );
    assert!(err && body.contains("160×120"), "{body}");
    // `score` names the side toward the camera per keyframe, with angles.
    let (err, body) = call(&mut c, 6, "score", json!({}));
    let _ = err;
    assert!(body.contains("side toward the camera"), "{body}");
    for f in ["000000.png", "000005.png", "000010.png"] {
        assert!(
            body.lines()
                .any(|l| l.trim_start().starts_with(&format!("{f}: "))
                    && l.contains("toward the camera")
                    && l.contains("° off the ray")
                    && l.contains("px in view)")),
            "{f}: {body}"
        );
    }
}
