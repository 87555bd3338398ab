//! The video refinement: a keyframe whose own mask ties, put right by the in-between frames
//! beside it.

use super::*;

/// `model` (a mug, a can: its axis along +Z) turning steadily about an oblique axis through
/// its pivot, 45° between keyframes (t = 1: the next keyframe), 0.5 in front of a still
/// camera, its joints at rest.
fn turning(model: &ObjectModel, scale: f64) -> impl Fn(f64) -> GenPose {
    let start = crate::appearance::tests::pose(Vector3::y(), 0.0, -100.0);
    let spin = UnitQuaternion::from_axis_angle(
        &agentstar_geom::nalgebra::Unit::new_normalize(Vector3::new(0.3, 1.0, 0.4)),
        45f64.to_radians(),
    );
    let rest = model.tree.rest_states();
    let pivot = model.pivot(&rest).coords * scale;
    let centre = start.pose.rotation * pivot + start.pose.translation;
    move |t: f64| {
        let rotation = spin.powf(t) * start.pose.rotation;
        GenPose {
            pose: ObjectPose::new(rotation, centre - rotation * pivot),
            states: rest.clone(),
        }
    }
}

/// The silhouette of `model` at `g` in `cam`.
fn mask_of(model: &ObjectModel, scale: f64, cam: &PinholeCamera, g: &GenPose) -> BitMask {
    let mut r = SilhouetteRenderer::new(cam.width, cam.height);
    let posed = PosedModel::new(model, &g.states, &g.pose.with_scale(scale));
    r.render(cam, &posed.instances).clone()
}

/// Three keyframes of `model` turning steadily ([`turning`]), the middle one under a hand
/// over wherever part `hidden` (its index in the model, as the full renderer's part buffer
/// holds it) is for
/// turns of up to 30° about the body's axis, and left turned 30° there: its own mask cannot
/// tell that pose from the truth. The nine frames of each gap (no hands) see the part as the
/// object turns. With them, how far (degrees) the video refinement leaves the keyframe from
/// the truth, and the log; without them, whether the pass moved anything.
fn under_a_hand(
    model: &ObjectModel,
    scale: f64,
    hidden: u16,
    turn_deg: f64,
) -> (f64, Vec<String>, bool) {
    let cam = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
    let at = turning(model, scale);
    let truths: Vec<GenPose> = (0..3).map(|k| at(k as f64)).collect();
    let wrong = spin_about_z(&truths[1], turn_deg);
    // The hand: the part's box at every turn between the truth and the wrong pose.
    let mut hand = BitMask::new(320, 240);
    for k in 0..=6 {
        let g = spin_about_z(&truths[1], turn_deg * k as f64 / 6.0);
        let b = agentstar_render::render_full(
            &cam,
            &PosedModel::new(model, &g.states, &g.pose.with_scale(scale)).instances,
        );
        let (x0, y0, x1, y1) =
            BitMask::from_fn(320, 240, |x, y| b.part[(y * 320 + x) as usize] == hidden)
                .bbox()
                .expect("the part is in view");
        for y in y0.saturating_sub(3)..(y1 + 4).min(240) {
            hand.set_span(y, x0.saturating_sub(3), (x1 + 3).min(319));
        }
    }
    let mut keys: Vec<ScoreTarget> = truths
        .iter()
        .map(|g| ScoreTarget::new(mask_of(model, scale, &cam, g), None).expect("target"))
        .collect();
    keys[1] = ScoreTarget::new(
        mask_of(model, scale, &cam, &truths[1]).and_not(&hand),
        Some(hand),
    )
    .expect("target");
    let frame_of = |k: usize, target| TrackFrame {
        name: format!("{:06}", 10 * k),
        camera: cam,
        target,
        world_from_camera: None,
        rgb: None,
    };
    let frames: Vec<TrackFrame<'_>> = keys
        .iter()
        .enumerate()
        .map(|(k, t)| frame_of(k, t))
        .collect();
    let between_targets: Vec<Vec<ScoreTarget>> = (0..2)
        .map(|g| {
            (1..10)
                .map(|j| {
                    let truth = at(g as f64 + j as f64 / 10.0);
                    ScoreTarget::new(mask_of(model, scale, &cam, &truth), None).expect("target")
                })
                .collect()
        })
        .collect();
    let between: Vec<Vec<TrackFrame<'_>>> = between_targets
        .iter()
        .enumerate()
        .map(|(g, ts)| ts.iter().map(|t| frame_of(g, t)).collect())
        .collect();
    // The keyframe's own mask ties: the wrong pose scores as the truth does.
    let own = |g: &GenPose| {
        FrameProblem::new(model, cam, &keys[1], scale, g.clone())
            .evaluator()
            .combined(g)
    };
    assert!(
        (own(&wrong) - own(&truths[1])).abs() < 0.01,
        "the keyframe's mask tells them apart: {} against {}",
        own(&wrong),
        own(&truths[1])
    );
    let run = |between: &[Vec<TrackFrame<'_>>]| {
        let s = Searcher::new(model, scale, &frames, &TrackConfig::default()).expect("searcher");
        let mut poses = vec![truths[0].clone(), wrong.clone(), truths[2].clone()];
        let mut scores = scores_of(model, scale, &frames, &poses);
        let observe = |_: &str| {};
        let mut log = Log::new(&observe);
        let moved = video_pass(
            &s,
            (&frames, between),
            (&mut poses, &mut scores),
            &[true, false, true],
            &mut log,
        )
        .expect("video refinement");
        (moved, poses, log.lines)
    };
    let (_, poses, lines) = run(&between);
    let (moved_without, unmoved, _) = run(&[]);
    assert!(!moved_without || unmoved[1] == wrong);
    (error_of(&poses[1], &truths[1]), lines, moved_without)
}

/// A mug whose handle the hand hides at a keyframe: the in-between frames put its turn
/// right; without them nothing moves.
#[test]
fn the_video_beside_a_keyframe_puts_right_a_turn_its_own_mask_cannot_see() {
    let (off, lines, moved_without) = under_a_hand(&mug(), 0.12, 2, 30.0);
    assert!(off < 4.0, "{off:.1}° off: {lines:?}");
    assert!(
        lines.iter().any(|l| l.contains("video refinement")),
        "{lines:?}"
    );
    assert!(!moved_without, "without the video nothing moves");
}

/// A can with a lever on its side, the lever under the hand at a keyframe: its outline is
/// round, so every refinement holds the turn about its axis; the video refinement frees it
/// (the lever shows it in the frames between) and takes back most of the turn.
#[test]
fn the_video_frees_a_round_outlines_turn_where_a_jointed_part_shows_it() {
    let model = crate::axis::tests::lever_can([0.04, 0.06, 0.4], 0.32, 0.15);
    let rest = model.tree.rest_states();
    assert!(crate::axis::outline_axis(&model, &rest).is_some());
    // Left 15° off; the lever is thin (a few pixels proud of the outline at half
    // resolution), and two sweeps take back most of the turn.
    let (off, lines, _) = under_a_hand(&model, 0.3, 1, 15.0);
    assert!(off < 5.0, "{off:.1}° off: {lines:?}");
    assert!(
        lines
            .iter()
            .any(|l| l.contains("the turn about the round outline's axis free")),
        "{lines:?}"
    );
}
