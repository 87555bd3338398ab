use super::*;
use crate::build_object;
use crate::objects::Symmetry;
use agentstar_geom::nalgebra::Unit;
use agentstar_geom::{ObjectModel, Point3, UnitQuaternion, Vector3};
use std::collections::HashMap;

fn turn(deg: f64) -> UnitQuaternion {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg.to_radians())
}

fn flip(deg: f64) -> UnitQuaternion {
    let (s, c) = deg.to_radians().sin_cos();
    UnitQuaternion::from_axis_angle(
        &Unit::new_normalize(Vector3::new(c, s, 0.0)),
        std::f64::consts::PI,
    )
}

fn plain(body: Body) -> Recipe {
    Recipe {
        seed: 0,
        body,
        top: None,
        side: None,
        prints: vec![],
        colours: PALETTE.to_vec(),
        size_m: 0.2,
    }
}

/// Whether `q` maps every part's vertices onto vertices of the same part (to `tol`) and
/// every joint onto itself: the object at rest, and its motions, map onto themselves.
fn maps_onto_itself(model: &ObjectModel, q: &UnitQuaternion, tol: f64) -> bool {
    let cell = |p: &Point3| {
        (
            (p.x / tol).floor() as i64,
            (p.y / tol).floor() as i64,
            (p.z / tol).floor() as i64,
        )
    };
    for part in &model.parts {
        let mut grid: HashMap<(i64, i64, i64), Vec<Point3>> = HashMap::new();
        for p in &part.mesh.positions {
            grid.entry(cell(p)).or_default().push(*p);
        }
        for p in &part.mesh.positions {
            let m = q * p;
            let (i, j, k) = cell(&m);
            let near = (-1..=1).any(|a| {
                (-1..=1).any(|b| {
                    (-1..=1).any(|c| {
                        grid.get(&(i + a, j + b, k + c))
                            .is_some_and(|v| v.iter().any(|o| (o - m).norm() < tol))
                    })
                })
            });
            if !near {
                return false;
            }
        }
    }
    model.tree.joints().iter().all(|j| {
        let axis = q * j.axis;
        let moved = q * j.origin - j.origin;
        (axis - j.axis).norm() < 1e-9 && moved.cross(&j.axis).norm() < 1e-6
    })
}

#[test]
fn generation_is_deterministic_for_a_seed() {
    for seed in 0..16 {
        let a = Recipe::random(seed);
        assert_eq!(a, Recipe::random(seed));
        assert_eq!(a.script(), Recipe::random(seed).script());
        let spec = generate_object(seed);
        assert_eq!(spec.name, object_name(seed));
        assert_eq!(spec.script, a.script());
    }
    let scripts: std::collections::BTreeSet<String> =
        (0..16).map(|s| Recipe::random(s).script()).collect();
    assert_eq!(scripts.len(), 16, "every seed draws its own object");
}

#[test]
fn names_round_trip_to_seeds() {
    assert_eq!(seed_of("gen-7"), Some(7));
    assert_eq!(seed_of(&object_name(123_456)), Some(123_456));
    for bad in ["gen-", "gen-07", "gen--1", "gen-x", "box", "gen-7 "] {
        assert_eq!(seed_of(bad), None, "{bad}");
    }
    assert!(ObjectSpec::resolve("gen-3").is_some());
    assert!(ObjectSpec::resolve("gen-03").is_none());
    assert_eq!(
        ObjectSpec::resolve("mug").map(|o| o.script),
        ObjectSpec::find("mug").map(|o| o.script.clone())
    );
}

#[test]
fn seeds_cycle_through_the_four_kinds() {
    for seed in 0..32u64 {
        let r = Recipe::random(seed);
        match seed % 4 {
            0 => assert!(!r.is_articulated() && r.prints.is_empty(), "{r:?}"),
            1 => assert!(!r.is_articulated() && !r.prints.is_empty(), "{r:?}"),
            2 => assert!(r.is_articulated(), "{r:?}"),
            _ => {}
        }
        assert!(r.prints.len() <= 2);
        let parts = 1 + usize::from(r.top.is_some()) + usize::from(r.side.is_some());
        assert_eq!(r.colours.len(), parts + r.prints.len());
        let distinct: std::collections::BTreeSet<_> = r.colours.iter().collect();
        assert_eq!(distinct.len(), r.colours.len(), "colours differ");
    }
}

