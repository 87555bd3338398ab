//! `agentstar capture …`: captures from other sources.

use crate::common::print_json;
use agentstar_import::bop::{import_bop, BopImport};
use anyhow::{Context, Result};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Subcommand)]
pub enum CaptureCommand {
    /// A capture from a video (frames extracted with ffmpeg) or a folder of frames, with masks
    /// from a segmenter's output folder and cameras by structure from motion (COLMAP), from a
    /// COLMAP or nerfstudio model, or a static camera.
    #[command(
        after_help = "Frames keep their numbers: a video's frames are numbered by their index in the video, and a\nfolder whose file names are integers (000000.jpg, 000010.jpg, ...) keeps them as the frames'\nnames, frame_index and time_s = number / fps. Other names are numbered 0, 1, 2, ... in natural\norder (a note says so). Masks and hand masks are matched by file stem only (000010.png or\n000010_mask.png for frame 000010.jpg).\n\nWith --cameras sfm, COLMAP reconstructs from at most --sfm-max-frames frames strided over the\nclip (the object and hand masks excluded from its features) and registers the other keyframes\nagainst that model, all under --sfm-time-limit-s; --fov/--intrinsics then fix the intrinsics (else the\nvideo's metadata or SfM gives them). The cameras are in the first keyframe's camera frame, one unit\nthe median background depth unless --background-depth-m is given (docs/sfm.md); COLMAP's logs and\nmodel are kept in CAPTURE/sfm/.\n\nExamples:\n  agentstar capture from-video clip.mp4 --masks sam2_masks/ --hands hand_masks/ --every 10 --cameras sfm --out cap\n  agentstar capture from-video clip.mp4 --masks sam2_masks/ --fov 65 --every 10 --out cap\n  agentstar capture from-video frames/ --masks masks/ --hands hand_masks/ --colmap sparse/0 --out cap"
    )]
    FromVideo(FromVideoArgs),
    /// One object of a BOP scene (also HOT3D clips converted to BOP) as capture/v1 with gt.json.
    #[command(
        after_help = "Example:\n  agentstar capture from-bop ycbv/test/000048 --models ycbv/models --obj-id 1 --out cap48 --every 5"
    )]
    FromBop(FromBopArgs),
    /// One object of a HOT3D sequence in its CSV layout (dynamic_objects.csv,
    /// headset_trajectory.csv, object GLBs) with frames exported from the recording.
    #[command(
        after_help = "Frames are undistorted (pinhole) images named by their timestamp in nanoseconds; masks are\nrendered from the ground truth when --masks is not given.\n\nExample:\n  agentstar capture from-hot3d P0001_10a27bf7 --models object_models --object-uid 194930206998778 \\\n    --frames rgb_undistorted/ --intrinsics 610,610,703.5,703.5 --out cap_mug"
    )]
    FromHot3d(FromHot3dArgs),
    /// An ARCTIC sequence from one allocentric camera (object arrays, two-part templates,
    /// misc.json cameras) with gt.json.
    #[command(
        after_help = "Example:\n  agentstar capture from-arctic arctic_data/data --subject s01 --sequence box_grab_01 --camera 1 --every 10 --out cap_box"
    )]
    FromArctic(FromArcticArgs),
}

