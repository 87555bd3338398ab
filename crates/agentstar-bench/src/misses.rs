//! Where a sequence's misses come from: for every keyframe whose tracked rotation is more
//! than [`MISS_DEG`] from the truth (after the object's symmetries), the evidence the tracker
//! scores, at the tracked pose and at the true one: the masks (the gate IoU every search
//! ranks by) and the model's own colours against the frame ([`model_agreement`]). A miss is
//! then one of three kinds, each asking for different work:
//!
//! - [`MissCause::Search`]: the truth explains the mask clearly better; masks alone would
//!   have taken it, so no search reached it (or a pass turned away from it).
//! - [`MissCause::Colours`]: the masks tie, and the model's colours prefer the truth: the
//!   evidence was there and the choice did not weigh it enough.
//! - [`MissCause::Evidence`]: neither the masks nor the model's colours prefer the truth (only
//!   the frames' colours against each other, or the motion, could tell).

use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{PinholeCamera, UnitQuaternion};
use agentstar_render::ScoreTarget;
use agentstar_synth::SynthCapture;
use agentstar_track::appearance::{model_agreement, AppearanceConfig, AppearanceFrame};
use agentstar_track::objective::FrameProblem;
use agentstar_track::tracker::ChoiceTrace;
use agentstar_track::GenPose;
use serde::{Deserialize, Serialize};

/// A keyframe tracked farther than this from the truth (rotation, after the object's
/// symmetries; the suites' 3° bound) is a miss.
pub const MISS_DEG: f64 = 3.0;
/// Two poses whose gate IoUs differ by less than this explain the mask equally (a
/// segmenter's boundary noise moves the right pose's IoU by about this much; the tracker's
/// appearance tie).
pub const MASK_TIE: f64 = 0.005;

/// Why a keyframe missed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MissCause {
    Search,
    Colours,
    Evidence,
}

/// Whether the sequence-level choice weighed a hypothesis within [`MISS_DEG`] of a missed
/// keyframe's truth (after the object's symmetries), and what it did with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighed {
    /// The choice took a pose near the truth: a pass after it moved the frame away.
    Taken,
    /// Among the choice's hypotheses, and another taken: the weighing is wrong.
    NotTaken,
    /// No hypothesis near the truth: no search proposed it.
    Absent,
}

/// One missed keyframe and the evidence at both poses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameMiss {
    pub frame: String,
    pub rotation_deg: f64,
    pub gate_tracked: f64,
    pub gate_truth: f64,
    /// The model's colours against the frame ([`model_agreement`]); `None` for a model of
    /// one colour or a frame without colours.
    pub model_ncc_tracked: Option<f64>,
    pub model_ncc_truth: Option<f64>,
    pub cause: MissCause,
    /// What the sequence-level choice did with the truth; `None` where it did not run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weighed: Option<Weighed>,
}

/// The misses of a sequence, counted by cause.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Misses {
    pub search: usize,
    pub colours: usize,
    pub evidence: usize,
    pub frames: Vec<FrameMiss>,
}

impl Misses {
    pub fn total(&self) -> usize {
        self.frames.len()
    }

    /// The misses whose truth the sequence-level choice weighed as `w`.
    pub fn weighed(&self, w: Weighed) -> usize {
        self.frames.iter().filter(|f| f.weighed == Some(w)).count()
    }
}

/// What the choice did with `truth` at one keyframe: its hypotheses there and the index its
/// path took; each hypothesis measured from the truth's equivalent under the object's
/// `symmetries` nearest it ([`nearest_equivalent`]), by rotation alone as a miss is (a
/// hypothesis with a joint off counts as the truth).
pub fn choice_verdict(
    hypotheses: &[GenPose],
    taken: usize,
    truth: &GenPose,
    symmetries: &[UnitQuaternion],
) -> Weighed {
    let near = |g: &GenPose| {
        let t = nearest_equivalent(truth, g, symmetries);
        t.pose.rotation.angle_to(&g.pose.rotation).to_degrees() <= MISS_DEG
    };
    if hypotheses.get(taken).is_some_and(near) {
        Weighed::Taken
    } else if hypotheses.iter().any(near) {
        Weighed::NotTaken
    } else {
        Weighed::Absent
    }
}

/// The cause of a miss from the evidence at the tracked pose and at the truth.
pub fn cause(
    gate_tracked: f64,
    gate_truth: f64,
    ncc_tracked: Option<f64>,
    ncc_truth: Option<f64>,
    ncc_margin: f64,
) -> MissCause {
    if gate_truth > gate_tracked + MASK_TIE {
        MissCause::Search
    } else if gate_truth >= gate_tracked - MASK_TIE
        && matches!((ncc_tracked, ncc_truth), (Some(a), Some(b)) if b > a + ncc_margin)
    {
        MissCause::Colours
    } else {
        MissCause::Evidence
    }
}

