//! Objects generated at random from primitives and joints, for a suite nobody tuned.
//!
//! A seed draws a [`Recipe`]: a body primitive with its proportions (a round can, a capsule,
//! a prism, a block, a frustum), up to two joints with their child parts (a hinged lid, a
//! sliding cap, a folding handle on top; a drawer, a door or a lever on the side) and up to
//! two prints, thin parts of their own colour (a label over part of a round side, a band, a
//! badge on a flat face, a disc on the top). The recipe is written out as a scene script, so
//! the known model goes through the scene builder as a model-written one would, and carries
//! its true symmetries: the rotations that map shape, print and joints onto themselves
//! ([`Recipe::group`]), by which errors are reduced as in BOP. The recipe lays every round
//! primitive out with 48 segments and every print's angle on multiples of 7.5°, so the
//! tessellated mesh has each symmetry of the ideal shape that the group lists (a test checks
//! the built meshes against the groups).
//!
//! An object is named `gen-N` after its seed N; to look at a single case, change the seed
//! (`agentstar synth --object gen-7`, `agentstar bench --suite general --only gen-7`), never a
//! constant of the generator.

use crate::objects::{Appearance, AxialGroup, Family, ObjectSpec};
use agentstar_optim::Rng;
use std::borrow::Cow;
use std::fmt::Write;

/// The body: every primitive centred at the origin with its axis on Z, longest side 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Body {
    /// A cylinder (a can).
    Round { radius: f64, height: f64 },
    /// A cylinder with hemispherical ends; `length` of the straight section.
    Capsule { radius: f64, length: f64 },
    /// A regular prism of `sides` sides, a vertex on +X, `radius` to its vertices.
    Prism {
        sides: u32,
        radius: f64,
        height: f64,
    },
    /// A box with full extents.
    Block { x: f64, y: f64, z: f64 },
    /// A truncated cone.
    Frustum { bottom: f64, top: f64, height: f64 },
}

/// A joint on the body's top, with its child part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Top {
    /// A slab of the top's outline hinged along its +Y edge.
    HingedLid { thickness: f64, limit_deg: f64 },
    /// A cap of the top's outline (a little wider) that slides up along Z.
    SlidingCap { height: f64, travel: f64 },
    /// A bail handle over the top turning about X.
    FoldingHandle { height: f64, limit_deg: f64 },
}

/// A joint on the body's side, with its child part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Side {
    /// A drawer in the −Y face of a block (in a cavity), sliding out along −Y.
    Drawer { travel_share: f64 },
    /// A door over the −Y face of a block, hinged on its −X edge.
    Door { limit_deg: f64 },
    /// A lever on the +X side, hinged at its top about Y.
    Lever { length_share: f64, limit_deg: f64 },
}

/// A print: a thin part of its own colour on the body, with no joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Print {
    /// A label over `angle_deg` of a round side, centred at `turn_deg` from +X.
    Label {
        angle_deg: f64,
        turn_deg: f64,
        z_centre: f64,
        height: f64,
    },
    /// A band all round a round side.
    Band { z_centre: f64, height: f64 },
    /// A rectangular badge on the flat side face whose outward normal is at `face_deg` from
    /// +X, its centre `u` along the face (counter-clockwise) and `v` up from the face's centre.
    Badge {
        face_deg: f64,
        u: f64,
        v: f64,
        width: f64,
        height: f64,
    },
    /// A disc on the top face, on the axis.
    TopDisc { radius: f64 },
}

/// Everything a generated object is made of.
#[derive(Debug, Clone, PartialEq)]
pub struct Recipe {
    pub seed: u64,
    pub body: Body,
    pub top: Option<Top>,
    pub side: Option<Side>,
    pub prints: Vec<Print>,
    /// Colours (`#rrggbb`), all different: the body's first, then each further part's in
    /// script order.
    pub colours: Vec<&'static str>,
    /// Metres per canonical unit.
    pub size_m: f64,
}

