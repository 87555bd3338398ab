//! Chamfer distance: the symmetric mean nearest-neighbour distance between point samples of
//! two surfaces, `(mean_a d(a, B) + mean_b d(b, A)) / 2`. Samples are area-weighted and
//! seeded, so a metric is reproducible.

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

/// Exact nearest-neighbour queries with a k-d tree: median splits on the widest axis down to
/// leaves of at most 16 points, searched near side first with pruning by the splitting
/// plane. Splits are by position in the sorted order, not by value, so repeated coordinates
/// (every flat face gives many) cost nothing. Query time does not grow with the distance
/// between the two clouds, which a uniform grid's shell search did.
struct KdTree {
    points: Vec<Point3>,
    order: Vec<u32>,
    nodes: Vec<Node>,
}

#[derive(Debug, Clone, Copy)]
enum Node {
    Leaf {
        start: u32,
        end: u32,
    },
    Split {
        axis: u8,
        value: f64,
        left: u32,
        right: u32,
    },
}

const LEAF: usize = 16;

impl KdTree {
    fn new(points: &[Point3]) -> KdTree {
        let mut g = KdTree {
            points: points.to_vec(),
            order: (0..points.len() as u32).collect(),
            nodes: Vec::with_capacity(2 * points.len() / LEAF + 1),
        };
        if !points.is_empty() {
            g.build(0, points.len());
        }
        g
    }

    /// Builds the subtree over `order[start..end]`; returns its node index.
    fn build(&mut self, start: usize, end: usize) -> u32 {
        let id = self.nodes.len() as u32;
        if end - start <= LEAF {
            self.nodes.push(Node::Leaf {
                start: start as u32,
                end: end as u32,
            });
            return id;
        }
        let b = agentstar_geom::Aabb::from_points(
            self.order[start..end]
                .iter()
                .map(|&i| &self.points[i as usize]),
        );
        let e = b.extent();
        let axis = if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        };
        let mid = (start + end) / 2;
        let points = &self.points;
        self.order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            points[a as usize][axis].total_cmp(&points[b as usize][axis])
        });
        let value = self.points[self.order[mid] as usize][axis];
        self.nodes.push(Node::Leaf { start: 0, end: 0 });
        let left = self.build(start, mid);
        let right = self.build(mid, end);
        self.nodes[id as usize] = Node::Split {
            axis: axis as u8,
            value,
            left,
            right,
        };
        id
    }

    fn nearest(&self, q: &Point3) -> f64 {
        let mut best_sq = f64::INFINITY;
        if self.nodes.is_empty() {
            return best_sq;
        }
        // (node, squared lower bound of its distance)
        let mut stack: Vec<(u32, f64)> = vec![(0, 0.0)];
        while let Some((n, bound)) = stack.pop() {
            if bound >= best_sq {
                continue;
            }
            match self.nodes[n as usize] {
                Node::Leaf { start, end } => {
                    for &i in &self.order[start as usize..end as usize] {
                        best_sq = best_sq.min((self.points[i as usize] - q).norm_squared());
                    }
                }
                Node::Split {
                    axis,
                    value,
                    left,
                    right,
                } => {
                    let d = q[axis as usize] - value;
                    let (near, far) = if d < 0.0 {
                        (left, right)
                    } else {
                        (right, left)
                    };
                    // Far first on the stack, so the near side is searched first.
                    stack.push((far, bound.max(d * d)));
                    stack.push((near, bound));
                }
            }
        }
        best_sq.sqrt()
    }
}

fn mean_nn(from: &[Point3], to: &KdTree, f: impl Fn(f64) -> f64) -> f64 {
    from.iter().map(|p| f(to.nearest(p))).sum::<f64>() / from.len() as f64
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
    let da: Vec<f64> = a.iter().map(|p| tb.nearest(p)).collect();
    let db: Vec<f64> = b.iter().map(|p| ta.nearest(p)).collect();
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
