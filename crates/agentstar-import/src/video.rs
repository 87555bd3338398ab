//! A capture from a video (frames extracted by the `ffmpeg` command) or a folder of frames,
//! masks from any segmenter's output folder, and cameras from COLMAP, nerfstudio or one
//! static pinhole camera.
//!
//! Frames keep their numbers: a video's frames are named by their index in the video, and a
//! folder whose file stems are all integers (`000120.jpg`) keeps them (stems, `frame_index`,
//! `time_s = number / fps`); other names are numbered 0, 1, 2, … in natural order, with a note.
//! Masks (and hand masks) are matched to frames by file stem only ([`MaskFolder`]): a frame
//! without its own object mask is an error; one without a hand mask shows no hands.

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
    /// Keep the frames between keyframes too (`formats.md` §2, in-between frames), every
    /// N-th from each keyframe (1: every frame); `None`: keyframes only.
    pub between: Option<usize>,
}

const IMAGE_EXTS: [&str; 6] = ["png", "jpg", "jpeg", "bmp", "tif", "tiff"];

/// The image files of a folder in natural order (by the number in the stem when every stem has
/// one, else by name).
pub fn images_in(dir: &Path) -> Result<Vec<PathBuf>> {
    if !dir.is_dir() {
        return Err(DataError::invalid(dir, "no such folder"));
    }
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

/// The frame number a file stem states: the whole stem when it is an integer (`000120`).
pub fn stem_number(stem: &str) -> Option<u64> {
    if stem.is_empty() || !stem.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    stem.parse().ok()
}

/// What may follow a frame's stem in a mask's name (`000120_mask.png`).
const SEPARATORS: [char; 3] = ['_', '-', '.'];

/// Frames numbered past this are refused (their times and indices would lose precision).
const MAX_FRAME_NUMBER: u64 = 1 << 40;

/// How long `ffmpeg` may take to extract a video's frames.
const EXTRACT_LIMIT: std::time::Duration = std::time::Duration::from_secs(30 * 60);

/// Extracts every frame of a video with ffmpeg into `dir` as PNGs (stopped past
/// [`EXTRACT_LIMIT`]).
fn extract(video: &Path, dir: &Path) -> Result<()> {
    let out = crate::process::output_within(
        std::process::Command::new("ffmpeg")
            .args(["-v", "error", "-nostdin", "-i"])
            .arg(video)
            .args(["-start_number", "0"])
            .arg(dir.join("%06d.png")),
        EXTRACT_LIMIT,
    )
    .map_err(|e| {
        DataError::invalid(
            video,
            if e.kind() == std::io::ErrorKind::TimedOut {
                format!("ffmpeg extracting the frames {e}; extract them yourself and pass their folder")
            } else {
                format!(
                    "cannot run ffmpeg ({e}); install it (for example `apt install ffmpeg`) or extract the frames yourself and pass their folder"
                )
            },
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

/// How a capture's frames got their numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Numbering {
    /// Every file stem is an integer (a video's frames are named by their index): kept.
    Stems,
    /// Some stem is not an integer: frames are numbered 0, 1, 2, … in natural order, taken
    /// as consecutive video frames.
    Order,
}

/// The frames of a video (extracted by ffmpeg into a temporary folder that lives as long as
/// this value) or of a frame folder, in temporal order, with their frame numbers.
#[derive(Debug)]
pub struct FrameFiles {
    _extracted: Option<tempfile::TempDir>,
    /// The folder holding the frames.
    pub dir: PathBuf,
    /// Every frame, in temporal order.
    pub paths: Vec<PathBuf>,
    /// Each frame's number (its index in the video): the integer file stem, or its position
    /// when the names are not all integers (see `numbering`). Strictly increasing.
    pub numbers: Vec<u64>,
    pub numbering: Numbering,
}

impl FrameFiles {
    /// Frames of `dir` (already listed in natural order by [`images_in`]) numbered by their
    /// stems when every stem is an integer, else by position. Two files with one frame number
    /// are an error naming both.
    pub fn numbered(dir: &Path, paths: Vec<PathBuf>) -> Result<Self> {
        let by_stem: Option<Vec<u64>> = paths.iter().map(|p| stem_number(&stem(p))).collect();
        let (numbers, numbering) = match by_stem {
            Some(n) => (n, Numbering::Stems),
            None => ((0..paths.len() as u64).collect(), Numbering::Order),
        };
        for (i, w) in numbers.windows(2).enumerate() {
            if w[0] == w[1] {
                return Err(DataError::invalid(
                    dir,
                    format!(
                        "{} and {} both name frame number {}; keep one of them",
                        paths[i].display(),
                        paths[i + 1].display(),
                        w[0]
                    ),
                ));
            }
        }
        if let Some(i) = numbers.iter().position(|&n| n > MAX_FRAME_NUMBER) {
            return Err(DataError::invalid(
                &paths[i],
                format!(
                    "frame number {} is too large (at most {MAX_FRAME_NUMBER}); name frames by their index in the video",
                    numbers[i]
                ),
            ));
        }
        Ok(FrameFiles {
            _extracted: None,
            dir: dir.to_path_buf(),
            paths,
            numbers,
            numbering,
        })
    }

    /// The positions (into `paths`) of the frames a capture keeps: every `every`-th frame
    /// present, from the first, at most `max_frames`.
    pub fn keyframe_indices(&self, every: usize, max_frames: Option<usize>) -> Vec<usize> {
        (0..self.paths.len())
            .step_by(every.max(1))
            .take(max_frames.unwrap_or(usize::MAX))
            .collect()
    }

    /// The positions of the in-between frames a capture keeps between consecutive
    /// `keyframes` (positions, ascending): every `stride`-th frame after each keyframe,
    /// before the next.
    pub fn between_indices(keyframes: &[usize], stride: usize) -> Vec<usize> {
        keyframes
            .windows(2)
            .flat_map(|w| ((w[0] + stride.max(1))..w[1]).step_by(stride.max(1)))
            .collect()
    }

    /// What a user should know about how the frames were numbered and subsampled, one line
    /// each (empty when nothing was assumed).
    pub fn notes(&self, every: usize) -> Vec<String> {
        let mut out = vec![];
        if self.numbering == Numbering::Order {
            let odd = self
                .paths
                .iter()
                .find(|p| stem_number(&stem(p)).is_none())
                .map(|p| p.display().to_string())
                .unwrap_or_default();
            out.push(format!(
                "the frame names in {} are not all integers (for example {odd}): the frames are numbered 0 to {} in natural order of their names and taken as consecutive video frames (time_s = number / fps); name frames by their frame number (000120.png) to keep their real times",
                self.dir.display(),
                self.paths.len().saturating_sub(1)
            ));
        }
        let contiguous = self.numbers.windows(2).all(|w| w[1] == w[0] + 1);
        if every > 1 && !contiguous {
            let kept: Vec<String> = self
                .keyframe_indices(every, Some(4))
                .iter()
                .map(|&i| self.numbers[i].to_string())
                .collect();
            out.push(format!(
                "--every {every} keeps every {every}th of the {} frames present (frame numbers {}, …), not every {every}th frame number: the folder skips frame numbers",
                self.paths.len(),
                kept.join(", ")
            ));
        }
        out
    }
}

/// The start of the name of the folder a process extracts a video's frames into (in the
/// system's temporary directory): `agentstar-frames-<host>-<pid>-`.
fn frame_folder_prefix(pid: u32) -> String {
    format!("agentstar-frames-{}-{pid}-", host_name())
}

fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().replace(['-', '/'], "_"))
        .unwrap_or_default()
}

/// Removes the frame folders in `root` of this host's processes that no longer run: an
/// import killed mid-extraction (`kill -9`) leaves every frame it had extracted. Best effort,
/// and only where `/proc` says which processes run; another host's folders (a shared
/// temporary directory) are left alone.
fn remove_stale_frame_folders(root: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let start = format!("agentstar-frames-{}-", host_name());
    let Ok(entries) = std::fs::read_dir(root) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(&start))
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        let dead = pid != std::process::id() && !Path::new("/proc").join(pid.to_string()).exists();
        if dead && entry.file_type().is_ok_and(|t| t.is_dir()) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Opens a video (extracting every frame with ffmpeg; frames are named by their index in the
/// video) or a folder of frames.
pub fn open_frames(input: &Path) -> Result<FrameFiles> {
    let (extracted, dir) = if input.is_dir() {
        (None, input.to_path_buf())
    } else if input.is_file() {
        let root = std::env::temp_dir();
        remove_stale_frame_folders(&root);
        let tmp = tempfile::Builder::new()
            .prefix(&frame_folder_prefix(std::process::id()))
            .tempdir_in(&root)
            .map_err(|e| DataError::io(&root, e))?;
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
    let mut frames = FrameFiles::numbered(&dir, paths)?;
    frames._extracted = extracted;
    Ok(frames)
}

/// A folder of masks (object or hand), matched to frames by file stem: the mask of frame
/// `000120.jpg` is `000120.*` or `000120_<anything>.*` (also `-` or `.` after the stem); when
/// the frame's stem is an integer, the mask's leading integer is compared as a number (so
/// `120.png` and `00120_mask.png` match too). A name without a separator (`000120`) is
/// preferred over one with a suffix. Nothing is matched by order.
#[derive(Debug, Clone)]
pub struct MaskFolder {
    pub dir: PathBuf,
    files: Vec<PathBuf>,
}

impl MaskFolder {
    pub fn open(dir: &Path) -> Result<Self> {
        Ok(MaskFolder {
            dir: dir.to_path_buf(),
            files: images_in(dir)?,
        })
    }

    /// The mask of each frame of `frames` (`None` where it has none). A frame with two
    /// equally good masks, or a mask that two frames claim, is an error naming them.
    pub fn assign(&self, frames: &FrameFiles) -> Result<Vec<Option<PathBuf>>> {
        use std::collections::HashMap;
        // Every name a mask answers to, with how well (2: exactly, 1: with a suffix).
        let mut by_number: HashMap<u64, Vec<(u8, usize)>> = HashMap::new();
        let mut by_stem: HashMap<&str, Vec<(u8, usize)>> = HashMap::new();
        let stems: Vec<String> = self.files.iter().map(|p| stem(p)).collect();
        for (i, m) in stems.iter().enumerate() {
            let digits = m.len() - m.trim_start_matches(|c: char| c.is_ascii_digit()).len();
            let (head, rest) = m.split_at(digits);
            if let Some(n) = stem_number(head) {
                if rest.is_empty() {
                    by_number.entry(n).or_default().push((2, i));
                } else if rest.starts_with(SEPARATORS) {
                    by_number.entry(n).or_default().push((1, i));
                }
            }
            by_stem.entry(m.as_str()).or_default().push((2, i));
            for (at, _) in m.match_indices(SEPARATORS) {
                by_stem.entry(&m[..at]).or_default().push((1, i));
            }
        }
        let mut out = Vec::with_capacity(frames.paths.len());
        let mut claimed: HashMap<usize, &Path> = HashMap::new();
        for frame in &frames.paths {
            let fs = stem(frame);
            let candidates = match stem_number(&fs) {
                Some(n) => by_number.get(&n),
                None => by_stem.get(fs.as_str()),
            };
            let Some(candidates) = candidates.filter(|c| !c.is_empty()) else {
                out.push(None);
                continue;
            };
            let best = candidates.iter().map(|c| c.0).max().unwrap_or(0);
            let found: Vec<usize> = candidates
                .iter()
                .filter(|c| c.0 == best)
                .map(|c| c.1)
                .collect();
            if found.len() > 1 {
                return Err(DataError::invalid(
                    &self.dir,
                    format!(
                        "frame {} has {} masks here ({}); keep one",
                        frame.display(),
                        found.len(),
                        found
                            .iter()
                            .map(|&i| self.files[i].display().to_string())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            }
            let m = found[0];
            if let Some(other) = claimed.insert(m, frame) {
                return Err(DataError::invalid(
                    &self.files[m],
                    format!(
                        "this mask matches two frames, {} and {}; masks are matched by file stem (the frame's name, or the frame's name then `_`, `-` or `.`)",
                        other.display(),
                        frame.display()
                    ),
                ));
            }
            out.push(Some(self.files[m].clone()));
        }
        Ok(out)
    }

    /// The masks of this folder that `assigned` (from [`MaskFolder::assign`]) gave to no
    /// frame.
    pub fn unmatched(&self, assigned: &[Option<PathBuf>]) -> Vec<PathBuf> {
        let used: std::collections::HashSet<&PathBuf> = assigned.iter().flatten().collect();
        self.files
            .iter()
            .filter(|p| !used.contains(p))
            .cloned()
            .collect()
    }

    /// The error for frame `frame` without a mask in this folder.
    pub fn missing(&self, frame: &Path) -> DataError {
        let s = stem(frame);
        DataError::invalid(
            &self.dir,
            format!(
                "no mask for frame {} (masks are matched by file stem: looked for {s}.* and {s}_*.*{}; {} image(s) here{})",
                frame.display(),
                if stem_number(&s).is_some() { ", the number compared as a number" } else { "" },
                self.files.len(),
                self.files
                    .first()
                    .map(|p| format!(", the first {}", p.display()))
                    .unwrap_or_default()
            ),
        )
    }
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
    let out = crate::process::output_within(
        std::process::Command::new("ffprobe")
            .args([
                "-v",
                "error",
                "-of",
                "json",
                "-show_entries",
                "format_tags:stream_tags",
            ])
            .arg(video),
        crate::process::PROBE_LIMIT,
    )
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

/// What an import wrote, and what a user should know about it.
#[derive(Debug, Clone, PartialEq)]
pub struct VideoSummary {
    /// The number of frames written.
    pub frames: usize,
    /// What was assumed (frame numbering, subsampling, frames without a hand mask), one line
    /// each, for the user.
    pub notes: Vec<String>,
}

/// Frames per second when none is given.
pub const DEFAULT_FPS: f64 = 30.0;
/// The lowest frame rate accepted (one frame in about 17 minutes).
pub const MIN_FPS: f64 = 0.001;
/// The highest frame rate accepted.
pub const MAX_FPS: f64 = 1000.0;

/// Refuses options that would write nonsense: a frame rate outside [MIN_FPS, MAX_FPS] or not
/// finite,
/// `every` 0, `max_frames` 0, an in-between stride that keeps nothing
/// ([`crate::between_stride_problem`]).
pub fn check_options(cfg: &VideoImport) -> Result<()> {
    if let Some(f) = cfg.fps {
        if !(f.is_finite() && (MIN_FPS..=MAX_FPS).contains(&f)) {
            return Err(DataError::invalid(
                &cfg.input,
                format!(
                    "fps {f:e}: frames per second must be a number from {MIN_FPS} to {MAX_FPS}"
                ),
            ));
        }
    }
    if cfg.every == 0 {
        return Err(DataError::invalid(
            &cfg.input,
            "every 0: keep every N-th frame, N at least 1",
        ));
    }
    if cfg.max_frames == Some(0) {
        return Err(DataError::invalid(
            &cfg.input,
            "max_frames 0: a capture needs at least one frame",
        ));
    }
    if let Some(problem) = crate::between_stride_problem(cfg.every, cfg.between) {
        return Err(DataError::invalid(&cfg.input, problem));
    }
    Ok(())
}

/// Writes the capture to `out` (a new directory).
pub fn import_video(cfg: &VideoImport, out: &Path) -> Result<VideoSummary> {
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
) -> Result<VideoSummary> {
    check_options(cfg)?;
    let all = &frames_in.paths;
    let keyframes = frames_in.keyframe_indices(cfg.every, cfg.max_frames);
    let between = cfg
        .between
        .map(|stride| FrameFiles::between_indices(&keyframes, stride))
        .unwrap_or_default();
    let mut keep: Vec<usize> = keyframes.iter().chain(&between).copied().collect();
    keep.sort_unstable();
    let mask_folder = MaskFolder::open(&cfg.masks)?;
    let masks = mask_folder.assign(frames_in)?;
    // Every kept frame needs its mask: the in-between frames' missing ones named together.
    let unmasked: Vec<String> = between
        .iter()
        .filter(|&&i| masks[i].is_none())
        .map(|&i| stem(&all[i]))
        .collect();
    if let Some(first) = unmasked.first() {
        return Err(DataError::invalid(
            &cfg.masks,
            format!(
                "{} of the {} in-between frames kept have no object mask ({}{}); every kept frame needs one: give masks for every frame, or keep fewer in-between frames (a larger --between stride), or none (masks are matched by file stem, for example {first}.png)",
                unmasked.len(),
                between.len(),
                unmasked.iter().take(8).cloned().collect::<Vec<_>>().join(", "),
                if unmasked.len() > 8 { ", …" } else { "" },
            ),
        ));
    }
    let hands = match &cfg.hands {
        Some(h) => {
            let folder = MaskFolder::open(h)?;
            let found = folder.assign(frames_in)?;
            let first = stem(&all[keep[0]]);
            if keep.iter().all(|&i| found[i].is_none()) {
                return Err(DataError::invalid(
                    h,
                    format!(
                        "no hand mask matches any of the {} frames kept (hand masks are matched by file stem like the object masks, for example {first}.png or {first}_hand.png)",
                        keep.len(),
                    ),
                ));
            }
            // Frames without a hand mask show no hands; but hand masks that name no frame
            // beside frames without one say that the names do not line up.
            let orphans = folder.unmatched(&found);
            if let (Some(orphan), Some(&bare)) =
                (orphans.first(), keep.iter().find(|&&i| found[i].is_none()))
            {
                return Err(DataError::invalid(
                    h,
                    format!(
                        "the hand masks' names do not line up with the frames: frame {} has no hand mask while {} matches no frame ({} such); hand masks are matched by file stem (for example {first}.png or {first}_hand.png)",
                        all[bare].display(),
                        orphan.display(),
                        orphans.len()
                    ),
                ));
            }
            Some(found)
        }
        None => None,
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
        number: u64,
        rgb: image::RgbImage,
        mask: agentstar_mask::BitMask,
        hand: Option<agentstar_mask::BitMask>,
        camera: PinholeCamera,
        c2w: Rigid,
    }
    let mut rows = vec![];
    let mut no_hands = vec![];
    for index in keep {
        let path = &all[index];
        let s = stem(path);
        let rgb = load_rgb(path)?;
        let (w, h) = rgb.dimensions();
        let number = frames_in.numbers[index];
        let name = format!("{number:06}.png");
        let mask_path = masks[index]
            .as_ref()
            .ok_or_else(|| mask_folder.missing(path))?;
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
        let hand = match &hands {
            Some(found) => match &found[index] {
                Some(p) => {
                    let hand = load_mask(p)?;
                    if (hand.width(), hand.height()) != (w, h) {
                        return Err(DataError::invalid(
                            p,
                            format!(
                                "hand mask is {}×{}, frame {} is {w}×{h}",
                                hand.width(),
                                hand.height(),
                                path.display()
                            ),
                        ));
                    }
                    Some(hand)
                }
                None => {
                    no_hands.push(name.clone());
                    None
                }
            },
            None => None,
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
            name,
            number,
            rgb,
            mask,
            hand,
            camera,
            c2w,
        });
    }
    let fps = cfg.fps.unwrap_or(DEFAULT_FPS);
    let frames: Vec<FrameOut<'_>> = rows
        .iter()
        .map(|r| FrameOut {
            name: &r.name,
            frame_index: Some(r.number as i64),
            time_s: Some(r.number as f64 / fps),
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
            "between": cfg.between,
            "fps": fps,
            "frame_numbers": match frames_in.numbering {
                Numbering::Stems => "the frame files' names (integers)".to_string(),
                Numbering::Order => format!("assumed: {}", frames_in.notes(1).join("; ")),
            },
            "frames_without_hand_mask": no_hands,
            "cameras": match &cfg.cameras {
                CameraSource::Given { note, .. } => note.clone(),
                other => serde_json::Value::String(format!("{other:?}")),
            },
            "camera_warnings": cams.map(|c| c.warnings).unwrap_or_default()}),
        ),
        keyframes: (!between.is_empty()).then(|| {
            keyframes
                .iter()
                .map(|&i| format!("{:06}.png", frames_in.numbers[i]))
                .collect()
        }),
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
    let mut notes = frames_in.notes(cfg.every);
    if let (Some(h), Some(first)) = (&cfg.hands, no_hands.first()) {
        notes.push(format!(
            "{} of the {} frames have no hand mask in {} (first: {first}); they are taken to show no hands",
            no_hands.len(),
            rows.len(),
            h.display()
        ));
    }
    Ok(VideoSummary {
        frames: rows.len(),
        notes,
    })
}

#[cfg(test)]
mod tests {

    /// What an import killed mid-extraction left is removed by the next one; a live
    /// process's folder and other names stay.
    #[test]
    fn frame_folders_of_dead_imports_are_removed() {
        let root = tempfile::tempdir().expect("tmp");
        // No process has this id (above the kernel's limit).
        let dead = root
            .path()
            .join(format!("{}Ab12Cd", frame_folder_prefix(999_999_999)));
        let live = root
            .path()
            .join(format!("{}Zz99Yy", frame_folder_prefix(std::process::id())));
        let other = root.path().join("agentstar-frames-elsewhere");
        for d in [&dead, &live, &other] {
            std::fs::create_dir(d).expect("dir");
            std::fs::write(d.join("000000.png"), b"frame").expect("frame");
        }
        remove_stale_frame_folders(root.path());
        if Path::new("/proc/self").exists() {
            assert!(!dead.exists(), "the dead import's frames are removed");
        }
        assert!(live.exists() && other.exists());
    }

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
