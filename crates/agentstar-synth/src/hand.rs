//! A rendered hand occluder: a palm and five capsule fingers in metres, placed so that it
//! grips the object from the camera's side.

use agentstar_geom::pose::Similarity;
use agentstar_geom::primitives::{bevelled_box, capsule};
use agentstar_geom::{Matrix3, Point3, TriMesh, UnitQuaternion, Vector3};

/// Skin colour (linear RGB).
pub const SKIN: [f32; 3] = [0.86, 0.64, 0.52];

/// The palm's breadth across the knuckles (along X) of [`hand_mesh`], metres: an adult
/// man's, before a capture's hand scale ([`hand_scale_for`]).
pub const PALM_BREADTH_M: f64 = 0.085;

/// The scale a capture draws its hands at for an object `size_m` across: full size for
/// objects of 0.3 m and more, down to half for small ones (so that a hand does not hide a
/// can whole). `agentstar scale --from hand` recovers the scale of captures at full size.
pub fn hand_scale_for(size_m: f64) -> f64 {
    (size_m / 0.3).clamp(0.5, 1.0)
}

/// The hand mesh in its own frame (metres): palm in the XY plane centred at the origin,
/// fingers along +Y, the back of the hand toward −Z.
pub fn hand_mesh() -> TriMesh {
    let mut m = bevelled_box(PALM_BREADTH_M, 0.09, 0.028, 0.008, 2).unwrap_or_default();
    let along_y = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), -std::f64::consts::FRAC_PI_2)
        .to_rotation_matrix()
        .into_inner();
    for (i, (x, len)) in [(-0.03, 0.055), (-0.01, 0.065), (0.01, 0.062), (0.03, 0.05)]
        .iter()
        .enumerate()
    {
        if let Ok(f) = capsule(0.0085, *len, 10) {
            // Fingers curl slightly toward +Z (around the object).
            let curl = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.35 + 0.05 * i as f64)
                .to_rotation_matrix()
                .into_inner();
            let offset = Vector3::new(*x, 0.045 + 0.5 * len, 0.006);
            m.append(&f.transformed(&(curl * along_y), &offset));
        }
    }
    if let Ok(thumb) = capsule(0.01, 0.05, 10) {
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.9)
            .to_rotation_matrix()
            .into_inner();
        m.append(&thumb.transformed(&(turn * along_y), &Vector3::new(-0.055, 0.01, 0.008)));
    }
    m
}

/// The hand's pose (hand frame → camera) gripping an object whose centre is `centre` (camera
/// frame) and radius `radius` (metres) from the image direction `phi`, in front of it.
pub fn grip_pose(centre: &Point3, radius: f64, phi: f64, hand_scale: f64) -> Similarity {
    reach_pose(centre, radius, phi, hand_scale, 1.05)
}

/// [`grip_pose`] with the palm `reach · radius` from the centre across the image (1.05: at
/// the rim; smaller values reach across the object and hide more of it).
pub fn reach_pose(
    centre: &Point3,
    radius: f64,
    phi: f64,
    hand_scale: f64,
    reach: f64,
) -> Similarity {
    let lateral = Vector3::new(phi.cos(), phi.sin(), 0.0);
    let position = centre.coords + lateral * (reach * radius) - Vector3::z() * (0.55 * radius);
    // Fingers point back toward the object's centre; the back of the hand faces the camera.
    let fingers = (-lateral + Vector3::new(0.0, 0.0, 0.35)).normalize();
    let back = -Vector3::z();
    let z_axis = (-(back - fingers * back.dot(&fingers))).normalize();
    let x_axis = fingers.cross(&z_axis).normalize();
    let r = Matrix3::from_columns(&[x_axis, fingers, z_axis]);
    let rotation = UnitQuaternion::from_rotation_matrix(
        &agentstar_geom::nalgebra::Rotation3::from_matrix_unchecked(r),
    );
    Similarity {
        scale: hand_scale,
        rotation,
        translation: position,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hand_is_closed_and_hand_sized() {
        let m = hand_mesh();
        let e = m.bounds().extent();
        assert!(e.y > 0.15 && e.y < 0.22, "{e:?}");
        assert!(e.x > 0.08 && e.x < 0.16, "{e:?}");
        assert!(agentstar_geom::Part::new("hand", m, SKIN).watertight);
    }

    #[test]
    fn the_grip_is_a_proper_rotation_in_front_of_the_object() {
        let c = Point3::new(0.0, 0.0, 0.6);
        for k in 0..8 {
            let p = grip_pose(&c, 0.1, k as f64, 1.0);
            let det = p.rotation.to_rotation_matrix().matrix().determinant();
            assert!((det - 1.0).abs() < 1e-9);
            assert!(p.translation.z < c.z, "the hand is nearer the camera");
        }
    }
}
