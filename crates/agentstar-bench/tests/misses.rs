//! Where a miss comes from: a half-turn about a plain can's axis ties on the masks and has
//! no colours to tell it (evidence, when the can's symmetries are not declared; with them it
//! is no miss at all), a tilt loses on the masks (search), the true pose is no miss, and on a
//! labelled can the model's colours prefer the truth to the half-turn.

use agentstar_bench::misses::{misses, MissCause, Misses, Weighed};
use agentstar_geom::{UnitQuaternion, Vector3};
use agentstar_render::ScoreTarget;
use agentstar_synth::{synthesize, SynthConfig};
use agentstar_track::tracker::ChoiceTrace;
use agentstar_track::GenPose;

/// Frame 0 as true, frame 1 turned half-way about the can's axis (its model z), frame 2
/// tilted 40° about the model's x; the misses of those poses on a capture of `object`, its
/// true symmetries declared or not.
fn misses_of_a_turn_and_a_tilt(object: &str, symmetries: bool) -> (Misses, Vec<String>) {
    misses_weighed(object, symmetries, None)
}

/// What a sequence choice weighed, made from the true and the tracked poses.
type Weigh = dyn Fn(&[GenPose], &[GenPose]) -> ChoiceTrace;

/// [`misses_of_a_turn_and_a_tilt`], with what a sequence choice weighed: `weighed(truth,
/// tracked)` gives its hypotheses and its pick per frame.
fn misses_weighed(
    object: &str,
    symmetries: bool,
    weighed: Option<&Weigh>,
) -> (Misses, Vec<String>) {
    let mut capture = synthesize(&SynthConfig {
        object: object.into(),
        frames: 3,
        width: 240,
        height: 180,
        seed: 3,
        hands: false,
        ..SynthConfig::default()
    })
    .expect("synth");
    if !symmetries {
        capture.symmetries.clear();
    }
    let targets: Vec<ScoreTarget> = capture
        .frames
        .iter()
        .map(|f| ScoreTarget::new(f.mask.clone(), None).expect("target"))
        .collect();
    let cameras = vec![capture.camera; capture.frames.len()];
    let truth: Vec<GenPose> = capture
        .frames
        .iter()
        .map(|f| GenPose {
            pose: f.camera_from_object,
            states: f.states.clone(),
        })
        .collect();
    let turned = |g: &GenPose, axis: Vector3, deg: f64| {
        let mut g = g.clone();
        g.pose.rotation *= UnitQuaternion::from_scaled_axis(axis * deg.to_radians());
        g
    };
    let tracked = vec![
        truth[0].clone(),
        turned(&truth[1], Vector3::z(), 180.0),
        turned(&truth[2], Vector3::x(), 40.0),
    ];
    let names = capture.frames.iter().map(|f| f.name.clone()).collect();
    let choice = weighed.map(|w| w(&truth, &tracked));
    (
        misses(
            &capture,
            &cameras,
            &targets,
            &truth,
            &tracked,
            choice.as_ref(),
        ),
        names,
    )
}

#[test]
fn a_miss_says_whether_the_sequence_choice_had_the_truth_and_took_it() {
    // Frame 1 (the half-turn): the choice weighed the truth and took the turned pose; frame
    // 2 (the tilt): it took the truth, and a later pass tilted it; frame 0 is no miss.
    let trace = |truth: &[GenPose], tracked: &[GenPose]| ChoiceTrace {
        hypotheses: vec![
            vec![truth[0].clone()],
            vec![tracked[1].clone(), truth[1].clone()],
            vec![tracked[2].clone(), truth[2].clone()],
        ],
        path: vec![0, 0, 1],
    };
    let (m, _) = misses_weighed("can", false, Some(&trace));
    assert_eq!(m.total(), 2, "{m:?}");
    assert_eq!(m.frames[0].weighed, Some(Weighed::NotTaken), "{m:?}");
    assert_eq!(m.frames[1].weighed, Some(Weighed::Taken), "{m:?}");
    // Only the tracked poses weighed: no search proposed the truth.
    let only_tracked = |_: &[GenPose], tracked: &[GenPose]| ChoiceTrace {
        hypotheses: tracked.iter().map(|g| vec![g.clone()]).collect(),
        path: vec![0; 3],
    };
    let (m, _) = misses_weighed("can", false, Some(&only_tracked));
    assert!(
        m.frames.iter().all(|f| f.weighed == Some(Weighed::Absent)),
        "{m:?}"
    );
    assert_eq!(m.weighed(Weighed::Absent), 2);
    // The can's symmetries declared: the half-turn is the truth's equivalent, no miss; and
    // a hypothesis in a symmetry of the truth counts as the truth.
    let turned_truth = |truth: &[GenPose], tracked: &[GenPose]| {
        let mut about_axis = truth[2].clone();
        about_axis.pose.rotation *=
            UnitQuaternion::from_scaled_axis(Vector3::z() * std::f64::consts::PI);
        ChoiceTrace {
            hypotheses: vec![
                vec![truth[0].clone()],
                vec![tracked[1].clone()],
                vec![tracked[2].clone(), about_axis],
            ],
            path: vec![0; 3],
        }
    };
    let (m, _) = misses_weighed("can", true, Some(&turned_truth));
    assert_eq!(m.total(), 1, "{m:?}");
    assert_eq!(m.frames[0].weighed, Some(Weighed::NotTaken), "{m:?}");
    // Without a choice, nothing is said.
    let (m, _) = misses_of_a_turn_and_a_tilt("can", false);
    assert!(m.frames.iter().all(|f| f.weighed.is_none()), "{m:?}");
}

#[test]
fn a_miss_is_put_down_to_the_evidence_that_prefers_the_truth() {
    // The plain can's half-turn about its axis is one of its symmetries: no miss.
    let (m, names) = misses_of_a_turn_and_a_tilt("can", true);
    assert_eq!(m.total(), 1, "{m:?}");
    assert_eq!(m.frames[0].frame, names[2]);
    // Without its symmetries declared, the half-turn is a miss nothing scored can tell.
    let (m, names) = misses_of_a_turn_and_a_tilt("can", false);
    assert_eq!(m.total(), 2, "{m:?}");
    let half_turn = &m.frames[0];
    assert_eq!(half_turn.frame, names[1]);
    assert!(
        (half_turn.rotation_deg - 180.0).abs() < 1e-6,
        "{half_turn:?}"
    );
    // The plain can: the same mask, one colour.
    assert_eq!(half_turn.cause, MissCause::Evidence, "{half_turn:?}");
    assert!(
        (half_turn.gate_truth - half_turn.gate_tracked).abs() < 0.005,
        "{half_turn:?}"
    );
    assert_eq!(half_turn.model_ncc_truth, None, "{half_turn:?}");
    let tilt = &m.frames[1];
    assert_eq!(tilt.frame, names[2]);
    assert_eq!(tilt.cause, MissCause::Search, "{tilt:?}");
    assert!(tilt.gate_truth > tilt.gate_tracked + 0.05, "{tilt:?}");
    assert_eq!((m.search, m.colours, m.evidence), (1, 0, 1));

    // The labelled can: its label tells the half-turn by the model's colours.
    let (m, _) = misses_of_a_turn_and_a_tilt("labelcan", true);
    let half_turn = &m.frames[0];
    let (tracked, truth) = (
        half_turn.model_ncc_tracked.expect("colours"),
        half_turn.model_ncc_truth.expect("colours"),
    );
    assert!(truth > tracked + 0.3, "{half_turn:?}");
}
