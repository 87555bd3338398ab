//! The one frame grammar (`Capture::select`) as every command takes it: names, stems, frame
//! numbers, ranges, `all`; unknown frames and empty selections are errors that list the
//! frames.

mod support;

use agentstar_reports::ScoreReport;
use support::{agentstar, s, small_run, text};

#[test]
fn frames_are_selected_by_names_stems_numbers_and_ranges() {
    let dir = tempfile::tempdir().expect("tmp");
    small_run(dir.path(), 3, true);
    let (cap, run) = (dir.path().join("cap"), dir.path().join("run"));
    let score = |spec: &str| {
        agentstar(&[
            "score",
            "--capture",
            &s(&cap),
            "--model",
            &s(&run.join("scene.rhai")),
            "--poses",
            &s(&run.join("pose.json")),
            "--frames",
            spec,
            "--json",
        ])
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
