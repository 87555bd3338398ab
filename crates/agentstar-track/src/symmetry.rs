//! The discrete turns that map a model's outline onto itself about an axis of its own: the
//! quarter turns of a square prism, the sixth turns of a hexagonal one, with the half-turns
//! about the axes across them. A pose composed with any of them shows the same outline
//! from every view, so the tracker must weigh each as a twin: a print decides between them,
//! the mask cannot.
//!
//! The principal half-turns ([`crate::hypotheses::principal_axes`]) find the twins of a
//! shape whose three second moments differ. Where two are equal (a square cross-section),
//! the moments fix no direction across the third axis: the principal axes there are
//! arbitrary, and their half-turns are no symmetry. The cross-section's own harmonics
//! (`∫ (x + iy)ⁿ` over the solid) do: an n-fold section has no harmonic below the n-th,
//! and the n-th's phase places its axes of symmetry.

use crate::hypotheses::{principal_frame, PrincipalFrame};
use agentstar_geom::nalgebra::{Complex, Unit};
use agentstar_geom::nearest::KdTree;
use agentstar_geom::{ObjectModel, Point3, UnitQuaternion, Vector3};

/// The highest order of turn looked for: an octagonal prism's.
pub const MAX_FOLD: usize = 8;

/// A harmonic of the cross-section weaker than this share of its bound (`|∫ zⁿ| / ∫ |z|ⁿ`)
/// is absent. A small badge on a square prism's face (2% of its surface, a thousandth of
/// its volume) leaves under 0.002 in any; a rectangle 0.9 × 1 leaves 0.10 in the second.
pub const HARMONIC_ABSENT: f64 = 0.02;

/// A harmonic at least this share of its bound is present: a square's fourth is 0.43, a
/// regular octagon's eighth 0.17, a hexagon's sixth 0.24, a 48-sided cylinder's eighth
/// under 10⁻⁴.
pub const HARMONIC_PRESENT: f64 = 0.04;

/// Each triangle's integrals are summed over like triangles it is cut into, `m × m`, so that
/// none is longer than the model's extent over this: the centre of each stands for it (a
/// square's fourth harmonic is then within 0.002 of its exact value).
const CUTS_PER_EXTENT: f64 = 24.0;

/// The most cuts of a triangle's side (a degenerate sliver longer than the model is not cut
/// into more).
const MAX_CUTS: usize = 32;

/// One n-fold axis of a model's outline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fold {
    /// The axis (unit, in the model's canonical frame at the joint states given).
    pub axis: Vector3,
    /// A point on it: the centroid across the axis, the middle of the extent along it.
    pub centre: Point3,
    /// n: the turn by 360°/n maps the outline onto itself.
    pub order: usize,
    /// A direction across the axis about which a half-turn maps the outline onto itself,
    /// where the shape's two ends alike allow it (the others lie every 180°/n from it).
    pub across: Vector3,
}

impl Fold {
    /// The group's elements other than the identity, each as (rotation, centre): the n − 1
    /// turns about the axis and the n half-turns about the directions across it.
    pub fn turns(&self) -> Vec<(UnitQuaternion, Point3)> {
        let n = self.order;
        let axis = Unit::new_normalize(self.axis);
        let mut out: Vec<(UnitQuaternion, Point3)> = (1..n)
            .map(|j| {
                let angle = std::f64::consts::TAU * j as f64 / n as f64;
                (UnitQuaternion::from_axis_angle(&axis, angle), self.centre)
            })
            .collect();
        out.extend((0..n).map(|j| {
            let angle = std::f64::consts::PI * j as f64 / n as f64;
            let across = UnitQuaternion::from_axis_angle(&axis, angle) * self.across;
            (
                UnitQuaternion::from_axis_angle(&Unit::new_normalize(across), std::f64::consts::PI),
                self.centre,
            )
        }));
        out
    }
}

