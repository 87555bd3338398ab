//! `track --bake`: the frames the outline settles, baked; those that disagree left out.

use super::*;

/// The spins about its axis at which [`uncoloured_mug`] sees the mug (degrees).
const MUG_SPINS: [f64; 5] = [-50.0, -80.0, -100.0, -120.0, -150.0];

/// The uncoloured mug's scene: model, scale, camera, targets, hands, images, truths, the
/// plain poses.
type MugScene = (
    ObjectModel,
    f64,
    PinholeCamera,
    Vec<ScoreTarget>,
    Vec<Option<BitMask>>,
    Vec<Vec<u8>>,
    Vec<GenPose>,
    Vec<GenPose>,
);

/// An uncoloured mug (the mug of [`mug`], every part one colour) printed all round, seen
/// level from five directions: its handle in view at the side in frames 0 and 4, hidden
/// behind the body in frames 1–3, whose poses are left turned half way about the body (the
/// handle in front, a hand over it: the masks tie). `paint(k)` paints frame k.
/// (model, scale, camera, targets' masks and hands, images, truths, the plain poses.)
fn uncoloured_mug(paint: &dyn Fn(usize, &Point3) -> [f64; 3]) -> MugScene {
    uncoloured_mug_at(&MUG_SPINS, paint)
}

/// The uncoloured mug at `spins` (degrees about its axis), painted by `paint(frame, point)`
/// in the frames; frames 1, 2 and 3 have the handle hidden under a hand and their plain
/// poses turned half way (a twin), the others their true poses.
fn uncoloured_mug_at(spins: &[f64], paint: &dyn Fn(usize, &Point3) -> [f64; 3]) -> MugScene {
    use crate::appearance::tests::{pose, shoot};
    use agentstar_render::render_full;
    let mut model = mug();
    for p in &mut model.parts {
        p.color = [0.6, 0.6, 0.6];
    }
    assert!(!crate::appearance::model_has_appearance(&model));
    let scale = 0.12;
    let (w, h) = (480, 360);
    let cam = PinholeCamera::new(450.0, 450.0, 252.0, 168.0, w, h).expect("camera");
    let truths: Vec<GenPose> = spins
        .iter()
        .map(|&spin| pose(Vector3::x(), -20.0, spin))
        .collect();
    let hidden = 1..4;
    let mut plain = truths.clone();
    let (mut targets, mut hands, mut images) = (vec![], vec![], vec![]);
    for (k, g) in truths.iter().enumerate() {
        let (rgb, mask) = shoot(&model, scale, &cam, g, &|p: &Point3| paint(k, p));
        let hand = hidden.contains(&k).then(|| {
            // A hand over the handle as it would lie in front.
            plain[k] = spin_about_z(g, 180.0);
            let t = &plain[k];
            let b = render_full(
                &cam,
                &PosedModel::new(&model, &t.states, &t.pose.with_scale(scale)).instances,
            );
            let (x0, y0, x1, y1) = BitMask::from_fn(w, h, |x, y| b.part[(y * w + x) as usize] == 2)
                .bbox()
                .expect("the handle is in view");
            let mut hand = BitMask::new(w, h);
            for y in y0.saturating_sub(4)..(y1 + 5).min(h) {
                hand.set_span(y, x0.saturating_sub(4), (x1 + 4).min(w - 1));
            }
            hand
        });
        let target = match &hand {
            Some(hd) => ScoreTarget::new(mask.and_not(hd), Some(hd.clone())),
            None => ScoreTarget::new(mask, None),
        }
        .expect("target");
        targets.push(target);
        hands.push(hand);
        images.push(rgb);
    }
    (model, scale, cam, targets, hands, images, truths, plain)
}

