//! The kinematic tree: revolute, continuous, prismatic and fixed joints declared in the
//! canonical rest frame, and forward kinematics exactly as `formats.md` states it:
//! revolute `T(origin) · Rot(axis, state) · T(−origin)`, prismatic a translation by
//! `state · axis`, chains accumulated parent first (`A_j = A_parent · L_j`).
//!
//! States are radians (revolute) and canonical units (prismatic) here; the degree
//! conversion happens in [`KinematicTree::states_from_interface`].

use crate::pose::Rigid;
use crate::{GeomError, Result, UnitQuaternion, Vector3};
use nalgebra::{Translation3, Unit};
use std::collections::BTreeMap;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointKind {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
}

impl JointKind {
    pub fn as_str(&self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
        }
    }
    pub fn parse(s: &str) -> Option<JointKind> {
        Some(match s {
            "revolute" => JointKind::Revolute,
            "continuous" => JointKind::Continuous,
            "prismatic" => JointKind::Prismatic,
            "fixed" => JointKind::Fixed,
            _ => return None,
        })
    }
    pub const NAMES: [&'static str; 4] = ["revolute", "continuous", "prismatic", "fixed"];
    /// True for joints whose state rotates (degrees at the interface).
    pub fn is_angular(&self) -> bool {
        matches!(self, JointKind::Revolute | JointKind::Continuous)
    }
    pub fn has_state(&self) -> bool {
        !matches!(self, JointKind::Fixed)
    }
}

/// One joint, as written in a scene or `pose.json` `joint_defs`. Limits are in interface
/// units (degrees for revolute, canonical units for prismatic).
#[derive(Debug, Clone, PartialEq)]
pub struct JointDef {
    pub name: String,
    pub kind: JointKind,
    /// Name of the parent joint, for chains.
    pub parent: Option<String>,
    /// Parts moved by this joint (a rigid group).
    pub child: Vec<String>,
    pub origin: Vector3,
    pub axis: Vector3,
    /// `(lower, upper)` in interface units; `None` only for continuous and fixed joints.
    pub limit: Option<(f64, f64)>,
}

impl JointDef {
    /// Converts an interface-unit state (degrees or canonical units) to the internal unit.
    pub fn to_internal(&self, value: f64) -> f64 {
        if self.kind.is_angular() {
            value.to_radians()
        } else {
            value
        }
    }
    pub fn to_interface(&self, value: f64) -> f64 {
        if self.kind.is_angular() {
            value.to_degrees()
        } else {
            value
        }
    }
    /// The joint's own motion `L_j` for an internal-unit state.
    pub fn local_motion(&self, state: f64, unit_axis: &Unit<Vector3>) -> Rigid {
        match self.kind {
            JointKind::Revolute | JointKind::Continuous => {
                let rot = UnitQuaternion::from_axis_angle(unit_axis, state);
                // T(o) · R · T(−o) = (R, o − R o)
                let t = self.origin - rot * self.origin;
                Rigid::from_parts(Translation3::from(t), rot)
            }
            JointKind::Prismatic => Rigid::from_parts(
                Translation3::from(unit_axis.into_inner() * state),
                UnitQuaternion::identity(),
            ),
            JointKind::Fixed => Rigid::identity(),
        }
    }
}

/// Which end of a joint's limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum LimitEnd {
    Lower,
    Upper,
}

/// A joint whose state piles up at one end of its limit ([`KinematicTree::at_limit`]).
#[derive(Debug, Clone, PartialEq)]
pub struct AtLimit {
    pub joint: String,
    pub end: LimitEnd,
    /// The limit there, interface units.
    pub bound: f64,
    /// The frames at it, in the order given.
    pub frames: Vec<String>,
    /// Frames in all.
    pub keyframes: usize,
}

/// A validated set of joints over a set of part names.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicTree {
    joints: Vec<JointDef>,
    unit_axes: Vec<Unit<Vector3>>,
    /// Joint indices, parents before children.
    order: Vec<usize>,
    parent_index: Vec<Option<usize>>,
    /// For each part (in the model's part order), the joint that carries it.
    part_joint: Vec<Option<usize>>,
}

impl KinematicTree {
    pub fn rigid(part_count: usize) -> Self {
        KinematicTree {
            joints: vec![],
            unit_axes: vec![],
            order: vec![],
            parent_index: vec![],
            part_joint: vec![None; part_count],
        }
    }

