//! `agentstar turntable`: 8 views on a sphere around the object, once per distinct joint
//! state (or the rest state), as images and one sheet per state.

use crate::common::{open_capture, open_model, out_dir, print_json};
use agentstar_data::images::save_png_rgb;
use agentstar_data::posefile::PoseFile;
use agentstar_geom::{ObjectModel, UnitQuaternion};
use agentstar_render::views::{
    contact_sheet, flatten, shade, sphere8, turntable_camera, turntable_pose, ShadeOptions,
    TurntableView,
};
use agentstar_render::{render_full, PosedModel};
use anyhow::{anyhow, Result};
use image::{Rgb, RgbImage};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar turntable --model run/scene.rhai --capture cap --poses run/pose.json --out turntables"
)]
pub struct Args {
    /// The model: scene script (.rhai), URDF or mesh.
    #[arg(long)]
    model: PathBuf,
    /// A pose file: one turntable per distinct joint state, oriented like the reference frame.
    #[arg(long, requires = "capture")]
    poses: Option<PathBuf>,
    /// The capture the poses belong to.
    #[arg(long)]
    capture: Option<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Image size in pixels (square).
    #[arg(long, default_value_t = 320)]
    size: u32,
    /// Horizontal field of view in degrees.
    #[arg(long, default_value_t = 45.0)]
    fov: f64,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
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
    let colors: Vec<[f32; 3]> = model.parts.iter().map(|p| p.color).collect();
    sphere8()
        .into_iter()
        .map(|v| {
            let pose = turntable_pose(model, states, reference_rotation, &v, fov);
            let posed = PosedModel::new(model, states, &pose);
            let img = flatten(
                &shade(
                    &render_full(&camera, &posed.instances),
                    &colors,
                    ShadeOptions::default(),
                ),
                Rgb([30, 30, 36]),
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

pub fn run(a: Args) -> Result<ExitCode> {
    let m = open_model(&a.model)?;
    let model = &m.model;
    // Distinct joint states (first frame that shows each), oriented by the reference pose.
    let mut states: Vec<(String, Vec<f64>)> = Vec::new();
    let mut rotation = UnitQuaternion::from_axis_angle(
        &agentstar_geom::Vector3::x_axis(),
        std::f64::consts::FRAC_PI_2,
    );
    if let (Some(p), Some(c)) = (&a.poses, &a.capture) {
        let capture = open_capture(c)?;
        let pf = PoseFile::read(p)?;
        let resolved = pf
            .resolve(&capture, &model.tree)
            .map_err(|e| anyhow!("{}: {e}", p.display()))?;
        rotation = resolved[capture.ref_index].pose.rotation;
        for (f, r) in capture.frames.iter().zip(&resolved) {
            if !states
                .iter()
                .any(|(_, s)| s.iter().zip(&r.states).all(|(a, b)| (a - b).abs() < 1e-6))
            {
                states.push((f.stem.clone(), r.states.clone()));
            }
        }
    } else {
        states.push(("rest".into(), model.tree.rest_states()));
    }
    let dir = out_dir(&a.out)?;
    let mut written = Vec::new();
    for (label, s) in &states {
        let tiles = turntable_tiles(model, s, &rotation, a.size, a.fov);
        for (_, img, v) in &tiles {
            let p = dir.join(format!(
                "turntable_{label}_az{:03}_el{:+03}.png",
                v.azimuth_deg as i64, v.elevation_deg as i64
            ));
            save_png_rgb(img, &p)?;
            written.push(p);
        }
        let joint_text: Vec<String> = model
            .tree
            .states_to_interface(s)
            .iter()
            .map(|(k, v)| format!("{k}={v:.1}"))
            .collect();
        let title = format!("state {label} {}", joint_text.join(" "));
        let sheet = dir.join(format!("turntable_sheet_{label}.png"));
        let t: Vec<(String, RgbImage)> = tiles.into_iter().map(|(n, i, _)| (n, i)).collect();
        save_png_rgb(&contact_sheet(&t, 4, &title), &sheet)?;
        written.push(sheet);
    }
    if a.json {
        print_json(
            &json!({"states": states.iter().map(|(l, _)| l).collect::<Vec<_>>(), "files": written}),
        )?;
    } else {
        println!(
            "turntables for {} state(s) in {}",
            states.len(),
            dir.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
