//! Object and camera trajectories of the three kinds of capture in the paper's datasets.
//!
//! Object motion is defined in a world frame and the camera has its own trajectory, so the
//! object's pose in each camera is `camera_from_world · world_from_object` and the cameras
//! written to the capture are the true ones (the tracker's camera compensation is tested).

use agentstar_geom::camera::look_at;
use agentstar_geom::pose::{ObjectPose, Rigid};
use agentstar_geom::{ObjectModel, PinholeCamera, Point3, UnitQuaternion, Vector3};
use agentstar_optim::Rng;
use std::f64::consts::{PI, TAU};

/// How the object and the camera move.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Motion {
    /// ARCTIC-like: held near an egocentric camera, rapid rotation (12° to 35° a
    /// keyframe about a drifting axis), every joint sweeping its range.
    HandHeld,
    /// HOT3D-like: rigid motion with steps up to 180° between keyframes (most small, some
    /// large), a wandering head camera.
    RigidSteps,
    /// iTACO-like: a static object, a camera orbiting it, one joint moving; with depth.
    StaticOrbit,
    /// The hard suite's hand-held motion, as in captures made outside this project: about
    /// 40° mean rotation a keyframe (most steps 12°–42°, some 80°–130° and one 130°–150°),
    /// every joint sweeping its range, a camera that moves around the object as well.
    HardHeld,
}

impl Motion {
    pub const ALL: [Motion; 4] = [
        Motion::HandHeld,
        Motion::RigidSteps,
        Motion::StaticOrbit,
        Motion::HardHeld,
    ];

    pub fn as_str(&self) -> &'static str {
        match self {
            Motion::HandHeld => "handheld",
            Motion::RigidSteps => "rigid-steps",
            Motion::StaticOrbit => "static-orbit",
            Motion::HardHeld => "hard-held",
        }
    }
    pub fn parse(s: &str) -> Option<Motion> {
        Motion::ALL.into_iter().find(|m| m.as_str() == s)
    }
    /// The motion the object's dataset has.
    pub fn default_for(family: crate::Family) -> Motion {
        match family {
            crate::Family::Arctic => Motion::HandHeld,
            crate::Family::Hot3d => Motion::RigidSteps,
            crate::Family::Itaco => Motion::StaticOrbit,
        }
    }
}

/// One keyframe of a trajectory.
#[derive(Debug, Clone)]
pub struct Step {
    pub world_from_camera: Rigid,
    pub camera_from_object: ObjectPose,
    pub states: Vec<f64>,
}

pub(crate) fn random_axis(rng: &mut Rng) -> Vector3 {
    loop {
        let v = Vector3::new(rng.normal(), rng.normal(), rng.normal());
        if v.norm() > 1e-3 {
            return v.normalize();
        }
    }
}

/// Joint states sweeping each joint's limits (a cosine with a random number of cycles and
/// phase); only `moving` joints move, the others keep a random fixed state.
pub(crate) fn joint_states(
    model: &ObjectModel,
    n: usize,
    moving: &[bool],
    rng: &mut Rng,
) -> Vec<Vec<f64>> {
    let joints = model.tree.joints();
    let plans: Vec<(f64, f64, f64, f64, f64)> = joints
        .iter()
        .map(|j| {
            let (lo, hi) = j.limit.unwrap_or(if j.kind.is_angular() {
                (-180.0, 180.0)
            } else {
                (0.0, 0.3)
            });
            // Keep clear of the limits by 5% so that states are strictly inside.
            let (lo, hi) = (lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo));
            (
                lo,
                hi,
                rng.range(0.6, 1.3),
                rng.range(0.0, 0.35),
                rng.range(0.0, 1.0),
            )
        })
        .collect();
    (0..n)
        .map(|k| {
            let t = k as f64 / (n - 1).max(1) as f64;
            joints
                .iter()
                .zip(&plans)
                .enumerate()
                .map(|(j, (jd, &(lo, hi, cycles, phase, fixed)))| {
                    let u = if moving.get(j).copied().unwrap_or(false) {
                        0.5 - 0.5 * (TAU * (cycles * t + phase)).cos()
                    } else {
                        fixed
                    };
                    jd.to_internal(lo + (hi - lo) * u)
                })
                .collect()
        })
        .collect()
}

/// The distance at which the object's bounding sphere spans `fraction` of the image height.
pub(crate) fn viewing_distance(
    model: &ObjectModel,
    scale: f64,
    camera: &PinholeCamera,
    fraction: f64,
) -> f64 {
    let radius = 0.5
        * model
            .posed_bounds(&model.tree.rest_states())
            .extent()
            .norm()
        * scale;
    camera.fy * radius / (0.5 * fraction * camera.height.min(camera.width) as f64)
}