    /// Validates `joints` against `part_names`: unique names, known parents and children,
    /// each part under at most one joint, no cycles, finite origins, non-zero axes,
    /// well-formed limits.
    pub fn new(joints: Vec<JointDef>, part_names: &[String]) -> Result<Self> {
        let bad = |j: &JointDef, reason: String| GeomError::InvalidJoint {
            joint: j.name.clone(),
            reason,
        };
        let mut by_name: BTreeMap<&str, usize> = BTreeMap::new();
        for (i, j) in joints.iter().enumerate() {
            if j.name.is_empty() {
                return Err(bad(j, "joint name is empty".into()));
            }
            if by_name.insert(j.name.as_str(), i).is_some() {
                return Err(bad(j, "a joint with this name is declared twice".into()));
            }
        }
        let mut unit_axes = Vec::with_capacity(joints.len());
        let mut parent_index = Vec::with_capacity(joints.len());
        let mut part_joint = vec![None; part_names.len()];
        for (i, j) in joints.iter().enumerate() {
            if !j.origin.iter().all(|c| c.is_finite()) {
                return Err(bad(
                    j,
                    format!(
                        "origin {:?} has a non-finite component",
                        j.origin.as_slice()
                    ),
                ));
            }
            if !j.axis.iter().all(|c| c.is_finite()) || j.axis.norm() < 1e-9 {
                return Err(bad(
                    j,
                    format!(
                        "axis {:?} must be a finite, non-zero vector",
                        j.axis.as_slice()
                    ),
                ));
            }
            unit_axes.push(Unit::new_normalize(j.axis));
            match (j.kind, j.limit) {
                (JointKind::Revolute | JointKind::Prismatic, None) => {
                    return Err(bad(j, format!("a {} joint needs `limit: [lower, upper]` (use type \"continuous\" for an unlimited rotation)", j.kind.as_str())));
                }
                (_, Some((lo, hi))) if !(lo.is_finite() && hi.is_finite()) || lo > hi => {
                    return Err(bad(
                        j,
                        format!("limit [{lo}, {hi}] must be finite with lower ≤ upper"),
                    ));
                }
                _ => {}
            }
            // A joint may carry no part only when other joints hang from it (a URDF link
            // without geometry in the middle of a chain).
            if j.child.is_empty()
                && !joints
                    .iter()
                    .any(|o| o.parent.as_deref() == Some(j.name.as_str()))
            {
                return Err(bad(j, "`child` names no part".into()));
            }
            for c in &j.child {
                let Some(pi) = part_names.iter().position(|p| p == c) else {
                    return Err(bad(
                        j,
                        format!(
                            "child part `{c}` is not defined; parts are: {}",
                            list(part_names)
                        ),
                    ));
                };
                if let Some(other) = part_joint[pi] {
                    let other: &JointDef = &joints[other];
                    return Err(bad(j, format!("part `{c}` is already the child of joint `{}`; a part moves with one joint", other.name)));
                }
                part_joint[pi] = Some(i);
            }
            parent_index.push(match &j.parent {
                None => None,
                Some(p) => match by_name.get(p.as_str()) {
                    Some(&pi) if pi == i => {
                        return Err(bad(j, "a joint cannot be its own parent".into()))
                    }
                    Some(&pi) => Some(pi),
                    None => {
                        let names: Vec<String> = joints.iter().map(|j| j.name.clone()).collect();
                        return Err(bad(
                            j,
                            format!(
                                "parent joint `{p}` is not declared; joints are: {}",
                                list(&names)
                            ),
                        ));
                    }
                },
            });
        }
        // Topological order with cycle detection.
        let mut order = Vec::with_capacity(joints.len());
        let mut state = vec![0u8; joints.len()]; // 0 new, 1 visiting, 2 done
        fn visit(
            i: usize,
            parents: &[Option<usize>],
            state: &mut [u8],
            order: &mut Vec<usize>,
            joints: &[JointDef],
        ) -> Result<()> {
            match state[i] {
                2 => return Ok(()),
                1 => {
                    return Err(GeomError::InvalidTree(format!(
                        "joint `{}` is part of a parent cycle",
                        joints[i].name
                    )))
                }
                _ => {}
            }
            state[i] = 1;
            if let Some(p) = parents[i] {
                visit(p, parents, state, order, joints)?;
            }
            state[i] = 2;
            order.push(i);
            Ok(())
        }
        for i in 0..joints.len() {
            visit(i, &parent_index, &mut state, &mut order, &joints)?;
        }
        Ok(KinematicTree {
            joints,
            unit_axes,
            order,
            parent_index,
            part_joint,
        })
    }

