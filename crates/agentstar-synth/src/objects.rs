//! The object library: procedural scene scripts modelled on the paper's datasets. ARCTIC-like
//! hand-held articulated objects, HOT3D-like rigid objects (some rotationally symmetric) and
//! iTACO-like furniture. Each script follows the scene conventions (+Z up, centred, longest
//! side about 1, rest state 0) and carries its size in metres.

/// Which of the paper's datasets an object and its default motion imitate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Family {
    /// Hand-held articulated objects (ARCTIC): 3-D tracking and geometry.
    Arctic,
    /// Rigid hand-held objects (HOT3D): pose tracking.
    Hot3d,
    /// Articulated furniture seen by a moving camera (iTACO): articulation.
    Itaco,
}

impl Family {
    pub fn as_str(&self) -> &'static str {
        match self {
            Family::Arctic => "arctic",
            Family::Hot3d => "hot3d",
            Family::Itaco => "itaco",
        }
    }
}

/// The rotational symmetries of an object's canonical frame (of shape, print and joints
/// together: the rotations that map the object onto itself in every joint state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Symmetry {
    /// None known.
    None,
    /// Any rotation about canonical +Z (listed in `gt.json` as BOP discretises it:
    /// [`agentstar_geom::truth::continuous_symmetry`], 315 turns 1.14° apart).
    ContinuousZ,
    /// A group of rotations that keep the Z axis ([`AxialGroup`]): turns about +Z and, where
    /// it has them, half-turns about horizontal axes (a plain box, a prism, a plain cylinder
    /// that may be turned upside down).
    Axial(AxialGroup),
}

/// A group of rotations that keep the canonical Z axis (as a line): the turns about +Z by
/// multiples of 360°/`fold` (`fold` 0: every turn), and, with `flip_deg`, the half-turns about
/// the horizontal axes at `flip_deg` + k·180°/`fold` from +X (every horizontal axis when
/// `fold` is 0). `fold` 1 without a flip is the identity alone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxialGroup {
    pub fold: u32,
    pub flip_deg: Option<f64>,
}

impl AxialGroup {
    /// The identity alone.
    pub const TRIVIAL: AxialGroup = AxialGroup {
        fold: 1,
        flip_deg: None,
    };
    /// Every turn about Z and every half-turn about a horizontal axis (a plain cylinder).
    pub const ROUND: AxialGroup = AxialGroup {
        fold: 0,
        flip_deg: Some(0.0),
    };

    /// The half-turn axes (degrees in [0, 180)) spaced by 180°/`fold`; `None` for `fold` 0.
    fn flip_axes(&self) -> Option<Vec<f64>> {
        let phi = self.flip_deg?;
        (self.fold > 0).then(|| {
            (0..self.fold)
                .map(|k| (phi + 180.0 * k as f64 / self.fold as f64).rem_euclid(180.0))
                .collect()
        })
    }

    /// Whether the half-turn about the horizontal axis at `psi_deg` is in the group.
    fn has_flip(&self, psi_deg: f64) -> bool {
        let Some(phi) = self.flip_deg else {
            return false;
        };
        self.fold == 0 || is_multiple(psi_deg - phi, 180.0 / self.fold as f64)
    }

    /// The rotations both groups hold (a group again: the largest common subgroup).
    pub fn intersect(&self, other: &AxialGroup) -> AxialGroup {
        let fold = match (self.fold, other.fold) {
            (0, f) | (f, 0) => f,
            (a, b) => gcd(a, b),
        };
        let flip_deg = match (self.flip_axes(), other.flip_axes()) {
            _ if self.flip_deg.is_none() || other.flip_deg.is_none() => None,
            (None, None) => self.flip_deg,
            (None, Some(_)) => other.flip_deg,
            (Some(axes), _) => axes.into_iter().find(|&psi| other.has_flip(psi)),
        };
        AxialGroup { fold, flip_deg }
    }

    /// Whether `q` is in the group (to 1e-6 rad).
    pub fn contains(&self, q: &UnitQuaternion) -> bool {
        let z = q * Vector3::z();
        if (z - Vector3::z()).norm() < 1e-6 {
            let x = q * Vector3::x();
            let turn = x.y.atan2(x.x).to_degrees();
            self.fold == 0 || is_multiple(turn, 360.0 / self.fold as f64)
        } else if (z + Vector3::z()).norm() < 1e-6 {
            // A half-turn about the horizontal axis at ψ sends +X to the direction at 2ψ.
            let x = q * Vector3::x();
            self.has_flip(0.5 * x.y.atan2(x.x).to_degrees())
        } else {
            false
        }
    }

