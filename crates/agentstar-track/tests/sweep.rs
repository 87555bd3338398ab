//! Sweeps that search: a population that starts flat still explores its box, and rank 0 is
//! never worse than the starting pose.

use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{UnitQuaternion, Vector3};
use agentstar_track::objective::FrameProblem;
use agentstar_track::search::{sweep, SweepConfig};
use agentstar_track::space::{parse_spec, Grammar};
use agentstar_track::update::GenPose;

mod common;
use common::case::{case_model, truth};
use common::view::{camera, target_of};

/// The true pose turned by `deg` about a tilted axis through the camera origin's view.
fn off_by(gt: &GenPose, deg: f64) -> GenPose {
    let off = UnitQuaternion::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vector3::new(0.3, 1.0, -0.2)),
        deg.to_radians(),
    );
    GenPose {
        pose: ObjectPose::new(off * gt.pose.rotation, gt.pose.translation),
        states: gt.states.clone(),
    }
}

#[test]
fn a_sweep_from_a_flat_initial_population_moves() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(1.0);
    let target = target_of(&model, &gt, scale);
    let problem = FrameProblem::new(&model, camera(), &target, scale, off_by(&gt, 1.5));
    let start = problem.evaluator().score(&problem.base).combined;
    // A narrow box: the initial population scores within about 1% of each other, the case
    // where SciPy's relative test stops after a generation or two.
    let space = parse_spec(
        "roll:-2,2;yaw:-2,2;pitch:-2,2",
        &model.tree,
        Grammar::Camera,
    )
    .expect("space");
    let scipy = sweep(&problem, &space, &SweepConfig::default().scipy_stop()).expect("sweep");
    assert!(
        scipy.restarts.iter().all(|r| r.generations < 10),
        "precondition: the relative rule stops within a few generations ({:?})",
        scipy
            .restarts
            .iter()
            .map(|r| r.generations)
            .collect::<Vec<_>>()
    );
    let r = sweep(&problem, &space, &SweepConfig::default()).expect("sweep");
    assert!(
        r.restarts.iter().all(|x| x.generations >= 10),
        "{:?}",
        r.restarts.iter().map(|x| x.generations).collect::<Vec<_>>()
    );
    let best = &r.ranked[0];
    assert!(!best.kept_start);
    let moved = best
        .pose
        .pose
        .rotation
        .angle_to(&problem.base.pose.rotation);
    let error = best.pose.pose.rotation.angle_to(&gt.pose.rotation);
    assert!(
        moved.to_degrees() > 0.5 && error.to_degrees() < 0.5,
        "moved {:.2}°, left {:.2}° from the truth",
        moved.to_degrees(),
        error.to_degrees()
    );
    assert!(
        best.score.combined > start + 0.002 && best.score.combined > scipy.ranked[0].score.combined,
        "IoU {:.4} from {start:.4} (relative rule: {:.4})",
        best.score.combined,
        scipy.ranked[0].score.combined
    );
}

#[test]
fn rank_zero_is_never_worse_than_the_start() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(2.0);
    let target = target_of(&model, &gt, scale);
    let problem = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
    let start = problem.evaluator().score(&problem.base).combined;
    // Boxes that exclude the start (which is the truth): no searched candidate can reach it.
    for (spec, strategy) in [
        (
            "yaw:20,40;pitch:10,30",
            agentstar_track::search::Strategy::De,
        ),
        (
            "yaw:20,40,3;pitch:10,30,3",
            agentstar_track::search::Strategy::Grid {
                default_steps: 3,
                refine: 1,
                shrink: 0.5,
            },
        ),
    ] {
        let space = parse_spec(spec, &model.tree, Grammar::Camera).expect("space");
        let r = sweep(
            &problem,
            &space,
            &SweepConfig {
                strategy,
                total_evals: 600,
                ..SweepConfig::default()
            },
        )
        .expect("sweep");
        assert!(r.ranked[0].kept_start, "{spec}");
        assert_eq!(r.ranked[0].score.combined, start, "{spec}");
        assert!(r.ranked[1..].iter().all(|c| c.score.combined < start));
    }
}

/// Play-test, 2026-12-02: a DE sweep whose start nothing beats listed the start six times
/// (every restart's winner). Distinct restarts are distinct candidates; repeats are dropped.
#[test]
fn a_de_sweep_lists_each_pose_once() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(2.0);
    let target = target_of(&model, &gt, scale);
    let problem = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
    let space = parse_spec("yaw:-10,10;pitch:-10,10", &model.tree, Grammar::Camera).expect("space");
    let r = sweep(
        &problem,
        &space,
        &SweepConfig {
            strategy: agentstar_track::search::Strategy::De,
            total_evals: 600,
            ..SweepConfig::default()
        },
    )
    .expect("sweep");
    for (i, a) in r.ranked.iter().enumerate() {
        for b in &r.ranked[i + 1..] {
            let same = a.x.iter().zip(&b.x).all(|(p, q)| (p - q).abs() <= 1e-9);
            assert!(
                !same,
                "ranks {} and {} are the same pose {:?}",
                a.rank, b.rank, a.x
            );
        }
    }
    assert_eq!(
        r.ranked[0].score.combined,
        problem.evaluator().score(&problem.base).combined
    );
}

