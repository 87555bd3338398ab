//! Hypotheses refined before ranking: a 180° flip of a slightly wrong pose is found and
//! refined back to the truth, and the lid ↔ base twin of a laptop-like model is found from
//! the wrong basin with both basins kept.

use agentstar_geom::pose::ObjectPose;
use agentstar_geom::primitives::cuboid;
use agentstar_geom::{KinematicTree, ObjectModel, Part, Point3, UnitQuaternion, Vector3};
use agentstar_track::hypotheses::{
    basins, polish_last, refine_above, refine_each, refine_first_pass, refine_local,
    refine_local_with, refine_ranked, refine_rest, LastPass, LocalWindow,
};
use agentstar_track::objective::FrameProblem;
use agentstar_track::search::{sweep, Strategy, SweepConfig};
use agentstar_track::space::{Dof, DofRange, SearchSpace};
use agentstar_track::update::{apply_object_rotation, flip, GenPose};

mod common;
use common::case::hinged::with_lid_hinge;
use common::case::{case_model, truth};
use common::view::{camera, target_of};

fn tilt(deg: f64) -> UnitQuaternion {
    UnitQuaternion::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vector3::new(0.4, -1.0, 0.3)),
        deg.to_radians(),
    )
}

fn rotation_error_deg(a: &GenPose, b: &GenPose) -> f64 {
    a.pose.rotation.angle_to(&b.pose.rotation).to_degrees()
}

#[test]
fn a_flip_of_a_slightly_wrong_pose_is_found_and_refined() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(3.0);
    let target = target_of(&model, &gt, scale);
    // The pose a tracker left: the truth flipped end for end, then 7° and 4% of depth off.
    let pivot = model.pivot(&gt.states);
    let flipped = apply_object_rotation(&gt.pose, scale, &pivot, &flip('z').expect("flip"));
    let left = GenPose {
        pose: ObjectPose::new(tilt(7.0) * flipped.rotation, flipped.translation * 1.04),
        states: gt.states.clone(),
    };
    let problem = FrameProblem::new(&model, camera(), &target, scale, left.clone());
    // What `oapply --set flips` ranks: the pose and its three flips.
    let hypotheses: Vec<GenPose> = std::iter::once(UnitQuaternion::identity())
        .chain(['x', 'y', 'z'].iter().filter_map(|&a| flip(a)))
        .map(|q| GenPose {
            pose: apply_object_rotation(&left.pose, scale, &pivot, &q),
            states: left.states.clone(),
        })
        .collect();
    let refined = refine_each(&problem, &hypotheses, &LocalWindow::basin(), 5).expect("refine");
    let best = refined
        .iter()
        .max_by(|a, b| a.score.combined.total_cmp(&b.score.combined))
        .expect("one");
    assert!(
        rotation_error_deg(&best.pose, &gt) < 2.0 && best.score.gate > 0.98,
        "best refined hypothesis {:.1}° from the truth, IoU {:.4}",
        rotation_error_deg(&best.pose, &gt),
        best.score.gate
    );
    // Its placed pose was the flip, and the refinement is what made it win.
    assert!(
        best.unrefined.combined < best.score.combined - 0.02,
        "unrefined {:.4}, refined {:.4}",
        best.unrefined.combined,
        best.score.combined
    );
}

/// Two slabs of the same outline, the lid hinged on the base's back edge.
fn laptop() -> ObjectModel {
    let base = cuboid(1.0, 0.7, 0.04)
        .expect("base")
        .translated(Vector3::new(0.0, 0.0, 0.02));
    let lid = cuboid(1.0, 0.7, 0.03)
        .expect("lid")
        .translated(Vector3::new(0.0, 0.0, 0.055));
    with_lid_hinge(
        vec![
            Part::new("base", base, [0.3, 0.3, 0.3]),
            Part::new("lid", lid, [0.6, 0.6, 0.6]),
        ],
        Vector3::new(0.0, 0.35, 0.04),
        -Vector3::x(),
        150.0,
    )
}

