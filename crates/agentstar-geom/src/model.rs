//! The object model: named parts (meshes in the canonical rest frame, each with a colour)
//! and the kinematic tree that moves them, plus the canonical-frame report.

use crate::kinematics::KinematicTree;
use crate::mesh::{Aabb, TriMesh};
use crate::pose::Rigid;
use crate::Point3;
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
}

impl Part {
    pub fn new(name: impl Into<String>, mesh: TriMesh, color: [f32; 3]) -> Part {
        let edges = if mesh.volume() > 0.0 {
            mesh.manifold_edges().map(Arc::new)
        } else {
            None
        };
        let watertight = edges.is_some();
        let bounds = mesh.bounds();
        Part {
            name: name.into(),
            mesh: Arc::new(mesh),
            color,
            watertight,
            bounds,
            edges,
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

    /// Measures the canonical-frame convention at rest.
    pub fn canonical_report(&self) -> CanonicalReport {
        let b = self.posed_bounds(&self.tree.rest_states());
        let ext = b.extent();
        let center = if b.is_empty() {
            Point3::origin()
        } else {
            b.center()
        };
        let longest = ext.max();
        let mut warnings = Vec::new();
        if b.is_empty() {
            warnings.push("the model has no geometry".into());
        } else {
            if center.coords.norm() > 0.05 * longest.max(1e-9) {
                warnings.push(format!(
                    "bounding-box centre ({:.3}, {:.3}, {:.3}) is off the origin by {:.3} (more than 5% of the longest side); centre the model",
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
