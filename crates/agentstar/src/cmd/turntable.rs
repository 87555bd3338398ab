//! `agentstar turntable`: 8 views on a sphere around the upright object (its canonical +Z
//! up) on a light background, for a few representative joint states (each joint's
//! minimum, median and maximum over the keyframes) or the ones asked for, as one sheet per
//! state within the image limits.

use crate::common::{joint_at_limit, open_capture, open_model, out_dir, print_json};
use agentstar_data::images::save_png_rgb;
use agentstar_data::posefile::PoseFile;
use agentstar_geom::{KinematicTree, ObjectModel, UnitQuaternion};
use agentstar_render::sheet::sheet_pages;
use agentstar_render::views::{
    flatten, shade_model, sphere8, turntable_camera, turntable_pose, ShadeOptions, TurntableView,
    TURNTABLE_BACKGROUND,
};
use agentstar_render::{render_full, PosedModel};
use agentstar_reports::view::{TurntableReport, TurntableState};
use anyhow::{anyhow, bail, Result};
use image::RgbImage;
use std::path::PathBuf;
use std::process::ExitCode;

/// How the object is turned before the views are placed around it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Orient {
    /// The model's canonical +Z up, seen from its −Y side at azimuth 0.
    Upright,
    /// As the reference keyframe's camera sees it (needs --poses).
    Reference,
}

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar turntable --model run/scene.rhai --capture cap --poses run/pose.json --out turntables\n  agentstar turntable --model run/scene.rhai --capture cap --poses run/pose.json --out tt --states 000000,000040"
)]
pub struct Args {
    /// The model: scene script (.rhai), URDF or mesh.
    #[arg(long)]
    model: PathBuf,
    /// A pose file: the joint states to show come from its keyframes.
    #[arg(long, requires = "capture")]
    poses: Option<PathBuf>,
    /// The capture the poses belong to.
    #[arg(long)]
    capture: Option<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// The joint states to show (the `turntable` tool's arguments; `representative` by
    /// default; states given outright need no poses: check a shape before tracking).
    #[command(flatten)]
    request: agentstar_requests::TurntableArgs,
    /// Orientation of the object: upright (canonical +Z up) or as in the reference keyframe.
    #[arg(long, value_enum, default_value_t = Orient::Upright)]
    orient: Orient,
    /// Also write each of the 8 views as its own image.
    #[arg(long)]
    each: bool,
    /// Image size of one view in pixels (square).
    #[arg(long, default_value_t = 320)]
    size: u32,
    /// Horizontal field of view in degrees.
    #[arg(long, default_value_t = 45.0)]
    fov: f64,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// The upright orientation: canonical +Z to the camera's up (−Y).
pub fn upright() -> UnitQuaternion {
    UnitQuaternion::from_axis_angle(
        &agentstar_geom::Vector3::x_axis(),
        std::f64::consts::FRAC_PI_2,
    )
}

/// Renders the sphere8 views of `model` at `states`; returns (label, image) tiles.
pub fn turntable_tiles(
    model: &ObjectModel,
    states: &[f64],
    reference_rotation: &UnitQuaternion,
    size: u32,
    fov: f64,
) -> Vec<(String, RgbImage, TurntableView)> {
    let camera = turntable_camera(size, fov);
    sphere8()
        .into_iter()
        .map(|v| {
            let pose = turntable_pose(model, states, reference_rotation, &v, fov);
            let posed = PosedModel::new(model, states, &pose);
            let buffers = render_full(&camera, &posed.instances);
            let img = flatten(
                &shade_model(
                    model,
                    &posed.instances,
                    &camera,
                    &buffers,
                    ShadeOptions::default(),
                ),
                TURNTABLE_BACKGROUND,
            );
            (
                format!(
                    "az{:03} el{:+03}",
                    v.azimuth_deg as i64, v.elevation_deg as i64
                ),
                img,
                v,
            )
        })
        .collect()
}

/// States given outright: `hinge:90|hinge:0;drawer:0.2`, one sheet per `|`-separated set,
/// interface units, the joints not named at rest; each checked against the joints' names
/// and limits. `(label, source, internal states)`.
fn explicit_states(spec: &str, tree: &KinematicTree) -> Result<Vec<(String, String, Vec<f64>)>> {
    let mut out = Vec::new();
    for set in spec.split('|').map(str::trim).filter(|s| !s.is_empty()) {
        let mut named = tree.states_to_interface(&tree.rest_states());
        for term in set.split(';').map(str::trim).filter(|t| !t.is_empty()) {
            let (name, value) = term
                .split_once(':')
                .ok_or_else(|| anyhow!("`{term}`: expected `joint:value`, e.g. `hinge:90`"))?;
            let value: f64 = value
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| anyhow!("`{term}`: `{}` is not a number", value.trim()))?;
            named.insert(name.trim().to_string(), value);
        }
        let states = tree
            .states_from_interface(&named)
            .map_err(|e| anyhow!("--states `{set}`: {e}"))?;
        let label: String = set
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        out.push((label, set.to_string(), states));
    }
    if out.is_empty() {
        bail!("--states `{spec}`: no joint states; e.g. `hinge:90|hinge:0`");
    }
    Ok(out)
}

