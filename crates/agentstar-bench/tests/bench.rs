//! The harness end to end on small synthetic sequences: the tracker is accurate on an
//! articulated hand-held capture, ground truth converts exactly, tables carry every section,
//! and tolerances catch regressions.

#[path = "../../agentstar-eval/tests/numpy/mod.rs"]
mod numpy;

use agentstar_bench::table::{result_table, tables};
use agentstar_bench::tolerance::{check, record};
use agentstar_bench::{run_sequence, Method, RunConfig, RunInfo, SequenceResult};
use agentstar_data::gt::{model_ground_truth, GroundTruth};
use agentstar_eval::{JointRecord, MetricsRecord};
use agentstar_geom::GenPose;
use agentstar_synth::{synthesize, SynthCapture, SynthConfig};

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
    // The first sequence of the quick suite. (Seed 1 of the same object initialises in a
    // near-symmetric basin; since the consistency pass searches wide from clearly better
    // neighbours it recovers too, EPE 0.12 cm.)
    let capture = synthesize(&SynthConfig {
        frames: 8,
        width: 240,
        height: 180,
        ..small("box", 2)
    })
    .expect("synth");
    let (r, poses) = run_sequence(&capture, Method::Tracker, &RunConfig::default()).expect("run");
    assert_eq!(poses.len(), 8);
    assert_eq!(r.info.method, "tracker");
    assert!(r.iou_mean > 0.97, "IoU {}", r.iou_mean);
    let epe = r.metrics.epe_cm.expect("epe");
    assert!(epe < 1.0, "EPE {epe} cm");
    assert!(
        (r.metrics.scale_alignment - 1.0).abs() < 0.03,
        "ŝ {}",
        r.metrics.scale_alignment
    );
    assert!(r.metrics.rotation_median_deg.expect("rot") < 3.0);
    let j = &r.metrics.joints[0];
    assert_eq!(j.pred_joint.as_deref(), Some("lid_hinge"));
    assert!(j.state_error.expect("state") < 0.05, "{j:?}");
    let t = result_table(&r);
    assert!(
        t.contains("3D EPE (cm)") && t.contains("joint lid_hinge"),
        "{t}"
    );
}

#[test]
fn a_short_clip_with_frames_in_a_wrong_basin_is_recovered_from_its_neighbours() {
    // Six keyframes of the hand-held box: the initial frame lands in a wrong basin (IoU 0.91);
    // the frames tracked from it are searched globally (under the band threshold), then the
    // first frame again with the wide search around its neighbours, and the consistency pass
    // carries the good poses to the frame the others left a few degrees off.
    let capture = synthesize(&SynthConfig {
        frames: 6,
        seed: 7,
        ..SynthConfig::default()
    })
    .expect("synth");
    let (r, _) = run_sequence(&capture, Method::Tracker, &RunConfig::default()).expect("run");
    assert!(
        r.iou_min > 0.98,
        "IoU min {} (mean {})",
        r.iou_min,
        r.iou_mean
    );
    assert!(
        r.metrics.epe_cm.expect("epe") < 1.0,
        "EPE {:?}",
        r.metrics.epe_cm
    );
    // Without the pass, the global search of the propagation (frames under the band
    // threshold) and of the first frame already takes every frame but one out of the wrong
    // basin; that one stays a few degrees off (it was IoU < 0.95 before the global search).
    let (n, _) = run_sequence(&capture, Method::NoTemporal, &RunConfig::default()).expect("run");
    let (with, without) = (
        r.metrics.epe_cm.expect("epe"),
        n.metrics.epe_cm.expect("epe"),
    );
    assert!(
        without > with + 0.3,
        "the pass should matter: EPE {with} cm with it, {without} cm without"
    );
}

/// The capture's ground truth from its model at its true poses (as `model_ground_truth`
/// writes it, in memory), its frame names, and the sequence of those frames read back.
fn true_sequence(
    capture: &SynthCapture,
) -> (
    GroundTruth,
    Vec<String>,
    agentstar_eval::sequence::GtSequence,
) {
    let truth: Vec<_> = capture
        .frames
        .iter()
        .map(|f| (f.name.clone(), f.camera_from_object, f.states.clone()))
        .collect();
    let (file, meshes) = model_ground_truth(&capture.model, capture.scale, &truth, &[]);
    let gt = GroundTruth::from_parts(std::path::Path::new("mem/gt.json"), file, meshes);
    let names: Vec<String> = capture.frames.iter().map(|f| f.name.clone()).collect();
    let seq = gt.sequence(&names).expect("sequence");
    (gt, names, seq)
}

