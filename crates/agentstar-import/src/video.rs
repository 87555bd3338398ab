//! A capture from a video (frames extracted by the `ffmpeg` command) or a folder of frames,
//! masks from any segmenter's output folder, and cameras from COLMAP, nerfstudio or one
//! static pinhole camera.
//!
//! Masks (and hand masks) are matched to frames by file stem (`000012.png` ↔ `000012.*` or
//! `000012_mask.*`), else by order when the folder holds exactly as many images as frames
//! before subsampling. Frames are numbered by their index in the video or folder.

use crate::cameras::{read_colmap, read_nerfstudio, rescaled, CameraSet};
use agentstar_data::capture_writer::{write_capture, CaptureInfo, FrameOut};
use agentstar_data::images::{load_mask, load_rgb};
use agentstar_data::{DataError, Result};
use agentstar_geom::pose::Rigid;
use agentstar_geom::PinholeCamera;
use std::path::{Path, PathBuf};

/// Where cameras come from.
#[derive(Debug, Clone)]
pub enum CameraSource {
    /// One pinhole camera for every frame, static: fx, fy, cx, cy in pixels of the frames.
    Static([f64; 4]),
    /// One static camera with this horizontal field of view (degrees), centred.
    Fov(f64),
    /// A COLMAP model directory (text or binary).
    Colmap(PathBuf),
    /// A nerfstudio `transforms.json`.
    Nerfstudio(PathBuf),
    /// Cameras already estimated (by structure from motion, `agentstar-sfm`), by frame stem,
    /// with a note of how, recorded in the capture's source.
    Given {
        cameras: CameraSet,
        note: serde_json::Value,
    },
}

#[derive(Debug, Clone)]
pub struct VideoImport {
    /// A video file or a folder of frames.
    pub input: PathBuf,
    pub masks: PathBuf,
    pub hands: Option<PathBuf>,
    pub every: usize,
    pub max_frames: Option<usize>,
    pub cameras: CameraSource,
    pub fps: Option<f64>,
}

const IMAGE_EXTS: [&str; 6] = ["png", "jpg", "jpeg", "bmp", "tif", "tiff"];

/// The image files of a folder in natural order (by the number in the stem when every stem has
/// one, else by name).
pub fn images_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| DataError::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| IMAGE_EXTS.contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    // Natural order: by the number in the stem when every stem has one, else by name.
    let num = |p: &Path| -> Option<u64> {
        let s = p.file_stem()?.to_str()?;
        let digits: String = s.chars().filter(|c| c.is_ascii_digit()).collect();
        digits.parse().ok()
    };
    if v.iter().all(|p| num(p).is_some()) {
        v.sort_by_key(|p| (num(p), p.clone()));
    } else {
        v.sort();
    }
    Ok(v)
}

/// A path's file stem (empty when it has none).
pub fn stem(p: &Path) -> String {
    p.file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("")
        .to_string()
}

/// Extracts every frame of a video with ffmpeg into `dir` as PNGs.
fn extract(video: &Path, dir: &Path) -> Result<()> {
    let out = std::process::Command::new("ffmpeg")
        .args(["-v", "error", "-nostdin", "-i"])
        .arg(video)
        .args(["-start_number", "0"])
        .arg(dir.join("%06d.png"))
        .output()
        .map_err(|e| {
            DataError::invalid(
                video,
                format!(
                    "cannot run ffmpeg ({e}); install it (for example `apt install ffmpeg`) or extract the frames yourself and pass their folder"
                ),
            )
        })?;
    if !out.status.success() {
        return Err(DataError::invalid(
            video,
            format!(
                "ffmpeg failed: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            ),
        ));
    }
    Ok(())
}

/// Finds the mask of frame `frame_stem` (position `index` among all frames) in `files`.
pub fn match_mask<'a>(
    files: &'a [PathBuf],
    frame_stem: &str,
    index: usize,
    total: usize,
) -> Option<&'a PathBuf> {
    files
        .iter()
        .find(|p| stem(p) == frame_stem)
        .or_else(|| {
            files.iter().find(|p| {
                let s = stem(p);
                s.starts_with(frame_stem) && s[frame_stem.len()..].starts_with(['_', '-', '.'])
            })
        })
        .or_else(|| (files.len() == total).then(|| &files[index]))
}

/// The frames of a video (extracted by ffmpeg into a temporary folder that lives as long as
/// this value) or of a frame folder, in natural order.
#[derive(Debug)]
pub struct FrameFiles {
    _extracted: Option<tempfile::TempDir>,
    /// The folder holding the frames.
    pub dir: PathBuf,
    /// Every frame, in order; a frame's index in the video is its position here.
    pub paths: Vec<PathBuf>,
}

