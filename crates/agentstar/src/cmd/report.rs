//! `agentstar report RUN`: one self-contained HTML page of a run (keyframes with overlays,
//! a three.js 3-D view, score and temporal plots, the agent's steps).

use crate::common::{print_json, Session};
use agentstar_data::ledger;
use agentstar_render::views::{overlay, ShadeOptions};
use agentstar_report::{
    render_html, FrameEntry, Image, Report, Step, Temporal, Viewer, ViewerFrame, ViewerMaterial,
    ViewerPart, ViewerSurface, ViewerTexture,
};
use anyhow::{anyhow, bail, Context, Result};
use image::RgbImage;
use rayon::prelude::*;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "The run directory holds scene.rhai, pose.json, run.json (naming the capture) and, when an agent\nworked on it, ledger.jsonl. Without run.json give --capture.\n\nExamples:\n  agentstar report /tmp/agentstar-demo/run\n  agentstar report myrun --capture cap --out myrun.html"
)]
pub struct Args {
    /// The run directory.
    run: PathBuf,
    /// The capture (default: run.json's `capture`).
    #[arg(long)]
    capture: Option<PathBuf>,
    /// The model (default: run.json's `model`, else RUN/scene.rhai).
    #[arg(long)]
    model: Option<PathBuf>,
    /// The pose file (default: run.json's `poses`, else RUN/pose.json).
    #[arg(long)]
    poses: Option<PathBuf>,
    /// Ground truth to evaluate against (default: the capture's gt.json when present).
    #[arg(long)]
    gt: Option<PathBuf>,
    /// Do not evaluate against ground truth even when the capture has it.
    #[arg(long)]
    no_gt: bool,
    /// Where to write the page (default: RUN/report.html).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Largest width of the images in the page, in pixels.
    #[arg(long, default_value_t = 640)]
    max_width: u32,
    /// Title of the page.
    #[arg(long)]
    title: Option<String>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

fn downscale(img: &RgbImage, max_width: u32) -> RgbImage {
    if img.width() <= max_width {
        return img.clone();
    }
    let h = ((img.height() as f64) * max_width as f64 / img.width() as f64)
        .round()
        .max(1.0) as u32;
    image::imageops::resize(img, max_width, h, image::imageops::FilterType::Triangle)
}

fn jpeg(img: &RgbImage) -> Result<Image> {
    let mut bytes = vec![];
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 85)
        .encode_image(img)
        .context("encoding a JPEG")?;
    Ok(Image {
        mime: "image/jpeg".into(),
        bytes,
    })
}

fn column_major(m: &agentstar_geom::Matrix4) -> [f64; 16] {
    let mut a = [0.0; 16];
    a.copy_from_slice(m.as_slice());
    a
}

