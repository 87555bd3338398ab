//! Cameras of a hand-held video by structure from motion on its static background.
//!
//! COLMAP (an existing, maintained SfM, run as a subprocess on the CPU; never a hand-written
//! one) sees the keyframes and the frames between them with the **object and hand masks
//! excluded from feature extraction** (a margin around them too), so only the background
//! constrains the cameras. The result is read back from COLMAP's text model
//! (`agentstar_import::cameras`), put in the documented gauge ([`gauge`]: the first keyframe's
//! camera frame, one unit the median background depth or metres), and checked.
//!
//! The failures a user meets come back as [`SfmError`]s that say what to do instead: a
//! static camera (checked before COLMAP runs), too little background texture (from COLMAP's
//! feature counts), no pair of frames with parallax, pure rotation, keyframes left without a
//! camera. Every COLMAP stage runs under the job's deadline and its output is kept in a log
//! file in the work folder.
//!
//! The caller names every frame that needs a camera (keyframes and the frames between them
//! that the capture keeps) and may add frames that only help; SfM reconstructs from a strided
//! subset and registers the other frames that need a camera against that model ([`plan`]).
//!
//! I/O: this crate reads frames, writes masks and logs into its work folder and runs COLMAP.

pub mod checks;
pub mod colmap;
pub mod gauge;
mod pipeline;
pub mod plan;
pub mod video;

pub use pipeline::estimate_cameras;

use agentstar_import::cameras::CameraSet;
use agentstar_mask::BitMask;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

pub use colmap::INSTALL_HINT;

/// What a user can do instead when SfM cannot give the cameras.
const FALLBACK: &str = "or give the cameras yourself: --colmap DIR / --nerfstudio FILE from another tool, or --fov DEG (or --intrinsics) for a static camera";

#[derive(Debug, thiserror::Error)]
pub enum SfmError {
    #[error("structure from motion needs COLMAP, which could not be run (`{}`: {reason}); {INSTALL_HINT}; {FALLBACK}", program.display())]
    ColmapMissing { program: PathBuf, reason: String },
    #[error("the camera does not move: the background changes by at most {largest_change:.2} of what a one-pixel shift changes (below {threshold}), so structure from motion has nothing to triangulate. For a camera on a tripod, drop --cameras sfm and give a static camera: --fov DEG or --intrinsics fx,fy,cx,cy")]
    StaticCamera { largest_change: f64, threshold: f64 },
    #[error("too little background texture for structure from motion: a median of {median} features per frame outside the object and hand masks (at least {needed} needed; fewest in {fewest}). Film in front of a textured background (shelves, posters, a patterned cloth, a cluttered desk), {FALLBACK}")]
    TooLittleTexture {
        median: usize,
        needed: usize,
        fewest: String,
    },
    #[error("COLMAP found no pair of frames with enough parallax to start a reconstruction (features per frame: median {median_features}): the camera turns in place (pure rotation) or barely moves. Move the camera around the object (a sideways step of a tenth of the distance to the background is enough), {FALLBACK}")]
    NoInitialPair { median_features: usize },
    #[error("the reconstructed cameras barely translate (largest distance from the first keyframe {baseline_ratio:.4} of the background depth, below {threshold}): the camera turned in place (pure rotation), which fixes orientations but not positions. Move the camera around the object, {FALLBACK}")]
    PureRotation { baseline_ratio: f64, threshold: f64 },
    #[error("structure from motion placed {registered} of the {needed} frames that need a camera; without one: {}. Film with more overlap between frames (slower motion), more background texture and less of the view covered by the object and hands, {FALLBACK}", name_some(missing))]
    TooFewRegistered {
        registered: usize,
        needed: usize,
        missing: Vec<String>,
    },
    #[error("`{} help`, the probe that finds COLMAP, did not answer within {seconds:.0} s and was stopped: check that it is COLMAP and runs without a display, or point AGENTSTAR_COLMAP at one that does; {FALLBACK}", program.display())]
    ProbeTimedOut { program: PathBuf, seconds: f64 },
    #[error("structure from motion ran past its time limit ({limit_s:.0} s for the whole run) and was stopped in its {stage} stage (COLMAP {command}; log: {}); allow more time (--sfm-time-limit-s), or reconstruct from fewer frames (--sfm-max-frames) with fewer features (--sfm-max-features)", log.display())]
    TimedOut {
        stage: String,
        command: String,
        limit_s: f64,
        log: PathBuf,
    },
    #[error("COLMAP {stage} failed ({status}); log: {}; its last lines:\n{tail}", log.display())]
    ToolFailed {
        stage: String,
        status: String,
        log: PathBuf,
        tail: String,
    },
    #[error("{}: {error}", path.display())]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error(transparent)]
    Data(#[from] agentstar_data::DataError),
    #[error("{0}")]
    Input(String),
}

/// At most ten names, then how many more.
fn name_some(names: &[String]) -> String {
    let mut text = names
        .iter()
        .take(10)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > 10 {
        text += &format!(" and {} more", names.len() - 10);
    }
    text
}

impl SfmError {
    /// A time-out of a COLMAP command, named by the stage of the run it stopped.
    pub(crate) fn in_stage(self, stage: &str, limit: Duration) -> Self {
        match self {
            SfmError::TimedOut { command, log, .. } => SfmError::TimedOut {
                stage: stage.to_string(),
                command,
                limit_s: limit.as_secs_f64(),
                log,
            },
            other => other,
        }
    }

