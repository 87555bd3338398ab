//! Coarser stand-ins of dense models for pose search: every part's mesh simplified by edge
//! collapses (meshoptimizer's quadric simplifier) under an absolute bound on how far the
//! surface may move, so the stand-in's silhouette stays within a fraction of a pixel of the
//! model's while its cost per render no longer grows with the model's triangle count.
//!
//! Coincident vertices are welded first (meshes from files repeat vertices along seams),
//! holes whose rims are shorter than a bound are closed (a scan's or an export's pinholes:
//! they would lock their rims and keep the stand-in dense; the silhouette changes only
//! where such a hole lies on the outline, by at most half its rim), the remaining open
//! borders are locked (an open part's silhouette is bounded by its rim), and a part that
//! would lose its closedness or every triangle keeps its own mesh.

use crate::appearance::SurfaceAppearance;
use crate::mesh::TriMesh;
use crate::model::{ObjectModel, Part};
use std::sync::Arc;

/// What [`simplified_model`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct SimplifyReport {
    pub triangles_before: usize,
    pub triangles_after: usize,
    /// The largest deviation the simplifier reports over the parts, in model units.
    pub deviation: f64,
    /// Parts kept as they were (too small to simplify, or simplification would open them).
    pub parts_kept: usize,
    /// Holes closed before simplification, over the parts simplified.
    pub holes_closed: usize,
}

/// One simplified mesh ([`simplify_mesh`]).
#[derive(Debug, Clone)]
pub struct SimplifiedMesh {
    pub mesh: TriMesh,
    /// The largest deviation the simplifier reports, in model units.
    pub deviation: f64,
    /// Holes closed before simplification ([`TriMesh::with_small_holes_closed`]).
    pub holes_closed: usize,
}

/// `mesh` with at most about `target_triangles` triangles where the surface moves by no more
/// than `max_deviation` (model units; the bound wins over the count), with the deviation
/// reached. Holes whose rims are at most `max_hole_rim` long are closed first (0: none);
/// the borders of the others stay where they are.
pub fn simplify_mesh(
    mesh: &TriMesh,
    max_deviation: f64,
    target_triangles: usize,
    max_hole_rim: f64,
) -> SimplifiedMesh {
    let extent = mesh.bounds().extent().norm();
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if mesh.triangles.is_empty() || !positive(extent) || !positive(max_deviation) {
        return SimplifiedMesh {
            mesh: mesh.clone(),
            deviation: 0.0,
            holes_closed: 0,
        };
    }
    let (welded, holes_closed) =
        mesh.welded(extent * 1e-9)
            .with_small_holes_closed(if positive(max_hole_rim) {
                max_hole_rim
            } else {
                0.0
            });
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
    SimplifiedMesh {
        mesh: TriMesh::new(welded.positions, triangles).compacted(),
        deviation: f64::from(deviation),
        holes_closed,
    }
}

