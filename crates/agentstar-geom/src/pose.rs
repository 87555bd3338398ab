//! Object poses: a similarity `p_cam = s · R · p_canon + t` with one scale shared by every
//! frame, quaternion conversions (scalar first) and camera-motion seeding.

use crate::{GeomError, Matrix4, Point3, Result, UnitQuaternion, Vector3};
use nalgebra::{Isometry3, Quaternion, Translation3};

/// A rigid transform `p -> R p + t`. Named by what it maps: `camera_from_object` etc.
pub type Rigid = Isometry3<f64>;

/// A similarity `p -> s R p + t` with `s > 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    pub scale: f64,
    pub rotation: UnitQuaternion,
    pub translation: Vector3,
}

/// A generalised pose: the base pose (object → camera) and every joint state, in the
/// kinematic tree's joint order and internal units (radians, model units). The one
/// articulated pose type: the tracker's hypotheses, resolved pose files, the evaluator's
/// predictions and the synthetic ground truth's frames are all `GenPose`s.
#[derive(Debug, Clone, PartialEq)]
pub struct GenPose {
    pub pose: ObjectPose,
    pub states: Vec<f64>,
}

impl GenPose {
    pub fn new(pose: ObjectPose, states: Vec<f64>) -> Self {
        GenPose { pose, states }
    }
}

/// The pose of an object in one frame: rotation and translation (object-to-camera); the
/// scale lives once per run and is combined with [`ObjectPose::with_scale`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectPose {
    pub rotation: UnitQuaternion,
    pub translation: Vector3,
}

impl ObjectPose {
    pub fn identity() -> Self {
        ObjectPose {
            rotation: UnitQuaternion::identity(),
            translation: Vector3::zeros(),
        }
    }
    pub fn new(rotation: UnitQuaternion, translation: Vector3) -> Self {
        ObjectPose {
            rotation,
            translation,
        }
    }
    pub fn with_scale(&self, scale: f64) -> Similarity {
        Similarity {
            scale,
            rotation: self.rotation,
            translation: self.translation,
        }
    }
    pub fn to_rigid(&self) -> Rigid {
        Isometry3::from_parts(Translation3::from(self.translation), self.rotation)
    }
    /// Pose from a quaternion `[w, x, y, z]` (renormalised) and a translation; rejects
    /// non-finite values and a zero quaternion.
    pub fn from_wxyz(quaternion_wxyz: [f64; 4], translation: [f64; 3]) -> Result<Self> {
        Ok(ObjectPose {
            rotation: quat_from_wxyz(quaternion_wxyz)?,
            translation: finite_vector(translation, "translation")?,
        })
    }
    pub fn quaternion_wxyz(&self) -> [f64; 4] {
        quat_to_wxyz(&self.rotation)
    }
}

impl Similarity {
    pub fn identity() -> Self {
        Similarity {
            scale: 1.0,
            rotation: UnitQuaternion::identity(),
            translation: Vector3::zeros(),
        }
    }
    pub fn from_rigid(rigid: &Rigid) -> Self {
        Similarity {
            scale: 1.0,
            rotation: rigid.rotation,
            translation: rigid.translation.vector,
        }
    }
    pub fn transform_point(&self, p: &Point3) -> Point3 {
        Point3::from(self.rotation * (p.coords * self.scale) + self.translation)
    }
    /// `self ∘ other`: apply `other` first.
    pub fn compose(&self, other: &Similarity) -> Similarity {
        Similarity {
            scale: self.scale * other.scale,
            rotation: self.rotation * other.rotation,
            translation: self.rotation * (other.translation * self.scale) + self.translation,
        }
    }
    pub fn inverse(&self) -> Similarity {
        let inv_rot = self.rotation.inverse();
        let inv_scale = 1.0 / self.scale;
        Similarity {
            scale: inv_scale,
            rotation: inv_rot,
            translation: -(inv_rot * self.translation) * inv_scale,
        }
    }
    pub fn to_matrix(&self) -> Matrix4 {
        let mut m = Matrix4::identity();
        let r = self.rotation.to_rotation_matrix().into_inner() * self.scale;
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }
}