/// Play-test, 2026-12-03: a DE sweep from a pose that nothing near beats returned one row,
/// the start; the other basins it passed through were lost. With runners-up asked for, the
/// best points it evaluated at least 10° from every kept candidate (and from each other) are
/// ranked too, flagged, scored as evaluated; without, none.
#[test]
fn a_de_sweep_ranks_other_basins_it_passed_through() {
    use agentstar_track::search::RUNNER_UP_DEG;
    let model = case_model();
    let scale = 0.5;
    let gt = truth(2.0);
    let target = target_of(&model, &gt, scale);
    let problem = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
    let space = parse_spec("yaw:-60,60;pitch:-60,60", &model.tree, Grammar::Camera).expect("space");
    let cfg = SweepConfig {
        total_evals: 1200,
        ..SweepConfig::default()
    };
    let plain = sweep(&problem, &space, &cfg).expect("sweep");
    assert!(plain.ranked.iter().all(|c| !c.runner_up));
    let r = sweep(
        &problem,
        &space,
        &SweepConfig {
            runners_up: 3,
            ..cfg
        },
    )
    .expect("sweep");
    let (others, kept): (Vec<_>, Vec<_>) = r.ranked.iter().partition(|c| c.runner_up);
    assert_eq!(
        others.len(),
        3,
        "{:?}",
        r.ranked.iter().map(|c| &c.x).collect::<Vec<_>>()
    );
    assert_eq!(kept.len(), plain.ranked.len());
    let mut ev = problem.evaluator();
    for (i, o) in others.iter().enumerate() {
        for c in kept.iter().chain(&others[..i]) {
            let deg = c
                .pose
                .pose
                .rotation
                .angle_to(&o.pose.pose.rotation)
                .to_degrees();
            assert!(deg >= RUNNER_UP_DEG - 1e-9, "{deg}° from another candidate");
        }
        assert_eq!(o.score.combined, ev.score(&o.pose).combined);
        assert!(o.score.combined < r.ranked[0].score.combined);
    }
    // Ranked by score, the runners-up among them.
    assert!(r
        .ranked
        .windows(2)
        .all(|w| w[0].score.combined >= w[1].score.combined));
}

/// Play-test, 2026-12-05: a grid over a joint whose part the mask cannot see scores every
/// value alike, and ranked the range's lower bound first; committing rank 0 wrote it.
#[test]
fn a_flat_grid_ranks_the_starts_own_value_first() {
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::Part;
    // A small block turning on a hinge inside a closed box: no state shows in the outline.
    let body = cuboid(1.0, 0.6, 0.4).expect("body");
    let inner = cuboid(0.1, 0.1, 0.1).expect("inner");
    let model = common::case::hinged::with_lid_hinge(
        vec![
            Part::new("body", body, [0.5; 3]),
            Part::new("lid", inner, [0.9, 0.2, 0.2]),
        ],
        Vector3::zeros(),
        Vector3::z(),
        90.0,
    );
    let scale = 0.5;
    let mut gt = truth(2.0);
    gt.states = vec![50f64.to_radians()];
    let target = target_of(&model, &gt, scale);
    let problem = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
    let space = parse_spec("hinge:0,90,10", &model.tree, Grammar::Object).expect("space");
    let r = sweep(
        &problem,
        &space,
        &SweepConfig {
            strategy: agentstar_track::search::Strategy::Grid {
                default_steps: 10,
                refine: 1,
                shrink: 0.5,
            },
            topk: 5,
            ..SweepConfig::default()
        },
    )
    .expect("sweep");
    // Every value ties (the precondition), and the one nearest the start's 50° comes first.
    assert!(r
        .ranked
        .iter()
        .all(|c| c.score.combined == r.ranked[0].score.combined));
    let first = r.ranked[0].pose.states[0].to_degrees();
    assert!((first - 50.0).abs() <= 5.0 + 1e-9, "rank 0 at {first:.1}°");
    let second = r.ranked[1].pose.states[0].to_degrees();
    assert!(
        (second - 50.0).abs() >= (first - 50.0).abs(),
        "{second:.1}°"
    );
}

/// Play-test, 2026-12-05: a whole-turn grid's best points all lay around the frame's own
/// basin. With runners-up, a grid also ranks its best points that far from those kept and
/// from each other: one per other basin.
#[test]
fn a_grids_runners_up_lie_apart_from_its_best_points_and_each_other() {
    let model = case_model();
    let scale = 0.5;
    let gt = truth(2.0);
    let target = target_of(&model, &gt, scale);
    let problem = FrameProblem::new(&model, camera(), &target, scale, gt.clone());
    let space = parse_spec("rz:-180,180,25", &model.tree, Grammar::Object).expect("space");
    let grid = agentstar_track::search::Strategy::Grid {
        default_steps: 25,
        refine: 0,
        shrink: 0.5,
    };
    let run = |runners_up: usize| {
        sweep(
            &problem,
            &space,
            &SweepConfig {
                strategy: grid.clone(),
                topk: 3,
                runners_up,
                runner_up_deg: 40.0,
                ..SweepConfig::default()
            },
        )
        .expect("sweep")
    };
    let apart = |a: &agentstar_track::Candidate, b: &agentstar_track::Candidate| {
        a.pose
            .pose
            .rotation
            .angle_to(&b.pose.pose.rotation)
            .to_degrees()
    };
    // Without: the three best points of a 15° grid, all around the truth.
    let plain = run(0);
    assert_eq!(plain.ranked.len(), 3);
    assert!(plain
        .ranked
        .iter()
        .all(|c| apart(c, &plain.ranked[0]) <= 30.0 + 1e-9));
    // With three: each at least 40° from the best points and from each other.
    let with = run(3);
    let (best, seen): (Vec<_>, Vec<_>) = with.ranked.iter().partition(|c| !c.runner_up);
    assert_eq!(
        (best.len(), seen.len()),
        (3, 3),
        "{:?}",
        with.ranked.iter().map(|c| &c.x).collect::<Vec<_>>()
    );
    for (k, r) in seen.iter().enumerate() {
        assert!(best.iter().all(|b| apart(r, b) >= 40.0 - 1e-9));
        assert!(seen[k + 1..].iter().all(|o| apart(r, o) >= 40.0 - 1e-9));
    }
}