/// The n-fold axes (3 ≤ n ≤ [`MAX_FOLD`]) of the posed model's outline: principal axes, or
/// normals of its large flat faces, across which the cross-section's harmonics vanish below
/// the n-th and the n-th does not, and whose turns each map the surface onto itself
/// ([`MAPPED_SHARE`] of it). A round body (no harmonic up to [`MAX_FOLD`]) has none here:
/// every turn about its axis is a symmetry of the outline, which the axis pass
/// ([`crate::axis`]) searches.
pub fn folds(model: &ObjectModel, states: &[f64]) -> Vec<Fold> {
    let Some(frame) = principal_frame(model, states) else {
        return Vec::new();
    };
    let transforms = model.tree.part_transforms(states);
    // The longest cut a triangle's integrals allow: the extent of the model's posed vertices.
    let extent = model.posed_bounds(states).extent().norm();
    if !(extent > 0.0 && extent.is_finite()) {
        return Vec::new();
    }
    let cut = extent / CUTS_PER_EXTENT;
    // The axes whose sections are tried: the principal axes, and the normals of the model's
    // large flat faces. Where all three moments are equal (a cube) the principal axes are
    // any three, and only the faces say where the box's own axes lie.
    let mut axes: Vec<Vector3> = frame.axes.to_vec();
    for normal in face_axes(model, &transforms) {
        if axes.iter().all(|a| a.dot(&normal).abs() < SAME_AXIS_COS) {
            axes.push(normal);
        }
    }
    let mut out: Vec<Fold> = Vec::new();
    let mut surface: Option<Surface> = None;
    let mut splits = Splits::default();
    for axis in axes {
        let e1 = axis.cross(&frame.axes[2]);
        let e1 = if e1.norm() > 0.5 {
            e1
        } else {
            axis.cross(&frame.axes[1])
        }
        .normalize();
        let e2 = axis.cross(&e1);
        let harmonics =
            section_harmonics(model, &transforms, &frame, axis, (e1, e2), cut, &mut splits);
        let strength: Vec<f64> = harmonics
            .iter()
            .map(|(sum, bound)| {
                if *bound > 0.0 {
                    sum.norm() / bound
                } else {
                    0.0
                }
            })
            .collect();
        // strength[n − 1] is the n-th harmonic's.
        let Some(order) = (3..=MAX_FOLD).find(|&n| {
            strength[n - 1] >= HARMONIC_PRESENT
                && strength[..n - 1].iter().all(|&h| h < HARMONIC_ABSENT)
        }) else {
            continue;
        };
        // The n-th harmonic of a section symmetric about the direction at angle φ is
        // real along it: its phase is n·φ (mod π, as either sign of the real part).
        let phase = harmonics[order - 1].0.arg() / order as f64;
        let across = e1 * phase.cos() + e2 * phase.sin();
        // The middle of the posed vertices' extent along the axis.
        let (lo, hi) = model.parts.iter().zip(&transforms).fold(
            (f64::INFINITY, f64::NEG_INFINITY),
            |(lo, hi), (part, t)| {
                part.mesh.positions.iter().fold((lo, hi), |(lo, hi), p| {
                    let d = (t * p - frame.centroid).dot(&axis);
                    (lo.min(d), hi.max(d))
                })
            },
        );
        let fold = Fold {
            axis,
            centre: frame.centroid + axis * (0.5 * (lo + hi)),
            order,
            across,
        };
        // The harmonics of the solid's thickness across an axis are a test the true axes
        // pass and some others too (a cube's about any axis): each turn must also map the
        // surface onto itself.
        let surface = surface
            .get_or_insert_with(|| Surface::sample(model, &transforms, extent, cut, &mut splits));
        if fold.turns().iter().all(|t| surface.maps_onto_itself(t)) {
            out.push(fold);
        }
    }
    out
}

/// Two axes within 10° of each other are one.
const SAME_AXIS_COS: f64 = 0.985;

