//! Acknowledged joint-limit warnings over MCP: `temporal` warns in full of a joint piled at
//! its limit until the agent acknowledges it (`acknowledge_limits: true`); then `temporal`
//! and `turntable` summarise that warning in one line, and a different one (other keyframes
//! at the limit) still warns in full.

mod support;

use serde_json::{json, Value};
use std::path::Path;
use support::{small_run_at_truth, McpClient};

/// Sets the lid hinge of the keyframes `at` (by position) to its lower limit in the run's
/// pose file and the others half way; returns the lower limit.
fn lid_at_lower_limit(run: &Path, at: &[usize]) -> f64 {
    let path = run.join("pose.json");
    let mut poses: Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("poses")).expect("json");
    let def = poses["joint_defs"]
        .as_array()
        .expect("joint defs")
        .iter()
        .find(|j| j["name"] == "lid_hinge")
        .cloned()
        .expect("lid_hinge");
    let (lo, hi) = (
        def["limit"][0].as_f64().expect("lower"),
        def["limit"][1].as_f64().expect("upper"),
    );
    let frames = poses["frames"].as_object_mut().expect("frames");
    for (k, (_, entry)) in frames.iter_mut().enumerate() {
        let state = if at.contains(&k) { lo } else { 0.5 * (lo + hi) };
        entry["joints"]["lid_hinge"] = json!(state);
    }
    std::fs::write(&path, serde_json::to_string_pretty(&poses).expect("encode")).expect("write");
    lo
}

fn warnings(r: &Value) -> Vec<String> {
    McpClient::text_of(r)
        .lines()
        .filter(|l| l.starts_with("warning: ") && l.contains("lid_hinge"))
        .map(str::to_string)
        .collect()
}

#[test]
fn an_acknowledged_limit_warning_is_summarised_and_a_new_one_still_warns() {
    let dir = tempfile::tempdir().expect("tmp");
    let run = small_run_at_truth(dir.path(), 5);
    let lower = lid_at_lower_limit(&run, &[0, 1, 2]);
    let (mut c, _) = McpClient::initialised(&run);
    let mut id = 100;
    let mut call = |name: &str, args: Value| {
        id += 1;
        c.call(id, name, args);
        c.response(id).0
    };
    let full = format!("joint `lid_hinge` sits at its lower limit {lower} in 3 of 5 keyframes");

    // Not acknowledged: in full, every time.
    for _ in 0..2 {
        let r = call("temporal", json!({}));
        assert_eq!(r["result"]["isError"], false, "{}", McpClient::text_of(&r));
        let w = warnings(&r);
        assert!(
            w.len() == 1 && w[0].contains(&full),
            "{}",
            McpClient::text_of(&r)
        );
    }
    // Acknowledged: this reply still shows it in full and says it is acknowledged.
    let r = call("temporal", json!({"acknowledge_limits": true}));
    let text = McpClient::text_of(&r);
    assert!(text.contains(&full), "{text}");
    assert!(
        text.contains("acknowledged 1 new joint-limit warning(s)"),
        "{text}"
    );
    let record = run.join(".agentstar/limits_acknowledged.json");
    assert!(record.is_file(), "{}", record.display());
    // Later replies, of both tools, summarise it in one line.
    for tool in ["temporal", "turntable"] {
        let r = call(tool, json!({}));
        assert_eq!(r["result"]["isError"], false, "{}", McpClient::text_of(&r));
        let w = warnings(&r);
        assert_eq!(w.len(), 1, "{tool}: {}", McpClient::text_of(&r));
        assert!(
            !w[0].contains("sits at its"),
            "{tool}: {}",
            McpClient::text_of(&r)
        );
        assert!(
            w[0].contains("acknowledged, unchanged: `lid_hinge` at its lower limit in 3 of 5"),
            "{tool}: {}",
            McpClient::text_of(&r)
        );
    }
    // Other keyframes at the limit: a new warning, in full.
    lid_at_lower_limit(&run, &[1, 2, 3, 4]);
    let r = call("temporal", json!({}));
    let w = warnings(&r);
    assert!(
        w.len() == 1
            && w[0].contains(&format!(
                "joint `lid_hinge` sits at its lower limit {lower} in 4 of 5 keyframes"
            )),
        "{}",
        McpClient::text_of(&r)
    );
}
