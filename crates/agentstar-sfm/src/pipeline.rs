//! The run: checks, features, matching and mapping on a strided subset, registration of the
//! other frames that need a camera, and the model read back in the gauge.

use crate::colmap::{nvidia_device_present, progress_in, Colmap, FeatureCounts};
use crate::{
    checks, gauge, mean, os, path_str, plan, FrameRole, GaugeReport, GpuUse, Intrinsics,
    IntrinsicsReport, Progress, SfmError, SfmFrame, SfmJob, SfmOutcome, SfmReport, MIN_FEATURES,
    PURE_ROTATION_RATIO, STATIC_CAMERA_RATIO,
};
use agentstar_geom::PinholeCamera;
use agentstar_import::cameras::{read_colmap, read_colmap_points, CameraSet, SourceCamera};
use std::collections::{BTreeMap, BTreeSet};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Pairs matched by one `matches_importer` run: small enough for progress every few seconds.
const PAIRS_PER_RUN: usize = 150;
/// The initial pair's least triangulation angle of each run of COLMAP's mapper on the subset
/// (None: COLMAP's 16°): another run follows one whose largest model holds under half of the
/// subset. Frames strided from a short hand-held video may hold too little parallax for 16°,
/// and which pairs COLMAP's matching leaves as planar or panoramic (no use for triangulation)
/// is an unseeded draw: in 1 run of 4 of the registration test's clip (2026-12-05) the mapper
/// placed 5 of 12 frames from a database where 8° placed all 12; the others placed all 12
/// at 16°.
const MAPPING_INIT_ANGLES_DEG: [Option<f64>; 3] = [None, Some(8.0), Some(4.0)];
const MAPPING_TRIES: usize = MAPPING_INIT_ANGLES_DEG.len();

fn secs(t: Instant) -> f64 {
    (t.elapsed().as_secs_f64() * 1000.0).round() / 1000.0
}

/// One run's fixed context: COLMAP, the folders, the deadline, the threads.
struct Run<'a> {
    colmap: Colmap,
    job: &'a SfmJob,
    db: PathBuf,
    logs: PathBuf,
    deadline: Instant,
    threads: String,
    gpu: bool,
}

impl Run<'_> {
    /// Runs one COLMAP command as part of `stage`, its time-out named by the stage.
    fn colmap(
        &self,
        stage: &str,
        command: &str,
        args: &[OsString],
        log_name: &str,
        on_line: &mut dyn FnMut(&str),
    ) -> Result<(), SfmError> {
        self.colmap
            .run(
                command,
                args,
                &self.logs.join(log_name),
                self.deadline,
                on_line,
            )
            .map_err(|e| e.in_stage(stage, self.job.time_limit))
    }

    /// The database, the frames' folder and the list of frames a command works on.
    fn database_and_images(&self, list: &Path) -> Vec<OsString> {
        os(&[
            "--database_path",
            path_str(&self.db).as_str(),
            "--image_path",
            path_str(&self.job.image_dir).as_str(),
            "--image_list_path",
            path_str(list).as_str(),
        ])
    }

    /// Matches `pairs` (positions into the job's frames) with `matches_importer`, in runs of
    /// at most [`PAIRS_PER_RUN`], reporting progress under `stage`.
    fn match_pairs(
        &self,
        stage: &'static str,
        pairs: &[(usize, usize)],
        progress: &mut dyn FnMut(Progress),
    ) -> Result<(), SfmError> {
        let total = pairs.len() as u64;
        let work = &self.job.work_dir;
        for (run, chunk) in pairs.chunks(PAIRS_PER_RUN).enumerate() {
            let list = work.join(format!("pairs_{stage}_{run}.txt"));
            let text: String = chunk
                .iter()
                .map(|&(a, b)| {
                    format!(
                        "{} {}\n",
                        self.job.frames[a].file_name, self.job.frames[b].file_name
                    )
                })
                .collect();
            std::fs::write(&list, text).map_err(|e| SfmError::io(&list, e))?;
            let use_gpu = if self.gpu { "1" } else { "0" };
            let args = os(&[
                "--database_path",
                path_str(&self.db).as_str(),
                "--match_list_path",
                path_str(&list).as_str(),
                "--match_type",
                "pairs",
                "--SiftMatching.use_gpu",
                use_gpu,
                "--SiftMatching.num_threads",
                &self.threads,
            ]);
            self.colmap(
                stage,
                "matches_importer",
                &args,
                &format!("matches_{stage}_{run}.log"),
                &mut |_| {},
            )?;
            progress(Progress {
                stage,
                done: ((run + 1) * PAIRS_PER_RUN).min(pairs.len()) as u64,
                total,
            });
        }
        Ok(())
    }

    /// Converts a binary model to text in `txt` and reads its cameras.
    fn to_text(&self, stage: &str, model: &Path, txt: &Path) -> Result<CameraSet, SfmError> {
        std::fs::create_dir_all(txt).map_err(|e| SfmError::io(txt, e))?;
        let name = txt
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "model".into());
        self.colmap(
            stage,
            "model_converter",
            &os(&[
                "--input_path",
                path_str(model).as_str(),
                "--output_path",
                path_str(txt).as_str(),
                "--output_type",
                "TXT",
            ]),
            &format!("model_converter_{name}.log"),
            &mut |_| {},
        )?;
        Ok(read_colmap(txt)?)
    }
}