#[derive(clap::Args)]
pub struct FromHot3dArgs {
    /// The sequence directory (dynamic_objects.csv, headset_trajectory.csv).
    sequence: PathBuf,
    /// The object library directory holding {object_uid}.glb.
    #[arg(long)]
    models: PathBuf,
    /// The object to import.
    #[arg(long)]
    object_uid: String,
    /// Undistorted frames named {timestamp_ns}.png or .jpg.
    #[arg(long)]
    frames: PathBuf,
    /// Pinhole intrinsics of the frames: fx,fy,cx,cy (pixels).
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_negative_numbers = true
    )]
    intrinsics: Vec<f64>,
    /// T_device_camera as qw,qx,qy,qz,tx,ty,tz (metres); identity when not given.
    // No `num_args = 7`: clap counts the arguments before splitting them at commas, so
    // `qw,qx,...` was refused as one value; the count is checked when the pose is built.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    device_from_camera: Option<Vec<f64>>,
    /// Object masks matched by stem; rendered from the ground truth when absent.
    #[arg(long)]
    masks: Option<PathBuf>,
    /// Hand masks matched by stem.
    #[arg(long)]
    hands: Option<PathBuf>,
    /// Largest time difference between a frame and a pose, in milliseconds.
    #[arg(long, default_value_t = 5.0)]
    max_dt_ms: f64,
    /// Keep every N-th frame (the keyframes).
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// Keep the frames between keyframes too, as in-between frames that `track` follows
    /// (docs/formats.md): every frame, or every N-th after each keyframe with `--between N`
    /// (N under --every). Their masks are read or rendered as the keyframes' are; gt.json
    /// holds the keyframes only.
    #[arg(long, num_args = 0..=1, default_missing_value = "1", value_name = "N")]
    between: Option<usize>,
    /// Where to write the capture (a new directory).
    #[arg(long)]
    out: PathBuf,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct FromArcticArgs {
    /// The ARCTIC data root (meta/, raw_seqs/, images/).
    root: PathBuf,
    /// The subject, e.g. s01.
    #[arg(long)]
    subject: String,
    /// The sequence, e.g. box_grab_01 (the object is the part before the first `_`).
    #[arg(long)]
    sequence: String,
    /// Allocentric camera 1-8.
    #[arg(long, default_value_t = 1)]
    camera: u32,
    /// The image folder (default: images/SUBJECT/SEQUENCE/CAMERA under the root).
    #[arg(long)]
    images: Option<PathBuf>,
    /// Object masks matched by stem; rendered from the ground truth when absent.
    #[arg(long)]
    masks: Option<PathBuf>,
    /// Hand masks matched by stem.
    #[arg(long)]
    hands: Option<PathBuf>,
    /// Image number minus object-array row (default: ioi_offset of misc.json).
    #[arg(long, allow_negative_numbers = true)]
    offset: Option<i64>,
    /// Keep every N-th image (the keyframes).
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// At most this many keyframes.
    #[arg(long)]
    max_frames: Option<usize>,
    /// Keep the images between keyframes too, as in-between frames that `track` follows
    /// (docs/formats.md): every image, or every N-th after each keyframe with `--between N`
    /// (N under --every). Their masks are read or rendered as the keyframes' are; gt.json
    /// holds the keyframes only.
    #[arg(long, num_args = 0..=1, default_missing_value = "1", value_name = "N")]
    between: Option<usize>,

    /// Where to write the capture (a new directory).
    #[arg(long)]
    out: PathBuf,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct FromVideoArgs {
    /// A video file (needs the ffmpeg command) or a folder of frames.
    input: PathBuf,
    /// The folder of object masks, matched to frames by file stem: frame 000120.jpg takes
    /// 000120.png or 000120_mask.png (an integer stem compared as a number, so 120.png too);
    /// never by order. A frame without its own mask is an error.
    #[arg(long)]
    masks: PathBuf,
    /// A folder of hand (occluder) masks, matched the same way; a frame without one shows no
    /// hands (a note says which).
    #[arg(long)]
    hands: Option<PathBuf>,
    /// Keep every N-th frame present (N at least 1): in a folder that skips frame numbers,
    /// every N-th file, not every N-th frame number.
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// At most this many frames (at least 1).
    #[arg(long)]
    max_frames: Option<usize>,
    /// Keep the frames between keyframes too, as in-between frames that `track` follows
    /// (docs/formats.md): every frame, or every N-th after each keyframe with `--between N`.
    /// Every kept frame needs its object mask.
    #[arg(long, num_args = 0..=1, default_missing_value = "1", value_name = "N")]
    between: Option<usize>,
    /// Frames per second of the input, from 0.001 to 1000 (default 30): time_s = frame
    /// number / fps.
    #[arg(long, allow_negative_numbers = true)]
    fps: Option<f64>,
    /// A COLMAP model directory (cameras.txt/images.txt or .bin).
    #[arg(long, group = "camera_source")]
    colmap: Option<PathBuf>,
    /// A nerfstudio transforms.json.
    #[arg(long, group = "camera_source")]
    nerfstudio: Option<PathBuf>,
    /// A static camera with this horizontal field of view in degrees.
    #[arg(long, group = "camera_source")]
    fov: Option<f64>,
    /// A static camera with these intrinsics: fx,fy,cx,cy (pixels of the frames).
    #[arg(
        long,
        group = "camera_source",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    intrinsics: Option<Vec<f64>>,
    /// How the cameras are found: `sfm` (structure from motion with COLMAP; --fov or
    /// --intrinsics then give the intrinsics) or `static` (the default with --fov/--intrinsics).
    #[arg(long, value_enum, conflicts_with_all = ["colmap", "nerfstudio"])]
    cameras: Option<CameraMode>,
    /// With --cameras sfm: the distance in metres from the first keyframe's camera to the
    /// background behind the object (the median depth), so that translations are in metres.
    #[arg(long, requires = "cameras")]
    background_depth_m: Option<f64>,
    /// With --cameras sfm: SfM reconstructs from at most this many frames, evenly strided over
    /// the clip, and registers every other frame that needs a camera against that model.
    #[arg(long, default_value_t = agentstar_sfm::DEFAULT_RECONSTRUCT_MAX, requires = "cameras")]
    sfm_max_frames: usize,
    /// With --cameras sfm: the most SIFT features per frame (COLMAP's
    /// SiftExtraction.max_num_features).
    #[arg(long, default_value_t = agentstar_sfm::DEFAULT_MAX_FEATURES, requires = "cameras")]
    sfm_max_features: usize,
    /// With --cameras sfm: each reconstructed frame is matched with this many next ones.
    #[arg(long, default_value_t = agentstar_sfm::DEFAULT_OVERLAP, requires = "cameras")]
    sfm_overlap: usize,
    /// With --cameras sfm: SIFT on the GPU where COLMAP was built with CUDA and an NVIDIA
    /// device is present (`auto`), or never (`off`).
    #[arg(long, value_enum, default_value = "auto", requires = "cameras")]
    sfm_gpu: SfmGpu,
    /// With --cameras sfm: the time limit of the whole SfM run (every stage together), in
    /// seconds.
    #[arg(long, default_value_t = agentstar_sfm::DEFAULT_TIME_LIMIT.as_secs(), requires = "cameras")]
    sfm_time_limit_s: u64,
    /// With --cameras sfm: the threads COLMAP may use (default: all), to leave cores to other
    /// work. Whatever the threads, COLMAP 3.8's cameras differ by about a tenth of a degree
    /// from run to run (its RANSAC draws are not seeded).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..), requires = "cameras")]
    sfm_threads: Option<u16>,
    /// Where to write the capture (a new directory).
    #[arg(long)]
    out: PathBuf,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SfmGpu {
    /// Where COLMAP has CUDA and the machine an NVIDIA device.
    Auto,
    /// On the CPU only.
    Off,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CameraMode {
    /// Structure from motion on the background (COLMAP).
    Sfm,
    /// One static camera (--fov or --intrinsics).
    Static,
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
    /// Keep every N-th image holding the object (the keyframes).
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// Keep the images between keyframes too, as in-between frames that `track` follows
    /// (docs/formats.md): every image holding the object, or every N-th after each keyframe with `--between N`
    /// (N under --every). Their masks are read or rendered as the keyframes' are; gt.json
    /// holds the keyframes only.
    #[arg(long, num_args = 0..=1, default_missing_value = "1", value_name = "N")]
    between: Option<usize>,

    /// Import depth/ too (16-bit PNGs with scene_camera depth_scale).
    #[arg(long)]
    depth: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Four finite numbers fx,fy,cx,cy.
fn four(v: &[f64], flag: &str) -> Result<[f64; 4]> {
    match v {
        [fx, fy, cx, cy] if v.iter().all(|x| x.is_finite()) => Ok([*fx, *fy, *cx, *cy]),
        _ => anyhow::bail!("{flag} takes 4 finite numbers fx,fy,cx,cy (pixels); got {v:?}"),
    }
}

/// The intrinsics that --fov or --intrinsics give, for frames of `size`.
fn given_intrinsics(a: &FromVideoArgs, size: (u32, u32)) -> Result<Option<[f64; 4]>> {
    if let Some(f) = a.fov {
        check_fov(f)?;
        let c = agentstar_geom::PinholeCamera::with_fov(f, size.0, size.1);
        return Ok(Some([c.fx, c.fy, c.cx, c.cy]));
    }
    a.intrinsics
        .as_ref()
        .map(|k| four(k, "--intrinsics"))
        .transpose()
}

fn check_fov(f: f64) -> Result<()> {
    if !(f.is_finite() && f > 1.0 && f < 179.0) {
        anyhow::bail!("--fov {f}: a horizontal field of view in degrees, between 1 and 179");
    }
    Ok(())
}

/// Refuses --fps, --every and --max-frames values that would write nonsense, before anything
/// is read or written.
fn check_video_options(a: &FromVideoArgs) -> Result<()> {
    use agentstar_import::video::{MAX_FPS, MIN_FPS};
    if let Some(f) = a.fps {
        if !(f.is_finite() && (MIN_FPS..=MAX_FPS).contains(&f)) {
            // Display writes 1e-300 as 301 digits; scientific notation says it shorter.
            let shown = match f.to_string() {
                t if t.len() > 16 => format!("{f:e}"),
                t => t,
            };
            anyhow::bail!(
                "--fps {shown}: frames per second of the input, from {MIN_FPS} to {MAX_FPS}"
            );
        }
    }
    if a.every == 0 {
        anyhow::bail!("--every 0: keep every N-th frame, N at least 1");
    }
    if a.max_frames == Some(0) {
        anyhow::bail!("--max-frames 0: a capture needs at least one frame");
    }
    check_between(a.every, a.between)
}

/// Refuses an --every of 0 and a --between stride that keeps nothing, before anything is
/// read or written.
fn check_between(every: usize, between: Option<usize>) -> Result<()> {
    if every == 0 {
        anyhow::bail!("--every 0: keep every N-th frame, N at least 1");
    }
    match agentstar_import::between_stride_problem(every, between) {
        Some(problem) => anyhow::bail!(problem),
        None => Ok(()),
    }
}

/// `N frames` or `N keyframes and M in-between frames`.
fn frames_written(keyframes: usize, between: usize) -> String {
    if between == 0 {
        format!("{keyframes} frames")
    } else {
        format!("{keyframes} keyframes and {between} in-between frames")
    }
}

fn from_video(a: FromVideoArgs) -> Result<ExitCode> {
    use agentstar_import::video::{import_video_frames, open_frames, CameraSource, VideoImport};
    check_video_options(&a)?;
    let sfm = a.cameras == Some(CameraMode::Sfm);
    let frames = open_frames(&a.input)?;
    let (cameras, keep, summary) = if sfm {
        let (source, keep, summary) = sfm_cameras(&a, &frames)?;
        (source, Some(keep), Some(summary))
    } else {
        let cameras = match (&a.colmap, &a.nerfstudio, a.fov, &a.intrinsics) {
            (Some(d), ..) => CameraSource::Colmap(d.clone()),
            (_, Some(p), ..) => CameraSource::Nerfstudio(p.clone()),
            (_, _, Some(f), _) => {
                check_fov(f)?;
                CameraSource::Fov(f)
            }
            (_, _, _, Some(k)) => CameraSource::Static(four(k, "--intrinsics")?),
            _ => anyhow::bail!(
                "give the cameras: --cameras sfm (structure from motion with COLMAP), --colmap DIR, --nerfstudio transforms.json, --fov DEG or --intrinsics fx,fy,cx,cy"
            ),
        };
        (cameras, None, None)
    };
    let done = import_video_frames(
        &VideoImport {
            input: a.input.clone(),
            masks: a.masks.clone(),
            hands: a.hands.clone(),
            every: a.every,
            max_frames: a.max_frames,
            cameras,
            fps: a.fps,
            between: a.between,
        },
        &frames,
        &a.out,
        keep.as_ref().map(|k| k.join("keep")).as_deref(),
    )?;
    for note in &done.notes {
        eprintln!("note: {note}");
    }
    let n = done.frames;
    if let Some(work) = &keep {
        // The capture holds what was worth keeping; the work folder goes.
        if let Err(e) = std::fs::remove_dir_all(work) {
            eprintln!("warning: cannot remove {}: {e}", work.display());
        }
    }
    if a.json {
        print_json(&json!({"capture": a.out, "frames": n, "notes": done.notes, "sfm": summary}))?;
    } else {
        println!(
            "wrote {} ({n} frames from {})",
            a.out.display(),
            a.input.display()
        );
        if let Some(r) = &summary {
            println!(
                "cameras by structure from motion ({}): {} of {} frames placed, {} points, reprojection error {:.2} px; intrinsics {} (fx {:.1}, fy {:.1}, cx {:.1}, cy {:.1}); world = the camera of {}, unit = {}; details in {}",
                r.tool,
                r.frames_registered,
                r.frames_used,
                r.points,
                r.mean_reprojection_error_px,
                r.intrinsics.source,
                r.intrinsics.fx,
                r.intrinsics.fy,
                r.intrinsics.cx,
                r.intrinsics.cy,
                r.gauge.origin_frame,
                r.gauge.unit,
                a.out.join("sfm/report.json").display()
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Frames of the video that SfM may choose from (keyframes and the frames between them,
/// thinned evenly).
const SFM_CANDIDATES: usize = 300;

/// Runs an SfM job with a progress bar on stderr and one line per stage as it starts and as
/// it ends (with its seconds), which stays in logs where the bar is not drawn.
pub fn run_sfm_with_progress(
    job: &agentstar_sfm::SfmJob,
    estimate: impl FnOnce(
        &agentstar_sfm::SfmJob,
        &mut dyn FnMut(agentstar_sfm::Progress),
    ) -> Result<agentstar_sfm::SfmOutcome, agentstar_sfm::SfmError>,
) -> Result<agentstar_sfm::SfmOutcome, agentstar_sfm::SfmError> {
    let bar = crate::common::progress(job.frames.len(), "sfm");
    let mut stage = "";
    let mut started = std::time::Instant::now();
    let run_start = started;
    let outcome = estimate(job, &mut |p| {
        if p.stage != stage {
            if !stage.is_empty() {
                let s = started.elapsed().as_secs_f64();
                bar.suspend(|| eprintln!("sfm: {stage} done in {s:.1} s"));
            }
            stage = p.stage;
            started = std::time::Instant::now();
            let at = run_start.elapsed().as_secs_f64();
            bar.suspend(|| eprintln!("sfm: {stage} ({} to do) at {at:.1} s", p.total));
            bar.set_message(p.stage);
            bar.set_length(p.total.max(1));
        }
        bar.set_position(p.done.min(p.total));
    });
    bar.finish_and_clear();
    match &outcome {
        Ok(_) => eprintln!(
            "sfm: {stage} done; whole run {:.1} s",
            run_start.elapsed().as_secs_f64()
        ),
        Err(_) => eprintln!(
            "sfm: stopped in {stage} after {:.1} s",
            run_start.elapsed().as_secs_f64()
        ),
    }
    outcome
}

/// Runs structure from motion for `from-video --cameras sfm`: the camera source, the work
/// folder (to attach to the capture, then remove) and the report.
fn sfm_cameras(
    a: &FromVideoArgs,
    frames: &agentstar_import::video::FrameFiles,
) -> Result<(
    agentstar_import::video::CameraSource,
    PathBuf,
    agentstar_sfm::SfmReport,
)> {
    use agentstar_sfm::video::{select_frames, sfm_frames};
    use agentstar_sfm::{estimate_cameras, GpuUse, Intrinsics, SfmJob, SfmSettings};
    if let Some(d) = a.background_depth_m {
        if !(d.is_finite() && d > 0.0) {
            anyhow::bail!("--background-depth-m {d}: a distance in metres, above 0");
        }
    }
    if a.sfm_time_limit_s == 0 {
        anyhow::bail!("--sfm-time-limit-s must be at least 1");
    }
    if a.sfm_max_frames < 2 {
        anyhow::bail!("--sfm-max-frames {}: at least 2", a.sfm_max_frames);
    }
    if a.sfm_max_features < 100 {
        anyhow::bail!("--sfm-max-features {}: at least 100", a.sfm_max_features);
    }
    if a.sfm_overlap == 0 {
        anyhow::bail!("--sfm-overlap 0: at least 1");
    }
    let keyframes = frames.keyframe_indices(a.every, a.max_frames);
    if keyframes.len() < 2 {
        anyhow::bail!(
            "--cameras sfm needs at least two keyframes; {} has {} frame(s) and --every {} keeps {}",
            a.input.display(),
            frames.paths.len(),
            a.every,
            keyframes.len()
        );
    }
    // SfM may use the frames between keyframes (at most SFM_CANDIDATES of the video); it
    // picks its own subset to reconstruct from and registers the keyframes it left out.
    // The in-between frames the capture keeps need cameras too: SfM registers those it does
    // not reconstruct from.
    let in_between = a
        .between
        .map(|stride| agentstar_import::video::FrameFiles::between_indices(&keyframes, stride))
        .unwrap_or_default();
    let mut indices = select_frames(&keyframes, SFM_CANDIDATES.max(keyframes.len()));
    indices.extend(&in_between);
    indices.sort_unstable();
    indices.dedup();
    let (sfm_frames, skipped) = sfm_frames(
        frames,
        &a.masks,
        a.hands.as_deref(),
        &keyframes,
        &in_between,
        &indices,
    )?;
    if !skipped.is_empty() {
        eprintln!(
            "note: {} frame(s) between keyframes have no mask and are left out of SfM (first: {})",
            skipped.len(),
            skipped[0]
        );
    }
    let size = agentstar_data::images::image_size(&frames.paths[keyframes[0]])?;
    let intrinsics = match given_intrinsics(a, size)? {
        Some(k) => Intrinsics::Given(k),
        None => match agentstar_import::video::video_focal_px(&a.input, size.0, size.1) {
            Some(f) => Intrinsics::Prior {
                focal_px: f,
                source: "video metadata".into(),
            },
            None => Intrinsics::Estimate,
        },
    };
    // The work folder sits beside the capture; it is kept (with COLMAP's logs) on failure.
    let name = a
        .out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "capture".into());
    let work = a.out.with_file_name(format!("{name}.sfm"));
    let marker = work.join(".agentstar-sfm");
    if work.exists() {
        if marker.is_file() {
            std::fs::remove_dir_all(&work)
                .with_context(|| format!("removing the old SfM folder {}", work.display()))?;
        } else {
            anyhow::bail!(
                "{} exists and is not an agentstar SfM folder; move it or choose another --out",
                work.display()
            );
        }
    }
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    std::fs::write(
        &marker,
        b"agentstar capture from-video --cameras sfm work folder\n",
    )
    .with_context(|| format!("writing {}", marker.display()))?;
    let job = SfmJob {
        image_dir: frames.dir.clone(),
        frames: sfm_frames,
        size: [size.0, size.1],
        intrinsics,
        work_dir: work.clone(),
        time_limit: std::time::Duration::from_secs(a.sfm_time_limit_s),
        settings: SfmSettings {
            reconstruct_max: a.sfm_max_frames,
            max_features: a.sfm_max_features,
            overlap: a.sfm_overlap,
            gpu: match a.sfm_gpu {
                SfmGpu::Auto => GpuUse::Auto,
                SfmGpu::Off => GpuUse::Off,
            },
        },
        background_depth_m: a.background_depth_m,
        colmap: None,
        threads: a.sfm_threads.map(usize::from),
    };
    eprintln!(
        "structure from motion with COLMAP: {} frames of the video to choose from, {} keyframes need cameras; at most {} s; logs in {}",
        job.frames.len(),
        keyframes.len(),
        a.sfm_time_limit_s,
        work.join("logs").display()
    );
    let outcome = run_sfm_with_progress(&job, estimate_cameras);
    let outcome = match outcome {
        Ok(o) => o,
        Err(e) => anyhow::bail!(
            "{e}\n(COLMAP's logs and the masks it used are in {})",
            work.display()
        ),
    };
    let note = serde_json::to_value(&outcome.report)?;
    Ok((
        agentstar_import::video::CameraSource::Given {
            cameras: outcome.cameras,
            note: json!({"kind": "sfm", "report": note}),
        },
        work,
        outcome.report,
    ))
}

/// What an importer with ground truth wrote, as `--json` prints it (its keys in alphabetical
/// order).
#[derive(serde::Serialize)]
struct ImportReport<'a> {
    between_frames: usize,
    capture: &'a Path,
    frames: usize,
    gt: PathBuf,
    #[serde(skip_serializing_if = "Option::is_none")]
    rendered_masks: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    skipped: Option<usize>,
}

impl<'a> ImportReport<'a> {
    fn new(out: &'a Path, keyframes: usize, between: usize) -> Self {
        ImportReport {
            between_frames: between,
            capture: out,
            frames: keyframes,
            gt: out.join("gt.json"),
            rendered_masks: None,
            skipped: None,
        }
    }

    /// Prints the report: JSON with `--json`, else `wrote OUT (N frames … what)`.
    fn print(&self, json: bool, what: &str) -> Result<ExitCode> {
        if json {
            print_json(self)?;
        } else {
            println!(
                "wrote {} ({} {what})",
                self.capture.display(),
                frames_written(self.frames, self.between_frames)
            );
        }
        Ok(ExitCode::SUCCESS)
    }
}

pub fn run(c: CaptureCommand) -> Result<ExitCode> {
    match c {
        CaptureCommand::FromVideo(a) => from_video(a),
        CaptureCommand::FromBop(a) => {
            check_between(a.every, a.between)?;
            let n = import_bop(
                &BopImport {
                    scene: a.scene.clone(),
                    models: a.models.clone(),
                    obj_id: a.obj_id,
                    every: a.every,
                    between: a.between,
                    depth: a.depth,
                },
                &a.out,
            )?;
            ImportReport::new(&a.out, n.keyframes, n.between).print(
                a.json,
                &format!(
                    "of object {} from {}, with gt.json",
                    a.obj_id,
                    a.scene.display()
                ),
            )
        }
        CaptureCommand::FromHot3d(a) => {
            use agentstar_geom::pose::{quat_from_wxyz, Rigid};
            use agentstar_import::hot3d::{import_hot3d, Hot3dImport};
            check_between(a.every, a.between)?;
            let intrinsics = four(&a.intrinsics, "--intrinsics")?;
            let device_from_camera = match &a.device_from_camera {
                None => Rigid::identity(),
                Some(v) if v.len() != 7 || v.iter().any(|x| !x.is_finite()) => anyhow::bail!(
                    "--device-from-camera takes 7 finite numbers qw,qx,qy,qz,tx,ty,tz; got {v:?}"
                ),
                Some(v) => Rigid::from_parts(
                    agentstar_geom::Vector3::new(v[4], v[5], v[6]).into(),
                    quat_from_wxyz([v[0], v[1], v[2], v[3]])
                        .map_err(|e| anyhow::anyhow!("--device-from-camera: {e}"))?,
                ),
            };
            if !(a.max_dt_ms.is_finite() && a.max_dt_ms >= 0.0) {
                anyhow::bail!(
                    "--max-dt-ms {}: a time in milliseconds, 0 or more",
                    a.max_dt_ms
                );
            }
            let s = import_hot3d(
                &Hot3dImport {
                    sequence: a.sequence.clone(),
                    models: a.models.clone(),
                    object_uid: a.object_uid.clone(),
                    frames: a.frames.clone(),
                    masks: a.masks.clone(),
                    hands: a.hands.clone(),
                    intrinsics,
                    device_from_camera,
                    max_dt_ns: (a.max_dt_ms * 1e6).round() as u64,
                    every: a.every,
                    between: a.between,
                },
                &a.out,
            )?;
            ImportReport {
                skipped: Some(s.skipped),
                rendered_masks: Some(s.rendered_masks),
                ..ImportReport::new(&a.out, s.frames, s.between)
            }
            .print(
                a.json,
                &format!(
                    "of object {}, {} frames without a pose skipped{}; with gt.json",
                    a.object_uid,
                    s.skipped,
                    if s.rendered_masks {
                        ", masks rendered from the ground truth"
                    } else {
                        ""
                    }
                ),
            )
        }
        CaptureCommand::FromArctic(a) => {
            use agentstar_import::arctic::{import_arctic, ArcticImport};
            check_between(a.every, a.between)?;
            if a.max_frames == Some(0) {
                anyhow::bail!("--max-frames 0: a capture needs at least one frame");
            }
            let n = import_arctic(
                &ArcticImport {
                    root: a.root.clone(),
                    subject: a.subject.clone(),
                    sequence: a.sequence.clone(),
                    camera: a.camera,
                    images: a.images.clone(),
                    masks: a.masks.clone(),
                    hands: a.hands.clone(),
                    offset: a.offset,
                    every: a.every,
                    max_frames: a.max_frames,
                    between: a.between,
                },
                &a.out,
            )?;
            ImportReport::new(&a.out, n.keyframes, n.between).print(
                a.json,
                &format!(
                    "of {}/{} from camera {}, with gt.json{}",
                    a.subject,
                    a.sequence,
                    a.camera,
                    if a.masks.is_none() {
                        "; masks rendered from the ground truth"
                    } else {
                        ""
                    }
                ),
            )
        }
    }
}
