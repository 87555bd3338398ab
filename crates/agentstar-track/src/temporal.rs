//! Temporal residuals (paper appendix; reference §3.22): per step the rotation, translation
//! and radial velocity and acceleration of the camera-motion-compensated pose
//! (`W_i = Rcam_i·R_i`, `u_i = Rcam_i·t_i / s`), and joint velocity and acceleration.
//! Differences are per step (never divided by the frame gap). No thresholds, no verdicts.

use agentstar_geom::pose::{ObjectPose, Rigid};
use agentstar_geom::{KinematicTree, UnitQuaternion, Vector3};

/// One keyframe's committed state.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub frame: String,
    /// The frame number (integer stem), for gaps.
    pub number: u64,
    pub pose: ObjectPose,
    /// Internal-unit joint states.
    pub states: Vec<f64>,
    /// `world_from_camera`, when cameras are known.
    pub world_from_camera: Option<Rigid>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct JointCell {
    pub name: String,
    /// Interface units (degrees or canonical units).
    pub state: f64,
    pub velocity: Option<f64>,
    pub acceleration: Option<f64>,
}

/// One row: the step that arrives at `frame` (velocity) and the change of step at `frame`
/// (acceleration, needing the next frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub frame: String,
    pub from: Option<String>,
    pub gap: Option<i64>,
    pub vel_rot_deg: Option<f64>,
    /// The axis of the step's rotation in the model's own frame (unit; the sign makes the
    /// turn positive), where the step turns by at least [`AXIS_MIN_DEG`]: a spin about the
    /// model's long axis and an end-over-end turn of the same angle read apart here.
    pub vel_axis: Option<[f64; 3]>,
    pub vel_trans: Option<f64>,
    pub vel_radial: Option<f64>,
    pub acc_rot_deg: Option<f64>,
    pub acc_trans: Option<f64>,
    pub acc_radial: Option<f64>,
    pub joints: Vec<JointCell>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// `oriented` (camera rotation compensated) or `camera` (no cameras: radial undefined).
    pub pose_frame: &'static str,
    pub rows: Vec<Row>,
    pub warnings: Vec<String>,
    /// The steps over [`LARGE_STEP_DEG`], in order (each also warned about).
    pub large_steps: Vec<LargeStep>,
}

/// A step turning the object by more than [`LARGE_STEP_DEG`]: a hand can make it, or one of
/// its two poses is a flip or a part swap of the right one.
#[derive(Debug, Clone, PartialEq)]
pub struct LargeStep {
    pub from: String,
    pub to: String,
    pub rotation_deg: f64,
}

/// A rotation step between keyframes over this many degrees is warned about ([`report`]).
pub const LARGE_STEP_DEG: f64 = 90.0;

/// Steps that turn less than this report no axis (it would be noise).
pub const AXIS_MIN_DEG: f64 = 1.0;

/// A model-frame axis for people and models: `+z` (or `-x`, …) within 18° of a model axis,
/// else its components.
pub fn axis_label(axis: &[f64; 3]) -> String {
    let (k, c) = (0..3)
        .map(|k| (k, axis[k]))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or((2, 1.0));
    if c.abs() >= 0.95 {
        format!("{}{}", if c < 0.0 { "-" } else { "+" }, ["x", "y", "z"][k])
    } else {
        format!("({:+.2},{:+.2},{:+.2})", axis[0], axis[1], axis[2])
    }
}

/// An angle the short way round, in (−180°, 180°]: −58°, not 302° (play-test 6).
pub fn signed_deg(deg: f64) -> f64 {
    180.0 - (180.0 - deg).rem_euclid(360.0)
}

/// Geodesic angle of a rotation in degrees, in [0, 180].
pub fn angle_deg(q: &UnitQuaternion) -> f64 {
    q.angle().to_degrees()
}

