//! A capture from a video (frames extracted by the `ffmpeg` command) or a folder of frames,
//! masks from any segmenter's output folder, and cameras from COLMAP, nerfstudio or one
//! static pinhole camera.
//!
//! Masks (and hand masks) are matched to frames by file stem (`000012.png` ↔ `000012.*` or
//! `000012_mask.*`), else by order when the folder holds exactly as many images as frames
//! before subsampling. Frames are numbered by their index in the video or folder.

use crate::cameras::{read_colmap, read_nerfstudio, rescaled, CameraSet};
use crate::capture_writer::{write_capture, CaptureInfo, FrameOut};
use crate::images::{load_mask, load_rgb};
use crate::{DataError, Result};
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

fn images_in(dir: &Path) -> Result<Vec<PathBuf>> {
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

fn stem(p: &Path) -> String {
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
fn match_mask<'a>(
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

/// Writes the capture to `out` (a new directory); returns the number of frames.
pub fn import_video(cfg: &VideoImport, out: &Path) -> Result<usize> {
    let tmp;
    let frame_dir: &Path = if cfg.input.is_dir() {
        &cfg.input
    } else if cfg.input.is_file() {
        tmp = tempfile::tempdir().map_err(|e| DataError::io(std::env::temp_dir(), e))?;
        extract(&cfg.input, tmp.path())?;
        tmp.path()
    } else {
        return Err(DataError::invalid(
            &cfg.input,
            "no such video file or frame folder",
        ));
    };
    let all = images_in(frame_dir)?;
    if all.is_empty() {
        return Err(DataError::invalid(
            frame_dir,
            "holds no frames (png, jpg, bmp, tif)",
        ));
    }
    let masks = images_in(&cfg.masks)?;
    let hands = match &cfg.hands {
        Some(h) => images_in(h)?,
        None => vec![],
    };
    // A camera set read from a file, or the static source itself.
    let cams: Option<CameraSet> = match &cfg.cameras {
        CameraSource::Colmap(d) => Some(read_colmap(d)?),
        CameraSource::Nerfstudio(p) => Some(read_nerfstudio(p)?),
        CameraSource::Static(_) | CameraSource::Fov(_) => None,
    };
    struct Row {
        name: String,
        index: usize,
        rgb: image::RgbImage,
        mask: agentstar_render::BitMask,
        hand: Option<agentstar_render::BitMask>,
        camera: PinholeCamera,
        c2w: Rigid,
    }
    let mut rows = vec![];
    for (index, path) in all.iter().enumerate().step_by(cfg.every.max(1)) {
        if cfg.max_frames.is_some_and(|m| rows.len() >= m) {
            break;
        }
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
            (None, CameraSource::Colmap(_) | CameraSource::Nerfstudio(_)) => {
                return Err(DataError::invalid(path, "no camera source was read"))
            }
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
            "cameras": format!("{:?}", cfg.cameras),
            "camera_warnings": cams.map(|c| c.warnings).unwrap_or_default()}),
        ),
    };
    write_capture(out, &frames, &info, |_| Ok(()))?;
    Ok(rows.len())
}