/// The trajectory of `n` keyframes.
pub fn trajectory(
    motion: Motion,
    model: &ObjectModel,
    scale: f64,
    camera: &PinholeCamera,
    n: usize,
    rng: &mut Rng,
) -> Vec<Step> {
    let n_joints = model.tree.joints().len();
    match motion {
        Motion::HandHeld | Motion::RigidSteps => {
            let hand_held = motion == Motion::HandHeld;
            let d = viewing_distance(model, scale, camera, if hand_held { 0.6 } else { 0.5 });
            let moving = vec![hand_held; n_joints];
            let states = joint_states(model, n, &moving, rng);
            let rotation = upright_start(rng, (100.0, 125.0));
            let axis = random_axis(rng);
            let drift = (rng.range(0.0, TAU), rng.range(0.0, TAU));
            let turns = Wander {
                rotation,
                axis,
                axis_weight: 0.6,
            };
            let step_deg = |_: usize, rng: &mut Rng| {
                if hand_held {
                    rng.range(12.0, 35.0)
                } else if rng.uniform() < 0.3 {
                    rng.range(40.0, 180.0)
                } else {
                    rng.range(3.0, 30.0)
                }
            };
            let place = |t: f64, rng: &mut Rng| {
                let centre = Point3::new(
                    0.12 * d * (TAU * 0.7 * t + drift.0).sin(),
                    0.08 * d * (TAU * 0.9 * t + drift.1).sin(),
                    d * (1.0 + 0.1 * (TAU * 0.5 * t + drift.0).sin()),
                );
                // The head moves a little and looks near the object; world up is −Y.
                let eye = Point3::new(
                    0.04 * d * rng.range(-1.0, 1.0),
                    0.04 * d * rng.range(-1.0, 1.0),
                    0.03 * d * rng.range(-1.0, 1.0),
                );
                let aim = centre + Vector3::new(rng.normal(), rng.normal(), 0.0) * 0.03 * d;
                (centre, look_at(&eye, &aim, &-Vector3::y()))
            };
            held_steps(model, scale, states, turns, rng, step_deg, place)
        }
        Motion::HardHeld => {
            let d = viewing_distance(model, scale, camera, 0.55);
            let states = joint_states(model, n, &vec![true; n_joints], rng);
            let rotation = upright_start(rng, (90.0, 135.0));
            // The one step of 130°–150°.
            let biggest = 1 + ((n.saturating_sub(1)) as f64 * rng.uniform()) as usize;
            let axis = random_axis(rng);
            let drift = (
                rng.range(0.0, TAU),
                rng.range(0.0, TAU),
                rng.range(0.0, TAU),
            );
            let turns = Wander {
                rotation,
                axis,
                axis_weight: 0.8,
            };
            let step_deg = |k: usize, rng: &mut Rng| {
                if k == biggest {
                    rng.range(130.0, 150.0)
                } else if rng.uniform() < 0.12 {
                    rng.range(80.0, 130.0)
                } else {
                    rng.range(12.0, 42.0)
                }
            };
            let place = |t: f64, rng: &mut Rng| {
                let centre = Point3::new(
                    0.15 * d * (TAU * 0.7 * t + drift.0).sin(),
                    0.1 * d * (TAU * 0.9 * t + drift.1).sin(),
                    d * (1.0 + 0.12 * (TAU * 0.5 * t + drift.2).sin()),
                );
                // The camera walks around the object (up to about ±25° of azimuth) and looks
                // near it; world up is −Y.
                let az = 0.45 * (TAU * 0.6 * t + drift.2).sin();
                let eye = centre
                    + Vector3::new(
                        -d * az.sin(),
                        0.12 * d * (TAU * t + drift.0).sin(),
                        -d * az.cos(),
                    )
                    + Vector3::new(rng.normal(), rng.normal(), rng.normal()) * 0.02 * d;
                let aim = centre + Vector3::new(rng.normal(), rng.normal(), 0.0) * 0.04 * d;
                (centre, look_at(&eye, &aim, &-Vector3::y()))
            };
            held_steps(model, scale, states, turns, rng, step_deg, place)
        }
        Motion::StaticOrbit => {
            // One joint moves (the first with a state); the object stands upright at the world
            // origin (world +Z up) and the camera orbits it at a fixed elevation.
            let mover = model.tree.joints().iter().position(|j| j.kind.has_state());
            let moving: Vec<bool> = (0..n_joints).map(|j| Some(j) == mover).collect();
            let states = joint_states(model, n, &moving, rng);
            let d = viewing_distance(model, scale, camera, 0.62);
            let elevation = rng.range(15.0, 35.0).to_radians();
            let azimuth0 = rng.range(-110.0, -70.0).to_radians();
            let sweep =
                rng.range(60.0, 110.0).to_radians() * if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
            let world_from_object = ObjectPose::identity();
            (0..n)
                .zip(states)
                .map(|(k, st)| {
                    let t = k as f64 / (n - 1).max(1) as f64;
                    let az = azimuth0 + sweep * t;
                    let r = d * (1.0 + 0.05 * (TAU * t).sin());
                    let eye = Point3::new(
                        r * elevation.cos() * az.cos(),
                        r * elevation.cos() * az.sin(),
                        r * elevation.sin(),
                    );
                    let camera_from_world = look_at(&eye, &Point3::origin(), &Vector3::z());
                    Step {
                        world_from_camera: camera_from_world.inverse(),
                        camera_from_object: compose(&camera_from_world, &world_from_object),
                        states: st,
                    }
                })
                .collect()
        }
    }
}