    pub fn joints(&self) -> &[JointDef] {
        &self.joints
    }

    /// The names of the joints with a state (every kind but fixed), in order: what a search
    /// or a candidate may set.
    pub fn moving_joint_names(&self) -> Vec<&str> {
        self.joints
            .iter()
            .filter(|j| j.kind.has_state())
            .map(|j| j.name.as_str())
            .collect()
    }

    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    pub fn unit_axis(&self, joint: usize) -> Unit<Vector3> {
        self.unit_axes[joint]
    }

    /// The joint carrying each part (by part index).
    pub fn part_joint(&self, part: usize) -> Option<usize> {
        self.part_joint[part]
    }

    /// The parts joint `joint` moves (those it carries and those of the joints below it),
    /// by part index, ascending.
    pub fn parts_moved_by(&self, joint: usize) -> Vec<usize> {
        let below = |mut k: usize| loop {
            if k == joint {
                return true;
            }
            match self.parent_index.get(k).copied().flatten() {
                Some(p) => k = p,
                None => return false,
            }
        };
        self.part_joint
            .iter()
            .enumerate()
            .filter(|(_, j)| j.is_some_and(below))
            .map(|(p, _)| p)
            .collect()
    }

    /// Warnings about the limits themselves: a revolute joint whose range spans a full
    /// turn (e.g. `[0, 360]`) reaches both θ and 360 − θ, which a part symmetric about a
    /// plane through its axis renders alike, so searches can alias between them.
    pub fn limit_warnings(&self) -> Vec<String> {
        self.joints
            .iter()
            .filter_map(|j| match (j.kind, j.limit) {
                (JointKind::Revolute, Some((lo, hi))) if hi - lo >= 360.0 - 1e-9 => Some(format!(
                    "joint `{}`: its limit [{lo}, {hi}] spans a full turn, so θ and 360−θ (a mirror image about the axis for many parts) are both reachable and can alias; limit it to the range the part really moves through",
                    j.name
                )),
                _ => None,
            })
            .collect()
    }

    /// Joints whose state sits at a limit (within 0.5% of the range) in at least 3 frames
    /// and a quarter of them, but not in all: a sign that the limit is too tight, the axis
    /// reversed or the part built in the wrong place. `states` holds each frame's
    /// internal-unit states, `names` the frames' names. In joint order, the lower limit first.
    pub fn at_limit(&self, states: &[Vec<f64>], names: &[String]) -> Vec<AtLimit> {
        let mut out = Vec::new();
        for (k, j) in self.joints.iter().enumerate() {
            let Some((lo, hi)) = j.limit.filter(|(lo, hi)| hi > lo) else {
                continue;
            };
            let tol = 0.005 * (hi - lo);
            for (bound, end) in [(lo, LimitEnd::Lower), (hi, LimitEnd::Upper)] {
                let at: Vec<String> = states
                    .iter()
                    .zip(names)
                    .filter(|(s, _)| {
                        s.get(k)
                            .is_some_and(|&v| (j.to_interface(v) - bound).abs() <= tol)
                    })
                    .map(|(_, n)| n.clone())
                    .collect();
                // Every frame at the limit is a joint that never moved (or was never
                // searched), not one that piles up against its limit.
                if at.len() >= 3 && at.len() * 4 >= states.len() && at.len() < states.len() {
                    out.push(AtLimit {
                        joint: j.name.clone(),
                        end,
                        bound,
                        frames: at,
                        keyframes: states.len(),
                    });
                }
            }
        }
        out
    }

    /// Rest states (all zero), internal units.
    pub fn rest_states(&self) -> Vec<f64> {
        vec![0.0; self.joints.len()]
    }

    /// Internal-unit states from interface-unit values by name. Every joint with a state
    /// must be named (0 is a real position, so a missing joint is an error) and lie within
    /// its limit; unknown names are errors too. Fixed joints may be omitted.
    pub fn states_from_interface(&self, named: &BTreeMap<String, f64>) -> Result<Vec<f64>> {
        for name in named.keys() {
            if self.joint_index(name).is_none() {
                let names: Vec<String> = self.joints.iter().map(|j| j.name.clone()).collect();
                return Err(GeomError::InvalidJoint {
                    joint: name.clone(),
                    reason: format!("no such joint; joints are: {}", list(&names)),
                });
            }
        }
        let mut states = self.rest_states();
        for (i, j) in self.joints.iter().enumerate() {
            if !j.kind.has_state() {
                continue;
            }
            let Some(&v) = named.get(&j.name) else {
                return Err(GeomError::InvalidJoint {
                    joint: j.name.clone(),
                    reason: "state is missing (states are absolute; give every non-fixed joint)"
                        .into(),
                });
            };
            states[i] = self.state_from_interface(i, v)?;
        }
        Ok(states)
    }