    /// Every rotation of the group but the identity; a continuous turn as BOP discretises it.
    pub fn rotations(&self) -> Vec<UnitQuaternion> {
        let mut turns: Vec<UnitQuaternion> = match self.fold {
            0 => agentstar_geom::truth::continuous_symmetry(&Vector3::z_axis()),
            n => (1..n)
                .map(|k| {
                    UnitQuaternion::from_axis_angle(
                        &Vector3::z_axis(),
                        std::f64::consts::TAU * k as f64 / n as f64,
                    )
                })
                .collect(),
        };
        if let Some(phi) = self.flip_deg {
            let (s, c) = phi.to_radians().sin_cos();
            let flip = UnitQuaternion::from_axis_angle(
                &agentstar_geom::nalgebra::Unit::new_normalize(Vector3::new(c, s, 0.0)),
                std::f64::consts::PI,
            );
            let flips: Vec<UnitQuaternion> = std::iter::once(flip)
                .chain(turns.iter().map(|t| t * flip))
                .collect();
            turns.extend(flips);
        }
        turns
    }

    /// The group as the library lists symmetries.
    pub fn symmetry(&self) -> Symmetry {
        match (self.fold, self.flip_deg) {
            (1, None) => Symmetry::None,
            (0, None) => Symmetry::ContinuousZ,
            _ => Symmetry::Axial(*self),
        }
    }
}

fn is_multiple(x: f64, step: f64) -> bool {
    let r = (x / step).round();
    (x - r * step).abs() < 1e-6
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

impl Symmetry {
    /// The rotations of the canonical frame (identity excluded) that map the object onto
    /// itself, as `gt.json` lists them.
    pub fn rotations(&self) -> Vec<UnitQuaternion> {
        match self {
            Symmetry::None => vec![],
            Symmetry::ContinuousZ => agentstar_geom::truth::continuous_symmetry(&Vector3::z_axis()),
            Symmetry::Axial(g) => g.rotations(),
        }
    }
}

/// How a part's surface is coloured (its albedo, before shading).
#[derive(Debug, Clone, Copy)]
pub enum Appearance {
    /// The part's colour times a checker fixed to the part (six squares per canonical unit).
    Checker,
    /// The part's colour only: the appearance has every symmetry of the shape.
    Plain,
    /// Printed: the linear-RGB albedo of part `index` at a point in canonical rest
    /// coordinates (labels, keys, logos: what tells apart poses with the same outline).
    Printed(fn(usize, &Point3) -> [f64; 3]),
}

/// One object: of the library (borrowed text) or generated ([`crate::generate`], owned).
#[derive(Debug, Clone)]
pub struct ObjectSpec {
    pub name: Cow<'static, str>,
    pub family: Family,
    /// Size in metres of one canonical unit (the object's longest side).
    pub size_m: f64,
    /// The symmetries of shape *and* appearance (listed in `gt.json`, by which errors are
    /// reduced as in HOT3D/BOP). An object whose outline is symmetric but whose print is not
    /// (a can with a label) lists none.
    pub symmetry: Symmetry,
    pub appearance: Appearance,
    pub script: Cow<'static, str>,
}

impl ObjectSpec {
    /// Looks an object of the library up by name.
    pub fn find(name: &str) -> Option<&'static ObjectSpec> {
        LIBRARY.iter().find(|o| o.name == name)
    }
    /// An object of the library, or a generated one by its name (`gen-N`, N its seed).
    pub fn resolve(name: &str) -> Option<ObjectSpec> {
        match ObjectSpec::find(name) {
            Some(o) => Some(o.clone()),
            None => crate::generate::seed_of(name).map(crate::generate::generate_object),
        }
    }
    /// The names of every object of the library, in library order.
    pub fn names() -> Vec<&'static str> {
        LIBRARY.iter().map(|o| o.name.as_ref()).collect()
    }
}

use agentstar_geom::{Point3, UnitQuaternion, Vector3};
use std::borrow::Cow;