#[test]
fn ground_truth_of_the_true_poses_scores_zero() {
    let capture = synthesize(&small("cabinet", 2)).expect("synth");
    let (gt, names, seq) = true_sequence(&capture);
    assert_eq!(gt.file.joints.len(), 2);
    assert_eq!(gt.file.base_part, "body");
    let pred = agentstar_eval::sequence::PredSequence {
        model: &capture.model,
        scale: capture.scale,
        poses: capture
            .frames
            .iter()
            .map(|f| GenPose::new(f.camera_from_object, f.states.clone()))
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
    // Only the sampling floor of two independent sample sets of the same surfaces.
    assert!(
        m.cd_sq_whole_m2.expect("cd") < 1e-3,
        "{:?}",
        m.cd_sq_whole_m2
    );
    for j in &m.joints {
        assert!(j.axis_angle_rad.expect("axis") < 1e-6, "{j:?}");
        assert!(j.state_error.expect("state") < 1e-9, "{j:?}");
    }
    // A frame the ground truth lacks is named.
    let e = gt
        .sequence(&["999999.png".to_string()])
        .expect_err("missing");
    assert!(
        e.to_string().contains("999999.png") && e.to_string().contains("mem/gt.json"),
        "{e}"
    );
}

fn fake(id: &str, family: &str, method: &str, epe: f64, iou: f64) -> SequenceResult {
    SequenceResult {
        info: RunInfo {
            id: id.into(),
            object: id.into(),
            family: family.into(),
            motion: "handheld".into(),
            method: method.into(),
            seconds: 1.5,
            evaluations: 100,
        },
        iou_mean: iou,
        iou_min: iou - 0.01,
        metrics: MetricsRecord {
            frames: 4,
            scale_alignment: 1.0,
            epe_cm: Some(epe),
            epe_points: 100,
            chamfer_cm: Some(0.2),
            cd_moving_cm: None,
            cd_static_cm: None,
            cd_w_m2: Some(1e-5),
            cd_m_m2: Some(2e-5),
            cd_s_m2: Some(1e-5),
            rotation_mean_deg: Some(1.0),
            rotation_median_deg: Some(0.5),
            translation_mean_cm: Some(0.3),
            translation_median_cm: Some(0.2),
            joints: vec![JointRecord {
                gt_joint: "hinge".into(),
                pred_joint: Some("hinge".into()),
                matched_by: "name".into(),
                revolute: true,
                axis_angle_rad: Some(0.01),
                axis_distance_m: Some(0.002),
                state_error: Some(0.02),
            }],
        },
        symmetry_reduced: None,
        capture_stats: None,
        misses: None,
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

/// One full sequence (a cabinet with a door and a drawer seen by an orbiting camera, a noisy
/// prediction at the wrong scale) against the independent numpy implementation in
/// `scripts/crosscheck_sequence.py`, where Python and numpy exist (skipped with a note
/// otherwise). Scale, articulation and rigid errors must agree to rounding; Chamfer
/// distances, which each side computes from its own random samples, within a few percent.
#[test]
fn a_full_sequence_matches_an_independent_numpy_implementation() {
    use agentstar_eval::sequence::{evaluate, EvalConfig, PredSequence};
    use agentstar_geom::pose::{ObjectPose, Similarity};
    use agentstar_geom::{UnitQuaternion, Vector3};
    use agentstar_render::raster::Affine;
    use agentstar_render::{render_full, Instance, PosedModel};
    use serde_json::json;
    if !numpy::has_numpy() {
        return;
    }
    let capture = synthesize(&small("cabinet", 3)).expect("synth");
    let n = capture.frames.len();
    let (_, _, seq) = true_sequence(&capture);
    // The prediction: 1.2 times too large (and so 1.2 times too far), a few degrees and
    // millimetres off, joints off by 3° and 0.02 units.
    let k = 1.2;
    let pred_scale = capture.scale * k;
    let poses: Vec<GenPose> = capture
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let wobble =
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), (2.0 + i as f64).to_radians());
            let mut states = f.states.clone();
            states[0] += 3f64.to_radians();
            states[1] += 0.02;
            GenPose::new(
                ObjectPose::new(
                    wobble * f.camera_from_object.rotation,
                    f.camera_from_object.translation * k
                        + Vector3::new(0.004, -0.002, 0.003 * i as f64),
                ),
                states,
            )
        })
        .collect();
    let pred = PredSequence {
        model: &capture.model,
        scale: pred_scale,
        poses: poses.clone(),
    };
    let cams = vec![capture.camera; n];
    let samples = 3000;
    let ours = evaluate(
        &seq,
        &pred,
        &cams,
        &EvalConfig {
            samples,
            ..EvalConfig::default()
        },
    );
    // Inputs for the script, from the raw data.
    let row8 = |s: &Similarity| {
        let q = agentstar_geom::pose::quat_to_wxyz(&s.rotation);
        vec![
            s.scale,
            q[0],
            q[1],
            q[2],
            q[3],
            s.translation.x,
            s.translation.y,
            s.translation.z,
        ]
    };
    let mesh = |m: &agentstar_geom::TriMesh| {
        json!({"vertices": m.positions.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
               "triangles": m.triangles})
    };
    let mut depth_pairs = Vec::new();
    for (f, GenPose { pose, states }) in poses.iter().enumerate() {
        let gi: Vec<Instance<'_>> = seq
            .meshes
            .iter()
            .zip(&seq.poses[f])
            .enumerate()
            .map(|(i, (m, p))| {
                Instance::bare(m, Affine::from_similarity(&p.with_scale(1.0)), i as u16)
            })
            .collect();
        let g = render_full(&capture.camera, &gi);
        let p = render_full(
            &capture.camera,
            &PosedModel::new(&capture.model, states, &pose.with_scale(pred_scale)).instances,
        );
        for (a, b) in g.depth.iter().zip(&p.depth) {
            if a.is_finite() && b.is_finite() && *a > 0.0 && *b > 0.0 {
                depth_pairs.push([*a as f64, *b as f64]);
            }
        }
    }
    let tree = &capture.model.tree;
    let pred_part_poses: Vec<Vec<Vec<f64>>> = poses
        .iter()
        .map(
            |GenPose {
                 pose: p,
                 states: st,
             }| {
                tree.part_transforms(st)
                    .iter()
                    .map(|t| row8(&p.with_scale(pred_scale).compose(&Similarity::from_rigid(t))))
                    .collect()
            },
        )
        .collect();
    let pred_joints: Vec<_> = seq
        .joints
        .iter()
        .map(|gj| {
            let j = tree
                .joint_index(&gj.name)
                .expect("same joint names in the synthetic model");
            let jd = &tree.joints()[j];
            json!({"axis": [jd.axis.x, jd.axis.y, jd.axis.z], "origin": [jd.origin.x, jd.origin.y, jd.origin.z],
                   "states": poses.iter().map(|p| p.states[j]).collect::<Vec<_>>(),
                   "object_pose": row8(&poses[0].pose.with_scale(pred_scale))})
        })
        .collect();
    let input = json!({
        "samples": samples,
        "depth_pairs": depth_pairs,
        "gt_meshes": seq.meshes.iter().map(mesh).collect::<Vec<_>>(),
        "gt_poses": seq.poses.iter().map(|r| r.iter().map(numpy::pose_row).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "gt_joints": seq.joints.iter().map(|j| json!({"parent": j.parent, "child": j.child,
            "axis": [j.axis.x, j.axis.y, j.axis.z], "origin": [j.origin.x, j.origin.y, j.origin.z],
            "states": j.states, "revolute": j.revolute})).collect::<Vec<_>>(),
        "gt_base": seq.base_part,
        "pred_meshes": capture.model.parts.iter().map(|p| mesh(&p.mesh)).collect::<Vec<_>>(),
        "pred_poses": pred_part_poses,
        "pred_moving": (0..capture.model.parts.len()).map(|i| tree.part_joint(i).is_some()).collect::<Vec<_>>(),
        "pred_joints": pred_joints,
        "pred_object_poses": poses.iter().map(|p| row8(&p.pose.with_scale(pred_scale))).collect::<Vec<_>>(),
        "pred_scale": pred_scale,
    });
    let t = numpy::crosscheck("crosscheck_sequence.py", &input);
    let close = |name: &str, a: f64, b: &serde_json::Value, rel: f64, abs: f64| {
        let b = b.as_f64().unwrap_or_else(|| panic!("{name}: {b}"));
        assert!(
            (a - b).abs() <= abs + rel * b.abs(),
            "{name}: ours {a}, numpy {b}"
        );
    };
    close("scale", ours.scale_alignment, &t["scale"], 1e-9, 1e-12);
    assert!(
        (ours.scale_alignment - 1.0 / k).abs() < 0.01,
        "ŝ {}",
        ours.scale_alignment
    );
    close(
        "chamfer_cm",
        ours.chamfer_cm.expect("cd"),
        &t["chamfer_cm"],
        0.06,
        0.01,
    );
    close(
        "cd_moving_cm",
        ours.cd_moving_cm.expect("cd"),
        &t["cd_moving_cm"],
        0.06,
        0.01,
    );
    close(
        "cd_static_cm",
        ours.cd_static_cm.expect("cd"),
        &t["cd_static_cm"],
        0.06,
        0.01,
    );
    close(
        "cd_w_m2",
        ours.cd_sq_whole_m2.expect("cd"),
        &t["cd_w_m2"],
        0.12,
        1e-7,
    );
    close(
        "cd_m_m2",
        ours.cd_sq_moving_m2.expect("cd"),
        &t["cd_m_m2"],
        0.12,
        1e-7,
    );
    close(
        "cd_s_m2",
        ours.cd_sq_static_m2.expect("cd"),
        &t["cd_s_m2"],
        0.12,
        1e-7,
    );
    let rigid = ours.rigid.as_ref().expect("rigid");
    close(
        "rotation_mean_deg",
        rigid.rotation_mean_deg,
        &t["rotation_mean_deg"],
        1e-6,
        1e-6,
    );
    close(
        "rotation_median_deg",
        rigid.rotation_median_deg,
        &t["rotation_median_deg"],
        1e-6,
        1e-6,
    );
    close(
        "translation_mean_cm",
        rigid.translation_mean_cm,
        &t["translation_mean_cm"],
        1e-6,
        1e-6,
    );
    close(
        "translation_median_cm",
        rigid.translation_median_cm,
        &t["translation_median_cm"],
        1e-6,
        1e-6,
    );
    assert_eq!(ours.joints.len(), 2);
    for (i, j) in ours.joints.iter().enumerate() {
        let tj = &t["joints"][i];
        close(
            "axis",
            j.axis_angle_rad.expect("axis"),
            &tj["axis_rad"],
            1e-9,
            1e-9,
        );
        close(
            "state",
            j.state_error.expect("state"),
            &tj["state"],
            1e-9,
            1e-9,
        );
        match j.axis_distance_m {
            Some(d) => close("position", d, &tj["position_m"], 1e-9, 1e-9),
            None => assert!(tj["position_m"].is_null()),
        }
    }
    // The injected joint offsets come back: 3° on the door, 0.02 units on the drawer.
    let door = ours
        .joints
        .iter()
        .find(|j| j.gt_joint == "door_hinge")
        .expect("door");
    assert!((door.state_error.expect("s") - 3f64.to_radians()).abs() < 1e-6);
}

