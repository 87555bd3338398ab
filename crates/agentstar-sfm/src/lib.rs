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
//! I/O: this crate reads frames, writes masks and logs into its work folder and runs COLMAP.

pub mod checks;
pub mod colmap;
pub mod gauge;
pub mod video;

use agentstar_geom::PinholeCamera;
use agentstar_import::cameras::{read_colmap, read_colmap_points, CameraSet, SourceCamera};
use agentstar_mask::BitMask;
use colmap::{progress_in, Colmap, FeatureCounts};
use serde::Serialize;
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

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
    #[error("structure from motion placed {registered} of {total} frames; keyframes without a camera: {}. Film with more overlap between frames (slower motion), more background texture and less of the view covered by the object and hands, {FALLBACK}", missing_keyframes.join(", "))]
    TooFewRegistered {
        registered: usize,
        total: usize,
        missing_keyframes: Vec<String>,
    },
    #[error("`{} help`, the probe that finds COLMAP, did not answer within {seconds:.0} s and was stopped: check that it is COLMAP and runs without a display, or point AGENTSTAR_COLMAP at one that does; {FALLBACK}", program.display())]
    ProbeTimedOut { program: PathBuf, seconds: f64 },
    #[error("COLMAP {stage} ran past the time limit and was stopped (log: {}); allow more time (--sfm-time-limit-s) or use fewer frames (--sfm-max-frames)", log.display())]
    TimedOut { stage: String, log: PathBuf },
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

