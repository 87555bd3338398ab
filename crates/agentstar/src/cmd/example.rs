//! `agentstar example OUT`: the built-in example. Writes a synthetic capture of an
//! articulated object (a case with a hinged lid, held by a hand that occludes it), its scene
//! script and ground-truth poses, then validates, scores, renders, makes turntables and
//! exports, printing what it did.

use crate::cmd::score::{print_table, summarise};
use crate::cmd::turntable::turntable_tiles;
use crate::common::{out_dir, Session, PASS_IOU};
use agentstar_data::capture::{Capture, Keyframe, Manifest};
use agentstar_data::export::{write_glb, write_urdf};
use agentstar_data::images::{mask_to_gray, save_png_rgb};
use agentstar_data::posefile::{FramePose, PoseFile};
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{PinholeCamera, UnitQuaternion, Vector3};
use agentstar_render::views::{
    comparison_legend, contact_sheet, overlay, shade_model, silhouette_comparison, with_legend,
    ShadeOptions,
};
use agentstar_render::{render_full, BitMask, PosedModel};
use anyhow::{Context, Result};
use image::{Rgb, RgbImage};
use std::path::PathBuf;
use std::process::ExitCode;

/// The built-in scene: a case with a hinged lid and a handle.
pub const EXAMPLE_SCENE: &str = r##"// A carrying case: a hollow base, a lid hinged along its back edge, a handle on the front.
// Canonical frame: +Z up, centred, longest side about 1.
let base = box(1.0, 0.62, 0.26, 0.02) - box(0.92, 0.54, 0.3).translate(0, 0, 0.06);
let handle = torus(0.06, 0.018, 32, 12).rotate_y(90).translate(0, -0.31, -0.04);
part("base", union(base.translate(0, 0, -0.06), handle).color("#2f6fb0"));
part("lid", box(1.0, 0.62, 0.08, 0.02).translate(0, 0, 0.11).color("#e0a030"));
joint(#{ name: "hinge", type: "revolute", child: "lid", origin: [0, 0.31, 0.07], axis: [-1, 0, 0], limit: [0, 120] });
"##;

#[derive(clap::Args)]
#[command(after_help = "Example:\n  agentstar example /tmp/agentstar-example")]
pub struct Args {
    /// Directory to write the example into (capture/, run/, out/).
    out: PathBuf,
    /// Number of keyframes.
    #[arg(long, default_value_t = 12)]
    frames: usize,
}

/// A deterministic hash-based noise in [0, 1) for backgrounds.
fn noise(x: u32, y: u32, seed: u32) -> f32 {
    let mut h = x.wrapping_mul(374_761_393)
        ^ y.wrapping_mul(668_265_263)
        ^ seed.wrapping_mul(2_246_822_519);
    h = (h ^ (h >> 13)).wrapping_mul(1_274_126_177);
    ((h ^ (h >> 16)) & 0xffff) as f32 / 65536.0
}

pub fn run(a: Args) -> Result<ExitCode> {
    let root = out_dir(&a.out)?;
    let cap_dir = root.join("capture");
    let run_dir = root.join("run");
    let views_dir = root.join("out");
    let n = a.frames.clamp(2, 200);
    let (w, h) = (320u32, 240u32);
    let camera = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, w, h)?;

    // The model, from the built-in script.
    std::fs::create_dir_all(&run_dir)?;
    let scene_path = run_dir.join("scene.rhai");
    agentstar_data::atomic::write_atomic(&scene_path, EXAMPLE_SCENE.as_bytes())?;
    let model = agentstar_data::scenefile::load_model(&scene_path)?.model;
    let scale = 0.42;

    // Ground truth: the case turns in the hand while the lid opens.
    let mut gt: Vec<FramePose> = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 / (n - 1) as f64;
        let tilt = UnitQuaternion::from_axis_angle(
            &Vector3::x_axis(),
            (112.0f64 + 10.0 * (3.0 * t).sin()).to_radians(),
        );
        let yaw =
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), (-35.0 + 70.0 * t).to_radians());
        let roll = UnitQuaternion::from_axis_angle(
            &Vector3::z_axis(),
            (8.0 * (5.0 * t).sin()).to_radians(),
        );
        let pose = ObjectPose::new(
            roll * yaw * tilt,
            Vector3::new(0.03 * (4.0 * t).sin(), 0.02 - 0.03 * t, 0.95 + 0.1 * t),
        );
        gt.push(FramePose {
            generalised: agentstar_geom::GenPose::new(pose, vec![(10.0 + 95.0 * t).to_radians()]),
            seeded: false,
            moved: true,
        });
    }

    // The capture: frames, masks, hand masks, cameras, keyframes.
    let names: Vec<String> = (0..n).map(|k| format!("{:06}.png", k * 5)).collect();
    for (k, name) in names.iter().enumerate() {
        let stem = &name[..6];
        let posed = PosedModel::new(
            &model,
            &gt[k].generalised.states,
            &gt[k].generalised.pose.with_scale(scale),
        );
        let buffers = render_full(&camera, &posed.instances);
        let silhouette = buffers.silhouette();
        // A hand: an ellipse grasping the lower right of the object, in every other frame.
        let (hx, hy) = (
            205.0 + 20.0 * (k as f64 * 0.7).sin(),
            165.0 + 10.0 * (k as f64 * 0.5).cos(),
        );
        let hand = BitMask::from_fn(w, h, |x, y| {
            k % 2 == 0 && {
                let dx = (x as f64 + 0.5 - hx) / 38.0;
                let dy = (y as f64 + 0.5 - hy) / 24.0;
                dx * dx + dy * dy <= 1.0
            }
        });
        let visible = silhouette.and_not(&hand);
        let shaded = shade_model(
            &model,
            &posed.instances,
            &camera,
            &buffers,
            ShadeOptions { outlines: false },
        );
        let mut frame = RgbImage::from_fn(w, h, |x, y| {
            let g = 0.55 + 0.25 * (y as f32 / h as f32) + 0.08 * noise(x / 4, y / 4, 7);
            Rgb([(g * 200.0) as u8, (g * 190.0) as u8, (g * 175.0) as u8])
        });
        frame = overlay(&frame, &shaded, 1.0);
        for (x, y, p) in frame.enumerate_pixels_mut() {
            if hand.get(x, y) {
                let s = 0.9 + 0.1 * noise(x, y, 3);
                *p = Rgb([(225.0 * s) as u8, (170.0 * s) as u8, (140.0 * s) as u8]);
            }
        }
        save_png_rgb(&frame, &cap_dir.join("frames").join(name))?;
        agentstar_data::images::save_png_gray(
            &mask_to_gray(&visible),
            &cap_dir.join("mask_object").join(format!("{stem}.png")),
        )?;
        if k % 2 == 0 {
            agentstar_data::images::save_png_gray(
                &mask_to_gray(&hand),
                &cap_dir.join("mask_hand").join(format!("{stem}.png")),
            )?;
        }
    }
    // A slowly orbiting camera, identity for the first frame.
    let mut c2w = Vec::new();
    let mut ks = Vec::new();
    for k in 0..n {
        let ang = (k as f64 * 2.0f64).to_radians();
        let r = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), ang).to_rotation_matrix();
        let m = r.matrix();
        for row in 0..4 {
            for col in 0..4 {
                c2w.push(match (row, col) {
                    (3, 3) => 1.0f32,
                    (3, _) => 0.0,
                    (_, 3) => [0.02 * k as f64, 0.0, 0.0][row] as f32,
                    _ => m[(row, col)] as f32,
                });
            }
        }
        ks.extend([300.0f32, 0.0, 160.0, 0.0, 300.0, 120.0, 0.0, 0.0, 1.0]);
    }
    agentstar_data::npz::write_arrays(
        &cap_dir.join("tracking/cameras.npz"),
        &[("c2w", &[n, 4, 4], &c2w), ("intrinsics", &[n, 3, 3], &ks)],
        &[("size", &[2], &[w as i64, h as i64])],
    )?;
    let keyframes: Vec<Keyframe> = names
        .iter()
        .enumerate()
        .map(|(k, nm)| Keyframe {
            view: k,
            frame_index: Some(5 * k as i64),
            frame_name: nm.clone(),
            time_s: Some(5.0 * k as f64 / 30.0),
        })
        .collect();
    agentstar_data::atomic::write_json(&cap_dir.join("tracking/keyframes.json"), &keyframes)?;
    let manifest = Manifest {
        format: "capture/v1".into(),
        image_size: [w, h],
        frames: names.clone(),
        ref_frame: Some(names[0].clone()),
        depth: "none".into(),
        depth_scale: None,
        dataset: Some("agentstar-example".into()),
        source: Some(
            serde_json::json!({"producer": "agentstar example", "model": "built-in case with hinged lid"}),
        ),
        downscale: Some(1.0),
        undistorted: Some(true),
        keyframes: None,
    };
    agentstar_data::atomic::write_json(&Capture::manifest_path(&cap_dir), &manifest)?;
    write_ground_truth(&cap_dir, &model, scale, &names, &gt)?;

    // Validate the capture we wrote, then commit the ground truth as the run's poses.
    let problems = Capture::validate(&cap_dir);
    anyhow::ensure!(
        problems.is_empty(),
        "the example capture is invalid: {problems:?}"
    );
    let capture = crate::common::open_capture(&cap_dir)?;
    let mut pose_file = PoseFile::initial(&capture, &model.tree, scale, &gt[0].generalised.pose);
    pose_file.set_frames(&capture, &model.tree, &gt);
    let pose_path = run_dir.join("pose.json");
    pose_file.write(&pose_path)?;

    // The main job on it: score, views, turntables, exports.
    let session =
        Session::open(&cap_dir, &scene_path, &pose_path).context("opening the example run")?;
    let scores: Vec<_> = (0..n)
        .map(|i| session.score(i, 0.1))
        .collect::<Result<_>>()?;
    let summary = summarise(&scores, PASS_IOU);
    std::fs::create_dir_all(&views_dir)?;
    let mut tiles = Vec::new();
    for (i, (f, score)) in capture.frames.iter().zip(&scores).enumerate() {
        let (buffers, shaded) = session.render_shaded(i, ShadeOptions::default());
        let over = overlay(&capture.load_frame(i)?, &shaded, 0.6);
        save_png_rgb(&over, &views_dir.join(format!("overlay_{}.png", f.stem)))?;
        let (img, _) = silhouette_comparison(
            &buffers.silhouette(),
            &capture.load_mask(i)?,
            capture.load_hand(i)?.as_ref(),
        );
        let hand = capture.load_hand(i)?.is_some();
        save_png_rgb(
            &with_legend(
                &img,
                &format!("{} IoU visible {:.4}", f.name, score.gate()),
                &comparison_legend(hand),
            ),
            &views_dir.join(format!("compare_{}.png", f.stem)),
        )?;
        tiles.push((f.name.clone(), over));
    }
    save_png_rgb(
        &contact_sheet(&tiles, 4, "example: render over frame"),
        &views_dir.join("sheet_overlay.png"),
    )?;
    // Upright, as `agentstar turntable` shows a model.
    let ref_rot = crate::cmd::turntable::upright();
    for (label, k) in [("open_first", 0usize), ("open_last", n - 1)] {
        let t: Vec<(String, RgbImage)> =
            turntable_tiles(&model, &gt[k].generalised.states, &ref_rot, 200, 45.0)
                .into_iter()
                .map(|(l, i, _)| (l, i))
                .collect();
        let deg = gt[k].generalised.states[0].to_degrees();
        save_png_rgb(
            &contact_sheet(&t, 4, &format!("turntable hinge={deg:.0}")),
            &views_dir.join(format!("turntable_sheet_{label}.png")),
        )?;
    }
    write_glb(&model, &views_dir.join("object.glb"))?;
    let urdf = write_urdf(&model, &views_dir.join("urdf"), "case")?;

    println!("example written to {}", root.display());
    println!(
        "  capture: {} ({n} frames, {w}×{h}, hand masks on every other frame)",
        cap_dir.display()
    );
    println!(
        "  model:   {} ({} parts, joint `hinge`)",
        scene_path.display(),
        model.parts.len()
    );
    println!("  poses:   {}", pose_path.display());
    println!(
        "  views:   {} (overlays, comparisons, turntables, object.glb, {})",
        views_dir.display(),
        urdf.display()
    );
    print_table(&scores, &summary);
    Ok(if summary.below_gate.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `gt.json` of the example: part meshes in metres and each part's pose per frame.
fn write_ground_truth(
    cap_dir: &std::path::Path,
    model: &agentstar_geom::ObjectModel,
    scale: f64,
    names: &[String],
    gt: &[FramePose],
) -> Result<()> {
    use agentstar_data::gt::{model_ground_truth, GroundTruth};
    let frames: Vec<_> = names
        .iter()
        .zip(gt)
        .map(|(n, g)| (n.clone(), g.generalised.pose, g.generalised.states.clone()))
        .collect();
    let (file, meshes) = model_ground_truth(model, scale, &frames, &[]);
    Ok(GroundTruth::from_parts(&cap_dir.join("gt.json"), file, meshes).write(cap_dir)?)
}