#[test]
fn the_general_suite_has_24_generated_objects_in_three_hard_captures_each() {
    use agentstar_bench::suite::{hard_sequence, SUITES};
    use agentstar_synth::{Motion, ObjectSpec, Symmetry};
    assert!(SUITES.contains(&"general"));
    let specs = agentstar_bench::suite("general").expect("general");
    let mut objects: Vec<&str> = specs.iter().map(|s| s.synth.object.as_str()).collect();
    objects.dedup();
    assert!(objects.len() >= 24, "{objects:?}");
    assert_eq!(specs.len(), 3 * objects.len());
    for o in &objects {
        let seeds: std::collections::BTreeSet<u64> = specs
            .iter()
            .filter(|s| s.synth.object == *o)
            .map(|s| s.synth.seed)
            .collect();
        assert_eq!(seeds.len(), 3, "{o}: three capture seeds");
    }
    for s in &specs {
        // The hard suite's captures, with only the object and seed changed.
        assert_eq!(s.synth, hard_sequence(&s.synth.object, s.synth.seed).synth);
        assert_eq!(s.synth.motion, Some(Motion::HardHeld));
        assert_eq!(s.synth.frames, 20);
        assert_eq!(s.synth.between, 0);
    }
    // A mix: rigid and articulated; real symmetries (a plain body), symmetric outlines told
    // apart by a print, and objects with none.
    let resolved: Vec<ObjectSpec> = objects
        .iter()
        .map(|o| ObjectSpec::resolve(o).expect("generated"))
        .collect();
    let articulated = resolved
        .iter()
        .filter(|o| o.family == agentstar_synth::Family::Arctic)
        .count();
    let symmetric = resolved
        .iter()
        .filter(|o| o.symmetry != Symmetry::None)
        .count();
    assert!(
        articulated >= 6 && resolved.len() - articulated >= 6,
        "{articulated}"
    );
    assert!(
        symmetric >= 6 && resolved.len() - symmetric >= 6,
        "{symmetric}"
    );
}

