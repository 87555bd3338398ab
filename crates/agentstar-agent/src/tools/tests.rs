//! The registry, schemas and handlers without a child process.

use super::*;
use agentstar_render::GATE_IOU;
use agentstar_reports::{SearchReport, SearchVerb, TrackReport};

#[test]
fn a_tracks_text_leads_with_its_summary_then_its_log_then_the_frames() {
    let frame = |name: &str, visible: f64| agentstar_reports::FrameScore {
        frame: name.into(),
        iou_visible: Some(visible),
        iou_raw: visible,
        render_px: 100,
        mask_px: 100,
        hand_px: 0,
        depth_mae: None,
        depth_mae_canon: None,
        depth_bias: None,
        combined: visible,
        band_px: None,
        iou_band: None,
        band_share: None,
    };
    let frames = vec![frame("000000.png", 0.99), frame("000005.png", 0.95)];
    let report = TrackReport {
        poses: "run/pose.json".into(),
        seconds: 4.0,
        evaluations: 1000,
        init_frame: "000000.png".into(),
        log: vec!["000005.png: refined from its pose, IoU 0.9400 → 0.9500".into()],
        sequence: agentstar_reports::SequenceScore::of(&frames, GATE_IOU),
        frames,
        pose_version: Some(3),
        keep_basins: false,
        basin_moves: vec![],
        bake: None,
        refused_turns: vec![],
    };
    let text = track_text(&report, None);
    assert!(text.starts_with("tracked 2 frame(s) in 4.0 s"), "{text}");
    assert!(!text.contains("refused"), "{text}");
    // A turn the video refused is listed before the log, with how to check it.
    let refused = TrackReport {
        refused_turns: vec![agentstar_reports::RefusedTurnRow {
            frame: "000005.png".into(),
            what: "appearance: turned +180° about the model's +x (NCC -0.50 → 0.16)".into(),
        }],
        ..report.clone()
    };
    let with = track_text(&refused, None);
    let listed = with
        .find("1 frame(s) whose colours wanted a turn that the video's motion refused")
        .expect("the refused turns");
    assert!(
        with.contains("  000005.png: appearance: turned +180°")
            && listed < with.find("what the tracker did").expect("the log"),
        "{with}"
    );
    assert!(
        text.contains("under the gate, worst first: 000005.png"),
        "{text}"
    );
    let log = text.find("refined from its pose").expect("the log");
    let table = text.find("frame        iou_band").expect("the table");
    assert!(log < table, "{text}");
    // No JSON: the report is the structured content.
    assert!(!text.contains('{'), "{text}");
    assert!(!text.contains("joints"), "a rigid model's table: {text}");
    // With the pose file: each frame's joint states end its line.
    let poses: agentstar_data::posefile::PoseFile = serde_json::from_value(json!({
        "scale": 0.2,
        "reference_frame": "000000.png",
        "joint_defs": [{"name": "cap_slide", "type": "prismatic", "child": "cap"}],
        "frames": {
            "000000.png": {"joints": {"lid_hinge": 0.5, "cap_slide": 0.0}},
            "000005.png": {"joints": {"lid_hinge": 195.25, "cap_slide": 0.045}}
        }
    }))
    .expect("a pose file");
    let text = track_text(&report, Some(&poses));
    assert!(text.contains("iou_visible  joints\n"), "{text}");
    let line = text
        .lines()
        .find(|l| l.starts_with("000005.png"))
        .expect("the frame's line");
    // A hinge's degrees to one decimal, a slide's model units to three (play-test 18 read a
    // lid 0.045 off as `0.0`).
    assert!(
        line.ends_with("0.9500  cap_slide 0.045  lid_hinge 195.2"),
        "{line}"
    );
}
use serde_json::json;

#[test]
fn a_tools_output_is_kept_up_to_its_cap_and_the_rest_is_counted() {
    let big = vec![b'x'; 1000];
    let t = read_capped_to(&big[..], 100);
    assert!(t.starts_with(&"x".repeat(100)), "{t}");
    assert!(t.contains("[900 more bytes of output dropped"), "{t}");
    assert_eq!(read_capped_to(&b"short"[..], 100), "short");
}