/// The motion between two consecutive keyframes at `s` in (0, 1), as a video samples it: the
/// object turns about its centre through the keyframes' one rotation step (the shortest
/// rotation between their orientations in the world) at a steady rate while its centre moves
/// on a straight line; the camera likewise; joint states move linearly.
pub fn between_step(a: &Step, b: &Step, model: &ObjectModel, scale: f64, s: f64) -> Step {
    let along = |ra: &UnitQuaternion, rb: &UnitQuaternion| (rb * ra.inverse()).powf(s) * ra;
    let states: Vec<f64> = a
        .states
        .iter()
        .zip(&b.states)
        .map(|(x, y)| x + s * (y - x))
        .collect();
    let world_from_object = |st: &Step| st.world_from_camera * st.camera_from_object.to_rigid();
    let (wa, wb) = (world_from_object(a), world_from_object(b));
    let pivot = |st: &[f64]| model.posed_bounds(st).center().coords * scale;
    let centre_a = wa * Point3::from(pivot(&a.states));
    let centre_b = wb * Point3::from(pivot(&b.states));
    let rotation = along(&wa.rotation, &wb.rotation);
    let centre = centre_a.coords + s * (centre_b - centre_a);
    let world_from_object = ObjectPose::new(rotation, centre - rotation * pivot(&states));
    let camera_rotation = along(&a.world_from_camera.rotation, &b.world_from_camera.rotation);
    let (ea, eb) = (
        a.world_from_camera.translation.vector,
        b.world_from_camera.translation.vector,
    );
    let world_from_camera = Rigid::from_parts((ea + s * (eb - ea)).into(), camera_rotation);
    Step {
        world_from_camera,
        camera_from_object: compose(&world_from_camera.inverse(), &world_from_object),
        states,
    }
}

/// A held object's turning: its first orientation, and the axis it turns about, which
/// wanders each step by `axis_weight` of a random axis.
struct Wander {
    rotation: UnitQuaternion,
    axis: Vector3,
    axis_weight: f64,
}

/// The keyframes of a held object, one per joint state: each after the first turned by
/// `step_deg(k, rng)` degrees about the wandering axis (its draw first), then placed by
/// `place(t, rng)` (t from 0 to 1: the centre in the world and `camera_from_world`).
fn held_steps(
    model: &ObjectModel,
    scale: f64,
    states: Vec<Vec<f64>>,
    turns: Wander,
    rng: &mut Rng,
    step_deg: impl Fn(usize, &mut Rng) -> f64,
    place: impl Fn(f64, &mut Rng) -> (Point3, Rigid),
) -> Vec<Step> {
    let n = states.len();
    let Wander {
        mut rotation,
        mut axis,
        axis_weight,
    } = turns;
    let mut steps = Vec::with_capacity(n);
    for (k, st) in states.into_iter().enumerate() {
        if k > 0 {
            axis = (axis + axis_weight * random_axis(rng)).normalize();
            rotation = turned(rotation, axis, step_deg(k, rng));
        }
        let t = k as f64 / (n - 1).max(1) as f64;
        let (centre, camera_from_world) = place(t, rng);
        steps.push(held_step(
            model,
            scale,
            &camera_from_world,
            rotation,
            centre,
            st,
        ));
    }
    steps
}

/// Upright, tilted toward the camera by an angle drawn from `tilt_deg`, at a random heading
/// (drawn first).
fn upright_start(rng: &mut Rng, tilt_deg: (f64, f64)) -> UnitQuaternion {
    let heading = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), rng.range(-PI, PI));
    heading
        * UnitQuaternion::from_axis_angle(
            &Vector3::x_axis(),
            rng.range(tilt_deg.0, tilt_deg.1).to_radians(),
        )
}

