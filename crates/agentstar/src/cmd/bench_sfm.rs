//! `agentstar bench --suite sfm`: cameras by structure from motion for a real-length clip.
//!
//! A seeded orbit of a static object (the microwave) in a room with photographic-statistics
//! textures (`Walls::Photographic`), 191 frames of 640×480 by default, keyframes every 10th
//! frame and every frame kept (so every frame needs a camera), runs through the same SfM as
//! `capture from-video --cameras sfm` and prints the time of each stage and the camera errors
//! against the truth after a similarity alignment, with the machine's load.

use crate::cmd::capture::run_sfm_with_progress;
use crate::common::print_json;
use agentstar_geom::pose::Rigid;
use agentstar_sfm::gauge::{camera_errors, CameraErrors};
use agentstar_sfm::{
    estimate_cameras, FrameRole, GpuUse, Intrinsics, SfmFrame, SfmJob, SfmReport, SfmSettings,
};
use agentstar_synth::environment::{synthesize_room_clip, CameraPath, RoomConfig, Walls};
use anyhow::{bail, Context, Result};
use serde::Serialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// What the SfM bench runs: the clip and the SfM settings.
#[derive(Debug, Clone)]
pub struct SfmBench {
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    pub keyframe_every: usize,
    pub orbit_deg: f64,
    pub seed: u64,
    pub settings: SfmSettings,
    pub out: Option<PathBuf>,
    pub results: Option<PathBuf>,
    pub json: bool,
}

/// Camera errors of one set of frames, in the units people read.
#[derive(Debug, Clone, Serialize)]
pub struct ErrorFigures {
    pub frames: usize,
    pub rotation_deg_max: f64,
    pub rotation_deg_median: f64,
    pub translation_percent_max: f64,
    pub translation_percent_median: f64,
    pub trajectory_length_m: f64,
}

