//! `agentstar capture …`: captures from other sources.

use crate::common::print_json;
use agentstar_data::bop::{import_bop, BopImport};
use anyhow::Result;
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Subcommand)]
pub enum CaptureCommand {
    /// A capture from a video (frames extracted with ffmpeg) or a folder of frames, with masks
    /// from a segmenter's output folder and cameras from COLMAP, nerfstudio or a static camera.
    #[command(
        after_help = "Examples:\n  agentstar capture from-video clip.mp4 --masks sam2_masks/ --fov 65 --every 10 --out cap\n  agentstar capture from-video frames/ --masks masks/ --hands hand_masks/ --colmap sparse/0 --out cap"
    )]
    FromVideo(FromVideoArgs),
    /// One object of a BOP scene (also HOT3D clips converted to BOP) as capture/v1 with gt.json.
    #[command(
        after_help = "Example:\n  agentstar capture from-bop ycbv/test/000048 --models ycbv/models --obj-id 1 --out cap48 --every 5"
    )]
    FromBop(FromBopArgs),
}

#[derive(clap::Args)]
pub struct FromVideoArgs {
    /// A video file (needs the ffmpeg command) or a folder of frames.
    input: PathBuf,
    /// The folder of object masks (matched by file stem, else by order).
    #[arg(long)]
    masks: PathBuf,
    /// A folder of hand (occluder) masks, matched the same way.
    #[arg(long)]
    hands: Option<PathBuf>,
    /// Keep every N-th frame.
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// At most this many frames.
    #[arg(long)]
    max_frames: Option<usize>,
    /// Frames per second of the input (for time_s).
    #[arg(long)]
    fps: Option<f64>,
    /// A COLMAP model directory (cameras.txt/images.txt or .bin).
    #[arg(long, group = "cameras")]
    colmap: Option<PathBuf>,
    /// A nerfstudio transforms.json.
    #[arg(long, group = "cameras")]
    nerfstudio: Option<PathBuf>,
    /// A static camera with this horizontal field of view in degrees.
    #[arg(long, group = "cameras")]
    fov: Option<f64>,
    /// A static camera with these intrinsics: fx,fy,cx,cy (pixels of the frames).
    #[arg(long, group = "cameras", value_delimiter = ',', num_args = 4)]
    intrinsics: Option<Vec<f64>>,
    /// Where to write the capture (a new directory).
    #[arg(long)]
    out: PathBuf,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct FromBopArgs {
    /// The BOP scene directory (scene_gt.json, scene_camera.json, rgb/, mask_visib/).
    scene: PathBuf,
    /// The dataset's models directory (obj_XXXXXX.ply in millimetres, models_info.json).
    #[arg(long)]
    models: PathBuf,
    /// The object to import.
    #[arg(long)]
    obj_id: u32,
    /// Where to write the capture (a new directory).
    #[arg(long)]
    out: PathBuf,
    /// Keep every N-th image holding the object.
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// Import depth/ too (16-bit PNGs with scene_camera depth_scale).
    #[arg(long)]
    depth: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(c: CaptureCommand) -> Result<ExitCode> {
    match c {
        CaptureCommand::FromVideo(a) => {
            use agentstar_data::video::{import_video, CameraSource, VideoImport};
            let cameras = match (&a.colmap, &a.nerfstudio, a.fov, &a.intrinsics) {
                (Some(d), ..) => CameraSource::Colmap(d.clone()),
                (_, Some(p), ..) => CameraSource::Nerfstudio(p.clone()),
                (_, _, Some(f), _) => CameraSource::Fov(f),
                (_, _, _, Some(k)) => CameraSource::Static([k[0], k[1], k[2], k[3]]),
                _ => anyhow::bail!(
                    "give the cameras: --colmap DIR, --nerfstudio transforms.json, --fov DEG or --intrinsics fx,fy,cx,cy"
                ),
            };
            if let CameraSource::Fov(f) = cameras {
                if !(f.is_finite() && f > 1.0 && f < 179.0) {
                    anyhow::bail!(
                        "--fov {f}: a horizontal field of view in degrees, between 1 and 179"
                    );
                }
            }
            let n = import_video(
                &VideoImport {
                    input: a.input.clone(),
                    masks: a.masks.clone(),
                    hands: a.hands.clone(),
                    every: a.every,
                    max_frames: a.max_frames,
                    cameras,
                    fps: a.fps,
                },
                &a.out,
            )?;
            if a.json {
                print_json(&json!({"capture": a.out, "frames": n}))?;
            } else {
                println!(
                    "wrote {} ({n} frames from {})",
                    a.out.display(),
                    a.input.display()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        CaptureCommand::FromBop(a) => {
            let n = import_bop(
                &BopImport {
                    scene: a.scene.clone(),
                    models: a.models.clone(),
                    obj_id: a.obj_id,
                    every: a.every,
                    depth: a.depth,
                },
                &a.out,
            )?;
            if a.json {
                print_json(&json!({"capture": a.out, "frames": n, "gt": a.out.join("gt.json")}))?;
            } else {
                println!(
                    "wrote {} ({n} frames of object {} from {}, with gt.json)",
                    a.out.display(),
                    a.obj_id,
                    a.scene.display()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}