/// The mug's print: a label at +X, bands of colour of pseudo-random width above it, and
/// stripes below it.
fn mug_print(p: &Point3) -> [f64; 3] {
    let cell = (p.y.atan2(p.x) / 0.35).floor() as i64;
    match (p.z > 0.32, p.z < -0.32, (cell * 7919).rem_euclid(5)) {
        (true, _, 0) => [0.1, 0.3, 0.8],
        (true, _, 1 | 2) => [0.9, 0.9, 0.2],
        (true, _, _) => [0.2, 0.6, 0.2],
        (_, true, k) => [0.15 * k as f64, 0.2, 0.7 - 0.1 * k as f64],
        _ => crate::appearance::tests::painted_label(p),
    }
}

/// The frames of [`uncoloured_mug`], and the plain track's result at its plain poses.
fn mug_frames<'a>(
    cam: &PinholeCamera,
    targets: &'a [ScoreTarget],
    images: &'a [Vec<u8>],
) -> Vec<TrackFrame<'a>> {
    targets
        .iter()
        .zip(images)
        .enumerate()
        .map(|(k, (t, rgb))| TrackFrame {
            name: format!("{k:06}.png"),
            camera: *cam,
            target: t,
            world_from_camera: None,
            rgb: Some(rgb),
        })
        .collect()
}