/// A unit quaternion from scalar-first `[w, x, y, z]`, renormalised.
pub fn quat_from_wxyz(q: [f64; 4]) -> Result<UnitQuaternion> {
    if q.iter().any(|c| !c.is_finite()) {
        return Err(GeomError::InvalidPose(format!(
            "quaternion {q:?} has a non-finite component"
        )));
    }
    let raw = Quaternion::new(q[0], q[1], q[2], q[3]);
    // The norm of [1e300, 1e300, 0, 0] overflows to infinity; a length that is not a
    // finite number well away from zero is an error rather than a NaN rotation.
    let norm = raw.norm();
    if norm < 1e-9 {
        return Err(GeomError::InvalidPose(format!(
            "quaternion {q:?} has zero length"
        )));
    }
    if !(norm.is_finite() && norm <= 1e9) {
        return Err(GeomError::InvalidPose(format!(
            "quaternion {q:?} has length {norm:e}; expected a unit quaternion (renormalised, but its length must lie in [1e-9, 1e9])"
        )));
    }
    Ok(UnitQuaternion::from_quaternion(raw))
}

pub fn quat_to_wxyz(q: &UnitQuaternion) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

fn finite_vector(v: [f64; 3], what: &str) -> Result<Vector3> {
    if v.iter().any(|c| !c.is_finite()) {
        return Err(GeomError::InvalidPose(format!(
            "{what} {v:?} has a non-finite component"
        )));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

/// A rigid transform from a 4×4 matrix whose upper-left block must be a rotation
/// (orthonormal within `1e-3`, determinant +1).
pub fn rigid_from_matrix(m: &Matrix4) -> Result<Rigid> {
    if m.iter().any(|c| !c.is_finite()) {
        return Err(GeomError::InvalidPose(
            "matrix has a non-finite entry".into(),
        ));
    }
    let r = m.fixed_view::<3, 3>(0, 0).into_owned();
    let err = (r.transpose() * r - crate::Matrix3::identity()).abs().max();
    if err > 1e-3 || r.determinant() < 0.0 {
        return Err(GeomError::InvalidPose(format!(
            "rotation block is not orthonormal with determinant +1 (|RᵀR − I| = {err:.2e}, det = {:.4})",
            r.determinant()
        )));
    }
    let rot = nalgebra::Rotation3::from_matrix(&r);
    let t = m.fixed_view::<3, 1>(0, 3).into_owned();
    Ok(Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&rot),
    ))
}

