//! The object model: named parts (meshes in the canonical rest frame, each with a colour)
//! and the kinematic tree that moves them, plus the canonical-frame report.

use crate::appearance::SurfaceAppearance;
use crate::kinematics::KinematicTree;
use crate::mesh::{Aabb, TriMesh};
use crate::pose::{ObjectPose, Rigid};
use crate::{Point3, Vector3};
use std::collections::BTreeMap;
use std::sync::Arc;

#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    pub name: String,
    pub mesh: Arc<TriMesh>,
    /// Linear RGB in [0, 1].
    pub color: [f32; 3],
    /// True when the mesh is closed and consistently oriented (renderers may cull back faces).
    pub watertight: bool,
    /// Bounds of `mesh` in the part's rest frame.
    pub bounds: Aabb,
    /// Edge–face adjacency of a watertight mesh (see [`TriMesh::manifold_edges`]), which
    /// lets renderers fill silhouettes from contour edges alone.
    pub edges: Option<Arc<Vec<[u32; 4]>>>,
    /// Every edge's triangles of a mesh that is not watertight
    /// ([`TriMesh::edge_incidence`]), which lets renderers fill its silhouette from the
    /// outlines of its front and back faces; `None` when `edges` is set.
    pub open_edges: Option<Arc<Vec<[u32; 4]>>>,
    /// The plane of each triangle of a watertight mesh, `[n, n·a]` with `n = (b − a) × (c − a)`
    /// (outward, not normalised): a triangle faces a viewpoint `p` when `n·p > n·a`, so
    /// renderers tell front faces from back ones without projecting every vertex. `None`
    /// when `edges` is.
    pub planes: Option<Arc<Vec<[f64; 4]>>>,
    /// Texture, vertex colours or materials per triangle where the model file had them;
    /// `color` is then their mean. `None`: the part is `color` all over.
    pub surface: Option<Arc<SurfaceAppearance>>,
}

impl Part {
    pub fn new(name: impl Into<String>, mesh: TriMesh, color: [f32; 3]) -> Part {
        let closed = mesh.volume() > 0.0;
        let mut edges = if closed {
            mesh.manifold_edges().map(Arc::new)
        } else {
            None
        };
        // A closed surface whose file repeats each vertex per corner (texture coordinates or
        // colours per corner) is closed once its coincident vertices are shared: the same
        // triangles in the same order, so a per-triangle appearance still fits it.
        let mut mesh = mesh;
        if closed && edges.is_none() {
            if let Some(shared) = mesh.with_coincident_vertices_shared() {
                if let Some(e) = shared.manifold_edges() {
                    edges = Some(Arc::new(e));
                    mesh = shared;
                }
            }
        }
        let watertight = edges.is_some();
        let open_edges = (!watertight).then(|| Arc::new(mesh.edge_incidence()));
        let bounds = mesh.bounds();
        let planes = watertight.then(|| Arc::new(mesh.face_planes()));
        Part {
            name: name.into(),
            mesh: Arc::new(mesh),
            color,
            watertight,
            bounds,
            edges,
            open_edges,
            planes,
            surface: None,
        }
    }

    /// The part with `surface` as its appearance, and its mean as its colour; refused when
    /// the surface is not for this many triangles.
    pub fn with_surface(mut self, surface: Arc<SurfaceAppearance>) -> crate::Result<Part> {
        if surface.triangle_count() != self.mesh.triangles.len() {
            return Err(crate::GeomError::InvalidArgument {
                primitive: "part".into(),
                reason: format!(
                    "part `{}`: an appearance for {} triangles on a mesh of {}",
                    self.name,
                    surface.triangle_count(),
                    self.mesh.triangles.len()
                ),
            });
        }
        self.color = surface.mean_color(&self.mesh);
        self.surface = Some(surface);
        Ok(self)
    }

