//! `agentstar track --from`: a warm start keeps its anchors exactly and repairs a block of
//! frames left flipped end for end.

mod support;

use std::path::Path;
use support::{agentstar, example, text, track_known};

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

#[test]
fn track_from_keeps_anchors_and_repairs_a_flipped_block() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let tracked = dir.path().join("tracked.json");
    let _: serde_json::Value = track_known(&cap, &model, &poses, &tracked);
    let good = read_json(&tracked);
    let mut names: Vec<String> = good["frames"]
        .as_object()
        .expect("frames")
        .keys()
        .cloned()
        .collect();
    names.sort();
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
