//! Search benchmarks: setup C of `shared/bench/README.md` (differential evolution recovers
//! the setup-A pose from a start 35° and 0.2 units away, all 6 DoF), and the automatic
//! tracker on a 20-keyframe articulated sequence (6 DoF + 1 joint), and the precision of the
//! tracker's local refinement on that sequence's frames. Prints medians.
//!
//! `cargo bench -p agentstar-track` (set `AGENTSTAR_BENCH_MESH` when `../shared` is elsewhere);
//! one of them by name: `cargo bench -p agentstar-track --bench search -- tracking` (or
//! `setup-c`, `refine`).

use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{KinematicTree, ObjectModel, Part, PinholeCamera, UnitQuaternion, Vector3};
use agentstar_render::{PosedModel, ScoreTarget, SilhouetteRenderer};
use agentstar_track::hypotheses::{refine_local_with, LastPass, LocalWindow};
use agentstar_track::objective::FrameProblem;
use agentstar_track::search::{sweep, SweepConfig};
use agentstar_track::space::{parse_spec, Grammar};
use agentstar_track::tracker::{track, TrackConfig, TrackFrame};
use agentstar_track::update::GenPose;
use std::time::Instant;

#[path = "../tests/common/case.rs"]
mod case;

fn target(model: &ObjectModel, cam: &PinholeCamera, g: &GenPose, scale: f64) -> ScoreTarget {
    let mut r = SilhouetteRenderer::new(cam.width, cam.height);
    ScoreTarget::new(
        r.render(
            cam,
            &PosedModel::new(model, &g.states, &g.pose.with_scale(scale)).instances,
        )
        .clone(),
        None,
    )
    .expect("target")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn setup_c() {
    let default =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/bench/mesh5k.obj");
    let path = std::env::var_os("AGENTSTAR_BENCH_MESH")
        .map(std::path::PathBuf::from)
        .unwrap_or(default);
    let mesh = agentstar_data::meshio::load_mesh(&path).expect("mesh5k.obj");
    let model = ObjectModel {
        tree: KinematicTree::rigid(1),
        parts: vec![Part::new("mesh5k", mesh, [0.7; 3])],
    };
    let cam = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.9, 0.3, -0.2, 0.25));
    let gt = GenPose {
        pose: ObjectPose::new(q, Vector3::new(0.05, -0.03, 3.0)),
        states: vec![],
    };
    let t = target(&model, &cam, &gt, 1.0);
    let mut times = Vec::new();
    let mut rot_errs = Vec::new();
    let mut trans_errs = Vec::new();
    let mut evals = Vec::new();
    for trial in 0..7u64 {
        // A start 35° and 0.2 units away, in a direction that changes per trial.
        let axis = nalgebra::Unit::new_normalize(Vector3::new(1.0, 0.3 * trial as f64 - 0.8, 0.5));
        let dir = Vector3::new((trial as f64).sin(), (trial as f64 * 1.7).cos(), 0.4).normalize();
        let start = GenPose {
            pose: ObjectPose::new(
                UnitQuaternion::from_axis_angle(&axis, 35f64.to_radians()) * q,
                gt.pose.translation + dir * 0.2,
            ),
            states: vec![],
        };
        let t0 = Instant::now();
        // Coarse to fine: a wide search, then narrower boxes re-centred (re-based) on the best.
        let passes = [
            ("roll:huge;yaw:huge;pitch:huge;dpx:-0.1,0.1;dpy:-0.1,0.1;tz:-0.12,0.12", 6, 7200, 0),
            ("roll:-8,8;yaw:-8,8;pitch:-8,8;dpx:-0.02,0.02;dpy:-0.02,0.02;tz:-0.03,0.03", 2, 2400, 0),
            ("roll:-1.5,1.5;yaw:-1.5,1.5;pitch:-1.5,1.5;dpx:-0.004,0.004;dpy:-0.004,0.004;tz:-0.006,0.006", 2, 1600, 1200),
        ];
        let mut current = start;
        let mut n_evals = 0;
        for (spec, restarts, budget, polish) in passes {
            let p = FrameProblem::new(&model, cam, &t, 1.0, current.clone());
            let space = parse_spec(spec, &model.tree, Grammar::Camera).expect("space");
            let r = sweep(
                &p,
                &space,
                &SweepConfig {
                    restarts,
                    total_evals: budget,
                    polish_evals: polish,
                    ..SweepConfig::default()
                },
            )
            .expect("sweep");
            n_evals += r.n_evals;
            current = r.ranked[0].pose.clone();
        }
        times.push(t0.elapsed().as_secs_f64());
        let best = &current.pose;
        rot_errs.push(best.rotation.angle_to(&q).to_degrees());
        trans_errs.push((best.translation - gt.pose.translation).norm() * 1000.0);
        evals.push(n_evals as f64);
    }
    println!(
        "setup C: median {:.3} s wall on {} threads, {:.0} evaluations; final error median {:.3}° rotation, {:.2} mm translation (max {:.3}°, {:.2} mm)",
        median(times.clone()),
        rayon::current_num_threads(),
        median(evals),
        median(rot_errs.clone()),
        median(trans_errs.clone()),
        rot_errs.iter().copied().fold(0.0, f64::max),
        trans_errs.iter().copied().fold(0.0, f64::max)
    );
}

