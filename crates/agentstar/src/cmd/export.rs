//! `agentstar export`: the canonical rest model as GLB (one node per part) or URDF; with a
//! capture and poses, the tracked motion as an animated GLB and the posed mesh of every frame.

use crate::common::{open_model, print_json, Session};
use agentstar_data::animation::{animated_glb_bytes, read_animated_glb, AnimFrame};
use agentstar_data::export::{write_glb, write_urdf};
use agentstar_geom::pose::Similarity;
use anyhow::{anyhow, bail, Result};
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar export --model scene.rhai --glb object.glb --urdf urdf/\n  agentstar export --model run/scene.rhai --capture cap --poses run/pose.json --animated-glb tracked.glb --posed-meshes posed/"
)]
pub struct Args {
    /// A scene script (.rhai), URDF or mesh file.
    #[arg(long)]
    model: PathBuf,
    /// Write a GLB file of the rest model here.
    #[arg(long)]
    glb: Option<PathBuf>,
    /// Write a URDF (and meshes/) into this directory.
    #[arg(long)]
    urdf: Option<PathBuf>,
    /// Robot name in the URDF.
    #[arg(long, default_value = "object")]
    name: String,
    /// The capture (for the motion exports: its cameras and keyframe times).
    #[arg(long, requires = "poses")]
    capture: Option<PathBuf>,
    /// The pose file (for the motion exports).
    #[arg(long, requires = "capture")]
    poses: Option<PathBuf>,
    /// Write the tracked motion as a glTF animation (world frame of the capture's cameras).
    #[arg(long, requires = "capture")]
    animated_glb: Option<PathBuf>,
    /// Write the posed mesh of every frame (camera frame, metres) as OBJ into this directory.
    #[arg(long, requires = "capture")]
    posed_meshes: Option<PathBuf>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    if a.glb.is_none() && a.urdf.is_none() && a.animated_glb.is_none() && a.posed_meshes.is_none() {
        bail!("nothing to export: give --glb FILE, --urdf DIR, --animated-glb FILE or --posed-meshes DIR");
    }
    let m = open_model(&a.model)?;
    let mut written = Vec::new();
    if let Some(p) = &a.glb {
        write_glb(&m.model, p)?;
        written.push(p.clone());
    }
    if let Some(d) = &a.urdf {
        written.push(write_urdf(&m.model, d, &a.name)?);
    }
    if let (Some(cap), Some(poses)) = (&a.capture, &a.poses) {
        let s = Session::open(cap, &a.model, poses)?;
        if let Some(p) = &a.animated_glb {
            let frames: Vec<AnimFrame> = s
                .capture
                .frames
                .iter()
                .zip(&s.poses)
                .enumerate()
                .map(|(i, (f, g))| {
                    let camera_from_object = g.pose.with_scale(s.scale());
                    AnimFrame {
                        name: f.name.clone(),
                        time_s: f.time_s.unwrap_or(i as f64 / 30.0),
                        world_from_object: Similarity::from_rigid(&f.world_from_camera)
                            .compose(&camera_from_object),
                        states: g.states.clone(),
                    }
                })
                .collect();
            let bytes = animated_glb_bytes(&s.model.model, &frames)
                .map_err(|e| anyhow!("{}: {e}", p.display()))?;
            // Read it back before writing: the validator of the gltf crate and our reader.
            read_animated_glb(&bytes, p)?;
            agentstar_data::atomic::write_atomic(p, &bytes)?;
            written.push(p.clone());
        }
        if let Some(dir) = &a.posed_meshes {
            for (i, f) in s.capture.frames.iter().enumerate() {
                let mut mesh = agentstar_geom::TriMesh::default();
                for inst in &s.posed(i).instances {
                    let mut part = inst.mesh.clone();
                    part.positions = part
                        .positions
                        .iter()
                        .map(|p| agentstar_geom::Point3::from(inst.camera_from_mesh.apply(p)))
                        .collect();
                    mesh.append(&part);
                }
                let path = dir.join(format!("{}.obj", f.stem));
                agentstar_data::atomic::write_atomic(
                    &path,
                    agentstar_data::meshio::obj_text(&mesh, &f.stem).as_bytes(),
                )?;
            }
            written.push(dir.clone());
        }
    }
    if a.json {
        print_json(&json!({"written": written, "parts": m.model.part_names()}))?;
    } else {
        for w in &written {
            println!("wrote {}", w.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
