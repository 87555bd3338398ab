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

/// The n-fold axes (3 ≤ n ≤ [`MAX_FOLD`]) of the posed model's outline: principal axes
/// across which the cross-section's harmonics vanish below the n-th and the n-th does not.
/// A round body (no harmonic up to [`MAX_FOLD`]) has none here: every turn about its axis
/// is a symmetry of the outline, which the axis pass ([`crate::axis`]) searches.
pub fn folds(model: &ObjectModel, states: &[f64]) -> Vec<Fold> {
    let Some(frame) = principal_frame(model, states) else {
        return Vec::new();
    };
    let transforms = model.tree.part_transforms(states);
    // The longest cut a triangle's integrals allow: the extent of the model's posed vertices.
    let (lo, hi) = model.parts.iter().zip(&transforms).fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), (part, t)| {
            part.mesh.positions.iter().fold((lo, hi), |(lo, hi), p| {
                let q = (t * p).coords;
                (lo.inf(&q), hi.sup(&q))
            })
        },
    );
    let extent = (hi - lo).norm();
    if !(extent > 0.0 && extent.is_finite()) {
        return Vec::new();
    }
    let cut = extent / CUTS_PER_EXTENT;
    let mut out = Vec::new();
    for k in 0..3 {
        let axis = frame.axes[k];
        let (e1, e2) = (frame.axes[(k + 1) % 3], frame.axes[(k + 2) % 3]);
        let harmonics = section_harmonics(model, &transforms, &frame, axis, (e1, e2), cut);
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
        let along = (frame.middle - frame.centroid).dot(&axis);
        out.push(Fold {
            axis,
            centre: frame.centroid + axis * along,
            order,
            across,
        });
    }
    out
}

/// Every non-trivial turn of [`folds`]: what [`crate::hypotheses::twin_candidates`] adds to
/// the flips and principal half-turns.
pub fn fold_turns(model: &ObjectModel, states: &[f64]) -> Vec<(UnitQuaternion, Point3)> {
    folds(model, states).iter().flat_map(Fold::turns).collect()
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
) -> [(Complex<f64>, f64); MAX_FOLD] {
    let mut acc = [(Complex::new(0.0, 0.0), 0.0); MAX_FOLD];
    // Barycentric centres of the m² like triangles a triangle splits into, for each m used:
    // the upright ones (i + j ≤ m − 1) and the inverted ones (i + j ≤ m − 2).
    let mut splits: Vec<Vec<(f64, f64)>> = Vec::new();
    let centres_of = |m: usize, splits: &mut Vec<Vec<(f64, f64)>>| {
        while splits.len() < m {
            let k = splits.len() + 1;
            let f = k as f64;
            let mut centres = Vec::with_capacity(k * k);
            for i in 0..k {
                for j in 0..k - i {
                    centres.push(((i as f64 + 1.0 / 3.0) / f, (j as f64 + 1.0 / 3.0) / f));
                    if i + j + 2 <= k {
                        centres.push(((i as f64 + 2.0 / 3.0) / f, (j as f64 + 2.0 / 3.0) / f));
                    }
                }
            }
            splits.push(centres);
        }
    };
    for (part, t) in model.parts.iter().zip(transforms) {
        let mesh = &part.mesh;
        for tri in &mesh.triangles {
            let [a, b, c] = tri.map(|k| (t * mesh.positions[k as usize]).coords);
            let area_vector = 0.5 * (b - a).cross(&(c - a));
            let area = area_vector.norm();
            if !(area > 0.0 && area.is_finite()) {
                continue;
            }
            let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
            let m = ((longest / cut).ceil() as usize).clamp(1, MAX_CUTS);
            centres_of(m, &mut splits);
            let centres = &splits[m - 1];
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
