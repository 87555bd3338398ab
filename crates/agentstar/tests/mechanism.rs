//! The mechanism check over MCP: the box's lid hinge swept about its declared axis and
//! about the negated axis as blind arms A and B; picks with evidence; `finish` refusing a
//! revolute joint without a fresh pick, and naming the sign to write when the frames match
//! the negated arm of a model whose hinge axis is mirrored.

mod support;

use agentstar_reports::mechanism::{ArmLabel, MechanismReport};
use serde_json::{json, Value};
use std::path::Path;
use support::{json_of, on_poses, s, small_run_at_truth, McpClient};

/// A client that numbers its own requests.
struct Session {
    c: McpClient,
    id: u64,
}

impl Session {
    fn new(run: &Path) -> Session {
        Session {
            c: McpClient::initialised(run).0,
            id: 100,
        }
    }

    fn call(&mut self, name: &str, args: Value) -> Value {
        self.id += 1;
        self.c.call(self.id, name, args);
        self.c.response(self.id).0
    }
}

/// What the mechanism command says of the run's scene, with the declared label of each
/// joint as the tool's last call drew it (the tool seeds its coin with the step, and keeps
/// the labels in the harness's `.agentstar/mechanism/sheets.json`, which it never shows).
fn report_of(dir: &Path) -> MechanismReport {
    let (cap, run) = (dir.join("cap"), dir.join("run"));
    let mut report: MechanismReport = json_of(&on_poses(
        "mechanism",
        &s(&cap),
        &s(&run.join("scene.rhai")),
        &s(&run.join("pose.json")),
        &["--out", &s(&dir.join("mech_cli")), "--json"],
    ));
    let sheets: Value = serde_json::from_str(
        &std::fs::read_to_string(run.join(".agentstar/mechanism/sheets.json")).expect("sheets"),
    )
    .expect("sheets json");
    for joint in &mut report.joints {
        joint.declared = serde_json::from_value(sheets["joints"][&joint.joint]["declared"].clone())
            .expect("declared label");
    }
    report
}

/// Evidence naming three interior states of `states`.
fn evidence(states: &[f64]) -> String {
    format!(
        "at {} deg the lid leaves the rim; at {} deg it stands over the back; at {} deg it leans back as in the frames",
        states[1], states[3], states[5]
    )
}

fn pick(label: ArmLabel, states: &[f64]) -> Value {
    json!({"picks": {"lid_hinge": {"arm": label.as_str(), "evidence": evidence(states)}}})
}

/// The mechanism lines of a `finish` answer.
fn mechanism_lines(finish: &Value) -> Vec<String> {
    McpClient::text_of(finish)
        .lines()
        .filter(|l| l.contains("joint lid_hinge"))
        .map(str::to_string)
        .collect()
}

