//! Coarser stand-ins of dense models for pose search: every part's mesh simplified by edge
//! collapses (meshoptimizer's quadric simplifier) under an absolute bound on how far the
//! surface may move, so the stand-in's silhouette stays within a fraction of a pixel of the
//! model's while its cost per render no longer grows with the model's triangle count.
//!
//! Open borders are locked (an open part's silhouette is bounded by its rim), coincident
//! vertices are welded first (meshes from files repeat vertices along seams), and a part
//! that would lose its closedness or every triangle keeps its own mesh.

use crate::mesh::TriMesh;
use crate::model::{ObjectModel, Part};

/// What [`simplified_model`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct SimplifyReport {
    pub triangles_before: usize,
    pub triangles_after: usize,
    /// The largest deviation the simplifier reports over the parts, in model units.
    pub deviation: f64,
    /// Parts kept as they were (too small to simplify, or simplification would open them).
    pub parts_kept: usize,
}

/// `mesh` with at most about `target_triangles` triangles where the surface moves by no more
/// than `max_deviation` (model units; the bound wins over the count), with the deviation
/// reached. Borders of open meshes stay where they are.
pub fn simplify_mesh(
    mesh: &TriMesh,
    max_deviation: f64,
    target_triangles: usize,
) -> (TriMesh, f64) {
    let extent = mesh.bounds().extent().norm();
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if mesh.triangles.is_empty() || !positive(extent) || !positive(max_deviation) {
        return (mesh.clone(), 0.0);
    }
    let welded = mesh.welded(extent * 1e-9);
    // Single precision about the centre: the simplifier's own arithmetic.
    let centre = welded.bounds().center();
    let positions: Vec<[f32; 3]> = welded
        .positions
        .iter()
        .map(|p| {
            let d = p - centre;
            [d.x as f32, d.y as f32, d.z as f32]
        })
        .collect();
    let indices: Vec<u32> = welded.triangles.iter().flatten().copied().collect();
    let mut deviation = 0.0f32;
    let kept = meshopt::simplify::simplify_decoder(
        &indices,
        &positions,
        target_triangles.saturating_mul(3),
        max_deviation as f32,
        meshopt::SimplifyOptions::LockBorder | meshopt::SimplifyOptions::ErrorAbsolute,
        Some(&mut deviation),
    );
    let triangles: Vec<[u32; 3]> = kept.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    (
        TriMesh::new(welded.positions, triangles).compacted(),
        f64::from(deviation),
    )
}

/// `model` with every part simplified ([`simplify_mesh`]) to within `max_deviation` model
/// units, its parts sharing about `target_triangles` in proportion to their own counts; the
/// kinematic tree, names and colours unchanged. A closed part whose simplified mesh is not
/// closed, or that would vanish, keeps its mesh.
pub fn simplified_model(
    model: &ObjectModel,
    max_deviation: f64,
    target_triangles: usize,
) -> (ObjectModel, SimplifyReport) {
    let before = model.triangle_count();
    let mut report = SimplifyReport {
        triangles_before: before,
        triangles_after: 0,
        deviation: 0.0,
        parts_kept: 0,
    };
    let parts = model
        .parts
        .iter()
        .map(|part| {
            let n = part.mesh.triangles.len();
            let share = (target_triangles as f64 * n as f64 / before.max(1) as f64).ceil() as usize;
            let (mesh, deviation) = simplify_mesh(&part.mesh, max_deviation, share.max(4));
            let simpler = Part::new(part.name.clone(), mesh, part.color);
            let keep = simpler.mesh.triangles.is_empty()
                || simpler.mesh.triangles.len() >= n
                || (part.watertight && !simpler.watertight);
            if keep {
                report.parts_kept += 1;
                report.triangles_after += n;
                part.clone()
            } else {
                report.triangles_after += simpler.mesh.triangles.len();
                report.deviation = report.deviation.max(deviation);
                simpler
            }
        })
        .collect();
    (
        ObjectModel {
            parts,
            tree: model.tree.clone(),
        },
        report,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives;

    #[test]
    fn a_dense_sphere_becomes_coarse_within_its_bound() {
        let dense = primitives::uv_sphere(1.0, 256, 128).expect("sphere");
        assert!(dense.triangles.len() > 60_000);
        let (coarse, deviation) = simplify_mesh(&dense, 0.002, 1000);
        assert!(
            coarse.triangles.len() < dense.triangles.len() / 10,
            "{}",
            coarse.triangles.len()
        );
        assert!(deviation <= 0.002, "{deviation}");
        assert!(coarse.is_watertight());
        // Every kept vertex is one of the sphere's: the radius is exact at the vertices and
        // the flat triangles between them stay within the bound of the sphere.
        for p in &coarse.positions {
            assert!((p.coords.norm() - 1.0).abs() < 1e-9);
        }
        let centroid_radius_min = (0..coarse.triangles.len())
            .map(|i| {
                let [a, b, c] = coarse.triangle(i);
                ((a.coords + b.coords + c.coords) / 3.0).norm()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(1.0 - centroid_radius_min < 0.004, "{centroid_radius_min}");
    }

    #[test]
    fn an_open_rim_stays_where_it_is() {
        // A dense open disc (a fan of many rings): its rim is its outline.
        let mut positions = vec![crate::Point3::origin()];
        let mut triangles = Vec::new();
        let (rings, around) = (40u32, 256u32);
        for r in 1..=rings {
            for k in 0..around {
                let a = k as f64 / around as f64 * std::f64::consts::TAU;
                let rr = r as f64 / rings as f64;
                positions.push(crate::Point3::new(rr * a.cos(), rr * a.sin(), 0.0));
            }
        }
        let at = |r: u32, k: u32| {
            if r == 0 {
                0
            } else {
                1 + (r - 1) * around + k % around
            }
        };
        for k in 0..around {
            triangles.push([0, at(1, k), at(1, k + 1)]);
        }
        for r in 1..rings {
            for k in 0..around {
                triangles.push([at(r, k), at(r + 1, k), at(r + 1, k + 1)]);
                triangles.push([at(r, k), at(r + 1, k + 1), at(r, k + 1)]);
            }
        }
        let disc = TriMesh::new(positions, triangles);
        let (coarse, _) = simplify_mesh(&disc, 0.01, 100);
        assert!(coarse.triangles.len() < disc.triangles.len() / 4);
        // Every rim vertex is still used.
        let rim = coarse
            .positions
            .iter()
            .filter(|p| (p.coords.norm() - 1.0).abs() < 1e-9)
            .count();
        assert_eq!(rim, around as usize);
    }

    #[test]
    fn seams_are_welded_before_simplifying() {
        // The dense sphere with every triangle on its own vertices (a triangle soup, as an
        // STL file gives it): still simplified, and closed again.
        let dense = primitives::uv_sphere(1.0, 128, 64).expect("sphere");
        let mut soup = TriMesh::default();
        for i in 0..dense.triangles.len() {
            let base = soup.positions.len() as u32;
            soup.positions.extend(dense.triangle(i));
            soup.triangles.push([base, base + 1, base + 2]);
        }
        let (coarse, _) = simplify_mesh(&soup, 0.004, 500);
        assert!(coarse.triangles.len() < dense.triangles.len() / 5);
        assert!(coarse.is_watertight());
    }
}