impl FrameFiles {
    /// The indices of the frames a capture keeps: every `every`-th from the first, at most
    /// `max_frames`.
    pub fn keyframe_indices(&self, every: usize, max_frames: Option<usize>) -> Vec<usize> {
        (0..self.paths.len())
            .step_by(every.max(1))
            .take(max_frames.unwrap_or(usize::MAX))
            .collect()
    }
}

/// Opens a video (extracting every frame with ffmpeg) or a folder of frames.
pub fn open_frames(input: &Path) -> Result<FrameFiles> {
    let (extracted, dir) = if input.is_dir() {
        (None, input.to_path_buf())
    } else if input.is_file() {
        let tmp = tempfile::tempdir().map_err(|e| DataError::io(std::env::temp_dir(), e))?;
        extract(input, tmp.path())?;
        let dir = tmp.path().to_path_buf();
        (Some(tmp), dir)
    } else {
        return Err(DataError::invalid(
            input,
            "no such video file or frame folder",
        ));
    };
    let paths = images_in(&dir)?;
    if paths.is_empty() {
        return Err(DataError::invalid(
            &dir,
            "holds no frames (png, jpg, bmp, tif)",
        ));
    }
    Ok(FrameFiles {
        _extracted: extracted,
        dir,
        paths,
    })
}

/// The focal length in pixels that a video's metadata states, for frames `width` × `height`:
/// the 35 mm-equivalent focal length phones write (QuickTime
/// `com.apple.quicktime.camera.focal_length.35mm_equivalent`, or any tag naming a 35 mm
/// focal length), converted over the frame diagonal. `None` when ffprobe is missing, the file
/// is not a video, or no such tag exists.
pub fn video_focal_px(video: &Path, width: u32, height: u32) -> Option<f64> {
    if !video.is_file() {
        return None;
    }
    let out = std::process::Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-of",
            "json",
            "-show_entries",
            "format_tags:stream_tags",
        ])
        .arg(video)
        .stdin(std::process::Stdio::null())
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).ok()?;
    let mut tags: Vec<&serde_json::Map<String, serde_json::Value>> = vec![];
    if let Some(t) = v["format"]["tags"].as_object() {
        tags.push(t);
    }
    for s in v["streams"].as_array().into_iter().flatten() {
        if let Some(t) = s["tags"].as_object() {
            tags.push(t);
        }
    }
    focal_from_tags(&tags, width, height)
}

/// The 35 mm-equivalent focal length among metadata tags, in pixels of a `width` × `height`
/// frame (the 35 mm frame's diagonal is 43.27 mm).
fn focal_from_tags(
    tags: &[&serde_json::Map<String, serde_json::Value>],
    width: u32,
    height: u32,
) -> Option<f64> {
    let f35 = tags.iter().flat_map(|t| t.iter()).find_map(|(k, v)| {
        let k = k.to_ascii_lowercase();
        if !(k.contains("focal") && k.contains("35")) {
            return None;
        }
        let f = match v {
            serde_json::Value::Number(n) => n.as_f64(),
            serde_json::Value::String(s) => s.trim().trim_end_matches("mm").trim().parse().ok(),
            _ => None,
        }?;
        (f.is_finite() && (5.0..=500.0).contains(&f)).then_some(f)
    })?;
    let diagonal_px = (width as f64).hypot(height as f64);
    Some(f35 * diagonal_px / 43.27)
}

/// Writes the capture to `out` (a new directory); returns the number of frames.
pub fn import_video(cfg: &VideoImport, out: &Path) -> Result<usize> {
    let frames = open_frames(&cfg.input)?;
    import_video_frames(cfg, &frames, out, None)
}