/// Distinct colours parts are drawn from (no two parts of an object share one, so no
/// symmetry can swap two parts).
const PALETTE: [&str; 12] = [
    "#c8553d", "#2a9d8f", "#e9c46a", "#264653", "#8d99ae", "#6a4c93", "#f4a261", "#1d3557",
    "#90be6d", "#b5179e", "#d9cc9e", "#3a5a40",
];

/// The name of the object generated from `seed`.
pub fn object_name(seed: u64) -> String {
    format!("gen-{seed}")
}

/// The seed of a generated object's name (`gen-N`, N without leading zeros).
pub fn seed_of(name: &str) -> Option<u64> {
    let n: u64 = name.strip_prefix("gen-")?.parse().ok()?;
    (object_name(n) == name).then_some(n)
}

/// The object generated from `seed` (deterministic).
pub fn generate_object(seed: u64) -> ObjectSpec {
    Recipe::random(seed).spec()
}

impl Body {
    /// The z of the top (and, negated, of the bottom).
    pub fn half_height(&self) -> f64 {
        match *self {
            Body::Round { height, .. }
            | Body::Prism { height, .. }
            | Body::Frustum { height, .. } => height / 2.0,
            Body::Block { z, .. } => z / 2.0,
            Body::Capsule { radius, length } => length / 2.0 + radius,
        }
    }

    /// The radius of a round side (and the half-height of its straight section).
    fn round_side(&self) -> Option<(f64, f64)> {
        match *self {
            Body::Round { radius, height } => Some((radius, height / 2.0)),
            Body::Capsule { radius, length } => Some((radius, length / 2.0)),
            _ => None,
        }
    }

    /// A solid of the top's outline, `scale` times as wide, `thickness` tall, centred at the
    /// origin; `None` for a domed top.
    fn top_section(&self, scale: f64, thickness: f64) -> Option<String> {
        match *self {
            Body::Round { radius, .. } => Some(format!(
                "cylinder({:.4}, {thickness:.4}, 48)",
                radius * scale
            )),
            Body::Prism { sides, radius, .. } => Some(format!(
                "cylinder({:.4}, {thickness:.4}, {sides})",
                radius * scale
            )),
            Body::Block { x, y, .. } => Some(format!(
                "box({:.4}, {:.4}, {thickness:.4})",
                x * scale,
                y * scale
            )),
            Body::Frustum { top, .. } => {
                Some(format!("cylinder({:.4}, {thickness:.4}, 48)", top * scale))
            }
            Body::Capsule { .. } => None,
        }
    }

    /// Half the top's extent along Y (where a lid's hinge sits) and along X (a handle's legs).
    fn top_half_extents(&self) -> (f64, f64) {
        match *self {
            Body::Round { radius, .. } | Body::Capsule { radius, .. } => (radius, radius),
            Body::Prism { sides, radius, .. } => {
                let n = sides as f64;
                let y = (0..sides)
                    .map(|k| radius * (std::f64::consts::TAU * k as f64 / n).sin())
                    .fold(0.0, f64::max);
                (y, radius * (std::f64::consts::PI / n).cos())
            }
            Body::Block { x, y, .. } => (y / 2.0, x / 2.0),
            Body::Frustum { top, .. } => (top, top),
        }
    }

    /// The largest radius of the top face a disc may cover.
    fn top_inradius(&self) -> f64 {
        match *self {
            Body::Round { radius, .. } | Body::Capsule { radius, .. } => radius,
            Body::Prism { sides, radius, .. } => {
                radius * (std::f64::consts::PI / sides as f64).cos()
            }
            Body::Block { x, y, .. } => x.min(y) / 2.0,
            Body::Frustum { top, .. } => top,
        }
    }

    /// The distance from the axis to the body's side along +X (its widest there).
    fn side_x(&self) -> f64 {
        match *self {
            Body::Round { radius, .. }
            | Body::Capsule { radius, .. }
            | Body::Prism { radius, .. } => radius,
            Body::Block { x, .. } => x / 2.0,
            Body::Frustum { bottom, top, .. } => bottom.max(top),
        }
    }

