//! Search spaces: which degrees of freedom a search moves and over what range, in the
//! reference harness's grammar, presets and defaults.
//!
//! ```text
//! spec      := term (';' term)*
//! term      := dof ':' lower ',' upper [',' steps]      explicit range (steps for grids)
//!            | angle ':' preset ['_' direction]         angle preset
//! dof       := roll | yaw | pitch | dpx | dpy | tz      camera-frame increments (sweep, apply)
//!            | rx | ry | rz                             object-frame rotation vector (osweep, oapply)
//!            | <joint name>                             absolute joint state
//! preset    := tiny | standard | large | huge           ±5 / ±15 / ±30 / ±45 degrees
//! direction := cw | ccw (roll), leftcloser | rightcloser (yaw), topcloser | bottomcloser (pitch)
//! ```
//! A direction makes the band one-sided with the full width: `pitch:standard_topcloser` is
//! [0°, +30°]. Joint ranges are clipped to the joint's limit.

use crate::TrackError;
use agentstar_geom::KinematicTree;

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Dof {
    Roll,
    Yaw,
    Pitch,
    Dpx,
    Dpy,
    Tz,
    Rx,
    Ry,
    Rz,
    Joint(usize),
}

impl Dof {
    pub fn is_camera(&self) -> bool {
        matches!(
            self,
            Dof::Roll | Dof::Yaw | Dof::Pitch | Dof::Dpx | Dof::Dpy | Dof::Tz
        )
    }
    pub fn is_object(&self) -> bool {
        matches!(self, Dof::Rx | Dof::Ry | Dof::Rz)
    }
    pub fn is_angle(&self) -> bool {
        matches!(
            self,
            Dof::Roll | Dof::Yaw | Dof::Pitch | Dof::Rx | Dof::Ry | Dof::Rz
        )
    }
    pub fn name(&self, tree: &KinematicTree) -> String {
        match self {
            Dof::Roll => "roll".into(),
            Dof::Yaw => "yaw".into(),
            Dof::Pitch => "pitch".into(),
            Dof::Dpx => "dpx".into(),
            Dof::Dpy => "dpy".into(),
            Dof::Tz => "tz".into(),
            Dof::Rx => "rx".into(),
            Dof::Ry => "ry".into(),
            Dof::Rz => "rz".into(),
            Dof::Joint(j) => tree.joints()[*j].name.clone(),
        }
    }
}

/// One searched degree of freedom, in interface units (degrees, fractions, joint units).
#[derive(Debug, Clone, PartialEq)]
pub struct DofRange {
    pub dof: Dof,
    pub lo: f64,
    pub hi: f64,
    pub steps: Option<usize>,
}

impl DofRange {
    /// `dof` from −`half` to `half`.
    pub fn symmetric(dof: Dof, half: f64) -> DofRange {
        DofRange {
            dof,
            lo: -half,
            hi: half,
            steps: None,
        }
    }
}

/// The six camera-frame pose DOFs: ±`angle_deg` of roll, yaw and pitch, ±`shift` of `dpx`
/// and `dpy`, ±`depth` of `tz`.
pub fn pose_ranges(angle_deg: f64, shift: f64, depth: f64) -> Vec<DofRange> {
    [
        (Dof::Roll, angle_deg),
        (Dof::Yaw, angle_deg),
        (Dof::Pitch, angle_deg),
        (Dof::Dpx, shift),
        (Dof::Dpy, shift),
        (Dof::Tz, depth),
    ]
    .into_iter()
    .map(|(dof, half)| DofRange::symmetric(dof, half))
    .collect()
}

/// Every joint with a state over its default range ([`joint_default`]).
pub fn joint_ranges(tree: &KinematicTree) -> Vec<DofRange> {
    tree.joints()
        .iter()
        .enumerate()
        .filter(|(_, j)| j.kind.has_state())
        .map(|(i, _)| {
            let (lo, hi) = joint_default(tree, i);
            DofRange {
                dof: Dof::Joint(i),
                lo,
                hi,
                steps: None,
            }
        })
        .collect()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpaceKind {
    Pose,
    Joint,
    Both,
}

/// Which grammar a verb speaks: camera-frame increments or object-frame rotations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Grammar {
    Camera,
    Object,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct SearchSpace {
    pub ranges: Vec<DofRange>,
    /// What was adjusted while building the space (clipped joint windows…).
    pub notes: Vec<String>,
}

impl SearchSpace {
    pub fn bounds(&self) -> Vec<(f64, f64)> {
        self.ranges.iter().map(|r| (r.lo, r.hi)).collect()
    }
    pub fn len(&self) -> usize {
        self.ranges.len()
    }
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }
}