/// Writes the capture to `out` from frames already opened; `attach` is a folder whose files
/// are copied into the capture under `sfm/` (structure-from-motion logs and model).
pub fn import_video_frames(
    cfg: &VideoImport,
    frames_in: &FrameFiles,
    out: &Path,
    attach: Option<&Path>,
) -> Result<usize> {
    let all = &frames_in.paths;
    let masks = images_in(&cfg.masks)?;
    let hands = match &cfg.hands {
        Some(h) => images_in(h)?,
        None => vec![],
    };
    // A camera set read from a file, or the static source itself.
    let cams: Option<CameraSet> = match &cfg.cameras {
        CameraSource::Colmap(d) => Some(read_colmap(d)?),
        CameraSource::Nerfstudio(p) => Some(read_nerfstudio(p)?),
        CameraSource::Given { cameras, .. } => Some(cameras.clone()),
        CameraSource::Static(_) | CameraSource::Fov(_) => None,
    };
    struct Row {
        name: String,
        index: usize,
        rgb: image::RgbImage,
        mask: agentstar_mask::BitMask,
        hand: Option<agentstar_mask::BitMask>,
        camera: PinholeCamera,
        c2w: Rigid,
    }
    let mut rows = vec![];
    for index in frames_in.keyframe_indices(cfg.every, cfg.max_frames) {
        let path = &all[index];
        let s = stem(path);
        let rgb = load_rgb(path)?;
        let (w, h) = rgb.dimensions();
        let mask_path = match_mask(&masks, &s, index, all.len()).ok_or_else(|| {
            DataError::invalid(
                &cfg.masks,
                format!(
                    "no mask for frame {} (looked for {s}.* and {s}_*.*)",
                    path.display()
                ),
            )
        })?;
        let mask = load_mask(mask_path)?;
        if (mask.width(), mask.height()) != (w, h) {
            return Err(DataError::invalid(
                mask_path,
                format!(
                    "mask is {}×{}, frame {} is {w}×{h}",
                    mask.width(),
                    mask.height(),
                    path.display()
                ),
            ));
        }
        let hand = match match_mask(&hands, &s, index, all.len()) {
            Some(p) if cfg.hands.is_some() => Some(load_mask(p)?),
            _ => None,
        };
        let (camera, c2w) = match (&cams, &cfg.cameras) {
            (Some(set), _) => {
                let c = set.by_stem.get(&s).ok_or_else(|| {
                    DataError::invalid(path, format!("the camera source has no image named {s}.*"))
                })?;
                let k = rescaled(c.intrinsics, c.size, [w, h]);
                (
                    PinholeCamera::from_matrix(&k, w, h)
                        .map_err(|e| DataError::invalid(path, e.to_string()))?,
                    c.world_from_camera,
                )
            }
            (None, CameraSource::Fov(deg)) => {
                (PinholeCamera::with_fov(*deg, w, h), Rigid::identity())
            }
            (None, CameraSource::Static(k)) => (
                PinholeCamera::new(k[0], k[1], k[2], k[3], w, h)
                    .map_err(|e| DataError::invalid(path, e.to_string()))?,
                Rigid::identity(),
            ),
            (
                None,
                CameraSource::Colmap(_) | CameraSource::Nerfstudio(_) | CameraSource::Given { .. },
            ) => return Err(DataError::invalid(path, "no camera source was read")),
        };
        rows.push(Row {
            name: format!("{index:06}.png"),
            index,
            rgb,
            mask,
            hand,
            camera,
            c2w,
        });
    }
    let fps = cfg
        .fps
        .filter(|f| f.is_finite() && *f > 0.0)
        .unwrap_or(30.0);
    let frames: Vec<FrameOut<'_>> = rows
        .iter()
        .map(|r| FrameOut {
            name: &r.name,
            frame_index: Some(r.index as i64),
            time_s: Some(r.index as f64 / fps),
            camera: &r.camera,
            world_from_camera: &r.c2w,
            rgb: &r.rgb,
            mask: &r.mask,
            hand: r.hand.as_ref(),
            depth_m: None,
        })
        .collect();
    let info = CaptureInfo {
        dataset: None,
        source: Some(
            serde_json::json!({"producer": "agentstar capture from-video",
            "input": cfg.input, "masks": cfg.masks, "every": cfg.every,
            "cameras": match &cfg.cameras {
                CameraSource::Given { note, .. } => note.clone(),
                other => serde_json::Value::String(format!("{other:?}")),
            },
            "camera_warnings": cams.map(|c| c.warnings).unwrap_or_default()}),
        ),
    };
    write_capture(out, &frames, &info, |root| {
        let Some(src) = attach else { return Ok(()) };
        let dst = root.join("sfm");
        for entry in std::fs::read_dir(src).map_err(|e| DataError::io(src, e))? {
            let path = entry.map_err(|e| DataError::io(src, e))?.path();
            if let (true, Some(name)) = (path.is_file(), path.file_name()) {
                let bytes = agentstar_data::read_bytes(&path)?;
                agentstar_data::atomic::write_atomic(&dst.join(name), &bytes)?;
            }
        }
        Ok(())
    })?;
    Ok(rows.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_35mm_equivalent_focal_length_becomes_pixels_over_the_diagonal() {
        let tags: serde_json::Map<String, serde_json::Value> = serde_json::from_str(
            r#"{"com.apple.quicktime.camera.focal_length.35mm_equivalent": "26",
                "com.apple.quicktime.make": "Apple"}"#,
        )
        .expect("json");
        let f = focal_from_tags(&[&tags], 1920, 1080).expect("a focal length");
        // 26 mm on a 43.27 mm diagonal: 2202.9 px × 26 / 43.27.
        assert!((f - 26.0 * 1920f64.hypot(1080.0) / 43.27).abs() < 1e-9);
        assert!((1300.0..1340.0).contains(&f), "{f}");
        let none: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(r#"{"encoder": "Lavf", "focal": "abc"}"#).expect("json");
        assert_eq!(focal_from_tags(&[&none], 1920, 1080), None);
    }
}