    /// The flat side faces: outward normal's angle from +X (degrees), distance from the axis,
    /// width and height.
    fn faces(&self) -> Vec<(f64, f64, f64, f64)> {
        match *self {
            Body::Block { x, y, z } => vec![
                (0.0, x / 2.0, y, z),
                (90.0, y / 2.0, x, z),
                (180.0, x / 2.0, y, z),
                (270.0, y / 2.0, x, z),
            ],
            Body::Prism {
                sides,
                radius,
                height,
            } => {
                let half = std::f64::consts::PI / sides as f64;
                (0..sides)
                    .map(|k| {
                        (
                            (k as f64 + 0.5) * 360.0 / sides as f64,
                            radius * half.cos(),
                            2.0 * radius * half.sin(),
                            height,
                        )
                    })
                    .collect()
            }
            _ => vec![],
        }
    }

    /// The body's own symmetries.
    pub fn group(&self) -> AxialGroup {
        match *self {
            Body::Round { .. } | Body::Capsule { .. } => AxialGroup::ROUND,
            Body::Prism { sides, .. } => AxialGroup {
                fold: sides,
                flip_deg: Some(0.0),
            },
            Body::Block { x, y, .. } => AxialGroup {
                fold: if x == y { 4 } else { 2 },
                flip_deg: Some(0.0),
            },
            Body::Frustum { .. } => AxialGroup {
                fold: 0,
                flip_deg: None,
            },
        }
    }

    fn describe(&self) -> String {
        match *self {
            Body::Round { radius, height } => {
                format!("a cylinder of radius {radius:.3} and height {height:.3}")
            }
            Body::Capsule { radius, length } => {
                format!("a capsule of radius {radius:.3} and straight length {length:.3}")
            }
            Body::Prism {
                sides,
                radius,
                height,
            } => format!("a prism of {sides} sides, radius {radius:.3} and height {height:.3}"),
            Body::Block { x, y, z } => format!("a block {x:.3} × {y:.3} × {z:.3}"),
            Body::Frustum {
                bottom,
                top,
                height,
            } => format!("a frustum of radii {bottom:.3} and {top:.3}, height {height:.3}"),
        }
    }
}

/// The flip about the horizontal axis at `deg` when `centred`, else the identity alone.
fn flip_if(centred: bool, deg: f64) -> AxialGroup {
    AxialGroup {
        fold: 1,
        flip_deg: centred.then_some(deg),
    }
}

impl Top {
    fn group(&self, body: &Body) -> AxialGroup {
        match self {
            // A cap of the top's outline sliding along the axis keeps the body's turns but
            // not its flips; a hinge or a handle's axis is moved by every turn.
            Top::SlidingCap { .. } => AxialGroup {
                fold: body.group().fold,
                flip_deg: None,
            },
            Top::HingedLid { .. } | Top::FoldingHandle { .. } => AxialGroup::TRIVIAL,
        }
    }
}

impl Print {
    fn group(&self) -> AxialGroup {
        match *self {
            Print::Label {
                turn_deg, z_centre, ..
            } => flip_if(z_centre == 0.0, turn_deg),
            Print::Band { z_centre, .. } => AxialGroup {
                fold: 0,
                flip_deg: (z_centre == 0.0).then_some(0.0),
            },
            Print::Badge { face_deg, u, v, .. } => flip_if(u == 0.0 && v == 0.0, face_deg),
            Print::TopDisc { .. } => AxialGroup {
                fold: 0,
                flip_deg: None,
            },
        }
    }

    fn name(&self) -> &'static str {
        match self {
            Print::Label { .. } => "label",
            Print::Band { .. } => "band",
            Print::Badge { .. } => "badge",
            Print::TopDisc { .. } => "top_print",
        }
    }
}

/// A value drawn from `lo..hi`, rounded to 3 decimals (scripts carry 4).
fn draw(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
    (rng.range(lo, hi) * 1000.0).round() / 1000.0
}

/// An offset from a centre: 0 (centred) a third of the time, else at least `min` from it
/// either way, at most `max` (0 when `max` < `min`).
fn offset(rng: &mut Rng, min: f64, max: f64) -> f64 {
    if rng.uniform() < 1.0 / 3.0 || max < min {
        0.0
    } else {
        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        sign * draw(rng, min, max)
    }
}