/// Runs structure from motion on the job's frames: a strided subset reconstructed, the other
/// frames that need a camera registered against it.
pub fn estimate_cameras(
    job: &SfmJob,
    progress: &mut dyn FnMut(Progress),
) -> Result<SfmOutcome, SfmError> {
    let start = Instant::now();
    let deadline = start + job.time_limit;
    let keyframes: Vec<&SfmFrame> = job
        .frames
        .iter()
        .filter(|f| f.role == FrameRole::Keyframe)
        .collect();
    if keyframes.len() < 2 {
        return Err(SfmError::Input(format!(
            "structure from motion needs at least two keyframes, got {}",
            keyframes.len()
        )));
    }
    let settings = &job.settings;
    if settings.reconstruct_max < 2 || settings.max_features < 100 || settings.overlap < 1 {
        return Err(SfmError::Input(format!(
            "SfM settings: at least 2 frames to reconstruct from (got {}), 100 features per frame (got {}) and an overlap of 1 (got {})",
            settings.reconstruct_max, settings.max_features, settings.overlap
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
            .min(crate::colmap::PROBE_LIMIT),
    )?;
    let gpu = settings.gpu == GpuUse::Auto && colmap.cuda && nvidia_device_present();
    let work = &job.work_dir;
    let masks_dir = work.join("masks");
    std::fs::create_dir_all(&masks_dir).map_err(|e| SfmError::io(&masks_dir, e))?;
    let logs = work.join("logs");
    std::fs::create_dir_all(&logs).map_err(|e| SfmError::io(&logs, e))?;
    let run = Run {
        colmap,
        job,
        db: work.join("database.db"),
        logs: logs.clone(),
        deadline,
        threads: job
            .threads
            .map_or_else(|| "-1".to_string(), |n| n.max(1).to_string()),
        gpu,
    };
    let mut stage_seconds = BTreeMap::new();

    // The plan: a strided subset to reconstruct from; every frame that needs a camera is used.
    let subset: Vec<usize> = plan::stride_subset(job.frames.len(), settings.reconstruct_max);
    let needed: Vec<usize> = (0..job.frames.len())
        .filter(|&i| job.frames[i].role.needs_camera())
        .collect();
    let used: Vec<usize> = subset
        .iter()
        .chain(&needed)
        .copied()
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();

    // 1. Masks with a margin (SIFT's support reaches past the boundary), and the static check.
    let t = Instant::now();
    let margin = (w.max(h) / 100).max(3);
    let factor = checks::thumb_factor(w, h);
    let total = used.len() as u64;
    let mut first: Option<checks::Thumb> = None;
    let mut self_shift = None;
    let mut largest_change: f64 = 0.0;
    progress(Progress {
        stage: "checks",
        done: 0,
        total,
    });
    for (n, &i) in used.iter().enumerate() {
        let f = &job.frames[i];
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
            done: n as u64 + 1,
            total,
        });
        if Instant::now() > deadline {
            return Err(SfmError::TimedOut {
                stage: "checks".into(),
                command: "(none: reading the frames)".into(),
                limit_s: job.time_limit.as_secs_f64(),
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

    // 2. Features (SIFT, at most `max_features` a frame), masked, for every frame used.
    let t = Instant::now();
    let list = work.join("image_list.txt");
    let names: Vec<&str> = used
        .iter()
        .map(|&i| job.frames[i].file_name.as_str())
        .collect();
    std::fs::write(&list, names.join("\n") + "\n").map_err(|e| SfmError::io(&list, e))?;
    if run.db.exists() {
        std::fs::remove_file(&run.db).map_err(|e| SfmError::io(&run.db, e))?;
    }
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
    let max_features = settings.max_features.to_string();
    let first_octave = plan::first_octave(job.size);
    let first_octave_text = first_octave.to_string();
    let use_gpu = if gpu { "1" } else { "0" };
    let mut args = run.database_and_images(&list);
    args.extend(os(&[
        "--ImageReader.mask_path",
        path_str(&masks_dir).as_str(),
        "--ImageReader.camera_model",
        model,
        "--ImageReader.single_camera",
        "1",
        "--SiftExtraction.use_gpu",
        use_gpu,
        "--SiftExtraction.num_threads",
        &run.threads,
        "--SiftExtraction.max_num_features",
        &max_features,
        "--SiftExtraction.first_octave",
        &first_octave_text,
    ]));
    if let Some(p) = &params {
        args.extend(os(&["--ImageReader.camera_params", p]));
    }
    let mut counts = FeatureCounts::default();
    progress(Progress {
        stage: "features",
        done: 0,
        total,
    });
    run.colmap(
        "features",
        "feature_extractor",
        &args,
        "feature_extractor.log",
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

    // 3. Matching within the subset: neighbours, longer links, both ends.
    let t = Instant::now();
    let subset_pairs: Vec<(usize, usize)> = plan::subset_pairs(subset.len(), settings.overlap)
        .into_iter()
        .map(|(a, b)| (subset[a], subset[b]))
        .collect();
    progress(Progress {
        stage: "matching",
        done: 0,
        total: subset_pairs.len() as u64,
    });
    run.match_pairs("matching", &subset_pairs, progress)?;
    stage_seconds.insert("matching".to_string(), secs(t));

    // 4. Incremental mapping of the subset, tried again with a smaller initial triangulation
    // angle while the largest model holds under half of it ([`MAPPING_INIT_ANGLES_DEG`]).
    let t = Instant::now();
    let subset_list = work.join("subset_list.txt");
    let subset_names: Vec<&str> = subset
        .iter()
        .map(|&i| job.frames[i].file_name.as_str())
        .collect();
    std::fs::write(&subset_list, subset_names.join("\n") + "\n")
        .map_err(|e| SfmError::io(&subset_list, e))?;
    let mut best: Option<(PathBuf, PathBuf, CameraSet)> = None;
    let mut mapping_tries = 0;
    while mapping_tries < MAPPING_TRIES
        && best
            .as_ref()
            .is_none_or(|(_, _, b)| 2 * b.by_stem.len() < subset.len())
    {
        mapping_tries += 1;
        let tried = map_subset(
            &run,
            &subset_list,
            subset.len(),
            refine,
            mapping_tries,
            progress,
        )?;
        if let Some(m) = tried {
            if best
                .as_ref()
                .is_none_or(|(_, _, b)| m.2.by_stem.len() > b.by_stem.len())
            {
                best = Some(m);
            }
        }
    }
    let Some((model_bin, mut model_dir, mut set)) = best else {
        return Err(SfmError::NoInitialPair { median_features });
    };
    let placed_by_mapping = set.by_stem.len();
    stage_seconds.insert("mapping".to_string(), secs(t));

    // 5. Registration: every frame that needs a camera and has none, matched with its nearest
    // placed frames, then placed against the model's points.
    let t = Instant::now();
    let placed_positions: Vec<usize> = (0..job.frames.len())
        .filter(|&i| set.by_stem.contains_key(&job.frames[i].stem))
        .collect();
    let to_register: Vec<usize> = needed
        .iter()
        .copied()
        .filter(|&i| !set.by_stem.contains_key(&job.frames[i].stem))
        .collect();
    let mut registration_pairs = vec![];
    if !to_register.is_empty() && !placed_positions.is_empty() {
        registration_pairs = plan::registration_pairs(&placed_positions, &to_register);
        progress(Progress {
            stage: "registration",
            done: 0,
            total: to_register.len() as u64,
        });
        run.match_pairs("registration", &registration_pairs, &mut |p| {
            // Matching is the first half of the stage, placing the second.
            progress(Progress {
                stage: "registration",
                done: p.done * to_register.len() as u64 / (2 * p.total.max(1)),
                total: to_register.len() as u64,
            })
        })?;
        let registered_bin = work.join("registered");
        if registered_bin.exists() {
            std::fs::remove_dir_all(&registered_bin)
                .map_err(|e| SfmError::io(&registered_bin, e))?;
        }
        std::fs::create_dir_all(&registered_bin).map_err(|e| SfmError::io(&registered_bin, e))?;
        let args = os(&[
            "--database_path",
            path_str(&run.db).as_str(),
            "--input_path",
            path_str(&model_bin).as_str(),
            "--output_path",
            path_str(&registered_bin).as_str(),
            "--Mapper.num_threads",
            &run.threads,
            "--Mapper.ba_refine_focal_length",
            "0",
            "--Mapper.ba_refine_principal_point",
            "0",
            "--Mapper.ba_refine_extra_params",
            "0",
        ]);
        let half = to_register.len() as u64 / 2;
        let mut registered = 0u64;
        run.colmap(
            "registration",
            "image_registrator",
            &args,
            "image_registrator.log",
            &mut |line| {
                if line.trim_start().starts_with("Registering image #") {
                    registered += 1;
                    progress(Progress {
                        stage: "registration",
                        done: (half + registered / 2).min(to_register.len() as u64),
                        total: to_register.len() as u64,
                    });
                }
            },
        )?;
        let txt = work.join("model_txt_registered");
        set = run.to_text("registration", &registered_bin, &txt)?;
        model_dir = txt;
    }
    let placed_by_registration = set.by_stem.len().saturating_sub(placed_by_mapping);
    stage_seconds.insert("registration".to_string(), secs(t));

    // 6. The model in the gauge, checked.
    let t = Instant::now();
    progress(Progress {
        stage: "model",
        done: 0,
        total: 1,
    });
    let missing: Vec<String> = needed
        .iter()
        .map(|&i| &job.frames[i])
        .filter(|f| !set.by_stem.contains_key(&f.stem))
        .map(|f| f.file_name.clone())
        .collect();
    if !missing.is_empty() {
        return Err(SfmError::TooFewRegistered {
            registered: needed.len() - missing.len(),
            needed: needed.len(),
            missing,
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
    let unregistered_frames: Vec<String> = used
        .iter()
        .map(|&i| &job.frames[i])
        .filter(|f| !set.by_stem.contains_key(&f.stem))
        .map(|f| f.file_name.clone())
        .collect();
    stage_seconds.insert("model".to_string(), secs(t));
    progress(Progress {
        stage: "model",
        done: 1,
        total: 1,
    });
    let metres = job.background_depth_m.is_some();
    let origin = keyframes[0].file_name.clone();
    let report = SfmReport {
        tool: run.colmap.version.clone(),
        matcher: format!(
            "pairs of a strided subset of {} frames: each with its next {}, longer links up to {} frames of the subset, the first and last {} with each other; registered frames with their {} nearest placed frames on each side",
            subset.len(),
            settings.overlap,
            plan::LONG_LINKS_SPAN * settings.overlap,
            plan::LOOP_FRAMES,
            plan::REGISTER_NEIGHBOURS
        ),
        gpu,
        frames_used: used.len(),
        frames_registered: set.by_stem.len(),
        keyframes: keyframes.len(),
        frames_needing_cameras: needed.len(),
        frames_reconstructed: subset.len(),
        frames_placed_by_mapping: placed_by_mapping,
        mapping_tries,
        frames_placed_by_registration: placed_by_registration,
        pairs_matched: [subset_pairs.len(), registration_pairs.len()],
        max_features: settings.max_features,
        first_octave,
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
            origin_frame: origin.clone(),
            unit: if metres {
                "metres".into()
            } else {
                "median background depth".into()
            },
            median_background_depth: target,
            scale_from_colmap: g.scale,
            meaning: if metres {
                format!("world = the camera frame of {origin} (OpenCV axes); translations in metres, from the background depth you gave ({target} m), as good as that measurement")
            } else {
                format!("world = the camera frame of {origin} (OpenCV axes); one unit of translation = the median depth of the background that frame sees. Rotations are exact; camera translations are right up to one unknown scale factor, so they are not in metres: the object's metric scale does not follow from them (give --background-depth-m, or fix the scale from the object)")
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

/// One run of COLMAP's incremental mapper on the subset (try `attempt`, from 1): the largest
/// model it left (binary folder, text folder, cameras), or None where it found no initial pair.
fn map_subset(
    run: &Run<'_>,
    subset_list: &Path,
    subset_len: usize,
    refine: bool,
    attempt: usize,
    progress: &mut dyn FnMut(Progress),
) -> Result<Option<(PathBuf, PathBuf, CameraSet)>, SfmError> {
    let job = run.job;
    let work = &job.work_dir;
    let sparse = work.join(format!("sparse_{attempt}"));
    if sparse.exists() {
        std::fs::remove_dir_all(&sparse).map_err(|e| SfmError::io(&sparse, e))?;
    }
    std::fs::create_dir_all(&sparse).map_err(|e| SfmError::io(&sparse, e))?;
    let flag = |b: bool| if b { "1" } else { "0" };
    let mut args = run.database_and_images(subset_list);
    args.extend(os(&[
        "--output_path",
        path_str(&sparse).as_str(),
        "--Mapper.num_threads",
        &run.threads,
        "--Mapper.ba_refine_focal_length",
        flag(refine),
        "--Mapper.ba_refine_principal_point",
        "0",
        "--Mapper.ba_refine_extra_params",
        "0",
        "--Mapper.min_model_size",
        "3",
    ]));
    if let Some(angle_deg) = MAPPING_INIT_ANGLES_DEG[attempt - 1] {
        args.extend(os(&["--Mapper.init_min_tri_angle", &angle_deg.to_string()]));
    }
    let mapping_total = subset_len as u64;
    let mut placed = 0u64;
    progress(Progress {
        stage: "mapping",
        done: 0,
        total: mapping_total,
    });
    let log = if attempt == 1 {
        "mapper.log".to_string()
    } else {
        format!("mapper_try{attempt}.log")
    };
    run.colmap("mapping", "mapper", &args, &log, &mut |line| {
        if line.trim_start().starts_with("Registering image #") {
            placed += 1;
            progress(Progress {
                stage: "mapping",
                done: (placed + 1).min(mapping_total),
                total: mapping_total,
            });
        }
    })?;
    // The largest model, as text, read back.
    let mut models: Vec<PathBuf> = std::fs::read_dir(&sparse)
        .map_err(|e| SfmError::io(&sparse, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    models.sort();
    // COLMAP says "No good initial image pair found" and writes nothing.
    let mut best: Option<(PathBuf, PathBuf, CameraSet)> = None;
    for (i, m) in models.iter().enumerate() {
        let txt = work.join(format!("model_txt_{attempt}_{i}"));
        let set = run.to_text("mapping", m, &txt)?;
        if best
            .as_ref()
            .is_none_or(|(_, _, b)| set.by_stem.len() > b.by_stem.len())
        {
            best = Some((m.clone(), txt, set));
        }
    }
    Ok(best)
}