#[test]
fn a_fit_is_saved_only_when_a_parameter_moved_and_the_iou_rose() {
    let report = |before: f64, after: f64, iou_before: f64, iou_after: f64| {
        agentstar_reports::fit::FitReport {
            params: vec![agentstar_reports::fit::FitParam {
                name: "width".into(),
                before,
                after,
                min: 0.8,
                max: 1.2,
                at_bound: false,
            }],
            held: vec![],
            frames: vec![],
            iou_mean_before: iou_before,
            iou_mean_after: iou_after,
            iou_min_before: iou_before,
            iou_min_after: iou_after,
            rounds: vec![],
            origin_shift: [0.0; 3],
            scene: "s.rhai".into(),
            poses: "p.json".into(),
            sheets: vec![],
            builds: 1,
            evaluations: 1,
            seconds: 0.0,
            written: false,
            views: None,
            held_part: None,
            unmet: vec![],
            unseen: vec![],
        }
    };
    // The play-test's case: the IoU rose (the poses were refined) but the width stayed.
    let why = fit_saves_nothing(&report(1.0, 1.0002, 0.93, 0.99)).expect("not saved");
    assert!(why.contains("No parameter moved"), "{why}");
    let why = fit_saves_nothing(&report(1.0, 1.05, 0.99, 0.99)).expect("not saved");
    assert!(why.contains("did not raise"), "{why}");
    assert_eq!(fit_saves_nothing(&report(1.0, 1.05, 0.93, 0.99)), None);
    // One parameter: it moved or not, nothing to single out.
    assert_eq!(unmoved_line(&report(1.0, 1.05, 0.93, 0.99)), None);
    assert_eq!(unmoved_line(&report(1.0, 1.0002, 0.93, 0.99)), None);
    // Of two, the one that stayed is named.
    let mut two = report(1.0, 1.05, 0.93, 0.99);
    let mut depth = two.params[0].clone();
    depth.name = "depth".into();
    depth.after = depth.before;
    two.params.push(depth);
    let line = unmoved_line(&two).expect("a line");
    assert!(line.starts_with("did not move: depth."), "{line}");
}