#[test]
fn the_lid_base_twin_is_found_and_refined_with_both_basins_kept() {
    let model = laptop();
    let scale = 0.4;
    let states = vec![100f64.to_radians()];
    let gt = GenPose {
        pose: ObjectPose::new(
            UnitQuaternion::from_euler_angles(-1.1, 0.5, 0.3),
            Vector3::new(0.02, -0.01, 1.3),
        ),
        states: states.clone(),
    };
    let target = target_of(&model, &gt, scale);
    // The twin: a half turn about the line that bisects the two slabs, through the hinge,
    // perpendicular to it; it swaps lid and base with the joint state unchanged.
    let transforms = model.tree.part_transforms(&states);
    let hinge = Point3::new(0.0, 0.35, 0.04);
    let lid_centre = transforms[1] * Point3::new(0.0, 0.0, 0.055);
    let base_dir = (Point3::new(0.0, 0.0, 0.02) - hinge).normalize();
    let lid_dir = (lid_centre - hinge).normalize();
    let bisector = nalgebra::Unit::new_normalize(base_dir + lid_dir);
    let half_turn = UnitQuaternion::from_axis_angle(&bisector, std::f64::consts::PI);
    let twin = GenPose {
        pose: apply_object_rotation(&gt.pose, scale, &hinge, &half_turn),
        states: states.clone(),
    };
    let problem = FrameProblem::new(&model, camera(), &target, scale, twin.clone());
    let twin_iou = problem.evaluator().score(&twin).gate;
    assert!(
        twin_iou > 0.9 && rotation_error_deg(&twin, &gt) > 170.0,
        "precondition: the twin explains the mask (IoU {twin_iou:.4})"
    );
    // A tracker left in the twin's basin, a few degrees off.
    let left = GenPose {
        pose: ObjectPose::new(tilt(5.0) * twin.pose.rotation, twin.pose.translation),
        states: vec![92f64.to_radians()],
    };
    let found = basins(&problem, &left, 24, 12, &LocalWindow::basin(), 11).expect("basins");
    let report: Vec<String> = found
        .iter()
        .map(|r| {
            format!(
                "IoU {:.4} (placed {:.4}), {:.1}° from the truth, joint {:.1}°",
                r.score.gate,
                r.unrefined.gate,
                rotation_error_deg(&r.pose, &gt),
                r.pose.states[0].to_degrees()
            )
        })
        .collect();
    let truth_basin = found
        .iter()
        .find(|r| rotation_error_deg(&r.pose, &gt) < 3.0);
    let twin_basin = found
        .iter()
        .find(|r| rotation_error_deg(&r.pose, &twin) < 3.0);
    assert!(
        truth_basin.is_some_and(
            |r| r.score.gate > 0.98 && (r.pose.states[0] - states[0]).abs().to_degrees() < 3.0
        ),
        "the true basin was not found:\n{}",
        report.join("\n")
    );
    assert!(
        twin_basin.is_some_and(|r| r.score.gate > 0.95),
        "the twin basin was not kept:\n{}",
        report.join("\n")
    );
}

/// Two slabs of one outline and thickness, mirror images about the hinge's plane when closed
/// (the hard suite's `twinlaptop`): at any opening, a half-turn about a principal axis
/// through the centroid swaps lid and base exactly.
fn twin_slabs() -> ObjectModel {
    let slab = |z: f64| {
        cuboid(1.0, 0.7, 0.03)
            .expect("slab")
            .translated(Vector3::new(0.0, 0.0, z))
    };
    with_lid_hinge(
        vec![
            Part::new("base", slab(-0.016), [0.3, 0.3, 0.3]),
            Part::new("lid", slab(0.016), [0.6, 0.6, 0.6]),
        ],
        Vector3::new(0.0, 0.35, 0.0),
        -Vector3::x(),
        150.0,
    )
}

