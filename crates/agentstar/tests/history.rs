//! History that connects, end to end: every writer of `pose.json` is a version with its
//! command (the tracker included), a version restores whole or for some frames, `pose
//! commit` takes a report, a pose file or a history version, one frame's pose and score
//! can be followed across versions; `finish` with categorised reasons and a share of
//! keyframes under the gate; two MCP servers on one run never give a scene version twice.

mod support;

use agentstar_data::posefile::PoseFile;
use agentstar_reports::{
    CommitReport, FrameHistoryReport, HistoryReport, RestoreReport, SearchReport, TrackReport,
};
use serde_json::json;
use std::collections::BTreeSet;
use std::path::Path;
use support::{
    agentstar, assert_failed_saying, json_of, ledger, on_poses, s, small_run, text, McpClient,
};

fn translation(pf: &PoseFile, frame: &str) -> [f64; 3] {
    pf.frames[frame]
        .object_pose
        .as_ref()
        .expect("a pose")
        .translation
}

fn quaternion(pf: &PoseFile, frame: &str) -> [f64; 4] {
    pf.frames[frame]
        .object_pose
        .as_ref()
        .expect("a pose")
        .quaternion
}

#[test]
fn a_track_is_a_version_and_frames_restore_commit_and_follow_across_versions() {
    let dir = tempfile::tempdir().expect("tmp");
    small_run(dir.path(), 4, true);
    let (cap, run) = (dir.path().join("cap"), dir.path().join("run"));
    let (model, poses) = (s(&run.join("scene.rhai")), s(&run.join("pose.json")));
    let cap_dir = s(&cap);
    // The tracker, warm-started from the true poses, writes the run's pose.json: version 1
    // after the file init made (version 0), with its command.
    // `track CAP --model MODEL --from FROM --out OUT ARGS… --json`.
    let track_from = |from: &str, out: &str, args: &[&str]| {
        let mut all = vec![
            "track", &cap_dir, "--model", &model, "--from", from, "--out", out,
        ];
        all.extend_from_slice(args);
        all.push("--json");
        agentstar(&all)
    };
    let o = track_from(
        &s(&cap.join("model/pose.json")),
        &poses,
        &["--evals", "300"],
    );
    let tracked: TrackReport = json_of(&o);
    assert_eq!(tracked.pose_version, Some(1), "{}", text(&o));
    let h: HistoryReport = json_of(&agentstar(&[
        "pose", "history", "--poses", &poses, "--json",
    ]));
    assert_eq!(h.total, 2);
    assert!(h.versions[0].command.starts_with("initial version"));
    assert!(
        h.versions[1].command.starts_with("agentstar track ")
            && h.versions[1].command.contains("--from"),
        "{:?}",
        h.versions[1]
    );
    let v1 = PoseFile::read(Path::new(&poses)).expect("v1");

    // One rotation for every frame, committed: version 2, every frame moved.
    let out = s(&run.join("images/rot"));
    let o = on_poses(
        "oapply-all",
        &s(&cap),
        &model,
        &poses,
        &["--out", &out, "--rotation", "rz:40", "--json"],
    );
    let rotated: SearchReport = json_of(&o);
    assert_eq!(rotated.frames.len(), 4);
    let report = s(&run.join("images/rot/oapply_all.json"));
    let c: CommitReport = json_of(&agentstar(&[
        "pose", "commit", "--poses", &poses, "--report", &report, "--json",
    ]));
    assert_eq!((c.version, c.committed.len()), (2, 4));
    let v2 = PoseFile::read(Path::new(&poses)).expect("v2");
    assert_ne!(quaternion(&v2, "000005.png"), quaternion(&v1, "000005.png"));

    // `pose restore --poses POSES --version 1 --frames FRAMES --json`, its report.
    let restore_from_1 = |frames: &str| -> RestoreReport {
        json_of(&agentstar(&[
            "pose",
            "restore",
            "--poses",
            &poses,
            "--version",
            "1",
            "--frames",
            frames,
            "--json",
        ]))
    };
    // Frame 000005 back from version 1, by its stem: the other frames keep version 2.
    let r = restore_from_1("000005");
    assert_eq!(
        (r.frames.as_slice(), r.version),
        (&["000005.png".to_string()][..], 3)
    );
    let v3 = PoseFile::read(Path::new(&poses)).expect("v3");
    assert_eq!(
        v3.frames["000005.png"].object_pose,
        v1.frames["000005.png"].object_pose
    );
    assert_eq!(
        v3.frames["000005.png"].joints,
        v1.frames["000005.png"].joints
    );
    for f in ["000000.png", "000010.png", "000015.png"] {
        assert_eq!(v3.frames[f], v2.frames[f], "{f} changed");
    }
    // A range restores a set of frames with the same grammar.
    let r = restore_from_1("000010..000015");
    assert_eq!(r.frames, ["000010.png", "000015.png"]);
    assert_eq!(r.version, 4);
    let v4 = PoseFile::read(Path::new(&poses)).expect("v4");
    assert_eq!(v4.frames["000000.png"], v2.frames["000000.png"]);

    // Frame 000005 across the versions, scored with the run's model (found from run.json).
    let fh: FrameHistoryReport = json_of(&agentstar(&[
        "pose", "history", "--poses", &poses, "--frame", "000005", "--json",
    ]));
    assert_eq!(fh.frame, "000005.png");
    let same: Vec<Option<u64>> = fh.versions.iter().map(|v| v.same_as).collect();
    assert_eq!(same, [None, None, None, Some(1), Some(1)]);
    let iou: Vec<f64> = fh
        .versions
        .iter()
        .map(|v| v.iou_visible.expect("scored"))
        .collect();
    assert!(iou[1] > 0.97 && iou[2] < iou[1] - 0.05, "{iou:?}");
    assert_eq!(iou[3], iou[1]);
    let listing = text(&agentstar(&[
        "pose", "history", "--poses", &poses, "--frame", "000005",
    ]));
    assert!(listing.contains("same as version 1"), "{listing}");

    // Commit takes a history version file and a track's pose file as well.
    let version2 = s(&run.join(".agentstar/history/pose/000002.json"));
    let c: CommitReport = json_of(&agentstar(&[
        "pose", "commit", "--poses", &poses, "--report", &version2, "--frames", "000005", "--json",
    ]));
    assert_eq!((c.source.as_str(), c.version), ("history version 2", 5));
    assert_eq!(
        translation(
            &PoseFile::read(Path::new(&poses)).expect("v5"),
            "000005.png"
        ),
        translation(&v2, "000005.png")
    );
    let elsewhere = run.join("alt/pose.json");
    let o = track_from(&poses, &s(&elsewhere), &["--anchors", "000000..000015"]);
    // A new file starts its own history at version 0.
    assert_eq!(json_of::<TrackReport>(&o).pose_version, Some(0));
    let c: CommitReport = json_of(&agentstar(&[
        "pose",
        "commit",
        "--poses",
        &poses,
        "--from",
        &s(&elsewhere),
        "--json",
    ]));
    assert_eq!((c.source.as_str(), c.committed.len()), ("pose file", 4));
    // A rank means nothing for a pose file; a frame the source lacks is named.
    let o = agentstar(&[
        "pose",
        "commit",
        "--poses",
        &poses,
        "--report",
        &s(&elsewhere),
        "--rank",
        "2",
    ]);
    assert_failed_saying(&o, &["--rank applies to search reports"]);
    let o = agentstar(&["pose", "restore", "--poses", &poses, "--version", "99"]);
    assert_failed_saying(&o, &["no version 99"]);
    let h: HistoryReport = json_of(&agentstar(&[
        "pose", "history", "--poses", &poses, "--last", "2", "--json",
    ]));
    assert_eq!(
        (h.total, h.versions.len(), h.versions[1].version),
        (7, 2, 6)
    );
}