/// A flat face counts as large ([`face_axes`]) from this share of the model's surface.
const LARGE_FACE_SHARE: f64 = 0.1;

/// The most face directions [`face_axes`] keeps apart: a curved surface's triangles each
/// face their own way, and past this many new directions are not counted.
const MAX_FACE_DIRECTIONS: usize = 64;

/// The normals (sign aside) of the posed model's large flat faces ([`LARGE_FACE_SHARE`] of
/// its surface or more, triangles within 10° of one direction together), largest first, at
/// most three.
fn face_axes(model: &ObjectModel, transforms: &[agentstar_geom::pose::Rigid]) -> Vec<Vector3> {
    // (area-weighted sum of the normals, each turned to the first's side; area)
    let mut directions: Vec<(Vector3, f64)> = Vec::new();
    let mut total = 0.0;
    for (_, area_vector, area) in posed_triangles(model, transforms) {
        total += area;
        let normal = area_vector / area;
        let found = directions
            .iter_mut()
            .find(|(sum, _)| sum.normalize().dot(&normal).abs() >= SAME_AXIS_COS);
        if let Some((sum, weight)) = found {
            let sign = sum.dot(&normal).signum();
            *sum += normal * (sign * area);
            *weight += area;
        } else if directions.len() < MAX_FACE_DIRECTIONS {
            directions.push((normal * area, area));
        }
    }
    directions.sort_by(|a, b| b.1.total_cmp(&a.1));
    directions
        .into_iter()
        .filter(|(_, area)| *area >= LARGE_FACE_SHARE * total)
        .take(3)
        .map(|(sum, _)| sum.normalize())
        .collect()
}

/// The share of the surface (by area) that a turn must put back on the surface
/// ([`Surface::maps_onto_itself`]) to count as a symmetry of the outline: a badge or a knob
/// (a few percent) may land anywhere.
const MAPPED_SHARE: f64 = 0.9;

/// The most points [`Surface::maps_onto_itself`] moves for one turn.
const MAX_CHECKED: usize = 2000;

/// Points spread over the posed model's surface by area, with a tree to find the nearest:
/// what [`folds`] checks a turn against.
struct Surface {
    /// (point, area it stands for)
    points: Vec<(Point3, f64)>,
    nearest: KdTree,
    /// The distance within which a moved point is on the surface: 2% of the model's extent,
    /// or the points' spacing where that is larger.
    tolerance: f64,
}

impl Surface {
    fn sample(
        model: &ObjectModel,
        transforms: &[agentstar_geom::pose::Rigid],
        extent: f64,
        cut: f64,
        splits: &mut Splits,
    ) -> Surface {
        let mut points = Vec::new();
        let mut spacing: f64 = 0.0;
        for ([a, b, c], _, area) in posed_triangles(model, transforms) {
            let (m, centres) = splits.of(&[a, b, c], cut);
            spacing = spacing.max(longest_side(&[a, b, c]) / m as f64);
            let share = area / centres.len() as f64;
            points.extend(
                centres
                    .iter()
                    .map(|&(u, v)| (Point3::from(a + (b - a) * u + (c - a) * v), share)),
            );
        }
        let cloud: Vec<Point3> = points.iter().map(|(p, _)| *p).collect();
        Surface {
            nearest: KdTree::new(&cloud),
            points,
            tolerance: (SURFACE_TOLERANCE * extent).max(spacing),
        }
    }

    /// Whether `(q, c)` puts at least [`MAPPED_SHARE`] of the surface back on it (at most
    /// [`MAX_CHECKED`] points moved, spread over the surface).
    fn maps_onto_itself(&self, (q, c): &(UnitQuaternion, Point3)) -> bool {
        let step = self.points.len().div_ceil(MAX_CHECKED).max(1);
        let checked = self.points.iter().step_by(step);
        let all: f64 = checked.clone().map(|(_, area)| area).sum();
        // Stops at the first point that puts the share off the surface over the allowance.
        let mut off = 0.0;
        for (p, area) in checked {
            let moved = c + q * (p - c);
            if self.nearest.nearest_distance(&moved) > self.tolerance {
                off += area;
                if off > (1.0 - MAPPED_SHARE) * all {
                    return false;
                }
            }
        }
        all > 0.0
    }
}