#[test]
fn a_twin_candidate_swaps_equal_slabs_exactly_at_any_opening() {
    let model = twin_slabs();
    let scale = 0.3;
    for deg in [10.0f64, 35.0, 70.0, 108.0, 140.0] {
        let gt = GenPose {
            pose: ObjectPose::new(
                UnitQuaternion::from_euler_angles(-1.1, 0.5, 0.3),
                Vector3::new(0.02, -0.01, 1.0),
            ),
            states: vec![deg.to_radians()],
        };
        let target = target_of(&model, &gt, scale);
        let problem = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
        let mut ev = problem.evaluator();
        let scores: Vec<(f64, f64)> =
            agentstar_track::hypotheses::twin_candidates(&model, scale, &gt)
                .iter()
                .map(|g| (ev.score(g).gate, rotation_error_deg(g, &gt)))
                .collect();
        assert!(
            scores
                .iter()
                .any(|&(iou, angle)| iou > 0.99 && angle > 170.0),
            "opening {deg}°: no exact twin among {scores:?}"
        );
    }
}

/// A rigid can's pose, turned askew a metre from the camera.
fn a_rigid_can_seen_askew() -> GenPose {
    GenPose {
        pose: ObjectPose::new(
            UnitQuaternion::from_euler_angles(1.2, 0.4, -0.3),
            Vector3::new(0.01, 0.02, 1.0),
        ),
        states: vec![],
    }
}

#[test]
fn a_half_turn_about_a_principal_axis_keeps_the_outline_of_a_shape_heavy_at_one_end() {
    // A can with a heavy slab inside its bottom (as a mug's solid base under its open
    // top): the outline is symmetric end for end, the mass is not. The centroid sits 0.055
    // below the middle; a half-turn through it would move the outline by 0.11.
    let can = agentstar_geom::primitives::cylinder(0.3, 1.0, 48).expect("can");
    let slab = agentstar_geom::primitives::cylinder(0.29, 0.2, 48)
        .expect("slab")
        .translated(Vector3::new(0.0, 0.0, -0.35));
    let model = ObjectModel {
        tree: KinematicTree::rigid(2),
        parts: vec![
            Part::new("can", can, [0.5, 0.5, 0.5]),
            Part::new("base", slab, [0.5, 0.5, 0.5]),
        ],
    };
    let scale = 0.3;
    let gt = a_rigid_can_seen_askew();
    let target = target_of(&model, &gt, scale);
    let problem = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
    let mut ev = problem.evaluator();
    let (centre, axes) = agentstar_track::hypotheses::principal_axes(&model, &[]).expect("axes");
    assert!(centre.z.abs() < 0.01, "centre {centre:?}");
    // Every axis across the can: a half-turn about it swaps the ends.
    let across: Vec<&Vector3> = axes.iter().filter(|a| a.z.abs() < 0.1).collect();
    assert_eq!(across.len(), 2, "axes {axes:?}");
    for axis in across {
        let q = UnitQuaternion::from_axis_angle(
            &agentstar_geom::nalgebra::Unit::new_normalize(*axis),
            std::f64::consts::PI,
        );
        let twin = GenPose {
            pose: apply_object_rotation(&gt.pose, scale, &centre, &q),
            states: vec![],
        };
        let iou = ev.score(&twin).gate;
        assert!(iou > 0.99, "the half-turn about {axis:?} scores {iou}");
    }
}

#[test]
fn coarse_passes_at_half_resolution_reach_the_full_resolution_optimum() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(2.0);
    let target = target_of(&model, &gt, scale);
    let halved = target.halved();
    let start = GenPose {
        pose: ObjectPose::new(
            tilt(14.0) * gt.pose.rotation,
            gt.pose.translation + Vector3::new(0.02, -0.015, 0.05),
        ),
        states: vec![gt.states[0] + 0.2],
    };
    let problem = FrameProblem::new(&model, camera(), &target, scale, start.clone());
    let full = refine_local(&problem, &start, &LocalWindow::polish(), 5).expect("refine");
    let coarse_problem = problem.clone().with_coarse(&halved);
    assert!(coarse_problem.coarsened().is_some());
    let coarse = refine_local(&coarse_problem, &start, &LocalWindow::polish(), 5).expect("refine");
    // The score returned is the full-resolution one of the pose returned.
    let own = problem.evaluator().combined(&coarse.0);
    assert_eq!(own, coarse.1);
    assert!(coarse.1 >= 0.99, "coarse {} (full {})", coarse.1, full.1);
    assert!(
        coarse.1 >= full.1 - 0.003,
        "coarse {} against full {}",
        coarse.1,
        full.1
    );
    assert!(rotation_error_deg(&coarse.0, &gt) < 2.0);
    // Never worse than the start, whatever the coarse passes found.
    let at_truth = refine_local(&coarse_problem, &gt, &LocalWindow::polish(), 9).expect("refine");
    assert!(at_truth.1 >= problem.evaluator().combined(&gt));
}