fn tracking() {
    let model = case::case_model();
    let cam = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
    let scale = 0.5;
    let gts: Vec<GenPose> = (0..20).map(|k| case::truth(k as f64)).collect();
    let targets: Vec<ScoreTarget> = gts.iter().map(|g| target(&model, &cam, g, scale)).collect();
    let frames: Vec<TrackFrame> = targets
        .iter()
        .enumerate()
        .map(|(k, t)| TrackFrame {
            name: format!("{k:06}"),
            camera: cam,
            target: t,
            world_from_camera: None,
            rgb: None,
        })
        .collect();
    // The tracker as it runs, and without its last polish: the figures the 2° and
    // 3° are about, and what the polish costs.
    for (label, last_polish) in [("tracking", true), ("tracking, no last polish", false)] {
        let cfg = TrackConfig {
            last_polish,
            ..TrackConfig::default()
        };
        tracking_with(&model, &cam, scale, (&gts, &targets), &frames, &cfg, label);
    }
}

fn tracking_with(
    model: &ObjectModel,
    cam: &PinholeCamera,
    scale: f64,
    (gts, targets): (&[GenPose], &[ScoreTarget]),
    frames: &[TrackFrame],
    cfg: &TrackConfig,
    label: &str,
) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..3 {
        let t0 = Instant::now();
        let r = track(model, scale, frames, cfg).expect("track");
        times.push(t0.elapsed().as_secs_f64());
        last = Some(r);
    }
    let r = last.expect("ran");
    if std::env::var_os("AGENTSTAR_BENCH_VERBOSE").is_some() {
        for (k, (g, e)) in gts.iter().zip(&r.poses).enumerate() {
            let truth = FrameProblem::new(model, *cam, &targets[k], scale, g.clone())
                .evaluator()
                .combined(g);
            eprintln!(
                "frame {k}: {:.2}° rotation, {:.2}% of depth, {:.2}° joint, IoU {:.4} (truth {truth:.4}), {} mask px",
                g.pose.rotation.angle_to(&e.pose.rotation).to_degrees(),
                (g.pose.translation - e.pose.translation).norm() / g.pose.translation.z * 100.0,
                (g.states[0] - e.states[0]).to_degrees().abs(),
                r.scores[k],
                targets[k].mask().count()
            );
        }
        for l in &r.log {
            eprintln!("{l}");
        }
    }
    let rot = gts
        .iter()
        .zip(&r.poses)
        .map(|(g, e)| g.pose.rotation.angle_to(&e.pose.rotation).to_degrees())
        .fold(0.0, f64::max);
    let trans = gts
        .iter()
        .zip(&r.poses)
        .map(|(g, e)| {
            (g.pose.translation - e.pose.translation).norm() / g.pose.translation.z * 100.0
        })
        .fold(0.0, f64::max);
    let joint = gts
        .iter()
        .zip(&r.poses)
        .map(|(g, e)| (g.states[0] - e.states[0]).to_degrees().abs())
        .fold(0.0, f64::max);
    let steps = (1..gts.len())
        .map(|k| {
            gts[k]
                .pose
                .rotation
                .angle_to(&gts[k - 1].pose.rotation)
                .to_degrees()
        })
        .fold(0.0, f64::max);
    println!(
        "{label}: 20 keyframes (6 DoF + 1 joint, steps up to {steps:.0}°): median {:.2} s wall on {} threads, {} evaluations; worst frame {rot:.2}° rotation, {trans:.2}% of depth, {joint:.2}° joint; min IoU {:.4}",
        median(times),
        rayon::current_num_threads(),
        r.evaluations,
        r.scores.iter().copied().fold(1.0, f64::min)
    );
}

