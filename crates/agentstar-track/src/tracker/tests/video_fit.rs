//! The steady motion between two keyframes, and how far pairs of keyframe poses joined by it
//! miss the video between them.

use super::*;

/// A square prism (0.3 × 0.3 × 1, centred): its outline is the same after a quarter turn
/// about its long axis, so its keyframes have twins that one frame's mask cannot tell apart.
fn square_prism() -> ObjectModel {
    ObjectModel {
        tree: KinematicTree::rigid(1),
        parts: vec![Part::new(
            "body",
            cuboid(0.3, 0.3, 1.0).expect("box"),
            [0.6, 0.6, 0.6],
        )],
    }
}

/// The pose of [`square_prism`] a share `t` of its steady turn of `step_deg` a keyframe
/// about an oblique axis (t = 1: the next keyframe), 1.4 in front of the camera.
fn turning_prism(step_deg: f64) -> impl Fn(f64) -> GenPose {
    let start = turn(Vector3::new(1.0, 0.2, 0.1), 70.0);
    let spin = turn(Vector3::new(0.2, 1.0, 0.5), step_deg);
    move |t: f64| GenPose {
        pose: ObjectPose::new(spin.powf(t) * start, Vector3::new(0.0, 0.02, 1.4)),
        states: vec![],
    }
}

fn turn(axis: Vector3, deg: f64) -> UnitQuaternion {
    UnitQuaternion::from_axis_angle(
        &agentstar_geom::nalgebra::Unit::new_normalize(axis),
        deg.to_radians(),
    )
}

fn frame_at<'a>(target: &'a ScoreTarget, world_from_camera: Option<Rigid>) -> TrackFrame<'a> {
    TrackFrame {
        name: "f".into(),
        camera: camera(),
        target,
        world_from_camera,
        rgb: None,
    }
}

/// At the keyframes the steady motion is their poses; between them it turns the object at a
/// steady rate about one axis in the world and moves its pivot on a straight line, whatever
/// the cameras do meanwhile.
#[test]
fn the_steady_motion_passes_through_both_keyframes_and_turns_steadily_in_the_world() {
    let model = ell();
    let scale = 0.5;
    let target = ScoreTarget::new(BitMask::new(320, 240), None).expect("target");
    let camera_at = |x: f64, yaw: f64| {
        Rigid::from_parts(
            Vector3::new(x, 0.02, -0.01).into(),
            UnitQuaternion::from_euler_angles(0.0, yaw, 0.05 * x),
        )
    };
    let (c0, c1, ch) = (
        camera_at(0.0, 0.0),
        camera_at(0.3, 0.4),
        camera_at(0.1, 0.15),
    );
    let (f0, f1, fh) = (
        frame_at(&target, Some(c0)),
        frame_at(&target, Some(c1)),
        frame_at(&target, Some(ch)),
    );
    // In the world: 80° about an oblique axis through the pivot, the pivot moving 0.2.
    let spin = turn(Vector3::new(0.4, 1.0, -0.3), 80.0);
    let pivot = model.pivot(&[]).coords * scale;
    let world_a = ObjectPose::new(
        UnitQuaternion::from_euler_angles(0.3, -0.2, 0.9),
        Vector3::new(0.05, -0.1, 1.3),
    );
    let pivot_at = |p: &ObjectPose| p.rotation * pivot + p.translation;
    let shift = Vector3::new(0.2, 0.0, 0.05);
    let world_at = |t: f64| {
        let rotation = spin.powf(t) * world_a.rotation;
        let centre = pivot_at(&world_a) + t * shift;
        ObjectPose::new(rotation, centre - rotation * pivot)
    };
    let in_camera = |c: &Rigid, p: &ObjectPose| {
        let inv = c.inverse();
        ObjectPose::new(
            inv.rotation * p.rotation,
            inv.rotation * p.translation + inv.translation.vector,
        )
    };
    let at = |p: ObjectPose| GenPose {
        pose: p,
        states: vec![],
    };
    let a = at(in_camera(&c0, &world_at(0.0)));
    let b = at(in_camera(&c1, &world_at(1.0)));
    let close = |x: &GenPose, y: &ObjectPose| {
        x.pose.rotation.angle_to(&y.rotation) < 1e-9
            && (x.pose.translation - y.translation).norm() < 1e-9
    };
    let steady = |here: &TrackFrame<'_>, t: f64| {
        steady_between(&model, scale, (&f0, &a), (&f1, &b), here, t)
    };
    assert!(close(&steady(&f0, 0.0), &a.pose));
    assert!(close(&steady(&f1, 1.0), &b.pose));
    for t in [0.1, 0.5, 0.8] {
        let got = steady(&fh, t);
        let want = in_camera(&ch, &world_at(t));
        assert!(
            close(&got, &want),
            "t {t}: {:.3}° and {:.2e} off",
            got.pose.rotation.angle_to(&want.rotation).to_degrees(),
            (got.pose.translation - want.translation).norm()
        );
    }
    // Without cameras (a still camera) the motion is taken in the camera's frame.
    let still = frame_at(&target, None);
    let mid = steady_between(&model, scale, (&still, &a), (&still, &b), &still, 0.5);
    let half = (b.pose.rotation * a.pose.rotation.inverse()).powf(0.5) * a.pose.rotation;
    assert!(mid.pose.rotation.angle_to(&half) < 1e-9);
}