#[test]
fn a_generated_object_is_tracked_and_its_errors_reduced_by_its_symmetries() {
    // gen-0: a plain body (its symmetries are real), in a short capture with in-between
    // frames, as `--between 2` makes the general suite's.
    let spec = agentstar_synth::ObjectSpec::resolve("gen-0").expect("generated");
    assert_ne!(spec.symmetry, agentstar_synth::Symmetry::None);
    let capture = synthesize(&SynthConfig {
        between: 2,
        ..small("gen-0", 4)
    })
    .expect("synth");
    assert_eq!(capture.between.len(), 2 * (capture.frames.len() - 1));
    let (r, poses) = run_sequence(
        &capture,
        Method::Tracker,
        &RunConfig {
            local_evals: 600,
            samples: 2000,
            ..RunConfig::default()
        },
    )
    .expect("run");
    assert_eq!(poses.len(), capture.frames.len());
    let reduced = r
        .symmetry_reduced
        .as_ref()
        .expect("reduced by its symmetries");
    assert_eq!(reduced.symmetries, spec.symmetry.rotations().len());
    // Reduction picks, per frame, the equivalent truth nearest the prediction: never worse.
    let (raw, sym) = (
        r.metrics.rotation_mean_deg.expect("raw"),
        reduced.rotation_mean_deg.expect("sym"),
    );
    assert!(sym <= raw + 1e-9, "{sym} > {raw}");
    assert_eq!(r.info.object, "gen-0");
}