/// `model` with every part simplified ([`simplify_mesh`]) to within `max_deviation` model
/// units, its parts sharing about `target_triangles` in proportion to their own counts, holes
/// with rims up to `max_hole_rim` closed; the kinematic tree, names and colours unchanged. A
/// closed part whose simplified mesh is not closed, or that would vanish, keeps its mesh.
pub fn simplified_model(
    model: &ObjectModel,
    max_deviation: f64,
    target_triangles: usize,
    max_hole_rim: f64,
) -> (ObjectModel, SimplifyReport) {
    let before = model.triangle_count();
    let mut report = SimplifyReport {
        triangles_before: before,
        triangles_after: 0,
        deviation: 0.0,
        parts_kept: 0,
        holes_closed: 0,
    };
    let parts = model
        .parts
        .iter()
        .map(|part| {
            let n = part.mesh.triangles.len();
            let share = (target_triangles as f64 * n as f64 / before.max(1) as f64).ceil() as usize;
            let simplified = simplify_mesh(&part.mesh, max_deviation, share.max(4), max_hole_rim);
            let simpler = Part::new(part.name.clone(), simplified.mesh, part.color);
            let keep = simpler.mesh.triangles.is_empty()
                || simpler.mesh.triangles.len() >= n
                || (part.watertight && !simpler.watertight);
            if keep {
                report.parts_kept += 1;
                report.triangles_after += n;
                part.clone()
            } else {
                report.triangles_after += simpler.mesh.triangles.len();
                report.deviation = report.deviation.max(simplified.deviation);
                report.holes_closed += simplified.holes_closed;
                match &part.surface {
                    Some(surface) if surface.varies() => {
                        let baked = baked_colors(&part.mesh, surface, &simpler.mesh);
                        simpler
                            .clone()
                            .with_surface(Arc::new(baked))
                            .unwrap_or(simpler)
                    }
                    _ => simpler,
                }
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

/// The appearance of `dense` carried onto its stand-in `coarse` as vertex colours: each
/// coarse vertex takes the colour of the nearest dense vertex (the mean over its corners,
/// so a texture is sampled at that vertex's coordinates), and the colours are interpolated
/// over the coarse triangles. A print blurs to the stand-in's resolution but keeps its
/// place, which is what the search's colour terms need to tell twins apart.
fn baked_colors(
    dense: &TriMesh,
    surface: &SurfaceAppearance,
    coarse: &TriMesh,
) -> SurfaceAppearance {
    let mut sum = vec![[0.0f32; 3]; dense.positions.len()];
    let mut count = vec![0u32; dense.positions.len()];
    for (t, tri) in dense.triangles.iter().enumerate() {
        for k in 0..3 {
            let mut bary = [0.0; 3];
            bary[k] = 1.0;
            let c = surface.color_at(t, bary);
            let v = tri[k] as usize;
            for i in 0..3 {
                sum[v][i] += c[i];
            }
            count[v] += 1;
        }
    }
    let colored: Vec<(crate::Point3, [f32; 3])> = dense
        .positions
        .iter()
        .zip(sum.iter().zip(&count))
        .filter(|(_, (_, &n))| n > 0)
        .map(|(p, (c, &n))| (*p, c.map(|v| v / n as f32)))
        .collect();
    let nearest = |p: &crate::Point3| {
        colored
            .iter()
            .min_by(|a, b| {
                (a.0 - p)
                    .norm_squared()
                    .total_cmp(&(b.0 - p).norm_squared())
            })
            .map_or([0.7; 3], |(_, c)| *c)
    };
    let vertex: Vec<[f32; 3]> = coarse.positions.iter().map(nearest).collect();
    let corners = coarse
        .triangles
        .iter()
        .map(|t| t.map(|i| vertex[i as usize]))
        .collect();
    SurfaceAppearance::vertex_colored(corners)
        .unwrap_or_else(|_| SurfaceAppearance::plain("stand-in", [0.7; 3], coarse.triangles.len()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::NO_FACE;
    use crate::primitives;

    #[test]
    fn a_dense_sphere_becomes_coarse_within_its_bound() {
        let dense = primitives::uv_sphere(1.0, 256, 128).expect("sphere");
        assert!(dense.triangles.len() > 60_000);
        let SimplifiedMesh {
            mesh: coarse,
            deviation,
            ..
        } = simplify_mesh(&dense, 0.002, 1000, 0.0);
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
    fn a_stand_in_keeps_a_coloured_parts_print_where_it_was() {
        // A dense sphere, red above the equator and blue below (vertex colours).
        let dense = primitives::uv_sphere(1.0, 96, 48).expect("sphere");
        let corners: Vec<[[f32; 3]; 3]> = dense
            .triangles
            .iter()
            .map(|t| {
                t.map(|i| {
                    if dense.positions[i as usize].z > 0.0 {
                        [1.0, 0.0, 0.0]
                    } else {
                        [0.0, 0.0, 1.0]
                    }
                })
            })
            .collect();
        let surface = Arc::new(SurfaceAppearance::vertex_colored(corners).expect("colours"));
        let model = ObjectModel {
            parts: vec![Part::new("ball", dense, [0.5; 3])
                .with_surface(surface)
                .expect("part")],
            tree: crate::KinematicTree::rigid(1),
        };
        let (standin, report) = simplified_model(&model, 0.01, 500, 0.0);
        assert!(
            report.triangles_after < report.triangles_before / 4,
            "{report:?}"
        );
        let part = &standin.parts[0];
        let surface = part.surface.as_ref().expect("colours carried");
        // Every triangle wholly on one side shows its side's colour; those across the
        // equator blend the two.
        let mut whole = 0;
        for (t, tri) in part.mesh.triangles.iter().enumerate() {
            let z = tri.map(|i| part.mesh.positions[i as usize].z);
            let want = if z.iter().all(|&z| z > 1e-9) {
                [1.0, 0.0, 0.0]
            } else if z.iter().all(|&z| z < -1e-9) {
                [0.0, 0.0, 1.0]
            } else {
                continue;
            };
            whole += 1;
            assert_eq!(
                surface.color_at(t, [1.0 / 3.0; 3]),
                want,
                "triangle {t} at {z:?}"
            );
        }
        assert!(whole > part.mesh.triangles.len() / 2, "{whole}");
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
        let coarse = simplify_mesh(&disc, 0.01, 100, 0.0).mesh;
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
        let coarse = simplify_mesh(&soup, 0.004, 500, 0.0).mesh;
        assert!(coarse.triangles.len() < dense.triangles.len() / 5);
        assert!(coarse.is_watertight());
    }

    #[test]
    fn pinholes_are_closed_and_large_holes_kept() {
        // A dense sphere with every 50th triangle missing (pinholes, rims about 0.17 long)
        // and a cap cut away about its north pole (a rim of about 1.2).
        let dense = primitives::uv_sphere(1.0, 128, 64).expect("sphere");
        let z = |t: &[u32; 3]| t.map(|v| dense.positions[v as usize].z);
        // Pinholes away from the poles: two missing triangles of a pole's fan leave a rim
        // through the pole twice (not a simple loop, kept open).
        let pinhole = |i: usize, t: &[u32; 3]| i % 50 == 7 && z(t).iter().all(|z| z.abs() < 0.9);
        let in_cap = |t: &[u32; 3]| z(t).iter().all(|&z| z >= 0.98);
        let pinholes = (dense.triangles.iter().enumerate())
            .filter(|&(i, t)| pinhole(i, t))
            .count();
        let triangles: Vec<[u32; 3]> = (dense.triangles.iter().enumerate())
            .filter(|&(i, t)| !pinhole(i, t) && !in_cap(t))
            .map(|(_, t)| *t)
            .collect();
        let holey = TriMesh::new(dense.positions.clone(), triangles).compacted();
        assert!(!holey.is_watertight());
        let (closed, count) = holey.with_small_holes_closed(0.3);
        // Pinholes next to each other merge into one rim; none stays open, the cap does.
        assert!(
            count > pinholes / 2 && count <= pinholes,
            "{count} of {pinholes}"
        );
        let rims: Vec<[u32; 4]> = closed
            .edge_incidence()
            .into_iter()
            .filter(|e| e[2] == NO_FACE || e[3] == NO_FACE)
            .collect();
        assert!(!rims.is_empty());
        for e in &rims {
            let (a, b) = (
                closed.positions[e[0] as usize],
                closed.positions[e[1] as usize],
            );
            assert!(
                a.z > 0.97 && b.z > 0.97,
                "an open edge off the cap's rim: {a} {b}"
            );
        }
        // Nothing to close within a tiny bound; with a bound past the cap's rim, closed.
        assert_eq!(holey.with_small_holes_closed(1e-4).1, 0);
        let (whole, _) = holey.with_small_holes_closed(2.0);
        assert!(whole.is_watertight(), "fans wound against their neighbours");
        // Simplified with the pinholes closed, the stand-in is coarse; with them open, their
        // locked rims keep it dense.
        let with = simplify_mesh(&holey, 0.02, 200, 0.3);
        let without = simplify_mesh(&holey, 0.02, 200, 0.0);
        assert!(with.holes_closed > pinholes / 2);
        assert!(
            with.mesh.triangles.len() * 2 < without.mesh.triangles.len(),
            "{} vs {}",
            with.mesh.triangles.len(),
            without.mesh.triangles.len()
        );
    }

    #[test]
    fn holes_that_touch_at_a_vertex_are_closed_together() {
        // Two triangles of a sphere that share one vertex and no edge, removed: their rims
        // pass through that vertex twice (a pinch). Split there, the two rims join into one
        // loop through both copies of the vertex, closed as one hole.
        let sphere = primitives::uv_sphere(1.0, 32, 16).expect("sphere");
        let t = &sphere.triangles;
        let first = t.len() / 2;
        let shares_one =
            |a: &[u32; 3], b: &[u32; 3]| a.iter().filter(|v| b.contains(v)).count() == 1;
        let second = (0..t.len())
            .find(|&k| k != first && shares_one(&t[first], &t[k]))
            .expect("a triangle touching at one vertex");
        let holey = TriMesh::new(
            sphere.positions.clone(),
            (t.iter().enumerate())
                .filter(|&(k, _)| k != first && k != second)
                .map(|(_, tri)| *tri)
                .collect(),
        );
        let leaving = |m: &TriMesh| {
            let mut count = std::collections::HashMap::new();
            for (a, _) in m.border_edges() {
                *count.entry(a).or_insert(0usize) += 1;
            }
            count.into_values().max().unwrap_or(0)
        };
        assert_eq!(leaving(&holey), 2, "a pinch: two rims leave one vertex");
        let split = holey.with_pinches_split();
        assert_eq!(leaving(&split), 1);
        assert_eq!(split.positions.len(), holey.positions.len() + 1);
        let (closed, count) = holey.with_small_holes_closed(2.0);
        assert_eq!(count, 1);
        assert!(closed.is_watertight());
        // The joined rim is as long as both: under that, nothing is closed.
        assert_eq!(holey.with_small_holes_closed(1.0).1, 0);
        // Nothing to close within a tiny bound: the mesh comes back as it was.
        assert_eq!(holey.with_small_holes_closed(1e-4).0, holey);
    }
}