/// An MCP session that numbers its calls and waits for each answer.
struct Session {
    client: McpClient,
    id: u64,
}

impl Session {
    fn new(run: &Path) -> Session {
        Session {
            client: McpClient::initialised(run).0,
            id: 10,
        }
    }

    fn call(&mut self, name: &str, args: serde_json::Value) -> serde_json::Value {
        self.id += 1;
        self.client.call(self.id, name, args);
        self.client.response(self.id).0
    }

    /// `apply` of one order to one keyframe, committed; the search's report.
    fn commit_order(&mut self, frame: &str, order: &str) -> SearchReport {
        let r = self.call("apply", json!({"frame": frame, "order": order}));
        let rep: SearchReport =
            serde_json::from_value(r["result"]["structuredContent"].clone()).expect("apply");
        let path = McpClient::text_of(&r)
            .lines()
            .find_map(|l| l.strip_prefix("report: ").map(str::to_string))
            .expect("report path");
        let r = self.call("pose_commit", json!({"report": path}));
        assert_eq!(r["result"]["isError"], false, "{r}");
        rep
    }
}

/// A 4-keyframe run with the known scene, an MCP session on it, and the tracker's answer
/// over MCP, warm-started from the true poses (pose version 1).
fn tracked_from_truth(dir: &Path) -> (std::path::PathBuf, Session, serde_json::Value) {
    small_run(dir, 4, true);
    let (cap, run) = (dir.join("cap"), dir.join("run"));
    // The gates under test here; the mechanism check has its own (tests/mechanism.rs).
    support::mechanism_check_off(&run);
    let mut c = Session::new(&run);
    let r = c.call("track", json!({"from": s(&cap.join("model/pose.json"))}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    (run, c, r)
}

#[test]
fn a_track_that_moves_a_keyframe_committed_since_the_last_one_says_how_to_bring_it_back() {
    let dir = tempfile::tempdir().expect("tmp");
    let (run, mut c, _) = tracked_from_truth(dir.path());
    // A keyframe committed turned 60° (as an agent's wrong choice would be), then a track
    // from scratch: it puts the keyframe back where its mask says.
    c.commit_order("000005", "yaw:60");
    let committed = PoseFile::read(&run.join("pose.json")).expect("poses");
    let r = c.call("track", json!({}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let text = McpClient::text_of(&r);
    let t: TrackReport =
        serde_json::from_value(r["result"]["structuredContent"].clone()).expect("track");
    let version = t.pose_version.expect("version");
    let after = PoseFile::read(&run.join("pose.json")).expect("poses");
    assert_ne!(
        after.frames["000005.png"].object_pose,
        committed.frames["000005.png"].object_pose
    );
    assert!(
        text.contains("Keyframes you committed since the last track that this track moved to another basin: 000005.png (")
            && text.contains(&format!("`pose_restore` with `version: {}` and `frames: \"000005.png\"`", version - 1)),
        "{text}"
    );
    // Only since the last track: a second one has nothing to say about it.
    let r = c.call("track", json!({"from": "pose.json"}));
    assert!(
        !McpClient::text_of(&r).contains("Keyframes you committed since the last track"),
        "{r}"
    );
}

#[test]
fn finish_takes_categorised_reasons_and_refuses_too_many_frames_under_the_gate() {
    let dir = tempfile::tempdir().expect("tmp");
    // The tracker over MCP, warm-started from the true poses: a pose version.
    let (run, mut c, r) = tracked_from_truth(dir.path());
    // The box's lid: each frame's line ends with its hinge state.
    let text = McpClient::text_of(&r);
    assert!(text.contains("iou_visible  joints\n"), "{text}");
    assert!(!text.contains("joint states not shown"), "{text}");
    let t: TrackReport =
        serde_json::from_value(r["result"]["structuredContent"].clone()).expect("track");
    assert_eq!(t.pose_version, Some(1));
    assert!(t.sequence.min_iou_visible >= 0.98, "{:?}", t.sequence);
    // Anchors are kept exactly.
    let before = PoseFile::read(&run.join("pose.json")).expect("poses");
    let r = c.call("track", json!({"from": "pose.json", "anchors": "000010"}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let after = PoseFile::read(&run.join("pose.json")).expect("poses");
    assert_eq!(
        after.frames["000010.png"].object_pose,
        before.frames["000010.png"].object_pose
    );
    let r = c.call("track", json!({"anchors": "000010"}));
    assert!(McpClient::text_of(&r).contains("give `from`"), "{r}");

    // One keyframe turned off the gate.
    let spoil = |c: &mut Session, frame: &str| {
        let rep = c.commit_order(frame, "yaw:35");
        assert!(rep.frames[0].ranked[0].gate < 0.9, "{rep:?}");
        c.call("temporal", json!({}));
    };
    spoil(&mut c, "000000");
    c.call("turntable", json!({}));
    // An image of the frame (as the server lists them after the text).
    let r = c.call("render", json!({"frames": "000000", "views": "compare"}));
    let listed = McpClient::text_of(&r);
    let image = listed
        .split("images (also inline below):\n")
        .nth(1)
        .and_then(|t| t.lines().next())
        .and_then(|l| l.strip_prefix("- "))
        .map(str::to_string)
        .unwrap_or_else(|| panic!("an image path: {listed}"));
    // No reason: refused, naming the frame.
    let r = c.call("finish", json!({}));
    let body = McpClient::text_of(&r);
    assert!(
        body.starts_with("Not finished") && body.contains("without a reason: 000000.png"),
        "{body}"
    );
    // Reasons that do not hold are named; a category outside the set is a schema error.
    for (why, says) in [
        (
            json!({"category": "out_of_reach", "note": "lid"}),
            "at least 20 characters",
        ),
        (
            json!({"category": "mask_error", "image": "/etc/passwd"}),
            "outside the run",
        ),
        (
            json!({"category": "occlusion", "percent": 80}),
            "under the run's 30% threshold",
        ),
    ] {
        let r = c.call("finish", json!({"unreachable": {"000000": why}}));
        let body = McpClient::text_of(&r);
        assert!(
            body.starts_with("Not finished") && body.contains(says),
            "{why}: {body}"
        );
    }
    let r = c.call(
        "finish",
        json!({"unreachable": {"000000": {"category": "glare"}}}),
    );
    assert_eq!(r["result"]["isError"], true, "{r}");
    // An image that shows the mask error, or a real note: one of four frames is within
    // the share, and the run finishes.
    for why in [
        json!({"category": "mask_error", "image": image}),
        json!({"category": "out_of_reach", "note": "the lid bends here; the model's lid is rigid"}),
    ] {
        let r = c.call("finish", json!({"unreachable": {"000000": why}}));
        let body = McpClient::text_of(&r);
        assert!(
            body.starts_with("All gates hold") && body.contains("000000.png ("),
            "{why}: {body}"
        );
    }
    // A search that is not committed changes no pose: the temporal report still counts.
    let r = c.call("osweep", json!({"frames": "000005", "opreset": "z:flip"}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let note =
        json!({"category": "out_of_reach", "note": "the lid bends here; the model's lid is rigid"});
    let r = c.call("finish", json!({"unreachable": {"000000": note}}));
    let body = McpClient::text_of(&r);
    assert!(body.starts_with("All gates hold"), "{body}");
    // Two of four under the gate is over the share of a quarter, reasons or not.
    spoil(&mut c, "000005");
    let note =
        json!({"category": "out_of_reach", "note": "the lid bends here; the model's lid is rigid"});
    let r = c.call("finish", json!({"unreachable": {"000000..000005": note}}));
    let body = McpClient::text_of(&r);
    assert!(
        body.contains("2 of 4 keyframes (50%) are under the gate"),
        "{body}"
    );
    assert!(!body.contains("without a reason"), "{body}");
    // A run that allows half finishes with the same reasons.
    let rf = run.join("run.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&rf).expect("run.json")).expect("json");
    v["finish"]["max_share_under_gate"] = json!(0.5);
    std::fs::write(&rf, v.to_string()).expect("write");
    drop(c);
    let mut c = Session::new(&run);
    let r = c.call("finish", json!({"unreachable": {"000000..000005": note}}));
    assert!(McpClient::text_of(&r).starts_with("All gates hold"), "{r}");
    // What the colours say of the finished poses, beside the gates (play-test 16).
    assert!(
        McpClient::text_of(&r).contains("Colours (not a gate): the keyframes' colours against their neighbours' at these poses, NCC mean "),
        "{r}"
    );
    // A writer that leaves the scene and the poses as they were changed nothing the gates
    // checked: no call to finish again (play-test 17 read it after a fit that moved nothing).
    let script = std::fs::read_to_string(run.join("scene.rhai")).expect("scene");
    let r = c.call("scene_write", json!({"script": script}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    assert!(
        !McpClient::text_of(&r).contains("this run had finished"),
        "{r}"
    );
    // The first frame's story, and its good pose back from version 1.
    let r = c.call("pose_history", json!({"frame": "000000"}));
    let fh: FrameHistoryReport =
        serde_json::from_value(r["result"]["structuredContent"].clone()).expect("frame history");
    let best = fh
        .versions
        .iter()
        .max_by(|a, b| a.iou_visible.partial_cmp(&b.iou_visible).expect("cmp"))
        .expect("a version");
    assert!(best.iou_visible.expect("iou") >= 0.98, "{fh:?}");
    // The text shows each new pose itself, as the structured report holds it.
    let text = McpClient::text_of(&r);
    for v in fh.versions.iter().filter(|v| v.same_as.is_none()) {
        let p = v.pose.as_ref().expect("a new pose has a pose");
        let q = format!(
            "quaternion (w,x,y,z) [{:.4}, {:.4}, {:.4}, {:.4}]",
            p.quaternion[0], p.quaternion[1], p.quaternion[2], p.quaternion[3]
        );
        assert!(
            text.contains(&q),
            "version {}: {q} not in\n{text}",
            v.version
        );
    }
    let r = c.call(
        "pose_restore",
        json!({"version": best.version, "frames": "000000"}),
    );
    // The run had finished: a change after it says that the gates must be checked again.
    assert!(
        McpClient::text_of(&r).contains("this run had finished (`finish` passed)"),
        "{r}"
    );
    let rr: RestoreReport =
        serde_json::from_value(r["result"]["structuredContent"].clone()).expect("restore");
    assert_eq!(rr.frames, ["000000.png"]);
    let r = c.call("pose_restore", json!({"version": 0}));
    assert_eq!(
        r["result"]["isError"], false,
        "version 0 restores like the CLI: {r}"
    );
}

#[test]
fn finish_asks_for_each_large_step_to_be_checked_and_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let (_run, mut c, _) = tracked_from_truth(dir.path());
    // The first keyframe turned far from its neighbour and committed (off the gate, with a
    // reason below): a large step 000000 -> 000005.
    c.commit_order("000000", "yaw:130");
    c.call("temporal", json!({}));
    c.call("turntable", json!({}));
    let reason = json!({"000000": {"category": "out_of_reach", "note": "the lid bends here; the model's lid is rigid"}});
    let finish = |c: &mut Session, checked: serde_json::Value| {
        let r = c.call(
            "finish",
            json!({"unreachable": reason, "steps_checked": checked}),
        );
        McpClient::text_of(&r)
    };
    let body = finish(&mut c, json!({}));
    assert!(
        body.starts_with("Not finished")
            && body.contains("step 000000.png -> 000005.png turns the object by")
            && body.contains("steps_checked"),
        "{body}"
    );
    // Named, but neither frame looked at.
    let named = json!({"000000->000005": "oapply on 000005: no twin within 0.01"});
    let body = finish(&mut c, named.clone());
    assert!(body.contains("neither frame was looked at"), "{body}");
    // A key that is no step, a frame that is no keyframe, an empty note: each named.
    for (checked, says) in [
        (json!({"000000-000005": "x"}), "is not a step"),
        (
            json!({"000000->000999": "x"}),
            "`steps_checked` key `000000->000999`",
        ),
        (json!({"000000->000005": " "}), "has no note"),
    ] {
        let body = finish(&mut c, checked.clone());
        assert!(
            body.starts_with("Not finished") && body.contains(says),
            "{checked}: {body}"
        );
    }
    // After the flips of one of its frames were scored, the named step passes, in either
    // order; a step that is not large (no longer, or never) is no gate.
    let r = c.call("oapply", json!({"frames": "000005", "set": "flips"}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let body = finish(&mut c, named.clone());
    assert!(body.starts_with("All gates hold"), "{body}");
    let body = finish(
        &mut c,
        json!({"000005->000000": "oapply on 000005: no twin within 0.01", "000005->000010": "x"}),
    );
    assert!(body.starts_with("All gates hold"), "{body}");
    // A look at poses since replaced is no check of the new ones.
    c.commit_order("000000", "yaw:1");
    c.call("temporal", json!({}));
    let body = finish(&mut c, named.clone());
    assert!(
        body.contains("neither frame was looked at since their poses last changed"),
        "{body}"
    );
    let r = c.call("frames", json!({"frames": "000000"}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let body = finish(&mut c, named.clone());
    assert!(body.starts_with("All gates hold"), "{body}");
    // A change of another frame's pose leaves the look standing (play-test 8: restoring one
    // frame asked for new looks at steps it was not part of).
    let r = c.call("pose_restore", json!({"version": 1, "frames": "000015"}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    c.call("temporal", json!({}));
    let body = finish(&mut c, named.clone());
    assert!(body.starts_with("All gates hold"), "{body}");
    // A rescale keeps every rotation and view: the look stands (play-test 17). A pose change
    // of one of the step's frames after it still asks for a new look.
    let r = c.call(
        "scale",
        json!({"method": "size", "axis": "x", "metres": 0.5, "apply": true}),
    );
    assert_eq!(r["result"]["isError"], false, "{r}");
    c.call("temporal", json!({}));
    let body = finish(&mut c, named.clone());
    assert!(body.starts_with("All gates hold"), "{body}");
    c.commit_order("000000", "yaw:1");
    c.call("temporal", json!({}));
    let body = finish(&mut c, named);
    assert!(
        body.contains("neither frame was looked at since their poses last changed"),
        "{body}"
    );
}

#[test]
fn two_mcp_servers_on_one_run_never_give_a_scene_version_twice() {
    let dir = tempfile::tempdir().expect("tmp");
    let run = dir.path().join("run");
    small_run(dir.path(), 2, true);
    let scene = std::fs::read_to_string(run.join("scene.rhai")).expect("scene");
    let (mut a, _) = McpClient::initialised(&run);
    let (mut b, _) = McpClient::initialised(&run);
    let script = |server: &str, k: u64| format!("// server {server}, write {k}\n{scene}");
    // Every request is sent before any answer is read.
    for k in 0..4u64 {
        a.call(100 + k, "scene_write", json!({"script": script("a", k)}));
        b.call(100 + k, "scene_write", json!({"script": script("b", k)}));
    }
    let ids: Vec<u64> = (100..104).collect();
    let mut versions = vec![];
    for (server, c) in [("a", &mut a), ("b", &mut b)] {
        for (id, r) in c.responses(&ids) {
            let body = McpClient::text_of(&r);
            assert_eq!(r["result"]["isError"], false, "{server} {id}: {r}");
            let v: u64 = body
                .strip_prefix("scene version ")
                .and_then(|t| t.split_whitespace().next())
                .and_then(|n| n.parse().ok())
                .unwrap_or_else(|| panic!("{body}"));
            // The version file holds the script this call sent.
            let file = run.join(format!(".agentstar/scenes/{v:04}.rhai"));
            assert_eq!(
                std::fs::read_to_string(file).expect("version"),
                script(server, id - 100)
            );
            versions.push(v);
        }
    }
    versions.sort_unstable();
    assert_eq!(
        versions,
        (2..10).collect::<Vec<u64>>(),
        "a version was given twice"
    );
    let last = std::fs::read_to_string(run.join(".agentstar/scenes/0009.rhai")).expect("v9");
    assert_eq!(
        std::fs::read_to_string(run.join("scene.rhai")).expect("scene"),
        last
    );
    let recorded: BTreeSet<u64> = ledger(&run)
        .iter()
        .filter(|e| e["tool"] == "scene_write")
        .filter_map(|e| e["scene_version"].as_u64())
        .collect();
    assert_eq!(recorded.len(), 8);
}
