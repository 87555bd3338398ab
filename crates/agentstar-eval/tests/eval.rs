//! Sequence metrics on constructed cases with known answers.

#[path = "../../agentstar-track/tests/common/hinged.rs"]
mod hinged;
mod numpy;

use agentstar_eval::sequence::{
    evaluate, EvalConfig, GtJoint, GtSequence, PredSequence, SequenceMetrics,
};
use agentstar_geom::kinematics::JointDef;
use agentstar_geom::pose::{GenPose, ObjectPose, Similarity};
use agentstar_geom::primitives::cuboid;
use agentstar_geom::{KinematicTree, ObjectModel, Part, PinholeCamera, UnitQuaternion, Vector3};
use hinged::with_lid_hinge;

fn model() -> ObjectModel {
    let parts = vec![
        Part::new("base", cuboid(1.0, 0.6, 0.2).expect("box"), [0.5; 3]),
        Part::new(
            "lid",
            cuboid(1.0, 0.6, 0.06)
                .expect("box")
                .translated(Vector3::new(0.0, 0.0, 0.14)),
            [0.5; 3],
        ),
    ];
    with_lid_hinge(parts, Vector3::new(0.0, 0.3, 0.1), -Vector3::x(), 120.0)
}

fn frames() -> Vec<GenPose> {
    (0..5)
        .map(|k| {
            let t = k as f64;
            let r = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 2.0)
                * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3 * t);
            GenPose::new(
                ObjectPose::new(r, Vector3::new(0.02 * t, -0.01, 0.8 + 0.02 * t)),
                vec![(20.0 + 15.0 * t).to_radians()],
            )
        })
        .collect()
}

/// The ground truth of `model` at scale `s`: meshes in metres, each part's pose per frame.
fn ground_truth(m: &ObjectModel, s: f64, f: &[GenPose]) -> GtSequence {
    let meshes = m
        .parts
        .iter()
        .map(|p| {
            (*p.mesh).clone().transformed(
                &(agentstar_geom::Matrix3::identity() * s),
                &Vector3::zeros(),
            )
        })
        .collect();
    let poses = f
        .iter()
        .map(|GenPose { pose, states }| {
            m.tree
                .part_transforms(states)
                .iter()
                .map(|a| {
                    let full = pose.with_scale(s).compose(&Similarity::from_rigid(a));
                    // Fold the scale into the mesh: the pose keeps rotation and translation.
                    ObjectPose::new(full.rotation, full.translation)
                })
                .collect()
        })
        .collect();
    let j = &m.tree.joints()[0];
    GtSequence {
        part_names: m.part_names(),
        meshes,
        base_part: 0,
        poses,
        joints: vec![GtJoint {
            name: "gt_hinge".into(),
            revolute: true,
            parent: 0,
            child: 1,
            axis: j.axis,
            origin: j.origin * s,
            states: f.iter().map(|x| x.states[0]).collect(),
        }],
    }
}

fn camera() -> PinholeCamera {
    PinholeCamera::new(200.0, 200.0, 80.0, 60.0, 160, 120).expect("camera")
}

/// `gt` evaluated against `model` at `scale` and `poses`, seen by `camera()` in every frame,
/// with `samples` surface samples for Chamfer.
fn evaluated(
    gt: &GtSequence,
    model: &ObjectModel,
    scale: f64,
    poses: Vec<GenPose>,
    samples: usize,
) -> SequenceMetrics {
    let cams = vec![camera(); poses.len()];
    evaluate(
        gt,
        &PredSequence {
            model,
            scale,
            poses,
        },
        &cams,
        &EvalConfig {
            samples,
            ..Default::default()
        },
    )
}

#[test]
fn a_perfect_prediction_scores_zero() {
    let m = model();
    let f = frames();
    let gt = ground_truth(&m, 0.3, &f);
    let r = evaluated(&gt, &m, 0.3, f.clone(), 3000);
    assert!(
        (r.scale_alignment - 1.0).abs() < 1e-5,
        "{}",
        r.scale_alignment
    );
    assert!(r.epe_cm.expect("epe") < 1e-3 && r.epe_points > 300, "{r:?}");
    // Chamfer compares independent samples of the two surfaces (as the published protocol
    // does), so a perfect prediction scores the sampling floor, which shrinks as 1/√n.
    let floor = r.chamfer_cm.expect("cd");
    assert!(floor > 0.0 && floor < 0.5, "{floor}");
    assert!(r.cd_moving_cm.expect("cd") < 0.5 && r.cd_static_cm.expect("cd") < 0.5);
    let r4 = evaluated(&gt, &m, 0.3, f.clone(), 12_000);
    let ratio = r4.chamfer_cm.expect("cd") / floor;
    assert!(
        (0.35..0.65).contains(&ratio),
        "four times the samples, half the floor: {ratio}"
    );
    let rigid = r.rigid.expect("rigid");
    assert!(rigid.rotation_mean_deg < 1e-3 && rigid.translation_mean_cm < 1e-3);
    let j = &r.joints[0];
    assert_eq!(
        (j.pred_joint.as_deref(), j.matched_by),
        (Some("hinge"), "child part name")
    );
    assert!(
        j.axis_angle_rad.expect("axis") < 1e-6
            && j.axis_distance_m.expect("line") < 1e-6
            && j.state_error.expect("state") < 1e-9
    );
}

