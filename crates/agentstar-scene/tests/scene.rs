//! Scene scripts end to end: the worked examples build, and every kind of mistake a model
//! makes gets a message with its position, what was expected and the valid names.

use agentstar_scene::{build_scene, Limits, MeshSource, NoMeshFiles, SceneErrorKind};
use std::time::Duration;

const MUG: &str = r##"
// The mug: a hollow body and a ring handle, one rigid part.
let body = cylinder(0.45, 1.0, 64);
let cavity = cylinder(0.37, 0.9, 64).translate(0, 0, 0.12);
let handle = torus(0.22, 0.055).rotate_x(90).translate(0.55, 0, 0);
part("mug", (body - cavity + handle).color("#d04030"));
"##;

const BOX_WITH_LID: &str = r#"
let base = box(1.0, 0.6, 0.3).translate(0, 0, -0.05);
let lid = box(1.0, 0.6, 0.1, 0.02).translate(0, 0, 0.15).color(0.2, 0.4, 0.9);
part("base", base);
part("lid", lid);
joint(#{ name: "hinge", type: "revolute", child: "lid", origin: [0, -0.3, 0.1], axis: [1, 0, 0], limit: [0, 110] });
"#;

fn build(src: &str) -> Result<agentstar_scene::SceneBuild, agentstar_scene::SceneError> {
    build_scene(src, &NoMeshFiles, &Limits::default())
}

#[test]
fn mug_builds_as_one_watertight_part() {
    let b = build(MUG).expect("mug");
    assert_eq!(b.model.parts.len(), 1);
    assert!(b.model.parts[0].watertight, "warnings: {:?}", b.warnings);
    assert!((b.model.parts[0].color[0] - 208.0 / 255.0).abs() < 1e-6);
    // Body plus handle reaching x = 0.825: about 1.27 long, so the report flags the size.
    assert!(
        (b.report.bbox_max[0] - 0.825).abs() < 1e-3,
        "{:?}",
        b.report
    );
    assert!(
        b.warnings.iter().any(|w| w.contains("longest side")),
        "{:?}",
        b.warnings
    );
}

#[test]
fn articulated_box_has_its_joint_and_rest_pose() {
    let b = build(BOX_WITH_LID).expect("box");
    assert_eq!(b.model.part_names(), vec!["base", "lid"]);
    let j = &b.model.tree.joints()[0];
    assert_eq!((j.name.as_str(), j.limit), ("hinge", Some((0.0, 110.0))));
    assert!(b.report.warnings.is_empty(), "{:?}", b.report.warnings);
    // Opening the lid 90° lifts its far edge to z = 0.1 + 0.6.
    let bounds = b.model.posed_bounds(&[90f64.to_radians()]);
    assert!((bounds.max.z - 0.7).abs() < 1e-3, "{bounds:?}");
}

#[test]
fn unknown_primitive_names_the_closest_one_with_position() {
    let e = build("let a = box(1, 1, 1);\npart(\"a\", a);\nlet b = cilinder(0.5, 1.0);")
        .expect_err("typo");
    assert_eq!(e.kind, SceneErrorKind::UnknownName);
    assert_eq!((e.line, e.column), (Some(3), Some(9)));
    let text = e.to_string();
    assert!(
        text.contains("unknown function `cilinder`") && text.contains("did you mean `cylinder`?"),
        "{text}"
    );
    assert!(
        text.contains("at 3:9") && text.contains("parts defined so far: a"),
        "{text}"
    );
}

#[test]
fn wrong_arguments_list_the_valid_forms() {
    let e = build("part(\"a\", cylinder(0.5));").expect_err("arity");
    assert_eq!(e.kind, SceneErrorKind::InvalidCall);
    assert!(
        e.message.contains("cylinder(radius, height)")
            && e.message.contains("cylinder(radius, height, segments)"),
        "{}",
        e.message
    );
    let e = build("part(\"a\", cylinder(\"big\", 1));").expect_err("type");
    assert!(
        e.message.contains("`radius` must be a number"),
        "{}",
        e.message
    );
    let e = build("part(\"a\", cylinder(-0.5, 1));").expect_err("value");
    assert!(
        e.message.contains("`radius` must be a positive"),
        "{}",
        e.message
    );
    assert_eq!(e.line, Some(1));
}

#[test]
fn integer_and_float_arguments_are_interchangeable() {
    build("part(\"a\", box(1, 2, 3).translate(1, 0.5, 0).rotate([0, 0, 1], 45).scale(0.5));")
        .expect("ints and floats");
}

#[test]
fn endless_loop_is_stopped_with_a_clear_error() {
    let e = build("let i = 0; loop { i += 1; }").expect_err("loop");
    assert_eq!(e.kind, SceneErrorKind::Limit);
    assert!(e.message.contains("operations"), "{}", e.message);
    // A wall-time budget stops heavy work that stays under the operation count.
    let limits = Limits {
        max_wall_time: Duration::from_millis(50),
        max_operations: u64::MAX,
        ..Limits::default()
    };
    let e = build_scene("let i = 0; loop { i += 1; }", &NoMeshFiles, &limits).expect_err("time");
    assert!(e.message.contains("longer than"), "{}", e.message);
}

#[test]
fn recursion_and_sizes_are_bounded() {
    let e = build("fn f(x) { f(x + 1) } f(0);").expect_err("recursion");
    assert_eq!(e.kind, SceneErrorKind::Limit);
    let limits = Limits {
        max_triangles: 1000,
        ..Limits::default()
    };
    let e = build_scene("part(\"a\", sphere(1, 256, 128));", &NoMeshFiles, &limits)
        .expect_err("triangles");
    assert!(e.message.contains("triangles"), "{}", e.message);
    assert!(build("eval(\"1\");").is_err());
}

/// Issue 35 item 2: 100,000 closures each capturing the last made `agentstar check` abort
/// (exit 134) when Rhai freed the chain recursively. Scene scripts have no closures (an
/// anonymous function sees only its parameters) and no `curry` (`f.curry(f)` doubled a
/// pointer at every step, out of memory), so no function pointer holds another; every other
/// nesting counts towards the size limits and runs on a stack that holds it.
#[test]
fn nested_closures_and_curried_pointers_are_refused_not_aborted() {
    let chain = "let f = || 1;\nfor i in 0..100000 { let g = f; f = || g.call(); }\nlet x = f.call();\npart(\"a\", box(1, 1, 1));";
    let e = build(chain).expect_err("closure chain");
    assert_eq!(e.kind, SceneErrorKind::UnknownName, "{}", e.message);
    assert!(
        e.message.contains("`g` inside an anonymous function") && e.message.contains("no closures"),
        "{}",
        e.message
    );
    assert_eq!(e.line, Some(2), "{e:?}");
    // Built but never called, the chain holds nothing and frees at once.
    build("let f = || 1;\nfor i in 0..100000 { let g = f; f = || g.call(); }\npart(\"a\", box(1, 1, 1));")
        .expect("uncalled anonymous functions");
    for bomb in [
        "fn h(x) { 1 }\nlet f = Fn(\"h\");\nfor i in 0..100000 { f = f.curry(f); }",
        "fn h(x) { 1 }\nlet f = curry(Fn(\"h\"), 1);",
    ] {
        let e = build(bomb).expect_err("curry");
        assert!(
            e.message.contains("`curry` is not available"),
            "{}",
            e.message
        );
        assert_eq!(e.line, Some(bomb.lines().count()), "{e:?}");
    }
    // Anonymous functions over their own parameters and function pointers still work.
    let b = build("fn h(x) { x + 1 }\nlet xs = [1, 2].map(|x| x * 2);\nlet y = Fn(\"h\").call(2);\npart(\"a\", box(xs[1], y, 1));")
        .expect("anonymous functions without captures");
    assert_eq!(b.model.parts.len(), 1);
}

#[test]
fn syntax_errors_point_at_the_line() {
    let e = build("let a = box(1, 1, 1);\npart(\"a\", a;\n").expect_err("syntax");
    assert_eq!(e.kind, SceneErrorKind::Syntax);
    assert_eq!(e.line, Some(2));
}

#[test]
fn joint_mistakes_are_explained() {
    let base =
        "part(\"base\", box(1, 1, 0.2)); part(\"lid\", box(1, 1, 0.1).translate(0, 0, 0.15));\n";
    let e = build(&format!("{base}joint(#{{ name: \"h\", type: \"revolute\", child: \"lid\", axis: [1, 0, 0], limits: [0, 90] }});")).expect_err("key");
    assert!(
        e.message.contains("unknown key `limits`") && e.message.contains("did you mean `limit`"),
        "{}",
        e.message
    );
    let e = build(&format!(
        "{base}joint(#{{ name: \"h\", type: \"hinge\", child: \"lid\", axis: [1, 0, 0] }});"
    ))
    .expect_err("type");
    assert!(
        e.message.contains("revolute, continuous, prismatic, fixed"),
        "{}",
        e.message
    );
    let e = build(&format!("{base}joint(#{{ name: \"h\", type: \"revolute\", child: \"cap\", axis: [1, 0, 0], limit: [0, 90] }});")).expect_err("child");
    assert_eq!(e.kind, SceneErrorKind::Model);
    assert!(
        e.message.contains("`cap` is not defined") && e.message.contains("`base`, `lid`"),
        "{}",
        e.message
    );
    assert_eq!(e.line, Some(2));
    let e = build(&format!(
        "{base}joint(#{{ name: \"h\", type: \"revolute\", child: \"lid\", axis: [1, 0, 0] }});"
    ))
    .expect_err("limit");
    assert!(e.message.contains("needs `limit"), "{}", e.message);
    let w = build(&format!("{base}joint(#{{ name: \"h\", type: \"revolute\", child: \"lid\", axis: [1, 0, 0], limit: [10, 90] }});")).expect("builds");
    assert!(
        w.warnings.iter().any(|m| m.contains("rest state 0")),
        "{:?}",
        w.warnings
    );
    // A full turn lets θ and 360−θ alias: the check says so.
    let w = build(&format!("{base}joint(#{{ name: \"h\", type: \"revolute\", child: \"lid\", axis: [1, 0, 0], limit: [0, 360] }});")).expect("builds");
    assert!(
        w.warnings
            .iter()
            .any(|m| m.contains("`h`") && m.contains("full turn")),
        "{:?}",
        w.warnings
    );
}

#[test]
fn duplicate_and_empty_parts_are_refused() {
    let e = build("part(\"a\", box(1, 1, 1)); part(\"a\", box(1, 1, 1));").expect_err("dup");
    assert!(e.message.contains("already exists"));
    let e = build("let x = box(1,1,1);").expect_err("no parts");
    assert_eq!(e.kind, SceneErrorKind::Model);
}

struct OneFile;
impl MeshSource for OneFile {
    fn load(&self, path: &str) -> Result<agentstar_geom::AppearedMesh, String> {
        if path == "handle.obj" {
            agentstar_geom::primitives::cuboid(0.1, 0.2, 0.3)
                .map(agentstar_geom::AppearedMesh::plain)
                .map_err(|e| e.to_string())
        } else {
            Err(format!("no file `{path}` beside the script"))
        }
    }
}

#[test]
fn mesh_files_come_only_through_the_source() {
    let b = build_scene(
        "part(\"h\", mesh(\"handle.obj\").translate(0, 0, 0.1));",
        &OneFile,
        &Limits::default(),
    )
    .expect("mesh");
    assert_eq!(b.model.parts[0].mesh.triangles.len(), 12);
    let e = build_scene(
        "part(\"h\", mesh(\"../etc/passwd\"));",
        &OneFile,
        &Limits::default(),
    )
    .expect_err("refused");
    assert!(e.message.contains("no file"), "{}", e.message);
    let e = build_scene(
        "let p = \"handle\" + \".obj\"; part(\"h\", mesh(p));",
        &OneFile,
        &Limits::default(),
    )
    .expect_err("dynamic");
    assert!(e.message.contains("string literal"), "{}", e.message);
}

#[test]
fn every_primitive_is_reachable() {
    let src = r#"
        part("a", box(0.2, 0.2, 0.2));
        part("b", box(0.2, 0.2, 0.2, 0.02, 2).translate([0.3, 0, 0]));
        part("c", cone(0.1, 0.05, 0.2));
        part("d", ico_sphere(0.1, 1));
        part("e", capsule(0.05, 0.1));
        part("f", plane(0.2, 0.1));
        part("g", disc(0.1));
        part("h", wedge(0.2, 0.2, 0.1));
        part("i", hull([[0,0,0],[0.1,0,0],[0,0.1,0],[0,0,0.1]]));
        part("j", extrude([[0,0],[0.2,0],[0.2,0.2],[0,0.2]], [[[0.05,0.05],[0.15,0.05],[0.15,0.15],[0.05,0.15]]], 0.05));
        part("k", lathe([[0, 0], [0.1, 0], [0.05, 0.2], [0, 0.2]]));
        part("l", intersection(sphere(0.1), box(0.15, 0.15, 0.15)).mirror("x").rotate_euler(10, 20, 30).rotate_y(5).rotate_z(5));
        part("m", union_all([box(0.1, 0.1, 0.1), sphere(0.06).translate(0.05, 0, 0)]).scale(1, 2, 1));
        part("n", intersection(cylinder(0.1, 0.2) - cylinder(0.09, 0.3), sector(0.3, 0.3, 195)));
        let s = box(0.1, 0.2, 0.3);
        print(s.size());
        print(s.bounds());
        print(s.volume());
        print(s.triangle_count());
    "#;
    let b = build(src).expect("all primitives");
    assert_eq!(b.model.parts.len(), 14);
    assert_eq!(b.printed.len(), 4);
    assert!(b.model.parts[9].watertight);
    // A shell cut to 195° of a turn: closed, and its volume 195/360 of the whole shell's
    // (within the polygons' 2%).
    let label = &b.model.parts[13];
    assert!(label.watertight);
    let shell = std::f64::consts::PI * (0.1f64.powi(2) - 0.09f64.powi(2)) * 0.2;
    let share = label.mesh.volume() / shell;
    assert!(
        (share - 195.0 / 360.0).abs() < 0.02 * 195.0 / 360.0,
        "{share}"
    );
}

#[test]
fn docs_reference_matches_the_registered_api() {
    let doc = include_str!("../../../docs/scene.md");
    let start = doc.find("<!-- api:begin -->").expect("marker") + "<!-- api:begin -->\n".len();
    let end = doc.find("<!-- api:end -->").expect("marker");
    assert_eq!(
        &doc[start..end],
        agentstar_scene::api_markdown(),
        "docs/scene.md is stale: paste api_markdown() between the markers"
    );
}

/// Issue 16: one boolean of two fine spheres ran past 150 s, ignoring the 20 s wall limit
/// (the engine's progress callback never runs inside a native function). The booleans now
/// take the script's deadline: the BSP kernel checks it in its loops, the robust kernel
/// (which does 200 × 100 spheres in well under a second) is abandoned at it, so finer
/// spheres (160 000 triangles each, a second or more of work) stand for a boolean too long.
#[test]
fn booleans_stop_at_the_scripts_wall_time_limit() {
    let limits = Limits {
        max_wall_time: Duration::from_millis(300),
        ..Limits::default()
    };
    let src = "part(\"a\", sphere(1, 400, 200) - sphere(0.9, 400, 200).translate(0.05, 0, 0));";
    let start = std::time::Instant::now();
    let e = build_scene(src, &NoMeshFiles, &limits).expect_err("over the limit");
    let took = start.elapsed();
    assert_eq!(e.kind, SceneErrorKind::Limit, "{}", e.message);
    assert!(e.message.contains("wall-time limit"), "{}", e.message);
    // The limit holds inside the kernel: well before the boolean's own minutes. Generous
    // against a loaded machine, but an unbounded boolean takes minutes.
    assert!(took < Duration::from_secs(10), "took {took:?}");
    // union_all checks it too.
    let src = "let s = []; for i in 0..50 { s.push(sphere(0.3, 96, 48).translate(i * 0.1, 0, 0)); } part(\"a\", union_all(s));";
    let e = build_scene(src, &NoMeshFiles, &limits).expect_err("chain");
    assert_eq!(e.kind, SceneErrorKind::Limit, "{}", e.message);
}

const PARAMS: &str = r#"
let w = param("width", 1.0, 0.8, 1.3);
let d = param("depth", 0.6, 0.4, 0.9);
part("body", box(w, d, 0.3));
"#;

#[test]
fn params_take_their_value_or_an_override_within_bounds() {
    let b = build(PARAMS).expect("params");
    let names: Vec<&str> = b.params.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["width", "depth"]);
    assert_eq!(
        (b.params[1].value, b.params[1].min, b.params[1].max),
        (0.6, 0.4, 0.9)
    );
    assert_eq!((b.params[1].line, b.params[1].column), (Some(3), Some(9)));
    assert!((b.report.extent[1] - 0.6).abs() < 1e-12);
    let with = |name: &str, v: f64| {
        let o = std::collections::BTreeMap::from([(name.to_string(), v)]);
        agentstar_scene::build_scene_with(PARAMS, &NoMeshFiles, &Limits::default(), &o)
    };
    let b = with("depth", 0.75).expect("override");
    assert!((b.report.extent[1] - 0.75).abs() < 1e-12);
    assert_eq!((b.params[1].default, b.params[1].value), (0.6, 0.75));
    // The width is what the script says.
    assert!((b.report.extent[0] - 1.0).abs() < 1e-12);
    let e = with("depth", 0.95).expect_err("outside");
    assert!(e.message.contains("outside its bounds [0.4, 0.9]"), "{e}");
    let e = with("dept", 0.5).expect_err("unknown");
    assert!(
        e.message.contains("no parameter `dept`") && e.message.contains("did you mean `depth`"),
        "{e}"
    );
    for (src, says) in [
        ("let a = param(\"a\", 2, 0, 1); part(\"b\", box(a, 1, 1));", "outside its bounds"),
        ("let a = param(\"a\", 1, 2, 0); part(\"b\", box(a, 1, 1));", "must be under max"),
        ("let a = param(\"a\", 1, 0, 2); let b = param(\"a\", 1, 0, 2); part(\"b\", box(a, b, 1));", "already exists"),
        ("let a = param(\"a b\", 1, 0, 2); part(\"b\", box(a, 1, 1));", "must be letters"),
    ] {
        let e = build(src).expect_err(src);
        assert!(e.message.contains(says), "{src}: {e}");
        assert!(e.line.is_some(), "{src}: {e}");
    }
    // Fitted values go back into the literals.
    let v = std::collections::BTreeMap::from([("depth".to_string(), 0.7123456)]);
    let out = agentstar_scene::set_param_values(PARAMS, &v).expect("write");
    assert!(
        out.contains("param(\"depth\", 0.712346, 0.4, 0.9)"),
        "{out}"
    );
    assert_eq!(build(&out).expect("rebuilt").params[1].value, 0.712346);
}
