//! `agentstar eval`: the paper's metrics for a run against a capture's ground truth.

use crate::common::{print_json, SessionArgs};
use agentstar_data::gt::GroundTruth;
use agentstar_eval::sequence::{evaluate, EvalConfig, GtJoint, GtSequence, PredSequence};
use agentstar_geom::Vector3;
use anyhow::{anyhow, Result};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    /// The ground truth (default: CAPTURE/gt.json).
    #[arg(long)]
    gt: Option<PathBuf>,
    /// Surface samples per mesh for Chamfer distances.
    #[arg(long, default_value_t = 10_000)]
    samples: usize,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// The ground truth of a capture's frames, in the evaluator's form.
pub fn gt_sequence(gt: &GroundTruth, frames: &[String]) -> Result<GtSequence> {
    let names: Vec<String> = gt.meshes.keys().cloned().collect();
    let index = |n: &str| {
        names
            .iter()
            .position(|x| x == n)
            .ok_or_else(|| anyhow!("{}: unknown part `{n}`", gt.path.display()))
    };
    let mut poses = Vec::with_capacity(frames.len());
    for f in frames {
        let mut row = Vec::with_capacity(names.len());
        for n in &names {
            row.push(gt.pose(f, n).ok_or_else(|| {
                anyhow!(
                    "{}: frame `{f}` has no pose for part `{n}`",
                    gt.path.display()
                )
            })?);
        }
        poses.push(row);
    }
    let joints = gt
        .file
        .joints
        .iter()
        .map(|j| {
            let states = frames
                .iter()
                .map(|f| {
                    j.states.get(f).copied().ok_or_else(|| {
                        anyhow!(
                            "{}: joint `{}` has no state for frame `{f}`",
                            gt.path.display(),
                            j.name
                        )
                    })
                })
                .collect::<Result<Vec<f64>>>()?;
            Ok(GtJoint {
                name: j.name.clone(),
                revolute: j.kind != "prismatic",
                parent: index(&j.parent)?,
                child: index(&j.child)?,
                axis: Vector3::from(j.axis),
                origin: Vector3::from(j.origin),
                states,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(GtSequence {
        base_part: index(&gt.file.base_part)?,
        meshes: gt.meshes.values().cloned().collect(),
        part_names: names,
        poses,
        joints,
    })
}

pub fn run(a: Args) -> Result<ExitCode> {
    let s = a.session.open()?;
    let gt_path =
        a.gt.clone()
            .unwrap_or_else(|| a.session.capture.join("gt.json"));
    let gt = GroundTruth::load(&gt_path)?;
    let frames: Vec<String> = s.capture.frames.iter().map(|f| f.name.clone()).collect();
    let seq = gt_sequence(&gt, &frames)?;
    let pred = PredSequence {
        model: &s.model.model,
        scale: s.scale(),
        poses: s.poses.iter().map(|p| (p.pose, p.states.clone())).collect(),
    };
    let cams: Vec<_> = s.capture.frames.iter().map(|f| f.camera).collect();
    let m = evaluate(
        &seq,
        &pred,
        &cams,
        &EvalConfig {
            samples: a.samples,
            ..EvalConfig::default()
        },
    );
    let rigid = m.rigid.as_ref();
    let out = json!({
        "capture": a.session.capture, "poses": a.session.poses, "gt": gt_path, "frames": m.frames,
        "scale_alignment": m.scale_alignment,
        "epe_cm": m.epe_cm, "epe_points": m.epe_points,
        "chamfer_cm": m.chamfer_cm, "cd_moving_cm": m.cd_moving_cm, "cd_static_cm": m.cd_static_cm,
        "rotation_mean_deg": rigid.map(|r| r.rotation_mean_deg), "rotation_median_deg": rigid.map(|r| r.rotation_median_deg),
        "translation_mean_cm": rigid.map(|r| r.translation_mean_cm), "translation_median_cm": rigid.map(|r| r.translation_median_cm),
        "joints": m.joints.iter().map(|j| json!({"gt_joint": j.gt_joint, "pred_joint": j.pred_joint, "matched_by": j.matched_by,
            "axis_angle_rad": j.axis_angle_rad, "axis_distance_m": j.axis_distance_m, "state_error": j.state_error})).collect::<Vec<_>>(),
    });
    if a.json {
        print_json(&out)?;
        return Ok(ExitCode::SUCCESS);
    }
    let f = |v: Option<f64>| v.map_or("n/a".to_string(), |x| format!("{x:.3}"));
    println!("| metric | value |\n|---|---|");
    println!("| frames | {} |", m.frames);
    println!("| scale alignment ŝ | {:.4} |", m.scale_alignment);
    println!("| 3D EPE (cm, {} points) | {} |", m.epe_points, f(m.epe_cm));
    println!("| Chamfer (cm) | {} |", f(m.chamfer_cm));
    println!(
        "| rotation error mean / median (°) | {} / {} |",
        f(rigid.map(|r| r.rotation_mean_deg)),
        f(rigid.map(|r| r.rotation_median_deg))
    );
    println!(
        "| translation error mean / median (cm) | {} / {} |",
        f(rigid.map(|r| r.translation_mean_cm)),
        f(rigid.map(|r| r.translation_median_cm))
    );
    if !m.joints.is_empty() {
        println!(
            "| CD-w / CD-m / CD-s (cm) | {} / {} / {} |",
            f(m.chamfer_cm),
            f(m.cd_moving_cm),
            f(m.cd_static_cm)
        );
    }
    for j in &m.joints {
        println!(
            "| joint {} ↔ {} ({}) | axis {} rad, line {} m, state {} |",
            j.gt_joint,
            j.pred_joint.as_deref().unwrap_or("-"),
            j.matched_by,
            f(j.axis_angle_rad),
            f(j.axis_distance_m),
            f(j.state_error)
        );
    }
    Ok(ExitCode::SUCCESS)
}