pub fn report(samples: &[Sample], scale: f64, tree: &KinematicTree) -> Report {
    let with_cams = samples
        .iter()
        .filter(|s| s.world_from_camera.is_some())
        .count();
    let oriented = with_cams == samples.len() && !samples.is_empty();
    let mut warnings = Vec::new();
    if with_cams > 0 && !oriented {
        warnings.push("only some frames have cameras: motion is reported in each frame's camera, radial is undefined".into());
    }
    let w: Vec<UnitQuaternion> = samples
        .iter()
        .map(|s| {
            if oriented {
                s.world_from_camera
                    .map_or(s.pose.rotation, |c| c.rotation * s.pose.rotation)
            } else {
                s.pose.rotation
            }
        })
        .collect();
    let u: Vec<Vector3> = samples
        .iter()
        .map(|s| {
            let tau = s.pose.translation / scale;
            if oriented {
                s.world_from_camera.map_or(tau, |c| c.rotation * tau)
            } else {
                tau
            }
        })
        .collect();
    let n = samples.len();
    let omega = |i: usize| w[i - 1].inverse() * w[i];
    let v = |i: usize| u[i] - u[i - 1];
    let mut gaps: Vec<i64> = (1..n)
        .map(|i| samples[i].number as i64 - samples[i - 1].number as i64)
        .collect();
    let rows: Vec<Row> = (0..n)
        .map(|i| {
            let has_v = i >= 1;
            let has_a = i >= 1 && i + 1 < n;
            let uhat = u[i].try_normalize(1e-12);
            let joints = tree
                .joints()
                .iter()
                .enumerate()
                .filter(|(_, j)| j.kind.has_state())
                .map(|(k, j)| {
                    let q =
                        |f: usize| j.to_interface(samples[f].states.get(k).copied().unwrap_or(0.0));
                    JointCell {
                        name: j.name.clone(),
                        state: q(i),
                        velocity: has_v.then(|| q(i) - q(i - 1)),
                        acceleration: has_a.then(|| (q(i + 1) - q(i)) - (q(i) - q(i - 1))),
                    }
                })
                .collect();
            Row {
                frame: samples[i].frame.clone(),
                from: has_v.then(|| samples[i - 1].frame.clone()),
                gap: has_v.then(|| samples[i].number as i64 - samples[i - 1].number as i64),
                vel_rot_deg: has_v.then(|| angle_deg(&omega(i))),
                vel_axis: has_v
                    .then(|| omega(i))
                    .filter(|q| angle_deg(q) >= AXIS_MIN_DEG)
                    .and_then(|q| q.axis())
                    .map(|a| [a.x, a.y, a.z]),
                vel_trans: has_v.then(|| v(i).norm()),
                vel_radial: if has_v && oriented {
                    uhat.map(|h| h.dot(&v(i)))
                } else {
                    None
                },
                acc_rot_deg: has_a.then(|| angle_deg(&(omega(i).inverse() * omega(i + 1)))),
                acc_trans: has_a.then(|| (v(i + 1) - v(i)).norm()),
                acc_radial: if has_a && oriented {
                    uhat.map(|h| h.dot(&(v(i + 1) - v(i))))
                } else {
                    None
                },
                joints,
            }
        })
        .collect();
    // A turn of more than a quarter between keyframes: hands do make them, but then a twin of
    // one of the two poses (a flip, a part swap) is as near as the pose itself, and every
    // gate passes either.
    let mut large_steps = Vec::new();
    for r in &rows {
        if let (Some(from), Some(deg)) = (&r.from, r.vel_rot_deg) {
            if deg > LARGE_STEP_DEG {
                large_steps.push(LargeStep {
                    from: from.clone(),
                    to: r.frame.clone(),
                    rotation_deg: deg,
                });
                let about = r
                    .vel_axis
                    .map(|a| format!(" about the model's {}", axis_label(&a)))
                    .unwrap_or_default();
                warnings.push(format!(
                    "step {from} -> {} turns the object by {deg:.0}°{about} (over {LARGE_STEP_DEG:.0}°): a hand can, or one of the two poses is a flip or part swap of the right one; `oapply` on {} scores its flips and swaps, each refined: if none comes within about 0.01 of its IoU, the step is real, else compare the close ones by eye (render side)",
                    r.frame, r.frame
                ));
            }
        }
    }
    gaps.sort_unstable();
    if let Some(&mode) = mode_of(&gaps) {
        for i in 1..n {
            let g = samples[i].number as i64 - samples[i - 1].number as i64;
            if g != mode {
                warnings.push(format!(
                    "step {} -> {} spans {g} frames where most steps span {mode}",
                    samples[i - 1].frame,
                    samples[i].frame
                ));
            }
        }
    }
    Report {
        pose_frame: if oriented { "oriented" } else { "camera" },
        rows,
        warnings,
        large_steps,
    }
}

fn mode_of(sorted: &[i64]) -> Option<&i64> {
    let mut best: Option<(&i64, usize)> = None;
    let mut i = 0;
    while i < sorted.len() {
        let j = sorted[i..].iter().take_while(|&&x| x == sorted[i]).count();
        if best.is_none_or(|(_, c)| j > c) {
            best = Some((&sorted[i], j));
        }
        i += j;
    }
    best.map(|(v, _)| v)
}

/// The residual between two frames' poses (reference §3.23).
#[derive(Debug, Clone, PartialEq)]
pub struct PairDiff {
    pub rotation_deg: f64,
    /// Rotation axis in the first frame's body (object) frame; `None` for no rotation.
    pub axis_body: Option<[f64; 3]>,
    pub translation_canon: [f64; 3],
    pub translation_dist_canon: f64,
    pub translation_dist: f64,
    /// Interface-unit joint deltas (b − a), by name, sorted.
    pub joints: Vec<(String, f64)>,
}