pub const GRAMMAR: &str = "ranges are `dof:lower,upper[,steps]` or `angle:preset[_direction]` separated by `;`, \
e.g. `yaw:-20,20;tz:-0.1,0.1;hinge:20,60` or `pitch:standard_topcloser`. Camera-frame dofs: roll, yaw, pitch (degrees), \
dpx, dpy (fractions of the image width and height), tz (fraction of the pivot depth); object-frame: rx, ry, rz (degrees); \
joints by name (degrees or canonical units). Presets: tiny ±5, standard ±15, large ±30, huge ±45; directions: \
roll cw|ccw, yaw leftcloser|rightcloser, pitch topcloser|bottomcloser";

pub fn preset_half_span(name: &str) -> Option<f64> {
    Some(match name {
        "tiny" => 5.0,
        "standard" => 15.0,
        "large" => 30.0,
        "huge" => 45.0,
        _ => return None,
    })
}

fn parse_dof(name: &str, tree: &KinematicTree, grammar: Grammar) -> Result<Dof, TrackError> {
    let dof = match name {
        "roll" => Dof::Roll,
        "yaw" => Dof::Yaw,
        "pitch" => Dof::Pitch,
        "dpx" => Dof::Dpx,
        "dpy" => Dof::Dpy,
        "tz" => Dof::Tz,
        "rx" => Dof::Rx,
        "ry" => Dof::Ry,
        "rz" => Dof::Rz,
        other => match tree.joint_index(other) {
            Some(j) if tree.joints()[j].kind.has_state() => Dof::Joint(j),
            Some(_) => {
                return Err(TrackError::Spec(format!(
                    "joint `{other}` is fixed and has no state to search"
                )))
            }
            None => {
                let joints = tree.moving_joint_names();
                return Err(TrackError::Spec(format!(
                    "unknown degree of freedom `{other}`; joints are {}. {GRAMMAR}",
                    if joints.is_empty() {
                        "(none)".to_string()
                    } else {
                        joints.join(", ")
                    }
                )));
            }
        },
    };
    match grammar {
        Grammar::Camera if dof.is_object() => Err(TrackError::Spec(format!("`{name}` is an object-frame rotation; use osweep/oapply for rx, ry, rz (sweep and apply take roll, yaw, pitch, dpx, dpy, tz and joints)"))),
        Grammar::Object if dof.is_camera() => Err(TrackError::Spec(format!("`{name}` is a camera-frame increment; use sweep/apply for it (osweep and oapply take rx, ry, rz and joints)"))),
        _ => Ok(dof),
    }
}

fn parse_number(s: &str, term: &str) -> Result<f64, TrackError> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(TrackError::Spec(format!(
            "`{term}`: `{s}` is not a number. {GRAMMAR}"
        ))),
    }
}

