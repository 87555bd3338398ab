//! `agentstar scale`: metres per model unit from the capture's depth, from the parallax of
//! metric cameras that move around a static object, from a size the agent states, or from
//! the hands' apparent palm breadth (hand masks without depth); and
//! the poses rescaled to it (rotations kept, translations scaled, so every silhouette stays).

use crate::common::OpenSession as _;
use crate::common::{print_json, select_frames, SessionArgs};
use agentstar_data::history::PoseHistory;
use agentstar_reports::fit::{ScaleFrame, ScaleReport};
use agentstar_requests::{ScaleMethod, SizeAxis};
use agentstar_track::scale::{
    ratio_from_depth, ratio_from_hand, ratio_from_parallax, DepthFrame, HandFrame, ParallaxFrame,
    ScaleEstimate, PALM_BREADTH_MEAN_M, PALM_BREADTH_SD_M,
};
use anyhow::{anyhow, bail, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar scale --capture cap --model run/scene.rhai --poses run/pose.json --from depth\n  agentstar scale --capture cap --model run/scene.rhai --poses run/pose.json --from size --axis x --metres 0.30 --write\n  agentstar scale --capture cap --model run/scene.rhai --poses run/pose.json --from hand"
)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    /// What to measure the scale from.
    #[arg(long = "from", value_enum)]
    method: ScaleMethod,
    /// With --from size: the model axis the size is along (`longest`: the longest side of the
    /// bounding box at rest).
    #[arg(long, value_enum, default_value = "longest")]
    axis: SizeAxis,
    /// With --from size: the object's size along --axis, metres.
    #[arg(long)]
    metres: Option<f64>,
    /// Keyframes to use: `all` (default), names, stems, indices or `a..b` ranges.
    #[arg(long)]
    frames: Option<String>,
    /// Write the rescaled poses to this file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the rescaled poses over --poses (recorded as a pose version).
    #[arg(long)]
    write: bool,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let s = a.session.open()?;
    let indices = select_frames(&s.capture, a.frames.as_deref())?;
    let scale = s.scale();
    let mut uncertainty = None;
    let mut palm_px: Vec<f64> = vec![];
    let (method, estimate, weak) = match a.method {
        ScaleMethod::Depth => {
            let mut inputs = vec![];
            for &i in &indices {
                let (target, depth) = s.target(i)?;
                if let Some(d) = depth {
                    inputs.push((i, s.render_buffers(i), d, target));
                }
            }
            if inputs.is_empty() {
                bail!(
                    "{}: no keyframe has depth; estimate from parallax instead (metric cameras that move: `--from parallax`, or method \"parallax\" in the agent's scale tool) or from a stated size (`--from size --metres M`, or method \"size\" with `metres`)",
                    a.session.capture.display()
                );
            }
            let frames: Vec<DepthFrame<'_>> = inputs
                .iter()
                .map(|(i, r, d, t)| DepthFrame {
                    name: s.capture.frames[*i].name.clone(),
                    render: r,
                    observed: d,
                    target: t,
                })
                .collect();
            let e = ratio_from_depth(&frames)?;
            let weak = !e.notes.is_empty();
            (ScaleMethod::Depth, e, weak)
        }
        ScaleMethod::Parallax => {
            let frames: Vec<ParallaxFrame> = indices
                .iter()
                .map(|&i| ParallaxFrame {
                    name: s.capture.frames[i].name.clone(),
                    world_from_camera: s.capture.frames[i].world_from_camera,
                    origin_in_camera: s.poses[i].generalised.pose.translation,
                })
                .collect();
            let mut e = ratio_from_parallax(&frames)?;
            // The estimate's own notes are its warnings (a short baseline, an object that
            // wanders); the assumption below holds for every parallax estimate.
            let weak = !e.notes.is_empty();
            e.notes.push(
                "parallax assumes the cameras are metric (COLMAP without --background-depth-m is not) and the object stays put in the world".into(),
            );
            (ScaleMethod::Parallax, e, weak)
        }
        ScaleMethod::Size => {
            let metres = a
                .metres
                .ok_or_else(|| anyhow!("the size method needs the object's size in metres (`--metres` here, `metres` in the agent's scale tool) along its axis (`--axis` / `axis`)"))?;
            if !(metres.is_finite() && metres > 0.0) {
                bail!("the size in metres (`--metres` / `metres`) must be positive, got {metres}");
            }
            let m = &s.model.model;
            let extent = m.posed_bounds(&m.tree.rest_states()).extent();
            let units = match a.axis {
                SizeAxis::X => extent.x,
                SizeAxis::Y => extent.y,
                SizeAxis::Z => extent.z,
                SizeAxis::Longest => extent.max(),
            };
            if !(units.is_finite() && units > 1e-9) {
                bail!("the model has no extent along {:?}", a.axis);
            }
            let new_scale = metres / units;
            (
                ScaleMethod::Size,
                ScaleEstimate {
                    ratio: new_scale / scale,
                    per_frame: vec![],
                    spread: 0.0,
                    samples: 1,
                    notes: vec![format!(
                        "{metres} m along {:?} over the model's {units:.4} units at rest",
                        a.axis
                    )],
                },
                false,
            )
        }
        ScaleMethod::Hand => {
            let mut hands = vec![];
            for &i in &indices {
                if let Some(hand) = s.capture.load_hand(i)? {
                    hands.push((i, hand));
                }
            }
            if hands.is_empty() {
                bail!(
                    "{}: no keyframe asked for has a hand mask (mask_hand/<stem>.png); the hand route needs hands holding the object. Use depth, parallax or a stated size instead",
                    a.session.capture.display()
                );
            }
            let m = &s.model.model;
            let frames: Vec<HandFrame<'_>> = hands
                .iter()
                .map(|(i, hand)| {
                    let p = &s.poses[*i].generalised;
                    let bounds = m.posed_bounds(&p.states);
                    let placed = p.pose.with_scale(scale);
                    let centre = placed.transform_point(&bounds.center());
                    let cam = &s.capture.frames[*i].camera;
                    HandFrame {
                        name: s.capture.frames[*i].name.clone(),
                        hand,
                        focal_px: (cam.fx * cam.fy).sqrt(),
                        object_depth_m: centre.z,
                        object_radius_m: 0.5 * bounds.extent().norm() * scale,
                    }
                })
                .collect();
            let h = ratio_from_hand(&frames)?;
            let mut e = h.estimate;
            let weak = !e.notes.is_empty();
            uncertainty = Some(h.uncertainty);
            palm_px = h.palm_px;
            e.notes.push(format!(
                "assumes adult hands (palm breadth {:.1} ± {:.1} cm, approximate anthropometric figures) holding the object, so that the hand is at its depth: ± {:.0}% (one standard deviation; the truth lies within twice that about 95% of the time). Depth (`--from depth`, method \"depth\" in the agent's scale tool) where the capture has it, parallax with metric cameras around an object that stays put (`--from parallax`, \"parallax\"), or a size you know (`--from size`, \"size\" with `metres`) are better where they apply",
                100.0 * PALM_BREADTH_MEAN_M,
                100.0 * PALM_BREADTH_SD_M,
                100.0 * h.uncertainty
            ));
            if s.capture.manifest.depth != "none" {
                e.notes.push(
                    "this capture has depth: `--from depth` (method \"depth\") measures the scale, the hand only estimates it".into(),
                );
            }
            (ScaleMethod::Hand, e, weak)
        }
    };
    let new_scale = scale * estimate.ratio;
    let mut pf = s.pose_file.clone();
    agentstar_data::poses::rescale(&mut pf, new_scale).map_err(|e| anyhow!(e))?;
    if let Some(out) = &a.out {
        pf.write(out)?;
    }
    let mut report = ScaleReport {
        method,
        scale_before: scale,
        scale_after: new_scale,
        ratio: estimate.ratio,
        frames: estimate
            .per_frame
            .iter()
            .enumerate()
            .map(|(k, (f, v))| ScaleFrame {
                frame: f.clone(),
                value: *v,
                palm_px: palm_px.get(k).copied(),
            })
            .collect(),
        spread: estimate.spread,
        samples: estimate.samples,
        uncertainty,
        notes: estimate.notes,
        weak,
        poses: a.out.clone(),
        written: false,
    };
    if a.write {
        PoseHistory::new(&a.session.poses).replace(
            pf,
            &format!(
                "scale --from {}: {scale} -> {new_scale:.6} m per unit (translations × {:.6})",
                method.as_str(),
                estimate.ratio
            ),
        )?;
        report.written = true;
    }
    if a.json {
        print_json(&report)?;
    } else {
        println!(
            "scale: {scale} -> {new_scale:.6} m per model unit (× {:.4}, spread {:.2}%, {} sample(s){}){}",
            report.ratio,
            100.0 * report.spread,
            report.samples,
            match report.uncertainty {
                Some(u) => format!(", ± {:.0}% one standard deviation", 100.0 * u),
                None => String::new(),
            },
            if report.written { "; pose.json rescaled" } else { "" }
        );
        for n in &report.notes {
            println!("note: {n}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
