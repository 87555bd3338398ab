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

/// Exact nearest-neighbour queries over a uniform grid (cells sized for surface samples,
/// about two points a cell), searching shells of cells outward, clipped to the grid, until
/// no closer point can exist. Cells are stored densely (start offsets into one index
/// array). Kd-tree crates were tried; the one we looked at panics when many samples share a
/// coordinate, which every flat face produces.
struct Grid {
    origin: Point3,
    cell: f64,
    dims: [i64; 3],
    /// `starts[c]..starts[c + 1]` indexes `order` for cell `c`.
    starts: Vec<u32>,
    order: Vec<u32>,
    points: Vec<Point3>,
}

/// The most cells a grid may have.
const MAX_CELLS: f64 = 4.0e6;

impl Grid {
    fn new(points: &[Point3]) -> Grid {
        let b = agentstar_geom::Aabb::from_points(points.iter());
        let ext = b.extent();
        let n = points.len().max(1) as f64;
        // Samples lie on surfaces: size cells by the bounding box's surface area.
        let area = 2.0 * (ext.x * ext.y + ext.y * ext.z + ext.z * ext.x);
        let mut cell = (2.0 * area / n).sqrt().max(ext.max() / 512.0).max(1e-9);
        let dims_for = |cell: f64| {
            [
                (ext.x / cell) as i64 + 1,
                (ext.y / cell) as i64 + 1,
                (ext.z / cell) as i64 + 1,
            ]
        };
        let mut dims = dims_for(cell);
        while (dims[0] * dims[1] * dims[2]) as f64 > MAX_CELLS {
            cell *= 1.5;
            dims = dims_for(cell);
        }
        let mut g = Grid {
            origin: b.min,
            cell,
            dims,
            starts: vec![],
            order: vec![],
            points: points.to_vec(),
        };
        let ncells = (dims[0] * dims[1] * dims[2]) as usize;
        let keys: Vec<usize> = points.iter().map(|p| g.index(g.key(p))).collect();
        let mut counts = vec![0u32; ncells + 1];
        for &k in &keys {
            counts[k + 1] += 1;
        }
        for i in 0..ncells {
            counts[i + 1] += counts[i];
        }
        let mut fill = counts.clone();
        let mut order = vec![0u32; points.len()];
        for (i, &k) in keys.iter().enumerate() {
            order[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        g.starts = counts;
        g.order = order;
        g
    }
    fn key(&self, p: &Point3) -> [i64; 3] {
        let f = |v: f64, o: f64, d: i64| (((v - o) / self.cell).floor() as i64).clamp(0, d - 1);
        [
            f(p.x, self.origin.x, self.dims[0]),
            f(p.y, self.origin.y, self.dims[1]),
            f(p.z, self.origin.z, self.dims[2]),
        ]
    }
    fn index(&self, k: [i64; 3]) -> usize {
        ((k[2] * self.dims[1] + k[1]) * self.dims[0] + k[0]) as usize
    }
    fn visit(&self, k: [i64; 3], q: &Point3, best: &mut f64) {
        let c = self.index(k);
        for &i in &self.order[self.starts[c] as usize..self.starts[c + 1] as usize] {
            *best = best.min((self.points[i as usize] - q).norm());
        }
    }
    fn nearest(&self, q: &Point3) -> f64 {
        if self.points.is_empty() {
            return f64::INFINITY;
        }
        let c = self.key(q);
        // Per axis, how far the query lies outside its (clamped) cell. A point of shell r is
        // at least (r − 1) cells away along some axis j, and at least o_k along every other
        // axis, so its distance is at least √(Σ o_k² + max(0, ((r − 1)·cell)² − max_k o_k²)).
        let lo = |k: usize| self.origin[k] + c[k] as f64 * self.cell;
        let o: Vec<f64> = (0..3)
            .map(|k| {
                let (a, b) = (lo(k), lo(k) + self.cell);
                (a - q[k]).max(q[k] - b).max(0.0)
            })
            .collect();
        let outside_sq: f64 = o.iter().map(|v| v * v).sum();
        let o_max_sq = o.iter().fold(0.0f64, |m, v| m.max(v * v));
        let bound = |r: i64| {
            let ring = ((r - 1).max(0) as f64 * self.cell).powi(2);
            (outside_sq + (ring - o_max_sq).max(0.0)).sqrt()
        };
        let mut best = f64::INFINITY;
        let max_r = self.dims.iter().copied().max().unwrap_or(1);
        let range = |k: usize, r: i64| ((-r).max(-c[k]), r.min(self.dims[k] - 1 - c[k]));
        for r in 0..=max_r {
            if r >= 1 && bound(r) > best {
                break;
            }
            let (x0, x1) = range(0, r);
            let (y0, y1) = range(1, r);
            let (z0, z1) = range(2, r);
            for dx in x0..=x1 {
                for dy in y0..=y1 {
                    if dx.abs() == r || dy.abs() == r {
                        for dz in z0..=z1 {
                            self.visit([c[0] + dx, c[1] + dy, c[2] + dz], q, &mut best);
                        }
                    } else {
                        // Inside the shell's x–y square only its two z faces (r > 0 here).
                        for dz in [-r, r] {
                            if dz >= z0 && dz <= z1 {
                                self.visit([c[0] + dx, c[1] + dy, c[2] + dz], q, &mut best);
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

fn mean_nn(from: &[Point3], to: &Grid, f: impl Fn(f64) -> f64) -> f64 {
    from.iter().map(|p| f(to.nearest(p))).sum::<f64>() / from.len() as f64
}

/// Symmetric Chamfer distance; `None` when either set is empty.
pub fn chamfer_distance(a: &[Point3], b: &[Point3]) -> Option<f64> {
    if a.is_empty() || b.is_empty() {
        return None;
    }
    let (ta, tb) = (Grid::new(a), Grid::new(b));
    Some(0.5 * (mean_nn(a, &tb, |d| d) + mean_nn(b, &ta, |d| d)))
}

/// Both kinds of Chamfer distance from one nearest-neighbour pass: the symmetric mean
/// distance (as [`chamfer_distance`]) and the squared form of the iTACO table,
/// `mean_a d(a, B)² + mean_b d(b, A)²` (units squared, the two directions summed).
pub fn chamfer_both(a: &[Point3], b: &[Point3]) -> Option<(f64, f64)> {
    if a.is_empty() || b.is_empty() {
        return None;
    }
    let (ta, tb) = (Grid::new(a), Grid::new(b));
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
        // Far apart and flat: shells clipped to a thin grid still find the exact neighbour.
        let flat = sample_surface(&cuboid(0.9, 0.6, 0.002).expect("flat"), 500, 4);
        let far: Vec<Point3> = a.iter().map(|p| p + Vector3::new(1.5, -0.7, 0.9)).collect();
        let want_far = 0.5 * (brute(&flat, &far) + brute(&far, &flat));
        assert!((chamfer_distance(&flat, &far).expect("cd") - want_far).abs() < 1e-12);
        let (cd, cd_sq) = chamfer_both(&a, &b).expect("both");
        assert!((cd - want).abs() < 1e-12);
        assert!((cd_sq - (brute_sq(&a, &b) + brute_sq(&b, &a))).abs() < 1e-12);
    }
}
