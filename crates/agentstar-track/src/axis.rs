//! The angle about a round body's axis, chosen for the whole sequence at once.
//!
//! A can, a bottle, a jar: every turn about the axis of the outline keeps the silhouette,
//! so the masks fix everything but that one angle, and only the colours fix it; a mug's
//! body too, in the frames whose turns keep its handle where the mask has it (or hidden).
//! The axis is found from the model's footprint along it ([`body_axis`]). One frame's
//! colours fix it weakly (a label seen face on has its edges at the limbs), while two
//! neighbouring frames' colours fix their *relative* angle well (the print carried from one
//! into the other) and say nothing of the absolute one: a block of frames turned alike
//! agrees with itself. Together they are a chain over the frames: per frame and angle `θ`,
//! the frame's colours against the model's own (`u_i(θ)`, a label part where the pose puts
//! it), and per step the colours of the two frames against each other (`p_i(θ_i − θ_{i−1})`;
//! a turn of both frames alike carries every pixel to the same place, so the step depends on
//! the difference alone). The best turns of all frames together, by dynamic programming over
//! a grid of angles (exact on the grid), replace a frame-by-frame settling that carried one
//! frame's small error into the next and could not move a block as a whole.
//!
//! No I/O; the tracker applies the turns and checks them on the masks.

use crate::appearance::{
    appearance_each, appearance_pooled, model_agreement, model_has_appearance, AppearanceConfig,
    AppearanceFrame, ReferenceView,
};
use crate::hypotheses::principal_axes;
use crate::sequence::{cheapest_path, cheapest_path_bent};
use crate::temporal::signed_deg;
use crate::update::{apply_object_rotation, GenPose};
use agentstar_geom::nalgebra::Unit;
use agentstar_geom::{ObjectModel, Point3, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// An axis of the model (canonical frame) and a point on it: a round body's
/// ([`body_axis`]), or one the caller names (the tracker's turns about principal axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SymmetryAxis {
    pub centre: Point3,
    pub axis: Vector3,
}

impl SymmetryAxis {
    /// `pose` turned by `deg` about the axis (in the object's frame).
    pub fn turn(&self, pose: &GenPose, scale: f64, deg: f64) -> GenPose {
        GenPose {
            pose: apply_object_rotation(
                &pose.pose,
                scale,
                &self.centre,
                &UnitQuaternion::from_axis_angle(&Unit::new_normalize(self.axis), deg.to_radians()),
            ),
            states: pose.states.clone(),
        }
    }

    /// `pose` with its turn about the axis set back to `base`'s: the object-frame turn from
    /// `base` to `pose` less its twist about the axis (its swing), the axis's line kept
    /// where `pose` puts it. For a round outline the silhouette is unchanged.
    pub fn without_twist(&self, base: &GenPose, pose: &GenPose, scale: f64) -> GenPose {
        let turn = base.pose.rotation.inverse() * pose.pose.rotation;
        let twist = twist_deg(&turn, &self.axis);
        if twist == 0.0 {
            return pose.clone();
        }
        self.turn(pose, scale, -twist)
    }
}

/// The part of `turn` about `axis` (degrees, signed, in (−180°, 180°]: the twist of a
/// swing-twist decomposition); 0 for a zero axis.
pub fn twist_deg(turn: &UnitQuaternion, axis: &Vector3) -> f64 {
    let Some(a) = axis.try_normalize(1e-12) else {
        return 0.0;
    };
    let q = turn.as_ref();
    let along = q.imag().dot(&a);
    signed_deg(2.0 * along.atan2(q.w).to_degrees())
}

/// The angle of `turn` (radians) once its part about `axis` is taken out (the swing of a
/// swing-twist decomposition): a turn about the axis alone gives 0, a tilt across it its
/// own angle. A zero axis leaves the whole turn.
pub fn angle_across(turn: &UnitQuaternion, axis: &Vector3) -> f64 {
    let Some(a) = Unit::try_new(*axis, 1e-12) else {
        return turn.angle();
    };
    // A half-turn across the axis has no twist (0): the whole turn is left.
    (turn * UnitQuaternion::from_axis_angle(&a, twist_deg(turn, axis).to_radians()).inverse())
        .angle()
}

/// Turns that test an axis: not a multiple of 360°/n for small n, so a box's 90° symmetry
/// does not pass for a continuous one. A regular hexagon's footprint keeps 0.92 under them
/// and an octagon's 0.97: prisms that near round count as round bodies, and the tracker's
/// per-frame IoU check keeps only the turns their outline allows.
const TEST_TURNS_DEG: [f64; 4] = [50.0, 130.0, 230.0, 310.0];
/// Cells across the model's footprint along an axis ([`body_axis`]): for the axis's
/// centre and score, and while its direction is searched.
const FOOTPRINT_CELLS: usize = 64;
const COARSE_CELLS: usize = 32;
/// A footprint this far under [`BODY_IOU`] along a principal axis is not searched for a
/// tilt (a mug's, 6° off its body's, scores 0.84; a square's 0.71).
const TILT_SEARCH_BELOW: f64 = 0.1;
/// A principal axis whose footprint keeps this IoU is the body's axis as it is, not tilted.
const ROUND_IOU: f64 = 0.95;
/// A footprint whose turns about its best centre keep at least this IoU with it (mean over
/// [`TEST_TURNS_DEG`]) is a round body: a can's disc keeps 0.97–1.0; a mug's, its handle
/// sticking out, about 0.9; a square's 0.71 (at 45°); a box with a lid or a laptop less.
const BODY_IOU: f64 = 0.85;

/// The model's footprint along an axis: every triangle projected orthographically onto the
/// plane across it, filled on a square grid over their extent.
struct Footprint {
    /// Cells along each side.
    n: usize,
    filled: Vec<bool>,
    /// Plane coordinates of cell (0, 0)'s corner, and the cell's side.
    origin: (f64, f64),
    cell: f64,
}