impl SfmError {
    pub(crate) fn io(path: impl AsRef<Path>, error: std::io::Error) -> Self {
        SfmError::Io {
            path: path.as_ref().to_path_buf(),
            error,
        }
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
    /// Keyframes must all get a camera; the frames between them help and may be dropped.
    pub keyframe: bool,
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
    /// In video order; at least two keyframes.
    pub frames: Vec<SfmFrame>,
    /// Every frame's size in pixels.
    pub size: [u32; 2],
    pub intrinsics: Intrinsics,
    /// Where masks, the database, the models and the logs go (an empty or new folder).
    pub work_dir: PathBuf,
    /// The whole run's time limit.
    pub time_limit: Duration,
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
    /// "checks", "features", "matching", "mapping", "model".
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
    pub matcher: String,
    pub frames_used: usize,
    pub frames_registered: usize,
    pub keyframes: usize,
    /// Frames between keyframes that got no camera (they are not needed).
    pub unregistered_frames: Vec<String>,
    pub features_per_frame_median: usize,
    pub intrinsics: IntrinsicsReport,
    pub points: usize,
    pub mean_reprojection_error_px: f64,
    pub mean_track_length: f64,
    /// Largest camera distance from the first keyframe over the median background depth.
    pub baseline_over_depth: f64,
    pub gauge: GaugeReport,
    /// Wall time of each stage (checks, features, matching, mapping, model), seconds.
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

fn secs(t: Instant) -> f64 {
    (t.elapsed().as_secs_f64() * 1000.0).round() / 1000.0
}

/// Runs structure from motion on the job's frames.
pub fn estimate_cameras(
    job: &SfmJob,
    progress: &mut dyn FnMut(Progress),
) -> Result<SfmOutcome, SfmError> {
    let start = Instant::now();
    let deadline = start + job.time_limit;
    let keyframes: Vec<&SfmFrame> = job.frames.iter().filter(|f| f.keyframe).collect();
    if keyframes.len() < 2 {
        return Err(SfmError::Input(format!(
            "structure from motion needs at least two keyframes, got {}",
            keyframes.len()
        )));
    }
    let [w, h] = job.size;
    if let Some(f) = job
        .frames
        .iter()
        .find(|f| (f.excluded.width(), f.excluded.height()) != (w, h))
    {
        return Err(SfmError::Input(format!(
            "frame {}: its mask is {}×{}, the frames are {w}×{h}",
            f.file_name,
            f.excluded.width(),
            f.excluded.height()
        )));
    }
    for dir in [&job.image_dir, &job.work_dir] {
        if dir.to_str().is_none() {
            return Err(SfmError::Input(format!(
                "{}: COLMAP is given paths as text; use a folder whose path is UTF-8",
                dir.display()
            )));
        }
    }
    // The probe is under the job's deadline too (and never longer than PROBE_LIMIT).
    let colmap = Colmap::find_within(
        job.colmap.as_deref(),
        deadline
            .saturating_duration_since(Instant::now())
            .min(colmap::PROBE_LIMIT),
    )?;
    let work = &job.work_dir;
    let masks_dir = work.join("masks");
    std::fs::create_dir_all(&masks_dir).map_err(|e| SfmError::io(&masks_dir, e))?;
    let logs = work.join("logs");
    std::fs::create_dir_all(&logs).map_err(|e| SfmError::io(&logs, e))?;
    let mut stage_seconds = BTreeMap::new();

    // 1. Masks with a margin (SIFT's support reaches past the boundary), and the static check.
    let t = Instant::now();
    let margin = (w.max(h) / 100).max(3);
    let factor = checks::thumb_factor(w, h);
    let total = job.frames.len() as u64;
    let mut first: Option<checks::Thumb> = None;
    let mut self_shift = None;
    let mut largest_change: f64 = 0.0;
    for (i, f) in job.frames.iter().enumerate() {
        let excluded = checks::dilate(&f.excluded, margin);
        let mask_path = masks_dir.join(format!("{}.png", f.file_name));
        checks::colmap_mask(&excluded)
            .save_with_format(&mask_path, image::ImageFormat::Png)
            .map_err(|e| SfmError::Input(format!("{}: cannot write: {e}", mask_path.display())))?;
        let rgb = agentstar_data::images::load_rgb(&job.image_dir.join(&f.file_name))?;
        if rgb.dimensions() != (w, h) {
            return Err(SfmError::Input(format!(
                "frame {} is {}×{}, the first is {w}×{h}",
                f.file_name,
                rgb.width(),
                rgb.height()
            )));
        }
        let thumb = checks::Thumb::new(&rgb, &excluded, factor);
        match &first {
            None => {
                self_shift = thumb.self_shift_difference();
                first = Some(thumb);
            }
            Some(a) => {
                if let Some(d) = a.difference(&thumb) {
                    largest_change = largest_change.max(d);
                }
            }
        }
        progress(Progress {
            stage: "checks",
            done: i as u64 + 1,
            total,
        });
        if Instant::now() > deadline {
            return Err(SfmError::TimedOut {
                stage: "checks".into(),
                log: logs.clone(),
            });
        }
    }
    if let Some(s) = self_shift.filter(|s| *s > 1e-6) {
        let ratio = largest_change / s;
        if ratio < STATIC_CAMERA_RATIO {
            return Err(SfmError::StaticCamera {
                largest_change: ratio,
                threshold: STATIC_CAMERA_RATIO,
            });
        }
    }
    stage_seconds.insert("checks".to_string(), secs(t));

    // 2. Features (SIFT on the CPU), masked.
    let t = Instant::now();
    let list = work.join("image_list.txt");
    let names: Vec<&str> = job.frames.iter().map(|f| f.file_name.as_str()).collect();
    std::fs::write(&list, names.join("\n") + "\n").map_err(|e| SfmError::io(&list, e))?;
    let db = work.join("database.db");
    if db.exists() {
        std::fs::remove_file(&db).map_err(|e| SfmError::io(&db, e))?;
    }
    let threads = job
        .threads
        .map_or_else(|| "-1".to_string(), |n| n.max(1).to_string());
    let (model, params, refine) = match &job.intrinsics {
        Intrinsics::Given(k) => (
            "PINHOLE",
            Some(format!("{},{},{},{}", k[0], k[1], k[2], k[3])),
            false,
        ),
        Intrinsics::Prior { focal_px, .. } => (
            "SIMPLE_PINHOLE",
            Some(format!(
                "{},{},{}",
                focal_px,
                0.5 * w as f64,
                0.5 * h as f64
            )),
            true,
        ),
        Intrinsics::Estimate => ("SIMPLE_PINHOLE", None, true),
    };
    let mut args = os(&[
        "--database_path",
        path_str(&db).as_str(),
        "--image_path",
        path_str(&job.image_dir).as_str(),
        "--image_list_path",
        path_str(&list).as_str(),
        "--ImageReader.mask_path",
        path_str(&masks_dir).as_str(),
        "--ImageReader.camera_model",
        model,
        "--ImageReader.single_camera",
        "1",
        "--SiftExtraction.use_gpu",
        "0",
        "--SiftExtraction.num_threads",
        &threads,
    ]);
    if let Some(p) = &params {
        args.extend(os(&["--ImageReader.camera_params", p]));
    }
    let mut counts = FeatureCounts::default();
    colmap.run(
        "feature_extractor",
        &args,
        &logs.join("feature_extractor.log"),
        deadline,
        &mut |line| {
            counts.line(line);
            if let Some((i, n)) = progress_in(line, "Processed file") {
                progress(Progress {
                    stage: "features",
                    done: i,
                    total: n,
                });
            }
        },
    )?;
    let mut by_count = counts.by_name.clone();
    by_count.sort_by_key(|(_, n)| *n);
    let median_features = by_count.get(by_count.len() / 2).map_or(0, |(_, n)| *n);
    if median_features < MIN_FEATURES {
        let fewest = by_count
            .iter()
            .take(3)
            .map(|(name, n)| format!("{name} ({n})"))
            .collect::<Vec<_>>()
            .join(", ");
        return Err(SfmError::TooLittleTexture {
            median: median_features,
            needed: MIN_FEATURES,
            fewest: if fewest.is_empty() {
                "every frame".into()
            } else {
                fewest
            },
        });
    }
    stage_seconds.insert("features".to_string(), secs(t));

    // 3. Matching: every pair for short clips, else each frame with its neighbours.
    let t = Instant::now();
    let n = job.frames.len();
    let (matcher, mut args) = if n <= 30 {
        ("exhaustive_matcher", vec![])
    } else {
        (
            "sequential_matcher",
            os(&[
                "--SequentialMatching.overlap",
                "10",
                "--SequentialMatching.quadratic_overlap",
                "1",
            ]),
        )
    };
    args.extend(os(&[
        "--database_path",
        path_str(&db).as_str(),
        "--SiftMatching.use_gpu",
        "0",
        "--SiftMatching.num_threads",
        &threads,
    ]));
    colmap.run(
        matcher,
        &args,
        &logs.join(format!("{matcher}.log")),
        deadline,
        &mut |line| {
            let p =
                progress_in(line, "Matching image").or_else(|| progress_in(line, "Matching block"));
            if let Some((i, n)) = p {
                progress(Progress {
                    stage: "matching",
                    done: i,
                    total: n,
                });
            }
        },
    )?;
    stage_seconds.insert("matching".to_string(), secs(t));

    // 4. Incremental mapping.
    let t = Instant::now();
    let sparse = work.join("sparse");
    if sparse.exists() {
        std::fs::remove_dir_all(&sparse).map_err(|e| SfmError::io(&sparse, e))?;
    }
    std::fs::create_dir_all(&sparse).map_err(|e| SfmError::io(&sparse, e))?;
    let flag = |b: bool| if b { "1" } else { "0" };
    let args = os(&[
        "--database_path",
        path_str(&db).as_str(),
        "--image_path",
        path_str(&job.image_dir).as_str(),
        "--output_path",
        path_str(&sparse).as_str(),
        "--Mapper.num_threads",
        &threads,
        "--Mapper.ba_refine_focal_length",
        flag(refine),
        "--Mapper.ba_refine_principal_point",
        "0",
        "--Mapper.ba_refine_extra_params",
        "0",
        "--Mapper.min_model_size",
        "3",
    ]);
    let mut registered = 0u64;
    let mut no_initial_pair = false;
    colmap.run(
        "mapper",
        &args,
        &logs.join("mapper.log"),
        deadline,
        &mut |line| {
            if line.contains("No good initial image pair found") {
                no_initial_pair = true;
            }
            if line.trim_start().starts_with("Registering image #") {
                registered += 1;
                progress(Progress {
                    stage: "mapping",
                    done: registered + 1,
                    total,
                });
            }
        },
    )?;
    stage_seconds.insert("mapping".to_string(), secs(t));

    // 5. The largest model, as text, read back.
    let t = Instant::now();
    let mut models: Vec<PathBuf> = std::fs::read_dir(&sparse)
        .map_err(|e| SfmError::io(&sparse, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    models.sort();
    if models.is_empty() {
        // COLMAP says "No good initial image pair found" and writes nothing.
        let _ = no_initial_pair;
        return Err(SfmError::NoInitialPair { median_features });
    }
    let mut best: Option<(PathBuf, CameraSet)> = None;
    for (i, m) in models.iter().enumerate() {
        let txt = work.join(format!("model_txt_{i}"));
        std::fs::create_dir_all(&txt).map_err(|e| SfmError::io(&txt, e))?;
        colmap.run(
            "model_converter",
            &os(&[
                "--input_path",
                path_str(m).as_str(),
                "--output_path",
                path_str(&txt).as_str(),
                "--output_type",
                "TXT",
            ]),
            &logs.join(format!("model_converter_{i}.log")),
            deadline,
            &mut |_| {},
        )?;
        let set = read_colmap(&txt)?;
        if best
            .as_ref()
            .is_none_or(|(_, b)| set.by_stem.len() > b.by_stem.len())
        {
            best = Some((txt, set));
        }
        progress(Progress {
            stage: "model",
            done: i as u64 + 1,
            total: models.len() as u64,
        });
    }
    let Some((model_dir, set)) = best else {
        return Err(SfmError::NoInitialPair { median_features });
    };
    let missing: Vec<String> = keyframes
        .iter()
        .filter(|f| !set.by_stem.contains_key(&f.stem))
        .map(|f| f.file_name.clone())
        .collect();
    if !missing.is_empty() {
        return Err(SfmError::TooFewRegistered {
            registered: set.by_stem.len(),
            total: job.frames.len(),
            missing_keyframes: missing,
        });
    }
    let points = read_colmap_points(&model_dir)?;
    let first = &set.by_stem[&keyframes[0].stem];
    let k = first.intrinsics;
    let camera0 = PinholeCamera::new(k[0], k[1], k[2], k[3], w, h)
        .map_err(|e| SfmError::Input(format!("the estimated intrinsics are invalid: {e}")))?;
    let xyz: Vec<[f64; 3]> = points.iter().map(|p| p.xyz).collect();
    let depth = gauge::median_depth(&camera0, &first.world_from_camera, &xyz)
        .filter(|d| *d > 0.0)
        .ok_or(SfmError::NoInitialPair { median_features })?;
    let c0 = first.world_from_camera.translation.vector;
    let baseline = set
        .by_stem
        .values()
        .map(|c| (c.world_from_camera.translation.vector - c0).norm())
        .fold(0.0, f64::max);
    let baseline_over_depth = baseline / depth;
    if baseline_over_depth < PURE_ROTATION_RATIO {
        return Err(SfmError::PureRotation {
            baseline_ratio: baseline_over_depth,
            threshold: PURE_ROTATION_RATIO,
        });
    }
    let target = job.background_depth_m.unwrap_or(1.0);
    let g = gauge::to_first_camera(&first.world_from_camera, depth, target);
    let mut cameras = CameraSet {
        by_stem: BTreeMap::new(),
        warnings: set.warnings.clone(),
    };
    for (stem, c) in &set.by_stem {
        cameras.by_stem.insert(
            stem.clone(),
            SourceCamera {
                intrinsics: c.intrinsics,
                size: c.size,
                world_from_camera: g.apply_camera(&c.world_from_camera),
            },
        );
    }
    let unregistered_frames: Vec<String> = job
        .frames
        .iter()
        .filter(|f| !set.by_stem.contains_key(&f.stem))
        .map(|f| f.file_name.clone())
        .collect();
    stage_seconds.insert("model".to_string(), secs(t));
    let metres = job.background_depth_m.is_some();
    let report = SfmReport {
        tool: colmap.version.clone(),
        matcher: matcher.to_string(),
        frames_used: job.frames.len(),
        frames_registered: set.by_stem.len(),
        keyframes: keyframes.len(),
        unregistered_frames,
        features_per_frame_median: median_features,
        intrinsics: IntrinsicsReport {
            source: match &job.intrinsics {
                Intrinsics::Given(_) => "given".into(),
                Intrinsics::Prior { source, .. } => source.clone(),
                Intrinsics::Estimate => "estimated".into(),
            },
            fx: k[0],
            fy: k[1],
            cx: k[2],
            cy: k[3],
            refined: refine,
            model: model.into(),
        },
        points: points.len(),
        mean_reprojection_error_px: mean(points.iter().map(|p| p.error_px)),
        mean_track_length: mean(points.iter().map(|p| p.track_len as f64)),
        baseline_over_depth,
        gauge: GaugeReport {
            origin_frame: keyframes[0].file_name.clone(),
            unit: if metres {
                "metres".into()
            } else {
                "median background depth".into()
            },
            median_background_depth: target,
            scale_from_colmap: g.scale,
            meaning: if metres {
                format!("world = the camera frame of {} (OpenCV axes); translations in metres, from the background depth you gave ({target} m), as good as that measurement", keyframes[0].file_name)
            } else {
                format!("world = the camera frame of {} (OpenCV axes); one unit of translation = the median depth of the background that frame sees. Rotations are exact; camera translations are right up to one unknown scale factor, so they are not in metres: the object's metric scale does not follow from them (give --background-depth-m, or fix the scale from the object)", keyframes[0].file_name)
            },
        },
        stage_seconds,
    };
    let report_path = work.join("report.json");
    let text = serde_json::to_string_pretty(&report)
        .map_err(|e| SfmError::Input(format!("report: {e}")))?;
    std::fs::write(&report_path, text).map_err(|e| SfmError::io(&report_path, e))?;
    let keep_dir = work.join("keep");
    std::fs::create_dir_all(&keep_dir).map_err(|e| SfmError::io(&keep_dir, e))?;
    let mut keep: Vec<PathBuf> = vec![report_path];
    for name in ["cameras.txt", "images.txt", "points3D.txt"] {
        keep.push(model_dir.join(name));
    }
    for entry in std::fs::read_dir(&logs).map_err(|e| SfmError::io(&logs, e))? {
        keep.push(entry.map_err(|e| SfmError::io(&logs, e))?.path());
    }
    for src in keep {
        if let Some(name) = src.file_name() {
            std::fs::copy(&src, keep_dir.join(name)).map_err(|e| SfmError::io(&src, e))?;
        }
    }
    Ok(SfmOutcome {
        cameras,
        report,
        keep_dir,
    })
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

fn os(args: &[&str]) -> Vec<OsString> {
    args.iter().map(OsString::from).collect()
}

fn path_str(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}