    /// The colour at barycentric coordinates `bary` of triangle `triangle`: the surface's
    /// where the part has one, else the part's colour.
    pub fn color_at(&self, triangle: usize, bary: [f32; 3]) -> [f32; 3] {
        match &self.surface {
            Some(s) => s.color_at(triangle, bary),
            None => self.color,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct ObjectModel {
    pub parts: Vec<Part>,
    pub tree: KinematicTree,
}

/// How the model sits in its canonical frame (+Z up, centred, longest side about 1).
#[derive(Debug, Clone, PartialEq)]
pub struct CanonicalReport {
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    pub extent: [f64; 3],
    pub center: [f64; 3],
    pub longest_side: f64,
    pub triangle_count: usize,
    /// Human-readable warnings when the convention drifts; empty when it holds.
    pub warnings: Vec<String>,
}

impl ObjectModel {
    pub fn part_names(&self) -> Vec<String> {
        self.parts.iter().map(|p| p.name.clone()).collect()
    }

    pub fn part_index(&self, name: &str) -> Option<usize> {
        self.parts.iter().position(|p| p.name == name)
    }

    pub fn triangle_count(&self) -> usize {
        self.parts.iter().map(|p| p.mesh.triangles.len()).sum()
    }

    /// Canonical bounds of the parts posed by forward kinematics at `states` (internal units).
    pub fn posed_bounds(&self, states: &[f64]) -> Aabb {
        let transforms = self.tree.part_transforms(states);
        let mut b = Aabb::empty();
        for (part, t) in self.parts.iter().zip(&transforms) {
            for tri in &part.mesh.triangles {
                for &i in tri {
                    b.grow(&(t * part.mesh.positions[i as usize]));
                }
            }
        }
        b
    }

    /// The pivot: centre of the posed canonical bounds (frozen by callers for a search).
    pub fn pivot(&self, states: &[f64]) -> Point3 {
        self.posed_bounds(states).center()
    }

    /// Measures the canonical-frame convention at rest; its warnings also name each part
    /// hidden inside another ([`crate::inside::hidden_parts`]).
    pub fn canonical_report(&self) -> CanonicalReport {
        let b = self.posed_bounds(&self.tree.rest_states());
        let ext = b.extent();
        let center = if b.is_empty() {
            Point3::origin()
        } else {
            b.center()
        };
        let longest = ext.max();
        // Parts hidden inside another (never seen in an image): every model load reports them.
        let mut warnings = crate::inside::hidden_part_warnings(self);
        if b.is_empty() {
            warnings.push("the model has no geometry".into());
        } else {
            if center.coords.norm() > 0.05 * longest.max(1e-9) {
                warnings.push(format!(
                    "bounding-box centre ({:.3}, {:.3}, {:.3}) is off the origin by {:.3} (more than 5% of the longest side); centre the body (advisory: the gates and tools work either way, and a part that sticks out, as a handle or a peg, may leave it so)",
                    center.x, center.y, center.z, center.coords.norm()
                ));
            }
            if !(0.8..=1.25).contains(&longest) {
                warnings.push(format!(
                    "longest side is {longest:.3}; the canonical frame expects about 1 (0.8–1.25)"
                ));
            }
        }
        CanonicalReport {
            bbox_min: if b.is_empty() {
                [0.0; 3]
            } else {
                b.min.coords.into()
            },
            bbox_max: if b.is_empty() {
                [0.0; 3]
            } else {
                b.max.coords.into()
            },
            extent: ext.into(),
            center: center.coords.into(),
            longest_side: longest,
            triangle_count: self.triangle_count(),
            warnings,
        }
    }
}

/// How the canonical origin moved between two versions of a model: `new ≈ old + shift` for
/// the geometry that did not change, so a pose made for `old` is carried to `new` by
/// [`OriginShift::carry`] (the object lands where it was in every image).
///
/// The canonical origin is the script's origin; it moves only when an edit moves geometry
/// that did not otherwise change, which is what re-centring a model after a shape edit does
/// (`translate(-c)` of every part). Every part of the same name and mesh layout in both
/// versions votes: moved whole by one translation, or with most of its vertices (at least
/// half, and 1.5× the next group) moved by one translation (its unchanged side), it votes
/// for that translation; changed with no translation shared, it votes for none (its origin
/// stayed). The largest voting part decides; with no vote the shift is zero.
#[derive(Debug, Clone, PartialEq)]
pub struct OriginShift {
    pub shift: Vector3,
    /// The part that decided it (`None`: no part matched, the shift is zero).
    pub part: Option<String>,
    /// Share of that part's vertices that moved by `shift` (1 for a whole part).
    pub share: f64,
}

impl OriginShift {
    pub fn none() -> Self {
        OriginShift {
            shift: Vector3::zeros(),
            part: None,
            share: 0.0,
        }
    }

    /// True when the origin moved by more than `tolerance` canonical units.
    pub fn moved(&self, tolerance: f64) -> bool {
        self.shift.norm() > tolerance
    }

    /// `pose` (made for the old model) for the new model: `p_cam = s·R·(x − shift) + t`.
    pub fn carry(&self, pose: &ObjectPose, scale: f64) -> ObjectPose {
        ObjectPose {
            rotation: pose.rotation,
            translation: pose.translation - pose.rotation * (self.shift * scale),
        }
    }
}

/// Groups vertex displacements by value (to `quantum`); returns the largest group's
/// displacement and its share of the vertices, and the next group's share.
fn displacement_groups(old: &TriMesh, new: &TriMesh, quantum: f64) -> (Vector3, f64, f64) {
    let mut groups: BTreeMap<[i64; 3], (usize, Vector3)> = BTreeMap::new();
    for (a, b) in old.positions.iter().zip(&new.positions) {
        let d = b - a;
        let key = [0, 1, 2].map(|k| (d[k] / quantum).round() as i64);
        let e = groups.entry(key).or_insert((0, Vector3::zeros()));
        e.0 += 1;
        e.1 += d;
    }
    let n = old.positions.len().max(1) as f64;
    let mut sizes: Vec<(usize, Vector3)> = groups.into_values().collect();
    sizes.sort_by_key(|g| std::cmp::Reverse(g.0));
    match sizes.as_slice() {
        [] => (Vector3::zeros(), 0.0, 0.0),
        [(c, sum), rest @ ..] => (
            sum / *c as f64,
            *c as f64 / n,
            rest.first().map_or(0.0, |r| r.0 as f64 / n),
        ),
    }
}

/// How far the canonical origin moved from `old` to `new` (see [`OriginShift`]).
pub fn origin_shift(old: &ObjectModel, new: &ObjectModel) -> OriginShift {
    let size = old
        .posed_bounds(&old.tree.rest_states())
        .extent()
        .max()
        .max(1e-9);
    let quantum = 1e-6 * size;
    let mut best: Option<(f64, OriginShift)> = None;
    for part in &new.parts {
        let Some(before) = old.parts.iter().find(|p| p.name == part.name) else {
            continue;
        };
        let (a, b) = (&before.mesh, &part.mesh);
        if a.positions.len() != b.positions.len() || a.triangles != b.triangles || a.is_empty() {
            continue;
        }
        let (shift, share, next) = displacement_groups(a, b, quantum);
        let whole = share >= 1.0 - 1e-12;
        let vote = if whole || (share >= 0.5 && share >= 1.5 * next) {
            OriginShift {
                shift,
                part: Some(part.name.clone()),
                share,
            }
        } else {
            OriginShift {
                shift: Vector3::zeros(),
                part: Some(part.name.clone()),
                share: 0.0,
            }
        };
        let weight = before.bounds.extent().norm();
        if best.as_ref().is_none_or(|(w, _)| weight > *w) {
            best = Some((weight, vote));
        }
    }
    best.map_or_else(OriginShift::none, |(_, s)| s)
}

/// The part a shape edit keeps in place when it carries poses to the new model, and why it
/// was chosen ([`held_part`]).
#[derive(Debug, Clone, PartialEq)]
pub struct HeldPart {
    pub name: String,
    /// Why this part: named by the caller, the largest in view, or the largest surface.
    pub why: String,
}

/// The part to hold in place across an edit from `old` to `new`: `named` when given (it
/// must be a part of both), else the part of both with the most visible pixels over the
/// frames (`visible`, per part of `old`, at the poses being carried), else, with no pixels
/// counted, the largest surface area (a convex body's mean projected area over all view
/// directions is a quarter of its surface area: Cauchy's formula).
pub fn held_part(
    old: &ObjectModel,
    new: &ObjectModel,
    named: Option<&str>,
    visible: Option<(&[u64], usize)>,
) -> Result<HeldPart, String> {
    let in_both = |name: &str| {
        old.parts.iter().any(|p| p.name == name) && new.parts.iter().any(|p| p.name == name)
    };
    if let Some(name) = named {
        if in_both(name) {
            return Ok(HeldPart {
                name: name.to_string(),
                why: "named".to_string(),
            });
        }
        let names: Vec<&str> = new
            .parts
            .iter()
            .map(|p| p.name.as_str())
            .filter(|n| in_both(n))
            .collect();
        return Err(format!(
            "part `{name}` is not a part of both the old and the new model (parts of both: {})",
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        ));
    }
    let candidates: Vec<usize> = (0..old.parts.len())
        .filter(|&k| in_both(&old.parts[k].name))
        .collect();
    if let Some((pixels, frames)) = visible.filter(|(v, _)| {
        candidates
            .iter()
            .any(|&k| v.get(k).copied().unwrap_or(0) > 0)
    }) {
        let total: u64 = pixels.iter().sum();
        if let Some(&k) = candidates
            .iter()
            .max_by_key(|&&k| (pixels.get(k).copied().unwrap_or(0), std::cmp::Reverse(k)))
        {
            let share = pixels.get(k).copied().unwrap_or(0) as f64 / total.max(1) as f64;
            return Ok(HeldPart {
                name: old.parts[k].name.clone(),
                why: format!(
                    "the largest part in view: {:.0}% of the model's visible pixels over {frames} keyframe(s)",
                    100.0 * share
                ),
            });
        }
    }
    candidates
        .iter()
        .max_by(|&&a, &&b| {
            old.parts[a]
                .mesh
                .area()
                .total_cmp(&old.parts[b].mesh.area())
        })
        .map(|&k| HeldPart {
            name: old.parts[k].name.clone(),
            why:
                "the largest part by surface area (no posed keyframe to measure the parts in view)"
                    .to_string(),
        })
        .ok_or_else(|| "the old and the new model share no part name".to_string())
}

/// How far the canonical origin moved from `old` to `new`, holding the part `held` in place:
/// with the same mesh layout in both, its vertices' shared translation (moved whole, or on
/// its unchanged side as [`origin_shift`] reads it; none shared: it stayed); with a new
/// layout (a boolean or a segment count changed), its bounds axis by axis: both faces moved
/// alike (a translation), one face stayed (it grew from there: no shift), else the move of
/// their centre (it grew about it). `None` when `held` is not a part of both.
pub fn origin_shift_holding(
    old: &ObjectModel,
    new: &ObjectModel,
    held: &str,
) -> Option<OriginShift> {
    let before = old.parts.iter().find(|p| p.name == held)?;
    let part = new.parts.iter().find(|p| p.name == held)?;
    let (a, b) = (&before.mesh, &part.mesh);
    if a.positions.len() == b.positions.len() && a.triangles == b.triangles && !a.is_empty() {
        let size = old
            .posed_bounds(&old.tree.rest_states())
            .extent()
            .max()
            .max(1e-9);
        let (shift, share, next) = displacement_groups(a, b, 1e-6 * size);
        let whole = share >= 1.0 - 1e-12;
        return Some(if whole || (share >= 0.5 && share >= 1.5 * next) {
            OriginShift {
                shift,
                part: Some(held.to_string()),
                share,
            }
        } else {
            OriginShift {
                shift: Vector3::zeros(),
                part: Some(held.to_string()),
                share: 0.0,
            }
        });
    }
    if a.is_empty() || b.is_empty() {
        return Some(OriginShift {
            shift: Vector3::zeros(),
            part: Some(held.to_string()),
            share: 0.0,
        });
    }
    // Meshed anew: its bounds, axis by axis. Both faces moved alike: a translation; one
    // face stayed: it grew from that side and the origin stayed; else it grew about its
    // centre, whose move is the shift.
    let (ba, bb) = (a.bounds(), b.bounds());
    let tolerance = 1e-6 * ba.extent().max().max(1e-9);
    let shift = Vector3::from_fn(|k, _| {
        let (dmin, dmax) = (bb.min[k] - ba.min[k], bb.max[k] - ba.max[k]);
        if (dmin - dmax).abs() <= tolerance {
            (dmin + dmax) / 2.0
        } else if dmin.abs() <= tolerance || dmax.abs() <= tolerance {
            0.0
        } else {
            (dmin + dmax) / 2.0
        }
    });
    Some(OriginShift {
        shift,
        part: Some(held.to_string()),
        share: 0.0,
    })
}

/// A copy of `mesh` mapped by a rigid transform.
pub fn transform_rigid(mesh: &TriMesh, t: &Rigid) -> TriMesh {
    TriMesh {
        positions: mesh.positions.iter().map(|p| t * p).collect(),
        triangles: mesh.triangles.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{JointDef, JointKind};
    use crate::primitives::cuboid;
    use crate::Vector3;

    /// `mesh` as a file with per-corner attributes stores it: each triangle its own three
    /// vertices.
    fn corner_per_vertex(mesh: &TriMesh) -> TriMesh {
        let positions = mesh
            .triangles
            .iter()
            .flat_map(|t| t.map(|i| mesh.positions[i as usize]))
            .collect();
        let triangles = (0..mesh.triangles.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        TriMesh::new(positions, triangles)
    }

    #[test]
    fn a_closed_mesh_stored_per_corner_is_a_closed_part_with_its_triangles_in_order() {
        let cube = cuboid(1.0, 0.5, 0.4).expect("box");
        let split = corner_per_vertex(&cube);
        assert!(
            split.manifold_edges().is_none(),
            "no triangle shares an edge"
        );
        let part = Part::new("body", split.clone(), [0.5; 3]);
        assert!(part.watertight);
        assert!(part.edges.is_some() && part.open_edges.is_none());
        assert_eq!(part.mesh.positions.len(), cube.positions.len());
        // The same triangles, in the same order, each corner at the same position: a
        // per-triangle appearance still fits.
        assert_eq!(part.mesh.triangles.len(), split.triangles.len());
        for (t, (a, b)) in part.mesh.triangles.iter().zip(&split.triangles).enumerate() {
            for k in 0..3 {
                assert_eq!(
                    part.mesh.positions[a[k] as usize], split.positions[b[k] as usize],
                    "triangle {t} corner {k}"
                );
            }
        }
        // A mesh without coincident vertices is left as it is.
        assert!(cube.with_coincident_vertices_shared().is_none());
        // An open sheet stored per corner stays open: sharing its vertices closes nothing.
        let mut sheet = cube.clone();
        sheet.triangles.truncate(sheet.triangles.len() - 2);
        let part = Part::new("sheet", corner_per_vertex(&sheet), [0.5; 3]);
        assert!(!part.watertight && part.open_edges.is_some());
    }

    #[test]
    fn canonical_report_flags_drift() {
        let parts = vec![Part::new(
            "body",
            cuboid(1.0, 0.5, 0.4).expect("box"),
            [0.5; 3],
        )];
        let model = ObjectModel {
            tree: KinematicTree::rigid(1),
            parts,
        };
        let r = model.canonical_report();
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert!((r.longest_side - 1.0).abs() < 1e-12);
        let moved = Part::new(
            "body",
            cuboid(2.0, 0.5, 0.4)
                .expect("box")
                .translated(Vector3::new(0.5, 0.0, 0.0)),
            [0.5; 3],
        );
        let model = ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![moved],
        };
        assert_eq!(model.canonical_report().warnings.len(), 2);
    }

    fn two_part(offset: Vector3, handle_x: f64) -> ObjectModel {
        let body = cuboid(1.0, 0.6, 0.4).expect("box").translated(offset);
        let handle = cuboid(handle_x, 0.1, 0.1)
            .expect("box")
            .translated(Vector3::new(0.5 + handle_x / 2.0, 0.0, 0.0) + offset);
        ObjectModel {
            tree: KinematicTree::rigid(2),
            parts: vec![
                Part::new("body", body, [0.5; 3]),
                Part::new("handle", handle, [0.5; 3]),
            ],
        }
    }

    #[test]
    fn the_origin_shift_follows_the_geometry_that_did_not_change() {
        // A longer handle, then everything re-centred: the body says how far.
        let old = two_part(Vector3::zeros(), 0.2);
        let moved = Vector3::new(-0.05, 0.01, 0.0);
        let new = two_part(moved, 0.3);
        let s = origin_shift(&old, &new);
        assert_eq!(s.part.as_deref(), Some("body"));
        assert!((s.shift - moved).norm() < 1e-9, "{s:?}");
        // Not re-centred: nothing moved.
        let s = origin_shift(&old, &two_part(Vector3::zeros(), 0.3));
        assert!(s.shift.norm() < 1e-12 && !s.moved(1e-9), "{s:?}");
        // A carried pose puts the unchanged body where it was in the camera.
        let pose = ObjectPose::new(
            crate::UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
            Vector3::new(0.1, 0.0, 2.0),
        );
        let s = origin_shift(&old, &new);
        let carried = s.carry(&pose, 0.25);
        let p_old = Point3::new(0.5, 0.3, -0.2);
        let before = pose.with_scale(0.25).transform_point(&p_old);
        let after = carried.with_scale(0.25).transform_point(&(p_old + moved));
        assert!((before - after).norm() < 1e-12);
        // One part whose vertices moved apart symmetrically (a deeper box, still centred):
        // no translation is shared by most of them, so the origin stays.
        let deep = |d: f64| ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![Part::new(
                "body",
                cuboid(1.0, d, 0.4).expect("box"),
                [0.5; 3],
            )],
        };
        let s = origin_shift(&deep(0.6), &deep(0.7));
        assert_eq!((s.shift, s.share), (Vector3::zeros(), 0.0));
        // A part whose layout changed does not vote.
        let single = ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![old.parts[0].clone()],
        };
        assert_eq!(
            origin_shift(&single, &deep(0.7)).part.as_deref(),
            Some("body")
        );
        let other = ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![Part::new(
                "body",
                crate::primitives::uv_sphere(0.5, 8, 4).expect("s"),
                [0.5; 3],
            )],
        };
        assert_eq!(origin_shift(&single, &other), OriginShift::none());
    }

    #[test]
    fn a_held_part_decides_the_shift_and_the_largest_in_view_is_held() {
        // A cabinet grown evenly about its centre: its handle moves out with its face.
        let cabinet = |w: f64, segments: usize| {
            let body = if segments == 0 {
                cuboid(w, 0.6, 0.8).expect("box")
            } else {
                crate::primitives::uv_sphere(w / 2.0, segments as i64 * 2, segments as i64)
                    .expect("body")
            };
            let handle = cuboid(0.04, 0.1, 0.1)
                .expect("box")
                .translated(Vector3::new(w / 2.0 + 0.02, 0.0, 0.0));
            ObjectModel {
                tree: KinematicTree::rigid(2),
                parts: vec![
                    Part::new("body", body, [0.5; 3]),
                    Part::new("handle", handle, [0.5; 3]),
                ],
            }
        };
        let (old, new) = (cabinet(1.0, 0), cabinet(1.2, 0));
        // Holding the handle (what the largest voting part did when the body voted for
        // nothing) moves every pose by the handle's move; holding the body, nothing moves.
        let by_handle = origin_shift_holding(&old, &new, "handle").expect("part");
        assert!((by_handle.shift - Vector3::new(0.1, 0.0, 0.0)).norm() < 1e-9);
        let by_body = origin_shift_holding(&old, &new, "body").expect("part");
        assert!(by_body.shift.norm() < 1e-12, "{by_body:?}");
        // A body meshed anew (another segment count): its bounds' centre, which stayed.
        let s = origin_shift_holding(&cabinet(1.0, 8), &cabinet(1.2, 9), "body").expect("part");
        assert!(s.shift.norm() < 1e-9, "{s:?}");
        // Meshed anew and grown from its bottom face up, then moved 0.1 along x: the face
        // that stayed keeps the origin along z; x moved whole.
        let one_sided = |h: f64, x: f64, rings: i64| ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![Part::new(
                "body",
                crate::primitives::cylinder(0.3, h, rings)
                    .expect("body")
                    .translated(Vector3::new(x, 0.0, h / 2.0)),
                [0.5; 3],
            )],
        };
        let s = origin_shift_holding(&one_sided(0.5, 0.0, 16), &one_sided(0.7, 0.1, 20), "body")
            .expect("part");
        assert!(
            (s.shift - Vector3::new(0.1, 0.0, 0.0)).norm() < 1e-9,
            "{s:?}"
        );
        assert!(origin_shift_holding(&old, &new, "lid").is_none());
        // The largest in view, else named, else by surface.
        let held = held_part(&old, &new, None, Some((&[9000, 400], 6))).expect("held");
        assert_eq!(held.name, "body");
        assert!(
            held.why.contains("96%") && held.why.contains("6 keyframe"),
            "{held:?}"
        );
        let held = held_part(&old, &new, None, Some((&[10, 400], 6))).expect("held");
        assert_eq!(held.name, "handle");
        assert_eq!(
            held_part(&old, &new, None, None).expect("held").name,
            "body"
        );
        assert_eq!(
            held_part(&old, &new, Some("handle"), None)
                .expect("held")
                .name,
            "handle"
        );
        let e = held_part(&old, &new, Some("lid"), None).expect_err("no lid");
        assert!(e.contains("`lid`") && e.contains("body, handle"), "{e}");
    }

    #[test]
    fn posed_bounds_follow_joints() {
        let parts = vec![
            Part::new("body", cuboid(1.0, 1.0, 0.2).expect("box"), [0.5; 3]),
            Part::new(
                "lid",
                cuboid(1.0, 1.0, 0.1)
                    .expect("box")
                    .translated(Vector3::new(0.0, 0.0, 0.15)),
                [0.5; 3],
            ),
        ];
        let joint = JointDef {
            name: "hinge".into(),
            kind: JointKind::Revolute,
            parent: None,
            child: vec!["lid".into()],
            origin: Vector3::new(0.0, -0.5, 0.1),
            axis: Vector3::x(),
            limit: Some((0.0, 180.0)),
        };
        let tree = KinematicTree::new(vec![joint], &["body".to_string(), "lid".to_string()])
            .expect("tree");
        let model = ObjectModel { parts, tree };
        let b = model.posed_bounds(&[std::f64::consts::FRAC_PI_2]);
        assert!((b.max.z - 1.1).abs() < 1e-9, "{:?}", b);
    }
}
