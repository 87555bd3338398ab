//! Synthetic captures: seeded, consistent with their ground truth (masks are the visible
//! model, hands occlude, depth is the rendered depth), and bad configurations are refused.

use agentstar_render::{render_full, PosedModel, SilhouetteRenderer};
use agentstar_synth::{synthesize, Family, Motion, SynthConfig, SynthError, LIBRARY};

fn cfg(object: &str, motion: Option<Motion>, seed: u64) -> SynthConfig {
    SynthConfig {
        object: object.into(),
        motion,
        frames: 5,
        width: 160,
        height: 120,
        seed,
        ..SynthConfig::default()
    }
}

#[test]
fn same_seed_same_capture_other_seed_other_capture() {
    let a = synthesize(&cfg("laptop", None, 4)).expect("a");
    let b = synthesize(&cfg("laptop", None, 4)).expect("b");
    let c = synthesize(&cfg("laptop", None, 5)).expect("c");
    for (fa, fb) in a.frames.iter().zip(&b.frames) {
        assert_eq!(fa.rgb, fb.rgb);
        assert_eq!(fa.mask, fb.mask);
        assert_eq!(fa.hand, fb.hand);
        assert_eq!(fa.camera_from_object, fb.camera_from_object);
    }
    assert_ne!(
        a.frames[1].camera_from_object,
        c.frames[1].camera_from_object
    );
    assert_eq!(a.id(), "laptop-handheld-s4");
}

#[test]
fn masks_are_the_visible_ground_truth_and_hands_only_occlude() {
    for (object, motion) in [
        ("box", Motion::HandHeld),
        ("mug", Motion::RigidSteps),
        ("cabinet", Motion::StaticOrbit),
    ] {
        let s = synthesize(&SynthConfig {
            frames: 8,
            ..cfg(object, Some(motion), 11)
        })
        .expect("synth");
        let mut r = SilhouetteRenderer::new(160, 120);
        let mut hands = 0;
        for f in &s.frames {
            let posed = PosedModel::new(
                &s.model,
                &f.states,
                &f.camera_from_object.with_scale(s.scale),
            );
            let full = r.render(&s.camera, &posed.instances).clone();
            // Every mask pixel is the object; every hidden object pixel is under a hand.
            assert_eq!(f.mask.and_not(&full).count(), 0, "{object} {}", f.name);
            let hidden = full.and_not(&f.mask);
            match &f.hand {
                Some(h) => {
                    hands += 1;
                    assert_eq!(hidden.and_not(h).count(), 0, "{object} {}", f.name);
                    assert_eq!(h.and(&f.mask).count(), 0, "hand and object are disjoint");
                }
                None => assert_eq!(
                    hidden.count(),
                    0,
                    "{object} {}: no hand, no occlusion",
                    f.name
                ),
            }
            assert!(
                f.mask.count() > 200,
                "{object} {}: the object is in view",
                f.name
            );
            if let Some(depth) = &f.depth_m {
                let b = render_full(&s.camera, &posed.instances);
                for (k, &z) in depth.iter().enumerate() {
                    let (x, y) = (k as u32 % 160, k as u32 / 160);
                    if f.mask.get(x, y) {
                        assert!((z - b.depth[k]).abs() < 1e-5, "depth at {x},{y}");
                    }
                }
            }
        }
        assert!(hands > 0, "{object}: some frames have hands");
        assert_eq!(
            s.frames.iter().any(|f| f.depth_m.is_some()),
            motion == Motion::StaticOrbit,
            "depth by default only for the orbit"
        );
    }
}

#[test]
fn static_orbit_moves_the_camera_not_the_object() {
    let s = synthesize(&cfg("oven", None, 2)).expect("oven");
    assert_eq!(s.motion, Motion::StaticOrbit);
    let world =
        |f: &agentstar_synth::SynthFrame| f.world_from_camera * f.camera_from_object.to_rigid();
    let w0 = world(&s.frames[0]);
    for f in &s.frames[1..] {
        let w = world(f);
        assert!((w.translation.vector - w0.translation.vector).norm() < 1e-9);
        assert!(w.rotation.angle_to(&w0.rotation) < 1e-9);
        assert!(
            f.world_from_camera.translation.vector
                != s.frames[0].world_from_camera.translation.vector
        );
    }
    // Exactly one joint moves.
    let moving = (0..s.model.tree.joints().len())
        .filter(|&j| {
            s.frames
                .iter()
                .any(|f| (f.states[j] - s.frames[0].states[j]).abs() > 1e-9)
        })
        .count();
    assert_eq!(moving, 1);
}