/// A start a polish begins from (the `refine` benchmark's): `gt` turned 2.5° about an axis
/// drawn with `seed`, its joint 3° off, shifted 0.3% of the depth sideways.
fn polish_start(gt: &GenPose, seed: u64) -> GenPose {
    let mut rng = agentstar_optim::Rng::new(seed);
    let axis = Vector3::new(rng.normal(), rng.normal(), rng.normal());
    let mut start = gt.clone();
    start.pose.rotation = UnitQuaternion::from_axis_angle(
        &agentstar_geom::nalgebra::Unit::new_normalize(axis),
        2.5f64.to_radians(),
    ) * gt.pose.rotation;
    start.states[0] -= 3f64.to_radians();
    start.pose.translation.x += 0.003 * gt.pose.translation.z;
    start
}

/// The narrow end searched by CMA-ES on the sub-pixel score follows the ridge that couples
/// a turn with a shift and the joint to the truth, from starts where the tracker's passes
/// stop a degree or more away (keyframes 13 and 17 of the `refine` benchmark's 2026-12-06
/// run: 4.9° and 2.5° left), and never ends worse than it started.
#[test]
fn the_cma_end_of_a_refinement_follows_the_ridge_to_the_truth() {
    let model = case_model();
    let scale = 0.5;
    for (k, trial) in [(13u64, 1u64), (17, 1)] {
        let gt = truth(k as f64);
        let target = target_of(&model, &gt, scale);
        let halved = target.halved();
        let start = polish_start(&gt, 100 * k + trial);
        let problem =
            FrameProblem::new(&model, camera(), &target, scale, start.clone()).with_coarse(&halved);
        let window = LocalWindow::polish();
        let (pose, score, evals) =
            refine_local_with(&problem, &start, &window, 7 + trial, LastPass::CmaSoft)
                .expect("refine");
        let mut ev = problem.evaluator();
        assert_eq!(score, ev.combined(&pose));
        assert!(score >= ev.combined(&start));
        let rotation = rotation_error_deg(&pose, &gt);
        let joint = (pose.states[0] - gt.states[0]).to_degrees().abs();
        assert!(
            rotation < 1.0 && joint < 1.0,
            "keyframe {k}: {rotation:.2}° and {joint:.2}° of joint left (IoU {score:.4})"
        );
        assert!(evals < 4_000, "{evals}");
        // Deterministic for its seed.
        let again = refine_local_with(&problem, &start, &window, 7 + trial, LastPass::CmaSoft)
            .expect("refine");
        assert_eq!(again.0, pose);
    }
}