/// Every object, grouped by family: the default suites' objects, then the hard suite's
/// (outlines that repeat under rotations or part swaps, told apart only by their print).
pub static LIBRARY: &[ObjectSpec] = &[
    // ── ARCTIC-like: hand-held, articulated ──
    ObjectSpec {
        name: Cow::Borrowed("box"),
        family: Family::Arctic,
        size_m: 0.24,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A box with a hinged lid.
let body = box(1.0, 0.7, 0.48, 0.02) - box(0.92, 0.62, 0.5).translate(0, 0, 0.06);
part("body", body.translate(0, 0, -0.04).color("#c8553d"));
part("lid", box(1.0, 0.7, 0.06, 0.01).translate(0, 0, 0.23).color("#f2d0a4"));
joint(#{ name: "lid_hinge", type: "revolute", child: "lid", origin: [0, 0.35, 0.2], axis: [-1, 0, 0], limit: [0, 110] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("laptop"),
        family: Family::Arctic,
        size_m: 0.3,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A laptop: a base with a keyboard well and a screen hinged at the back.
let base = box(1.0, 0.7, 0.05, 0.01) - box(0.8, 0.35, 0.03).translate(0, 0.08, 0.03);
part("base", base.translate(0, 0, -0.025).color("#5c6f7b"));
part("screen", box(1.0, 0.7, 0.03, 0.008).translate(0, 0, 0.016).color("#22313a"));
joint(#{ name: "screen_hinge", type: "revolute", child: "screen", origin: [0, 0.35, 0.0], axis: [-1, 0, 0], limit: [0, 150] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("notebook"),
        family: Family::Arctic,
        size_m: 0.24,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A notebook: pages on the back cover, a front cover hinged along the spine.
let back = box(1.0, 0.74, 0.02).translate(0, 0, -0.025) + box(0.95, 0.7, 0.04).translate(0.02, 0, 0.0);
part("back", back.color("#2a9d8f"));
part("cover", box(1.0, 0.74, 0.015).translate(0, 0, 0.028).color("#e9c46a"));
joint(#{ name: "spine", type: "revolute", child: "cover", origin: [-0.5, 0, 0.02], axis: [0, -1, 0], limit: [0, 170] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("ketchup"),
        family: Family::Arctic,
        size_m: 0.2,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A ketchup bottle with a flip-top cap.
let body = lathe([[0, -0.5], [0.2, -0.5], [0.22, -0.46], [0.22, 0.18], [0.13, 0.33], [0.09, 0.36], [0, 0.36]]);
let neck = cylinder(0.09, 0.08).translate(0, 0, 0.39);
part("bottle", (body + neck).color("#b22222"));
part("cap", (cylinder(0.09, 0.05).translate(0, 0, 0.455) + box(0.06, 0.05, 0.03).translate(0, -0.1, 0.455)).color("#f5f5f0"));
joint(#{ name: "cap_hinge", type: "revolute", child: "cap", origin: [0, 0.09, 0.43], axis: [-1, 0, 0], limit: [0, 160] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("phone"),
        family: Family::Arctic,
        size_m: 0.11,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A flip phone: a keypad half and a screen half hinged at one end.
part("keypad", (box(0.46, 1.0, 0.09, 0.02) + box(0.3, 0.5, 0.02).translate(0, -0.15, 0.045)).translate(0, 0, -0.045).color("#3d405b"));
part("flip", box(0.46, 1.0, 0.07, 0.02).translate(0, 0, 0.045).color("#81b29a"));
joint(#{ name: "flip_hinge", type: "revolute", child: "flip", origin: [0, 0.5, 0.01], axis: [-1, 0, 0], limit: [0, 165] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("waffleiron"),
        family: Family::Arctic,
        size_m: 0.28,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A waffle iron: round plates with handles, the top one hinged at the back.
part("base", (cylinder(0.4, 0.16).translate(0, 0.08, -0.08) + box(0.14, 0.26, 0.06).translate(0, -0.37, -0.1)).color("#4a4e69"));
part("top", (cylinder(0.4, 0.12).translate(0, 0.08, 0.06) + box(0.14, 0.26, 0.05).translate(0, -0.37, 0.05)).color("#9a8c98"));
joint(#{ name: "top_hinge", type: "revolute", child: "top", origin: [0, 0.48, 0.0], axis: [-1, 0, 0], limit: [0, 100] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("scissors"),
        family: Family::Arctic,
        size_m: 0.2,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// Scissors: two blades with ring handles turning about a pivot screw.
let blade = box(0.62, 0.08, 0.02).translate(0.19, 0.0, 0) + torus(0.1, 0.028).translate(-0.3, -0.09, 0) + box(0.2, 0.05, 0.02).translate(-0.12, -0.05, 0);
part("lower", blade.translate(0, 0, -0.011).color("#e76f51"));
part("upper", blade.mirror("y").translate(0, 0, 0.011).color("#264653"));
joint(#{ name: "pivot", type: "revolute", child: "upper", origin: [0, 0, 0], axis: [0, 0, -1], limit: [0, 45] });
"##,
        ),
    },
    // ── HOT3D-like: rigid ──
    ObjectSpec {
        name: Cow::Borrowed("mug"),
        family: Family::Hot3d,
        size_m: 0.12,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A mug with a handle.
let handle = box(0.22, 0.08, 0.07).translate(0.4, 0, 0.22) + box(0.22, 0.08, 0.07).translate(0.4, 0, -0.22) + box(0.07, 0.08, 0.51).translate(0.475, 0, 0);
let cup = cylinder(0.32, 0.8) - cylinder(0.28, 0.8).translate(0, 0, 0.06);
part("mug", (cup + handle).translate(-0.095, 0, 0).color("#f4a261"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("bottle"),
        family: Family::Hot3d,
        size_m: 0.22,
        symmetry: Symmetry::ContinuousZ,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A water bottle (symmetric about its axis).
part("bottle", lathe([[0, -0.5], [0.17, -0.5], [0.18, -0.48], [0.18, 0.15], [0.07, 0.32], [0.06, 0.42], [0.065, 0.5], [0, 0.5]], 40).color("#4ea8de"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("can"),
        family: Family::Hot3d,
        size_m: 0.12,
        symmetry: Symmetry::ContinuousZ,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A drinks can (symmetric about its axis).
part("can", lathe([[0, -0.5], [0.26, -0.5], [0.3, -0.44], [0.3, 0.4], [0.24, 0.5], [0, 0.5]], 40).color("#c1121f"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("keyboard"),
        family: Family::Hot3d,
        size_m: 0.42,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A keyboard: a flat case, a key field and a number pad.
let shell = box(1.0, 0.34, 0.05, 0.01);
let keys = box(0.66, 0.24, 0.03).translate(-0.12, -0.02, 0.035) + box(0.2, 0.24, 0.03).translate(0.36, -0.02, 0.035);
part("keyboard", (shell + keys).translate(0, 0, -0.02).color("#adb5bd"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("cellphone"),
        family: Family::Hot3d,
        size_m: 0.15,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A smartphone with a camera bump.
part("phone", (box(0.48, 1.0, 0.08, 0.03) + box(0.16, 0.2, 0.04, 0.01).translate(0.1, 0.34, -0.05)).color("#343a40"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("spray"),
        family: Family::Hot3d,
        size_m: 0.24,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A spray bottle: a round body, a trigger head with a nozzle.
let body = lathe([[0, -0.5], [0.2, -0.5], [0.2, 0.2], [0.08, 0.33], [0, 0.33]], 32);
let head = box(0.14, 0.34, 0.16).translate(0, -0.08, 0.38);
let nozzle = box(0.07, 0.1, 0.07).translate(0, -0.28, 0.41);
part("spray", (body + (head + nozzle)).translate(0, 0.04, 0.02).color("#90be6d"));
"##,
        ),
    },
    // ── iTACO-like: furniture ──
    ObjectSpec {
        name: Cow::Borrowed("cabinet"),
        family: Family::Itaco,
        size_m: 0.8,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A cabinet: a door on the upper compartment, a drawer in the lower one.
let shell = box(0.8, 0.5, 1.0) - box(0.72, 0.48, 0.44).translate(0, -0.05, 0.23) - box(0.72, 0.48, 0.42).translate(0, -0.05, -0.24);
part("body", shell.color("#bc6c25"));
part("door", (box(0.72, 0.02, 0.44).translate(0, -0.26, 0.23) + box(0.03, 0.04, 0.12).translate(0.3, -0.285, 0.23)).color("#dda15e"));
part("drawer", (box(0.7, 0.46, 0.4).translate(0, -0.03, -0.24) + box(0.16, 0.04, 0.03).translate(0, -0.27, -0.2)).color("#fefae0"));
joint(#{ name: "door_hinge", type: "revolute", child: "door", origin: [-0.36, -0.26, 0.23], axis: [0, 0, -1], limit: [0, 110] });
joint(#{ name: "drawer_slide", type: "prismatic", child: "drawer", axis: [0, -1, 0], limit: [0, 0.38] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("microwave"),
        family: Family::Itaco,
        size_m: 0.5,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// A microwave: a cavity on the left, a control panel, a door hinged on its left edge.
let shell = box(1.0, 0.6, 0.56) - box(0.62, 0.56, 0.44).translate(-0.15, -0.05, 0);
part("body", (shell + box(0.2, 0.02, 0.3).translate(0.33, -0.305, 0.05)).color("#e5e5e5"));
part("door", (box(0.66, 0.03, 0.5).translate(-0.15, -0.315, 0) + box(0.03, 0.04, 0.3).translate(0.12, -0.34, 0)).color("#2b2d42"));
joint(#{ name: "door_hinge", type: "revolute", child: "door", origin: [-0.48, -0.315, 0], axis: [0, 0, -1], limit: [0, 120] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("oven"),
        family: Family::Itaco,
        size_m: 0.7,
        symmetry: Symmetry::None,
        appearance: Appearance::Checker,
        script: Cow::Borrowed(
            r##"// An oven: a cavity, knobs on the front panel, a door hinged along its bottom edge.
let shell = box(0.9, 0.8, 0.9) - box(0.74, 0.7, 0.55).translate(0, -0.1, -0.06);
let knobs = cylinder(0.04, 0.04).rotate_x(90).translate(-0.25, -0.415, 0.35) + cylinder(0.04, 0.04).rotate_x(90).translate(0.25, -0.415, 0.35);
part("body", (shell + knobs).color("#6c757d"));
part("door", (box(0.78, 0.04, 0.6).translate(0, -0.42, -0.06) + box(0.5, 0.04, 0.04).translate(0, -0.455, 0.18)).color("#212529"));
joint(#{ name: "door_hinge", type: "revolute", child: "door", origin: [0, -0.42, -0.36], axis: [1, 0, 0], limit: [0, 90] });
"##,
        ),
    },
    // ── The hard suite's objects: same outline under a rotation or a part swap, told apart
    // only by their print (or, for the plain bottle, not at all) ──
    ObjectSpec {
        name: Cow::Borrowed("labelcan"),
        family: Family::Hot3d,
        size_m: 0.12,
        symmetry: Symmetry::None,
        appearance: Appearance::Printed(paint_labelcan),
        script: Cow::Borrowed(
            r##"// A drinks can with a printed label on half of its side: the outline is symmetric about
// the axis, the print is not; the label is a thin part of its own colour.
part("can", lathe([[0, -0.5], [0.26, -0.5], [0.3, -0.44], [0.3, 0.4], [0.24, 0.5], [0, 0.5]], 48).color("#c1121f"));
let sleeve = cylinder(0.306, 0.6) - cylinder(0.301, 0.62);
part("label", intersection(sleeve, box(0.4, 0.9, 0.7).translate(0.2, 0, 0)).color("#d9cc9e"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("plainbottle"),
        family: Family::Hot3d,
        size_m: 0.22,
        symmetry: Symmetry::ContinuousZ,
        appearance: Appearance::Plain,
        script: Cow::Borrowed(
            r##"// A plain bottle: symmetric about its axis in shape and in colour.
part("bottle", lathe([[0, -0.5], [0.17, -0.5], [0.18, -0.48], [0.18, 0.15], [0.07, 0.32], [0.06, 0.42], [0.065, 0.5], [0, 0.5]], 48).color("#5fa8d3"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("printmug"),
        family: Family::Hot3d,
        size_m: 0.12,
        symmetry: Symmetry::None,
        appearance: Appearance::Printed(paint_printmug),
        script: Cow::Borrowed(
            r##"// A mug with a handle and a printed badge on one side (a thin part of its own colour).
let handle = box(0.22, 0.08, 0.07).translate(0.4, 0, 0.22) + box(0.22, 0.08, 0.07).translate(0.4, 0, -0.22) + box(0.07, 0.08, 0.51).translate(0.475, 0, 0);
let cup = cylinder(0.32, 0.8) - cylinder(0.28, 0.8).translate(0, 0, 0.06);
part("mug", (cup + handle).translate(-0.095, 0, 0).color("#e9e4d8"));
let sleeve = cylinder(0.326, 0.4) - cylinder(0.321, 0.42);
part("badge", intersection(sleeve, box(0.4, 0.4, 0.5).translate(0, 0.2, 0)).translate(-0.095, 0, 0).color("#14339a"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("highmug"),
        family: Family::Hot3d,
        size_m: 0.12,
        symmetry: Symmetry::None,
        appearance: Appearance::Printed(paint_printmug),
        script: Cow::Borrowed(
            r##"// The printed mug with its handle high on the side, as most mugs are: its outline tells
// top from bottom where the handle is in view, and is the same under any turn about the
// body's axis where the handle is hidden. Not in a suite: the figures of `track --bake` on
// an uncoloured mesh whose handle fixes the basin where it is seen.
let handle = box(0.22, 0.08, 0.07).translate(0.4, 0, 0.3) + box(0.22, 0.08, 0.07).translate(0.4, 0, -0.06) + box(0.07, 0.08, 0.43).translate(0.475, 0, 0.12);
let cup = cylinder(0.32, 0.8) - cylinder(0.28, 0.8).translate(0, 0, 0.06);
part("mug", (cup + handle).translate(-0.095, 0, 0).color("#e9e4d8"));
let sleeve = cylinder(0.326, 0.4) - cylinder(0.321, 0.42);
part("badge", intersection(sleeve, box(0.4, 0.4, 0.5).translate(0, 0.2, 0)).translate(-0.095, 0, 0).color("#14339a"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("kettle"),
        family: Family::Hot3d,
        size_m: 0.22,
        symmetry: Symmetry::None,
        appearance: Appearance::Printed(paint_kettle),
        script: Cow::Borrowed(
            r##"// A kettle: a round steel body, a lid knob, a spout and a handle on opposite sides.
let body = lathe([[0, -0.42], [0.3, -0.42], [0.34, -0.3], [0.34, 0.02], [0.26, 0.2], [0.15, 0.26], [0, 0.26]], 48);
let knob = cylinder(0.05, 0.1).translate(0, 0, 0.28);
let spout = cylinder(0.05, 0.34).rotate_y(50).translate(0.38, 0, 0.02);
let handle = box(0.08, 0.1, 0.5).translate(-0.5, 0, -0.03) + box(0.3, 0.09, 0.08).translate(-0.37, 0, 0.1) + box(0.3, 0.09, 0.08).translate(-0.37, 0, -0.2);
part("kettle", (body + knob + handle + spout).translate(0.0, 0, 0.045).color("#b8bcc2"));
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("twinlaptop"),
        family: Family::Arctic,
        size_m: 0.3,
        symmetry: Symmetry::None,
        appearance: Appearance::Printed(paint_twinlaptop),
        script: Cow::Borrowed(
            r##"// A laptop whose base and lid are slabs of the same outline: keys and a touchpad on the
// base, a screen inside the lid, a logo outside; the print is thin parts of their own colours.
part("base", box(1.0, 0.7, 0.03, 0.006).translate(0, 0, -0.016).color("#737880"));
part("lid", box(1.0, 0.7, 0.03, 0.006).translate(0, 0, 0.016).color("#737880"));
part("keys", box(0.84, 0.36, 0.004).translate(0, 0.12, 0).color("#08080a"));
part("touchpad", box(0.26, 0.19, 0.004).translate(0, -0.215, 0).color("#a6a8b3"));
part("screen", box(0.9, 0.6, 0.004).translate(0, 0, 0).color("#04050a"));
part("logo", cylinder(0.1, 0.004).translate(0, 0, 0.031).color("#e6e6eb"));
joint(#{ name: "hinge", type: "revolute", child: ["lid", "screen", "logo"], origin: [0, 0.35, 0.0], axis: [-1, 0, 0], limit: [0, 150] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("drawerbox"),
        family: Family::Arctic,
        size_m: 0.2,
        symmetry: Symmetry::None,
        appearance: Appearance::Printed(paint_drawerbox),
        script: Cow::Borrowed(
            r##"// A nearly cubic wooden case with a drawer (and its knob) in the front face.
let shell = box(1.0, 0.94, 0.97, 0.02) - box(0.86, 0.9, 0.36).translate(0, -0.04, -0.24);
part("body", shell.color("#a47148"));
part("drawer", (box(0.84, 0.88, 0.34).translate(0, -0.03, -0.24) + box(0.2, 0.04, 0.05).translate(0, -0.485, -0.24)).color("#d4a373"));
joint(#{ name: "drawer_slide", type: "prismatic", child: "drawer", axis: [0, -1, 0], limit: [0, 0.5] });
"##,
        ),
    },
    ObjectSpec {
        name: Cow::Borrowed("shears"),
        family: Family::Arctic,
        size_m: 0.2,
        symmetry: Symmetry::None,
        appearance: Appearance::Printed(paint_shears),
        script: Cow::Borrowed(
            r##"// Shears of three parts: two mirror-image blades with ring handles about a pivot screw,
// and a lock lever hinged on the lower handle. The blades differ by their rings' colours.
let blade = box(0.62, 0.08, 0.02).translate(0.19, 0.0, 0) + torus(0.1, 0.028).translate(-0.3, -0.09, 0) + box(0.2, 0.05, 0.02).translate(-0.12, -0.05, 0);
part("lower", blade.translate(0, 0, -0.011).color("#e76f51"));
part("upper", blade.mirror("y").translate(0, 0, 0.011).color("#264653"));
part("lock", box(0.16, 0.035, 0.018).translate(-0.2, -0.05, -0.031).color("#f4d35e"));
joint(#{ name: "pivot", type: "revolute", child: "upper", origin: [0, 0, 0], axis: [0, 0, -1], limit: [0, 45] });
joint(#{ name: "lock_hinge", type: "revolute", child: "lock", origin: [-0.13, -0.05, -0.031], axis: [0, 0, 1], limit: [0, 70] });
"##,
        ),
    },
];

// ── Prints of the hard suite's objects (linear RGB albedo at canonical rest coordinates) ──

/// A deterministic value in [0, 1) for an integer cell.
fn cell_hash(i: i64, j: i64, salt: u32) -> f64 {
    crate::noise::hash01((i + 4096) as u32, (j + 4096) as u32, salt)
}

/// Can: red, a cream label over half the side with two lines of dark "lettering", a gold
/// ring near the top, silver ends.
fn paint_labelcan(_part: usize, p: &Point3) -> [f64; 3] {
    let r = (p.x * p.x + p.y * p.y).sqrt();
    if p.z > 0.44 || p.z < -0.46 || r < 0.25 {
        return [0.55, 0.56, 0.6];
    }
    if (0.34..0.39).contains(&p.z) {
        return [0.75, 0.55, 0.12];
    }
    let theta = p.y.atan2(p.x);
    if p.z.abs() < 0.3 && theta.abs() < 1.6 {
        // Two rows of letters: large ones above, small ones below.
        let (cw, z0, z1, salt) = if p.z > 0.0 {
            (0.2, 0.06, 0.22, 11)
        } else {
            (0.11, -0.2, -0.08, 12)
        };
        if p.z > z0 && p.z < z1 {
            let u = theta / cw;
            let cell = u.floor();
            let f = u - cell;
            if f > 0.15 && f < 0.85 && cell_hash(cell as i64, salt, 5) < 0.7 {
                return [0.04, 0.08, 0.35];
            }
        }
        return [0.85, 0.8, 0.62];
    }
    [0.6, 0.04, 0.05]
}

/// Mug: off-white, a blue badge with a red centre on the side at +Y, a blue rim band over
/// the half at +Y.
fn paint_printmug(_part: usize, p: &Point3) -> [f64; 3] {
    let (x, y) = (p.x + 0.095, p.y);
    let r = (x * x + y * y).sqrt();
    if r > 0.3 && r < 0.34 {
        let theta = y.atan2(x);
        let arc = 0.32 * (theta - std::f64::consts::FRAC_PI_2);
        let d = (arc * arc + (p.z - 0.0).powi(2)).sqrt();
        if d < 0.09 {
            return [0.75, 0.08, 0.1];
        }
        if d < 0.2 {
            return [0.08, 0.2, 0.6];
        }
        if p.z > 0.28 && y > 0.0 {
            return [0.08, 0.2, 0.6];
        }
    }
    [0.82, 0.79, 0.72]
}

/// Kettle: steel, a black handle and base band, a dark brand plate with light letters on
/// the side at −Y.
fn paint_kettle(_part: usize, p: &Point3) -> [f64; 3] {
    let x = p.x;
    if x < -0.36 {
        return [0.04, 0.04, 0.045];
    }
    if p.z < -0.3 && x.abs() < 0.36 {
        return [0.05, 0.05, 0.06];
    }
    if p.y < -0.2 && x.abs() < 0.16 && (p.z + 0.14).abs() < 0.09 {
        let cell = ((x + 0.16) / 0.05).floor();
        let f = (x + 0.16) / 0.05 - cell;
        if (p.z + 0.14).abs() < 0.04 && f > 0.2 && f < 0.8 && cell_hash(cell as i64, 3, 9) < 0.75 {
            return [0.8, 0.8, 0.75];
        }
        return [0.06, 0.1, 0.2];
    }
    [0.55, 0.57, 0.6]
}

/// Laptop: keys and a touchpad on the base's top face, rubber feet under it; a black
/// screen in a bezel inside the lid, a light logo outside; grey aluminium elsewhere. Parts:
/// base, lid, keys, touchpad, screen, logo (the last four thin slabs over the first two).
fn paint_twinlaptop(part: usize, p: &Point3) -> [f64; 3] {
    let alu = [0.45, 0.47, 0.5];
    match part {
        2 => return paint_twinlaptop(0, &Point3::new(p.x, p.y, p.z.max(-0.003))),
        3 => return [0.65, 0.66, 0.7],
        4 => return [0.015, 0.02, 0.03],
        5 => return [0.9, 0.9, 0.92],
        _ => {}
    }
    if part == 0 {
        if p.z > -0.004 {
            if p.x.abs() < 0.42 && p.y > -0.06 && p.y < 0.3 {
                let (u, v) = ((p.x + 0.42) / 0.07, (p.y + 0.06) / 0.07);
                let (fu, fv) = (u - u.floor(), v - v.floor());
                if fu > 0.12 && fu < 0.88 && fv > 0.12 && fv < 0.88 {
                    return [0.03, 0.03, 0.035];
                }
            }
            if p.x.abs() < 0.13 && p.y > -0.31 && p.y < -0.12 {
                return [0.65, 0.66, 0.7];
            }
        } else if p.z < -0.028 {
            for (fx, fy) in [(-0.42, -0.28), (0.42, -0.28), (-0.42, 0.28), (0.42, 0.28)] {
                if (p.x - fx).powi(2) + (p.y - fy).powi(2) < 0.04f64.powi(2) {
                    return [0.02, 0.02, 0.02];
                }
            }
        }
        return alu;
    }
    if p.z < 0.004 {
        if p.x.abs() < 0.45 && p.y.abs() < 0.3 {
            return [0.015, 0.02, 0.03];
        }
    } else if p.z > 0.028 && p.x * p.x + p.y * p.y < 0.1f64.powi(2) {
        return [0.9, 0.9, 0.92];
    }
    alu
}

/// Case: wood with a grain, a light inlaid diamond on the top face, a lighter drawer front
/// with a brass knob.
fn paint_drawerbox(part: usize, p: &Point3) -> [f64; 3] {
    let grain = 0.85 + 0.15 * (38.0 * (p.x + 0.25 * (6.0 * p.z + 3.0 * p.y).sin())).sin();
    if part == 1 {
        if p.y < -0.47 {
            return [0.8, 0.6, 0.18];
        }
        return [0.62 * grain, 0.42 * grain, 0.22 * grain];
    }
    if p.z > 0.47 && p.x.abs() + p.y.abs() < 0.25 {
        return [0.85, 0.8, 0.65];
    }
    [0.38 * grain, 0.2 * grain, 0.09 * grain]
}

/// Shears: steel blades, an orange ring on the lower blade, a black one on the upper, a
/// yellow lock; an engraved mark on the lower blade.
fn paint_shears(part: usize, p: &Point3) -> [f64; 3] {
    let steel = [0.55, 0.57, 0.6];
    match part {
        0 if p.x < -0.17 => [0.85, 0.3, 0.06],
        1 if p.x < -0.17 => [0.03, 0.03, 0.03],
        0 if p.x > 0.2 && p.x < 0.35 && p.y.abs() < 0.02 => [0.15, 0.15, 0.17],
        2 => [0.9, 0.75, 0.2],
        _ => steel,
    }
}