/// The true pose of a frame turned by whichever of the object's `symmetries` (rotations in
/// the model's frame, about its origin; the identity is always one) brings it nearest to
/// `tracked`: a pose equivalent to the truth in shape, print and joints, and the one a miss is
/// measured from. The sequence's errors align the whole sequence by one gauge; a frame's
/// evidence needs a pose the frame could show, so it is chosen per frame (BOP's rule): a
/// tracker that put every frame of a two-fold object in its half-turn twin has no miss.
pub fn nearest_equivalent(
    truth: &GenPose,
    tracked: &GenPose,
    symmetries: &[UnitQuaternion],
) -> GenPose {
    std::iter::once(UnitQuaternion::identity())
        .chain(symmetries.iter().copied())
        .map(|s| GenPose {
            pose: ObjectPose::new(truth.pose.rotation * s, truth.pose.translation),
            states: truth.states.clone(),
        })
        .min_by(|a, b| {
            a.pose
                .rotation
                .angle_to(&tracked.pose.rotation)
                .total_cmp(&b.pose.rotation.angle_to(&tracked.pose.rotation))
        })
        .unwrap_or_else(|| truth.clone())
}

/// The misses of `tracked` against `truth` (per keyframe), each frame's truth taken as its
/// equivalent under the object's `symmetries` nearest the tracked pose
/// ([`nearest_equivalent`]), with `cameras` and `targets` as the tracker saw them.
pub fn misses(
    capture: &SynthCapture,
    cameras: &[PinholeCamera],
    targets: &[ScoreTarget],
    truth: &[GenPose],
    tracked: &[GenPose],
    choice: Option<&ChoiceTrace>,
) -> Misses {
    let cfg = AppearanceConfig::default();
    let mut out = Misses::default();
    for (i, (t, p)) in truth.iter().zip(tracked).enumerate() {
        let t = &nearest_equivalent(t, p, &capture.symmetries);
        let rotation_deg = t.pose.rotation.angle_to(&p.pose.rotation).to_degrees();
        if rotation_deg <= MISS_DEG {
            continue;
        }
        let (Some(f), Some(camera), Some(target)) =
            (capture.frames.get(i), cameras.get(i), targets.get(i))
        else {
            continue;
        };
        let problem = FrameProblem::new(&capture.model, *camera, target, capture.scale, t.clone());
        let mut ev = problem.evaluator();
        let (gate_truth, gate_tracked) = (ev.score(t).gate, ev.score(p).gate);
        let frame = AppearanceFrame {
            camera,
            rgb: f.rgb.as_raw().as_slice(),
            mask: target.mask(),
        };
        let ncc = |g: &GenPose| model_agreement(&capture.model, capture.scale, &frame, g, &cfg).ncc;
        let (model_ncc_truth, model_ncc_tracked) = (ncc(t), ncc(p));
        let cause = cause(
            gate_tracked,
            gate_truth,
            model_ncc_tracked,
            model_ncc_truth,
            cfg.margin,
        );
        match cause {
            MissCause::Search => out.search += 1,
            MissCause::Colours => out.colours += 1,
            MissCause::Evidence => out.evidence += 1,
        }
        let weighed = choice.and_then(|c| {
            Some(choice_verdict(
                c.hypotheses.get(i)?,
                *c.path.get(i)?,
                t,
                &capture.symmetries,
            ))
        });
        out.frames.push(FrameMiss {
            frame: f.name.clone(),
            rotation_deg,
            gate_tracked,
            gate_truth,
            model_ncc_tracked,
            model_ncc_truth,
            cause,
            weighed,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_miss_is_told_by_the_evidence_that_prefers_the_truth() {
        // The truth clearly better on the mask: the search never reached it.
        assert_eq!(
            cause(0.95, 0.99, Some(0.5), Some(0.1), 0.02),
            MissCause::Search
        );
        // Masks tie (either way within the tie) and the model's colours prefer the truth.
        assert_eq!(
            cause(0.97, 0.968, Some(0.1), Some(0.5), 0.02),
            MissCause::Colours
        );
        // Masks tie, colours within their margin: nothing scored prefers the truth.
        assert_eq!(
            cause(0.97, 0.97, Some(0.49), Some(0.5), 0.02),
            MissCause::Evidence
        );
        // The tracked pose explains the mask better: colours do not excuse it.
        assert_eq!(
            cause(0.98, 0.96, Some(0.1), Some(0.9), 0.02),
            MissCause::Evidence
        );
        // A model of one colour has no colour evidence.
        assert_eq!(cause(0.97, 0.97, None, None, 0.02), MissCause::Evidence);
    }

    #[test]
    fn a_frame_in_a_true_symmetry_of_the_truth_is_measured_from_that_equivalent() {
        use agentstar_geom::Vector3;
        let truth = GenPose {
            pose: ObjectPose::new(
                UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
                Vector3::new(0.0, 0.0, 0.6),
            ),
            states: vec![],
        };
        let half_turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let nudge = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1f64.to_radians());
        // Tracked 1° off the truth's half-turn twin, which is one of the object's symmetries.
        let tracked = GenPose {
            pose: ObjectPose::new(
                truth.pose.rotation * half_turn * nudge,
                truth.pose.translation,
            ),
            states: vec![],
        };
        let deg = |t: &GenPose| {
            t.pose
                .rotation
                .angle_to(&tracked.pose.rotation)
                .to_degrees()
        };
        assert!(deg(&truth) > 170.0, "{}", deg(&truth));
        let near = nearest_equivalent(&truth, &tracked, &[half_turn]);
        assert!((deg(&near) - 1.0).abs() < 1e-6, "{}", deg(&near));
        assert_eq!(near.pose.translation, truth.pose.translation);
        // Without the symmetry, the truth itself.
        assert_eq!(nearest_equivalent(&truth, &tracked, &[]), truth);
    }
}
