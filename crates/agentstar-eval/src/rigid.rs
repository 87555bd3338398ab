//! Rigid pose errors after one gauge per trajectory (HOT3D protocol, paper appendix):
//! the prediction's canonical frame is arbitrary, so a rotation `G*` (SO(3) Procrustes over
//! all frames) and an origin offset `c*` (least squares) map it onto the ground truth's
//! object frame, with the monocular scale `ŝ` from depth alignment; then per-frame
//! geodesic rotation error (degrees) and translation error (cm). No per-frame symmetry
//! quotienting.
//!
//! Conventions: ground truth `p_cam = R_gt·p + t_gt` (metres); prediction
//! `p_cam = ŝ·(s·R·p + t)` after scale alignment. The gauge predicts the ground-truth pose
//! as `R_gt ≈ R·G`, `t_gt ≈ ŝ·(s·R·c + t)`.

use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{Matrix3, UnitQuaternion, Vector3};

#[derive(Debug, Clone, PartialEq)]
pub struct GaugeErrors {
    pub gauge_rotation: UnitQuaternion,
    /// The ground-truth origin in the prediction's canonical frame.
    pub gauge_offset: Vector3,
    pub rotation_deg: Vec<f64>,
    pub translation_cm: Vec<f64>,
    pub rotation_mean_deg: f64,
    pub rotation_median_deg: f64,
    pub translation_mean_cm: f64,
    pub translation_median_cm: f64,
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Nearest rotation to `m` (SVD, determinant fixed to +1).
pub fn project_to_so3(m: &Matrix3) -> Matrix3 {
    let svd = m.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let d = (u * vt).determinant().signum();
    u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt
}

/// Gauge-aligned errors of one trajectory. `pred_scale` is the prediction's shared object
/// scale `s`; `depth_scale` is `ŝ`. Frames pair up by index; `None` for an empty trajectory.
pub fn gauge_aligned_errors(
    gt: &[ObjectPose],
    pred: &[ObjectPose],
    pred_scale: f64,
    depth_scale: f64,
) -> Option<GaugeErrors> {
    if gt.is_empty() || gt.len() != pred.len() {
        return None;
    }
    let mut m = Matrix3::zeros();
    for (g, p) in gt.iter().zip(pred) {
        m += p.rotation.to_rotation_matrix().into_inner().transpose()
            * g.rotation.to_rotation_matrix().into_inner();
    }
    let gmat = project_to_so3(&m);
    let gauge_rotation = UnitQuaternion::from_rotation_matrix(
        &agentstar_geom::nalgebra::Rotation3::from_matrix_unchecked(gmat),
    );
    // c* = argmin Σ |t_gt − ŝ t − ŝ s R c|²  =  mean(Rᵀ (t_gt − ŝ t)) / (ŝ s).
    let k = depth_scale * pred_scale;
    let mut acc = Vector3::zeros();
    for (g, p) in gt.iter().zip(pred) {
        acc += p.rotation.inverse() * (g.translation - p.translation * depth_scale);
    }
    let gauge_offset = acc / (gt.len() as f64 * k);
    let mut rotation_deg = Vec::with_capacity(gt.len());
    let mut translation_cm = Vec::with_capacity(gt.len());
    for (g, p) in gt.iter().zip(pred) {
        rotation_deg.push(
            g.rotation
                .angle_to(&(p.rotation * gauge_rotation))
                .to_degrees(),
        );
        let predicted = (p.rotation * gauge_offset) * k + p.translation * depth_scale;
        translation_cm.push((g.translation - predicted).norm() * 100.0);
    }
    let n = gt.len() as f64;
    Some(GaugeErrors {
        gauge_rotation,
        gauge_offset,
        rotation_mean_deg: rotation_deg.iter().sum::<f64>() / n,
        rotation_median_deg: median(&rotation_deg),
        translation_mean_cm: translation_cm.iter().sum::<f64>() / n,
        translation_median_cm: median(&translation_cm),
        rotation_deg,
        translation_cm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn trajectory() -> Vec<ObjectPose> {
        (0..8)
            .map(|k| {
                let t = k as f64;
                ObjectPose::new(
                    UnitQuaternion::from_euler_angles(
                        0.3 * t,
                        -0.2 + 0.1 * t,
                        0.5 * (0.7 * t).sin(),
                    ),
                    Vector3::new(0.05 * t.sin(), -0.02 * t, 0.6 + 0.03 * t),
                )
            })
            .collect()
    }

    #[test]
    fn perfect_prediction_scores_zero() {
        let gt = trajectory();
        let e = gauge_aligned_errors(&gt, &gt, 1.0, 1.0).expect("errors");
        assert!(
            e.rotation_mean_deg < 1e-6 && e.translation_mean_cm < 1e-9,
            "{e:?}"
        );
    }

    #[test]
    fn a_per_frame_offset_gives_exactly_the_expected_numbers() {
        // Every predicted frame 3° off about the object's x axis, alternating in sign, so the
        // Procrustes gauge is the identity and every frame keeps exactly 3°.
        let gt = trajectory();
        let pred: Vec<ObjectPose> = gt
            .iter()
            .enumerate()
            .map(|(k, g)| {
                let r = if k % 2 == 0 { 3f64 } else { -3.0 };
                ObjectPose::new(
                    g.rotation
                        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), r.to_radians()),
                    g.translation,
                )
            })
            .collect();
        let e = gauge_aligned_errors(&gt, &pred, 1.0, 1.0).expect("errors");
        for r in &e.rotation_deg {
            assert!((r - 3.0).abs() < 1e-9, "{r}");
        }
        // A pure translation offset of 2 cm on one frame of eight: the mean offset 0.25 cm is
        // absorbed by the gauge, leaving 1.75 cm on that frame.
        let mut pred2 = gt.clone();
        pred2[0].translation += gt[0].rotation * Vector3::new(0.02, 0.0, 0.0);
        let e = gauge_aligned_errors(&gt, &pred2, 1.0, 1.0).expect("errors");
        assert!(
            (e.translation_cm[0] - 1.75).abs() < 1e-9,
            "{:?}",
            e.translation_cm
        );
        assert!((e.translation_cm[1] - 0.25).abs() < 1e-9);
    }

    #[test]
    fn a_symmetry_flip_is_not_quotiented_per_frame() {
        // A can is symmetric about its axis, but a prediction that turns half way about it in
        // one frame changes every point's trajectory: that frame scores 180°, the others 0.
        let gt = trajectory();
        let mut pred = gt.clone();
        pred[3].rotation *=
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
        let e = gauge_aligned_errors(&gt, &pred, 1.0, 1.0).expect("errors");
        assert!(
            (e.rotation_deg[3] - 180.0).abs() < 1e-6,
            "{:?}",
            e.rotation_deg
        );
        for (k, r) in e.rotation_deg.iter().enumerate() {
            if k != 3 {
                assert!(*r < 1e-6, "frame {k}: {r}");
            }
        }
        assert!(e.translation_cm.iter().all(|t| *t < 1e-9));
    }

    proptest! {
        // Any similarity of the prediction's canonical frame (and any monocular scale) leaves
        // the gauge-aligned errors unchanged.
        #[test]
        fn invariant_to_the_prediction_gauge(ax in -1.0f64..1.0, ay in -1.0f64..1.0, angle in -3.0f64..3.0, sigma in 0.2f64..5.0,
                                             dx in -0.5f64..0.5, dy in -0.5f64..0.5, depth in 0.3f64..3.0) {
            let gt = trajectory();
            // A noisy prediction in the ground truth's own frame.
            let base: Vec<ObjectPose> = gt.iter().enumerate().map(|(k, g)| ObjectPose::new(
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.02 * k as f64) * g.rotation,
                g.translation + Vector3::new(0.003 * k as f64, 0.0, -0.002),
            )).collect();
            let reference = gauge_aligned_errors(&gt, &base, 1.0, 1.0).expect("errors");
            // Re-express it in another canonical frame p' = σ Q p + d, at another depth scale:
            // s' = 1/σ, R' = R Qᵀ, t' = (t − R Qᵀ d / σ) / depth.
            let q = UnitQuaternion::from_axis_angle(&agentstar_geom::nalgebra::Unit::new_normalize(Vector3::new(ax, ay, 0.4)), angle);
            let d = Vector3::new(dx, dy, 0.1);
            let moved: Vec<ObjectPose> = base.iter().map(|p| {
                let r = p.rotation * q.inverse();
                ObjectPose::new(r, (p.translation - r * d / sigma) / depth)
            }).collect();
            let e = gauge_aligned_errors(&gt, &moved, 1.0 / sigma, depth).expect("errors");
            for (a, b) in reference.rotation_deg.iter().zip(&e.rotation_deg) {
                prop_assert!((a - b).abs() < 1e-6);
            }
            for (a, b) in reference.translation_cm.iter().zip(&e.translation_cm) {
                prop_assert!((a - b).abs() < 1e-6);
            }
        }
    }
}
