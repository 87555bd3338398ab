//! Parts hidden inside other parts: a part whose whole surface lies inside another part's
//! closed mesh never shows in an image (its colour and shape cannot be checked against the
//! frames), which is almost always a modelling mistake (a label a hair smaller than its can,
//! a knob sunk into a door). Insideness is the generalised winding number of the closed
//! mesh about a point, summed solid angles of its triangles (exact for a closed mesh, and
//! robust where a closed mesh has tiny gaps).

use crate::mesh::{Aabb, TriMesh};
use crate::model::ObjectModel;
use crate::pose::Rigid;
use crate::Point3;

/// Points of a part's surface a test samples, at most: every vertex and every triangle's
/// centroid, thinned evenly to this many.
const MAX_SAMPLES: usize = 256;

/// A point counts as inside where the winding number is over this: 1 strictly inside an
/// outward closed mesh, 0 outside, ½ on its surface. A part flush with its container (a
/// drawer front in the cabinet's face) samples points on the surface, which stay under it.
const INSIDE_WINDING: f64 = 0.75;

/// The generalised winding number of `mesh` (placed by `placed`) about `p`: the solid
/// angle its triangles subtend at `p` over 4π (Van Oosterom and Strackee's formula), signed
/// by their orientation. For a closed outward mesh: 1 inside, 0 outside.
pub fn winding_number(mesh: &TriMesh, placed: &Rigid, p: &Point3) -> f64 {
    let mut total = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = [0, 1, 2].map(|k| placed * mesh.positions[t[k] as usize] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        if la < 1e-15 || lb < 1e-15 || lc < 1e-15 {
            // On a vertex: on the surface.
            return 0.5;
        }
        let numerator = a.dot(&b.cross(&c));
        let denominator = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        if numerator.abs() <= 1e-12 * la * lb * lc && denominator <= 0.0 {
            // In the triangle's plane, within it (its solid angle is ±2π, either sign): on
            // the surface.
            return 0.5;
        }
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// The surface samples of `mesh` placed by `placed`: vertices used by a triangle and
/// triangle centroids, thinned evenly to [`MAX_SAMPLES`].
fn samples(mesh: &TriMesh, placed: &Rigid) -> Vec<Point3> {
    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    let mut points: Vec<Point3> = mesh
        .positions
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(p, _)| *p)
        .collect();
    points.extend(mesh.triangles.iter().map(|t| {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize].coords);
        Point3::from((a + b + c) / 3.0)
    }));
    let stride = points.len().div_ceil(MAX_SAMPLES).max(1);
    points
        .into_iter()
        .step_by(stride)
        .map(|p| placed * p)
        .collect()
}

/// The joint states a hidden part is checked at: rest, and each joint with a limit at its
/// lower and its upper limit (the others at rest). A part hidden at rest that comes out when
/// its joint moves (a closed drawer) is not hidden.
fn configurations(model: &ObjectModel) -> Vec<Vec<f64>> {
    let rest = model.tree.rest_states();
    let mut out = vec![rest.clone()];
    for (j, jd) in model.tree.joints().iter().enumerate() {
        if !jd.kind.has_state() {
            continue;
        }
        if let Some((lo, hi)) = jd.limit {
            for v in [lo, hi] {
                let mut s = rest.clone();
                s[j] = jd.to_internal(v);
                out.push(s);
            }
        }
    }
    out
}

/// The parts hidden inside another: `(hidden, container)` part indices, where every
/// sampled point of `hidden`'s surface lies inside `container`'s closed mesh at every
/// configuration ([`configurations`]). Only watertight containers are tested (an open
/// surface has no inside); each hidden part is named once, with the first container found.
pub fn hidden_parts(model: &ObjectModel) -> Vec<(usize, usize)> {
    let configs = configurations(model);
    let placed: Vec<Vec<Rigid>> = configs
        .iter()
        .map(|s| model.tree.part_transforms(s))
        .collect();
    let mut out = Vec::new();
    for (h, part) in model.parts.iter().enumerate() {
        if part.mesh.triangles.is_empty() {
            continue;
        }
        let container = model.parts.iter().enumerate().find(|&(c, outer)| {
            c != h
                && outer.watertight
                && placed.iter().all(|t| {
                    let (th, tc) = (&t[h], &t[c]);
                    let points = samples(&part.mesh, th);
                    // The container's rest bounds placed (corners: a box around it); a
                    // sample outside that box is outside the container.
                    let (lo, hi) = (outer.bounds.min, outer.bounds.max);
                    let corners: Vec<Point3> = (0..8)
                        .map(|k| {
                            tc * Point3::new(
                                if k & 1 == 0 { lo.x } else { hi.x },
                                if k & 2 == 0 { lo.y } else { hi.y },
                                if k & 4 == 0 { lo.z } else { hi.z },
                            )
                        })
                        .collect();
                    let around = Aabb::from_points(&corners);
                    points.iter().all(|p| around.contains(p))
                        && points
                            .iter()
                            .all(|p| winding_number(&outer.mesh, tc, p).abs() > INSIDE_WINDING)
                })
        });
        if let Some((c, _)) = container {
            out.push((h, c));
        }
    }
    out
}