/// A turn's moved surface points count as on the surface within this share of the model's
/// extent ([`Surface`]).
const SURFACE_TOLERANCE: f64 = 0.02;

/// The barycentric centres of each split of a triangle used so far ([`split_centres`]),
/// made once for all the triangles and axes of one [`folds`].
#[derive(Default)]
struct Splits(Vec<Vec<(f64, f64)>>);

impl Splits {
    /// The split of triangle `corners` that leaves no side longer than `cut` (at most
    /// [`MAX_CUTS`] cuts a side): `m` and its centres.
    fn of(&mut self, corners: &[Vector3; 3], cut: f64) -> (usize, &[(f64, f64)]) {
        let m = ((longest_side(corners) / cut).ceil() as usize).clamp(1, MAX_CUTS);
        while self.0.len() < m {
            self.0.push(split_centres(self.0.len() + 1));
        }
        (m, &self.0[m - 1])
    }
}

fn longest_side([a, b, c]: &[Vector3; 3]) -> f64 {
    (b - a).norm().max((c - b).norm()).max((a - c).norm())
}

/// The posed model's triangles with a positive, finite area: corners (posed), the area
/// vector (half the cross product, along the outward normal) and the area.
fn posed_triangles<'m>(
    model: &'m ObjectModel,
    transforms: &'m [agentstar_geom::pose::Rigid],
) -> impl Iterator<Item = ([Vector3; 3], Vector3, f64)> + 'm {
    model.parts.iter().zip(transforms).flat_map(|(part, t)| {
        let mesh = &part.mesh;
        mesh.triangles.iter().filter_map(move |tri| {
            let [a, b, c] = tri.map(|k| (t * mesh.positions[k as usize]).coords);
            let area_vector = 0.5 * (b - a).cross(&(c - a));
            let area = area_vector.norm();
            (area > 0.0 && area.is_finite()).then_some(([a, b, c], area_vector, area))
        })
    })
}

/// Barycentric centres of the m² like triangles a triangle splits into: the upright ones
/// (i + j ≤ m − 1) and the inverted ones (i + j ≤ m − 2).
fn split_centres(m: usize) -> Vec<(f64, f64)> {
    let f = m as f64;
    let mut centres = Vec::with_capacity(m * m);
    for i in 0..m {
        for j in 0..m - i {
            centres.push(((i as f64 + 1.0 / 3.0) / f, (j as f64 + 1.0 / 3.0) / f));
            if i + j + 2 <= m {
                centres.push(((i as f64 + 2.0 / 3.0) / f, (j as f64 + 2.0 / 3.0) / f));
            }
        }
    }
    centres
}

/// Every non-trivial turn of [`folds`]: what [`crate::hypotheses::twin_candidates`] adds to
/// the flips and principal half-turns.
pub fn fold_turns(model: &ObjectModel, states: &[f64]) -> Vec<(UnitQuaternion, Point3)> {
    folds_remembered(model, states)
        .iter()
        .flat_map(Fold::turns)
        .collect()
}

/// The models and joint states [`folds_remembered`] keeps the folds of.
const REMEMBERED: usize = 64;