/// Parses a range spec. Joint windows are clipped to their limits (noted).
pub fn parse_spec(
    spec: &str,
    tree: &KinematicTree,
    grammar: Grammar,
) -> Result<SearchSpace, TrackError> {
    let mut space = SearchSpace::default();
    for term in spec.split(';').map(str::trim).filter(|t| !t.is_empty()) {
        let Some((name, value)) = term.split_once(':') else {
            return Err(TrackError::Spec(format!("`{term}` has no `:`. {GRAMMAR}")));
        };
        let dof = parse_dof(name.trim(), tree, grammar)?;
        if space.ranges.iter().any(|r| r.dof == dof) {
            return Err(TrackError::Spec(format!(
                "`{}` is given twice",
                name.trim()
            )));
        }
        let value = value.trim();
        let (lo, hi, steps) = if value
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic())
            && !value.contains(',')
        {
            if !dof.is_angle() {
                return Err(TrackError::Spec(format!(
                    "`{term}`: presets apply to angles only. {GRAMMAR}"
                )));
            }
            let (preset, dir) = match value.split_once('_') {
                Some((p, d)) => (p, Some(d)),
                None => (value, None),
            };
            let Some(h) = preset_half_span(preset) else {
                return Err(TrackError::Spec(format!(
                    "`{term}`: unknown preset `{preset}`. {GRAMMAR}"
                )));
            };
            match (dof, dir) {
                (_, None) => (-h, h, None),
                (Dof::Roll, Some("cw"))
                | (Dof::Yaw, Some("leftcloser"))
                | (Dof::Pitch, Some("topcloser")) => (0.0, 2.0 * h, None),
                (Dof::Roll, Some("ccw"))
                | (Dof::Yaw, Some("rightcloser"))
                | (Dof::Pitch, Some("bottomcloser")) => (-2.0 * h, 0.0, None),
                (d, Some(other)) if d.is_object() => {
                    return Err(TrackError::Spec(format!("`{term}`: object-frame axes take symmetric presets only (got direction `{other}`)")));
                }
                (_, Some(other)) => {
                    return Err(TrackError::Spec(format!(
                        "`{term}`: `{other}` is not a direction of `{}`. {GRAMMAR}",
                        name.trim()
                    )))
                }
            }
        } else {
            let parts: Vec<&str> = value.split(',').collect();
            if parts.len() < 2 || parts.len() > 3 {
                return Err(TrackError::Spec(format!(
                    "`{term}`: expected `lower,upper` or `lower,upper,steps`. {GRAMMAR}"
                )));
            }
            let lo = parse_number(parts[0], term)?;
            let hi = parse_number(parts[1], term)?;
            if lo > hi {
                return Err(TrackError::Spec(format!(
                    "`{term}`: lower {lo} is above upper {hi}"
                )));
            }
            let steps = match parts.get(2) {
                Some(s) => match s.trim().parse::<usize>() {
                    Ok(n) if n >= 1 => Some(n),
                    _ => {
                        return Err(TrackError::Spec(format!(
                            "`{term}`: steps `{s}` must be a whole number ≥ 1"
                        )))
                    }
                },
                None => None,
            };
            (lo, hi, steps)
        };
        let (lo, hi) = clip_joint(dof, lo, hi, tree, &mut space.notes);
        space.ranges.push(DofRange { dof, lo, hi, steps });
    }
    Ok(space)
}

fn clip_joint(
    dof: Dof,
    lo: f64,
    hi: f64,
    tree: &KinematicTree,
    notes: &mut Vec<String>,
) -> (f64, f64) {
    let Dof::Joint(j) = dof else { return (lo, hi) };
    let jd = &tree.joints()[j];
    let Some((llo, lhi)) = jd.limit else {
        return (lo, hi);
    };
    let (clo, chi) = (lo.clamp(llo, lhi), hi.clamp(llo, lhi));
    if (clo, chi) != (lo, hi) {
        notes.push(format!(
            "joint `{}`: window [{lo}, {hi}] clipped to its limit as [{clo}, {chi}]",
            jd.name
        ));
    }
    (clo, chi)
}

/// The default span of a joint: its limit, else ±180° (revolute) or ±1 (prismatic).
pub fn joint_default(tree: &KinematicTree, j: usize) -> (f64, f64) {
    let jd = &tree.joints()[j];
    jd.limit.unwrap_or(if jd.kind.is_angular() {
        (-180.0, 180.0)
    } else {
        (-1.0, 1.0)
    })
}

/// The reference's default boxes: pose ±15° angles, dpx/dpy ±0.08, tz ±0.1; joints over
/// their limits; both = yaw ±15°, tz ±0.1 and the joints.
pub fn default_space(kind: SpaceKind, tree: &KinematicTree) -> SearchSpace {
    let ranges = match kind {
        SpaceKind::Pose => pose_ranges(15.0, 0.08, 0.1),
        SpaceKind::Joint => joint_ranges(tree),
        SpaceKind::Both => {
            let mut v = vec![
                DofRange::symmetric(Dof::Yaw, 15.0),
                DofRange::symmetric(Dof::Tz, 0.1),
            ];
            v.extend(joint_ranges(tree));
            v
        }
    };
    SearchSpace {
        ranges,
        notes: vec![],
    }
}