/// The tracker's last polish, from where its refinement stopped (the same starts as the CMA
/// test above: 2.5° turned, 3° of joint, 0.3% of the depth sideways), ends nearer the truth
/// (within 1°, or most of the way where the refinement stopped farther than its box)
/// and never scores under where it started; at a pose nothing beats (the truth on its own
/// exact mask) it returns that pose itself.
#[test]
fn the_last_polish_takes_a_refined_pose_nearer_the_truth_and_keeps_one_nothing_beats() {
    let model = case_model();
    let scale = 0.5;
    let window = LocalWindow::polish();
    for k in [13u64, 17] {
        let gt = truth(k as f64);
        let target = target_of(&model, &gt, scale);
        let halved = target.halved();
        let start = polish_start(&gt, 100 * k + 1);
        let problem =
            FrameProblem::new(&model, camera(), &target, scale, start.clone()).with_coarse(&halved);
        let (refined, refined_score, _) =
            refine_local(&problem, &start, &window, 8).expect("refine");
        let (polished, score, evals) =
            polish_last(&problem, &refined, &window, 11).expect("polish");
        let mut ev = problem.evaluator();
        assert_eq!(score, ev.combined(&polished));
        assert!(score >= refined_score, "{score} < {refined_score}");
        let before = rotation_error_deg(&refined, &gt);
        let rotation = rotation_error_deg(&polished, &gt);
        let joint = (polished.states[0] - gt.states[0]).to_degrees().abs();
        // Its box (3.6°) may not reach all the way from where a refinement stopped far
        // out: it closes most of the way (keyframe 13: 4.9° → 1.25°, measured 2026-12-06).
        assert!(
            rotation < 1.0f64.max(0.3 * before) && joint < 1.0,
            "keyframe {k}: {before:.2}° after the refinement, {rotation:.2}° and {joint:.2}° of joint after the polish (IoU {score:.4})"
        );
        assert!(evals < 2_000, "{evals}");
        // Nothing beats the truth on its own mask: kept as it is.
        let at_truth = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
        let (kept, kept_score, _) = polish_last(&at_truth, &gt, &window, 11).expect("polish");
        assert_eq!(kept, gt);
        assert_eq!(kept_score, at_truth.evaluator().combined(&gt));
    }
}

/// With a held axis (a round outline's, which the tracker's problems carry), the last polish
/// leaves the turn about it where the pose had it, however the rest moves: the silhouette
/// cannot see that turn, and the polish must not choose it.
#[test]
fn the_last_polish_keeps_the_turn_about_a_held_axis() {
    let can = agentstar_geom::primitives::cylinder(0.3, 1.0, 48).expect("can");
    let model = ObjectModel {
        tree: KinematicTree::rigid(1),
        parts: vec![Part::new("can", can, [0.5, 0.5, 0.5])],
    };
    let scale = 0.3;
    let gt = a_rigid_can_seen_askew();
    let target = target_of(&model, &gt, scale);
    let axis = agentstar_track::axis::SymmetryAxis {
        centre: Point3::origin(),
        axis: Vector3::z(),
    };
    // Turned 40° about the can's axis (invisible) and 2° across it (visible).
    let turned = axis.turn(&gt, scale, 40.0);
    let start = GenPose {
        pose: ObjectPose::new(tilt(2.0) * turned.pose.rotation, turned.pose.translation),
        states: vec![],
    };
    let twist_of = |p: &GenPose| {
        agentstar_track::axis::twist_deg(
            &(start.pose.rotation.inverse() * p.pose.rotation),
            &axis.axis,
        )
    };
    let window = LocalWindow::polish();
    let held = FrameProblem::new(&model, camera(), &target, scale, start.clone())
        .with_held_axis(Some(axis));
    let (polished, score, _) = polish_last(&held, &start, &window, 3).expect("polish");
    assert!(score > held.evaluator().combined(&start), "{score}");
    let across = agentstar_track::axis::angle_across(
        &(turned.pose.rotation.inverse() * polished.pose.rotation),
        &axis.axis,
    )
    .to_degrees();
    assert!(across < 0.7, "{across:.2}° across the axis left");
    assert!(twist_of(&polished).abs() < 1e-6, "{}", twist_of(&polished));
}