impl Recipe {
    /// The recipe of `seed`. The seed's residue modulo 4 fixes the kind, so every four
    /// consecutive seeds hold one of each: 0 rigid without print (its symmetry is real), 1
    /// rigid with one or two prints, 2 articulated (one or two joints, maybe a print), 3 any
    /// number of joints and prints (0–2 each).
    pub fn random(seed: u64) -> Recipe {
        let mut rng = Rng::new(seed.wrapping_mul(0xA076_1D64_78BD_642F).wrapping_add(7));
        let body = random_body(&mut rng);
        let (joints, prints) = match seed % 4 {
            0 => (0, 0),
            1 => (0, 1 + rng.below(2)),
            2 => (1 + rng.below(2), rng.below(2)),
            _ => (rng.below(3), rng.below(3)),
        };
        let mut top = None;
        let mut side = None;
        let has_top = !matches!(body, Body::Capsule { .. });
        let on_top = match joints {
            0 => false,
            1 => has_top && rng.uniform() < 0.5,
            _ => has_top,
        };
        if on_top {
            top = Some(match rng.below(3) {
                0 => Top::HingedLid {
                    thickness: draw(&mut rng, 0.04, 0.08),
                    limit_deg: draw(&mut rng, 90.0, 130.0),
                },
                1 => Top::SlidingCap {
                    height: draw(&mut rng, 0.1, 0.2),
                    travel: draw(&mut rng, 0.2, 0.4),
                },
                _ => Top::FoldingHandle {
                    height: draw(&mut rng, 0.15, 0.25),
                    limit_deg: draw(&mut rng, 60.0, 90.0),
                },
            });
        }
        if joints >= 2 || (joints == 1 && !on_top) {
            let block = matches!(body, Body::Block { .. });
            side = Some(match if block { rng.below(3) } else { 2 } {
                0 => Side::Drawer {
                    travel_share: draw(&mut rng, 0.5, 0.85),
                },
                1 => Side::Door {
                    limit_deg: draw(&mut rng, 90.0, 120.0),
                },
                _ => Side::Lever {
                    length_share: draw(&mut rng, 0.3, 0.5),
                    limit_deg: draw(&mut rng, 40.0, 70.0),
                },
            });
        }
        let prints = random_prints(&mut rng, &body, top.is_some(), side.as_ref(), prints);
        let mut colours = PALETTE.to_vec();
        rng.shuffle(&mut colours);
        let parts = 1 + usize::from(top.is_some()) + usize::from(side.is_some()) + prints.len();
        colours.truncate(parts);
        Recipe {
            seed,
            body,
            top,
            side,
            prints,
            colours,
            size_m: draw(&mut rng, 0.1, 0.3),
        }
    }

    pub fn is_articulated(&self) -> bool {
        self.top.is_some() || self.side.is_some()
    }

    /// The rotations that map shape, print and joints onto themselves: the body's group
    /// intersected with each other part's (the parts' colours all differ, so no rotation
    /// swaps two of them).
    pub fn group(&self) -> AxialGroup {
        let mut g = self.body.group();
        if let Some(t) = &self.top {
            g = g.intersect(&t.group(&self.body));
        }
        if self.side.is_some() {
            g = g.intersect(&AxialGroup::TRIVIAL);
        }
        for p in &self.prints {
            g = g.intersect(&p.group());
        }
        g
    }

    /// The object: its script, symmetries, family (articulated: ARCTIC-like, rigid:
    /// HOT3D-like) and size; plain colours, so the print parts are all its appearance.
    pub fn spec(&self) -> ObjectSpec {
        ObjectSpec {
            name: Cow::Owned(object_name(self.seed)),
            family: if self.is_articulated() {
                Family::Arctic
            } else {
                Family::Hot3d
            },
            size_m: self.size_m,
            symmetry: self.group().symmetry(),
            appearance: Appearance::Plain,
            script: Cow::Owned(self.script()),
        }
    }