/// Every schema, at every depth: no `null` types (optional fields are left out) and no
/// line breaks inside a paragraph of a description (review, 2026-12-02: `finish`'s
/// reasons showed `["string","null"]` and descriptions kept the source's wrapping).
#[test]
fn schemas_have_no_null_types_and_no_wrapped_descriptions() {
    fn walk(tool: &str, path: &str, v: &Value, problems: &mut Vec<String>) {
        match v {
            Value::Object(o) => {
                if let Some(t) = o.get("type") {
                    let has_null =
                        t == "null" || t.as_array().is_some_and(|a| a.iter().any(|x| x == "null"));
                    if has_null {
                        problems.push(format!("{tool}{path}: type {t}"));
                    }
                }
                if let Some(Value::String(d)) = o.get("description") {
                    if d.replace("\n\n", "").contains('\n') {
                        problems.push(format!("{tool}{path}: description {d:?}"));
                    }
                }
                for (k, c) in o {
                    if k != "enum" && k != "const" && k != "default" {
                        walk(tool, &format!("{path}/{k}"), c, problems);
                    }
                }
            }
            Value::Array(a) => {
                for (i, c) in a.iter().enumerate() {
                    walk(tool, &format!("{path}/{i}"), c, problems);
                }
            }
            _ => {}
        }
    }
    let mut problems = vec![];
    for t in registry() {
        walk(t.name, "", &t.schema(), &mut problems);
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    assert_eq!(one_line_paragraphs("a\n b\n\nc\nd"), "a b\n\nc d");
}

#[test]
fn a_child_commands_last_stderr_line_is_the_activity_of_the_call() {
    let activity = Activity::default();
    let mut t = toolbox(None);
    t.exe = "sh".into();
    let script = "printf 'track: 000000.png init\\n\\ntrack: 000005.png from 000000.png' >&2; echo ' tail' >&2; echo done";
    let (ok, stdout, stderr) =
        with_activity(&activity, || t.exec(&["-c".into(), script.into()])).expect("exec");
    assert!(ok, "{stderr}");
    assert_eq!(stdout.trim(), "done");
    // The last complete non-empty line, blank lines skipped.
    assert_eq!(
        activity.last_line(),
        "track: 000005.png from 000000.png tail"
    );
    assert!(stderr.contains("000000.png init"), "{stderr}");
    // Outside with_activity nothing reports, and the thread's activity is unset.
    let other = Activity::default();
    let (ok, _, _) = t
        .exec(&["-c".into(), "echo quiet >&2".into()])
        .expect("exec");
    assert!(ok);
    assert_eq!(
        activity.last_line(),
        "track: 000005.png from 000000.png tail"
    );
    assert_eq!(other.last_line(), "");
}

fn toolbox(window: Option<&[&str]>) -> Toolbox {
    let run = RunDir {
        dir: "run".into(),
        capture: "cap".into(),
        scene: "run/scene.rhai".into(),
        poses: "run/pose.json".into(),
        finish: Default::default(),
    };
    let t = Toolbox::new("agentstar".into(), run);
    match window {
        Some(w) => t.for_window(w.iter().map(|s| s.to_string()).collect()),
        None => t,
    }
}

#[test]
fn a_sub_agent_may_change_only_its_window() {
    let w = ["000000.png".to_string(), "000005.png".to_string()];
    assert!(outside_window(&w, &["000000.png".into()]).is_empty());
    assert_eq!(
        outside_window(&w, &["000005.png".into(), "000010.png".into()]),
        ["000010.png"]
    );
    let t = toolbox(Some(&["000000.png", "000005.png"]));
    assert!(t.check_window(None).is_err());
    // Shape changes, whole-file restores and the tracker are refused outright.
    for (tool, args) in [
        (
            "scene_write",
            json!({"script": "part(\"a\", box(1, 1, 1));"}),
        ),
        ("pose_restore", json!({"version": 1})),
        ("track", json!({})),
    ] {
        let o = t.call(tool, &args, 1);
        assert!(o.is_error, "{tool}: {}", o.text);
    }
    assert!(toolbox(None).check_window(None).is_ok());
}

#[test]
fn every_tool_has_a_generated_object_schema_and_unknown_tools_are_named() {
    let all = catalogue();
    let mut names: Vec<&str> = all.iter().map(|t| t.name).collect();
    names.sort_unstable();
    names.dedup();
    assert_eq!(names.len(), all.len(), "duplicate tool names");
    for t in &all {
        assert_eq!(t.schema["type"], "object", "{}", t.name);
        assert_eq!(t.schema["additionalProperties"], false, "{}", t.name);
        assert!(t.schema.get("$schema").is_none() && t.schema.get("$defs").is_none());
        assert!(
            t.description.len() > 40,
            "{} needs a description that teaches it",
            t.name
        );
    }
    let sweep = find("sweep").expect("sweep").schema();
    assert_eq!(sweep["required"], json!(["frames", "ranges"]));
    assert_eq!(sweep["properties"]["evals"]["minimum"], 50);
    assert_eq!(
        sweep["properties"]["strategy"]["enum"],
        json!(["de", "grid"])
    );
    let o = toolbox(None).call("fly", &json!({}), 1);
    assert!(o.is_error && o.text.contains("sweep"));
    // `finish` takes reasons from a fixed set, named in its schema.
    let finish = find("finish").expect("finish").schema();
    let reason = &finish["properties"]["unreachable"]["additionalProperties"];
    let categories: Vec<&str> = reason["oneOf"]
        .as_array()
        .expect("one schema per category")
        .iter()
        .map(|v| {
            let c = &v["properties"]["category"];
            c["const"]
                .as_str()
                .or_else(|| c["enum"][0].as_str())
                .expect("a category")
        })
        .collect();
    assert_eq!(
        categories,
        ["occlusion", "mask_error", "truncated", "out_of_reach"],
        "{reason}"
    );
    // Pose versions start at 0 (as the CLI's), scene versions at 1.
    let restore = find("pose_restore").expect("tool").schema();
    assert_eq!(restore["properties"]["version"]["minimum"], 0);
    let track = find("track").expect("tool").schema();
    assert!(track["properties"]["from"].is_object() && track["properties"]["anchors"].is_object());
}

#[test]
fn the_render_description_names_the_colours_the_images_use() {
    let d = find("render").expect("render").description;
    for e in agentstar_render::views::COMPARE_LEGEND {
        assert!(d.contains(e.name), "{}: {d}", e.name);
    }
    // The search text tells an MCP client what to call, never pose numbers or a shell.
    let report = SearchReport {
        verb: SearchVerb::Oapply,
        capture: "cap".into(),
        model: "m.rhai".into(),
        poses: "p.json".into(),
        scale: 0.2,
        depth_weight: 0.0,
        frames: vec![agentstar_reports::SearchFrame {
            frame: "000000.png".into(),
            sheet: "run/images/x/oapply_sheet_000000.png".into(),
            notes: vec![],
            search: json!({}),
            pages: vec![],
            frame_alone: None,
            ranked: vec![agentstar_reports::Candidate {
                rank: 0,
                label: "flip:y;rz:30".into(),
                pose: agentstar_data::posefile::PoseJson {
                    quaternion: [0.5, 0.5, 0.5, 0.5],
                    translation: [0.1, 0.2, 0.9],
                    scale: Some(0.2),
                },
                joints: BTreeMap::new(),
                iou_visible: Some(0.97),
                iou_raw: 0.95,
                iou_band: None,
                gate: 0.97,
                depth_canon: None,
                combined: 0.97,
                model_ncc: None,
                neighbour_steps: vec![],
                outside_region: vec![],
                extra: json!({}),
            }],
        }],
        mean_gate_iou: 0.97,
        min_gate_iou: Some(0.97),
        details: json!({}),
        command: "agentstar oapply".into(),
    };
    let t = search_text(&report, Path::new("run/images/x/oapply.json"));
    assert!(!t.contains("paste") && !t.contains("agentstar "), "{t}");
    assert!(!t.contains("0.5, 0.5") && !t.contains("quaternion"), "{t}");
    assert!(
        t.contains("`pose_commit`") && t.contains("run/images/x/oapply.json"),
        "{t}"
    );
    assert!(t.contains("flip:y;rz:30") && t.contains("0.9700"), "{t}");
    assert!(!t.contains("nothing the search evaluated"), "{t}");
    // A search that kept only its start says so, and what to try (play-test 2026-12-02:
    // three sweeps came back with the start alone and the agent could not tell why).
    let mut kept = report.clone();
    kept.frames[0].ranked[0].label = agentstar_reports::KEPT_START.into();
    let t = search_text(&kept, Path::new("run/images/x/sweep.json"));
    assert!(
        t.contains("nothing the search evaluated in this region scored above the start"),
        "{t}"
    );
    assert!(!t.contains("seen: a place"), "{t}");
    assert!(!t.contains("outside the region you named"), "{t}");
    // A start outside the region named is first only for want of better (play-test 6
    // took it for the region's best).
    kept.frames[0].ranked[0].outside_region = vec!["hinge 10 not in 100..120".into()];
    let t = search_text(&kept, Path::new("run/images/x/sweep.json"));
    assert!(
        t.contains("rank 0 is the start, which lies outside the region you named (hinge 10 not in 100..120): it is first only because nothing inside the region scored higher."),
        "{t}"
    );
    // Not also the note that calls such a start the best pose here.
    assert!(!t.contains("nothing the search evaluated"), "{t}");
    // With a row after it, that row is the region's best.
    let mut two = kept.clone();
    let mut second = two.frames[0].ranked[0].clone();
    second.rank = 1;
    second.outside_region.clear();
    second.label = "hinge:120".into();
    two.frames[0].ranked.push(second);
    let t = search_text(&two, Path::new("run/images/x/sweep.json"));
    assert!(t.contains("; the region's best is rank 1."), "{t}");
    // A runner-up row is explained where it appears (play-test 5: `seen` was a mystery).
    let mut seen = report.clone();
    seen.frames[0].ranked[0].label = "seen yaw:40".into();
    let t = search_text(&seen, Path::new("run/images/x/sweep.json"));
    assert!(t.contains("seen: a place the search passed through"), "{t}");
}

/// An unknown argument is answered with every argument the tool takes, those of flattened
/// structs too (play-test 2026-12-06: `osweep`'s error listed `frames`, `opreset`,
/// `ranges` and `order`, not `crop` and `zoom`).
#[test]
fn an_unknown_argument_is_answered_with_every_argument_the_tool_takes() {
    let def = registry()
        .iter()
        .find(|d| d.name == "osweep")
        .expect("osweep");
    let err = def
        .parse_args(&json!({"frames": "000000", "rotations": "z:flip"}))
        .expect_err("unknown field")
        .to_string();
    for says in ["unknown field `rotations`", "`ranges`", "`crop`", "`zoom`"] {
        assert!(err.contains(says), "{says} not in: {err}");
    }
}

#[test]
fn arguments_are_checked_against_the_schema_before_anything_runs() {
    let t = toolbox(None);
    for (tool, args, says) in [
        ("score", json!({"frames": 12345}), "invalid type"),
        ("score", json!({"frames": ["nope.png"]}), "invalid type"),
        ("score", json!({"frame": "000000"}), "unknown field"),
        ("score", json!("all"), "must be an object"),
        (
            "sweep",
            json!({"frames": "000000"}),
            "missing field `ranges`",
        ),
        (
            "sweep",
            json!({"frames": "0", "ranges": "yaw:-1,1", "evals": 10}),
            "under its minimum 50",
        ),
        (
            "sweep",
            json!({"frames": "0", "ranges": "yaw:-1,1", "strategy": "anneal"}),
            "unknown variant",
        ),
        ("track", json!({"scale": 0}), "must be over 0"),
        ("track", json!({"scale": -2.5}), "must be over 0"),
        (
            "scene_restore",
            json!({"version": 0}),
            "under its minimum 1",
        ),
        ("pose_restore", json!({"version": -1}), "invalid value"),
        (
            "finish",
            json!({"unreachable": {"000000": {"category": "glare"}}}),
            "unknown variant",
        ),
        (
            "finish",
            json!({"unreachable": {"000000": {"category": "out_of_reach"}}}),
            "missing field `note`",
        ),
        (
            "sweep",
            json!({"frames": "", "ranges": "yaw:-1,1"}),
            "at least 1",
        ),
        (
            "notes",
            json!({"text": "x".repeat(MAX_NOTE_CHARS + 1)}),
            "over its limit",
        ),
    ] {
        let o = t.call(tool, &args, 1);
        assert!(o.is_error, "{tool} {args}: {}", o.text);
        assert!(o.text.contains(says), "{tool} {args}: {}", o.text);
        assert!(o.text.starts_with(tool), "{}", o.text);
    }
    // The schema's limits are the constants the tools use.
    let scene = find("scene_write").expect("tool").schema();
    assert_eq!(
        scene["properties"]["script"]["maxLength"],
        json!(MAX_SCRIPT_CHARS)
    );
    let notes = find("notes").expect("tool").schema();
    assert_eq!(
        notes["properties"]["text"]["maxLength"],
        json!(MAX_NOTE_CHARS)
    );
}

#[test]
fn paths_outside_the_run_and_the_capture_are_refused() {
    let dir = tempfile::tempdir().expect("tmp");
    let run_dir = dir.path().join("run");
    let cap = dir.path().join("cap");
    std::fs::create_dir_all(run_dir.join("images")).expect("mkdir");
    std::fs::create_dir_all(&cap).expect("mkdir");
    std::fs::write(run_dir.join("images/r.json"), "{}").expect("w");
    std::fs::write(dir.path().join("secret.json"), "{}").expect("w");
    let t = Toolbox::new(
        "agentstar".into(),
        RunDir {
            dir: run_dir.clone(),
            capture: cap,
            scene: run_dir.join("scene.rhai"),
            poses: run_dir.join("pose.json"),
            finish: Default::default(),
        },
    );
    assert!(t.confine("images/r.json").is_ok());
    assert!(t
        .confine(&run_dir.join("images/r.json").display().to_string())
        .is_ok());
    for bad in ["/etc/passwd", "../secret.json", "images/../../secret.json"] {
        let e = t.confine(bad).expect_err(bad);
        assert!(e.contains("outside the run directory"), "{bad}: {e}");
    }
    let o = t.call("pose_commit", &json!({"report": "/etc/passwd"}), 1);
    assert!(o.is_error && o.text.contains("outside"), "{}", o.text);
}

#[test]
fn a_bad_call_is_answered_with_what_the_tool_takes() {
    let fit = arguments_help("fit_shape", &schema_of::<FitShapeArgs>());
    assert!(fit.starts_with("fit_shape takes:"), "{fit}");
    assert!(
        fit.contains("- `params` (required, list of string): The parameters to fit"),
        "{fit}"
    );
    assert!(fit.contains("- `rounds` (integer 1–10)"), "{fit}");
    // Its names as a list or as one string of them separated by commas (play-test 18).
    for params in [json!(["radius", "lid_h"]), json!("radius, lid_h")] {
        let a: FitShapeArgs = serde_json::from_value(json!({ "params": params })).expect("args");
        assert_eq!(a.params, ["radius", "lid_h"]);
    }
    assert!(serde_json::from_value::<FitShapeArgs>(json!({"params": 3})).is_err());
    // A nested argument shows its shape: each category with its own fields.
    let finish = arguments_help("finish", &schema_of::<FinishArgs>());
    assert!(
        finish.contains("- `unreachable` (map of key → {category: \"occlusion\", percent: number} | {category: \"mask_error\", image: string, note?: string}"),
        "{finish}"
    );
    assert!(
        finish.contains("{category: \"out_of_reach\", note: string}"),
        "{finish}"
    );
    assert_eq!(
        arguments_help("task", &schema_of::<NoArgs>()),
        "task takes no arguments: call it with {}"
    );
}

#[test]
fn a_scene_edit_says_pose_json_unchanged_only_when_no_version_was_made() {
    let unchanged = scene::pose_line(&[], None);
    assert!(unchanged.contains("unchanged") && unchanged.contains("no pose version"));
    // Play-test 15: a new part made pose version 11 while the reply said "unchanged".
    let added = scene::pose_line(&["parts listed, added: patch".to_string()], Some(11));
    assert_eq!(added, " pose.json version 11: parts listed, added: patch.");
    let header = scene::pose_line(&[], Some(11));
    assert!(
        !header.contains("unchanged") && header.contains("version 11"),
        "{header}"
    );
}

#[test]
fn a_views_images_come_with_the_model_first() {
    let dir = tempfile::tempdir().expect("tempdir");
    for name in [
        "frame_000000.png",
        "frame_000004.png",
        "sheet_frames.png",
        "sheet_side.png",
        "side_000000.png",
        "side_000004.png",
        "notes.txt",
    ] {
        std::fs::write(dir.path().join(name), b"").expect("write");
    }
    let names: Vec<String> = pngs(dir.path())
        .iter()
        .map(|p| p.file_name().expect("name").to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "sheet_side.png",
            "sheet_frames.png",
            "side_000000.png",
            "side_000004.png",
            "frame_000000.png",
            "frame_000004.png"
        ]
    );
}

#[test]
fn a_failures_text_is_its_error_without_the_notes_or_the_notes_when_that_is_all() {
    let stderr = "note: cap holds 4 in-between frame(s) besides its 3 keyframes; this works on the keyframes\nerror: `000001` is an in-between frame\n";
    assert_eq!(
        failure_text(stderr),
        "error: `000001` is an in-between frame"
    );
    let only = "note: cap holds 4 in-between frame(s)\n";
    assert_eq!(failure_text(only), "note: cap holds 4 in-between frame(s)");
    assert_eq!(failure_text(""), "");
}