    pub(crate) fn io(path: impl AsRef<Path>, error: std::io::Error) -> Self {
        SfmError::Io {
            path: path.as_ref().to_path_buf(),
            error,
        }
    }
}

/// What a frame is to the capture, and so to SfM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameRole {
    /// A keyframe: it needs a camera; the first one fixes the gauge.
    Keyframe,
    /// A frame between keyframes that the capture keeps: it needs a camera.
    InBetween,
    /// A frame the capture does not keep: SfM may reconstruct from it, and places it if it does.
    Helper,
}

impl FrameRole {
    pub fn needs_camera(self) -> bool {
        self != FrameRole::Helper
    }
}

/// One frame for SfM.
#[derive(Debug, Clone)]
pub struct SfmFrame {
    /// The image file inside the job's image folder.
    pub file_name: String,
    /// Its stem: the key of the resulting camera set.
    pub stem: String,
    /// Pixels whose features are ignored: the object and the hands (without margin).
    pub excluded: BitMask,
    pub role: FrameRole,
}

/// Whether COLMAP's SIFT runs on a GPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GpuUse {
    /// Where COLMAP was built with CUDA and an NVIDIA device is present.
    Auto,
    /// Never.
    Off,
}

/// How much work SfM does: the trade-off of time against accuracy (docs/sfm.md has the
/// measurements behind the defaults).
#[derive(Debug, Clone, PartialEq)]
pub struct SfmSettings {
    /// The most frames the reconstruction (matching and mapping) runs on, evenly strided over
    /// the clip; the other frames that need a camera are registered against the model.
    pub reconstruct_max: usize,
    /// The most SIFT features kept per frame (`SiftExtraction.max_num_features`).
    pub max_features: usize,
    /// Each reconstructed frame is matched with this many next ones of the subset.
    pub overlap: usize,
    pub gpu: GpuUse,
}

/// Reconstruct from at most this many frames by default.
pub const DEFAULT_RECONSTRUCT_MAX: usize = 50;
/// Features per frame by default.
pub const DEFAULT_MAX_FEATURES: usize = 2048;
/// Matching overlap by default.
pub const DEFAULT_OVERLAP: usize = 5;
/// The whole run's time limit by default (every stage together).
pub const DEFAULT_TIME_LIMIT: Duration = Duration::from_secs(1800);

impl Default for SfmSettings {
    fn default() -> Self {
        SfmSettings {
            reconstruct_max: DEFAULT_RECONSTRUCT_MAX,
            max_features: DEFAULT_MAX_FEATURES,
            overlap: DEFAULT_OVERLAP,
            gpu: GpuUse::Auto,
        }
    }
}

/// Where the intrinsics come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Intrinsics {
    /// fx, fy, cx, cy in pixels, given by the user: kept fixed.
    Given([f64; 4]),
    /// A focal length in pixels as a starting value (the principal point at the centre),
    /// refined; `source` says where it came from (e.g. "video metadata").
    Prior { focal_px: f64, source: String },
    /// Estimated by SfM, one camera shared by every frame, from COLMAP's default prior.
    Estimate,
}

/// What to run and how.
#[derive(Debug, Clone)]
pub struct SfmJob {
    /// The folder of the frames.
    pub image_dir: PathBuf,
    /// In video order: every frame that needs a camera (at least two keyframes) and any
    /// frames that only help.
    pub frames: Vec<SfmFrame>,
    /// Every frame's size in pixels.
    pub size: [u32; 2],
    pub intrinsics: Intrinsics,
    /// Where masks, the database, the models and the logs go (an empty or new folder).
    pub work_dir: PathBuf,
    /// The whole run's time limit (every stage together; [`DEFAULT_TIME_LIMIT`]).
    pub time_limit: Duration,
    pub settings: SfmSettings,
    /// The distance from the first keyframe's camera to the background, in metres, when the
    /// user knows it: translations are then in metres. Else one unit is that distance.
    pub background_depth_m: Option<f64>,
    /// A COLMAP executable; else `$AGENTSTAR_COLMAP`, else `colmap` on PATH.
    pub colmap: Option<PathBuf>,
    /// Threads COLMAP may use (None: all).
    pub threads: Option<usize>,
}

