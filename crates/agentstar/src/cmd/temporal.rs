//! `agentstar temporal` (velocities and accelerations per step, with a plot) and
//! `agentstar pose-diff` (the residual between two frames).

use crate::common::OpenSession as _;
use crate::common::{
    joint_at_limit, print_json, read_acknowledged_limits, select_frames, Session, SessionArgs,
};
use agentstar_data::images::save_png_rgb;
use agentstar_render::text::{draw_text, fill_rect};
use agentstar_reports::limits::JointAtLimit;
use agentstar_reports::{
    JointMotion, Motion, PoseDiffReport, TemporalLargeStep, TemporalReport, TemporalRow,
    TemporalUnits,
};
use agentstar_track::temporal::{pair_diff, report, Row, Sample};
use anyhow::{bail, Result};
use image::{Rgb, RgbImage};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar temporal --capture cap --model run/scene.rhai --poses run/pose.json --plot temporal.png"
)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    /// Rows: frames, names or `a..b` ranges (all rows by default).
    #[arg(long)]
    frames: Option<String>,
    /// Columns: any of vel, accel and joint names (default all).
    #[arg(long)]
    columns: Option<String>,
    /// The sort (the `temporal` tool's arguments).
    #[command(flatten)]
    request: agentstar_requests::TemporalArgs,
    /// Write a plot of the velocities over the sequence here (PNG).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// A record of acknowledged joint-limit warnings (JSON, as the agent's tools keep it in
    /// a run's `.agentstar/limits_acknowledged.json`): those are summarised in one line.
    #[arg(long)]
    limits_acknowledged: Option<PathBuf>,
}

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar pose-diff --capture cap --model run/scene.rhai --poses run/pose.json --a 000010.png --b 000015.png"
)]
pub struct DiffArgs {
    #[command(flatten)]
    session: SessionArgs,
    /// The two keyframes (the `pose_diff` tool's arguments).
    #[command(flatten)]
    request: agentstar_requests::PoseDiffArgs,
}

pub(crate) fn samples(s: &Session) -> Vec<Sample> {
    // Every capture has cameras (a shared one is the identity), so motion is always
    // compensated by them.
    s.capture
        .frames
        .iter()
        .zip(&s.poses)
        .map(|(f, p)| Sample {
            frame: f.name.clone(),
            number: f.number,
            pose: p.generalised.pose,
            states: p.generalised.states.clone(),
            world_from_camera: Some(f.world_from_camera),
        })
        .collect()
}

fn value(r: &Row, col: &str) -> Option<f64> {
    match col {
        "vel.rot" => r.vel_rot_deg,
        "vel.trans" => r.vel_trans,
        "vel.radial" => r.vel_radial,
        "accel.rot" => r.acc_rot_deg,
        "accel.trans" => r.acc_trans,
        "accel.radial" => r.acc_radial,
        other => {
            let (j, what) = other.rsplit_once('.')?;
            let c = r.joints.iter().find(|c| c.name == j)?;
            match what {
                "vel" => c.velocity,
                "accel" => c.acceleration,
                "state" => Some(c.state),
                _ => None,
            }
        }
    }
}

fn cell(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{x:.3}"))
}

