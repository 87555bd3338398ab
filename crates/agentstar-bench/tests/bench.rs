//! The harness end to end on small synthetic sequences: the tracker is accurate on an
//! articulated hand-held capture, ground truth converts exactly, tables carry every section,
//! and tolerances catch regressions.

use agentstar_bench::gt::gt_sequence;
use agentstar_bench::table::{result_table, tables};
use agentstar_bench::tolerance::{check, record};
use agentstar_bench::{run_sequence, Method, RunConfig, SequenceResult};
use agentstar_data::gt::{model_ground_truth, GroundTruth};
use agentstar_synth::{synthesize, SynthConfig};

fn small(object: &str, seed: u64) -> SynthConfig {
    SynthConfig {
        object: object.into(),
        frames: 5,
        width: 200,
        height: 150,
        seed,
        ..SynthConfig::default()
    }
}

#[test]
fn the_tracker_recovers_an_articulated_hand_held_sequence() {
    // The first sequence of the quick suite (seed 1 of the same object is one the tracker
    // gets wrong: its initialisation lands in a near-symmetric basin; see bench/).
    let capture = synthesize(&SynthConfig {
        frames: 8,
        width: 240,
        height: 180,
        ..small("box", 2)
    })
    .expect("synth");
    let (r, poses) = run_sequence(&capture, Method::Tracker, &RunConfig::default()).expect("run");
    assert_eq!(poses.len(), 8);
    assert_eq!(r.method, "tracker");
    assert!(r.iou_mean > 0.97, "IoU {}", r.iou_mean);
    let epe = r.epe_cm.expect("epe");
    assert!(epe < 1.0, "EPE {epe} cm");
    assert!(
        (r.scale_alignment - 1.0).abs() < 0.03,
        "ŝ {}",
        r.scale_alignment
    );
    assert!(r.rotation_median_deg.expect("rot") < 3.0);
    let j = &r.joints[0];
    assert_eq!(j.pred_joint.as_deref(), Some("lid_hinge"));
    assert!(j.state.expect("state") < 0.05, "{j:?}");
    let t = result_table(&r);
    assert!(
        t.contains("3D EPE (cm)") && t.contains("joint lid_hinge"),
        "{t}"
    );
}

#[test]
fn ground_truth_of_the_true_poses_scores_zero() {
    let capture = synthesize(&small("cabinet", 2)).expect("synth");
    let truth: Vec<_> = capture
        .frames
        .iter()
        .map(|f| (f.name.clone(), f.camera_from_object, f.states.clone()))
        .collect();
    let (file, meshes) = model_ground_truth(&capture.model, capture.scale, &truth, &[]);
    assert_eq!(file.joints.len(), 2);
    assert_eq!(file.base_part, "body");
    let gt = GroundTruth::from_parts(std::path::Path::new("mem/gt.json"), file, meshes);
    let names: Vec<String> = capture.frames.iter().map(|f| f.name.clone()).collect();
    let seq = gt_sequence(&gt, &names).expect("sequence");
    let pred = agentstar_eval::sequence::PredSequence {
        model: &capture.model,
        scale: capture.scale,
        poses: capture
            .frames
            .iter()
            .map(|f| (f.camera_from_object, f.states.clone()))
            .collect(),
    };
    let m = agentstar_eval::sequence::evaluate(
        &seq,
        &pred,
        &vec![capture.camera; names.len()],
        &Default::default(),
    );
    assert!((m.scale_alignment - 1.0).abs() < 1e-6);
    assert!(m.epe_cm.expect("epe") < 1e-6);
    assert!(m.cd_sq_whole_m2.expect("cd") < 1e-12);
    for j in &m.joints {
        assert!(j.axis_angle_rad.expect("axis") < 1e-6, "{j:?}");
        assert!(j.state_error.expect("state") < 1e-9, "{j:?}");
    }
    // A frame the ground truth lacks is named.
    let e = gt_sequence(&gt, &["999999.png".to_string()]).expect_err("missing");
    assert!(
        e.to_string().contains("999999.png") && e.to_string().contains("mem/gt.json"),
        "{e}"
    );
}

fn fake(id: &str, family: &str, method: &str, epe: f64, iou: f64) -> SequenceResult {
    SequenceResult {
        id: id.into(),
        object: id.into(),
        family: family.into(),
        motion: "handheld".into(),
        method: method.into(),
        frames: 4,
        seconds: 1.5,
        evaluations: 100,
        iou_mean: iou,
        iou_min: iou - 0.01,
        scale_alignment: 1.0,
        epe_cm: Some(epe),
        chamfer_cm: Some(0.2),
        rotation_mean_deg: Some(1.0),
        rotation_median_deg: Some(0.5),
        translation_mean_cm: Some(0.3),
        translation_median_cm: Some(0.2),
        cd_w_m2: Some(1e-5),
        cd_m_m2: Some(2e-5),
        cd_s_m2: Some(1e-5),
        joints: vec![agentstar_bench::run::JointResult {
            gt_joint: "hinge".into(),
            pred_joint: Some("hinge".into()),
            revolute: true,
            axis_rad: Some(0.01),
            position_m: Some(0.002),
            state: Some(0.02),
        }],
    }
}

#[test]
fn tables_have_every_section_and_average_per_method() {
    let rs = vec![
        fake("a", "arctic", "tracker", 1.0, 0.99),
        fake("b", "arctic", "tracker", 3.0, 0.98),
        fake("a", "arctic", "vlm-free", 10.0, 0.9),
        fake("c", "hot3d", "tracker", 2.0, 0.99),
        fake("d", "itaco", "tracker", 2.0, 0.99),
    ];
    let t = tables(&rs, true);
    for section in [
        "ARCTIC-like",
        "HOT3D-like",
        "iTACO-like",
        "Ablation",
        "Per sequence",
        "CD-w (m²)",
        "Position (m)",
    ] {
        assert!(t.contains(section), "missing {section}:\n{t}");
    }
    // The tracker's ARCTIC mean EPE is (1 + 3) / 2.
    assert!(t.contains("| tracker | 2 | 2.00 |"), "{t}");
    assert!(t.contains("| vlm-free | 1 | 10.00 |"), "{t}");
}

#[test]
fn tolerances_pass_on_the_recorded_run_and_catch_regressions() {
    let rs = vec![
        fake("a", "arctic", "tracker", 1.0, 0.99),
        fake("c", "hot3d", "tracker", 2.0, 0.99),
    ];
    let file = record(&rs, "quick", "today");
    assert_eq!(file.entries.len(), 2);
    assert!(check(&rs, &file).is_empty());
    // EPE bound is 2·1.0 + 0.5 = 2.5 cm: 2.4 passes, 2.6 fails.
    let ok = vec![fake("a", "arctic", "tracker", 2.4, 0.99), rs[1].clone()];
    assert!(check(&ok, &file).is_empty(), "{:?}", check(&ok, &file));
    let worse = vec![fake("a", "arctic", "tracker", 2.6, 0.99), rs[1].clone()];
    let v = check(&worse, &file);
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(
        v[0].contains("epe_cm") && v[0].contains("a (tracker)"),
        "{v:?}"
    );
    // IoU under its bound, and a missing sequence, are reported too.
    let v = check(&[fake("a", "arctic", "tracker", 1.0, 0.9)], &file);
    assert!(v.iter().any(|s| s.contains("iou_mean")), "{v:?}");
    assert!(
        v.iter()
            .any(|s| s.contains("c (tracker)") && s.contains("not run")),
        "{v:?}"
    );
}