/// A square prism turning 70° between two keyframes, seen in nine frames between them: a
/// pair of keyframe poses in the same twin (the truth, or both a quarter turn about the
/// prism's axis) explains every frame between; a pair whose ends lie in different twins
/// turns the prism through poses the frames do not show.
#[test]
fn pairs_of_keyframe_poses_in_different_twins_miss_the_video_between_them() {
    let model = square_prism();
    let scale = 0.5;
    let at = turning_prism(70.0);
    let keys = silhouettes(&model, scale, &[at(0.0), at(1.0)]);
    let between_poses: Vec<GenPose> = (1..10).map(|j| at(j as f64 / 10.0)).collect();
    let between_targets = silhouettes(&model, scale, &between_poses);
    let frames = silhouette_frames(&keys);
    let between = vec![silhouette_frames(&between_targets)];
    let s = Searcher::new(&model, scale, &frames, &TrackConfig::default()).expect("searcher");
    let quarter = turn(Vector3::z(), 90.0);
    let twin = |g: GenPose| GenPose {
        pose: ObjectPose::new(g.pose.rotation * quarter, g.pose.translation),
        states: vec![],
    };
    // The twin's outline at the keyframes is the truth's.
    let iou = |k: usize, g: &GenPose| {
        FrameProblem::new(&model, camera(), &keys[k], scale, g.clone())
            .evaluator()
            .combined(g)
    };
    assert!((iou(0, &twin(at(0.0))) - iou(0, &at(0.0))).abs() < 0.01);
    let hyps = vec![
        vec![(at(0.0), 1.0), (twin(at(0.0)), 1.0)],
        vec![(at(1.0), 1.0), (twin(at(1.0)), 1.0)],
    ];
    let cost = video_fit(&s, (&frames, &between), &hyps);
    assert!(cost[0].is_empty(), "no gap before the first keyframe");
    let c = &cost[1];
    assert!(c[0][0] < 1.0 && c[1][1] < 1.0, "same twin: {c:?}");
    assert!(c[0][1] > 20.0 && c[1][0] > 20.0, "twins mixed: {c:?}");
    // A gap without in-between frames has no cost.
    let none = video_fit(&s, (&frames, &[vec![]]), &hyps);
    assert!(none[1].is_empty());
}

/// A square prism turning 60° between each of three keyframes, keyframe 1 left a quarter turn
/// off about its axis (a twin its mask cannot tell apart) and both gaps' motions measured as
/// a drifted chain would measure them (joining that twin to its neighbours): with the video
/// between the keyframes the sequence choice puts keyframe 1 back on the truth; without it,
/// the chains' motions keep the twin.
#[test]
fn the_choice_follows_the_steady_motion_through_the_video_over_a_drifted_chain() {
    let model = square_prism();
    let scale = 0.5;
    let at = turning_prism(60.0);
    let truths: Vec<GenPose> = (0..3).map(|k| at(k as f64)).collect();
    let keys = silhouettes(&model, scale, &truths);
    let frames = silhouette_frames(&keys);
    let between_targets: Vec<Vec<ScoreTarget>> = (0..2)
        .map(|g| {
            let poses: Vec<GenPose> = (1..10).map(|j| at(g as f64 + j as f64 / 10.0)).collect();
            silhouettes(&model, scale, &poses)
        })
        .collect();
    let between: Vec<Vec<TrackFrame<'_>>> = between_targets
        .iter()
        .map(|t| silhouette_frames(t))
        .collect();
    let quarter = turn(Vector3::z(), 90.0);
    let twin_1 = GenPose {
        pose: ObjectPose::new(
            truths[1].pose.rotation * quarter,
            truths[1].pose.translation,
        ),
        states: vec![],
    };
    let choose = |between: &[Vec<TrackFrame<'_>>]| {
        let s = Searcher::new(&model, scale, &frames, &TrackConfig::default()).expect("searcher");
        let mut poses = vec![truths[0].clone(), twin_1.clone(), truths[2].clone()];
        s.set_gap(0, Gap::between(&frames, 0, &poses[0], &poses[1]));
        s.set_gap(1, Gap::between(&frames, 1, &poses[1], &poses[2]));
        let mut scores = scores_of(&model, scale, &frames, &poses);
        let observe = |_: &str| {};
        let mut log = Log::new(&observe);
        choose_sequence(
            &s,
            (&frames, between),
            (&mut poses, &mut scores),
            &[false; 3],
            &vec![Vec::new(); 3],
            &mut log,
        )
        .expect("choice");
        (error_of(&poses[1], &truths[1]), log.lines)
    };
    let (with_video, lines) = choose(&between);
    assert!(with_video < 2.0, "{with_video:.1}° off: {lines:?}");
    assert!(
        lines.iter().any(|l| l.contains("steady motion")),
        "{lines:?}"
    );
    let (without, _) = choose(&[]);
    assert!(
        without > 80.0,
        "the chains' motions alone: {without:.1}° off"
    );
}
