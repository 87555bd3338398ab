//! Chamfer distance: the symmetric mean nearest-neighbour distance between point samples of
//! two surfaces, `(mean_a d(a, B) + mean_b d(b, A)) / 2`. Samples are area-weighted and
//! seeded, so a metric is reproducible.

use agentstar_geom::nearest::KdTree;
use agentstar_geom::{Point3, TriMesh};
use agentstar_optim::Rng;

/// `n` points uniformly distributed over the surface (area-weighted triangles, uniform
/// barycentric coordinates).
pub fn sample_surface(mesh: &TriMesh, n: usize, seed: u64) -> Vec<Point3> {
    let areas: Vec<f64> = (0..mesh.triangles.len())
        .map(|i| {
            let [a, b, c] = mesh.triangle(i);
            (b - a).cross(&(c - a)).norm() * 0.5
        })
        .collect();
    let total: f64 = areas.iter().sum();
    if total <= 0.0 || n == 0 {
        return vec![];
    }
    let mut cdf = Vec::with_capacity(areas.len());
    let mut acc = 0.0;
    for a in &areas {
        acc += a / total;
        cdf.push(acc);
    }
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let u = rng.uniform();
            let t = cdf.partition_point(|&c| c < u).min(cdf.len() - 1);
            let [a, b, c] = mesh.triangle(t);
            let (mut r1, mut r2) = (rng.uniform(), rng.uniform());
            if r1 + r2 > 1.0 {
                r1 = 1.0 - r1;
                r2 = 1.0 - r2;
            }
            a + (b - a) * r1 + (c - a) * r2
        })
        .collect()
}

fn mean_nn(from: &[Point3], to: &KdTree, f: impl Fn(f64) -> f64) -> f64 {
    from.iter().map(|p| f(to.nearest_distance(p))).sum::<f64>() / from.len() as f64
}

/// Symmetric Chamfer distance; `None` when either set is empty.
pub fn chamfer_distance(a: &[Point3], b: &[Point3]) -> Option<f64> {
    if a.is_empty() || b.is_empty() {
        return None;
    }
    let (ta, tb) = (KdTree::new(a), KdTree::new(b));
    Some(0.5 * (mean_nn(a, &tb, |d| d) + mean_nn(b, &ta, |d| d)))
}

/// Both kinds of Chamfer distance from one nearest-neighbour pass: the symmetric mean
/// distance (as [`chamfer_distance`]) and the squared form of the iTACO table,
/// `mean_a d(a, B)² + mean_b d(b, A)²` (units squared, the two directions summed).
pub fn chamfer_both(a: &[Point3], b: &[Point3]) -> Option<(f64, f64)> {
    if a.is_empty() || b.is_empty() {
        return None;
    }
    let (ta, tb) = (KdTree::new(a), KdTree::new(b));
    let da: Vec<f64> = a.iter().map(|p| tb.nearest_distance(p)).collect();
    let db: Vec<f64> = b.iter().map(|p| ta.nearest_distance(p)).collect();
    let mean = |v: &[f64], f: fn(f64) -> f64| v.iter().map(|&d| f(d)).sum::<f64>() / v.len() as f64;
    Some((
        0.5 * (mean(&da, |d| d) + mean(&db, |d| d)),
        mean(&da, |d| d * d) + mean(&db, |d| d * d),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::primitives::{cuboid, uv_sphere};
    use agentstar_geom::Vector3;

    #[test]
    fn identical_samples_score_zero_and_shifts_score_their_offset() {
        let m = uv_sphere(0.5, 32, 16).expect("sphere");
        let a = sample_surface(&m, 4000, 1);
        assert_eq!(chamfer_distance(&a, &a), Some(0.0));
        // Two point sets offset along a plane's normal are that far apart, both ways.
        let plane: Vec<Point3> = (0..50)
            .flat_map(|i| (0..50).map(move |j| Point3::new(i as f64 * 0.02, j as f64 * 0.02, 0.0)))
            .collect();
        let lifted: Vec<Point3> = plane
            .iter()
            .map(|p| p + Vector3::new(0.0, 0.0, 0.03))
            .collect();
        assert!((chamfer_distance(&plane, &lifted).expect("cd") - 0.03).abs() < 1e-12);
        // Samples lie on the surface and are spread over it.
        let cube = cuboid(1.0, 1.0, 1.0).expect("cube");
        let s = sample_surface(&cube, 6000, 7);
        assert!(s
            .iter()
            .all(|p| (0..3).any(|k| (p[k].abs() - 0.5).abs() < 1e-12)));
        let top = s.iter().filter(|p| (p.z - 0.5).abs() < 1e-12).count();
        assert!((800..1200).contains(&top), "{top}");
        assert_eq!(sample_surface(&cube, 10, 3), sample_surface(&cube, 10, 3));
    }

    #[test]
    fn matches_brute_force() {
        let a = sample_surface(&uv_sphere(0.4, 16, 8).expect("s"), 300, 2);
        let b = sample_surface(&cuboid(0.7, 0.5, 0.6).expect("c"), 280, 3);
        let brute = |x: &[Point3], y: &[Point3]| {
            x.iter()
                .map(|p| {
                    y.iter()
                        .map(|q| (p - q).norm())
                        .fold(f64::INFINITY, f64::min)
                })
                .sum::<f64>()
                / x.len() as f64
        };
        let want = 0.5 * (brute(&a, &b) + brute(&b, &a));
        assert!((chamfer_distance(&a, &b).expect("cd") - want).abs() < 1e-12);
        let brute_sq = |x: &[Point3], y: &[Point3]| {
            x.iter()
                .map(|p| {
                    y.iter()
                        .map(|q| (p - q).norm_squared())
                        .fold(f64::INFINITY, f64::min)
                })
                .sum::<f64>()
                / x.len() as f64
        };
        // Far apart and flat: the search is exact whatever the distance between the clouds.
        let flat = sample_surface(&cuboid(0.9, 0.6, 0.002).expect("flat"), 500, 4);
        let far: Vec<Point3> = a.iter().map(|p| p + Vector3::new(1.5, -0.7, 0.9)).collect();
        let want_far = 0.5 * (brute(&flat, &far) + brute(&far, &flat));
        assert!((chamfer_distance(&flat, &far).expect("cd") - want_far).abs() < 1e-12);
        let (cd, cd_sq) = chamfer_both(&a, &b).expect("both");
        assert!((cd - want).abs() < 1e-12);
        assert!((cd_sq - (brute_sq(&a, &b) + brute_sq(&b, &a))).abs() < 1e-12);
    }
}
