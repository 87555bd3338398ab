//! `agentstar track --from`: a warm start keeps its anchors exactly and repairs a block of
//! frames left flipped end for end.

mod support;

use std::path::Path;
use support::{agentstar, assert_failed_saying, example, on_poses, text, track_known};

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(p).expect("read")).expect("json")
}

fn quaternion(v: &serde_json::Value, frame: &str) -> [f64; 4] {
    let q = v["frames"][frame]["object_pose"]["quaternion"]
        .as_array()
        .expect("quaternion");
    [0, 1, 2, 3].map(|k| q[k].as_f64().expect("number"))
}

/// The angle between two rotations given as unit quaternions, in degrees.
fn angle_deg(a: [f64; 4], b: [f64; 4]) -> f64 {
    let dot: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    2.0 * dot.abs().min(1.0).acos().to_degrees()
}

/// The frame names of a pose file read as JSON, sorted.
fn frame_names(poses: &serde_json::Value) -> Vec<String> {
    let mut names: Vec<String> = poses["frames"]
        .as_object()
        .expect("frames")
        .keys()
        .cloned()
        .collect();
    names.sort();
    names
}

#[test]
fn track_from_keeps_anchors_and_repairs_a_flipped_block() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let tracked = dir.path().join("tracked.json");
    let _: serde_json::Value = track_known(&cap, &model, &poses, &tracked);
    let good = read_json(&tracked);
    let names = frame_names(&good);
    assert_eq!(names.len(), 6);
    // Frames 3 and 4 turned end for end: q · (0, 0, 0, 1), a half turn about the canonical z.
    let mut bad = good.clone();
    for name in &names[3..5] {
        let [w, x, y, z] = quaternion(&good, name);
        bad["frames"][name]["object_pose"]["quaternion"] = serde_json::json!([-z, y, -x, w]);
        assert!(angle_deg(quaternion(&bad, name), [w, x, y, z]) > 179.0);
    }
    let start = dir.path().join("flipped.json");
    std::fs::write(&start, serde_json::to_vec(&bad).expect("json")).expect("write");
    let out = dir.path().join("repaired.json");
    let anchors = format!("{}..{}", names[0], names[2]);
    let o = agentstar(&[
        "track",
        &cap,
        "--model",
        &model,
        "--from",
        start.to_str().expect("utf8"),
        "--anchors",
        &anchors,
        "--out",
        out.to_str().expect("utf8"),
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
    let repaired = read_json(&out);
    // Anchors exactly as given (up to the renormalisation of quaternions on read).
    for name in &names[..3] {
        let moved = angle_deg(quaternion(&repaired, name), quaternion(&bad, name));
        assert!(moved < 1e-4, "anchor {name} turned by {moved}°");
        assert_eq!(
            repaired["frames"][name]["object_pose"]["translation"],
            bad["frames"][name]["object_pose"]["translation"],
            "anchor {name} moved"
        );
    }
    for name in &names[3..5] {
        let a = angle_deg(quaternion(&repaired, name), quaternion(&good, name));
        assert!(
            a < 3.0,
            "{name}: {a:.1}° from the tracked pose\n{}",
            text(&o)
        );
    }
    // Anchors need a warm start to anchor.
    let bad_arg = agentstar(&[
        "track",
        &cap,
        "--model",
        &model,
        "--anchors",
        "000000",
        "--out",
        "x.json",
    ]);
    assert!(!bad_arg.status.success());
}

/// The frames of a pose file and whether each is marked moved.
fn moved_flags(v: &serde_json::Value) -> Vec<(String, bool)> {
    let mut out: Vec<(String, bool)> = v["frames"]
        .as_object()
        .expect("frames")
        .iter()
        .map(|(k, f)| (k.clone(), f["moved"].as_bool().unwrap_or(false)))
        .collect();
    out.sort();
    out
}

/// `track CAP --model MODEL --scale-from POSES --out OUT` (the known model from scratch).
fn track_args<'a>(cap: &'a str, model: &'a str, poses: &'a str, out: &'a Path) -> Vec<&'a str> {
    let out = out.to_str().expect("utf8");
    vec![
        "track",
        cap,
        "--model",
        model,
        "--scale-from",
        poses,
        "--out",
        out,
    ]
}

#[test]
fn a_stopped_track_leaves_its_poses_so_far_and_a_finished_one_removes_them() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let out = dir.path().join("tracked.json");
    let partial = dir.path().join("tracked.partial.json");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_agentstar"))
        .args(track_args(&cap, &model, &poses, &out))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawn");
    // Stopped as soon as it has kept anything (the first frame, before the others).
    let t0 = std::time::Instant::now();
    let (mut finished, mut waited_s) = (false, 0);
    while !partial.exists() {
        if matches!(child.try_wait(), Ok(Some(_)) | Err(_)) {
            finished = true;
            break;
        }
        waited_s = t0.elapsed().as_secs();
        if waited_s >= 300 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    // Stopped (or reaped, if it already ended) on every path.
    let _ = child.kill();
    child.wait().expect("wait");
    assert!(waited_s < 300, "no partial poses after 300 s");
    // The partial file appears after the first frame, seconds before the run ends.
    assert!(
        !finished,
        "the run ended before its partial poses were seen"
    );
    {
        // A complete pose file (written atomically), every frame in it, the tracked ones
        // marked moved; `score` reads it and scores every frame.
        let kept = read_json(&partial);
        let flags = moved_flags(&kept);
        assert_eq!(flags.len(), 6, "{kept}");
        assert!(flags.iter().any(|f| f.1), "no frame tracked: {flags:?}");
        let o = on_poses(
            "score",
            &cap,
            &model,
            partial.to_str().expect("utf8"),
            &["--no-appearance", "--json"],
        );
        // (It exits 1 when frames are under the gate, as the carried ones are.)
        let scored: serde_json::Value =
            serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(&o)));
        assert_eq!(
            scored["frames"].as_array().map(Vec::len),
            Some(6),
            "{scored}"
        );
        assert!(!out.exists(), "the stopped run wrote its final file");
    }
    // A run that finishes writes the pose file and removes the partial one.
    let _: serde_json::Value = track_known(&cap, &model, &poses, &out);
    assert!(out.exists());
    assert!(
        !partial.exists(),
        "the partial file outlived a finished run"
    );
    assert!(moved_flags(&read_json(&out)).iter().all(|f| f.1));
}

