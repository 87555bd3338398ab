//! Writing a capture in the `capture/v1` layout: frames, object and hand masks, cameras,
//! keyframes, optional depth and the manifest. The whole directory is built beside its
//! destination and renamed into place, so a failure leaves nothing half-written.

use crate::capture::{Capture, Keyframe, Manifest, FORMAT};
use crate::images::{mask_to_gray, save_png_gray, save_png_rgb};
use crate::{DataError, Result};
use agentstar_geom::pose::Rigid;
use agentstar_geom::PinholeCamera;
use agentstar_mask::BitMask;
use image::RgbImage;
use std::path::Path;

/// One frame to write.
#[derive(Debug, Clone, Copy)]
pub struct FrameOut<'a> {
    /// File name in `frames/`, e.g. `000010.png` (its stem names the mask files).
    pub name: &'a str,
    pub frame_index: Option<i64>,
    pub time_s: Option<f64>,
    pub camera: &'a PinholeCamera,
    pub world_from_camera: &'a Rigid,
    pub rgb: &'a RgbImage,
    pub mask: &'a BitMask,
    pub hand: Option<&'a BitMask>,
    /// Planar depth in metres, row-major; NaN where invalid.
    pub depth_m: Option<&'a [f32]>,
}

/// What the manifest says about where the capture comes from.
#[derive(Debug, Clone, Default)]
pub struct CaptureInfo {
    pub dataset: Option<String>,
    pub source: Option<serde_json::Value>,
    /// The names of the keyframes when the capture also keeps in-between frames
    /// (`formats.md` §2); `None`: every frame written is a keyframe.
    pub keyframes: Option<Vec<String>>,
}

/// A camera's `c2w` (row-major 4×4) and intrinsics (row-major 3×3) as `tracking/cameras.npz`
/// stores them: float32, as the format says.
fn stored_camera_rows(camera: &PinholeCamera, world_from_camera: &Rigid) -> ([f32; 16], [f32; 9]) {
    let m = world_from_camera.to_homogeneous();
    let k = camera.matrix();
    (
        std::array::from_fn(|i| m[(i / 4, i % 4)] as f32),
        std::array::from_fn(|i| k[(i / 3, i % 3)] as f32),
    )
}

/// The camera and its pose exactly as a reader of the written capture gets them: rounded to
/// float32 as [`write_capture`] stores them, then parsed as [`crate::capture`] parses them.
/// A benchmark that tracks in memory uses these so that it measures what `track` on the
/// written files gets (the search is sensitive to perturbations of 1e-7).
pub fn as_stored(
    camera: &PinholeCamera,
    world_from_camera: &Rigid,
) -> Result<(PinholeCamera, Rigid)> {
    let (c2w, k) = stored_camera_rows(camera, world_from_camera);
    let c2w = agentstar_geom::Matrix4::from_row_slice(&c2w.map(f64::from));
    let k = agentstar_geom::Matrix3::from_row_slice(&k.map(f64::from));
    let bad = |e: String| DataError::invalid(Path::new("tracking/cameras.npz"), e);
    let rigid = crate::capture::rigid_from_c2w(&c2w).map_err(bad)?;
    let camera = PinholeCamera::from_matrix(&k, camera.width, camera.height)
        .map_err(|e| bad(e.to_string()))?;
    Ok((camera, rigid))
}