/// The warning for each part hidden inside another ([`hidden_parts`]).
pub fn hidden_part_warnings(model: &ObjectModel) -> Vec<String> {
    hidden_parts(model)
        .into_iter()
        .map(|(h, c)| {
            let (h, c) = (&model.parts[h].name, &model.parts[c].name);
            format!(
                "part `{h}` lies entirely inside part `{c}` (every sampled point of its surface is inside `{c}`'s closed surface, at rest and at each joint's limits): it never shows in an image, so its shape and colour cannot be seen; make it stand out of `{c}` where it should show (a label a little larger than its can) or remove it"
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{JointDef, JointKind, KinematicTree};
    use crate::model::Part;
    use crate::primitives::{cuboid, cylinder};
    use crate::Vector3;

    fn model(parts: Vec<Part>, tree: KinematicTree) -> ObjectModel {
        ObjectModel { parts, tree }
    }

    #[test]
    fn the_winding_number_tells_inside_from_outside_and_the_surface() {
        let b = cuboid(1.0, 1.0, 1.0).expect("box");
        let id = Rigid::identity();
        assert!((winding_number(&b, &id, &Point3::new(0.1, -0.2, 0.3)) - 1.0).abs() < 1e-9);
        assert!(winding_number(&b, &id, &Point3::new(0.9, 0.0, 0.0)).abs() < 1e-9);
        let on = winding_number(&b, &id, &Point3::new(0.5, 0.1, 0.2));
        assert!((on - 0.5).abs() < 1e-6, "{on}");
        // Placed elsewhere, the inside moves with it.
        let moved = Rigid::translation(2.0, 0.0, 0.0);
        assert!((winding_number(&b, &moved, &Point3::new(2.1, 0.0, 0.0)) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_label_inside_its_can_is_named_and_one_around_it_is_not() {
        let can = || Part::new("can", cylinder(0.5, 1.0, 32).expect("can"), [0.5; 3]);
        let label = |r: f64| Part::new("label", cylinder(r, 0.4, 32).expect("label"), [0.9; 3]);
        let rigid = KinematicTree::rigid(2);
        let inside = model(vec![can(), label(0.45)], rigid.clone());
        assert_eq!(hidden_parts(&inside), [(1, 0)]);
        let w = hidden_part_warnings(&inside);
        assert!(w[0].contains("`label`") && w[0].contains("`can`"), "{w:?}");
        // A label a little larger than its can shows: no warning; nor for the can, which
        // sticks out of the label at both ends.
        let around = model(vec![can(), label(0.51)], rigid.clone());
        assert!(hidden_parts(&around).is_empty());
        // Flush with the can (the same radius, inside its height): on the surface, shown.
        let flush = model(vec![can(), label(0.5)], rigid);
        assert!(
            hidden_parts(&flush).is_empty(),
            "{:?}",
            hidden_parts(&flush)
        );
    }

    #[test]
    fn a_part_that_slides_out_on_its_joint_is_not_hidden() {
        let body = Part::new("body", cuboid(1.0, 1.0, 1.0).expect("box"), [0.5; 3]);
        let drawer = Part::new("drawer", cuboid(0.6, 0.6, 0.3).expect("box"), [0.8; 3]);
        let slide = |limit: (f64, f64)| {
            KinematicTree::new(
                vec![JointDef {
                    name: "slide".into(),
                    kind: JointKind::Prismatic,
                    parent: None,
                    child: vec!["drawer".into()],
                    origin: Vector3::zeros(),
                    axis: Vector3::x(),
                    limit: Some(limit),
                }],
                &["body".into(), "drawer".into()],
            )
            .expect("tree")
        };
        let m = model(vec![body.clone(), drawer.clone()], slide((0.0, 0.8)));
        assert!(hidden_parts(&m).is_empty());
        // A slide too short to bring it out: hidden all the same.
        let m = model(vec![body, drawer], slide((0.0, 0.1)));
        assert_eq!(hidden_parts(&m), [(1, 0)]);
    }
}