impl Footprint {
    fn new(points: &[(f64, f64)], triangles: &[[usize; 3]], n: usize) -> Option<Self> {
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for &(u, v) in points {
            lo = (lo.0.min(u), lo.1.min(v));
            hi = (hi.0.max(u), hi.1.max(v));
        }
        let side = (hi.0 - lo.0).max(hi.1 - lo.1);
        if !(side.is_finite() && side > 0.0) {
            return None;
        }
        let cell = side / n as f64;
        let mut filled = vec![false; n * n];
        for t in triangles {
            let [a, b, c] = t.map(|k| points[k]);
            let area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
            if area.abs() < 1e-18 {
                continue;
            }
            let cells = |x: f64, y: f64| {
                (
                    ((x - lo.0) / cell).floor().clamp(0.0, (n - 1) as f64) as usize,
                    ((y - lo.1) / cell).floor().clamp(0.0, (n - 1) as f64) as usize,
                )
            };
            let (x0, y0) = cells(a.0.min(b.0).min(c.0), a.1.min(b.1).min(c.1));
            let (x1, y1) = cells(a.0.max(b.0).max(c.0), a.1.max(b.1).max(c.1));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let p = (
                        lo.0 + (x as f64 + 0.5) * cell,
                        lo.1 + (y as f64 + 0.5) * cell,
                    );
                    let edge = |p0: (f64, f64), p1: (f64, f64)| {
                        ((p1.0 - p0.0) * (p.1 - p0.1) - (p1.1 - p0.1) * (p.0 - p0.0))
                            * area.signum()
                    };
                    if edge(a, b) >= 0.0 && edge(b, c) >= 0.0 && edge(c, a) >= 0.0 {
                        filled[y * n + x] = true;
                    }
                }
            }
        }
        Some(Footprint {
            n,
            filled,
            origin: lo,
            cell,
        })
    }

    fn get(&self, u: f64, v: f64) -> bool {
        let n = self.n as f64;
        let x = ((u - self.origin.0) / self.cell).floor();
        let y = ((v - self.origin.1) / self.cell).floor();
        x >= 0.0 && y >= 0.0 && x < n && y < n && self.filled[y as usize * self.n + x as usize]
    }

    /// Mean IoU of the footprint with itself turned by each of [`TEST_TURNS_DEG`] about
    /// `centre` (plane coordinates), over the filled cells' centres (`cells`).
    fn turned_iou(&self, cells: &[(f64, f64)], centre: (f64, f64)) -> f64 {
        if cells.is_empty() {
            return 0.0;
        }
        let area = cells.len() as f64;
        let mut sum = 0.0;
        for deg in TEST_TURNS_DEG {
            let (sin, cos) = deg.to_radians().sin_cos();
            let inter = cells
                .iter()
                .filter(|&&(u, v)| {
                    let (du, dv) = (u - centre.0, v - centre.1);
                    self.get(
                        centre.0 + cos * du - sin * dv,
                        centre.1 + sin * du + cos * dv,
                    )
                })
                .count() as f64;
            sum += inter / (2.0 * area - inter);
        }
        sum / TEST_TURNS_DEG.len() as f64
    }

    /// The centres of the filled cells (plane coordinates).
    fn cells(&self) -> Vec<(f64, f64)> {
        let n = self.n;
        (0..n * n)
            .filter(|&k| self.filled[k])
            .map(|k| {
                (
                    self.origin.0 + ((k % n) as f64 + 0.5) * self.cell,
                    self.origin.1 + ((k / n) as f64 + 0.5) * self.cell,
                )
            })
            .collect()
    }
}

/// The axis of the model's round body, if it has one: of its principal axes (at `states`),
/// the one along which its footprint stays most alike under turns, through the footprint's
/// centre of turning (found by search: a mug's handle pulls the principal axes' centre off
/// its body's axis), when that footprint keeps [`BODY_IOU`]. A can's or a bottle's is its
/// axis; a mug's or a kettle's the axis of its body, about which only turns that hide the
/// handle keep the outline; a box has none.
pub fn body_axis(model: &ObjectModel, states: &[f64]) -> Option<SymmetryAxis> {
    scored_body_axis(model, states).map(|b| b.1)
}

/// The axis of a body whose outline every turn about it keeps (its footprint along the axis
/// keeps [`ROUND_IOU`] under turns, and the reach of its parts that no joint moves lies
/// within [`OUTLINE_SPREAD`] of the farthest in every direction across it,
/// [`reach_spread`]): a can's or a bottle's (with a lever on its side or not), not a mug's
/// (its handle shows the turn) nor an octagonal prism's (seen from the side its outline narrows
/// by 8% between a corner and a face, which masks measure). Silhouettes cannot measure a
/// turn about it at all.
pub fn outline_axis(model: &ObjectModel, states: &[f64]) -> Option<SymmetryAxis> {
    scored_body_axis(model, states)
        .filter(|b| b.0 >= ROUND_IOU)
        .map(|b| b.1)
        .filter(|axis| reach_spread(model, states, axis) <= OUTLINE_SPREAD)
}

/// The axis of a faceted body: one whose footprint along it keeps [`ROUND_IOU`] under turns
/// (as a round body's does) while its outline seen across it narrows by more than
/// [`OUTLINE_SPREAD`] as it turns (an octagonal prism's faces, 7.6%): every frame's mask shows
/// its turn a little, so the video between keyframes can follow it. Not a can's (round) nor
/// a mug's (its handle breaks the footprint).
pub fn faceted_axis(model: &ObjectModel, states: &[f64]) -> Option<SymmetryAxis> {
    scored_body_axis(model, states)
        .filter(|b| b.0 >= ROUND_IOU)
        .map(|b| b.1)
        .filter(|axis| reach_spread(model, states, axis) > OUTLINE_SPREAD)
}