/// [`folds`], remembered for the last [`REMEMBERED`] models and joint states it was asked
/// about: every pass of the tracker asks again for each frame's twins, and a rigid model's
/// folds never change.
fn folds_remembered(model: &ObjectModel, states: &[f64]) -> Vec<Fold> {
    use std::hash::{Hash, Hasher};
    static MEMORY: std::sync::Mutex<Vec<(u64, Vec<Fold>)>> = std::sync::Mutex::new(Vec::new());
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    for s in states {
        s.to_bits().hash(&mut hasher);
    }
    for part in &model.parts {
        part.mesh.triangles.hash(&mut hasher);
        for p in &part.mesh.positions {
            [p.x, p.y, p.z].map(f64::to_bits).hash(&mut hasher);
        }
    }
    for t in model.tree.part_transforms(states) {
        t.to_homogeneous()
            .iter()
            .for_each(|v| v.to_bits().hash(&mut hasher));
    }
    let key = hasher.finish();
    if let Ok(memory) = MEMORY.lock() {
        if let Some((_, found)) = memory.iter().find(|(k, _)| *k == key) {
            return found.clone();
        }
    }
    let found = folds(model, states);
    if let Ok(mut memory) = MEMORY.lock() {
        if memory.len() >= REMEMBERED {
            memory.remove(0);
        }
        memory.push((key, found.clone()));
    }
    found
}

