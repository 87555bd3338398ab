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
    /// Write 3-D point tracks of query pixels: .npz (tracks (F, N, 3) metres, visible (F, N),
    /// queries (N, 2) pixels, part (N)) or .json.
    #[arg(long, requires = "capture")]
    tracks: Option<PathBuf>,
    /// The frame whose pixels are queried (name, stem or index; default: the first).
    #[arg(long)]
    query_frame: Option<String>,
    /// Query every N-th rendered pixel of the query frame.
    #[arg(long, default_value_t = 8)]
    stride: u32,
    /// Query these pixels instead: a JSON file [[u, v], …] (pixel centres at +0.5).
    #[arg(long)]
    queries: Option<PathBuf>,
    /// Write the base pose of every frame as BOP results (CSV: scene_id, im_id, obj_id,
    /// score, R, t in mm, time); the model in BOP units is the canonical model × scale × 1000.
    #[arg(long, requires = "capture")]
    bop: Option<PathBuf>,
    /// BOP scene id.
    #[arg(long, default_value_t = 1)]
    bop_scene_id: u32,
    /// BOP object id.
    #[arg(long, default_value_t = 1)]
    bop_obj_id: u32,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    if a.glb.is_none()
        && a.urdf.is_none()
        && a.animated_glb.is_none()
        && a.posed_meshes.is_none()
        && a.tracks.is_none()
        && a.bop.is_none()
    {
        bail!("nothing to export: give --glb FILE, --urdf DIR, or with --capture and --poses: --animated-glb FILE, --posed-meshes DIR, --tracks FILE, --bop FILE");
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
                    let camera_from_object = g.generalised.pose.with_scale(s.scale());
                    AnimFrame {
                        name: f.name.clone(),
                        time_s: f.time_s.unwrap_or(i as f64 / 30.0),
                        world_from_object: Similarity::from_rigid(&f.world_from_camera)
                            .compose(&camera_from_object),
                        states: g.generalised.states.clone(),
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
        if let Some(p) = &a.tracks {
            write_tracks(&s, &a, p)?;
            written.push(p.clone());
        }
        if let Some(p) = &a.bop {
            let mut csv = String::from("scene_id,im_id,obj_id,score,R,t,time\n");
            for (f, g) in s.capture.frames.iter().zip(&s.poses) {
                let r = g.generalised.pose.rotation.to_rotation_matrix();
                let m = r.matrix();
                let rows: Vec<String> = (0..3)
                    .flat_map(|i| (0..3).map(move |j| (i, j)))
                    .map(|(i, j)| format!("{:.9}", m[(i, j)]))
                    .collect();
                let t: Vec<String> = g
                    .generalised
                    .pose
                    .translation
                    .iter()
                    .map(|v| format!("{:.6}", v * 1000.0))
                    .collect();
                csv.push_str(&format!(
                    "{},{},{},1,{},{},-1\n",
                    a.bop_scene_id,
                    f.number,
                    a.bop_obj_id,
                    rows.join(" "),
                    t.join(" ")
                ));
            }
            agentstar_data::atomic::write_atomic(p, csv.as_bytes())?;
            written.push(p.clone());
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

/// Point tracks of query pixels, as NPZ or JSON by the file's extension.
fn write_tracks(s: &Session, a: &Args, path: &std::path::Path) -> Result<()> {
    let qf = match &a.query_frame {
        Some(q) => *crate::common::select_frames(&s.capture, Some(q))?
            .first()
            .ok_or_else(|| anyhow!("--query-frame {q}: no such frame"))?,
        None => 0,
    };
    let queries: Vec<[f64; 2]> = match &a.queries {
        Some(p) => serde_json::from_str(&agentstar_data::read_text(p)?)
            .map_err(|e| anyhow!("{}: expected [[u, v], …]: {e}", p.display()))?,
        None => vec![],
    };
    let poses: Vec<_> = (0..s.poses.len()).map(|i| s.gen_pose(i)).collect();
    let cams: Vec<_> = s.capture.frames.iter().map(|f| f.camera).collect();
    let t = agentstar_track::tracks::point_tracks(
        &s.model.model,
        s.scale(),
        &poses,
        &cams,
        qf,
        &queries,
        a.stride,
    );
    if !queries.is_empty() && t.queries_px.len() < queries.len() {
        eprintln!(
            "warning: {} of {} query pixels miss the model in {} and were dropped",
            queries.len() - t.queries_px.len(),
            queries.len(),
            s.capture.frames[qf].name
        );
    }
    let names = s.model.model.part_names();
    match path.extension().and_then(|e| e.to_str()) {
        Some("npz") => {
            let (f, n) = (t.points.len(), t.queries_px.len());
            let pts: Vec<f32> = t
                .points
                .iter()
                .flatten()
                .flat_map(|p| p.map(|v| v as f32))
                .collect();
            let vis: Vec<i64> = t.visible.iter().flatten().map(|&v| v as i64).collect();
            let q: Vec<f32> = t
                .queries_px
                .iter()
                .flat_map(|p| p.map(|v| v as f32))
                .collect();
            let part: Vec<i64> = t.parts.iter().map(|&p| p as i64).collect();
            agentstar_data::npz::write_arrays(
                path,
                &[("tracks", &[f, n, 3], &pts), ("queries", &[n, 2], &q)],
                &[
                    ("visible", &[f, n], &vis),
                    ("part", &[n], &part),
                    ("query_frame", &[1], &[qf as i64]),
                ],
            )?;
        }
        Some("json") => agentstar_data::atomic::write_json(
            path,
            &json!({
                "frames": s.capture.frames.iter().map(|f| &f.name).collect::<Vec<_>>(),
                "query_frame": s.capture.frames[qf].name,
                "units": "m, camera frame of each keyframe (OpenCV axes)",
                "queries_px": t.queries_px,
                "parts": t.parts.iter().map(|&p| &names[p]).collect::<Vec<_>>(),
                "tracks": t.points,
                "visible": t.visible,
            }),
        )?,
        _ => bail!(
            "{}: point tracks are written as .npz or .json",
            path.display()
        ),
    }
    Ok(())
}
