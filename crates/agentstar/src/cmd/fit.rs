//! `agentstar fit-shape`: fit the named `param(...)` values of a scene script against the
//! committed poses over chosen keyframes (the poses refined locally as it goes), and write
//! the script with the fitted values, the poses for it, a report and before/after
//! silhouette comparisons.

use crate::common::OpenSession as _;
use crate::common::{out_dir, print_json, select_frames, SessionArgs};
use agentstar_data::history::PoseHistory;
use agentstar_data::images::save_png_rgb;
use agentstar_data::posefile::{joint_json, pose_json, PoseFile};
use agentstar_data::scenefile::ScriptDirMeshes;
use agentstar_geom::ObjectModel;
use agentstar_render::frames::{crop_box, crop_zoomed};
use agentstar_render::views::{contact_sheet, silhouette_comparison};
use agentstar_render::{PosedModel, ScoreTarget, SilhouetteRenderer};
use agentstar_reports::fit::{FitFrame, FitParam, FitReport, FitRoundRow, HeldParam};
use agentstar_scene::{build_scene_with, set_param_values, Limits, ParamDecl};
use agentstar_track::shape::{fit_shape, ShapeFitConfig, ShapeFrame, ShapeParam};
use agentstar_track::GenPose;
use anyhow::{anyhow, bail, Context, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The report's file name in `--out`.
pub const REPORT: &str = "fit.json";
/// Frames shown on the comparison sheet (the worst before the fit first).
const SHEET_FRAMES: usize = 6;
/// Long side of a before/after tile, cropped around the mask and both silhouettes (the
/// object, not the frame: play-test 5 could not judge a lid's edge on whole 640×480 tiles).
const TILE_LONG_SIDE_PX: u32 = 380;
/// Margin of that crop, a fraction of the box's longer side.
const TILE_MARGIN: f64 = 0.12;

#[derive(clap::Args)]
#[command(
    after_help = "The script declares the parameters, e.g. `let d = param(\"depth\", 0.6, 0.4, 0.9);`.\n\nExample:\n  agentstar fit-shape --capture cap --model run/scene.rhai --poses run/pose.json --params depth,handle_height --out run/fit"
)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    /// The parameters to fit, comma separated (names of the script's `param(...)` calls);
    /// every other parameter keeps its value.
    #[arg(long)]
    params: String,
    /// Keyframes to fit on: `all` (default), names, stems, indices or `a..b` ranges.
    #[arg(long)]
    frames: Option<String>,
    /// Output directory: fit_scene.rhai, fit_pose.json, fit.json, fit_compare_sheet.png.
    #[arg(long)]
    out: PathBuf,
    /// Rounds of (parameters with poses held, poses refined).
    #[arg(long, default_value_t = 3)]
    rounds: usize,
    /// Model builds per round.
    #[arg(long, default_value_t = 60)]
    evals: usize,
    /// Hold the poses as committed (no local refinement).
    #[arg(long)]
    no_refine: bool,
    /// The part kept in place when the poses are carried to each new shape (default: the
    /// part with the most visible pixels in the fitted keyframes at their poses).
    #[arg(long)]
    hold: Option<String>,
    /// Seed of the pose refinements.
    #[arg(long, default_value_t = 17)]
    seed: u64,
    /// Write the fitted script over --model and the poses over --poses (recorded as a pose
    /// version).
    #[arg(long)]
    write: bool,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// The script's directory (meshes named by the script are beside it).
fn script_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

fn names(list: &str) -> Vec<String> {
    list.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect()
}