/// `track --bake` after the plain `result` with the default bake settings, and its log.
fn bake_logged(
    model: &ObjectModel,
    scale: f64,
    frames: &[TrackFrame<'_>],
    hands: &[Option<BitMask>],
    result: &TrackResult,
) -> (BakePass, String) {
    let lines = std::sync::Mutex::new(Vec::new());
    let keep = |l: &str| lines.lock().expect("lines").push(l.to_string());
    let pass = track_with_bake(
        model,
        scale,
        (frames, &[]),
        hands,
        result,
        &quick_config(),
        &crate::bake::BakeConfig::default(),
        &keep,
    )
    .expect("track --bake");
    (pass, lines.into_inner().expect("lines").join("\n"))
}

fn plain_result(poses: &[GenPose], scores: Vec<f64>) -> TrackResult {
    TrackResult {
        poses: poses.to_vec(),
        scores,
        init_frame: 0,
        log: vec![],
        evaluations: 0,
        between: vec![],
        choice: None,
        refused_turns: vec![],
    }
}

/// The budget of these tests' local searches (a quarter of the default: debug builds).
fn quick_config() -> TrackConfig {
    TrackConfig {
        local_evals: 600,
        ..TrackConfig::default()
    }
}

#[test]
fn a_bake_from_the_frames_the_handle_settles_turns_an_uncoloured_mugs_twins_back() {
    let (model, scale, cam, targets, hands, images, truths, plain) =
        uncoloured_mug(&|_, p| mug_print(p));
    let frames = mug_frames(&cam, &targets, &images);
    let cfg = quick_config();
    let scores = scores_of(&model, scale, &frames, &plain);
    let observe = |_: &str| {};
    // Without a bake the passes have only the frames' colours against each other: the three
    // frames with the handle hidden stay turned half way (each agrees with the others).
    let without = track_from_with(
        &model,
        scale,
        &frames,
        (&plain, &[]),
        BasinPolicy::Search,
        &cfg,
        &observe,
    )
    .expect("warm start");
    for (k, (g, t)) in without.result.poses.iter().zip(&truths).enumerate() {
        let e = error_of(g, t);
        if (1..4).contains(&k) {
            assert!(e > 90.0, "frame {k} {e:.1}° off without a bake");
        }
    }
    // With it: the frames with the handle in view are settled, baked from, kept; the others
    // are turned back by the print and named.
    let result = plain_result(&plain, scores);
    let (pass, log) = bake_logged(&model, scale, &frames, &hands, &result);
    assert_eq!(pass.settled_frames(), vec![0, 4], "{log}");
    for f in &pass.settled[1..4] {
        let (deg, _) = f.rival.expect("a rival");
        assert!(deg > 150.0, "{f:?}");
    }
    let BakeOutcome::Used(b, w) = &pass.outcome else {
        panic!("the bake was not used: {log}");
    };
    assert!(b.disagreeing().is_empty(), "{:?}", b.frames);
    assert!(pass.baked_model.is_some());
    for (k, t) in truths.iter().enumerate() {
        let e = error_of(&w.result.poses[k], t);
        assert!(e < 20.0, "frame {k} {e:.1}° off with the bake\n{log}");
    }
    // The anchors exactly, and the frames moved named.
    assert_eq!(w.result.poses[0], plain[0]);
    assert_eq!(w.result.poses[4], plain[4]);
    let moved: Vec<usize> = w.basin_moves.iter().map(|m| m.frame).collect();
    assert_eq!(moved, vec![1, 2, 3], "{log}");
}

#[test]
fn a_settled_frame_whose_colours_disagree_is_left_out_and_the_rest_baked() {
    // A sixth view with the handle in view, its print turned a quarter about the body (its
    // pose puts the colours elsewhere than the others do): settled by the outline, left out
    // of the bake, which the other two settled frames make and the passes use.
    let mut spins = MUG_SPINS.to_vec();
    spins.push(-30.0);
    let (model, scale, cam, targets, hands, images, truths, plain) =
        uncoloured_mug_at(&spins, &|k, p| {
            if k == 5 {
                mug_print(&Point3::new(-p.y, p.x, p.z))
            } else {
                mug_print(p)
            }
        });
    let frames = mug_frames(&cam, &targets, &images);
    let result = plain_result(&plain, scores_of(&model, scale, &frames, &plain));
    let (pass, log) = bake_logged(&model, scale, &frames, &hands, &result);
    assert_eq!(pass.settled_frames(), vec![0, 4, 5], "{log}");
    assert_eq!(pass.left_out, vec![5], "{log}");
    let BakeOutcome::Used(b, w) = &pass.outcome else {
        panic!("the bake was not used: {log}");
    };
    let baked_from: Vec<&str> = b.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(baked_from, vec!["000000.png", "000004.png"], "{log}");
    assert!(b.disagreeing().is_empty(), "{:?}", b.frames);
    assert!(log.contains("000005.png"), "{log}");
    for (k, (g, t)) in w
        .result
        .poses
        .iter()
        .zip(&truths)
        .enumerate()
        .take(4)
        .skip(1)
    {
        let e = error_of(g, t);
        assert!(e < 20.0, "frame {k} {e:.1}° off with the bake\n{log}");
    }
}

#[test]
fn a_bake_from_settled_frames_that_disagree_is_refused_and_too_few_bake_nothing() {
    // Frame 4's colours are of the print turned a quarter about the body: its pose puts
    // them elsewhere than frame 0's.
    let (model, scale, cam, targets, hands, images, _, plain) = uncoloured_mug(&|k, p| {
        if k == 4 {
            mug_print(&Point3::new(-p.y, p.x, p.z))
        } else {
            mug_print(p)
        }
    });
    let frames = mug_frames(&cam, &targets, &images);
    let cfg = quick_config();
    let observe = |_: &str| {};
    let result = plain_result(&plain, scores_of(&model, scale, &frames, &plain));
    let bake_cfg = crate::bake::BakeConfig::default();
    let pass = track_with_bake(
        &model,
        scale,
        (&frames, &[]),
        &hands,
        &result,
        &cfg,
        &bake_cfg,
        &observe,
    )
    .expect("track --bake");
    assert_eq!(pass.settled_frames(), vec![0, 4]);
    let BakeOutcome::Refused(b) = &pass.outcome else {
        panic!("not refused: {:?}", pass.settled);
    };
    assert!(!b.disagreeing().is_empty(), "{:?}", b.frames);
    assert!(pass.baked_model.is_none());
    // Only the frames with the handle hidden: none settles, nothing is baked.
    let hidden = 1..4;
    let result = plain_result(
        &plain[hidden.clone()],
        result.scores[hidden.clone()].to_vec(),
    );
    let pass = track_with_bake(
        &model,
        scale,
        (&frames[hidden.clone()], &[]),
        &hands[hidden],
        &result,
        &cfg,
        &bake_cfg,
        &observe,
    )
    .expect("track --bake");
    assert!(pass.settled_frames().is_empty());
    assert!(matches!(pass.outcome, BakeOutcome::TooFewSettled));
}