impl From<&CameraErrors> for ErrorFigures {
    fn from(e: &CameraErrors) -> Self {
        ErrorFigures {
            frames: 0,
            rotation_deg_max: e.rotation_deg_max,
            rotation_deg_median: e.rotation_deg_median,
            translation_percent_max: 100.0 * e.translation_max_fraction,
            translation_percent_median: 100.0 * e.translation_median_fraction,
            trajectory_length_m: e.trajectory_length,
        }
    }
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

fn errors_of(
    names: &[String],
    estimated: &agentstar_import::cameras::CameraSet,
    truth: &[Rigid],
) -> Result<ErrorFigures> {
    let mut est = vec![];
    for name in names {
        let stem = name.trim_end_matches(".png");
        let c = estimated
            .by_stem
            .get(stem)
            .with_context(|| format!("SfM gave no camera for {name}"))?;
        est.push(c.world_from_camera);
    }
    let e = camera_errors(&est, truth).context("camera errors need two frames or more")?;
    Ok(ErrorFigures {
        frames: names.len(),
        ..ErrorFigures::from(&e)
    })
}

pub fn run(b: &SfmBench) -> Result<ExitCode> {
    if b.frames < 3 || b.keyframe_every == 0 {
        bail!(
            "the sfm bench needs at least 3 frames and keyframes every 1 or more (got {} and {})",
            b.frames,
            b.keyframe_every
        );
    }
    // Without --out, the clip and SfM's work go to a folder of this process, removed after.
    let temp = b
        .out
        .is_none()
        .then(|| std::env::temp_dir().join(format!("agentstar-bench-sfm-{}", std::process::id())));
    let root: &Path = match (&b.out, &temp) {
        (Some(p), _) | (None, Some(p)) => p,
        (None, None) => unreachable!("a folder either way"),
    };
    let result = run_in(b, root);
    if let Some(t) = &temp {
        if let Err(e) = std::fs::remove_dir_all(t) {
            eprintln!("warning: cannot remove {}: {e}", t.display());
        }
    }
    result
}

fn run_in(b: &SfmBench, root: &Path) -> Result<ExitCode> {
    let cfg = RoomConfig {
        object: "microwave".into(),
        frames: b.frames,
        keyframe_every: b.keyframe_every,
        width: b.width,
        height: b.height,
        seed: b.seed,
        walls: Walls::Photographic,
        camera: CameraPath::OrbitWobble,
        object_turn_deg_per_frame: 0.0,
        hand: false,
        orbit_deg: Some(b.orbit_deg),
    };
    eprintln!(
        "bench sfm: rendering {} frames of {}×{} (seed {}) …",
        b.frames, b.width, b.height, b.seed
    );
    let t = Instant::now();
    let clip = synthesize_room_clip(&cfg)?;
    let frames_dir = root.join("frames");
    std::fs::create_dir_all(&frames_dir)
        .with_context(|| format!("creating {}", frames_dir.display()))?;
    let mut frames = vec![];
    for f in &clip.frames {
        agentstar_data::images::save_png_rgb(&f.rgb, &frames_dir.join(&f.name))?;
        let excluded = match &f.hand {
            Some(h) => f.mask.or(h),
            None => f.mask.clone(),
        };
        frames.push(SfmFrame {
            file_name: f.name.clone(),
            stem: f.name.trim_end_matches(".png").to_string(),
            excluded,
            role: if (f.frame_index as usize).is_multiple_of(b.keyframe_every) {
                FrameRole::Keyframe
            } else {
                FrameRole::InBetween
            },
        });
    }
    let render_s = t.elapsed().as_secs_f64();
    let work = root.join("work");
    if work.exists() {
        std::fs::remove_dir_all(&work).with_context(|| format!("removing {}", work.display()))?;
    }
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    let job = SfmJob {
        image_dir: frames_dir,
        frames,
        size: [b.width, b.height],
        intrinsics: Intrinsics::Estimate,
        work_dir: work,
        time_limit: agentstar_sfm::DEFAULT_TIME_LIMIT,
        background_depth_m: None,
        colmap: None,
        threads: None,
        settings: b.settings.clone(),
    };
    let load_before = load_average();
    let t = Instant::now();
    let outcome = run_sfm_with_progress(&job, estimate_cameras)?;
    let sfm_s = t.elapsed().as_secs_f64();
    let load_after = load_average();
    let names: Vec<String> = clip.frames.iter().map(|f| f.name.clone()).collect();
    let truth: Vec<Rigid> = clip.frames.iter().map(|f| f.world_from_camera).collect();
    let all = errors_of(&names, &outcome.cameras, &truth)?;
    let (key_names, key_truth): (Vec<String>, Vec<Rigid>) = clip
        .keyframes()
        .map(|f| (f.name.clone(), f.world_from_camera))
        .unzip();
    let keyframes = errors_of(&key_names, &outcome.cameras, &key_truth)?;
    let report: &SfmReport = &outcome.report;
    let focal_error_percent = 100.0 * (report.intrinsics.fx / clip.camera.fx - 1.0);
    let date = crate::cmd::bench::today();
    let machine = crate::cmd::bench::machine();
    let settings = &b.settings;
    let mut md = format!(
        "## agentstar bench: sfm suite\n\nRecorded {date} on {machine}; load average (1, 5, 15 min) {load_before} before SfM, {load_after} after.\n\n\
         Clip: {} frames of {}×{}, seed {}, a static microwave in a room with photographic-statistics textures, a {}° hand-held orbit; keyframes every {} frames and every frame kept (all {} need a camera); rendered in {render_s:.1} s.\n\n\
         SfM: at most {} frames reconstructed, {} features per frame, overlap {}, GPU {}.\n\n",
        b.frames,
        b.width,
        b.height,
        b.seed,
        b.orbit_deg,
        b.keyframe_every,
        b.frames,
        settings.reconstruct_max,
        settings.max_features,
        settings.overlap,
        if report.gpu { "on" } else { "off" },
    );
    md += "| stage | seconds |\n|---|---:|\n";
    // In the order they run.
    for stage in [
        "checks",
        "features",
        "matching",
        "mapping",
        "registration",
        "model",
    ] {
        if let Some(s) = report.stage_seconds.get(stage) {
            md += &format!("| {stage} | {s:.1} |\n");
        }
    }
    md += &format!("| **whole SfM** | **{sfm_s:.1}** |\n\n");
    md += &format!(
        "Frames: {} used, {} reconstructed ({} placed by mapping), {} placed by registration, {} of {} with a camera; median {} features a frame; pairs matched {} + {}; {} points, reprojection error {:.2} px; focal length {:.1} px ({focal_error_percent:+.2}% of the true {:.1}).\n\n",
        report.frames_used,
        report.frames_reconstructed,
        report.frames_placed_by_mapping,
        report.frames_placed_by_registration,
        report.frames_registered,
        b.frames,
        report.features_per_frame_median,
        report.pairs_matched[0],
        report.pairs_matched[1],
        report.points,
        report.mean_reprojection_error_px,
        report.intrinsics.fx,
        clip.camera.fx,
    );
    md += "| cameras | frames | rotation max (°) | rotation median (°) | translation max (% of trajectory) | translation median (%) |\n|---|---:|---:|---:|---:|---:|\n";
    for (what, e) in [("every frame", &all), ("keyframes", &keyframes)] {
        md += &format!(
            "| {what} | {} | {:.3} | {:.3} | {:.2} | {:.2} |\n",
            e.frames,
            e.rotation_deg_max,
            e.rotation_deg_median,
            e.translation_percent_max,
            e.translation_percent_median
        );
    }
    md += &format!("\nTrajectory length {:.3} m.\n", all.trajectory_length_m);
    let result = json!({
        "suite": "sfm",
        "date": date,
        "machine": machine,
        "load_average_before": load_before,
        "load_average_after": load_after,
        "clip": {"frames": b.frames, "width": b.width, "height": b.height, "seed": b.seed,
                 "orbit_deg": b.orbit_deg, "keyframe_every": b.keyframe_every, "render_seconds": render_s},
        "settings": {"reconstruct_max": settings.reconstruct_max, "max_features": settings.max_features,
                     "overlap": settings.overlap},
        "sfm_seconds": sfm_s,
        "report": report,
        "errors": {"every_frame": all, "keyframes": keyframes},
        "focal_error_percent": focal_error_percent,
    });
    if let Some(p) = &b.results {
        agentstar_data::atomic::write_atomic(p, md.as_bytes())?;
        agentstar_data::atomic::write_json(&p.with_extension("json"), &result)?;
    }
    if b.json {
        print_json(&result)?;
    } else {
        print!("{md}");
    }
    Ok(ExitCode::SUCCESS)
}

/// The SfM settings of a bench run from the command's options.
pub fn settings(max_frames: usize, max_features: usize, overlap: usize, gpu: bool) -> SfmSettings {
    SfmSettings {
        reconstruct_max: max_frames,
        max_features,
        overlap,
        gpu: if gpu { GpuUse::Auto } else { GpuUse::Off },
    }
}