pub fn run(a: Args) -> Result<ExitCode> {
    let model_path = &a.session.model;
    if model_path.extension().and_then(|e| e.to_str()) != Some("rhai") {
        bail!(
            "{}: fit-shape fits the `param(...)` values of a scene script (.rhai); a URDF or mesh has none",
            model_path.display()
        );
    }
    if a.rounds == 0 || a.rounds > 20 {
        bail!("--rounds must be 1 to 20, got {}", a.rounds);
    }
    if a.evals < 5 || a.evals > 5000 {
        bail!("--evals must be 5 to 5000, got {}", a.evals);
    }
    let t0 = std::time::Instant::now();
    let s = a.session.open()?;
    let source = agentstar_data::read_text(model_path)?;
    let meshes = ScriptDirMeshes::new(script_dir(model_path));
    let limits = Limits::default();
    let declared: Vec<ParamDecl> = build_scene_with(&source, &meshes, &limits, &BTreeMap::new())
        .map_err(|e| anyhow!("{}: {e}", model_path.display()))?
        .params;
    let wanted = names(&a.params);
    if wanted.is_empty() {
        bail!("--params: name at least one parameter");
    }
    let mut params = vec![];
    for name in &wanted {
        let Some(d) = declared.iter().find(|d| &d.name == name) else {
            bail!(
                "--params: {} declares no parameter `{name}`; {}",
                model_path.display(),
                if declared.is_empty() {
                    "declare one with `let d = param(\"depth\", 0.6, 0.4, 0.9);` (value, min, max)"
                        .to_string()
                } else {
                    format!(
                        "it declares {}",
                        declared
                            .iter()
                            .map(|d| d.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                }
            );
        };
        if params.iter().any(|p: &ShapeParam| &p.name == name) {
            bail!("--params: `{name}` is named twice");
        }
        params.push(ShapeParam {
            name: name.clone(),
            start: d.value,
            min: d.min,
            max: d.max,
        });
    }
    let build = |values: &[f64]| -> std::result::Result<ObjectModel, String> {
        let overrides: BTreeMap<String, f64> =
            wanted.iter().cloned().zip(values.iter().copied()).collect();
        build_scene_with(&source, &meshes, &limits, &overrides)
            .map(|b| b.model)
            .map_err(|e| e.to_string())
    };
    // The joints of the session's model are the script's; the poses resolve against them.
    let indices = select_frames(&s.capture, a.frames.as_deref())?;
    let targets: Vec<ScoreTarget> = indices
        .iter()
        .map(|&i| s.target(i).map(|(t, _)| t))
        .collect::<Result<_>>()?;
    let frames: Vec<ShapeFrame<'_>> = indices
        .iter()
        .zip(&targets)
        .map(|(&i, t)| ShapeFrame {
            name: s.capture.frames[i].name.clone(),
            camera: s.capture.frames[i].camera,
            target: t,
            pose: s.gen_pose(i),
        })
        .collect();
    // The part held in place as the shape changes: named, or the one most in view.
    let visible = agentstar_render::visible_part_pixels(
        &s.model.model,
        frames.iter().map(|f| {
            (
                &f.camera,
                f.pose.pose.with_scale(s.scale()),
                f.pose.states.as_slice(),
            )
        }),
    );
    let held = agentstar_geom::held_part(
        &s.model.model,
        &s.model.model,
        a.hold.as_deref(),
        Some((&visible, frames.len())),
    )
    .map_err(|e| anyhow!("--hold: {e}"))?;
    eprintln!(
        "fit-shape: holding part `{}` in place ({})",
        held.name, held.why
    );
    let cfg = ShapeFitConfig {
        held: Some(held.name.clone()),
        rounds: a.rounds,
        evals_per_round: a.evals,
        refine_poses: !a.no_refine,
        seed: a.seed,
        ..ShapeFitConfig::default()
    };
    eprintln!(
        "fit-shape: {} parameter(s) over {} keyframe(s), up to {} round(s) of {} builds",
        params.len(),
        frames.len(),
        a.rounds,
        a.evals
    );
    let fit = fit_shape(&build, &params, &frames, s.scale(), &cfg)?;
    let dir = out_dir(&a.out)?;

    // The script with the fitted values, and every frame's pose for it.
    let values: BTreeMap<String, f64> = wanted
        .iter()
        .cloned()
        .zip(fit.values.iter().copied())
        .collect();
    let fitted_source =
        set_param_values(&source, &values).map_err(|e| anyhow!("{}: {e}", model_path.display()))?;
    let mut pf: PoseFile = s.pose_file.clone();
    agentstar_data::poses::carry_origin(&s.model.model, &fit.model, &mut pf, &held);
    let tree = &fit.model.tree;
    pf.joint_defs = tree.joints().iter().map(joint_json).collect();
    for (&i, g) in indices.iter().zip(&fit.poses) {
        let e = pf
            .frames
            .entry(s.capture.frames[i].name.clone())
            .or_default();
        e.object_pose = Some(pose_json(&g.pose, Some(pf.scale)));
        e.joints = tree.states_to_interface(&g.states);
    }
    let scene_out = dir.join("fit_scene.rhai");
    let poses_out = dir.join("fit_pose.json");
    agentstar_data::atomic::write_atomic(&scene_out, fitted_source.as_bytes())?;
    pf.write(&poses_out)?;

    // Before/after comparisons of the frames that were worst before.
    let mut order: Vec<usize> = (0..frames.len()).collect();
    order.sort_by(|&x, &y| fit.before[x].total_cmp(&fit.before[y]));
    order.truncate(SHEET_FRAMES);
    order.sort_unstable();
    let start_model = build(&params.iter().map(|p| p.start).collect::<Vec<_>>())
        .map_err(|e| anyhow!("{}: {e}", model_path.display()))?;
    let mut tiles = vec![];
    for &k in &order {
        let i = indices[k];
        let mask = s.capture.load_mask(i)?;
        let hand = s.capture.load_hand(i)?;
        let pair = [
            ("before", &start_model, &frames[k].pose, fit.before[k]),
            ("after", &fit.model, &fit.poses[k], fit.after[k]),
        ]
        .map(|(label, m, g, iou)| {
            let sil = silhouette(m, g, s.scale(), &frames[k].camera);
            (label, sil, iou)
        });
        // One crop for the pair, around the mask and both silhouettes: the tiles line up.
        let both = pair[0].1.or(&pair[1].1);
        let crop = crop_box(&mask, Some(&both), TILE_MARGIN).unwrap_or([
            0,
            0,
            mask.width(),
            mask.height(),
        ]);
        for (label, sil, iou) in &pair {
            let (img, _) = silhouette_comparison(sil, &mask, hand.as_ref());
            tiles.push((
                format!("{} {label} {iou:.4}", s.capture.frames[i].stem),
                crop_zoomed(&img, crop, TILE_LONG_SIDE_PX),
            ));
        }
    }
    let title = format!(
        "fit-shape: {}",
        params
            .iter()
            .zip(&fit.values)
            .map(|(p, v)| format!("{} {:.4}->{:.4}", p.name, p.start, v))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let sheet = dir.join("fit_compare_sheet.png");
    save_png_rgb(&contact_sheet(&tiles, 4, &title), &sheet)?;

    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let min = |v: &[f64]| v.iter().copied().fold(1.0, f64::min);
    let mut report = FitReport {
        params: params
            .iter()
            .zip(&fit.values)
            .map(|(p, &v)| FitParam {
                name: p.name.clone(),
                before: p.start,
                after: v,
                min: p.min,
                max: p.max,
                at_bound: (v - p.min).min(p.max - v) < AT_BOUND_SHARE * (p.max - p.min),
            })
            .collect(),
        held: declared
            .iter()
            .filter(|d| !wanted.contains(&d.name))
            .map(|d| HeldParam {
                name: d.name.clone(),
                value: d.value,
            })
            .collect(),
        frames: frames
            .iter()
            .enumerate()
            .map(|(k, f)| FitFrame {
                frame: f.name.clone(),
                iou_before: fit.before[k],
                iou_after: fit.after[k],
                iou_band_after: Some(agentstar_track::objective::band_iou(
                    &fit.model,
                    f.camera,
                    &f.target
                        .clone()
                        .with_band(agentstar_render::DEFAULT_BAND_PX),
                    s.scale(),
                    &fit.poses[k],
                )),
            })
            .collect(),
        iou_mean_before: mean(&fit.before),
        iou_mean_after: mean(&fit.after),
        iou_min_before: min(&fit.before),
        iou_min_after: min(&fit.after),
        rounds: fit
            .rounds
            .iter()
            .map(|r| FitRoundRow {
                values: r.values.clone(),
                iou_held: r.iou_held,
                iou_refined: r.iou_refined,
                builds: r.builds,
                guided: r
                    .guided
                    .as_ref()
                    .map(|g| agentstar_reports::fit::GuidedRow {
                        wanted: g.wanted,
                        values: g.values.clone(),
                        iou_refined: g.iou_refined,
                        taken: g.taken,
                    }),
            })
            .collect(),
        origin_shift: fit.origin_shift.shift.into(),
        scene: scene_out.clone(),
        poses: poses_out.clone(),
        sheets: vec![sheet],
        builds: fit.builds,
        evaluations: fit.evaluations,
        seconds: t0.elapsed().as_secs_f64(),
        written: false,
        views: Some(view_residuals(&fit, &frames, s.scale())),
        held_part: Some(format!("{} ({})", held.name, held.why)),
        unmet: fit
            .unmet
            .iter()
            .map(|u| agentstar_reports::fit::UnmetAxis {
                axis: ["X", "Y", "Z"][u.axis].to_string(),
                want: u.want,
            })
            .collect(),
        unseen: params
            .iter()
            .zip(&fit.iou_span)
            .filter(|(_, &span)| span < agentstar_track::shape::UNSEEN_IOU)
            .map(|(p, &span)| agentstar_reports::fit::UnseenParam {
                name: p.name.clone(),
                iou_span: span,
            })
            .collect(),
    };
    if a.write {
        agentstar_data::atomic::write_atomic(model_path, fitted_source.as_bytes())?;
        PoseHistory::new(&a.session.poses)
            .replace(
                pf,
                &format!(
                    "fit-shape --params {}: {}",
                    a.params,
                    report
                        .params
                        .iter()
                        .map(|p| format!(
                            "{} {}",
                            p.name,
                            agentstar_scene::format_param_value(p.after)
                        ))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
            .with_context(|| format!("writing {}", a.session.poses.display()))?;
        report.written = true;
    }
    agentstar_data::atomic::write_json(&dir.join(REPORT), &report)?;
    if a.json {
        print_json(&report)?;
    } else {
        print_summary(&report);
    }
    Ok(ExitCode::SUCCESS)
}

/// The fitted silhouettes' residuals grouped by viewing direction, at the fitted poses.
fn view_residuals(
    fit: &agentstar_track::shape::ShapeFit,
    frames: &[ShapeFrame<'_>],
    scale: f64,
) -> agentstar_reports::fit::ViewResiduals {
    use agentstar_reports::fit as r;
    use agentstar_track::proportion as p;
    let v = agentstar_track::shape::shape_view_residuals(&fit.model, frames, &fit.poses, scale);
    let wants = |w: &p::AxisWants| r::AxisWants {
        want: w.want,
        equations: w.equations,
    };
    let all = wants(&v.all);
    let groups: Vec<r::ViewGroup> = v
        .groups
        .iter()
        .map(|g| r::ViewGroup {
            face_on: g.face_on.clone(),
            frames: g.frames.clone(),
            wants: wants(&g.wants),
        })
        .collect();
    r::ViewResiduals {
        verdict: r::ViewResiduals::verdict_of(&all, &groups),
        all,
        groups,
    }
}

/// The silhouette of `model` at `pose`.
fn silhouette(
    model: &ObjectModel,
    pose: &GenPose,
    scale: f64,
    camera: &agentstar_geom::PinholeCamera,
) -> agentstar_render::BitMask {
    let posed = PosedModel::new(model, &pose.states, &pose.pose.with_scale(scale));
    SilhouetteRenderer::new(camera.width, camera.height)
        .render(camera, &posed.instances)
        .clone()
}

fn print_summary(r: &FitReport) {
    for p in &r.params {
        println!(
            "{}: {} -> {} (bounds [{}, {}]){}",
            p.name,
            p.before,
            agentstar_scene::format_param_value(p.after),
            p.min,
            p.max,
            if p.at_bound { "  at a bound" } else { "" }
        );
    }
    if !r.held.is_empty() {
        println!(
            "held: {}",
            r.held
                .iter()
                .map(|h| format!("{} {}", h.name, h.value))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    println!(
        "visible IoU over {} keyframe(s): mean {:.4} -> {:.4}, min {:.4} -> {:.4} ({} builds, {:.1} s)",
        r.frames.len(),
        r.iou_mean_before,
        r.iou_mean_after,
        r.iou_min_before,
        r.iou_min_after,
        r.builds,
        r.seconds
    );
    if let Some(line) = agentstar_reports::fit::unmet_line(&r.unmet) {
        print!("{line}");
    }
    if let Some(line) = agentstar_reports::fit::unseen_line(&r.unseen) {
        print!("{line}");
    }
    if let Some(v) = &r.views {
        print!("{}", agentstar_reports::fit::views_text(v));
    }
    println!(
        "wrote {} and {}{}",
        r.scene.display(),
        r.poses.display(),
        if r.written {
            " (and over the inputs)"
        } else {
            ""
        }
    );
}

/// A fitted value within this share of its range from a bound is reported at the bound
/// ([`agentstar_reports::fit::FitParam::at_bound`]).
const AT_BOUND_SHARE: f64 = 0.02;