/// How much the model's outline seen across `axis` may narrow as it turns, a share of its
/// widest: a 48-sided cylinder's 0.2%, a label standing 1% proud of a can; a 16-sided
/// prism's 1.9%; a 12-sided prism's 3.4% and an octagon's 7.6% (at 640×480, 7 and 15 px
/// of a 200-px-wide body) do not count as round.
pub const OUTLINE_SPREAD: f64 = 0.03;

/// The spread of the reach from `axis` of the model's parts that no joint moves, over the
/// directions across it (their support function in the plane across the axis, about the
/// axis's centre, every 1°): 1 − the least reach over the farthest. 0 for a body of
/// revolution. A part a joint moves (a lever on a can's side) shows the turn only where it
/// is in view, so a chain cannot follow the turn through the frames that hide it; the body's
/// own outline shows it in every frame (an octagonal prism's).
pub fn reach_spread(model: &ObjectModel, states: &[f64], axis: &SymmetryAxis) -> f64 {
    spread_of_reach(model, states, axis, false)
}

/// [`reach_spread`] over every part, those a joint moves too (at `states`): above
/// [`OUTLINE_SPREAD`] where a lever or a handle on a round body shows its turn in the frames
/// that see it.
pub fn reach_spread_all(model: &ObjectModel, states: &[f64], axis: &SymmetryAxis) -> f64 {
    spread_of_reach(model, states, axis, true)
}