#[test]
fn every_object_synthesises_with_its_default_motion() {
    for o in LIBRARY {
        let s = synthesize(&SynthConfig {
            frames: 2,
            width: 96,
            height: 72,
            ..cfg(&o.name, None, 1)
        })
        .unwrap_or_else(|e| panic!("{}: {e}", o.name));
        assert_eq!(s.motion, Motion::default_for(o.family));
        assert!(s.frames.iter().all(|f| f.mask.count() > 0), "{}", o.name);
    }
}

#[test]
fn bad_configurations_are_refused_with_a_reason() {
    let e = synthesize(&cfg("teapot", None, 0)).expect_err("unknown");
    assert!(matches!(e, SynthError::UnknownObject { .. }));
    assert!(e.to_string().contains("laptop"), "{e}");
    let e = synthesize(&SynthConfig {
        frames: 1,
        ..cfg("box", None, 0)
    })
    .expect_err("one frame");
    assert!(e.to_string().contains("frames"), "{e}");
    let e = synthesize(&SynthConfig {
        mask_noise_px: f64::NAN,
        ..cfg("box", None, 0)
    })
    .expect_err("nan noise");
    assert!(e.to_string().contains("mask noise"), "{e}");
}

#[test]
fn mask_noise_moves_boundaries_only() {
    let clean = synthesize(&cfg("box", None, 3)).expect("clean");
    let noisy = synthesize(&SynthConfig {
        mask_noise_px: 2.0,
        ..cfg("box", None, 3)
    })
    .expect("noisy");
    for (a, b) in clean.frames.iter().zip(&noisy.frames) {
        assert_eq!(a.rgb, b.rgb, "noise touches masks, not images");
        let changed = a.mask.and_not(&b.mask).count() + b.mask.and_not(&a.mask).count();
        assert!(changed > 0);
        assert!((changed as f64) < 0.5 * a.mask.count() as f64);
    }
}

#[test]
fn hard_captures_have_big_steps_large_hands_and_an_off_centre_camera() {
    let s = synthesize(&SynthConfig {
        object: "twinlaptop".into(),
        motion: Some(Motion::HardHeld),
        frames: 12,
        width: 200,
        height: 150,
        seed: 3,
        mask_noise_px: 2.0,
        principal_point: Some((112.0, 68.0)),
        hand_coverage_max: Some(0.6),
        ..SynthConfig::default()
    })
    .expect("synth");
    assert_eq!((s.camera.cx, s.camera.cy), (112.0, 68.0));
    let steps = s.step_angles_deg();
    let max = steps.iter().cloned().fold(0.0, f64::max);
    assert!((130.0..=150.0).contains(&max), "{steps:?}");
    let coverage: Vec<f64> = s.frames.iter().map(|f| f.hand_coverage).collect();
    assert!(coverage.iter().all(|&c| c <= 0.6 + 1e-9), "{coverage:?}");
    assert!(
        coverage.iter().any(|&c| c > 0.15),
        "hands reach across the object: {coverage:?}"
    );
    // The camera moves: its centre travels in the world.
    let travel = (s.frames[0].world_from_camera.translation.vector
        - s.frames[6].world_from_camera.translation.vector)
        .norm();
    assert!(travel > 0.05, "the camera moved {travel} m");
    assert_eq!(s.id(), "twinlaptop-hard-held-s3");
    // The known model carries the print that tells its slabs apart (as the can's label
    // and the mug's badge): thin parts whose colours are the painted ones, the touchpad
    // light on the base, the screen dark inside the lid, moving with it.
    let laptop = agentstar_synth::ObjectSpec::find("twinlaptop").expect("laptop");
    let agentstar_synth::Appearance::Printed(paint) = laptop.appearance else {
        panic!("the laptop is printed")
    };
    let colour_of = |name: &str| {
        let k = (s.model.parts.iter())
            .position(|p| p.name == name)
            .unwrap_or_else(|| panic!("no part {name}"));
        (k, s.model.parts[k].color.map(f64::from))
    };
    // Thin parts of one colour: painted alike anywhere on them.
    let anywhere = agentstar_geom::Point3::new(0.0, -0.2, 0.0);
    for name in ["touchpad", "screen", "logo"] {
        let (k, colour) = colour_of(name);
        let painted = paint(k, &anywhere);
        let diff: f64 = colour
            .iter()
            .zip(&painted)
            .map(|(a, b)| (a - b).abs())
            .sum();
        assert!(diff < 0.1, "{name}: model {colour:?}, painted {painted:?}");
    }
    // The keys part is painted with the base's key pattern: a dark key at its corner.
    let (keys, keys_colour) = colour_of("keys");
    let key = paint(keys, &agentstar_geom::Point3::new(-0.385, -0.025, 0.002));
    assert!(
        key[0] < 0.1 && keys_colour[0] < 0.1,
        "{key:?} {keys_colour:?}"
    );
    let (touchpad, screen) = (colour_of("touchpad").1, colour_of("screen").1);
    assert!(touchpad[0] - screen[0] > 0.5, "{touchpad:?} vs {screen:?}");
    let tree = &s.model.tree;
    assert_eq!(tree.part_joint(colour_of("screen").0), Some(0));
    assert_eq!(tree.part_joint(colour_of("lid").0), Some(0));
    assert_eq!(tree.part_joint(colour_of("touchpad").0), None);
    let e = synthesize(&SynthConfig {
        principal_point: Some((500.0, 10.0)),
        ..cfg("box", None, 1)
    })
    .expect_err("principal point outside");
    assert!(e.to_string().contains("principal point"), "{e}");
}

