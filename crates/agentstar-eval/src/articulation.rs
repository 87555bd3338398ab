//! Articulation errors as iTACO defines them: axis angle error `arccos(|â·a|)` (radians;
//! the sign of an axis is not identifiable), the distance between the two axis lines for
//! revolute joints (parallel lines handled explicitly), and the state error, the mean over
//! frames of `| |q| − |q̂| |`.

use agentstar_geom::Vector3;

/// `arccos(|â·a|)` in radians, in [0, π/2].
pub fn axis_angle_error(pred: &Vector3, gt: &Vector3) -> f64 {
    let (Some(p), Some(g)) = (pred.try_normalize(1e-12), gt.try_normalize(1e-12)) else {
        return std::f64::consts::FRAC_PI_2;
    };
    p.dot(&g).abs().min(1.0).acos()
}

/// Distance between the lines `o1 + λ·d1` and `o2 + μ·d2`.
pub fn axis_line_distance(o1: &Vector3, d1: &Vector3, o2: &Vector3, d2: &Vector3) -> f64 {
    let (Some(u), Some(v)) = (d1.try_normalize(1e-12), d2.try_normalize(1e-12)) else {
        return (o1 - o2).norm();
    };
    let n = u.cross(&v);
    let w = o2 - o1;
    if n.norm() < 1e-9 {
        // Parallel (or anti-parallel): the distance from o2 to the first line.
        return (w - u * w.dot(&u)).norm();
    }
    w.dot(&n).abs() / n.norm()
}

/// Mean over frames of `| |q| − |q̂| |`; `None` without frames.
pub fn state_error(pred: &[f64], gt: &[f64]) -> Option<f64> {
    if pred.is_empty() || pred.len() != gt.len() {
        return None;
    }
    Some(
        pred.iter()
            .zip(gt)
            .map(|(p, g)| (p.abs() - g.abs()).abs())
            .sum::<f64>()
            / pred.len() as f64,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_and_lines_hand_computed() {
        let x = Vector3::x();
        assert!(axis_angle_error(&x, &x) < 1e-12);
        assert!(
            axis_angle_error(&-x, &x) < 1e-12,
            "anti-parallel is the same axis"
        );
        assert!(
            (axis_angle_error(&Vector3::new(1.0, 1.0, 0.0), &x) - std::f64::consts::FRAC_PI_4)
                .abs()
                < 1e-12
        );
        // Skew lines: x axis through the origin and y axis through (0, 0, 0.3).
        assert!(
            (axis_line_distance(
                &Vector3::zeros(),
                &x,
                &Vector3::new(5.0, 0.0, 0.3),
                &Vector3::y()
            ) - 0.3)
                .abs()
                < 1e-12
        );
        // Parallel and anti-parallel lines 0.2 apart.
        let o2 = Vector3::new(3.0, 0.2, 0.0);
        assert!((axis_line_distance(&Vector3::zeros(), &x, &o2, &x) - 0.2).abs() < 1e-12);
        assert!((axis_line_distance(&Vector3::zeros(), &x, &o2, &-x) - 0.2).abs() < 1e-12);
        // Intersecting lines are 0 apart.
        assert!(
            axis_line_distance(
                &Vector3::zeros(),
                &x,
                &Vector3::new(1.0, -1.0, 0.0),
                &Vector3::y()
            ) < 1e-12
        );
        assert!((state_error(&[0.5, -0.2], &[0.4, 0.2]).expect("error") - 0.05).abs() < 1e-12);
        assert_eq!(state_error(&[], &[]), None);
    }
}