/// Everything the page shows, gathered from the run.
pub fn build_report(
    s: &Session,
    model_path: &Path,
    run: &Path,
    gt: Option<&Path>,
    max_width: u32,
    title: String,
) -> Result<Report> {
    let model = &s.model.model;
    let scale = s.scale();
    let n = s.capture.frames.len();
    let bar = crate::common::progress(n, "report");
    let frames: Vec<FrameEntry> = (0..n)
        .into_par_iter()
        .map(|i| -> Result<FrameEntry> {
            bar.inc(1);
            let f = &s.capture.frames[i];
            let img = s.capture.load_frame(i)?;
            let (buffers, shaded) = s.render_shaded(i, ShadeOptions { outlines: true });
            let over = overlay(&img, &shaded, 0.6);
            let score = s.score(i, 0.0)?;
            Ok(FrameEntry {
                name: f.name.clone(),
                frame: jpeg(&downscale(&img, max_width))?,
                overlay: jpeg(&downscale(&over, max_width))?,
                iou_visible: score.iou_visible,
                iou_raw: score.iou_raw,
                facing: s.facing_in(i, &buffers).map(|f| f.line),
            })
        })
        .collect::<Result<_>>()?;
    // The 3-D view: part meshes scaled to metres, poses in the world frame.
    let tree = &model.tree;
    let joints: Vec<(usize, &agentstar_geom::JointDef)> = tree
        .joints()
        .iter()
        .enumerate()
        .filter(|(_, j)| j.kind.has_state())
        .collect();
    let parts: Vec<ViewerPart> = model
        .parts
        .iter()
        .map(|p| ViewerPart {
            name: p.name.clone(),
            color: p.color,
            positions: p
                .mesh
                .positions
                .iter()
                .flat_map(|v| {
                    [
                        (v.x * scale) as f32,
                        (v.y * scale) as f32,
                        (v.z * scale) as f32,
                    ]
                })
                .collect(),
            triangles: p.mesh.triangles.iter().flatten().copied().collect(),
            surface: p.surface.as_deref().map(viewer_surface),
        })
        .collect();
    let viewer_frames: Vec<ViewerFrame> = s
        .capture
        .frames
        .iter()
        .zip(&s.poses)
        .map(|(f, p)| {
            let cam = p.generalised.pose.with_scale(scale);
            let world_from_part = tree
                .part_transforms(&p.generalised.states)
                .iter()
                .map(|a| {
                    let full = cam.compose(&agentstar_geom::Similarity::from_rigid(a));
                    let rigid = agentstar_geom::pose::Rigid::from_parts(
                        full.translation.into(),
                        full.rotation,
                    );
                    column_major(&(f.world_from_camera * rigid).to_homogeneous())
                })
                .collect();
            ViewerFrame {
                name: f.name.clone(),
                world_from_part,
                world_from_camera: column_major(&f.world_from_camera.to_homogeneous()),
                intrinsics: [f.camera.fx, f.camera.fy, f.camera.cx, f.camera.cy],
                size: [f.camera.width, f.camera.height],
                joint_states: joints
                    .iter()
                    .map(|(k, j)| {
                        let v = p.generalised.states.get(*k).copied().unwrap_or(0.0);
                        if j.kind.is_angular() {
                            v.to_degrees()
                        } else {
                            v * scale
                        }
                    })
                    .collect(),
            }
        })
        .collect();
    // Temporal report.
    let rep = agentstar_track::temporal::report(&crate::cmd::temporal::samples(s), scale, tree);
    let rows = rep.rows.iter().skip(1);
    let temporal = (n > 1).then(|| Temporal {
        pose_frame: rep.pose_frame.to_string(),
        frames: rows.clone().map(|r| r.frame.clone()).collect(),
        rot_step_deg: rows.clone().map(|r| r.vel_rot_deg).collect(),
        trans_step: rows.map(|r| r.vel_trans).collect(),
        warnings: rep.warnings.clone(),
    });
    // Facts.
    let gate = crate::common::PASS_IOU;
    let ious: Vec<f64> = frames.iter().filter_map(|f| f.iou_visible).collect();
    let below = frames
        .iter()
        .filter(|f| f.iou_visible.is_none_or(|v| v < gate))
        .count();
    let f0 = &s.capture.frames[0];
    let mut facts = vec![
        ("capture".to_string(), s.capture.dir.display().to_string()),
        (
            "keyframes".into(),
            format!("{n} ({}×{} px)", f0.camera.width, f0.camera.height),
        ),
        ("model".into(), model_path.display().to_string()),
        ("parts".into(), model.part_names().join(", ")),
        (
            "joints".into(),
            if joints.is_empty() {
                "none (rigid)".into()
            } else {
                joints
                    .iter()
                    .map(|(_, j)| format!("{} ({})", j.name, j.kind.as_str()))
                    .collect::<Vec<_>>()
                    .join(", ")
            },
        ),
        ("scale".into(), format!("{scale:.4} m per model unit")),
    ];
    if !ious.is_empty() {
        let mean = ious.iter().sum::<f64>() / ious.len() as f64;
        let min = ious.iter().copied().fold(f64::INFINITY, f64::min);
        facts.push((
            "IoU visible".into(),
            format!("mean {mean:.4}, min {min:.4}; {below} of {n} keyframes below the gate {gate}"),
        ));
    }
    // Metrics against ground truth.
    let mut metrics = vec![];
    if let Some(gt) = gt {
        let (m, _) = crate::cmd::eval::evaluate_run(s, gt, 20_000)?;
        metrics.push(("ground truth".into(), gt.display().to_string()));
        metrics.push((
            "scale alignment".into(),
            format!("{:.4}", m.scale_alignment),
        ));
        if let Some(v) = m.epe_cm {
            metrics.push(("EPE".into(), format!("{v:.2} cm")));
        }
        if let Some(v) = m.chamfer_cm {
            metrics.push(("Chamfer".into(), format!("{v:.2} cm")));
        }
        if let Some(r) = &m.rigid {
            metrics.push((
                "rotation error".into(),
                format!(
                    "mean {:.2}°, median {:.2}°",
                    r.rotation_mean_deg, r.rotation_median_deg
                ),
            ));
            metrics.push((
                "translation error".into(),
                format!(
                    "mean {:.2} cm, median {:.2} cm",
                    r.translation_mean_cm, r.translation_median_cm
                ),
            ));
        }
        for j in &m.joints {
            let mut parts = vec![format!("matched {}", j.matched_by)];
            if let Some(a) = j.axis_angle_rad {
                parts.push(format!("axis {:.2}°", a.to_degrees()));
            }
            if let Some(d) = j.axis_distance_m {
                parts.push(format!("position {:.1} mm", d * 1000.0));
            }
            if let Some(e) = j.state_error {
                parts.push(format!("state error {e:.4}"));
            }
            metrics.push((format!("joint {}", j.gt_joint), parts.join(", ")));
        }
    }
    // The ledger.
    let mut notes = vec![];
    let ledger_path = run.join("ledger.jsonl");
    let mut steps = vec![];
    if ledger_path.is_file() {
        let (entries, skipped) = ledger::read(&ledger_path)?;
        notes.extend(skipped);
        for e in entries {
            let images = e
                .images
                .iter()
                .map(|rel| {
                    let p = run.join(rel);
                    let img = agentstar_data::images::load_rgb(&p)
                        .ok()
                        .and_then(|img| jpeg(&downscale(&img, 240.min(max_width))).ok());
                    if img.is_none() {
                        notes.push(format!(
                            "step {}: image {} could not be read",
                            e.step,
                            p.display()
                        ));
                    }
                    (rel.clone(), img)
                })
                .collect();
            steps.push(Step {
                step: e.step,
                time_s: e.time_s,
                kind: e.kind,
                tool: e.tool,
                summary: e.summary,
                scores: e.scores.into_iter().collect(),
                images,
            });
        }
    }
    Ok(Report {
        title,
        facts,
        metrics,
        gate,
        frames,
        viewer: Viewer {
            parts,
            joint_names: joints.iter().map(|(_, j)| j.name.clone()).collect(),
            frames: viewer_frames,
        },
        temporal,
        steps,
        notes,
        generator: format!("agentstar {}", env!("CARGO_PKG_VERSION")),
    })
}

