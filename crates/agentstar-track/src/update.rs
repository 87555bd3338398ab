//! Pose updates exactly as the reference harness defines them (reference-harness §2).
//!
//! Camera-frame order (left update): `p_new = s·dR·R·(p − c) + s·R·c + t + dT` with
//! `dR = R_pitch · R_yaw · R_roll`; roll about +Z (optical axis), yaw about −Y (camera up),
//! pitch about +X (camera right), all right-handed, degrees at the interface. `dT` is
//! `(dpx·W/fx·z, dpy·H/fy·z, tz·z)` with `z` the pivot's camera depth. The pivot `c` is the
//! canonical bounding-box centre of the forward-kinematics-posed parts, frozen per search.
//!
//! Object-frame rotation (right update): `R' = R·dR`, `t' = t + s·R·(I − dR)·c`, with `dR`
//! the rotation vector `(rx, ry, rz)` in degrees.

use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{PinholeCamera, Point3, UnitQuaternion, Vector3};

pub use agentstar_geom::pose::GenPose;

/// A camera-frame increment: angles in degrees, shifts as fractions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CameraOrder {
    pub roll_deg: f64,
    pub yaw_deg: f64,
    pub pitch_deg: f64,
    /// Fraction of the image width.
    pub dpx: f64,
    /// Fraction of the image height.
    pub dpy: f64,
    /// Fraction of the pivot's camera depth (+ moves away).
    pub tz: f64,
}

/// `dR = R_pitch · R_yaw · R_roll`.
pub fn camera_rotation(order: &CameraOrder) -> UnitQuaternion {
    let roll = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), order.roll_deg.to_radians());
    let yaw = UnitQuaternion::from_axis_angle(&-Vector3::y_axis(), order.yaw_deg.to_radians());
    let pitch = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), order.pitch_deg.to_radians());
    pitch * yaw * roll
}

/// The pivot in camera coordinates, `C = s·R·c + t`.
pub fn pivot_in_camera(pose: &ObjectPose, scale: f64, pivot: &Point3) -> Vector3 {
    pose.rotation * (pivot.coords * scale) + pose.translation
}

/// Applies a camera-frame order to a pose.
pub fn apply_camera_order(
    pose: &ObjectPose,
    scale: f64,
    pivot: &Point3,
    camera: &PinholeCamera,
    order: &CameraOrder,
) -> ObjectPose {
    let c = pivot_in_camera(pose, scale, pivot);
    let depth_z = c.z;
    let dr = camera_rotation(order);
    let dt = Vector3::new(
        order.dpx * camera.width as f64 / camera.fx * depth_z,
        order.dpy * camera.height as f64 / camera.fy * depth_z,
        order.tz * depth_z,
    );
    // t' = t + (I − dR)·(s·R·c) + dT
    let src = pose.rotation * (pivot.coords * scale);
    ObjectPose {
        rotation: dr * pose.rotation,
        translation: pose.translation + src - dr * src + dt,
    }
}

/// The rotation of a rotation vector given in degrees.
pub fn rotation_vector_deg(r: [f64; 3]) -> UnitQuaternion {
    UnitQuaternion::from_scaled_axis(Vector3::new(r[0], r[1], r[2]).map(f64::to_radians))
}

/// Right-multiplies an object-frame rotation about the canonical point `c`.
pub fn apply_object_rotation(
    pose: &ObjectPose,
    scale: f64,
    c: &Point3,
    dr: &UnitQuaternion,
) -> ObjectPose {
    let t = pose.translation + pose.rotation * ((c.coords - dr * c.coords) * scale);
    ObjectPose {
        rotation: pose.rotation * dr,
        translation: t,
    }
}