/// The tracker's polish ([`LocalWindow::polish`], half-resolution wide passes as the tracker
/// runs them) started off each of the tracking benchmark's 20 true poses: turned 2.5° about a
/// seeded axis, its joint 3° off (each sign), shifted 0.3% of the depth; three starts a
/// frame. The masks are exact (the truth scores IoU 1.0), so every degree left is the
/// optimiser's: how far from the truth it ends (the larger of rotation and joint error),
/// and in how many evaluations. Each way of searching the narrow end ([`LastPass`]): the
/// tracker's, then CMA-ES on the sub-pixel score.
fn refine() {
    for last in [LastPass::NelderMead, LastPass::CmaSoft] {
        refine_with(last);
    }
}

fn refine_with(last: LastPass) {
    let model = case::case_model();
    let cam = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
    let scale = 0.5;
    let mut errors_deg = Vec::new();
    let mut rotation_deg = Vec::new();
    let mut evaluations = 0;
    let mut times = Vec::new();
    for k in 0..20 {
        let truth = case::truth(k as f64);
        let target = target(&model, &cam, &truth, scale);
        let halved = target.halved();
        for trial in 0..3u64 {
            let mut rng = agentstar_optim::Rng::new(100 * k as u64 + trial);
            let axis = Vector3::new(rng.normal(), rng.normal(), rng.normal());
            let mut start = truth.clone();
            start.pose.rotation = UnitQuaternion::from_axis_angle(
                &agentstar_geom::nalgebra::Unit::new_normalize(axis),
                2.5f64.to_radians(),
            ) * truth.pose.rotation;
            start.states[0] += 3f64.to_radians() * if trial % 2 == 0 { 1.0 } else { -1.0 };
            start.pose.translation.x += 0.003 * truth.pose.translation.z;
            let problem =
                FrameProblem::new(&model, cam, &target, scale, start.clone()).with_coarse(&halved);
            let t0 = Instant::now();
            let (found, _, n) =
                refine_local_with(&problem, &start, &LocalWindow::polish(), 7 + trial, last)
                    .expect("refine");
            times.push(t0.elapsed().as_secs_f64());
            evaluations += n;
            let rotation = truth
                .pose
                .rotation
                .angle_to(&found.pose.rotation)
                .to_degrees();
            rotation_deg.push(rotation);
            errors_deg.push(rotation.max((truth.states[0] - found.states[0]).to_degrees().abs()));
        }
    }
    errors_deg.sort_by(f64::total_cmp);
    rotation_deg.sort_by(f64::total_cmp);
    let n = errors_deg.len();
    println!(
        "refine ({last:?}): {n} polishes from 2.5° and 3° of joint off the truth: median {:.4} s each, {} evaluations each; error left (the larger of rotation and joint) median {:.2}°, 90% {:.2}°, max {:.2}°; {} of {n} over 1° (rotation alone: median {:.2}°, max {:.2}°)",
        median(times),
        evaluations / n,
        errors_deg[n / 2],
        errors_deg[n * 9 / 10],
        errors_deg[n - 1],
        errors_deg.iter().filter(|&&e| e > 1.0).count(),
        rotation_deg[n / 2],
        rotation_deg[n - 1],
    );
}

fn main() {
    // Names given after `--` choose benchmarks; cargo's own flags (`--bench`) are not names.
    let names: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let chosen = |name: &str| names.is_empty() || names.iter().any(|n| n == name);
    let mut ran = false;
    for (name, bench) in [
        ("setup-c", setup_c as fn()),
        ("tracking", tracking),
        ("refine", refine),
    ] {
        if chosen(name) {
            bench();
            ran = true;
        }
    }
    if !ran {
        eprintln!("no benchmark named {names:?}; the benchmarks are setup-c, tracking and refine");
        std::process::exit(2);
    }
}