/// Writes the report of `run` to `out` (atomically); returns the number of bytes.
pub fn write_report(
    s: &Session,
    model_path: &Path,
    run: &Path,
    gt: Option<&Path>,
    out: &Path,
    max_width: u32,
    title: String,
) -> Result<usize> {
    let report = build_report(s, model_path, run, gt, max_width, title)?;
    let html = render_html(&report);
    agentstar_data::atomic::write_atomic(out, html.as_bytes())?;
    Ok(html.len())
}

pub fn run(a: Args) -> Result<ExitCode> {
    if !a.run.is_dir() {
        bail!("{}: not a run directory", a.run.display());
    }
    if a.max_width < 64 {
        bail!("--max-width {}: at least 64 pixels", a.max_width);
    }
    let rf = agentstar_data::runfile::RunFile::read(&a.run)?;
    let capture = a
        .capture
        .clone()
        .or_else(|| rf.as_ref().map(|r| r.capture.clone()))
        .ok_or_else(|| {
            anyhow!(
                "{}: no run.json names the capture; give --capture",
                a.run.display()
            )
        })?;
    let model = a
        .model
        .clone()
        .or_else(|| rf.as_ref().map(|r| r.model.clone()))
        .unwrap_or_else(|| a.run.join("scene.rhai"));
    let poses = a
        .poses
        .clone()
        .or_else(|| rf.as_ref().map(|r| r.poses.clone()))
        .unwrap_or_else(|| a.run.join("pose.json"));
    let s = Session::open(&capture, &model, &poses)?;
    let gt = match (&a.gt, a.no_gt) {
        (_, true) => None,
        (Some(g), _) => Some(g.clone()),
        (None, _) => Some(capture.join("gt.json")).filter(|p| p.is_file()),
    };
    let out = a.out.clone().unwrap_or_else(|| a.run.join("report.html"));
    let title = a.title.clone().unwrap_or_else(|| {
        format!(
            "agentstar report: {}",
            a.run
                .canonicalize()
                .unwrap_or_else(|_| a.run.clone())
                .display()
        )
    });
    let bytes = write_report(&s, &model, &a.run, gt.as_deref(), &out, a.max_width, title)?;
    if a.json {
        print_json(
            &json!({"report": out, "bytes": bytes, "frames": s.capture.frames.len(),
            "ground_truth": gt}),
        )?;
    } else {
        println!(
            "wrote {} ({:.1} MB, {} keyframes{}); open it in a browser, it works offline",
            out.display(),
            bytes as f64 / 1e6,
            s.capture.frames.len(),
            if gt.is_some() {
                ", with metrics against the ground truth"
            } else {
                ""
            }
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// A part's textures and vertex colours for the report's 3-D view: its triangles grouped by
/// material, each corner's colour and texture coordinates, the textures as PNG.
fn viewer_surface(surface: &agentstar_geom::SurfaceAppearance) -> ViewerSurface {
    use agentstar_geom::WrapMode;
    let wrap = |m: WrapMode| match m {
        WrapMode::Repeat => 10497,
        WrapMode::MirroredRepeat => 33648,
        WrapMode::ClampToEdge => 33071,
    };
    let mut textures: Vec<ViewerTexture> = Vec::new();
    let mut texture_of: Vec<(*const agentstar_geom::Texture, u32)> = Vec::new();
    let materials = surface
        .materials()
        .iter()
        .map(|m| ViewerMaterial {
            color: m.color,
            texture: m.texture.as_ref().and_then(|t| {
                let key = std::sync::Arc::as_ptr(t);
                if let Some((_, i)) = texture_of.iter().find(|(k, _)| *k == key) {
                    return Some(*i);
                }
                // A texture that does not encode is drawn in its material's colour.
                let png = agentstar_data::texture::texture_png(t).ok()?;
                textures.push(ViewerTexture {
                    png,
                    wrap: [wrap(t.wrap_u), wrap(t.wrap_v)],
                });
                let i = (textures.len() - 1) as u32;
                texture_of.push((key, i));
                Some(i)
            }),
        })
        .collect();
    let mut order: Vec<u32> = (0..surface.triangle_count() as u32).collect();
    // Stable: triangles keep their order within a material.
    order.sort_by_key(|&t| surface.triangle_material()[t as usize]);
    let mut groups: Vec<(u32, u32)> = Vec::new();
    for &t in &order {
        let m = u32::from(surface.triangle_material()[t as usize]);
        match groups.last_mut() {
            Some((n, last)) if *last == m => *n += 1,
            _ => groups.push((1, m)),
        }
    }
    let corner_colors = order
        .iter()
        .flat_map(|&t| {
            surface
                .corner_color()
                .map_or([[1.0; 3]; 3], |c| c[t as usize])
        })
        .flatten()
        .collect();
    let corner_uvs = match surface.corner_uv() {
        Some(uv) => order
            .iter()
            .flat_map(|&t| uv[t as usize])
            .flatten()
            .collect(),
        None => Vec::new(),
    };
    ViewerSurface {
        order,
        corner_colors,
        corner_uvs,
        groups,
        materials,
        textures,
    }
}
