//! The gauge of cameras from structure from motion, and their errors against true cameras.
//!
//! SfM recovers cameras up to a similarity (rotation, translation and scale of the world).
//! We fix it as follows: the world frame is the first keyframe's camera frame (OpenCV axes:
//! +X right, +Y down, +Z forward), and the unit of length is either the metre (when the user
//! gives the distance to the background in the first keyframe) or the median depth of the
//! background points that the first keyframe sees. Rotations between cameras are exact
//! whatever the gauge; translations are right up to that one scale factor.

use agentstar_geom::nalgebra::{Matrix3, Translation3, UnitQuaternion};
use agentstar_geom::pose::Rigid;
use agentstar_geom::{PinholeCamera, Point3, Vector3};

/// A similarity `x ↦ scale · rotation · x + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sim3 {
    pub scale: f64,
    pub rotation: UnitQuaternion<f64>,
    pub translation: Vector3,
}

impl Sim3 {
    pub fn apply(&self, p: &Point3) -> Point3 {
        Point3::from(self.scale * (self.rotation * p.coords) + self.translation)
    }
    /// `world_from_camera` in the new world: the camera's rotation turns, its centre moves.
    pub fn apply_camera(&self, world_from_camera: &Rigid) -> Rigid {
        let centre = self.apply(&Point3::from(world_from_camera.translation.vector));
        Rigid::from_parts(
            Translation3::from(centre.coords),
            self.rotation * world_from_camera.rotation,
        )
    }
}

/// The similarity that maps the SfM world onto the first keyframe's camera frame, scaled so
/// that `reference_depth` (the median background depth in SfM units) becomes `target_depth`.
pub fn to_first_camera(
    first_world_from_camera: &Rigid,
    reference_depth: f64,
    target_depth: f64,
) -> Sim3 {
    let camera_from_world = first_world_from_camera.inverse();
    let scale = target_depth / reference_depth;
    Sim3 {
        scale,
        rotation: camera_from_world.rotation,
        translation: scale * camera_from_world.translation.vector,
    }
}

/// The median depth of the points in front of a camera that project inside its image.
pub fn median_depth(
    camera: &PinholeCamera,
    world_from_camera: &Rigid,
    points: &[[f64; 3]],
) -> Option<f64> {
    let camera_from_world = world_from_camera.inverse();
    let mut depths: Vec<f64> = points
        .iter()
        .filter_map(|p| {
            let q = camera_from_world * Point3::new(p[0], p[1], p[2]);
            let (u, v) = camera.project(&q)?;
            (u >= 0.0 && v >= 0.0 && u < camera.width as f64 && v < camera.height as f64)
                .then_some(q.z)
        })
        .collect();
    if depths.is_empty() {
        return None;
    }
    depths.sort_by(f64::total_cmp);
    Some(depths[depths.len() / 2])
}

/// Errors of estimated cameras against true ones after the best similarity alignment.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraErrors {
    pub rotation_deg_max: f64,
    pub rotation_deg_median: f64,
    /// Camera-centre errors over the length of the true trajectory (sum of steps).
    pub translation_max_fraction: f64,
    pub translation_median_fraction: f64,
    pub trajectory_length: f64,
    /// Estimated world → true world.
    pub alignment: Sim3,
}