/// Each joint's minimum, median and maximum over `frames` (internal units), as up to three
/// distinct states labelled `min`, `median`, `max`.
fn representative(frames: &[Vec<f64>], n_joints: usize) -> Vec<(String, Vec<f64>)> {
    let pick = |q: f64| -> Vec<f64> {
        (0..n_joints)
            .map(|j| {
                let mut v: Vec<f64> = frames.iter().filter_map(|s| s.get(j).copied()).collect();
                v.sort_by(f64::total_cmp);
                if v.is_empty() {
                    0.0
                } else {
                    v[((v.len() - 1) as f64 * q).round() as usize]
                }
            })
            .collect()
    };
    let mut out: Vec<(String, Vec<f64>)> = Vec::new();
    for (label, q) in [("min", 0.0), ("median", 0.5), ("max", 1.0)] {
        let s = pick(q);
        if !out
            .iter()
            .any(|(_, o)| o.iter().zip(&s).all(|(a, b)| (a - b).abs() < 1e-6))
        {
            out.push((label.to_string(), s));
        }
    }
    out
}

pub fn run(a: Args) -> Result<ExitCode> {
    if !(16..=1024).contains(&a.size) {
        bail!("--size {} must lie in [16, 1024]", a.size);
    }
    if !(a.fov.is_finite() && a.fov > 1.0 && a.fov < 170.0) {
        bail!("--fov {} must lie in (1, 170) degrees", a.fov);
    }
    let m = open_model(&a.model)?;
    let model = &m.model;
    let tree = &model.tree;
    let mut rotation = upright();
    let mut states: Vec<(String, String, Vec<f64>)> = Vec::new();
    let warnings = tree.limit_warnings();
    let mut at_limit = Vec::new();
    let explicit = a.request.states().contains(':');
    if explicit {
        states = explicit_states(a.request.states(), tree)?;
    }
    match (&a.poses, &a.capture) {
        _ if explicit && a.orient == Orient::Upright => {}
        (Some(p), Some(c)) => {
            let capture = open_capture(c)?;
            let pf = PoseFile::read(p)?;
            let resolved = pf
                .resolve(&capture, tree)
                .map_err(|e| anyhow!("{}: {e}", p.display()))?;
            if a.orient == Orient::Reference {
                rotation = resolved[capture.ref_index].generalised.pose.rotation;
            }
            let all: Vec<Vec<f64>> = resolved
                .iter()
                .map(|r| r.generalised.states.clone())
                .collect();
            let names: Vec<String> = capture.frames.iter().map(|f| f.name.clone()).collect();
            at_limit.extend(tree.at_limit(&all, &names).into_iter().map(joint_at_limit));
            match a.request.states() {
                _ if explicit => {}
                "representative" | "" => {
                    let r = representative(&all, tree.joints().len());
                    if r.len() == 1 {
                        // Every keyframe has the same joint states.
                        let s = r.into_iter().next().map(|x| x.1).unwrap_or_default();
                        states.push(("keyframes".into(), "every keyframe".into(), s));
                    } else {
                        for (label, s) in r {
                            states.push((label.clone(), label, s));
                        }
                    }
                }
                "all" => {
                    for (f, s) in capture.frames.iter().zip(&all) {
                        if !states
                            .iter()
                            .any(|(_, _, o)| o.iter().zip(s).all(|(a, b)| (a - b).abs() < 1e-6))
                        {
                            states.push((f.stem.clone(), f.name.clone(), s.clone()));
                        }
                    }
                }
                spec => {
                    for i in capture.select(Some(spec))? {
                        let f = &capture.frames[i];
                        states.push((f.stem.clone(), f.name.clone(), all[i].clone()));
                    }
                }
            }
        }
        _ => {
            if a.orient == Orient::Reference {
                bail!("--orient reference needs --capture and --poses");
            }
            if a.request.states() != "representative" {
                bail!(
                    "--states {} needs --capture and --poses",
                    a.request.states()
                );
            }
            states.push(("rest".into(), "rest".into(), tree.rest_states()));
        }
    }
    if tree.joints().iter().all(|j| !j.kind.has_state()) {
        // A rigid model has one state.
        states.truncate(1);
    }
    let dir = out_dir(&a.out)?;
    let mut files = Vec::new();
    let mut all_sheets = Vec::new();
    let mut shown = Vec::new();
    for (label, source, s) in &states {
        let tiles = turntable_tiles(model, s, &rotation, a.size, a.fov);
        if a.each {
            for (_, img, v) in &tiles {
                let p = dir.join(format!(
                    "turntable_{label}_az{:03}_el{:+03}.png",
                    v.azimuth_deg as i64, v.elevation_deg as i64
                ));
                save_png_rgb(img, &p)?;
                files.push(p);
            }
        }
        let joints = tree.states_to_interface(s);
        let joint_text: Vec<String> = joints.iter().map(|(k, v)| format!("{k}={v:.1}")).collect();
        let title = format!("turntable {label} {}", joint_text.join(" "));
        let t: Vec<(String, RgbImage)> = tiles.into_iter().map(|(n, i, _)| (n, i)).collect();
        let mut sheets = Vec::new();
        for (k, page) in sheet_pages(&t, 4, title.trim()).iter().enumerate() {
            let p = if k == 0 {
                dir.join(format!("turntable_sheet_{label}.png"))
            } else {
                dir.join(format!("turntable_sheet_{label}_p{}.png", k + 1))
            };
            save_png_rgb(page, &p)?;
            sheets.push(p);
        }
        files.extend(sheets.iter().cloned());
        all_sheets.extend(sheets.iter().cloned());
        shown.push(TurntableState {
            label: label.clone(),
            source: source.clone(),
            joints,
            sheets,
        });
    }
    for w in warnings
        .iter()
        .cloned()
        .chain(at_limit.iter().map(|w| w.warning()))
    {
        eprintln!("warning: {w}");
    }
    if a.json {
        print_json(&TurntableReport {
            states: shown,
            sheets: all_sheets,
            files,
            warnings,
            at_limit,
        })?;
    } else {
        println!(
            "turntables for {} joint state(s) ({}) in {}: {} sheet(s), {} file(s)",
            shown.len(),
            shown
                .iter()
                .map(|s| s.label.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            dir.display(),
            all_sheets.len(),
            files.len()
        );
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn representative_states_are_each_joints_min_median_and_max() {
        let frames: Vec<Vec<f64>> = [[0.3, 5.0], [0.1, 2.0], [0.9, 1.0], [0.5, 4.0], [0.2, 3.0]]
            .iter()
            .map(|r| r.to_vec())
            .collect();
        let r = representative(&frames, 2);
        let labels: Vec<&str> = r.iter().map(|(l, _)| l.as_str()).collect();
        assert_eq!(labels, ["min", "median", "max"]);
        assert_eq!(r[0].1, [0.1, 1.0]);
        assert_eq!(r[1].1, [0.3, 3.0]);
        assert_eq!(r[2].1, [0.9, 5.0]);
        // A joint that never moves gives one state.
        let still = vec![vec![0.4]; 6];
        assert_eq!(representative(&still, 1).len(), 1);
    }
}