/// Writes a capture to `dir` (which must not exist yet, or be empty): every file goes into a
/// temporary sibling directory that is renamed to `dir` once complete. `extra` writes more
/// files (ground truth, a model) into the temporary directory before the rename.
pub fn write_capture(
    dir: &Path,
    frames: &[FrameOut<'_>],
    info: &CaptureInfo,
    extra: impl FnOnce(&Path) -> Result<()>,
) -> Result<()> {
    let first = frames
        .first()
        .ok_or_else(|| DataError::invalid(dir, "a capture needs at least one frame"))?;
    let (w, h) = (first.camera.width, first.camera.height);
    if dir.exists()
        && std::fs::read_dir(dir)
            .map_err(|e| DataError::io(dir, e))?
            .next()
            .is_some()
    {
        return Err(DataError::invalid(
            dir,
            "already exists and is not empty; choose a new directory",
        ));
    }
    let parent = dir.parent().filter(|p| !p.as_os_str().is_empty());
    let parent = parent.unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| DataError::io(parent, e))?;
    let tmp = tempfile::Builder::new()
        .prefix(".capture-")
        .tempdir_in(parent)
        .map_err(|e| DataError::io(parent, e))?;
    let root = tmp.path();
    let has_depth = frames.iter().any(|f| f.depth_m.is_some());
    let mut c2w = Vec::with_capacity(frames.len() * 16);
    let mut ks = Vec::with_capacity(frames.len() * 9);
    let mut keyframes = Vec::with_capacity(frames.len());
    for (view, f) in frames.iter().enumerate() {
        if (f.camera.width, f.camera.height) != (w, h) {
            return Err(DataError::invalid(
                dir,
                format!("frame {} has a different image size", f.name),
            ));
        }
        let stem = Path::new(f.name)
            .file_stem()
            .and_then(|s| s.to_str())
            .ok_or_else(|| DataError::invalid(dir, format!("bad frame name `{}`", f.name)))?;
        save_png_rgb(f.rgb, &root.join("frames").join(f.name))?;
        save_png_gray(
            &mask_to_gray(f.mask),
            &root.join("mask_object").join(format!("{stem}.png")),
        )?;
        if let Some(hand) = f.hand {
            save_png_gray(
                &mask_to_gray(hand),
                &root.join("mask_hand").join(format!("{stem}.png")),
            )?;
        }
        if let Some(depth) = f.depth_m {
            if depth.len() != (w * h) as usize {
                return Err(DataError::invalid(
                    dir,
                    format!(
                        "frame {}: depth has {} values for {w}×{h}",
                        f.name,
                        depth.len()
                    ),
                ));
            }
            let mut local = Vec::with_capacity(depth.len() * 3);
            let mut conf = Vec::with_capacity(depth.len());
            for (k, &z) in depth.iter().enumerate() {
                let (x, y) = ((k as u32 % w) as f64 + 0.5, (k as u32 / w) as f64 + 0.5);
                let d = f.camera.ray_direction(x, y) * z as f64;
                local.extend([d.x as f32, d.y as f32, z]);
                conf.push(if z.is_finite() { 1.0 } else { 0.0 });
            }
            crate::npz::write_arrays(
                &root.join("depth").join(format!("{stem}.npz")),
                &[
                    ("local", &[h as usize, w as usize, 3], &local),
                    ("conf", &[h as usize, w as usize], &conf),
                ],
                &[],
            )?;
        }
        let (c2w_rows, k_rows) = stored_camera_rows(f.camera, f.world_from_camera);
        c2w.extend(c2w_rows);
        ks.extend(k_rows);
        keyframes.push(Keyframe {
            view,
            frame_index: f.frame_index,
            frame_name: f.name.to_string(),
            time_s: f.time_s,
        });
    }
    let n = frames.len();
    crate::npz::write_arrays(
        &root.join("tracking/cameras.npz"),
        &[("c2w", &[n, 4, 4], &c2w), ("intrinsics", &[n, 3, 3], &ks)],
        &[("size", &[2], &[w as i64, h as i64])],
    )?;
    crate::atomic::write_json(&root.join("tracking/keyframes.json"), &keyframes)?;
    let manifest = Manifest {
        format: FORMAT.into(),
        image_size: [w, h],
        frames: frames.iter().map(|f| f.name.to_string()).collect(),
        ref_frame: Some(
            info.keyframes
                .as_ref()
                .and_then(|k| k.first().cloned())
                .unwrap_or_else(|| first.name.to_string()),
        ),
        depth: if has_depth {
            "rendered".into()
        } else {
            "none".into()
        },
        depth_scale: None,
        dataset: info.dataset.clone(),
        source: info.source.clone(),
        downscale: Some(1.0),
        undistorted: Some(true),
        keyframes: info.keyframes.clone(),
    };
    crate::atomic::write_json(&Capture::manifest_path(root), &manifest)?;
    let problems = Capture::validate(root);
    if !problems.is_empty() {
        let list: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
        return Err(DataError::invalid(
            dir,
            format!("the written capture does not validate: {}", list.join("; ")),
        ));
    }
    extra(root)?;
    if dir.exists() {
        std::fs::remove_dir(dir).map_err(|e| DataError::io(dir, e))?;
    }
    let kept = tmp.keep();
    std::fs::rename(&kept, dir).map_err(|e| {
        let _ = std::fs::remove_dir_all(&kept);
        DataError::io(dir, e)
    })
}