    /// Joint `joint`'s internal-unit state from an interface-unit value: finite, within its
    /// limit (to a millionth of its range), and the joint not fixed.
    pub fn state_from_interface(&self, joint: usize, v: f64) -> Result<f64> {
        let j = self.joints.get(joint).ok_or_else(|| {
            GeomError::InvalidTree(format!("no joint {joint} of {}", self.joints.len()))
        })?;
        let invalid = |reason: String| GeomError::InvalidJoint {
            joint: j.name.clone(),
            reason,
        };
        if !j.kind.has_state() {
            return Err(invalid("the joint is fixed: it has no state".into()));
        }
        if !v.is_finite() {
            return Err(invalid(format!("state {v} is not finite")));
        }
        if let Some((lo, hi)) = j.limit {
            let tol = 1e-6 * (hi - lo).abs().max(1.0);
            if v < lo - tol || v > hi + tol {
                return Err(invalid(format!(
                    "state {v} is outside its limit [{lo}, {hi}]"
                )));
            }
        }
        Ok(j.to_internal(v))
    }

    /// Interface-unit values by name (sorted), for writing.
    pub fn states_to_interface(&self, states: &[f64]) -> BTreeMap<String, f64> {
        self.joints
            .iter()
            .zip(states)
            .filter(|(j, _)| j.kind.has_state())
            .map(|(j, &s)| (j.name.clone(), j.to_interface(s)))
            .collect()
    }

    /// Clamps internal-unit states to the joints' limits.
    pub fn clamp_states(&self, states: &mut [f64]) {
        for (j, s) in self.joints.iter().zip(states.iter_mut()) {
            if let Some((lo, hi)) = j.limit {
                *s = s.clamp(j.to_internal(lo), j.to_internal(hi));
            }
        }
    }

    /// The accumulated transform `A_j` of every joint for internal-unit `states`.
    pub fn joint_transforms(&self, states: &[f64]) -> Vec<Rigid> {
        let mut joints = Vec::new();
        self.part_transforms_into(states, &mut joints, &mut Vec::new());
        joints
    }

    /// `object_from_part` for every part (by part index): the canonical placement of each
    /// part's rest geometry under `states`.
    pub fn part_transforms(&self, states: &[f64]) -> Vec<Rigid> {
        let mut joints = Vec::new();
        let mut parts = Vec::new();
        self.part_transforms_into(states, &mut joints, &mut parts);
        parts
    }

    /// [`Self::part_transforms`] into caller-owned buffers (no allocation once they are sized).
    pub fn part_transforms_into(
        &self,
        states: &[f64],
        joints: &mut Vec<Rigid>,
        parts: &mut Vec<Rigid>,
    ) {
        joints.clear();
        joints.resize(self.joints.len(), Rigid::identity());
        for &i in &self.order {
            let local = self.joints[i]
                .local_motion(states.get(i).copied().unwrap_or(0.0), &self.unit_axes[i]);
            joints[i] = match self.parent_index[i] {
                Some(p) => joints[p] * local,
                None => local,
            };
        }
        parts.clear();
        parts.extend(
            self.part_joint
                .iter()
                .map(|j| j.map_or_else(Rigid::identity, |j| joints[j])),
        );
    }
}

