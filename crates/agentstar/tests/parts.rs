//! `score` names a part that sits on the object's mask in some keyframes and off it in
//! others: the shears' upper blade modelled rigid while it opens in the frames (play-test 17
//! modelled a hinged lever as a peg), and nothing at the true model.

mod support;

use agentstar_reports::ScoreReport;
use support::{on_poses, path_str, synth_object, text};

#[test]
fn score_names_a_part_modelled_rigid_that_moves_in_the_frames() {
    let dir = tempfile::tempdir().expect("tmp");
    let cap = dir.path().join("cap");
    let o = synth_object(path_str(&cap), "shears", &["--frames", "8", "--seed", "7"]);
    assert!(o.status.success(), "{}", text(&o));
    let (scene, poses) = (cap.join("model/scene.rhai"), cap.join("model/pose.json"));
    // The true model at the true poses: no part off the mask.
    let at_truth = on_poses(
        "score",
        path_str(&cap),
        path_str(&scene),
        path_str(&poses),
        &["--json", "--no-appearance"],
    );
    let report: ScoreReport = serde_json::from_slice(&at_truth.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", text(&at_truth)));
    assert!(
        report.parts_off_mask.is_empty(),
        "{:?}",
        report.parts_off_mask
    );
    // Its joints taken out: the blades and the lock rigid at rest, the base poses true.
    let script = std::fs::read_to_string(&scene).expect("scene");
    let rigid: String = script
        .lines()
        .filter(|l| !l.starts_with("joint("))
        .map(|l| format!("{l}\n"))
        .collect();
    let rigid_scene = dir.path().join("rigid.rhai");
    std::fs::write(&rigid_scene, rigid).expect("write");
    let mut pose: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&poses).expect("poses")).expect("json");
    pose["joint_defs"] = serde_json::json!([]);
    for f in pose["frames"].as_object_mut().expect("frames").values_mut() {
        f["joints"] = serde_json::json!({});
    }
    let rigid_poses = dir.path().join("rigid_pose.json");
    std::fs::write(&rigid_poses, pose.to_string()).expect("write");
    let o = on_poses(
        "score",
        path_str(&cap),
        path_str(&rigid_scene),
        path_str(&rigid_poses),
        &["--json", "--no-appearance"],
    );
    let report: ScoreReport =
        serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(&o)));
    let upper = report
        .parts_off_mask
        .iter()
        .find(|p| p.part == "upper")
        .unwrap_or_else(|| panic!("the upper blade is not named: {:?}", report.parts_off_mask));
    assert!(!upper.jointed);
    // Worst where the blades stand open (the pivot at 40° in keyframes 2 and 3, 000010 and
    // 000015, or 22° in 000020 and 000035), on the mask where they are near closed.
    let worst = &upper.frames[0];
    assert!(worst.off_share >= 0.4, "{upper:?}");
    assert!(
        upper.median_off_share <= worst.off_share - 0.25,
        "{upper:?}"
    );
    // The text says what to do.
    let o = on_poses(
        "score",
        path_str(&cap),
        path_str(&rigid_scene),
        path_str(&rigid_poses),
        &["--no-appearance"],
    );
    let body = text(&o);
    assert!(
        body.contains("parts off the object mask in some keyframes only")
            && body.contains("upper (rigid)")
            && body.contains("give it a joint"),
        "{body}"
    );
}