/// `(∫ zⁿ, ∫ |z|ⁿ)` for n = 1..=[`MAX_FOLD`], z = x + iy the offset across `axis` from the
/// centroid in the basis `across`. Over the solid where the moments are the solid's (by the
/// divergence theorem, `∫_V f dV = ∮ t f n_t dA` with t the coordinate along the axis: a thin
/// print adds its volume, not its area), over the surface otherwise.
fn section_harmonics(
    model: &ObjectModel,
    transforms: &[agentstar_geom::pose::Rigid],
    frame: &PrincipalFrame,
    axis: Vector3,
    (e1, e2): (Vector3, Vector3),
    cut: f64,
    splits: &mut Splits,
) -> [(Complex<f64>, f64); MAX_FOLD] {
    let mut acc = [(Complex::new(0.0, 0.0), 0.0); MAX_FOLD];
    for ([a, b, c], area_vector, area) in posed_triangles(model, transforms) {
        let (_, centres) = splits.of(&[a, b, c], cut);
        let share = 1.0 / centres.len() as f64;
        for &(u, v) in centres {
            let d = a + (b - a) * u + (c - a) * v - frame.centroid.coords;
            let weight = if frame.solid {
                d.dot(&axis) * area_vector.dot(&axis) * share
            } else {
                area * share
            };
            let z = Complex::new(d.dot(&e1), d.dot(&e2));
            let r = z.norm();
            let (mut power, mut radius) = (Complex::new(1.0, 0.0), 1.0);
            for slot in acc.iter_mut() {
                power *= z;
                radius *= r;
                slot.0 += power * weight;
                slot.1 += radius * weight;
            }
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::primitives::{cuboid, cylinder};
    use agentstar_geom::{KinematicTree, Part};

    fn model_of(parts: Vec<Part>) -> ObjectModel {
        ObjectModel {
            tree: KinematicTree::rigid(parts.len()),
            parts,
        }
    }

    /// The largest distance from a moved vertex to the nearest of the original ones.
    fn vertex_mismatch(model: &ObjectModel, (q, c): &(UnitQuaternion, Point3)) -> f64 {
        let points: Vec<Point3> = model
            .parts
            .iter()
            .flat_map(|p| p.mesh.positions.iter().copied())
            .collect();
        points
            .iter()
            .map(|p| {
                let moved = c + q * (p - c);
                points
                    .iter()
                    .map(|o| (o - moved).norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_square_prism_turned_anyhow_has_four_quarter_turns_and_four_half_turns_across() {
        // A box 0.8 × 0.8 × 1 turned 20° about its long axis and moved off the origin: its
        // second moments across the axis are equal, so the principal axes there fix nothing.
        let turned = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 20f64.to_radians());
        let mesh = cuboid(0.8, 0.8, 1.0).expect("box").transformed(
            turned.to_rotation_matrix().matrix(),
            &Vector3::new(0.1, -0.2, 0.3),
        );
        let model = model_of(vec![Part::new("body", mesh, [0.5, 0.5, 0.5])]);
        let folds = folds(&model, &[]);
        assert_eq!(folds.len(), 1, "{folds:?}");
        let fold = folds[0];
        assert_eq!(fold.order, 4);
        assert!(
            fold.axis.cross(&Vector3::z()).norm() < 1e-6,
            "{:?}",
            fold.axis
        );
        let turns = fold.turns();
        assert_eq!(turns.len(), 7);
        for t in &turns {
            let off = vertex_mismatch(&model, t);
            assert!(off < 1e-6, "{:?} moves a corner {off}", t.0);
        }
    }

    #[test]
    fn a_cube_turned_anyhow_has_its_three_quarter_turn_axes_from_its_faces() {
        // All three second moments equal: the principal axes are any three, and only the
        // faces say where the cube's own axes lie. Every fold found maps corners on corners.
        let turned = UnitQuaternion::from_axis_angle(
            &Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)),
            37f64.to_radians(),
        );
        let mesh = cuboid(1.0, 1.0, 1.0)
            .expect("cube")
            .transformed(turned.to_rotation_matrix().matrix(), &Vector3::zeros());
        let model = model_of(vec![Part::new("body", mesh, [0.5, 0.5, 0.5])]);
        let found = folds(&model, &[]);
        assert_eq!(found.len(), 3, "{found:?}");
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            let axis = turned * axis;
            assert!(
                found
                    .iter()
                    .any(|f| f.order == 4 && f.axis.cross(&axis).norm() < 1e-6),
                "no quarter turns about {axis:?}: {found:?}"
            );
        }
        for f in &found {
            for t in f.turns() {
                let off = vertex_mismatch(&model, &t);
                assert!(off < 1e-6, "{:?} moves a corner {off}", t.0);
            }
        }
    }

    #[test]
    fn prisms_of_three_six_and_eight_sides_have_their_order_and_a_cylinder_none() {
        for sides in [3usize, 6, 8] {
            let mesh = cylinder(0.5, 0.6, sides as i64).expect("prism");
            let model = model_of(vec![Part::new("body", mesh, [0.5, 0.5, 0.5])]);
            let folds = folds(&model, &[]);
            assert_eq!(folds.len(), 1, "{sides} sides: {folds:?}");
            assert_eq!(folds[0].order, sides, "{sides} sides");
            for t in folds[0].turns() {
                let off = vertex_mismatch(&model, &t);
                assert!(off < 1e-6, "{sides} sides: {:?} moves a corner {off}", t.0);
            }
        }
        let round = cylinder(0.5, 0.6, 48).expect("cylinder");
        assert!(folds(&model_of(vec![Part::new("body", round, [0.5; 3])]), &[]).is_empty());
    }

    #[test]
    fn a_badge_does_not_hide_the_symmetry_and_a_rectangle_has_none() {
        // A thin badge on one face of a square prism: its volume is a thousandth of the
        // body's, so the quarter turns stay (the print tells them apart; the outline cannot).
        let body = cuboid(0.829, 0.829, 1.0).expect("box");
        let badge = cuboid(0.005, 0.172, 0.268)
            .expect("badge")
            .translated(Vector3::new(0.418, 0.158, 0.153));
        let disc = cylinder(0.262, 0.005, 48)
            .expect("disc")
            .translated(Vector3::new(0.0, 0.0, 0.5035));
        let model = model_of(vec![
            Part::new("body", body, [0.2, 0.3, 0.3]),
            Part::new("badge", badge, [0.4, 0.3, 0.6]),
            Part::new("top", disc, [0.5, 0.6, 0.7]),
        ]);
        let found = folds(&model, &[]);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].order, 4);
        // A section 0.9 × 1: a rectangle's twins are the principal half-turns alone.
        let oblong = cuboid(0.9, 1.0, 0.6).expect("box");
        assert!(folds(&model_of(vec![Part::new("body", oblong, [0.5; 3])]), &[]).is_empty());
    }
}