#[test]
fn printed_objects_differ_where_their_outlines_repeat() {
    // The can's outline is symmetric about its axis; its colours are not: the half with
    // the label and the half without, at the same height, look different, as do the laptop's
    // two slabs seen from the same side.
    let can = agentstar_synth::ObjectSpec::find("labelcan").expect("can");
    let agentstar_synth::Appearance::Printed(paint) = can.appearance else {
        panic!("the label can is printed")
    };
    let p = |x, y, z| agentstar_geom::Point3::new(x, y, z);
    let front = paint(0, &p(0.3, 0.0, -0.25));
    let back = paint(0, &p(-0.3, 0.0, -0.25));
    let diff: f64 = front.iter().zip(&back).map(|(a, b)| (a - b).abs()).sum();
    assert!(diff > 0.5, "{front:?} vs {back:?}");
    let laptop = agentstar_synth::ObjectSpec::find("twinlaptop").expect("laptop");
    let agentstar_synth::Appearance::Printed(paint) = laptop.appearance else {
        panic!("the laptop is printed")
    };
    // The base's keys (top face) and the lid's outside (its top face) at the same place.
    let keys = paint(0, &p(0.1, 0.1, -0.002));
    let lid = paint(1, &p(0.1, 0.1, 0.031));
    assert_ne!(keys, lid);
    let bottle = agentstar_synth::ObjectSpec::find("plainbottle").expect("bottle");
    assert!(matches!(
        bottle.appearance,
        agentstar_synth::Appearance::Plain
    ));
    assert_eq!(bottle.symmetry, agentstar_synth::Symmetry::ContinuousZ);
}

#[test]
fn generated_objects_synthesise_with_their_symmetries_and_in_between_frames() {
    // gen-0 is rigid without print (its symmetries are real), gen-2 articulated.
    for name in ["gen-0", "gen-2"] {
        let spec = agentstar_synth::ObjectSpec::resolve(name).expect("generated");
        let config = SynthConfig {
            frames: 3,
            width: 96,
            height: 72,
            between: 2,
            ..cfg(name, Some(Motion::HardHeld), 5)
        };
        let s = synthesize(&config).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.object.name, name);
        assert_eq!(s.frames.len(), 3);
        assert_eq!(s.between.len(), 4, "{name}: two in-between frames a gap");
        assert_eq!(s.symmetries, spec.symmetry.rotations());
        assert_eq!(
            s.model.tree.joints().is_empty(),
            spec.family == Family::Hot3d
        );
        // The keyframes are those of the capture without in-between frames.
        let plain = synthesize(&SynthConfig {
            between: 0,
            ..config
        })
        .expect("synth");
        for (a, b) in s.frames.iter().zip(&plain.frames) {
            assert_eq!(a.mask, b.mask, "{name}");
        }
    }
    let gen0 = agentstar_synth::ObjectSpec::resolve("gen-0").expect("generated");
    assert!(
        !gen0.symmetry.rotations().is_empty(),
        "a plain body has symmetries"
    );
    let err = synthesize(&cfg("gen-01", None, 1)).expect_err("not a canonical name");
    assert!(err.to_string().contains("gen-N"), "{err}");
}