    /// The scene script.
    pub fn script(&self) -> String {
        let mut s = String::new();
        let mut colours = self.colours.iter();
        let mut colour = || colours.next().copied().unwrap_or("#808080");
        let zt = self.body.half_height();
        let _ = writeln!(
            s,
            "// Generated object {} (seed {}): {}.",
            object_name(self.seed),
            self.seed,
            self.body.describe()
        );
        let _ = writeln!(s, "// True symmetries: {}.", describe(&self.group()));
        let mut body = match self.body {
            Body::Round { radius, height } => format!("cylinder({radius:.4}, {height:.4}, 48)"),
            Body::Capsule { radius, length } => format!("capsule({radius:.4}, {length:.4}, 48)"),
            Body::Prism {
                sides,
                radius,
                height,
            } => format!("cylinder({radius:.4}, {height:.4}, {sides})"),
            Body::Block { x, y, z } => format!("box({x:.4}, {y:.4}, {z:.4})"),
            Body::Frustum {
                bottom,
                top,
                height,
            } => format!("cone({bottom:.4}, {top:.4}, {height:.4}, 48)"),
        };
        // A drawer's cavity: the cutter sticks out through the front face.
        let drawer = match (&self.side, &self.body) {
            (Some(Side::Drawer { travel_share }), &Body::Block { x, y, z }) => {
                let (cx, cy, cz, zc) = (0.7 * x, 0.7 * y, 0.4 * z, -0.15 * z);
                body = format!(
                    "({body} - box({cx:.4}, {:.4}, {cz:.4}).translate(0, {:.4}, {zc:.4}))",
                    cy + 0.1,
                    -y / 2.0 + (cy - 0.1) / 2.0
                );
                Some((x, y, cx, cy, cz, zc, *travel_share))
            }
            _ => None,
        };
        let _ = writeln!(s, "part(\"body\", {body}.color(\"{}\"));", colour());
        if let Some(top) = &self.top {
            let (hy, hx) = self.body.top_half_extents();
            match *top {
                Top::HingedLid {
                    thickness,
                    limit_deg,
                } => {
                    let lid = self.body.top_section(1.0, thickness).unwrap_or_default();
                    let _ = writeln!(
                        s,
                        "part(\"lid\", {lid}.translate(0, 0, {:.4}).color(\"{}\"));",
                        zt + thickness / 2.0,
                        colour()
                    );
                    let _ = writeln!(
                        s,
                        "joint(#{{ name: \"lid_hinge\", type: \"revolute\", child: \"lid\", origin: [0, {hy:.4}, {zt:.4}], axis: [-1, 0, 0], limit: [0, {limit_deg:.1}] }});"
                    );
                }
                Top::SlidingCap { height, travel } => {
                    let cap = self.body.top_section(1.04, height).unwrap_or_default();
                    let _ = writeln!(
                        s,
                        "part(\"cap\", {cap}.translate(0, 0, {:.4}).color(\"{}\"));",
                        zt + height / 2.0,
                        colour()
                    );
                    let _ = writeln!(
                        s,
                        "joint(#{{ name: \"cap_slide\", type: \"prismatic\", child: \"cap\", axis: [0, 0, 1], limit: [0, {travel:.4}] }});"
                    );
                }
                Top::FoldingHandle { height, limit_deg } => {
                    let w = 0.75 * hx;
                    let _ = writeln!(
                        s,
                        "part(\"handle\", (box(0.04, 0.04, {height:.4}).translate({w:.4}, 0, {zh:.4}) + box(0.04, 0.04, {height:.4}).translate({:.4}, 0, {zh:.4}) + box({:.4}, 0.04, 0.04).translate(0, 0, {:.4})).color(\"{}\"));",
                        -w,
                        2.0 * w + 0.04,
                        zt + height,
                        colour(),
                        zh = zt + height / 2.0,
                    );
                    let _ = writeln!(
                        s,
                        "joint(#{{ name: \"handle_fold\", type: \"revolute\", child: \"handle\", origin: [0, 0, {zt:.4}], axis: [1, 0, 0], limit: [0, {limit_deg:.1}] }});"
                    );
                }
            }
        }
        if let Some(side) = &self.side {
            match (*side, drawer, &self.body) {
                (Side::Drawer { .. }, Some((_, y, cx, cy, cz, zc, share)), _) => {
                    let front = -y / 2.0;
                    let _ = writeln!(
                        s,
                        "part(\"drawer\", (box({:.4}, {:.4}, {:.4}).translate(0, {:.4}, {zc:.4}) + box({:.4}, 0.04, 0.05).translate(0, {:.4}, {zc:.4})).color(\"{}\"));",
                        cx - 0.02,
                        cy - 0.02,
                        cz - 0.02,
                        front + (cy - 0.02) / 2.0,
                        0.25 * cx,
                        front - 0.015,
                        colour()
                    );
                    let _ = writeln!(
                        s,
                        "joint(#{{ name: \"drawer_slide\", type: \"prismatic\", child: \"drawer\", axis: [0, -1, 0], limit: [0, {:.4}] }});",
                        share * cy
                    );
                }
                (Side::Door { limit_deg }, _, &Body::Block { x, y, z }) => {
                    let yd = -y / 2.0 - 0.016;
                    let _ = writeln!(
                        s,
                        "part(\"door\", (box({:.4}, 0.03, {:.4}).translate(0, {yd:.4}, 0) + box(0.04, 0.04, {:.4}).translate({:.4}, {:.4}, 0)).color(\"{}\"));",
                        0.8 * x,
                        0.8 * z,
                        0.15 * z,
                        0.3 * x,
                        yd - 0.034,
                        colour()
                    );
                    let _ = writeln!(
                        s,
                        "joint(#{{ name: \"door_hinge\", type: \"revolute\", child: \"door\", origin: [{:.4}, {yd:.4}, 0], axis: [0, 0, -1], limit: [0, {limit_deg:.1}] }});",
                        -0.4 * x
                    );
                }
                (
                    Side::Lever {
                        length_share,
                        limit_deg,
                    },
                    _,
                    body,
                ) => {
                    let straight = body.round_side().map_or(zt, |(_, half)| half);
                    let length = length_share * 2.0 * straight;
                    let (xl, zp) = (body.side_x() + 0.026, 0.3 * straight);
                    let _ = writeln!(
                        s,
                        "part(\"lever\", box(0.05, 0.08, {length:.4}).translate({xl:.4}, 0, {:.4}).color(\"{}\"));",
                        zp - length / 2.0,
                        colour()
                    );
                    let _ = writeln!(
                        s,
                        "joint(#{{ name: \"lever_hinge\", type: \"revolute\", child: \"lever\", origin: [{xl:.4}, 0, {zp:.4}], axis: [0, -1, 0], limit: [0, {limit_deg:.1}] }});"
                    );
                }
                // A drawer or a door is only drawn for a block.
                _ => {}
            }
        }
        for p in &self.prints {
            let solid = match *p {
                Print::Label {
                    angle_deg,
                    turn_deg,
                    z_centre,
                    height,
                } => {
                    let r = self.body.round_side().map_or(0.5, |(r, _)| r);
                    format!(
                        "intersection(cylinder({:.4}, {height:.4}, 48) - cylinder({:.4}, {:.4}, 48), sector({:.4}, {:.4}, {angle_deg:.1}, 48)).rotate_z({turn_deg:.1}).translate(0, 0, {z_centre:.4})",
                        r + 0.006,
                        r + 0.001,
                        height + 0.02,
                        r + 0.1,
                        height + 0.1
                    )
                }
                Print::Band { z_centre, height } => {
                    let r = self.body.round_side().map_or(0.5, |(r, _)| r);
                    format!(
                        "(cylinder({:.4}, {height:.4}, 48) - cylinder({:.4}, {:.4}, 48)).translate(0, 0, {z_centre:.4})",
                        r + 0.011,
                        r + 0.006,
                        height + 0.02
                    )
                }
                Print::Badge {
                    face_deg,
                    u,
                    v,
                    width,
                    height,
                } => {
                    let d = self
                        .body
                        .faces()
                        .iter()
                        .find(|f| f.0 == face_deg)
                        .map_or(0.5, |f| f.1);
                    format!(
                        "box(0.005, {width:.4}, {height:.4}).translate({:.4}, {u:.4}, {v:.4}).rotate_z({face_deg:.1})",
                        d + 0.0035
                    )
                }
                Print::TopDisc { radius } => {
                    format!(
                        "cylinder({radius:.4}, 0.005, 48).translate(0, 0, {:.4})",
                        zt + 0.0035
                    )
                }
            };
            let _ = writeln!(
                s,
                "part(\"{}\", {solid}.color(\"{}\"));",
                p.name(),
                colour()
            );
        }
        s
    }
}