/// 180° about a canonical axis (`'x'`, `'y'`, `'z'`).
pub fn flip(axis: char) -> Option<UnitQuaternion> {
    let a = match axis {
        'x' | 'X' => Vector3::x_axis(),
        'y' | 'Y' => Vector3::y_axis(),
        'z' | 'Z' => Vector3::z_axis(),
        _ => return None,
    };
    Some(UnitQuaternion::from_axis_angle(&a, std::f64::consts::PI))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cam() -> PinholeCamera {
        PinholeCamera::new(500.0, 400.0, 320.0, 240.0, 640, 480).expect("camera")
    }

    #[test]
    fn screen_directions_match_the_reference() {
        let pose = ObjectPose::new(UnitQuaternion::identity(), Vector3::new(0.0, 0.0, 2.0));
        let c = Point3::origin();
        let s = 1.0;
        let proj = |p: &ObjectPose, q: Vector3| {
            let x = p.rotation * q + p.translation;
            (500.0 * x.x / x.z + 320.0, 400.0 * x.y / x.z + 240.0, x.z)
        };
        // +roll is clockwise on screen: a point to the right moves down.
        let r = apply_camera_order(
            &pose,
            s,
            &c,
            &cam(),
            &CameraOrder {
                roll_deg: 10.0,
                ..Default::default()
            },
        );
        assert!(proj(&r, Vector3::x()).1 > 240.0);
        // +yaw brings the left edge closer; +pitch brings the top edge closer.
        let y = apply_camera_order(
            &pose,
            s,
            &c,
            &cam(),
            &CameraOrder {
                yaw_deg: 10.0,
                ..Default::default()
            },
        );
        assert!(proj(&y, -Vector3::x()).2 < 2.0 && proj(&y, Vector3::x()).2 > 2.0);
        let p = apply_camera_order(
            &pose,
            s,
            &c,
            &cam(),
            &CameraOrder {
                pitch_deg: 10.0,
                ..Default::default()
            },
        );
        assert!(proj(&p, -Vector3::y()).2 < 2.0);
        // dpx is a fraction of the width at the pivot's depth: 0.1·640 px = 64 px right.
        let t = apply_camera_order(
            &pose,
            s,
            &c,
            &cam(),
            &CameraOrder {
                dpx: 0.1,
                dpy: -0.05,
                tz: 0.25,
                ..Default::default()
            },
        );
        assert!(
            (t.translation
                - Vector3::new(
                    0.1 * 640.0 / 500.0 * 2.0,
                    -0.05 * 480.0 / 400.0 * 2.0,
                    0.5 + 2.0
                ))
            .norm()
                < 1e-12
        );
        let (u, v, _) = proj(
            &ObjectPose {
                translation: t.translation - Vector3::new(0.0, 0.0, 0.5),
                ..t
            },
            Vector3::zeros(),
        );
        assert!(
            (u - 384.0).abs() < 1e-9 && (v - 216.0).abs() < 1e-9,
            "{u} {v}"
        );
    }

    #[test]
    fn hand_computed_order_about_an_offset_pivot() {
        // Pivot at canonical (0.1, 0, 0), scale 2, identity rotation, t = (0, 0, 3):
        // C = (0.2, 0, 3). Roll 90° about +Z through C maps a canonical point p = 0 (camera
        // (0, 0, 3)) to C + Rz(90°)·(−0.2, 0, 0) = (0.2, −0.2, 3).
        let pose = ObjectPose::new(UnitQuaternion::identity(), Vector3::new(0.0, 0.0, 3.0));
        let out = apply_camera_order(
            &pose,
            2.0,
            &Point3::new(0.1, 0.0, 0.0),
            &cam(),
            &CameraOrder {
                roll_deg: 90.0,
                ..Default::default()
            },
        );
        let p = out.rotation * Vector3::zeros() * 2.0 + out.translation;
        assert!((p - Vector3::new(0.2, -0.2, 3.0)).norm() < 1e-12, "{p}");
        // The order composes pitch·yaw·roll: roll acts first.
        let o = CameraOrder {
            roll_deg: 30.0,
            yaw_deg: 20.0,
            pitch_deg: 10.0,
            ..Default::default()
        };
        let expect = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 10f64.to_radians())
            * UnitQuaternion::from_axis_angle(&-Vector3::y_axis(), 20f64.to_radians())
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 30f64.to_radians());
        assert!(camera_rotation(&o).angle_to(&expect) < 1e-12);
    }

    #[test]
    fn object_rotation_and_flips_hand_computed() {
        // rz = +90 turns canonical +X toward +Y; about pivot c the pivot stays put.
        let pose = ObjectPose::new(
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.3),
            Vector3::new(0.1, 0.2, 2.0),
        );
        let c = Point3::new(0.0, 0.5, 0.0);
        let dr = rotation_vector_deg([0.0, 0.0, 90.0]);
        assert!((dr * Vector3::x() - Vector3::y()).norm() < 1e-12);
        let out = apply_object_rotation(&pose, 1.5, &c, &dr);
        let before = pose.rotation * (c.coords * 1.5) + pose.translation;
        let after = out.rotation * (c.coords * 1.5) + out.translation;
        assert!((before - after).norm() < 1e-12);
        // Two flips about the same axis are the identity.
        let f = flip('y').expect("axis");
        let twice = apply_object_rotation(&apply_object_rotation(&pose, 1.5, &c, &f), 1.5, &c, &f);
        assert!(
            twice.rotation.angle_to(&pose.rotation) < 1e-12
                && (twice.translation - pose.translation).norm() < 1e-12
        );
        assert!(flip('w').is_none());
    }

    proptest! {
        // The pivot's camera position is invariant under any rotation order, and a zero
        // order is the identity.
        #[test]
        fn rotations_keep_the_pivot(r in -180.0f64..180.0, y in -90.0f64..90.0, p in -90.0f64..90.0, cx in -0.5f64..0.5, cz in -0.5f64..0.5) {
            let pose = ObjectPose::new(UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0), Vector3::new(0.05, -0.1, 1.7));
            let c = Point3::new(cx, 0.2, cz);
            let out = apply_camera_order(&pose, 0.8, &c, &cam(), &CameraOrder { roll_deg: r, yaw_deg: y, pitch_deg: p, ..Default::default() });
            prop_assert!((pivot_in_camera(&out, 0.8, &c) - pivot_in_camera(&pose, 0.8, &c)).norm() < 1e-9);
            let same = apply_camera_order(&pose, 0.8, &c, &cam(), &CameraOrder::default());
            prop_assert!(same.rotation.angle_to(&pose.rotation) < 1e-12 && (same.translation - pose.translation).norm() < 1e-12);
        }
    }
}