fn list(names: &[String]) -> String {
    if names.is_empty() {
        "(none)".into()
    } else {
        names
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Point3;
    use proptest::prelude::*;

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| s.to_string()).collect()
    }

    fn hinge(
        name: &str,
        parent: Option<&str>,
        child: &str,
        origin: [f64; 3],
        axis: [f64; 3],
    ) -> JointDef {
        JointDef {
            name: name.into(),
            kind: JointKind::Revolute,
            parent: parent.map(Into::into),
            child: vec![child.into()],
            origin: Vector3::from(origin),
            axis: Vector3::from(axis),
            limit: Some((-180.0, 180.0)),
        }
    }

    #[test]
    fn a_joint_moves_its_own_parts_and_those_of_the_joints_below_it() {
        let tree = KinematicTree::new(
            vec![
                hinge("arm", None, "arm", [0.0; 3], [0.0, 0.0, 1.0]),
                hinge(
                    "wrist",
                    Some("arm"),
                    "hand",
                    [1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                ),
            ],
            &names(&["base", "arm", "hand", "lamp"]),
        )
        .expect("tree");
        assert_eq!(tree.parts_moved_by(0), [1, 2]);
        assert_eq!(tree.parts_moved_by(1), [2]);
    }

    #[test]
    fn full_turn_limits_and_states_piled_at_a_limit_are_warned_about() {
        let mut full = hinge("dial", None, "dial", [0.0; 3], [0.0, 0.0, 1.0]);
        full.limit = Some((0.0, 360.0));
        let mut lid = hinge("lid", None, "lid", [0.0; 3], [1.0, 0.0, 0.0]);
        lid.limit = Some((0.0, 120.0));
        let tree =
            KinematicTree::new(vec![full, lid], &names(&["body", "dial", "lid"])).expect("tree");
        let w = tree.limit_warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("`dial`") && w[0].contains("360"), "{w:?}");
        // The lid at 0° in 4 of 8 frames (the dial spread out): one warning, the lower limit.
        let states: Vec<Vec<f64>> = (0..8)
            .map(|k| {
                let lid = if k % 2 == 0 { 0.0 } else { 40.0 + k as f64 };
                vec![(20.0 * k as f64).to_radians(), f64::to_radians(lid)]
            })
            .collect();
        let frames: Vec<String> = (0..8).map(|k| format!("{k:06}.png")).collect();
        let piled = tree.at_limit(&states, &frames);
        assert_eq!(
            piled,
            [AtLimit {
                joint: "lid".into(),
                end: LimitEnd::Lower,
                bound: 0.0,
                frames: ["000000.png", "000002.png", "000004.png", "000006.png"]
                    .map(String::from)
                    .to_vec(),
                keyframes: 8,
            }]
        );
        // Every frame at the rest state (nothing tracked yet) is not a pile-up.
        let rest = vec![vec![0.0, 0.0]; 8];
        assert!(tree.at_limit(&rest, &frames).is_empty());
        // Two frames of eight are not "many".
        let w = tree.at_limit(&states[..3], &frames[..3]);
        assert!(w.is_empty(), "{w:?}");
        assert!(KinematicTree::new(vec![], &names(&["body"]))
            .expect("tree")
            .limit_warnings()
            .is_empty());
    }

    #[test]
    fn revolute_hand_computed() {
        // Lid hinged on the X axis through (0, -0.5, 0.05); +90° swings a point at the lid's
        // front (0, 0.5, 0.05) up to (0, -0.5, 1.05).
        let tree = KinematicTree::new(
            vec![hinge(
                "hinge",
                None,
                "lid",
                [0.0, -0.5, 0.05],
                [1.0, 0.0, 0.0],
            )],
            &names(&["body", "lid"]),
        )
        .expect("tree");
        let t = tree.part_transforms(&[90f64.to_radians()]);
        assert_eq!(t[0], Rigid::identity());
        let p = t[1] * Point3::new(0.0, 0.5, 0.05);
        assert!((p - Point3::new(0.0, -0.5, 1.05)).norm() < 1e-12, "{p}");
    }

    #[test]
    fn prismatic_and_chain_hand_computed() {
        let mut drawer = hinge("slide", None, "drawer", [0.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        drawer.kind = JointKind::Prismatic;
        drawer.limit = Some((0.0, 0.5));
        // A knob that turns about Z through the drawer front (0, 0.5, 0), mounted on the drawer.
        let knob = hinge(
            "knob",
            Some("slide"),
            "knob",
            [0.0, 0.5, 0.0],
            [0.0, 0.0, 1.0],
        );
        let tree = KinematicTree::new(vec![knob, drawer], &names(&["cabinet", "drawer", "knob"]))
            .expect("tree");
        let states = [90f64.to_radians(), 0.3]; // knob, slide (declaration order)
        let t = tree.part_transforms(&states);
        let p = t[1] * Point3::new(0.0, 0.5, 0.0);
        assert!((p - Point3::new(0.0, 0.8, 0.0)).norm() < 1e-12);
        // A point 0.1 right of the knob centre rotates to 0.1 in front of it, then slides.
        let q = t[2] * Point3::new(0.1, 0.5, 0.0);
        assert!((q - Point3::new(0.0, 0.9, 0.0)).norm() < 1e-12, "{q}");
    }

    #[test]
    fn invalid_trees_are_explained() {
        let parts = names(&["a", "b"]);
        let mut j = hinge("j", None, "c", [0.0; 3], [1.0, 0.0, 0.0]);
        let e = KinematicTree::new(vec![j.clone()], &parts).expect_err("unknown child");
        assert!(
            e.to_string().contains("`c` is not defined") && e.to_string().contains("`a`, `b`"),
            "{e}"
        );
        j.child = vec!["a".into()];
        j.axis = Vector3::zeros();
        assert!(KinematicTree::new(vec![j.clone()], &parts).is_err());
        let a = hinge("a", Some("b"), "a", [0.0; 3], [1.0, 0.0, 0.0]);
        let b = hinge("b", Some("a"), "b", [0.0; 3], [1.0, 0.0, 0.0]);
        let e = KinematicTree::new(vec![a, b], &parts).expect_err("cycle");
        assert!(e.to_string().contains("cycle"), "{e}");
        let mut lim = hinge("l", None, "a", [0.0; 3], [1.0, 0.0, 0.0]);
        lim.limit = Some((10.0, -10.0));
        assert!(KinematicTree::new(vec![lim.clone()], &parts).is_err());
        lim.limit = None;
        assert!(KinematicTree::new(vec![lim], &parts).is_err());
    }

    #[test]
    fn interface_states_are_complete_and_within_limits() {
        let mut j = hinge("hinge", None, "lid", [0.0; 3], [1.0, 0.0, 0.0]);
        j.limit = Some((0.0, 120.0));
        let tree = KinematicTree::new(vec![j], &names(&["lid"])).expect("tree");
        let mut m = BTreeMap::new();
        assert!(tree.states_from_interface(&m).is_err());
        m.insert("hinge".to_string(), 150.0);
        assert!(tree
            .states_from_interface(&m)
            .expect_err("limit")
            .to_string()
            .contains("outside"));
        m.insert("hinge".to_string(), 90.0);
        let s = tree.states_from_interface(&m).expect("ok");
        assert!((s[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(tree.states_to_interface(&s)["hinge"], 90.0);
        // One joint at a time, as a candidate sets it: the same checks.
        assert!((tree.state_from_interface(0, 90.0).expect("ok") - s[0]).abs() < 1e-12);
        assert!(tree.state_from_interface(0, 120.0 + 1e-9).is_ok());
        for (v, says) in [(150.0, "outside its limit"), (f64::NAN, "not finite")] {
            let e = tree
                .state_from_interface(0, v)
                .expect_err("bad")
                .to_string();
            assert!(e.contains(says), "{e}");
        }
        assert!(tree.state_from_interface(1, 0.0).is_err());
    }

    proptest! {
        // Flipping the axis is the same as flipping the state.
        #[test]
        fn axis_sign_flip_equals_state_flip(ax in -1.0f64..1.0, ay in -1.0f64..1.0, az in 0.1f64..1.0, angle in -3.0f64..3.0,
                                            ox in -1.0f64..1.0, oy in -1.0f64..1.0, px in -1.0f64..1.0, pz in -1.0f64..1.0) {
            let parts = names(&["p"]);
            let a = KinematicTree::new(vec![hinge("j", None, "p", [ox, oy, 0.2], [ax, ay, az])], &parts).expect("tree");
            let b = KinematicTree::new(vec![hinge("j", None, "p", [ox, oy, 0.2], [-ax, -ay, -az])], &parts).expect("tree");
            let p = Point3::new(px, 0.3, pz);
            let pa = a.part_transforms(&[angle])[0] * p;
            let pb = b.part_transforms(&[-angle])[0] * p;
            prop_assert!((pa - pb).norm() < 1e-9);
        }

        // Points on the axis line do not move; distances to the axis are preserved.
        #[test]
        fn revolute_fixes_its_axis(angle in -6.0f64..6.0, t in -2.0f64..2.0, ox in -1.0f64..1.0) {
            let parts = names(&["p"]);
            let tree = KinematicTree::new(vec![hinge("j", None, "p", [ox, 0.5, -0.2], [0.3, 1.0, 0.2])], &parts).expect("tree");
            let m = tree.part_transforms(&[angle])[0];
            let on_axis = Point3::new(ox, 0.5, -0.2) + Vector3::new(0.3, 1.0, 0.2).normalize() * t;
            prop_assert!((m * on_axis - on_axis).norm() < 1e-9);
        }
    }
}