fn spread_of_reach(
    model: &ObjectModel,
    states: &[f64],
    axis: &SymmetryAxis,
    with_jointed: bool,
) -> f64 {
    let (u, v) = plane_basis(&axis.axis);
    let transforms = model.tree.part_transforms(states);
    let tree = &model.tree;
    let rooted = !with_jointed && (0..model.parts.len()).any(|k| tree.part_joint(k).is_none());
    let across: Vec<(f64, f64)> = model
        .parts
        .iter()
        .zip(&transforms)
        .enumerate()
        .filter(|(k, _)| !rooted || tree.part_joint(*k).is_none())
        .flat_map(|(_, (part, t))| part.mesh.positions.iter().map(move |p| t * p))
        .map(|p| {
            let d = p - axis.centre;
            (d.dot(&u), d.dot(&v))
        })
        .collect();
    let reach: Vec<f64> = (0..360)
        .map(|k| {
            let (sin, cos) = (k as f64).to_radians().sin_cos();
            across
                .iter()
                .map(|(x, y)| x * cos + y * sin)
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
    let most = reach.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let least = reach.iter().copied().fold(f64::INFINITY, f64::min);
    if most.is_nan() || most <= 0.0 {
        return 1.0;
    }
    1.0 - least / most
}

/// [`body_axis`] with its footprint's score.
fn scored_body_axis(model: &ObjectModel, states: &[f64]) -> Option<(f64, SymmetryAxis)> {
    let (centre, axes) = principal_axes(model, states)?;
    let transforms = model.tree.part_transforms(states);
    let mut positions: Vec<Point3> = Vec::new();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    for (part, t) in model.parts.iter().zip(&transforms) {
        let base = positions.len();
        positions.extend(part.mesh.positions.iter().map(|p| t * p));
        triangles.extend(
            part.mesh
                .triangles
                .iter()
                .map(|tri| tri.map(|k| base + k as usize)),
        );
    }
    let mut best: Option<(f64, SymmetryAxis)> = None;
    for principal in axes {
        // The axis itself: from the principal axis, tilted by a pattern search (a hollow
        // mug's handle tilts its principal axes 6° off its body's).
        // The tilt is searched on a coarse footprint; a footprint far from round there
        // (a box's: 0.71) is not searched.
        let Some(found) = round_along(&positions, &triangles, &principal, COARSE_CELLS) else {
            continue;
        };
        if found.0 < BODY_IOU - TILT_SEARCH_BELOW {
            continue;
        }
        let mut axis = principal;
        let Some((mut score, mut at)) =
            round_along(&positions, &triangles, &principal, FOOTPRINT_CELLS)
        else {
            continue;
        };
        // Coarse steps on the coarse footprint, then fine ones on the fine footprint (a
        // tilt of 2° moves a mug's rim by less than a coarse cell); none where the principal
        // axis is already round (a can: exact moments beat a raster, which a label part
        // standing proud of half the side tilts by a fraction of a degree).
        let tilts: &[(usize, f64, f64)] = if score >= ROUND_IOU {
            &[]
        } else {
            &[
                (COARSE_CELLS, AXIS_TILT_STEP_DEG, 1.0),
                (FOOTPRINT_CELLS, 1.0, AXIS_TILT_MIN_DEG),
            ]
        };
        for &(cells, first_deg, last_deg) in tilts {
            let Some(mut here) = round_along(&positions, &triangles, &axis, cells) else {
                break;
            };
            let mut step = first_deg;
            while step >= last_deg {
                let (u, v) = plane_basis(&axis);
                let better = [(u, step), (u, -step), (v, step), (v, -step)]
                    .iter()
                    .filter_map(|(about, deg)| {
                        let tilted = UnitQuaternion::from_axis_angle(
                            &Unit::new_normalize(*about),
                            deg.to_radians(),
                        ) * axis;
                        if tilted.dot(&principal).clamp(-1.0, 1.0).acos().to_degrees()
                            > AXIS_TILT_MAX_DEG
                        {
                            return None;
                        }
                        Some((tilted, round_along(&positions, &triangles, &tilted, cells)?))
                    })
                    .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
                    .filter(|b| b.1 .0 > here.0);
                match better {
                    Some((tilted, r)) => (axis, here) = (tilted, r),
                    None => step /= 2.0,
                }
            }
            (score, at) = here;
        }
        let (cu, cv) = at;
        if score >= BODY_IOU && best.as_ref().is_none_or(|b| score > b.0) {
            let (u, v) = plane_basis(&axis);
            let along = centre.coords.dot(&axis);
            best = Some((
                score,
                SymmetryAxis {
                    centre: Point3::from(u * cu + v * cv + axis * along),
                    axis,
                },
            ));
        }
    }
    best
}

/// The first tilt of [`body_axis`]'s search for the axis, the least, and the most from the
/// principal axis it starts at.
const AXIS_TILT_STEP_DEG: f64 = 4.0;
const AXIS_TILT_MIN_DEG: f64 = 0.25;
const AXIS_TILT_MAX_DEG: f64 = 20.0;

/// Two unit vectors spanning the plane across `axis`.
fn plane_basis(axis: &Vector3) -> (Vector3, Vector3) {
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    (u, v)
}

/// How round the model's footprint along `axis` is: its mean IoU with itself turned about
/// its best centre of turning, and that centre (plane coordinates along
/// [`plane_basis`]). The centre is found from the footprint's centroid by a pattern search
/// (a step each way along both plane axes, halved when none gains) down to half a cell.
fn round_along(
    positions: &[Point3],
    triangles: &[[usize; 3]],
    axis: &Vector3,
    cells_across: usize,
) -> Option<(f64, (f64, f64))> {
    let (u, v) = plane_basis(axis);
    let points: Vec<(f64, f64)> = positions
        .iter()
        .map(|p| (p.coords.dot(&u), p.coords.dot(&v)))
        .collect();
    let footprint = Footprint::new(&points, triangles, cells_across)?;
    let cells = footprint.cells();
    let n_cells = cells.len().max(1) as f64;
    let mut at = cells.iter().fold((0.0, 0.0), |a, c| {
        (a.0 + c.0 / n_cells, a.1 + c.1 / n_cells)
    });
    let mut score = footprint.turned_iou(&cells, at);
    let mut step = footprint.cell * cells_across as f64 / 8.0;
    while step >= 0.5 * footprint.cell {
        let moves = [(step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step)];
        let better = moves
            .iter()
            .map(|m| {
                let c = (at.0 + m.0, at.1 + m.1);
                (c, footprint.turned_iou(&cells, c))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|b| b.1 > score);
        match better {
            Some((c, sc)) => (at, score) = (c, sc),
            None => step /= 2.0,
        }
    }
    Some((score, at))
}

/// The grid of one choice: angles (degrees) relative to each frame's current pose, the
/// first 0 (kept on ties).
#[derive(Debug, Clone, PartialEq)]
pub struct AngleGrid {
    pub angles_deg: Vec<f64>,
}

impl AngleGrid {
    /// Every `step_deg` round the circle (at least 1°; a step that is not a positive number
    /// gives the grid of no turn).
    pub fn circle(step_deg: f64) -> Self {
        if !(step_deg.is_finite() && step_deg > 0.0) {
            return AngleGrid {
                angles_deg: vec![0.0],
            };
        }
        let n = (360.0 / step_deg.max(1.0)).round().max(1.0) as usize;
        AngleGrid {
            angles_deg: (0..n).map(|k| k as f64 * 360.0 / n as f64).collect(),
        }
    }
    /// `0, ±step, ±2·step, …` up to `±half_width_deg` (at most 180 each way; a step or
    /// width that is not a positive number gives the grid of no turn).
    pub fn around(step_deg: f64, half_width_deg: f64) -> Self {
        if !(step_deg.is_finite() && step_deg > 0.0 && half_width_deg.is_finite()) {
            return AngleGrid {
                angles_deg: vec![0.0],
            };
        }
        let n = (half_width_deg / step_deg).floor().clamp(0.0, 180.0) as i64;
        let mut angles_deg = vec![0.0];
        for k in 1..=n {
            angles_deg.push(k as f64 * step_deg);
            angles_deg.push(-(k as f64) * step_deg);
        }
        AngleGrid { angles_deg }
    }
}

/// An angle in (−180°, 180°], in thousandths of a degree: the key of a difference of turns.
fn key(deg: f64) -> i64 {
    (signed_deg(deg) * 1000.0).round() as i64
}

/// A turn away from the current pose costs this much NCC per 180° in the choice: only a
/// tie-break (the colours' noise between two near turns is about 0.01), so that where the
/// colours say nothing (a frame whose print is hidden) the frame keeps its angle.
const MOVE_COST_PER_HALF_TURN: f64 = 0.005;

/// The weight of a frame's colours against the model's own in the choice, against one step's
/// colours between frames: as much as both of its steps together, as in
/// [`crate::appearance`] (the model's colours are the one reference that does not depend on
/// other frames' angles being right; a block of frames turned alike agrees with itself).
/// On the hard suite's labelled can (seeds 17–19, 2026-12-03) the mean rotation error was
/// 3.2 / 7.4 / 4.4° at weight 1.5, 2.7 / 2.9 / 3.7° at 2 and 2.7 / 2.8 / 3.1° at 3.
const MODEL_WEIGHT: f64 = 2.0;

/// What [`choose_turns`]'s frames are, and so how it weighs a step between two of them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Steps<'a> {
    /// Keyframes far apart, whose views share little but each part's shading and print:
    /// each part's colours on their own ([`appearance_each`]), and no cost for a turn of one
    /// frame against the next.
    Keyframes,
    /// Every video frame, a few degrees apart: every part's colours in one group
    /// ([`appearance_pooled`]: a label's edge against its body is the evidence). Where
    /// `measured[i]` and `measured[i − 1]`, the steps into frames i − 1 and i are ones a
    /// chain followed (the frames at the poses the video's motion carried them to), and a
    /// change between the two steps' turns costs [`MOTION_COST_PER_HALF_TURN`]: the chain's
    /// motion is kept up to a steady correction, so where the print is hidden a stretch of
    /// frames turns on at the rate the frames around it show. A step into a keyframe (whose
    /// pose the chain did not give) is weighed by colours only. For a round body, whose turn
    /// the masks do not see: the chain held it as the motion predicted (a chain fitted to a
    /// prism's outline may slip a face). The tie-break toward the current angle is shared by
    /// all frames ([`MOVE_COST_PER_HALF_TURN`] over the sequence).
    Video { measured: &'a [bool] },
}

/// In [`Steps::Video`], a change of turn between two followed steps costs this much NCC per
/// 180°: a half turn as much as a print's whole disagreement, 20° about 0.11 (what a print
/// in view says about such a turn: its NCC falls by 0.1–0.3).
const MOTION_COST_PER_HALF_TURN: f64 = 1.0;

/// The turn of every frame (degrees, one of `grid`'s) that best explains the colours: the
/// most total NCC of each frame against the model's own colours and of each pair of
/// neighbouring frames against each other (both directions, averaged), a frame or a step
/// without evidence counting alike at every turn. Frame `i` takes only its own angle (0) and
/// the turns `allowed[i]` marks (a mug's turns that keep its handle hidden; the tracker marks
/// those that keep the frame's IoU, and none for a frame it keeps fixed).
/// `turned(i, deg)`: frame `i`'s pose turned by `deg` about the axis (its joints fitted again
/// where a turn moves what they hold in the mask). `frames[i]` is `None` for a frame without
/// colours. Every turn is 0 when nothing has
/// evidence, and for a model of one colour ([`model_has_appearance`]): without the model's
/// own colours the angle is a free choice of the whole sequence (a plain bottle's shading
/// correlates between frames at some turns, by chance).
#[allow(clippy::too_many_arguments)]
pub fn choose_turns(
    model: &ObjectModel,
    scale: f64,
    (cfg, steps): (&AppearanceConfig, Steps<'_>),
    frames: &[Option<AppearanceFrame<'_>>],
    poses: &[GenPose],
    allowed: &[Vec<bool>],
    turned: &(dyn Fn(usize, f64) -> GenPose + Sync),
    grid: &AngleGrid,
) -> Vec<f64> {
    let n = frames.len();
    if n == 0
        || poses.len() != n
        || allowed.len() != n
        || allowed.iter().any(|a| a.len() != grid.angles_deg.len())
        || grid.angles_deg.first() != Some(&0.0)
        || !model_has_appearance(model)
    {
        return vec![0.0; n];
    }
    let angles = &grid.angles_deg;
    // The turns each frame may take: its own angle and those `allowed` marks.
    let takes = |i: usize, k: usize| k == 0 || allowed[i][k];
    // Each frame's own colours against the model's, at each turn it may take.
    let unary: Vec<Vec<Option<f64>>> = (0..n)
        .into_par_iter()
        .map(|i| match frames[i] {
            Some(app) => angles
                .iter()
                .enumerate()
                .map(|(k, &deg)| {
                    if !takes(i, k) {
                        return None;
                    }
                    let g = turned(i, deg);
                    model_agreement(model, scale, &app, &g, cfg).ncc
                })
                .collect(),
            None => vec![None; angles.len()],
        })
        .collect();
    // Each frame as it is, rendered once for both of its steps.
    let views: Vec<Option<ReferenceView<'_>>> = (0..n)
        .into_par_iter()
        .map(|i| ReferenceView::new(model, scale, frames[i]?, &poses[i]))
        .collect();
    // pair[i]: per difference d of turns the step from frame i − 1 to i can take (sorted by
    // `key`), frame i turned by d against frame i − 1 as it is and frame i − 1 turned by −d
    // against frame i as it is, averaged where both have evidence.
    let pair: Vec<Vec<(i64, Option<f64>)>> = (0..n)
        .into_par_iter()
        .map(|i| {
            if i == 0 {
                return vec![];
            }
            let mut diffs: Vec<i64> = (0..angles.len())
                .filter(|&a| takes(i - 1, a))
                .flat_map(|a| {
                    (0..angles.len())
                        .filter(move |&b| takes(i, b))
                        .map(move |b| key(angles[b] - angles[a]))
                })
                .collect();
            diffs.sort_unstable();
            diffs.dedup();
            let none = || diffs.iter().map(|&d| (d, None)).collect();
            let (Some(fa), Some(fb), Some(va), Some(vb)) =
                (frames[i - 1], frames[i], &views[i - 1], &views[i])
            else {
                return none();
            };
            diffs
                .iter()
                .map(|&d| {
                    let deg = d as f64 / 1000.0;
                    let score = |frame: &AppearanceFrame<'_>, g: &GenPose, view| match steps {
                        Steps::Keyframes => {
                            appearance_each(model, scale, frame, g, std::slice::from_ref(view), cfg)
                                [0]
                            .ncc
                        }
                        Steps::Video { .. } => {
                            appearance_pooled(model, scale, frame, g, view, cfg).ncc
                        }
                    };
                    let forward = score(&fb, &turned(i, deg), va);
                    let backward = score(&fa, &turned(i - 1, -deg), vb);
                    let ncc = match (forward, backward) {
                        (Some(f), Some(b)) => Some(0.5 * (f + b)),
                        (f, b) => f.or(b),
                    };
                    (d, ncc)
                })
                .collect()
        })
        .collect();
    let evidence = unary
        .iter()
        .flatten()
        .chain(pair.iter().flatten().map(|(_, v)| v))
        .any(Option::is_some);
    if !evidence {
        return vec![0.0; n];
    }
    // Costs to minimise: 1 − NCC (a turn without evidence where others have some counts
    // as uncorrelated), plus the tie-break toward the current angle.
    let cost_of = |evidence: bool, value: Option<f64>| -> f64 {
        if evidence {
            1.0 - value.unwrap_or(0.0)
        } else {
            0.0
        }
    };
    let unary_evidence: Vec<bool> = unary
        .iter()
        .map(|r| r.iter().any(Option::is_some))
        .collect();
    let pair_evidence: Vec<bool> = pair
        .iter()
        .map(|r| r.iter().any(|e| e.1.is_some()))
        .collect();
    let move_cost = match steps {
        Steps::Keyframes => MOVE_COST_PER_HALF_TURN,
        Steps::Video { .. } => MOVE_COST_PER_HALF_TURN / n as f64,
    };
    let unary_cost: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            angles
                .iter()
                .enumerate()
                .map(|(k, &deg)| {
                    if !takes(i, k) {
                        return f64::INFINITY;
                    }
                    MODEL_WEIGHT * cost_of(unary_evidence[i], unary[i][k])
                        + move_cost * (key(deg) as f64 / 1000.0).abs() / 180.0
                })
                .collect()
        })
        .collect();
    let step = |i: usize, a: usize, b: usize| -> f64 {
        let row = &pair[i];
        match row.binary_search_by_key(&key(angles[b] - angles[a]), |e| e.0) {
            Ok(k) => cost_of(pair_evidence[i], row[k].1),
            Err(_) => 0.0,
        }
    };
    let path = match steps {
        Steps::Keyframes => cheapest_path(&unary_cost, &step),
        Steps::Video { measured } => {
            // A change of turn rate over two steps a chain followed: the chain's motion (the
            // turn it carried, at the velocity it predicted where the masks did not see it)
            // is kept up to a steady correction.
            let followed = |i: usize| measured.get(i).copied().unwrap_or(false);
            let bend = |i: usize, z: usize, a: usize, b: usize| -> f64 {
                if !(followed(i) && followed(i - 1)) {
                    return 0.0;
                }
                let (before, after) = (
                    signed_deg(angles[a] - angles[z]),
                    signed_deg(angles[b] - angles[a]),
                );
                MOTION_COST_PER_HALF_TURN * signed_deg(after - before).abs() / 180.0
            };
            cheapest_path_bent(&unary_cost, &step, &bend)
        }
    };
    if path.len() != n {
        return vec![0.0; n];
    }
    path.iter().map(|&k| angles[k]).collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::appearance::tests::{
        cylinder_model, label_of_half_width, labelled_model, pose, shoot,
    };
    use agentstar_geom::{primitives, KinematicTree, Part, PinholeCamera};
    use agentstar_render::BitMask;

    /// A pose turned from a base about a can's axis and tilted across it: without its twist
    /// it keeps the tilt, turns as the base does about the axis, and keeps the axis's line
    /// where the pose put it (its silhouette unchanged).
    #[test]
    fn without_its_twist_a_pose_keeps_its_swing_and_the_axis_line() {
        let model = labelled_model();
        let axis = outline_axis(&model, &model.tree.rest_states()).expect("a can is round");
        let scale = 0.12;
        let base = pose(Vector3::new(0.3, 1.0, 0.1), 10.0, -90.0);
        let across = Unit::new_normalize(axis.axis.cross(&Vector3::new(0.3, 0.5, 0.1)));
        let mut moved = axis.turn(&base, scale, 35.0);
        moved.pose = apply_object_rotation(
            &moved.pose,
            scale,
            &axis.centre,
            &UnitQuaternion::from_axis_angle(&across, 12f64.to_radians()),
        );
        moved.pose.translation += Vector3::new(0.01, -0.02, 0.03);
        let held = axis.without_twist(&base, &moved, scale);
        let turn = base.pose.rotation.inverse() * held.pose.rotation;
        assert!(twist_deg(&turn, &axis.axis).abs() < 1e-9);
        let swing = |g: &GenPose| {
            angle_across(
                &(base.pose.rotation.inverse() * g.pose.rotation),
                &axis.axis,
            )
        };
        assert!((swing(&held) - swing(&moved)).abs() < 1e-9);
        assert!((swing(&held).to_degrees() - 12.0).abs() < 1e-6);
        // Two points of the axis's line land where the moved pose puts them.
        for t in [-0.4, 0.3] {
            let p = axis.centre + axis.axis.normalize() * t;
            let at = |g: &GenPose| g.pose.with_scale(scale).transform_point(&p);
            assert!((at(&held) - at(&moved)).norm() < 1e-12);
        }
        // Without a twist to take out, the pose is kept.
        assert_eq!(axis.without_twist(&base, &base, scale), base);
    }

    #[test]
    fn a_twist_is_the_part_of_a_turn_about_the_axis() {
        let about = |axis: Vector3, deg: f64| {
            UnitQuaternion::from_axis_angle(&Unit::new_normalize(axis), deg.to_radians())
        };
        // A swing across the axis after a twist about it leaves the twist.
        let turn = about(Vector3::x(), 20.0) * about(Vector3::z(), -70.0);
        assert!((twist_deg(&turn, &Vector3::z()) + 70.0).abs() < 1e-9);
        assert!((twist_deg(&about(Vector3::z(), 200.0), &Vector3::z()) + 160.0).abs() < 1e-9);
        assert!(twist_deg(&about(Vector3::y(), 50.0), &Vector3::z()).abs() < 1e-9);
        assert_eq!(twist_deg(&turn, &Vector3::zeros()), 0.0);
    }

    #[test]
    fn grids_start_at_no_turn_and_keys_read_the_short_way_round() {
        let circle = AngleGrid::circle(10.0);
        assert_eq!(circle.angles_deg.len(), 36);
        assert_eq!(circle.angles_deg[0], 0.0);
        let around = AngleGrid::around(2.0, 10.0);
        assert_eq!(around.angles_deg.len(), 11);
        assert_eq!(around.angles_deg[0], 0.0);
        assert!(around.angles_deg.contains(&-10.0) && around.angles_deg.contains(&10.0));
        assert_eq!(key(350.0), -10_000);
        assert_eq!(key(-190.0), 170_000);
        assert_eq!(key(180.0), 180_000);
    }

    fn camera() -> PinholeCamera {
        PinholeCamera::new(300.0, 300.0, 168.0, 112.0, 320, 240).expect("camera")
    }

    /// A can seen from six directions, spun about its axis so that its side at +X (where
    /// the test's label is) faces the camera more or less.
    fn truths() -> Vec<GenPose> {
        (0..6)
            .map(|k| {
                let tilt = [0.0, 20.0, -15.0, 30.0, -25.0, 10.0][k];
                let spin = [-130.0, -110.0, -90.0, -70.0, -50.0, -80.0][k];
                pose(Vector3::new(0.3, 1.0, 0.1 * k as f64), tilt, spin)
            })
            .collect()
    }

    #[test]
    fn a_can_and_a_mug_have_a_body_axis_through_their_body_and_a_box_has_none() {
        let can = labelled_model();
        let axis = body_axis(&can, &[]).expect("the can's axis");
        assert!(axis.axis.z.abs() > 0.999, "axis {:?}", axis.axis);
        // Through the can's axis (x = y = 0), within a cell of the footprint.
        let off = (axis.centre.x.powi(2) + axis.centre.y.powi(2)).sqrt();
        assert!(off < 0.01, "centre {:?}", axis.centre);
        // A handle on the side pulls the principal axes' centre off the body's axis, and,
        // high on the side, tilts them off it; the body's axis is found all the same.
        let body = primitives::cylinder(0.3, 0.6, 48).expect("body");
        let handle = primitives::cuboid(0.12, 0.12, 0.2)
            .expect("handle")
            .translated(Vector3::new(0.36, 0.0, 0.2));
        let mut mug = ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![Part::new("body", body, [0.6, 0.1, 0.1])],
        };
        mug.parts
            .push(Part::new("handle", handle, [0.85, 0.8, 0.6]));
        mug.tree = KinematicTree::rigid(2);
        let (principal_centre, principal) = principal_axes(&mug, &[]).expect("axes");
        assert!(principal_centre.x > 0.02, "{principal_centre:?}");
        let tilt = |a: &Vector3| a.z.abs().clamp(0.0, 1.0).acos().to_degrees();
        assert!(
            principal.iter().map(tilt).fold(f64::INFINITY, f64::min) > 2.0,
            "{principal:?}"
        );
        let axis = body_axis(&mug, &[]).expect("the mug's body axis");
        assert!(tilt(&axis.axis) < 1.0, "axis {:?}", axis.axis);
        let off = (axis.centre.x.powi(2) + axis.centre.y.powi(2)).sqrt();
        assert!(off < 0.015, "centre {:?}", axis.centre);
        // A square box: 90° turns keep its footprint, 50° turns do not.
        let square = ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![Part::new(
                "box",
                primitives::cuboid(0.5, 0.5, 1.0).expect("box"),
                [0.5, 0.5, 0.5],
            )],
        };
        assert_eq!(body_axis(&square, &[]), None);
    }

    /// A can (radius 0.3, height 0.8, 48 sides) with a box lever of `size` hinged on its
    /// side (a revolute joint about −Y, 0–60°, at `reach` from the axis and `hinge_z` up):
    /// its outline is round all the same, the lever a jointed part.
    pub(crate) fn lever_can(size: [f64; 3], reach: f64, hinge_z: f64) -> ObjectModel {
        let mut model = ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![Part::new(
                "body",
                primitives::cylinder(0.3, 0.8, 48).expect("can"),
                [0.5, 0.5, 0.5],
            )],
        };
        model.parts.push(Part::new(
            "lever",
            primitives::cuboid(size[0], size[1], size[2])
                .expect("lever")
                .translated(Vector3::new(reach, 0.0, hinge_z - size[2] / 2.0)),
            [0.1, 0.2, 0.6],
        ));
        model.tree = KinematicTree::new(
            vec![agentstar_geom::JointDef {
                name: "lever_hinge".into(),
                kind: agentstar_geom::JointKind::Revolute,
                parent: None,
                child: vec!["lever".into()],
                origin: Vector3::new(reach, 0.0, hinge_z),
                axis: Vector3::new(0.0, -1.0, 0.0),
                limit: Some((0.0, 60.0)),
            }],
            &model.part_names(),
        )
        .expect("tree");
        model
    }

    #[test]
    fn a_can_and_a_labelled_can_have_a_round_outline_and_an_octagonal_prism_a_faceted_one() {
        let one = |mesh: agentstar_geom::TriMesh| ObjectModel {
            tree: KinematicTree::rigid(1),
            parts: vec![Part::new("body", mesh, [0.5, 0.5, 0.5])],
        };
        let can = one(primitives::cylinder(0.3, 0.8, 48).expect("can"));
        let octagon = one(primitives::cylinder(0.3, 0.8, 8).expect("octagonal prism"));
        let sixteen = one(primitives::cylinder(0.3, 0.8, 16).expect("16-sided prism"));
        for (name, model, round) in [
            ("can", &can, true),
            ("labelled can", &labelled_model(), true),
            ("16-sided prism", &sixteen, true),
            ("octagonal prism", &octagon, false),
        ] {
            let body = body_axis(model, &[]).unwrap_or_else(|| panic!("{name}: a body axis"));
            let spread = reach_spread(model, &[], &body);
            assert_eq!(
                outline_axis(model, &[]).is_some(),
                round,
                "{name}: reach spread {spread:.4}"
            );
            // Not round, its footprint round all the same: faceted.
            assert_eq!(faceted_axis(model, &[]).is_some(), !round, "{name}");
        }
        // A lever hinged on a can's side: the can's outline is round all the same (the lever
        // shows the turn only where it is in view).
        let lever_can = lever_can([0.03, 0.05, 0.3], 0.33, 0.1);
        let rest = lever_can.tree.rest_states();
        let axis = outline_axis(&lever_can, &rest).expect("the can with a lever is round");
        assert!(axis.axis.z.abs() > 0.99, "{axis:?}");
        // The whole model's reach, lever and all, spreads past the bound.
        let whole = ObjectModel {
            tree: KinematicTree::rigid(2),
            ..lever_can.clone()
        };
        assert!(reach_spread(&whole, &[], &axis) > OUTLINE_SPREAD);
        // So does the jointed model's, counting the parts its joints move; the plain can's
        // does not.
        assert!(reach_spread_all(&lever_can, &rest, &axis) > OUTLINE_SPREAD);
        let can_axis = body_axis(&can, &[]).expect("axis");
        assert!(reach_spread_all(&can, &[], &can_axis) < 0.005);
        // An octagon's reach from its axis: between its faces' distance and its corners'.
        let body = body_axis(&octagon, &[]).expect("axis");
        let expected = 1.0 - (std::f64::consts::PI / 8.0).cos();
        assert!(
            (reach_spread(&octagon, &[], &body) - expected).abs() < 0.005,
            "{}",
            reach_spread(&octagon, &[], &body)
        );
    }

    /// A can with a label over a quarter of its side (±0.8 rad about +X), and its paint:
    /// every view shows both colours (the model's colours against a frame that shows only
    /// the label's, shaded, score as a print missing; not what this test is about).
    fn quarter_label() -> (ObjectModel, impl Fn(&Point3) -> [f64; 3]) {
        let paint = |p: &Point3| {
            if p.z.abs() < 0.3 && p.y.atan2(p.x).abs() < 0.8 {
                [0.85, 0.8, 0.6]
            } else {
                [0.6, 0.05, 0.05]
            }
        };
        (label_of_half_width(0.8), paint)
    }

    /// The spin error about the can's axis, in degrees (the axis itself is never moved).
    fn spin_error(g: &GenPose, truth: &GenPose) -> f64 {
        (g.pose.rotation.inverse() * truth.pose.rotation)
            .angle()
            .to_degrees()
    }

    #[test]
    fn the_chain_turns_a_block_and_a_lone_frame_back_and_leaves_a_plain_can_alone() {
        let cam = camera();
        let truths = truths();
        let scale = 0.12;
        let (can, paint) = quarter_label();
        let shots: Vec<(Vec<u8>, BitMask)> = truths
            .iter()
            .map(|t| shoot(&can, scale, &cam, t, &paint))
            .collect();
        let frames: Vec<Option<AppearanceFrame<'_>>> = shots
            .iter()
            .map(|(rgb, mask)| {
                Some(AppearanceFrame {
                    camera: &cam,
                    rgb,
                    mask,
                })
            })
            .collect();
        let axis = body_axis(&can, &[]).expect("axis");
        // Frames 2–4 turned alike by 40° (they agree with one another), frame 5 by −90°.
        let offsets = [0.0, 0.0, 40.0, 40.0, 40.0, -90.0];
        let mut poses: Vec<GenPose> = truths
            .iter()
            .zip(offsets)
            .map(|(t, deg)| axis.turn(t, scale, deg))
            .collect();
        // Every turn keeps a can's outline.
        let every = |grid: &AngleGrid| vec![vec![true; grid.angles_deg.len()]; truths.len()];
        for grid in [AngleGrid::circle(10.0), AngleGrid::around(2.0, 10.0)] {
            let turns = choose_turns(
                &can,
                scale,
                (&AppearanceConfig::default(), Steps::Keyframes),
                &frames,
                &poses,
                &every(&grid),
                &|i: usize, d: f64| axis.turn(&poses[i], scale, d),
                &grid,
            );
            for (g, deg) in poses.iter_mut().zip(turns) {
                *g = axis.turn(g, scale, deg);
            }
        }
        for (k, (g, t)) in poses.iter().zip(&truths).enumerate() {
            assert!(
                spin_error(g, t) < 5.0,
                "frame {k}: {:.1}° off",
                spin_error(g, t)
            );
        }
        // A frame allowed no turn keeps its angle, even turned wrong (a fixed frame; a mug's
        // handle in view).
        let wrong: Vec<GenPose> = truths
            .iter()
            .zip(offsets)
            .map(|(t, deg)| axis.turn(t, scale, deg))
            .collect();
        let circle = AngleGrid::circle(10.0);
        let mut allowed = every(&circle);
        for k in [3, 5] {
            allowed[k] = vec![false; circle.angles_deg.len()];
        }
        let turns = choose_turns(
            &can,
            scale,
            (&AppearanceConfig::default(), Steps::Keyframes),
            &frames,
            &wrong,
            &allowed,
            &|i: usize, d: f64| axis.turn(&wrong[i], scale, d),
            &circle,
        );
        assert_eq!((turns[3], turns[5]), (0.0, 0.0), "{turns:?}");
        // The others still turn back (frames 2 and 4 by about −40°).
        for k in [2, 4] {
            assert!(
                (key(turns[k]) as f64 / 1000.0 + 40.0).abs() <= 10.0,
                "{turns:?}"
            );
        }
        // A model of one colour cannot fix the angle: nothing turns.
        let plain = cylinder_model();
        let turns = choose_turns(
            &plain,
            scale,
            (&AppearanceConfig::default(), Steps::Keyframes),
            &frames,
            &wrong,
            &every(&circle),
            &|i: usize, d: f64| axis.turn(&wrong[i], scale, d),
            &circle,
        );
        assert!(turns.iter().all(|&d| d == 0.0), "{turns:?}");
    }
}