#[test]
fn a_mirrored_hinge_is_caught_by_the_blind_arms_and_finish_names_the_sign() {
    let dir = tempfile::tempdir().expect("tmp");
    // The capture's poses: the lid opens over the keyframes.
    let run = small_run_at_truth(dir.path(), 3);
    let known = std::fs::read_to_string(run.join("scene.rhai")).expect("scene");
    assert!(known.contains("axis: [-1, 0, 0]"), "{known}");
    let mut c = Session::new(&run);

    // 1. The correct model: no pick yet blocks finish.
    let r = c.call("finish", json!({}));
    let lines = mechanism_lines(&r);
    assert!(
        lines.len() == 1 && lines[0].contains("no mechanism pick for the current scene"),
        "{r}"
    );
    // A pick before any sheets is refused.
    let r = c.call(
        "mechanism_pick",
        pick(ArmLabel::A, &[0.0, 18.0, 37.0, 55.0, 73.0, 92.0, 110.0]),
    );
    assert_eq!(r["result"]["isError"], true, "{r}");
    assert!(McpClient::text_of(&r).contains("run `mechanism`"), "{r}");

    let r = c.call("mechanism", json!({}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let body = McpClient::text_of(&r);
    // Two arms and the keyframe where the lid is most open, as images; the text never
    // says which arm is declared.
    let images = r["result"]["content"]
        .as_array()
        .expect("content")
        .iter()
        .filter(|b| b["type"] == "image")
        .count();
    assert_eq!(images, 3, "{body}");
    assert!(body.contains("states 0, 18, 37, 55, 73, 92, 110"), "{body}");
    assert!(body.contains("shown open in"), "{body}");
    assert!(body.contains("% of lid in view"), "{body}");
    assert!(!body.contains("declared\""), "{body}");
    assert!(r["result"].get("structuredContent").is_none(), "{r}");
    let report = report_of(dir.path());
    let joint = &report.joints[0];
    assert_eq!(joint.joint, "lid_hinge");
    assert_eq!(joint.states.len(), 7);
    let shown = joint.frame.as_ref().expect("a keyframe shown");
    assert_eq!(shown.parts, ["lid"]);
    assert!(
        shown.part_in_view_share > 0.0 && shown.part_in_view_share <= 1.0,
        "{shown:?}"
    );
    assert!(
        joint
            .views
            .iter()
            .all(|v| (v.off_swing_plane_deg - 50.0).abs() < 1e-6),
        "{:?}",
        joint.views
    );
    // The sheets keep the image limits.
    for p in joint.sheets_a.iter().chain(&joint.sheets_b) {
        let img = image::open(p).expect("sheet").to_rgb8();
        assert!(
            agentstar_render::sheet::within_limits(img.width(), img.height()),
            "{}",
            p.display()
        );
    }

    // Evidence naming only the ends (and one interior state) is refused; nothing recorded.
    let r = c.call(
        "mechanism_pick",
        json!({"picks": {"lid_hinge": {"arm": "A", "evidence": "closed at 0, open at 110, half way at 55"}}}),
    );
    assert_eq!(r["result"]["isError"], true, "{r}");
    assert!(
        McpClient::text_of(&r).contains("names 1 interior state(s)"),
        "{r}"
    );
    // The true arm on the correct model is the declared one: the gate holds.
    let r = c.call("mechanism_pick", pick(joint.declared, &joint.states));
    assert_eq!(r["result"]["isError"], false, "{r}");
    assert!(
        McpClient::text_of(&r).contains("arm about the declared axis"),
        "{r}"
    );
    let r = c.call("finish", json!({}));
    assert!(mechanism_lines(&r).is_empty(), "{r}");

    // 2. The hinge axis mirrored: the pick made for the old scene is stale.
    let mirrored = known.replace("axis: [-1, 0, 0]", "axis: [1, 0, 0]");
    let r = c.call("scene_write", json!({"script": mirrored}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let r = c.call("finish", json!({}));
    let lines = mechanism_lines(&r);
    assert!(
        lines.len() == 1 && lines[0].contains("made for scene version 1"),
        "{r}"
    );
    // Picking on the old sheets is refused.
    let r = c.call("mechanism_pick", pick(joint.declared, &joint.states));
    assert_eq!(r["result"]["isError"], true, "{r}");
    assert!(
        McpClient::text_of(&r).contains("run `mechanism` again"),
        "{r}"
    );
    let r = c.call("mechanism", json!({"joints": "lid_hinge"}));
    assert_eq!(r["result"]["isError"], false, "{r}");
    let report = report_of(dir.path());
    let joint = &report.joints[0];
    assert_eq!(joint.axis, [1.0, 0.0, 0.0]);
    // The frames show the lid opening about −x: the arm about the negated axis.
    let truth = joint.declared.other();
    let r = c.call("mechanism_pick", pick(truth, &joint.states));
    assert_eq!(r["result"]["isError"], false, "{r}");
    assert!(McpClient::text_of(&r).contains("NEGATED"), "{r}");
    let r = c.call("finish", json!({}));
    let lines = mechanism_lines(&r);
    assert_eq!(lines.len(), 1, "{r}");
    assert!(
        lines[0].contains("the frames match the arm about the negated axis")
            && lines[0].contains("declare axis (-1, 0, 0) for lid_hinge instead of (1, 0, 0)")
            && lines[0].contains("[-110, 0]"),
        "{}",
        lines[0]
    );
    // The pick is in the ledger with its evidence.
    let picks: Vec<Value> = support::ledger(&run)
        .into_iter()
        .filter(|e| e["tool"] == "mechanism_pick" && e["scores"]["negated_picks"] == 1.0)
        .collect();
    assert_eq!(picks.len(), 1);

    // 3. Off in run.json: no mechanism line.
    drop(c);
    support::mechanism_check_off(&run);
    let mut c = Session::new(&run);
    let r = c.call("finish", json!({}));
    assert!(mechanism_lines(&r).is_empty(), "{r}");
}