#[test]
fn monocular_scale_is_aligned_and_joints_match_by_geometry() {
    // The same images from an object twice as large and twice as far: ŝ = 0.5, errors 0.
    let m = model();
    let f = frames();
    let gt = ground_truth(&m, 0.3, &f);
    let doubled: Vec<GenPose> = f
        .iter()
        .map(|g| {
            GenPose::new(
                ObjectPose::new(g.pose.rotation, g.pose.translation * 2.0),
                g.states.clone(),
            )
        })
        .collect();
    let mut renamed = m.clone();
    renamed.parts[1].name = "top".into();
    let hinge = JointDef {
        child: vec!["top".into()],
        ..m.tree.joints()[0].clone()
    };
    renamed.tree = KinematicTree::new(vec![hinge], &["base".into(), "top".into()]).expect("tree");
    let r = evaluated(&gt, &renamed, 0.6, doubled, 3000);
    assert!(
        (r.scale_alignment - 0.5).abs() < 1e-5,
        "{}",
        r.scale_alignment
    );
    assert!(r.epe_cm.expect("epe") < 1e-3, "{r:?}");
    assert!(r.rigid.expect("rigid").translation_mean_cm < 1e-3);
    let j = &r.joints[0];
    assert_eq!(j.matched_by, "nearest moving parts");
    assert!(j.axis_distance_m.expect("line") < 1e-6);
    // A state off by 10° in every frame reads as 10° of state error.
    let off: Vec<GenPose> = f
        .iter()
        .map(|g| GenPose::new(g.pose, vec![g.states[0] + 10f64.to_radians()]))
        .collect();
    let r = evaluated(&gt, &m, 0.3, off, 2000);
    assert!((r.joints[0].state_error.expect("state") - 10f64.to_radians()).abs() < 1e-9);
    assert!(r.cd_moving_cm.expect("cd") > r.cd_static_cm.expect("cd"));
}

/// Cross-checks the gauge-aligned errors of a noisy trajectory against the independent numpy
/// implementation in `scripts/crosscheck_rigid.py`, where Python and numpy exist (skipped
/// with a note otherwise, since CI machines need not have numpy).
#[test]
fn rigid_errors_match_an_independent_numpy_implementation() {
    use agentstar_eval::rigid::gauge_aligned_errors;
    if !numpy::has_numpy() {
        return;
    }
    let f = frames();
    let gt: Vec<ObjectPose> = f.iter().map(|x| x.pose).collect();
    let pred: Vec<ObjectPose> = gt
        .iter()
        .enumerate()
        .map(|(k, g)| {
            let noise =
                UnitQuaternion::from_euler_angles(0.01 * k as f64, -0.02, 0.015 * (k as f64).sin());
            let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.7);
            ObjectPose::new(
                noise * g.rotation * q,
                (g.translation + Vector3::new(0.004 * k as f64, -0.003, 0.002)) / 1.7,
            )
        })
        .collect();
    let ours = gauge_aligned_errors(&gt, &pred, 0.4, 1.7).expect("errors");
    let input = serde_json::json!({"gt": gt.iter().map(numpy::pose_row).collect::<Vec<_>>(), "pred": pred.iter().map(numpy::pose_row).collect::<Vec<_>>(), "pred_scale": 0.4, "depth_scale": 1.7});
    let theirs = numpy::crosscheck("crosscheck_rigid.py", &input);
    for (k, (a, b)) in ours
        .rotation_deg
        .iter()
        .zip(theirs["rotation_deg"].as_array().expect("rot"))
        .enumerate()
    {
        assert!(
            (a - b.as_f64().expect("f64")).abs() < 1e-6,
            "frame {k}: rotation {a} vs {b}"
        );
    }
    for (k, (a, b)) in ours
        .translation_cm
        .iter()
        .zip(theirs["translation_cm"].as_array().expect("trans"))
        .enumerate()
    {
        assert!(
            (a - b.as_f64().expect("f64")).abs() < 1e-6,
            "frame {k}: translation {a} vs {b}"
        );
    }
    assert!(ours.rotation_mean_deg > 0.5, "the case is not trivial");
}
