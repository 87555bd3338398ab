//! Every subcommand on the built-in example, bad input giving a clear message and a
//! non-zero exit without writing half a file, and shell completions.

mod support;

use agentstar_reports::ScoreReport;
use std::path::Path;
use support::{agentstar, assert_failed_saying, example, json_of, on_poses, score_of, text};

#[test]
fn example_and_every_subcommand_on_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());
    let v: serde_json::Value = json_of(&agentstar(&["validate", &cap, "--json"]));
    assert_eq!(v["valid"], true);
    assert_eq!(v["frames"], 6);

    let v: ScoreReport = score_of(&cap, &model, &poses, None);
    assert_eq!(v.sequence.min_iou_visible, 1.0);
    assert_eq!(v.frames.len(), 6);

    let out = dir.path().join("views");
    let o = on_poses(
        "render",
        &cap,
        &model,
        &poses,
        &[
            "--frames",
            "000000..000010",
            "--views",
            "overlay,compare,ids,shaded,depth",
            "--out",
            out.to_str().expect("utf8"),
            "--json",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    for f in [
        "overlay_000005.png",
        "compare_000010.png",
        "ids_000000.png",
        "shaded_000005.png",
        "depth_000010.npy",
        "sheet_overlay.png",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    assert!(
        !out.join("overlay_000015.png").exists(),
        "frame selection ignored"
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(
        v["sheets"][0],
        out.join("sheet_overlay.png").display().to_string()
    );

    // The raw keyframes cropped around the mask, outlined and zoomed; a call without the
    // overlay names no overlay sheet, and every file it names exists.
    let fv = dir.path().join("frames_view");
    let v: serde_json::Value = json_of(&on_poses(
        "render",
        &cap,
        &model,
        &poses,
        &[
            "--frames",
            "000000,000005",
            "--views",
            "compare,frame,side",
            "--outline",
            "both",
            "--zoom",
            "2",
            "--out",
            fv.to_str().expect("utf8"),
            "--json",
        ],
    ));
    let sheets: Vec<&str> = v["sheets"]
        .as_array()
        .expect("sheets")
        .iter()
        .map(|p| p.as_str().expect("path"))
        .collect();
    assert_eq!(
        sheets,
        // The side sheet (with the model) before the crops alone.
        ["sheet_compare.png", "sheet_side.png", "sheet_frames.png"]
            .map(|n| fv.join(n).display().to_string())
    );
    assert!(!fv.join("sheet_overlay.png").exists());
    // The sheets draw every crop at one size whatever the zoom, and say so (play-test 16).
    let notes = v["notes"].as_array().expect("notes");
    assert!(
        notes.iter().any(|n| n
            .as_str()
            .is_some_and(|n| n.contains("the zoom asked (2.00) is in the per-frame images"))),
        "{notes:?}"
    );
    // The compare sheet's crops keep the comparison's colours (nearest-neighbour zoom): the
    // agreement and the background, and no blend of them.
    let sheet = image::open(fv.join("sheet_compare.png"))
        .expect("png")
        .to_rgb8();
    let count = |c: image::Rgb<u8>| sheet.pixels().filter(|p| **p == c).count();
    let (both, background) = (
        agentstar_render::views::BOTH,
        agentstar_render::views::BACKGROUND,
    );
    assert!(count(both) > 2_000, "{} agreeing pixels", count(both));
    assert!(count(background) > 2_000);
    // A frame's own compare image is cropped around the object too: the agreement fills a
    // larger share of it than the mask fills of the frame.
    let single = image::open(fv.join("compare_000005.png"))
        .expect("png")
        .to_rgb8();
    let share = |img: &image::RgbImage| {
        img.pixels().filter(|p| **p == both).count() as f64 / img.pixels().len() as f64
    };
    let mask = image::open(Path::new(&cap).join("mask_object/000005.png"))
        .expect("mask")
        .to_luma8();
    let mask_share =
        mask.pixels().filter(|p| p.0[0] > 127).count() as f64 / mask.pixels().len() as f64;
    assert!(
        share(&single) > 1.3 * mask_share,
        "{} against {mask_share}",
        share(&single)
    );
    let halfway =
        image::Rgb([0, 1, 2].map(|k| ((both[k] as u16 + background[k] as u16) / 2) as u8));
    assert_eq!(count(halfway), 0, "the crops were filtered");
    for f in v["frames"].as_array().expect("frames") {
        for p in f["files"].as_array().expect("files") {
            assert!(Path::new(p.as_str().expect("path")).is_file(), "{p}");
        }
        let crop = f["crop"].as_array().expect("crop");
        let (w, h) = (crop[2].as_u64().expect("w"), crop[3].as_u64().expect("h"));
        let frame = f["frame"].as_str().expect("frame").trim_end_matches(".png");
        let img = image::open(fv.join(format!("frame_{frame}.png"))).expect("png");
        assert_eq!((img.width() as u64, img.height() as u64), (2 * w, 2 * h));
        assert_eq!(f["zoom"], 2.0);
        // The same crop and zoom, the model opaque beside the frame.
        let side = image::open(fv.join(format!("side_{frame}.png"))).expect("png");
        let gap = agentstar_render::views::SIDE_GAP_PX as u64;
        assert_eq!(
            (side.width() as u64, side.height() as u64),
            (4 * w + gap, 2 * h)
        );
    }
    for (bad, says) in [
        ("--zoom=0", "--zoom"),
        ("--zoom=9", "--zoom"),
        ("--margin=-1", "--margin"),
    ] {
        let o = on_poses(
            "render",
            &cap,
            &model,
            &poses,
            &["--views", "frame", "--out", fv.to_str().expect("utf8"), bad],
        );
        assert_failed_saying(&o, &[says]);
    }

    let tt = dir.path().join("tt");
    // `turntable … --out TT --size 96 ARGS… --json`, its report.
    let turntable = |args: &[&str]| -> serde_json::Value {
        let mut all = vec!["--out", tt.to_str().expect("utf8"), "--size", "96"];
        all.extend_from_slice(args);
        all.push("--json");
        json_of(&on_poses("turntable", &cap, &model, &poses, &all))
    };
    let v = turntable(&[]);
    // Every frame of the example has its own lid angle: by default the lid's minimum,
    // median and maximum, one sheet each, and no single views.
    let labels: Vec<&str> = v["states"]
        .as_array()
        .expect("states")
        .iter()
        .map(|s| s["label"].as_str().expect("label"))
        .collect();
    assert_eq!(labels, ["min", "median", "max"]);
    assert_eq!(v["sheets"].as_array().expect("sheets").len(), 3);
    for f in v["files"].as_array().expect("files") {
        assert!(Path::new(f.as_str().expect("path")).is_file(), "{f}");
    }
    assert!(tt.join("turntable_sheet_median.png").is_file());
    assert!(!tt.join("turntable_min_az000_el+20.png").exists());
    // Every distinct state, with the single views, on request.
    let v = turntable(&["--states", "all", "--each"]);
    assert_eq!(v["states"].as_array().expect("states").len(), 6);
    assert!(tt.join("turntable_000000_az000_el+20.png").is_file());
    // States given outright, without poses (a shape checked before tracking); a state past
    // its joint's limit is refused, naming the joint.
    let tt_given = dir.path().join("tt_given");
    let given = |states: &str| {
        agentstar(&[
            "turntable",
            "--model",
            &model,
            "--out",
            tt_given.to_str().expect("utf8"),
            "--size",
            "96",
            "--states",
            states,
            "--json",
        ])
    };
    let o = given("hinge:30|hinge:90");
    assert!(o.status.success(), "{}", text(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let shown: Vec<f64> = v["states"]
        .as_array()
        .expect("states")
        .iter()
        .map(|s| s["joints"]["hinge"].as_f64().expect("state"))
        .collect();
    assert_eq!(shown.len(), 2, "{v}");
    assert!(
        (shown[0] - 30.0).abs() < 1e-9 && (shown[1] - 90.0).abs() < 1e-9,
        "{v}"
    );
    let o = given("hinge:1000");
    assert_failed_saying(&o, &["hinge", "limit"]);

    let glb = dir.path().join("object.glb");
    let o = agentstar(&[
        "export",
        "--model",
        &model,
        "--glb",
        glb.to_str().expect("utf8"),
        "--urdf",
        dir.path().join("urdf").to_str().expect("utf8"),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = agentstar(&["check", glb.to_str().expect("utf8"), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["parts"].as_array().expect("parts").len(), 2);
    let o = agentstar(&[
        "check",
        dir.path().join("urdf/object.urdf").to_str().expect("utf8"),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("joint hinge"), "{}", text(&o));
}

#[test]
fn bad_input_fails_clearly() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model, poses) = example(dir.path());

    // A broken capture: every problem listed, exit 1.
    std::fs::remove_file(dir.path().join("capture/mask_object/000005.png")).expect("rm");
    let o = agentstar(&["validate", &cap]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o).contains("missing object mask for frame `000005.png`"),
        "{}",
        text(&o)
    );
    let o = on_poses("score", &cap, &model, &poses, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("problem"), "{}", text(&o));
    std::fs::copy(
        dir.path().join("capture/mask_object/000000.png"),
        dir.path().join("capture/mask_object/000005.png"),
    )
    .expect("restore");

    // A broken scene script: position, suggestion, exit 2.
    let bad_scene = dir.path().join("run/bad.rhai");
    std::fs::write(&bad_scene, "part(\"a\", cilinder(0.5, 1));").expect("w");
    let o = agentstar(&["check", bad_scene.to_str().expect("utf8")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("did you mean `cylinder`") && text(&o).contains("1:11"),
        "{}",
        text(&o)
    );

    // A NaN pose.
    let bad_pose = dir.path().join("run/bad_pose.json");
    let p = std::fs::read_to_string(&poses).expect("r").replacen(
        "\"translation\": [",
        "\"translation\": [NaN, ",
        1,
    );
    std::fs::write(&bad_pose, p).expect("w");
    let o = on_poses("score", &cap, &model, bad_pose.to_str().expect("utf8"), &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("bad_pose.json"), "{}", text(&o));

    // Unknown frames and views are named with what is valid.
    let out = dir.path().join("v");
    for (args, says) in [
        (["--frames", "999999"], "unknown frame `999999`"),
        (
            ["--views", "xray"],
            "unknown view `xray`; views are overlay",
        ),
    ] {
        let mut all = args.to_vec();
        all.extend(["--out", out.to_str().expect("utf8")]);
        let o = on_poses("render", &cap, &model, &poses, &all);
        assert!(text(&o).contains(says), "{args:?}: {}", text(&o));
    }

    // A failing export leaves no partial file behind.
    let o = agentstar(&[
        "export",
        "--model",
        bad_scene.to_str().expect("utf8"),
        "--glb",
        dir.path().join("x.glb").to_str().expect("utf8"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!dir.path().join("x.glb").exists());
}

#[test]
fn completions_cover_every_subcommand() {
    let o = agentstar(&["completions", "bash"]);
    assert!(o.status.success(), "{}", text(&o));
    let script = String::from_utf8_lossy(&o.stdout);
    for sub in [
        "demo", "synth", "bench", "eval", "track", "export", "from-bop",
    ] {
        assert!(script.contains(sub), "bash completion lacks {sub}");
    }
    let o = agentstar(&["completions", "tcsh"]);
    assert_eq!(o.status.code(), Some(2));
}