/// A space from an optional spec and kind: an empty spec gives the default box of the kind
/// (pose when unspecified); a spec with a kind of `both` or `pose` keeps the named ranges
/// and fills the default box's other DOFs.
pub fn build_space(
    spec: Option<&str>,
    kind: Option<SpaceKind>,
    tree: &KinematicTree,
    grammar: Grammar,
) -> Result<SearchSpace, TrackError> {
    let parsed = match spec {
        Some(s) if !s.trim().is_empty() => Some(parse_spec(s, tree, grammar)?),
        _ => None,
    };
    match (parsed, kind) {
        (None, k) => Ok(match grammar {
            Grammar::Camera => default_space(k.unwrap_or(SpaceKind::Pose), tree),
            Grammar::Object => SearchSpace {
                ranges: [Dof::Rx, Dof::Ry, Dof::Rz]
                    .into_iter()
                    .map(|d| DofRange {
                        dof: d,
                        lo: -15.0,
                        hi: 15.0,
                        steps: None,
                    })
                    .collect(),
                notes: vec![],
            },
        }),
        (Some(p), None) => Ok(p),
        (Some(mut p), Some(k)) => {
            for d in default_space(k, tree).ranges {
                if !p.ranges.iter().any(|r| r.dof == d.dof) {
                    p.ranges.push(d);
                }
            }
            Ok(p)
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use agentstar_geom::kinematics::{JointDef, JointKind};
    use agentstar_geom::Vector3;

    /// A base and a lid on one revolute hinge about X at the origin, open 0° to `max_deg`.
    pub(crate) fn hinged_tree(max_deg: f64) -> KinematicTree {
        let j = JointDef {
            name: "hinge".into(),
            kind: JointKind::Revolute,
            parent: None,
            child: vec!["lid".into()],
            origin: Vector3::zeros(),
            axis: Vector3::x(),
            limit: Some((0.0, max_deg)),
        };
        KinematicTree::new(vec![j], &["base".into(), "lid".into()]).expect("tree")
    }

    fn tree() -> KinematicTree {
        hinged_tree(120.0)
    }

    #[test]
    fn presets_and_directions() {
        let s = parse_spec(
            "pitch:standard_topcloser; roll:tiny_cw; yaw:large_rightcloser; rz:huge",
            &tree(),
            Grammar::Camera,
        );
        assert!(s
            .expect_err("rz in camera grammar")
            .to_string()
            .contains("object-frame rotation; use osweep"));
        let s = parse_spec(
            "pitch:standard_topcloser; roll:tiny_cw; yaw:large_rightcloser; tz:-0.1,0.2,5",
            &tree(),
            Grammar::Camera,
        )
        .expect("spec");
        let r: Vec<(f64, f64)> = s.bounds();
        assert_eq!(r, vec![(0.0, 30.0), (0.0, 10.0), (-60.0, 0.0), (-0.1, 0.2)]);
        assert_eq!(s.ranges[3].steps, Some(5));
        let o = parse_spec("rz:large;hinge:-30,60", &tree(), Grammar::Object).expect("object");
        assert_eq!(o.bounds(), vec![(-30.0, 30.0), (0.0, 60.0)]);
        assert_eq!(o.notes.len(), 1);
    }

    #[test]
    fn bad_specs_show_the_grammar() {
        for (spec, needle) in [
            ("yaw=-10,10", "has no `:`"),
            ("yaw:-10", "expected `lower,upper`"),
            ("yaw:ten,20", "is not a number"),
            ("yaw:20,-20", "is above upper"),
            ("yaw:enormous", "unknown preset"),
            ("dpx:standard", "presets apply to angles only"),
            ("roll:standard_leftcloser", "not a direction of `roll`"),
            (
                "hinj:0,30",
                "unknown degree of freedom `hinj`; joints are hinge",
            ),
            ("tz:0,1,0", "steps"),
            ("yaw:1,2;yaw:3,4", "given twice"),
        ] {
            let e = parse_spec(spec, &tree(), Grammar::Camera)
                .expect_err(spec)
                .to_string();
            assert!(e.contains(needle), "{spec}: {e}");
        }
        let e = parse_spec("yaw:1", &tree(), Grammar::Camera)
            .expect_err("grammar")
            .to_string();
        assert!(e.contains("dof:lower,upper[,steps]"), "{e}");
        assert!(parse_spec("tz:-1,1", &tree(), Grammar::Object)
            .expect_err("camera in object")
            .to_string()
            .contains("use sweep/apply"));
    }

    #[test]
    fn defaults_follow_the_reference() {
        let t = tree();
        assert_eq!(
            default_space(SpaceKind::Pose, &t).bounds(),
            vec![
                (-15.0, 15.0),
                (-15.0, 15.0),
                (-15.0, 15.0),
                (-0.08, 0.08),
                (-0.08, 0.08),
                (-0.1, 0.1)
            ]
        );
        assert_eq!(
            default_space(SpaceKind::Both, &t).bounds(),
            vec![(-15.0, 15.0), (-0.1, 0.1), (0.0, 120.0)]
        );
        let b = build_space(
            Some("hinge:10,20"),
            Some(SpaceKind::Pose),
            &t,
            Grammar::Camera,
        )
        .expect("space");
        assert_eq!(b.len(), 7);
    }
}