/// Aligns `estimated` to `truth` (both `world_from_camera`, the same frames in order) by a
/// similarity — the rotation that best maps the estimated orientations onto the true ones
/// (chordal mean), then the scale and translation that best map the centres given it — and
/// measures what is left. `None` with fewer than two frames or a trajectory of zero length.
pub fn camera_errors(estimated: &[Rigid], truth: &[Rigid]) -> Option<CameraErrors> {
    if estimated.len() != truth.len() || estimated.len() < 2 {
        return None;
    }
    let mut m = Matrix3::zeros();
    for (e, t) in estimated.iter().zip(truth) {
        m += t.rotation.to_rotation_matrix().matrix()
            * e.rotation.to_rotation_matrix().matrix().transpose();
    }
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    let rotation = UnitQuaternion::from_matrix(&r);
    let n = estimated.len() as f64;
    let ce: Vec<Vector3> = estimated.iter().map(|e| e.translation.vector).collect();
    let ct: Vec<Vector3> = truth.iter().map(|t| t.translation.vector).collect();
    let me = ce.iter().sum::<Vector3>() / n;
    let mt = ct.iter().sum::<Vector3>() / n;
    let (mut num, mut den) = (0.0, 0.0);
    for (e, t) in ce.iter().zip(&ct) {
        let x = rotation * (e - me);
        num += x.dot(&(t - mt));
        den += x.norm_squared();
    }
    if den <= 0.0 {
        return None;
    }
    let scale = num / den;
    let alignment = Sim3 {
        scale,
        rotation,
        translation: mt - scale * (rotation * me),
    };
    let length: f64 = ct.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    if length <= 0.0 {
        return None;
    }
    let mut rot: Vec<f64> = estimated
        .iter()
        .zip(truth)
        .map(|(e, t)| {
            (t.rotation.inverse() * rotation * e.rotation)
                .angle()
                .to_degrees()
        })
        .collect();
    let mut trans: Vec<f64> = ce
        .iter()
        .zip(&ct)
        .map(|(e, t)| (alignment.apply(&Point3::from(*e)).coords - t).norm() / length)
        .collect();
    rot.sort_by(f64::total_cmp);
    trans.sort_by(f64::total_cmp);
    Some(CameraErrors {
        rotation_deg_max: rot[rot.len() - 1],
        rotation_deg_median: rot[rot.len() / 2],
        translation_max_fraction: trans[trans.len() - 1],
        translation_median_fraction: trans[trans.len() / 2],
        trajectory_length: length,
        alignment,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::nalgebra::Unit;

    fn cam(angle: f64, t: [f64; 3]) -> Rigid {
        Rigid::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            UnitQuaternion::from_axis_angle(
                &Unit::new_normalize(Vector3::new(0.2, 1.0, 0.1)),
                angle,
            ),
        )
    }

    #[test]
    fn a_similar_trajectory_has_no_error_and_its_alignment_is_found() {
        let truth: Vec<Rigid> = (0..6)
            .map(|k| cam(0.1 * k as f64, [0.3 * k as f64, 0.05 * (k * k) as f64, 0.1]))
            .collect();
        let g = Sim3 {
            scale: 0.37,
            rotation: UnitQuaternion::from_euler_angles(0.3, -0.5, 1.1),
            translation: Vector3::new(1.0, -2.0, 0.5),
        };
        let estimated: Vec<Rigid> = truth.iter().map(|c| g.apply_camera(c)).collect();
        let e = camera_errors(&estimated, &truth).expect("errors");
        assert!(e.rotation_deg_max < 1e-6, "{e:?}");
        assert!(e.translation_max_fraction < 1e-9, "{e:?}");
        assert!((e.alignment.scale - 1.0 / 0.37).abs() < 1e-9);
        // One camera off by 2° shows as about 2° (the mean rotation moves a little).
        let mut bent = estimated.clone();
        bent[3] = Rigid::from_parts(
            bent[3].translation,
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 2f64.to_radians())
                * bent[3].rotation,
        );
        let e = camera_errors(&bent, &truth).expect("errors");
        assert!((1.5..2.0).contains(&e.rotation_deg_max), "{e:?}");
    }

    #[test]
    fn the_first_camera_becomes_the_world_at_the_chosen_depth() {
        let first = cam(0.4, [1.0, 2.0, 3.0]);
        let other = cam(0.7, [1.5, 2.0, 2.0]);
        let g = to_first_camera(&first, 4.0, 1.0);
        let a = g.apply_camera(&first);
        assert!(a.translation.vector.norm() < 1e-12 && a.rotation.angle() < 1e-12);
        let b = g.apply_camera(&other);
        let d_before = (other.translation.vector - first.translation.vector).norm();
        assert!((b.translation.vector.norm() - d_before / 4.0).abs() < 1e-12);
        let rel = first.inverse() * other;
        assert!((b.rotation.angle_to(&rel.rotation)) < 1e-12);
        let k = PinholeCamera::new(100.0, 100.0, 50.0, 50.0, 100, 100).expect("camera");
        let pts: Vec<[f64; 3]> = [2.0, 3.0, 9.0, -1.0]
            .iter()
            .map(|z| {
                let p = first * Point3::new(0.0, 0.0, *z);
                [p.x, p.y, p.z]
            })
            .collect();
        let d = median_depth(&k, &first, &pts).expect("points in view");
        assert!((d - 3.0).abs() < 1e-9, "{d}");
    }
}