pub fn pair_diff(
    a: &Sample,
    b: &Sample,
    scale: f64,
    tree: &KinematicTree,
    oriented: bool,
) -> PairDiff {
    let wa = if oriented {
        a.world_from_camera
            .map_or(a.pose.rotation, |c| c.rotation * a.pose.rotation)
    } else {
        a.pose.rotation
    };
    let wb = if oriented {
        b.world_from_camera
            .map_or(b.pose.rotation, |c| c.rotation * b.pose.rotation)
    } else {
        b.pose.rotation
    };
    let ua = if oriented {
        a.world_from_camera
            .map_or(a.pose.translation, |c| c.rotation * a.pose.translation)
    } else {
        a.pose.translation
    } / scale;
    let ub = if oriented {
        b.world_from_camera
            .map_or(b.pose.translation, |c| c.rotation * b.pose.translation)
    } else {
        b.pose.translation
    } / scale;
    let rel = wa.inverse() * wb;
    let d = ub - ua;
    let mut joints: Vec<(String, f64)> = tree
        .joints()
        .iter()
        .enumerate()
        .filter(|(_, j)| j.kind.has_state())
        .map(|(k, j)| {
            (
                j.name.clone(),
                j.to_interface(b.states.get(k).copied().unwrap_or(0.0))
                    - j.to_interface(a.states.get(k).copied().unwrap_or(0.0)),
            )
        })
        .collect();
    joints.sort_by(|x, y| x.0.cmp(&y.0));
    PairDiff {
        rotation_deg: angle_deg(&rel),
        axis_body: rel.axis().map(|ax| ax.into_inner().into()),
        translation_canon: d.into(),
        translation_dist_canon: d.norm(),
        translation_dist: d.norm() * scale,
        joints,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::kinematics::KinematicTree;

    fn tree() -> KinematicTree {
        crate::space::tests::hinged_tree(180.0)
    }

    fn sample(k: u64, yaw_deg: f64, t: [f64; 3], hinge_deg: f64) -> Sample {
        Sample {
            frame: format!("{k:06}.jpg"),
            number: k,
            pose: ObjectPose::new(
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians()),
                Vector3::from(t),
            ),
            states: vec![hinge_deg.to_radians()],
            world_from_camera: None,
        }
    }

    #[test]
    fn hand_computed_sequence() {
        // Rotation about z: 0, 30, 90, 280 (a 190° step, which reads as 170°).
        let s = vec![
            sample(0, 0.0, [0.0, 0.0, 1.0], 0.0),
            sample(5, 30.0, [0.1, 0.0, 1.0], 10.0),
            sample(10, 90.0, [0.1, 0.0, 1.2], 30.0),
            sample(15, 280.0, [0.1, 0.0, 1.2], 30.0),
        ];
        let r = report(&s, 0.5, &tree());
        assert_eq!(r.pose_frame, "camera");
        assert_eq!(r.rows[0].vel_rot_deg, None);
        assert!((r.rows[1].vel_rot_deg.expect("v") - 30.0).abs() < 1e-9);
        assert!((r.rows[2].vel_rot_deg.expect("v") - 60.0).abs() < 1e-9);
        // Every step turns about the model's z axis (the 190° one as 170° about −z).
        let axis = |k: usize| axis_label(&r.rows[k].vel_axis.expect("axis"));
        assert_eq!(
            (axis(1), axis(2), axis(3)),
            ("+z".into(), "+z".into(), "-z".into())
        );
        assert_eq!(r.rows[0].vel_axis, None);
        assert!(
            (r.rows[3].vel_rot_deg.expect("v") - 170.0).abs() < 1e-9,
            "{:?}",
            r.rows[3].vel_rot_deg
        );
        // Translation in object units (t / s): 0.1/0.5 = 0.2, then 0.2/0.5 = 0.4.
        assert!((r.rows[1].vel_trans.expect("v") - 0.2).abs() < 1e-12);
        assert!((r.rows[2].vel_trans.expect("v") - 0.4).abs() < 1e-12);
        // Acceleration at frame 1: |v2 − v1| = |(0, 0, 0.4) − (0.2, 0, 0)|; rotation 60 − 30.
        assert!((r.rows[1].acc_trans.expect("a") - (0.04f64 + 0.16).sqrt()).abs() < 1e-12);
        assert!((r.rows[1].acc_rot_deg.expect("a") - 30.0).abs() < 1e-9);
        // Ω2ᵀΩ3 = Rz(−60)·Rz(190) = Rz(130).
        assert!((r.rows[2].acc_rot_deg.expect("a") - 130.0).abs() < 1e-9);
        assert_eq!(r.rows[3].acc_rot_deg, None);
        assert!((r.rows[2].joints[0].velocity.expect("v") - 20.0).abs() < 1e-9);
        assert!((r.rows[1].joints[0].acceleration.expect("a") - 10.0).abs() < 1e-9);
        assert_eq!(r.rows[1].vel_radial, None, "radial needs cameras");
        // The 170° step, and only it, is over a quarter turn.
        assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
        assert!(
            r.warnings[0].starts_with("step 000010.jpg -> 000015.jpg turns the object by 170°"),
            "{:?}",
            r.warnings
        );
        // It names the check that settles it, on the later frame, without claiming a twin fits.
        assert!(
            r.warnings[0].contains("`oapply` on 000015.jpg scores its flips and swaps"),
            "{:?}",
            r.warnings
        );
    }

    #[test]
    fn camera_motion_is_compensated_and_radial_is_signed() {
        // A static object seen by a camera that turns: no object rotation in the world.
        let mut s = Vec::new();
        for k in 0..3u64 {
            let cam_rot = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.1 * k as f64);
            let c2w = Rigid::from_parts(nalgebra::Translation3::new(0.0, 0.0, 0.0), cam_rot);
            // Object at world (0, 0, 2 + 0.5 k): in camera k it is R_kᵀ · p.
            let world_p = Vector3::new(0.0, 0.0, 2.0 + 0.5 * k as f64);
            let pose = ObjectPose::new(cam_rot.inverse(), cam_rot.inverse() * world_p);
            s.push(Sample {
                frame: format!("{k}"),
                number: k,
                pose,
                states: vec![0.0],
                world_from_camera: Some(c2w),
            });
        }
        let r = report(&s, 1.0, &tree());
        assert_eq!(r.pose_frame, "oriented");
        assert!(r.rows[1].vel_rot_deg.expect("v") < 1e-9);
        assert!(
            (r.rows[1].vel_radial.expect("radial") - 0.5).abs() < 1e-9,
            "moving away is positive"
        );
        let d = pair_diff(&s[0], &s[2], 1.0, &tree(), true);
        assert!(d.rotation_deg < 1e-9 && (d.translation_dist_canon - 1.0).abs() < 1e-9);
    }

    #[test]
    fn uneven_gaps_are_warned() {
        let s = vec![
            sample(0, 0.0, [0.0; 3], 0.0),
            sample(5, 0.0, [0.0; 3], 0.0),
            sample(10, 0.0, [0.0; 3], 0.0),
            sample(25, 0.0, [0.0; 3], 0.0),
        ];
        let r = report(&s, 1.0, &tree());
        assert_eq!(r.warnings.len(), 1);
        assert!(r.warnings[0].contains("spans 15"));
    }

    #[test]
    fn a_spin_and_an_end_over_end_turn_of_one_angle_have_different_axes() {
        // The model turned 90° about its own x axis after a 40° turn about z: the step's
        // axis is the model's x, whatever the pose it starts from.
        let start = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 40f64.to_radians());
        let about = |axis: nalgebra::Unit<Vector3>, deg: f64| {
            start * UnitQuaternion::from_axis_angle(&axis, deg.to_radians())
        };
        let at = |k: u64, q: UnitQuaternion| Sample {
            frame: format!("{k}"),
            number: k,
            pose: ObjectPose::new(q, Vector3::new(0.0, 0.0, 1.0)),
            states: vec![0.0],
            world_from_camera: None,
        };
        let s = vec![
            at(0, start),
            at(1, about(Vector3::x_axis(), 90.0)),
            at(
                2,
                about(Vector3::x_axis(), 90.0)
                    * UnitQuaternion::from_axis_angle(
                        &nalgebra::Unit::new_normalize(Vector3::new(0.0, 1.0, 1.0)),
                        0.9,
                    ),
            ),
            at(
                3,
                about(Vector3::x_axis(), 90.0)
                    * UnitQuaternion::from_axis_angle(
                        &nalgebra::Unit::new_normalize(Vector3::new(0.0, 1.0, 1.0)),
                        0.9,
                    ),
            ),
        ];
        let r = report(&s, 1.0, &tree());
        assert_eq!(axis_label(&r.rows[1].vel_axis.expect("axis")), "+x");
        assert_eq!(
            axis_label(&r.rows[2].vel_axis.expect("axis")),
            "(+0.00,+0.71,+0.71)"
        );
        assert_eq!(r.rows[3].vel_axis, None, "no turn, no axis");
    }
}