#[test]
fn every_generated_script_builds_with_its_parts_and_joints() {
    let mut problems = Vec::new();
    for seed in 0..48 {
        let recipe = Recipe::random(seed);
        let spec = recipe.spec();
        let model = match build_object(&spec) {
            Ok(m) => m,
            Err(e) => {
                problems.push(format!("{}: {e}\n{}", spec.name, spec.script));
                continue;
            }
        };
        let joints = usize::from(recipe.top.is_some()) + usize::from(recipe.side.is_some());
        if model.tree.joints().len() != joints {
            problems.push(format!(
                "{}: {} joints",
                spec.name,
                model.tree.joints().len()
            ));
        }
        if model.parts.len() != recipe.colours.len() {
            problems.push(format!("{}: {} parts", spec.name, model.parts.len()));
        }
        for p in &model.parts {
            if !p.watertight {
                problems.push(format!("{}: part {} is not closed", spec.name, p.name));
            }
        }
        let r = model.canonical_report();
        if !(0.95..=1.4).contains(&r.longest_side) {
            problems.push(format!("{}: longest side {}", spec.name, r.longest_side));
        }
        if (spec.family == Family::Arctic) != recipe.is_articulated() {
            problems.push(format!("{}: family {:?}", spec.name, spec.family));
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}

#[test]
fn constructed_cases_have_their_symmetries() {
    // A plain box with two equal sides: quarter-turns about the odd axis and the half-turns.
    let square = plain(Body::Block {
        x: 0.6,
        y: 0.6,
        z: 1.0,
    });
    let g = square.group();
    for q in [turn(90.0), turn(180.0), flip(0.0), flip(45.0), flip(90.0)] {
        assert!(g.contains(&q), "{q:?}");
    }
    assert!(!g.contains(&turn(45.0)) && !g.contains(&flip(30.0)));
    assert_eq!(g.rotations().len(), 7);
    // A box with three different sides: the three half-turns.
    let g = plain(Body::Block {
        x: 1.0,
        y: 0.6,
        z: 0.4,
    })
    .group();
    assert_eq!(g.rotations().len(), 3);
    assert!(g.contains(&turn(180.0)) && g.contains(&flip(0.0)) && g.contains(&flip(90.0)));
    assert!(!g.contains(&turn(90.0)));
    // A print off the centre of a face removes them all.
    let mut badged = square.clone();
    badged.prints.push(Print::Badge {
        face_deg: 0.0,
        u: 0.1,
        v: 0.0,
        width: 0.2,
        height: 0.3,
    });
    assert_eq!(badged.group().symmetry(), Symmetry::None);
    assert!(badged.spec().symmetry.rotations().is_empty());
    // Centred on the face, the half-turn about that face's normal stays.
    badged.prints[0] = Print::Badge {
        face_deg: 90.0,
        u: 0.0,
        v: 0.0,
        width: 0.2,
        height: 0.3,
    };
    let g = badged.group();
    assert_eq!(g.rotations().len(), 1);
    assert!(g.contains(&flip(90.0)) && !g.contains(&flip(0.0)));
    // A disc on the top keeps the turns, not the flips.
    let mut lidded = square.clone();
    lidded.prints.push(Print::TopDisc { radius: 0.2 });
    let g = lidded.group();
    assert!(g.contains(&turn(90.0)) && !g.contains(&flip(0.0)));
    assert_eq!(g.rotations().len(), 3);
    // A plain cylinder: every turn and every flip; a label tells them all apart but the
    // half-turn about its own centre when it is centred in height; a centred band keeps all.
    let can = plain(Body::Round {
        radius: 0.3,
        height: 1.0,
    });
    assert_eq!(can.group(), AxialGroup::ROUND);
    assert!(can.group().contains(&turn(13.0)) && can.group().contains(&flip(71.0)));
    let mut labelled = can.clone();
    labelled.prints.push(Print::Label {
        angle_deg: 120.0,
        turn_deg: 30.0,
        z_centre: 0.1,
        height: 0.4,
    });
    assert_eq!(labelled.group().symmetry(), Symmetry::None);
    labelled.prints[0] = Print::Label {
        angle_deg: 120.0,
        turn_deg: 30.0,
        z_centre: 0.0,
        height: 0.4,
    };
    let g = labelled.group();
    assert!(g.contains(&flip(30.0)) && !g.contains(&flip(0.0)) && !g.contains(&turn(180.0)));
    let mut banded = can.clone();
    banded.prints.push(Print::Band {
        z_centre: 0.0,
        height: 0.1,
    });
    assert_eq!(banded.group(), AxialGroup::ROUND);
    banded.prints[0] = Print::Band {
        z_centre: 0.2,
        height: 0.1,
    };
    assert_eq!(banded.group().symmetry(), Symmetry::ContinuousZ);
    // A hinged lid leaves nothing; a cap sliding along the axis keeps the turns.
    let mut hinged = square.clone();
    hinged.top = Some(Top::HingedLid {
        thickness: 0.05,
        limit_deg: 100.0,
    });
    assert_eq!(hinged.group().symmetry(), Symmetry::None);
    hinged.top = Some(Top::SlidingCap {
        height: 0.1,
        travel: 0.3,
    });
    assert_eq!(
        hinged.group(),
        AxialGroup {
            fold: 4,
            flip_deg: None
        }
    );
}

#[test]
fn groups_intersect_to_their_common_rotations() {
    let d6 = AxialGroup {
        fold: 6,
        flip_deg: Some(0.0),
    };
    let d4 = AxialGroup {
        fold: 4,
        flip_deg: Some(45.0),
    };
    let g = d6.intersect(&d4);
    assert_eq!(g.fold, 2);
    // Flips of D6 at multiples of 30°, of D4 at 45° + multiples of 45° (every 45°): 0°, 90°.
    assert!(g.contains(&flip(0.0)) && g.contains(&flip(90.0)) && !g.contains(&flip(45.0)));
    let c3 = AxialGroup {
        fold: 3,
        flip_deg: Some(10.0),
    };
    assert_eq!(c3.intersect(&d4).symmetry(), Symmetry::None);
    // Every listed rotation is in the group, and they are distinct.
    for g in [d6, d4, c3, AxialGroup::ROUND, g] {
        let rs = g.rotations();
        assert!(rs.iter().all(|q| g.contains(q)), "{g:?}");
        for (i, a) in rs.iter().enumerate() {
            assert!(a.angle() > 1e-6);
            assert!(rs[i + 1..].iter().all(|b| a.angle_to(b) > 1e-6), "{g:?}");
        }
    }
    assert_eq!(AxialGroup::ROUND.rotations().len(), 2 * 315 - 1);
}

/// The groups the recipes list are the built meshes' own: every candidate rotation that maps
/// the tessellated parts (each part onto itself, its colour being its own) and joints onto
/// themselves is in the group, and no other.
#[test]
fn listed_symmetries_are_those_of_the_built_meshes() {
    let mut candidates: Vec<(String, UnitQuaternion)> = [45.0, 60.0, 90.0, 120.0, 180.0]
        .iter()
        .map(|&d| (format!("turn {d}°"), turn(d)))
        .collect();
    candidates.extend(
        [0.0, 22.5, 30.0, 45.0, 60.0, 67.5, 90.0, 135.0]
            .iter()
            .map(|&d| (format!("flip {d}°"), flip(d))),
    );
    let mut problems = Vec::new();
    let mut kinds = [0usize; 3];
    for seed in 0..40 {
        let recipe = Recipe::random(seed);
        let g = recipe.group();
        let model = build_object(&recipe.spec()).expect("builds");
        let mut own = candidates.clone();
        for p in &recipe.prints {
            match *p {
                Print::Label { turn_deg: d, .. } | Print::Badge { face_deg: d, .. } => {
                    own.push((format!("flip {d}° (the print's)"), flip(d)));
                }
                _ => {}
            }
        }
        for (label, q) in &own {
            let listed = g.contains(q);
            if listed != maps_onto_itself(&model, q, 2e-3) {
                problems.push(format!(
                    "gen-{seed}: {label} listed {listed}, group {g:?}\n{}",
                    recipe.script()
                ));
            }
        }
        kinds[match g.symmetry() {
            Symmetry::None => 0,
            Symmetry::ContinuousZ => 1,
            Symmetry::Axial(_) => 2,
        }] += 1;
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    assert!(kinds.iter().all(|&k| k >= 3), "kinds of group {kinds:?}");
}