pub fn run(a: Args) -> Result<ExitCode> {
    let s = a.session.open()?;
    let samples = samples(&s);
    let rep = report(&samples, s.scale(), &s.model.model.tree);
    // Joints piled at a limit over the sequence (a too-tight limit or a reversed axis).
    let states: Vec<Vec<f64>> = samples.iter().map(|x| x.states.clone()).collect();
    let names: Vec<String> = samples.iter().map(|x| x.frame.clone()).collect();
    let at_limit: Vec<JointAtLimit> = s
        .model
        .model
        .tree
        .at_limit(&states, &names)
        .into_iter()
        .map(joint_at_limit)
        .collect();
    let acknowledged = read_acknowledged_limits(a.limits_acknowledged.as_deref())?;
    let keep = select_frames(&s.capture, a.frames.as_deref())?;
    let mut rows: Vec<&Row> = keep.iter().map(|&i| &rep.rows[i]).collect();
    let joint_names: Vec<String> = s
        .model
        .model
        .tree
        .moving_joint_names()
        .into_iter()
        .map(str::to_string)
        .collect();
    let cols: Vec<String> = a
        .columns
        .as_deref()
        .map(|c| c.split(',').map(|x| x.trim().to_string()).collect())
        .unwrap_or_else(|| {
            let mut v = vec!["vel".to_string(), "accel".to_string()];
            v.extend(joint_names.clone());
            v
        });
    for c in &cols {
        if c != "vel" && c != "accel" && !joint_names.contains(c) {
            bail!(
                "unknown column `{c}`; columns are vel, accel and the joints ({})",
                joint_names.join(", ")
            );
        }
    }
    if let Some(key) = &a.request.sort_by {
        let valid = [
            "vel.rot",
            "vel.trans",
            "vel.radial",
            "accel.rot",
            "accel.trans",
            "accel.radial",
        ];
        if !valid.contains(&key.as_str())
            && !joint_names
                .iter()
                .any(|j| key.starts_with(&format!("{j}.")))
        {
            bail!(
                "cannot sort by `{key}`; use one of {} or <joint>.vel|accel|state",
                valid.join(", ")
            );
        }
        rows.sort_by(|x, y| match (value(x, key), value(y, key)) {
            (Some(p), Some(q)) => q.abs().total_cmp(&p.abs()),
            (Some(_), None) => std::cmp::Ordering::Less,
            (None, Some(_)) => std::cmp::Ordering::Greater,
            _ => std::cmp::Ordering::Equal,
        });
    }
    if let Some(plot) = &a.plot {
        save_png_rgb(&plot_velocities(&rep.rows), plot)?;
    }
    if a.json {
        let motion = |rot, axis, trans, radial| Motion {
            rotation_deg: rot,
            axis_model: axis,
            translation_canon: trans,
            radial_canon: radial,
        };
        print_json(&TemporalReport {
            pose_frame: rep.pose_frame.to_string(),
            units: TemporalUnits {
                rotation: "deg per step".into(),
                translation: "object units per step".into(),
                joints: "deg or canonical units per step".into(),
            },
            large_step_deg: agentstar_track::temporal::LARGE_STEP_DEG,
            large_steps: rep
                .large_steps
                .iter()
                .map(|s| TemporalLargeStep {
                    from: s.from.clone(),
                    to: s.to.clone(),
                    rotation_deg: s.rotation_deg,
                })
                .collect(),
            warnings: rep.warnings.clone(),
            at_limit,
            frames: rows
                .iter()
                .map(|r| TemporalRow {
                    frame: r.frame.clone(),
                    from: r.from.clone(),
                    frame_gap: r.gap,
                    velocity: motion(r.vel_rot_deg, r.vel_axis, r.vel_trans, r.vel_radial),
                    acceleration: motion(r.acc_rot_deg, None, r.acc_trans, r.acc_radial),
                    joints: r
                        .joints
                        .iter()
                        .map(|c| {
                            (
                                c.name.clone(),
                                JointMotion {
                                    state: c.state,
                                    velocity: c.velocity,
                                    acceleration: c.acceleration,
                                },
                            )
                        })
                        .collect(),
                })
                .collect(),
        })?;
        return Ok(ExitCode::SUCCESS);
    }
    let mut head = format!("{:<26} {:>4}", "step", "gap");
    if cols.iter().any(|c| c == "vel") {
        head.push_str(&format!(
            " {:>8} {:>20} {:>8} {:>8}",
            "v.rot", "v.axis (model)", "v.trans", "v.radial"
        ));
    }
    if cols.iter().any(|c| c == "accel") {
        head.push_str(&format!(
            " {:>8} {:>8} {:>8}",
            "a.rot", "a.trans", "a.radial"
        ));
    }
    for j in cols.iter().filter(|c| joint_names.contains(c)) {
        head.push_str(&format!(
            " {:>9} {:>8} {:>8}",
            format!("{j}"),
            "vel",
            "accel"
        ));
    }
    println!("{head}");
    if a.request.sort_by.is_some() {
        println!(
            "(sorted by |{}|, not in temporal order)",
            a.request.sort_by.as_deref().unwrap_or("")
        );
    }
    for r in rows {
        let step = match &r.from {
            Some(f) => format!("{f}->{}", r.frame),
            None => r.frame.clone(),
        };
        let mut line = format!(
            "{:<26} {:>4}",
            step,
            r.gap.map_or("-".into(), |g| g.to_string())
        );
        if cols.iter().any(|c| c == "vel") {
            line.push_str(&format!(
                " {:>8} {:>20} {:>8} {:>8}",
                cell(r.vel_rot_deg),
                r.vel_axis
                    .as_ref()
                    .map_or("-".into(), agentstar_track::temporal::axis_label),
                cell(r.vel_trans),
                cell(r.vel_radial)
            ));
        }
        if cols.iter().any(|c| c == "accel") {
            line.push_str(&format!(
                " {:>8} {:>8} {:>8}",
                cell(r.acc_rot_deg),
                cell(r.acc_trans),
                cell(r.acc_radial)
            ));
        }
        for j in cols.iter().filter(|c| joint_names.contains(c)) {
            if let Some(c) = r.joints.iter().find(|c| &c.name == j) {
                line.push_str(&format!(
                    " {:>9.3} {:>8} {:>8}",
                    c.state,
                    cell(c.velocity),
                    cell(c.acceleration)
                ));
            }
        }
        println!("{line}");
    }
    println!(
        "pose frame: {} (rotation in degrees, translation in object units, per step)",
        rep.pose_frame
    );
    for w in rep.warnings.iter().chain(&acknowledged.lines(&at_limit)) {
        println!("warning: {w}");
    }
    Ok(ExitCode::SUCCESS)
}