#[test]
fn a_track_whose_final_write_fails_keeps_every_tracked_pose() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    // The output path is a directory: the final write fails after the tracking.
    let out = dir.path().join("tracked.json");
    std::fs::create_dir(&out).expect("mkdir");
    let o = agentstar(
        &[
            track_args(&cap, &model, &poses, &out),
            vec!["--evals", "1200"],
        ]
        .concat(),
    );
    assert_failed_saying(&o, &["tracked.json"]);
    let kept = read_json(&dir.path().join("tracked.partial.json"));
    let flags = moved_flags(&kept);
    assert_eq!(flags.len(), 6);
    assert!(flags.iter().all(|f| f.1), "{flags:?}");
}

/// Issue 34 item 2 over MCP: the example's true poses with one frame turned end for end (a
/// half-turn about the canonical z) and every other frame an anchor. The default warm start
/// carries the anchors' poses into it, moving it to the other basin, and names it with the
/// evidence; `keep_basins` polishes it within 45° of the pose it was given.
#[test]
fn track_over_mcp_names_frames_it_moves_to_another_basin_and_keep_basins_keeps_them() {
    use agentstar_reports::TrackReport;
    use serde_json::json;
    use support::McpClient;
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let truth = read_json(Path::new(&poses));
    let scale = truth["scale"].as_f64().expect("scale").to_string();
    let run = dir.path().join("mcp_run");
    let o = agentstar(&[
        "init",
        run.to_str().expect("utf8"),
        "--capture",
        &cap,
        "--scene",
        &model,
        "--scale",
        &scale,
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let names = frame_names(&truth);
    let turned = &names[3];
    let mut bad = truth.clone();
    let [w, x, y, z] = quaternion(&truth, turned);
    bad["frames"][turned]["object_pose"]["quaternion"] = json!([-z, y, -x, w]);
    std::fs::write(
        run.join("turned.json"),
        serde_json::to_vec(&bad).expect("json"),
    )
    .expect("write");
    let given = quaternion(&bad, turned);
    let anchors: Vec<&str> = names
        .iter()
        .filter(|n| *n != turned)
        .map(String::as_str)
        .collect();
    let anchors = anchors.join(",");
    let (mut c, _) = McpClient::initialised(&run);
    // The default: the frame moved back by the carry from its anchors, and named.
    c.call(
        2,
        "track",
        json!({"from": "turned.json", "anchors": anchors}),
    );
    let (resp, _) = c.response(2);
    let body = McpClient::text_of(&resp);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    let r: TrackReport =
        serde_json::from_value(resp["result"]["structuredContent"].clone()).expect("report");
    assert!(!r.keep_basins);
    let moved: Vec<&str> = r.basin_moves.iter().map(|m| m.frame.as_str()).collect();
    assert_eq!(moved, [turned.as_str()], "{body}");
    let m = &r.basin_moves[0];
    assert!(m.rotation_deg > 135.0 && m.bound_deg == 45.0, "{m:?}");
    assert!(m.iou_after > m.iou_before, "{m:?}");
    assert!(!m.pass.is_empty(), "{m:?}");
    assert!(
        body.contains("moved to another basin (1 frame(s)"),
        "{body}"
    );
    assert!(body.contains(&m.line()), "{body}");
    let now = read_json(&run.join("pose.json"));
    assert!(angle_deg(quaternion(&now, turned), given) > 135.0, "{body}");
    // Keeping basins: the frame stays within the bound of the pose it was given.
    c.call(
        3,
        "track",
        json!({"from": "turned.json", "anchors": anchors, "keep_basins": true}),
    );
    let (resp, _) = c.response(3);
    let body = McpClient::text_of(&resp);
    assert_eq!(resp["result"]["isError"], false, "{resp}");
    let r: TrackReport =
        serde_json::from_value(resp["result"]["structuredContent"].clone()).expect("report");
    assert!(r.keep_basins && r.basin_moves.is_empty(), "{body}");
    assert!(body.contains("basins kept"), "{body}");
    let now = read_json(&run.join("pose.json"));
    let kept = angle_deg(quaternion(&now, turned), given);
    assert!(
        kept <= 45.0,
        "{kept:.1}° from the pose it was given\n{body}"
    );
    // Keeping the basins of nothing is a mistake the tool names.
    c.call(4, "track", json!({"keep_basins": true}));
    let (resp, _) = c.response(4);
    assert_eq!(resp["result"]["isError"], true, "{resp}");
    assert!(
        McpClient::text_of(&resp).contains("give `from` too"),
        "{resp}"
    );
}