/// `rotation` followed by a turn of `angle_deg` about `axis` (in the world frame).
pub(crate) fn turned(rotation: UnitQuaternion, axis: Vector3, angle_deg: f64) -> UnitQuaternion {
    UnitQuaternion::from_axis_angle(
        &agentstar_geom::nalgebra::Unit::new_normalize(axis),
        angle_deg.to_radians(),
    ) * rotation
}

/// A keyframe of a held object: turned by `rotation` about its bounding-box centre, which
/// stands at `centre` in the world, seen by `camera_from_world`.
pub(crate) fn held_step(
    model: &ObjectModel,
    scale: f64,
    camera_from_world: &Rigid,
    rotation: UnitQuaternion,
    centre: Point3,
    states: Vec<f64>,
) -> Step {
    let pivot = model.posed_bounds(&states).center().coords * scale;
    let world_from_object = ObjectPose::new(rotation, centre.coords - rotation * pivot);
    Step {
        world_from_camera: camera_from_world.inverse(),
        camera_from_object: compose(camera_from_world, &world_from_object),
        states,
    }
}

fn compose(camera_from_world: &Rigid, world_from_object: &ObjectPose) -> ObjectPose {
    let c = camera_from_world * world_from_object.to_rigid();
    ObjectPose::new(c.rotation, c.translation.vector)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{build_object, ObjectSpec};

    fn step_angle_deg(a: &Step, b: &Step) -> f64 {
        // Rotation of the object in the world between two keyframes.
        let wa = a.world_from_camera.rotation * a.camera_from_object.rotation;
        let wb = b.world_from_camera.rotation * b.camera_from_object.rotation;
        (wb * wa.inverse()).angle().to_degrees()
    }

    #[test]
    fn motions_have_the_promised_steps_and_keep_the_object_in_front() {
        let spec = ObjectSpec::find("laptop").expect("laptop");
        let model = build_object(spec).expect("builds");
        let cam = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
        for motion in Motion::ALL {
            let mut rng = Rng::new(5);
            let steps = trajectory(motion, &model, spec.size_m, &cam, 30, &mut rng);
            assert_eq!(steps.len(), 30);
            let angles: Vec<f64> = steps
                .windows(2)
                .map(|w| step_angle_deg(&w[0], &w[1]))
                .collect();
            let max = angles.iter().cloned().fold(0.0, f64::max);
            match motion {
                Motion::HandHeld => assert!(
                    angles.iter().all(|&a| (11.9..=35.1).contains(&a)),
                    "{angles:?}"
                ),
                Motion::RigidSteps => assert!(max > 40.0 && max <= 180.0, "{angles:?}"),
                Motion::StaticOrbit => assert!(max < 1e-9, "the object is static: {angles:?}"),
                Motion::HardHeld => {
                    let mean = angles.iter().sum::<f64>() / angles.len() as f64;
                    assert!((130.0..=150.0).contains(&max), "{angles:?}");
                    assert!((30.0..=50.0).contains(&mean), "mean {mean}: {angles:?}");
                    assert!(angles.iter().all(|&a| a >= 11.9), "{angles:?}");
                }
            }
            // In-between steps divide each keyframe step evenly and end where it ends.
            for pair in steps.windows(2) {
                let whole = step_angle_deg(&pair[0], &pair[1]);
                let mut previous = pair[0].clone();
                for j in 1..=9 {
                    let mid =
                        between_step(&pair[0], &pair[1], &model, spec.size_m, j as f64 / 10.0);
                    let part = step_angle_deg(&previous, &mid);
                    assert!(
                        (part - whole / 10.0).abs() < 1e-6,
                        "{motion:?}: {part} of {whole}"
                    );
                    assert!(mid.camera_from_object.translation.z > 0.2, "{motion:?}");
                    previous = mid;
                }
                let last = step_angle_deg(&previous, &pair[1]);
                assert!(
                    (last - whole / 10.0).abs() < 1e-6,
                    "{motion:?}: {last} of {whole}"
                );
                let end = between_step(&pair[0], &pair[1], &model, spec.size_m, 1.0);
                assert!(
                    (end.camera_from_object.translation - pair[1].camera_from_object.translation)
                        .norm()
                        < 1e-9
                        && end
                            .camera_from_object
                            .rotation
                            .angle_to(&pair[1].camera_from_object.rotation)
                            < 1e-9,
                    "{motion:?}: s = 1 is the next keyframe"
                );
            }
            for s in &steps {
                assert!(s.camera_from_object.translation.z > 0.2, "{motion:?}");
                let lim = model.tree.joints()[0].limit.expect("limit");
                let deg = s.states[0].to_degrees();
                assert!(deg >= lim.0 && deg <= lim.1, "{deg} within {lim:?}");
            }
        }
    }
}