/// Rotation and translation velocity over the sequence, the three largest rotation steps
/// marked with their frame.
fn plot_velocities(rows: &[Row]) -> RgbImage {
    let (w, h, pad) = (900u32, 320u32, 40i64);
    let mut img = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
    let n = rows.len().max(2);
    let x_of = |i: usize| pad + (i as i64) * (w as i64 - 2 * pad) / (n as i64 - 1);
    type Series<'a> = (&'a str, Rgb<u8>, Vec<Option<f64>>);
    let series: [Series; 2] = [
        (
            "rotation deg/step",
            Rgb([200, 40, 40]),
            rows.iter().map(|r| r.vel_rot_deg).collect(),
        ),
        (
            "translation x100 obj units/step",
            Rgb([40, 90, 200]),
            rows.iter()
                .map(|r| r.vel_trans.map(|v| v * 100.0))
                .collect(),
        ),
    ];
    let max = series
        .iter()
        .flat_map(|s| s.2.iter().flatten())
        .copied()
        .fold(1e-9, f64::max);
    let y_of = |v: f64| h as i64 - pad - ((v / max) * (h as i64 - 2 * pad) as f64) as i64;
    fill_rect(
        &mut img,
        pad,
        h as i64 - pad,
        w - 2 * pad as u32,
        1,
        Rgb([0, 0, 0]),
    );
    for (si, (label, color, vals)) in series.iter().enumerate() {
        let mut last: Option<(i64, i64)> = None;
        for (i, v) in vals.iter().enumerate() {
            let Some(v) = v else { continue };
            let p = (x_of(i), y_of(*v));
            if let Some(q) = last {
                let steps = (p.0 - q.0).abs().max((p.1 - q.1).abs()).max(1);
                for k in 0..=steps {
                    let x = q.0 + (p.0 - q.0) * k / steps;
                    let y = q.1 + (p.1 - q.1) * k / steps;
                    fill_rect(&mut img, x - 1, y - 1, 2, 2, *color);
                }
            }
            fill_rect(&mut img, p.0 - 2, p.1 - 2, 5, 5, *color);
            last = Some(p);
        }
        draw_text(&mut img, pad + 340 * si as i64, 8, label, 1, *color);
    }
    let mut idx: Vec<usize> = (0..rows.len())
        .filter(|&i| rows[i].vel_rot_deg.is_some())
        .collect();
    idx.sort_by(|&a, &b| {
        rows[b]
            .vel_rot_deg
            .unwrap_or(0.0)
            .total_cmp(&rows[a].vel_rot_deg.unwrap_or(0.0))
    });
    for &i in idx.iter().take(3) {
        let v = rows[i].vel_rot_deg.unwrap_or(0.0);
        draw_text(
            &mut img,
            x_of(i) - 20,
            y_of(v) - 14,
            &format!("{} {v:.0}", rows[i].frame.split('.').next().unwrap_or("")),
            1,
            Rgb([0, 0, 0]),
        );
    }
    draw_text(
        &mut img,
        pad,
        h as i64 - pad + 8,
        &format!("max {max:.1}  ({} keyframes)", rows.len()),
        1,
        Rgb([0, 0, 0]),
    );
    img
}

pub fn run_diff(a: DiffArgs) -> Result<ExitCode> {
    let s = a.session.open()?;
    let ia = select_frames(&s.capture, Some(&a.request.a))?;
    let ib = select_frames(&s.capture, Some(&a.request.b))?;
    let (Some(&ia), Some(&ib)) = (ia.first(), ib.first()) else {
        bail!("name one frame for --a and one for --b")
    };
    let sm = samples(&s);
    let oriented = sm.iter().all(|x| x.world_from_camera.is_some());
    let d = pair_diff(&sm[ia], &sm[ib], s.scale(), &s.model.model.tree, oriented);
    print_json(&PoseDiffReport {
        from: sm[ia].frame.clone(),
        to: sm[ib].frame.clone(),
        pose_frame: if oriented { "oriented" } else { "camera" }.into(),
        rotation_deg: d.rotation_deg,
        axis_body: d.axis_body,
        translation_canon: d.translation_canon,
        translation_dist_canon: d.translation_dist_canon,
        translation_dist: d.translation_dist,
        joints: d.joints.iter().cloned().collect(),
    })?;
    Ok(ExitCode::SUCCESS)
}