#[test]
fn the_general_table_gives_the_share_within_1cm_3deg_and_quantiles() {
    use agentstar_bench::misses::{FrameMiss, MissCause, Misses, Weighed};
    use agentstar_bench::run::ReducedErrors;
    use agentstar_bench::table::{general_table, histogram, misses_table, quantile};
    let reduced = |epe: f64, rot: f64| ReducedErrors {
        symmetries: 3,
        epe_cm: Some(epe),
        rotation_mean_deg: Some(rot),
        rotation_median_deg: Some(rot),
        translation_mean_cm: Some(0.1),
        translation_median_cm: Some(0.1),
    };
    let mut rs = vec![
        fake("gen-0-hard-held-s1000", "hot3d", "tracker", 5.0, 0.95),
        fake("gen-0-hard-held-s1001", "hot3d", "tracker", 0.4, 0.97),
        fake("gen-2-hard-held-s1020", "arctic", "tracker", 0.8, 0.96),
        fake("gen-2-hard-held-s1021", "arctic", "tracker", 2.0, 0.9),
    ];
    // gen-0 lists symmetries: its first sequence is within after reduction, not before.
    rs[0].symmetry_reduced = Some(reduced(0.6, 2.0));
    rs[1].symmetry_reduced = Some(reduced(0.4, 1.0));
    for r in &mut rs {
        r.info.object = r.info.id.split("-hard").next().unwrap_or_default().into();
    }
    let t = general_table(&rs);
    // Within 1 cm and 3°: s1000 (after reduction), s1001, s1020; not s1021 (2 cm).
    assert!(t.contains("| tracker · all | 2 | 4 | 3 (75%) |"), "{t}");
    assert!(t.contains("| tracker · rigid | 1 | 2 | 2 (100%) |"), "{t}");
    assert!(
        t.contains("| tracker · no symmetry | 1 | 2 | 1 (50%) |"),
        "{t}"
    );
    // EPE after reduction: 0.4, 0.6, 0.8, 2.0, by linear interpolation.
    assert!(
        t.contains("| 0.40 / 0.55 / 0.70 / 1.10 / 1.64 / 2.00 |"),
        "{t}"
    );
    assert!(
        t.contains("EPE sym. (cm): ≤ 0.5: 1 · 0.5–1: 2 · 1–2: 1 · 2–5: 0"),
        "{t}"
    );
    assert!(
        t.contains("| gen-2-hard-held-s1021 | tracker | articulated | 0 |"),
        "{t}"
    );
    // Where the misses come from: none recorded, no section; two misses of one sequence,
    // counted per method and named with its worst frame.
    assert_eq!(misses_table(&rs), "");
    let miss = |frame: &str, rotation_deg: f64, cause: MissCause| FrameMiss {
        frame: frame.into(),
        rotation_deg,
        gate_tracked: 0.97,
        gate_truth: 0.968,
        model_ncc_tracked: Some(0.1),
        model_ncc_truth: Some(0.5),
        cause,
        weighed: Some(if rotation_deg > 90.0 {
            Weighed::NotTaken
        } else {
            Weighed::Absent
        }),
    };
    rs[3].misses = Some(Misses {
        search: 1,
        colours: 1,
        evidence: 0,
        frames: vec![
            miss("000010.png", 12.0, MissCause::Search),
            miss("000020.png", 178.5, MissCause::Colours),
        ],
    });
    let t = misses_table(&rs);
    assert!(
        t.contains("| tracker | 16 | 2 | 1 | 1 | 0 | 0 / 1 / 1 |"),
        "{t}"
    );
    assert!(
        t.contains("| gen-2-hard-held-s1021 | tracker | 2 | 1 | 1 | 0 | 0 / 1 / 1 | 000020.png: 178.5°, 0.9700 / 0.9680, 0.10 / 0.50 |"),
        "{t}"
    );
    assert_eq!(quantile(&[], 0.5), None);
    assert_eq!(quantile(&[1.0, 3.0], 0.5), Some(2.0));
    assert_eq!(
        histogram(&[0.5, 0.6, 11.0], &[0.5, 1.0, 10.0]),
        vec![1, 1, 0, 1]
    );
}

#[test]
fn the_general_suite_runs_over_other_generator_seeds_and_captures() {
    use agentstar_bench::suite::{general_suite, general_suite_over, parse_seed_range};
    let fresh = general_suite_over(parse_seed_range("24..27").expect("range"), 1);
    let names: Vec<(&str, u64)> = fresh
        .iter()
        .map(|s| (s.synth.object.as_str(), s.synth.seed))
        .collect();
    assert_eq!(
        names,
        [("gen-24", 1240), ("gen-25", 1250), ("gen-26", 1260)]
    );
    // The suite itself is the same function over its own range.
    let own = general_suite_over(0..24, 3);
    let suite = general_suite();
    assert_eq!(own.len(), suite.len());
    assert!(own.iter().zip(&suite).all(|(a, b)| a.synth == b.synth));
    for bad in ["48..24", "5..5", "24-48", "a..b", "", "..3"] {
        let e = parse_seed_range(bad).expect_err(bad).to_string();
        assert!(e.contains("START..END"), "{bad}: {e}");
    }
    assert_eq!(parse_seed_range(" 0..2 ").expect("spaces"), 0..2);
}