/// A group in words, for the script's header.
pub fn describe(g: &AxialGroup) -> String {
    let turns = match g.fold {
        0 => "every turn about Z".to_string(),
        1 => String::new(),
        n => format!("turns about Z by multiples of {}°", 360 / n),
    };
    let flips = match (g.flip_deg, g.fold) {
        (None, _) => String::new(),
        (Some(_), 0) => "every half-turn about a horizontal axis".to_string(),
        (Some(phi), n) => format!(
            "half-turns about the horizontal axes at {phi:.1}° + k·{:.1}° from +X",
            180.0 / n as f64
        ),
    };
    match (turns.is_empty(), flips.is_empty()) {
        (true, true) => "none".into(),
        (false, true) => turns,
        (true, false) => flips,
        (false, false) => format!("{turns} and {flips}"),
    }
}

fn random_body(rng: &mut Rng) -> Body {
    let u = rng.uniform();
    if u < 0.25 {
        // Height over diameter from 0.4 to 2.5; the longer of the two is 1.
        let aspect = (rng.range(0.4f64.ln(), 2.5f64.ln())).exp();
        let (radius, height) = if aspect >= 1.0 {
            (0.5 / aspect, 1.0)
        } else {
            (0.5, aspect)
        };
        Body::Round {
            radius: (radius * 1000.0).round() / 1000.0,
            height: (height * 1000.0).round() / 1000.0,
        }
    } else if u < 0.35 {
        let radius = draw(rng, 0.12, 0.3);
        Body::Capsule {
            radius,
            length: 1.0 - 2.0 * radius,
        }
    } else if u < 0.55 {
        let sides = [3, 6, 8][rng.below(3)];
        // The outline's wider extent at radius 1.
        let n = sides as f64;
        let extent = |f: fn(f64) -> f64| {
            let v: Vec<f64> = (0..sides)
                .map(|k| f(std::f64::consts::TAU * k as f64 / n))
                .collect();
            v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
        };
        let wide = extent(f64::cos).max(extent(f64::sin));
        let (radius, height) = if rng.uniform() < 0.5 {
            (
                ((1.0 / wide) * 1000.0).floor() / 1000.0,
                draw(rng, 0.3, 0.85),
            )
        } else {
            (draw(rng, 0.2, 0.42), 1.0)
        };
        Body::Prism {
            sides,
            radius,
            height,
        }
    } else if u < 0.85 {
        if rng.uniform() < 0.35 {
            // A square section about Z, its height at least 0.15 from its side.
            loop {
                let (a, b) = (1.0, draw(rng, 0.3, 0.85));
                let (s, z) = if rng.uniform() < 0.5 { (a, b) } else { (b, a) };
                if (s - z).abs() >= 0.15 {
                    return Body::Block { x: s, y: s, z };
                }
            }
        }
        // Three sides at least 0.15 apart (no accidental square section), the longest 1.
        loop {
            let mut d = [1.0, draw(rng, 0.3, 0.85), draw(rng, 0.3, 0.85)];
            if (d[1] - d[2]).abs() < 0.15 {
                continue;
            }
            rng.shuffle(&mut d);
            return Body::Block {
                x: d[0],
                y: d[1],
                z: d[2],
            };
        }
    } else {
        // Height and widest diameter scaled so that the longer of the two is 1.
        let (height, bottom) = (rng.range(0.5, 1.0), rng.range(0.3, 0.5));
        let top = bottom * rng.range(0.45, 0.8);
        let unit = height.max(2.0 * bottom);
        let round = |v: f64| (v / unit * 1000.0).round() / 1000.0;
        Body::Frustum {
            bottom: round(bottom),
            top: round(top),
            height: round(height),
        }
    }
}