#[test]
fn a_refinement_above_its_floor_is_the_whole_one_and_under_it_stops_after_one_pass() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(1.0);
    let target = target_of(&model, &gt, scale);
    let halved = target.halved();
    let problem =
        FrameProblem::new(&model, camera(), &target, scale, gt.clone()).with_coarse(&halved);
    let window = LocalWindow::polish();
    // Near the truth: above any floor it can reach, exactly refine_local's pose.
    let near = GenPose {
        pose: ObjectPose::new(tilt(8.0) * gt.pose.rotation, gt.pose.translation * 1.02),
        states: gt.states.clone(),
    };
    let (whole, whole_score, whole_evals) =
        refine_local(&problem, &near, &window, 3).expect("refine");
    let (above, above_evals) = refine_above(&problem, &near, &window, 3, 0.5).expect("refine");
    assert_eq!(above, whole);
    assert!(whole_score > 0.98, "{whole_score}");
    // A floor over what the first pass reaches: it stops there, with about half the
    // evaluations, never worse than where it started.
    let (stopped, stopped_evals) = refine_above(&problem, &near, &window, 3, 1.01).expect("refine");
    assert!(
        stopped_evals * 10 < whole_evals * 7 && above_evals >= whole_evals,
        "{stopped_evals} stopped, {whole_evals} whole, {above_evals} above"
    );
    let mut ev = problem.evaluator();
    assert!(ev.combined(&stopped) >= ev.combined(&near));
    // The same split by hand: the first pass, then the rest, is refine_local.
    let (first, first_score, _) = refine_first_pass(&problem, &near, &window, 3).expect("first");
    assert_eq!(first_score, ev.combined(&first));
    let (rest, rest_score, _) = refine_rest(&problem, &near, &first, &window, 3).expect("rest");
    assert_eq!((rest, rest_score), (whole, whole_score));
}

#[test]
fn starts_that_refine_to_one_pose_are_ranked_once() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(3.0);
    let target = target_of(&model, &gt, scale);
    // The pose left 8° off the truth; object-frame candidates about z: three starts in the
    // truth's basin (-10°, 0°, +10° from the left pose) and the end-for-end flip.
    let left = GenPose {
        pose: ObjectPose::new(tilt(8.0) * gt.pose.rotation, gt.pose.translation),
        states: gt.states.clone(),
    };
    let problem = FrameProblem::new(&model, camera(), &target, scale, left);
    let space = SearchSpace {
        ranges: [Dof::Rx, Dof::Ry, Dof::Rz]
            .into_iter()
            .map(|dof| DofRange {
                dof,
                lo: -360.0,
                hi: 360.0,
                steps: None,
            })
            .collect(),
        notes: vec![],
    };
    let starts = vec![
        vec![0.0, 0.0, -10.0],
        vec![0.0, 0.0, 0.0],
        vec![0.0, 0.0, 10.0],
        vec![180.0, 0.0, 0.0],
    ];
    let cfg = SweepConfig {
        topk: starts.len(),
        strategy: Strategy::Candidates(starts.clone()),
        ..SweepConfig::default()
    };
    let placed = sweep(&problem, &space, &cfg).expect("sweep");
    assert_eq!(placed.ranked.len(), 4, "every start placed");
    let refined = refine_ranked(&problem, placed, &LocalWindow::basin(), 17).expect("refine");
    // The three starts in the truth's basin end at the truth: one row, the best first.
    let at_truth = refined
        .ranked
        .iter()
        .filter(|c| rotation_error_deg(&c.pose, &gt) < 3.0)
        .count();
    assert_eq!(
        at_truth,
        1,
        "{:?}",
        refined
            .ranked
            .iter()
            .map(|c| (&c.x, rotation_error_deg(&c.pose, &gt)))
            .collect::<Vec<_>>()
    );
    assert!(rotation_error_deg(&refined.ranked[0].pose, &gt) < 3.0);
    // The flip stays its own row, and ranks are consecutive.
    assert!(refined.ranked.len() >= 2, "the flip is kept");
    assert!(refined.ranked.iter().enumerate().all(|(i, c)| c.rank == i));
    for (i, a) in refined.ranked.iter().enumerate() {
        for b in &refined.ranked[i + 1..] {
            assert!(
                rotation_error_deg(&a.pose, &b.pose) >= 1.0
                    || (a.pose.pose.translation - b.pose.pose.translation).norm()
                        > 0.005 * a.pose.pose.translation.z,
                "two rows at one pose"
            );
        }
    }
}
