//! Nearest-neighbour queries over a point cloud: what Chamfer distances (`agentstar-eval`) and
//! the check that a turn maps a model's surface onto itself (`agentstar-track`'s symmetry)
//! ask of sampled surfaces.

use crate::Point3;

/// Exact nearest-neighbour queries with a k-d tree: median splits on the widest axis down to
/// leaves of at most 16 points, searched near side first with pruning by the splitting
/// plane. Splits are by position in the sorted order, not by value, so repeated coordinates
/// (every flat face gives many) cost nothing. Query time does not grow with the distance
/// between the two clouds, which a uniform grid's shell search did.
pub struct KdTree {
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
    /// The tree over `points` (copied).
    pub fn new(points: &[Point3]) -> KdTree {
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
        let b = crate::Aabb::from_points(
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

    /// The distance from `q` to the nearest of the points (infinite for none).
    pub fn nearest_distance(&self, q: &Point3) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn the_nearest_distance_is_the_brute_force_minimum(
            cloud in prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0), 1..200),
            query in (-2.0f64..2.0, -2.0f64..2.0, -2.0f64..2.0),
        ) {
            let points: Vec<Point3> = cloud.iter().map(|&(x, y, z)| Point3::new(x, y, z)).collect();
            let q = Point3::new(query.0, query.1, query.2);
            let brute = points.iter().map(|p| (p - q).norm()).fold(f64::INFINITY, f64::min);
            prop_assert!((KdTree::new(&points).nearest_distance(&q) - brute).abs() < 1e-12);
        }
    }

    #[test]
    fn an_empty_cloud_is_infinitely_far() {
        assert_eq!(
            KdTree::new(&[]).nearest_distance(&Point3::origin()),
            f64::INFINITY
        );
    }
}