fn random_prints(
    rng: &mut Rng,
    body: &Body,
    top_taken: bool,
    side: Option<&Side>,
    count: usize,
) -> Vec<Print> {
    // The kinds this body can carry; at most one of each.
    let mut kinds: Vec<&str> = Vec::new();
    if body.round_side().is_some() {
        kinds.extend(["label", "band"]);
    }
    if !body.faces().is_empty() {
        kinds.push("badge");
    }
    if !top_taken && !matches!(body, Body::Capsule { .. }) {
        kinds.push("disc");
    }
    rng.shuffle(&mut kinds);
    let mut prints: Vec<Print> = Vec::new();
    for kind in kinds.into_iter().take(count) {
        match kind {
            "label" | "band" => {
                let Some((_, half)) = body.round_side() else {
                    continue;
                };
                let (height, angle_deg) = if kind == "label" {
                    (draw(rng, 0.3, 0.6) * 2.0 * half, draw(rng, 60.0, 200.0))
                } else {
                    (draw(rng, 0.05, 0.15) * 2.0 * half, 0.0)
                };
                let room = half - height / 2.0 - 0.02;
                // Off a print already on the side (a label and a band never overlap).
                let taken: Vec<(f64, f64)> = prints
                    .iter()
                    .filter_map(|p| match *p {
                        Print::Label {
                            z_centre, height, ..
                        }
                        | Print::Band { z_centre, height } => Some((z_centre, height)),
                        _ => None,
                    })
                    .collect();
                let clear = |z: f64| {
                    taken
                        .iter()
                        .all(|&(zc, h)| (z - zc).abs() >= (h + height) / 2.0 + 0.02)
                };
                let Some(z_centre) = (0..40).map(|_| offset(rng, 0.08, room)).find(|&z| clear(z))
                else {
                    continue;
                };
                prints.push(if kind == "label" {
                    Print::Label {
                        angle_deg,
                        // On the meshes' 7.5° lattice, so a centred label's half-turn maps
                        // the tessellated body onto itself too.
                        turn_deg: 7.5 * rng.below(48) as f64,
                        z_centre,
                        height: (height * 1000.0).round() / 1000.0,
                    }
                } else {
                    Print::Band {
                        z_centre,
                        height: (height * 1000.0).round() / 1000.0,
                    }
                });
            }
            "badge" => {
                // Not on the −Y face of a block with a drawer or a door there.
                let faces: Vec<(f64, f64, f64, f64)> = body
                    .faces()
                    .into_iter()
                    .filter(|f| {
                        !(f.0 == 270.0
                            && matches!(side, Some(Side::Drawer { .. } | Side::Door { .. })))
                    })
                    .collect();
                let (face_deg, _, w, h) = faces[rng.below(faces.len())];
                let (width, height) = (draw(rng, 0.2, 0.45) * w, draw(rng, 0.2, 0.45) * h);
                // Centred a third of the time, else off the centre by 0.05 or more.
                let (u, v) = if rng.uniform() < 1.0 / 3.0 {
                    (0.0, 0.0)
                } else {
                    let room_u = (w - width) / 2.0 - 0.01;
                    let room_v = (h - height) / 2.0 - 0.01;
                    let sign = |rng: &mut Rng| if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                    if room_u >= 0.05 {
                        let u = sign(rng) * draw(rng, 0.05, room_u);
                        (u, draw(rng, -room_v.max(0.0), room_v.max(0.0)))
                    } else {
                        (0.0, sign(rng) * draw(rng, 0.05, room_v.max(0.05)))
                    }
                };
                prints.push(Print::Badge {
                    face_deg,
                    u,
                    v,
                    width: (width * 1000.0).round() / 1000.0,
                    height: (height * 1000.0).round() / 1000.0,
                });
            }
            _ => prints.push(Print::TopDisc {
                radius: (draw(rng, 0.3, 0.8) * body.top_inradius() * 1000.0).round() / 1000.0,
            }),
        }
    }
    prints
}

#[cfg(test)]
mod tests;