/// Seeds a frame's object pose from the reference frame's through the cameras:
/// `M_k = inv(c2w_k) · c2w_ref · M_ref` (the object stays still in the world).
pub fn seed_from_reference(
    world_from_camera_k: &Rigid,
    world_from_camera_ref: &Rigid,
    pose_ref: &ObjectPose,
) -> ObjectPose {
    let k_from_ref = world_from_camera_k.inverse() * world_from_camera_ref;
    ObjectPose {
        rotation: k_from_ref.rotation * pose_ref.rotation,
        translation: k_from_ref.rotation * pose_ref.translation + k_from_ref.translation.vector,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sim(s: f64, axis: [f64; 3], angle: f64, t: [f64; 3]) -> Similarity {
        let axis = nalgebra::Unit::new_normalize(Vector3::from(axis));
        Similarity {
            scale: s,
            rotation: UnitQuaternion::from_axis_angle(&axis, angle),
            translation: Vector3::from(t),
        }
    }

    #[test]
    #[allow(clippy::approx_constant)] // the reference's example writes 0.707107 literally
    fn quaternion_is_renormalised_and_scalar_first() {
        let q = quat_from_wxyz([2.0, 0.0, 0.0, 0.0]).expect("valid");
        assert_eq!(quat_to_wxyz(&q), [1.0, 0.0, 0.0, 0.0]);
        // +90° about X maps canonical +Z onto camera −Y (image up).
        let q = quat_from_wxyz([0.707107, 0.707107, 0.0, 0.0]).expect("valid");
        let p = q * Vector3::z();
        assert!((p - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-6);
        assert!(quat_from_wxyz([f64::NAN, 0.0, 0.0, 1.0]).is_err());
        assert!(quat_from_wxyz([0.0; 4]).is_err());
        // Issue 16: the norm overflows to infinity and the rotation came out NaN.
        let e = quat_from_wxyz([1e300, 1e300, 0.0, 0.0]).expect_err("overflowing length");
        assert!(e.to_string().contains("length"), "{e}");
        assert!(quat_from_wxyz([1e-200, 0.0, 0.0, 0.0]).is_err());
    }

    #[test]
    fn seeding_keeps_the_object_still_in_the_world() {
        let c2w_ref = Rigid::identity();
        let c2w_k = Isometry3::from_parts(
            Translation3::new(0.3, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.2),
        );
        let pose_ref = ObjectPose::new(
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.5),
            Vector3::new(0.0, 0.0, 1.0),
        );
        let pose_k = seed_from_reference(&c2w_k, &c2w_ref, &pose_ref);
        let p = Point3::new(0.1, 0.2, 0.3);
        let world_ref = c2w_ref * (pose_ref.to_rigid() * p);
        let world_k = c2w_k * (pose_k.to_rigid() * p);
        assert!((world_ref - world_k).norm() < 1e-12);
    }

    #[test]
    fn matrix_round_trip_rejects_non_rotations() {
        let mut m = Matrix4::identity();
        m[(0, 0)] = 2.0;
        assert!(rigid_from_matrix(&m).is_err());
        let s = sim(1.0, [1.0, 2.0, 3.0], 0.7, [1.0, 2.0, 3.0]);
        let r = rigid_from_matrix(&s.to_matrix()).expect("rotation");
        assert!((r.translation.vector - s.translation).norm() < 1e-12);
        assert!(r.rotation.angle_to(&s.rotation) < 1e-9);
    }

    proptest! {
        #[test]
        fn similarity_inverse_is_identity(s in 0.1f64..5.0, ax in -1.0f64..1.0, ay in -1.0f64..1.0, angle in -3.0f64..3.0,
                                          tx in -2.0f64..2.0, ty in -2.0f64..2.0, tz in -2.0f64..2.0,
                                          px in -1.0f64..1.0, py in -1.0f64..1.0, pz in -1.0f64..1.0) {
            let a = sim(s, [ax, ay, 0.3], angle, [tx, ty, tz]);
            let p = Point3::new(px, py, pz);
            let back = a.inverse().transform_point(&a.transform_point(&p));
            prop_assert!((back - p).norm() < 1e-9);
            let m = a.to_matrix();
            let q = m.transform_point(&p);
            prop_assert!((q - a.transform_point(&p)).norm() < 1e-9);
        }

        #[test]
        fn compose_matches_sequential_application(s1 in 0.1f64..3.0, s2 in 0.1f64..3.0, a1 in -3.0f64..3.0, a2 in -3.0f64..3.0,
                                                   px in -1.0f64..1.0, py in -1.0f64..1.0) {
            let a = sim(s1, [0.2, 1.0, 0.1], a1, [0.1, -0.2, 0.3]);
            let b = sim(s2, [1.0, 0.0, 0.5], a2, [-0.5, 0.4, 0.9]);
            let p = Point3::new(px, py, 0.25);
            let lhs = a.compose(&b).transform_point(&p);
            let rhs = a.transform_point(&b.transform_point(&p));
            prop_assert!((lhs - rhs).norm() < 1e-9);
        }
    }
}