/// Progress of a run, for a progress bar.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// "checks", "features", "matching", "mapping", "registration", "model"; `done` 0 when a
    /// stage starts.
    pub stage: &'static str,
    pub done: u64,
    pub total: u64,
}

/// The intrinsics used, and where they came from.
#[derive(Debug, Clone, Serialize)]
pub struct IntrinsicsReport {
    /// "given", "video metadata" (or another prior's source) or "estimated".
    pub source: String,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// Whether SfM refined them (the focal length; the principal point stays at the centre).
    pub refined: bool,
    /// The COLMAP camera model (PINHOLE when given, SIMPLE_PINHOLE otherwise).
    pub model: String,
}

/// The gauge the cameras are expressed in.
#[derive(Debug, Clone, Serialize)]
pub struct GaugeReport {
    /// The keyframe whose camera frame is the world frame.
    pub origin_frame: String,
    /// "metres" (the user gave the background depth) or "median background depth".
    pub unit: String,
    /// The median depth of the background points seen by the first keyframe, in the
    /// capture's units (1 unless metres).
    pub median_background_depth: f64,
    /// Capture units per COLMAP unit.
    pub scale_from_colmap: f64,
    pub meaning: String,
}

/// What was estimated and how well: written as `report.json` in the work folder.
#[derive(Debug, Clone, Serialize)]
pub struct SfmReport {
    pub tool: String,
    /// How pairs were chosen ("strided subset, overlap N, longer links, loop ends").
    pub matcher: String,
    /// Whether SIFT ran on the GPU.
    pub gpu: bool,
    /// Frames whose features were extracted (the reconstruction's and the registered ones).
    pub frames_used: usize,
    /// Frames that got a camera.
    pub frames_registered: usize,
    pub keyframes: usize,
    /// Frames that need a camera (keyframes and kept frames between them).
    pub frames_needing_cameras: usize,
    /// Frames the reconstruction ran on, and how many of them it placed.
    pub frames_reconstructed: usize,
    pub frames_placed_by_mapping: usize,
    /// Runs of COLMAP's mapper: another run, with a smaller initial triangulation angle (16°,
    /// 8°, 4°), follows one whose largest model holds under half of the frames reconstructed;
    /// the largest model wins.
    pub mapping_tries: usize,
    /// Frames placed afterwards by registration against the model.
    pub frames_placed_by_registration: usize,
    /// Pairs of frames matched (reconstruction, registration).
    pub pairs_matched: [usize; 2],
    /// The most features per frame asked for.
    pub max_features: usize,
    /// COLMAP's first SIFT octave (−1: the frame doubled first; [`plan::first_octave`]).
    pub first_octave: i32,
    /// Helper frames used that got no camera (they are not needed).
    pub unregistered_frames: Vec<String>,
    pub features_per_frame_median: usize,
    pub intrinsics: IntrinsicsReport,
    pub points: usize,
    pub mean_reprojection_error_px: f64,
    pub mean_track_length: f64,
    /// Largest camera distance from the first keyframe over the median background depth.
    pub baseline_over_depth: f64,
    pub gauge: GaugeReport,
    /// Wall time of each stage (checks, features, matching, mapping, registration, model),
    /// seconds.
    pub stage_seconds: BTreeMap<String, f64>,
}

/// The cameras (by frame stem, in the gauge) and the report.
#[derive(Debug, Clone)]
pub struct SfmOutcome {
    pub cameras: CameraSet,
    pub report: SfmReport,
    /// A folder of what is worth keeping with the capture: `report.json`, COLMAP's text
    /// model (`cameras.txt`, `images.txt`, `points3D.txt`, in COLMAP's own frame) and the
    /// logs of every stage.
    pub keep_dir: PathBuf,
}

/// A static camera: the background moves less than this fraction of a one-block shift.
pub const STATIC_CAMERA_RATIO: f64 = 0.3;
/// Fewer features per frame (median) than this is too little texture.
pub const MIN_FEATURES: usize = 100;
/// Cameras within this fraction of the background depth of the first are pure rotation.
pub const PURE_ROTATION_RATIO: f64 = 0.01;

pub(crate) fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

pub(crate) fn os(args: &[&str]) -> Vec<std::ffi::OsString> {
    args.iter().map(std::ffi::OsString::from).collect()
}

pub(crate) fn path_str(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}
