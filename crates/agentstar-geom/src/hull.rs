//! 3-D convex hull by incremental construction (visible faces replaced by a cone from the
//! new point to the horizon). Quadratic in the worst case, fine for the few thousand
//! points that scene scripts produce; the output is watertight and oriented outward.

use crate::mesh::{Aabb, TriMesh};
use crate::{GeomError, Point3, Result, Vector3};
use std::collections::HashSet;

struct Face {
    v: [usize; 3],
    normal: Vector3,
    offset: f64,
    alive: bool,
}

fn make_face(points: &[Point3], a: usize, b: usize, c: usize) -> Face {
    let n = (points[b] - points[a]).cross(&(points[c] - points[a]));
    let normal = n.try_normalize(1e-300).unwrap_or_else(Vector3::zeros);
    Face {
        v: [a, b, c],
        normal,
        offset: normal.dot(&points[a].coords),
        alive: true,
    }
}

/// The convex hull of `points`. Needs at least four points that are not coplanar.
pub fn convex_hull(points: &[Point3]) -> Result<TriMesh> {
    let err = |reason: String| GeomError::InvalidArgument {
        primitive: "hull".into(),
        reason,
    };
    if points.len() < 4 {
        return Err(err(format!(
            "needs at least 4 points, got {}",
            points.len()
        )));
    }
    if points
        .iter()
        .any(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(err("a point has a non-finite coordinate".into()));
    }
    let bounds = Aabb::from_points(points.iter());
    let size = bounds.extent().norm().max(1e-12);
    let eps = size * 1e-10;

    // An initial tetrahedron from extreme points.
    let i0 = 0;
    let i1 = (0..points.len())
        .max_by(|&a, &b| {
            (points[a] - points[i0])
                .norm()
                .total_cmp(&(points[b] - points[i0]).norm())
        })
        .unwrap_or(0);
    let line = points[i1] - points[i0];
    let i2 = (0..points.len())
        .max_by(|&a, &b| {
            line.cross(&(points[a] - points[i0]))
                .norm()
                .total_cmp(&line.cross(&(points[b] - points[i0])).norm())
        })
        .unwrap_or(0);
    let plane_n = line.cross(&(points[i2] - points[i0]));
    if plane_n.norm() < eps * size {
        return Err(err("all points are collinear".into()));
    }
    let plane_n = plane_n.normalize();
    let i3 = (0..points.len())
        .max_by(|&a, &b| {
            plane_n
                .dot(&(points[a] - points[i0]))
                .abs()
                .total_cmp(&plane_n.dot(&(points[b] - points[i0])).abs())
        })
        .unwrap_or(0);
    if plane_n.dot(&(points[i3] - points[i0])).abs() < eps * 10.0 {
        return Err(err("all points are coplanar; a hull needs volume".into()));
    }

    let mut faces: Vec<Face> = Vec::new();
    let centroid = Point3::from(
        (points[i0].coords + points[i1].coords + points[i2].coords + points[i3].coords) / 4.0,
    );
    for (a, b, c) in [(i0, i1, i2), (i0, i1, i3), (i0, i2, i3), (i1, i2, i3)] {
        let mut f = make_face(points, a, b, c);
        if f.normal.dot(&(centroid - points[a])) > 0.0 {
            f = make_face(points, a, c, b);
        }
        faces.push(f);
    }

    let used: HashSet<usize> = [i0, i1, i2, i3].into_iter().collect();
    for (pi, p) in points.iter().enumerate() {
        if used.contains(&pi) {
            continue;
        }
        let visible: Vec<usize> = (0..faces.len())
            .filter(|&f| faces[f].alive && faces[f].normal.dot(&p.coords) - faces[f].offset > eps)
            .collect();
        if visible.is_empty() {
            continue;
        }
        let mut edges: HashSet<(usize, usize)> = HashSet::new();
        for &f in &visible {
            let v = faces[f].v;
            for k in 0..3 {
                edges.insert((v[k], v[(k + 1) % 3]));
            }
            faces[f].alive = false;
        }
        let mut horizon: Vec<(usize, usize)> = edges
            .iter()
            .copied()
            .filter(|&(a, b)| !edges.contains(&(b, a)))
            .collect();
        horizon.sort_unstable();
        for (a, b) in horizon {
            faces.push(make_face(points, a, b, pi));
        }
        if faces.len() > 4 * faces.iter().filter(|f| f.alive).count() + 64 {
            faces.retain(|f| f.alive);
        }
    }
    let triangles: Vec<[u32; 3]> = faces
        .iter()
        .filter(|f| f.alive)
        .map(|f| [f.v[0] as u32, f.v[1] as u32, f.v[2] as u32])
        .collect();
    Ok(TriMesh::new(points.to_vec(), triangles).compacted())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hull_of_cube_corners_with_interior_points() {
        let mut pts = Vec::new();
        for x in [-0.5, 0.5] {
            for y in [-0.5, 0.5] {
                for z in [-0.5, 0.5] {
                    pts.push(Point3::new(x, y, z));
                }
            }
        }
        pts.push(Point3::new(0.1, 0.0, 0.2));
        pts.push(Point3::new(0.0, 0.0, 0.5)); // on a face
        let h = convex_hull(&pts).expect("hull");
        assert!(h.is_watertight());
        assert!((h.volume() - 1.0).abs() < 1e-9);
        assert!((h.area() - 6.0).abs() < 1e-9);
    }

    #[test]
    fn degenerate_inputs_are_refused() {
        let flat: Vec<Point3> = (0..10)
            .map(|i| Point3::new(i as f64, (i * i) as f64, 0.0))
            .collect();
        assert!(convex_hull(&flat).is_err());
        assert!(convex_hull(&flat[..3]).is_err());
    }
}
