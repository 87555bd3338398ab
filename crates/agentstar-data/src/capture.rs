//! Captures in the `capture/v1` layout (`formats.md` §2): reading, and validation that
//! reports every problem at once with the file it concerns.

use crate::images::{image_size, load_mask, load_rgb};
use crate::npz::read_arrays;
use crate::{read_text, DataError, Result};
use agentstar_geom::pose::{rigid_from_matrix, Rigid};
use agentstar_geom::{Matrix3, Matrix4, PinholeCamera};
use agentstar_mask::{BitMask, DepthObservation};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const FORMAT: &str = "capture/v1";

/// `capture.json`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    pub format: String,
    pub image_size: [u32; 2],
    pub frames: Vec<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ref_frame: Option<String>,
    #[serde(default = "default_depth")]
    pub depth: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_scale: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<serde_json::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub downscale: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub undistorted: Option<bool>,
    /// The frames that are tracked, scored, evaluated and shown (names or stems of entries of
    /// `frames`); the others are in-between frames. Absent: every frame is a keyframe.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keyframes: Option<Vec<String>>,
}

fn default_depth() -> String {
    "none".into()
}

/// One row of `tracking/keyframes.json`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Keyframe {
    pub view: usize,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_index: Option<i64>,
    pub frame_name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_s: Option<f64>,
}

/// `tracking/cameras.json`: the same keys as `cameras.npz`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CamerasJson {
    pub c2w: Vec<[[f64; 4]; 4]>,
    pub intrinsics: Vec<[[f64; 3]; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<[u32; 2]>,
}

/// A frame of a capture, in temporal order.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The key used everywhere (`"000010.jpg"`).
    pub name: String,
    pub stem: String,
    /// The integer stem, which orders frames in time.
    pub number: u64,
    pub camera: PinholeCamera,
    pub world_from_camera: Rigid,
    pub time_s: Option<f64>,
}

/// A frame of the video (key or in-between) with its index among the keyframes.
#[derive(Debug, Clone, Copy)]
pub struct VideoFrame<'a> {
    pub frame: &'a Frame,
    /// Index into [`Capture::frames`] for a keyframe; `None` for an in-between frame.
    pub keyframe: Option<usize>,
}

/// An opened, validated capture.
#[derive(Debug, Clone)]
pub struct Capture {
    pub dir: PathBuf,
    pub manifest: Manifest,
    /// The keyframes, in temporal order: what every keyframe tool indexes.
    pub frames: Vec<Frame>,
    /// The in-between frames (`formats.md` §2), in temporal order; empty for a capture
    /// without the `keyframes` key. Never tracked, scored or evaluated as keyframes.
    pub between: Vec<Frame>,
    /// Index into `frames` of the reference frame.
    pub ref_index: usize,
    /// Non-fatal observations made while opening (shared camera, rescaled intrinsics…).
    pub notes: Vec<String>,
    /// Things that are probably wrong but do not stop the capture from being read (times
    /// that do not fit the frame numbers).
    pub warnings: Vec<String>,
}

/// A problem found in a capture.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Problem {
    pub path: PathBuf,
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

/// Every problem that keeps a capture from opening, with the capture's directory: one error
/// that every caller prints the same way ([`std::fmt::Display`]: all of them, one a line;
/// [`CaptureProblems::brief`]: one line naming the first few).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CaptureProblems {
    pub dir: PathBuf,
    pub problems: Vec<Problem>,
}

impl CaptureProblems {
    /// One line: how many problems, the first three, and the command that lists them all.
    pub fn brief(&self) -> String {
        let first: Vec<String> = self
            .problems
            .iter()
            .take(3)
            .map(|p| p.to_string())
            .collect();
        format!(
            "{}: not a valid capture ({} problem(s); run `agentstar validate {}`): {}",
            self.dir.display(),
            self.problems.len(),
            self.dir.display(),
            first.join("; ")
        )
    }
}

impl std::ops::Deref for CaptureProblems {
    type Target = [Problem];
    fn deref(&self) -> &[Problem] {
        &self.problems
    }
}

impl std::fmt::Display for CaptureProblems {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the capture at {} has {} problem(s):",
            self.dir.display(),
            self.problems.len()
        )?;
        for p in &self.problems {
            write!(f, "\n  {p}")?;
        }
        Ok(())
    }
}

impl std::error::Error for CaptureProblems {}

struct Collector {
    problems: Vec<Problem>,
}

impl Collector {
    fn add(&mut self, path: &Path, message: impl Into<String>) {
        self.problems.push(Problem {
            path: path.to_path_buf(),
            message: message.into(),
        });
    }
}

/// Whether `name` names `frame`: its file name, its stem, or a file name with its stem.
fn named_by(frame: &Frame, name: &str) -> bool {
    frame.name == name || frame.stem == name || frame.stem == stem_of(name)
}

fn stem_of(name: &str) -> &str {
    Path::new(name)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(name)
}

impl Capture {
    pub fn manifest_path(dir: &Path) -> PathBuf {
        dir.join("capture.json")
    }
    pub fn frame_path(&self, i: usize) -> PathBuf {
        self.frame_file(&self.frames[i])
    }
    pub fn mask_path(&self, i: usize) -> PathBuf {
        self.mask_file(&self.frames[i])
    }
    pub fn hand_path(&self, i: usize) -> PathBuf {
        self.hand_file(&self.frames[i])
    }
    /// The RGB file of any frame of the capture, key or in-between.
    pub fn frame_file(&self, frame: &Frame) -> PathBuf {
        self.dir.join("frames").join(&frame.name)
    }
    pub fn mask_file(&self, frame: &Frame) -> PathBuf {
        self.dir
            .join("mask_object")
            .join(format!("{}.png", frame.stem))
    }
    pub fn hand_file(&self, frame: &Frame) -> PathBuf {
        self.dir
            .join("mask_hand")
            .join(format!("{}.png", frame.stem))
    }
    /// Every frame, key or in-between, in temporal order, with its keyframe index.
    pub fn video(&self) -> Vec<VideoFrame<'_>> {
        let mut all: Vec<VideoFrame<'_>> = self
            .frames
            .iter()
            .enumerate()
            .map(|(k, frame)| VideoFrame {
                frame,
                keyframe: Some(k),
            })
            .chain(self.between.iter().map(|frame| VideoFrame {
                frame,
                keyframe: None,
            }))
            .collect();
        all.sort_by_key(|v| v.frame.number);
        all
    }
    /// The in-between frames strictly between keyframes `k` and `k + 1`, in temporal order
    /// (empty for the last keyframe or a capture without in-between frames).
    pub fn between_keyframes(&self, k: usize) -> Vec<&Frame> {
        let (Some(a), Some(b)) = (self.frames.get(k), self.frames.get(k + 1)) else {
            return vec![];
        };
        self.between
            .iter()
            .filter(|f| f.number > a.number && f.number < b.number)
            .collect()
    }
    /// One line for a keyframe tool's log when the capture has in-between frames: how many,
    /// and that the command works on the keyframes. `None` without in-between frames.
    pub fn between_note(&self) -> Option<String> {
        (!self.between.is_empty()).then(|| {
            format!(
                "{} holds {} in-between frame(s) besides its {} keyframes; this works on the keyframes",
                self.dir.display(),
                self.between.len(),
                self.frames.len()
            )
        })
    }
    pub fn width(&self) -> u32 {
        self.manifest.image_size[0]
    }
    pub fn height(&self) -> u32 {
        self.manifest.image_size[1]
    }
    pub fn frame_index(&self, name: &str) -> Option<usize> {
        self.frames.iter().position(|f| named_by(f, name))
    }

    /// The one frame grammar (`--frames`, the tools' `frames`, a sub-agent's window): `all`
    /// (or nothing), names (`000010.png`), stems (`000010`) or frame numbers, and inclusive
    /// ranges `a..b` of any of those, comma separated. Returns capture indices in temporal
    /// order without repeats; an unknown frame is an error that lists the frames.
    pub fn select(&self, spec: Option<&str>) -> Result<Vec<usize>, DataError> {
        let Some(spec) = spec.map(str::trim).filter(|s| !s.is_empty() && *s != "all") else {
            return Ok((0..self.frames.len()).collect());
        };
        let mut out = Vec::new();
        for tok in spec.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            if let Some((a, b)) = tok.split_once("..") {
                let (ia, ib) = (self.find_frame(a.trim())?, self.find_frame(b.trim())?);
                out.extend(ia.min(ib)..=ia.max(ib));
            } else {
                out.push(self.find_frame(tok)?);
            }
        }
        if out.is_empty() {
            return Err(DataError::Selection {
                dir: self.dir.clone(),
                message: format!(
                    "`{spec}` names no frame (use names, stems, `a..b` ranges or `all`)"
                ),
            });
        }
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }

    fn find_frame(&self, tok: &str) -> Result<usize, DataError> {
        if let Some(i) = self.frame_index(tok) {
            return Ok(i);
        }
        if let Ok(n) = tok.parse::<u64>() {
            if let Some(i) = self.frames.iter().position(|f| f.number == n) {
                return Ok(i);
            }
        }
        if let Some(b) = self
            .between
            .iter()
            .find(|f| named_by(f, tok) || tok.parse() == Ok(f.number))
        {
            // An in-between frame: the keyframe tools take keyframes only; name the two it lies
            // between, so the caller can pick one.
            let before = self.frames.iter().rev().find(|f| f.number < b.number);
            let after = self.frames.iter().find(|f| f.number > b.number);
            let around = match (before, after) {
                (Some(a), Some(c)) => format!("between keyframes {} and {}", a.name, c.name),
                (Some(a), None) => format!("after the last keyframe, {}", a.name),
                (None, Some(c)) => format!("before the first keyframe, {}", c.name),
                (None, None) => "in a capture without keyframes".to_string(),
            };
            return Err(DataError::Selection {
                dir: self.dir.clone(),
                message: format!(
                    "`{tok}` is an in-between frame ({}, {around}); this takes keyframes only (the capture has {} keyframes and {} in-between frames)",
                    b.name,
                    self.frames.len(),
                    self.between.len()
                ),
            });
        }
        let names: Vec<&str> = self.frames.iter().map(|f| f.name.as_str()).collect();
        let shown = if names.len() > 8 {
            format!(
                "{} … {}",
                names[..4].join(", "),
                names[names.len() - 2..].join(", ")
            )
        } else {
            names.join(", ")
        };
        Err(DataError::Selection {
            dir: self.dir.clone(),
            message: format!("unknown frame `{tok}`; frames are {shown} (use names, stems, `a..b` ranges or `all`)"),
        })
    }

    pub fn load_frame(&self, i: usize) -> Result<image::RgbImage> {
        self.load_frame_of(&self.frames[i])
    }
    pub fn load_mask(&self, i: usize) -> Result<BitMask> {
        self.load_mask_of(&self.frames[i])
    }
    /// The hand (don't-care) mask, when the capture has one for this frame.
    pub fn load_hand(&self, i: usize) -> Result<Option<BitMask>> {
        self.load_hand_of(&self.frames[i])
    }
    /// Observed depth for a frame, when the capture has depth and this frame has a file.
    pub fn load_depth(&self, i: usize) -> Result<Option<DepthObservation>> {
        self.load_depth_of(&self.frames[i])
    }
    /// The RGB image of any frame, key or in-between.
    pub fn load_frame_of(&self, frame: &Frame) -> Result<image::RgbImage> {
        let p = self.frame_file(frame);
        let img = load_rgb(&p)?;
        self.check_size(&p, img.width(), img.height())?;
        Ok(img)
    }
    pub fn load_mask_of(&self, frame: &Frame) -> Result<BitMask> {
        let p = self.mask_file(frame);
        let m = load_mask(&p)?;
        self.check_size(&p, m.width(), m.height())?;
        Ok(m)
    }
    pub fn load_hand_of(&self, frame: &Frame) -> Result<Option<BitMask>> {
        let p = self.hand_file(frame);
        if !p.is_file() {
            return Ok(None);
        }
        let m = load_mask(&p)?;
        self.check_size(&p, m.width(), m.height())?;
        Ok(Some(m))
    }
    fn check_size(&self, p: &Path, w: u32, h: u32) -> Result<()> {
        if [w, h] != self.manifest.image_size {
            return Err(DataError::invalid(
                p,
                format!(
                    "size {w}×{h} differs from image_size {}×{}",
                    self.width(),
                    self.height()
                ),
            ));
        }
        Ok(())
    }

    pub fn load_depth_of(&self, frame: &Frame) -> Result<Option<DepthObservation>> {
        if self.manifest.depth == "none" {
            return Ok(None);
        }
        let stem = &frame.stem;
        let npz = self.dir.join("depth").join(format!("{stem}.npz"));
        let png = self.dir.join("depth").join(format!("{stem}.png"));
        let (w, h) = (self.width(), self.height());
        if npz.exists() {
            return load_depth_npz(&npz, w, h).map(Some);
        }
        if png.is_file() {
            let scale = self.manifest.depth_scale.ok_or_else(|| {
                DataError::invalid(&png, "16-bit depth PNGs need `depth_scale` in capture.json")
            })?;
            let img = crate::images::decode_image(&png, "depth")?.to_luma16();
            self.check_size(&png, img.width(), img.height())?;
            let depth = img
                .pixels()
                .map(|p| {
                    if p[0] == 0 {
                        f32::NAN
                    } else {
                        (p[0] as f64 * scale) as f32
                    }
                })
                .collect();
            return Ok(Some(DepthObservation {
                width: w,
                height: h,
                depth,
                confidence: vec![1.0; (w * h) as usize],
            }));
        }
        Ok(None)
    }

    /// Opens and validates a capture; fails with every problem found.
    pub fn open(dir: &Path) -> std::result::Result<Capture, CaptureProblems> {
        let mut c = Collector { problems: vec![] };
        let cap = open_inner(dir, &mut c, true);
        match cap {
            Some(cap) if c.problems.is_empty() => Ok(cap),
            _ => {
                c.problems.sort();
                c.problems.dedup();
                Err(CaptureProblems {
                    dir: dir.to_path_buf(),
                    problems: c.problems,
                })
            }
        }
    }

    /// Every problem of a capture (empty when it is valid), including checks that read each
    /// mask and depth file.
    pub fn validate(dir: &Path) -> Vec<Problem> {
        match Capture::open(dir) {
            Err(p) => p.problems,
            Ok(cap) => {
                let mut problems = Vec::new();
                for VideoFrame { frame, keyframe } in cap.video() {
                    for r in [
                        cap.load_frame_of(frame).map(|_| ()),
                        cap.load_mask_of(frame).map(|_| ()),
                        cap.load_hand_of(frame).map(|_| ()),
                        cap.load_depth_of(frame).map(|_| ()),
                    ] {
                        if let Err(e) = r {
                            let (path, message) = match e {
                                DataError::Invalid { path, message } => (path, message),
                                other => (cap.dir.clone(), other.to_string()),
                            };
                            problems.push(Problem { path, message });
                        }
                    }
                    // An in-between frame may show no object (it left the view or a hand covers
                    // it): the tracker carries its pose across; a keyframe must show it.
                    if let Ok(m) = cap.load_mask_of(frame) {
                        if keyframe.is_some() && m.count() == 0 {
                            problems.push(Problem {
                                path: cap.mask_file(frame),
                                message: "the object mask is empty".into(),
                            });
                        }
                    }
                }
                problems
            }
        }
    }
}

fn load_depth_npz(path: &Path, w: u32, h: u32) -> Result<DepthObservation> {
    let arrays = read_arrays(path, &["local", "conf", "keep"])?;
    let get = |n: &str| arrays.iter().find(|(k, _)| k == n).map(|(_, a)| a);
    let local =
        get("local").ok_or_else(|| DataError::invalid(path, "missing array `local` (H, W, 3)"))?;
    if local.shape.len() != 3 || local.shape[2] != 3 {
        return Err(DataError::invalid(
            path,
            format!("`local` must have shape (H, W, 3), got {:?}", local.shape),
        ));
    }
    let (dh, dw) = (local.shape[0], local.shape[1]);
    let conf = get("conf");
    let keep = get("keep");
    for (name, a) in [("conf", conf), ("keep", keep)] {
        if let Some(a) = a {
            if a.shape != [dh, dw] {
                return Err(DataError::invalid(
                    path,
                    format!("`{name}` must have shape ({dh}, {dw}), got {:?}", a.shape),
                ));
            }
        }
    }
    // Nearest-neighbour resampling onto the image grid when the depth grid differs.
    let mut depth = Vec::with_capacity((w * h) as usize);
    let mut confidence = Vec::with_capacity((w * h) as usize);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let sy = ((y as f64 + 0.5) * dh as f64 / h as f64) as usize;
            let sx = ((x as f64 + 0.5) * dw as f64 / w as f64) as usize;
            let k = sy.min(dh - 1) * dw + sx.min(dw - 1);
            let z = local.data[k * 3 + 2];
            let kept = keep.is_none_or(|a| a.data[k] != 0.0);
            depth.push(if kept && z.is_finite() && z > 0.0 {
                z as f32
            } else {
                f32::NAN
            });
            confidence.push(conf.map_or(1.0, |a| a.data[k] as f32));
        }
    }
    Ok(DepthObservation {
        width: w,
        height: h,
        depth,
        confidence,
    })
}

/// Camera rows as read: c2w matrices, intrinsics, the size they were given for, the file.
type CameraRows = (Vec<Matrix4>, Vec<Matrix3>, Option<[u32; 2]>, PathBuf);

fn read_cameras(dir: &Path, c: &mut Collector) -> Option<CameraRows> {
    let npz = dir.join("tracking/cameras.npz");
    let json = dir.join("tracking/cameras.json");
    if npz.exists() {
        let arrays = match read_arrays(&npz, &["c2w", "intrinsics", "size"]) {
            Ok(a) => a,
            Err(e) => {
                c.add(
                    &npz,
                    e.to_string()
                        .trim_start_matches(&format!("{}: ", npz.display()))
                        .to_string(),
                );
                return None;
            }
        };
        let get = |n: &str| arrays.iter().find(|(k, _)| k == n).map(|(_, a)| a.clone());
        let (Some(c2w), Some(k)) = (get("c2w"), get("intrinsics")) else {
            c.add(
                &npz,
                "needs arrays `c2w` (K, 4, 4) and `intrinsics` (K, 3, 3)",
            );
            return None;
        };
        if c2w.shape.len() != 3
            || c2w.shape[1..] != [4, 4]
            || k.shape.len() != 3
            || k.shape[1..] != [3, 3]
            || c2w.shape[0] != k.shape[0]
        {
            c.add(&npz, format!("`c2w` must be (K, 4, 4) and `intrinsics` (K, 3, 3) with the same K; got {:?} and {:?}", c2w.shape, k.shape));
            return None;
        }
        let n = c2w.shape[0];
        let mats = (0..n)
            .map(|i| Matrix4::from_row_slice(&c2w.data[i * 16..i * 16 + 16]))
            .collect();
        let ks = (0..n)
            .map(|i| Matrix3::from_row_slice(&k.data[i * 9..i * 9 + 9]))
            .collect();
        let size = match get("size") {
            None => None,
            Some(s) => match check_size_array(&s.data) {
                Ok(size) => Some(size),
                Err(m) => {
                    c.add(&npz, m);
                    return None;
                }
            },
        };
        Some((mats, ks, size, npz))
    } else if json.exists() {
        let parsed: std::result::Result<CamerasJson, String> = read_text(&json)
            .map_err(|e| e.to_string())
            .and_then(|t| crate::parse_json::<serde_json::Value>(&t))
            .and_then(|v| {
                // `size` is checked as numbers first, so that [-1, -1], [NaN, 240] or
                // [640, 480, 3] are named as `size` rather than as a type error.
                if let Some(size) = v.get("size").filter(|s| !s.is_null()) {
                    let values: Option<Vec<f64>> = size
                        .as_array()
                        .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect());
                    check_size_array(&values.unwrap_or_default())?;
                }
                serde_json::from_value(v).map_err(|e| e.to_string())
            });
        match parsed {
            Err(e) => {
                c.add(&json, format!("invalid cameras JSON: {e}"));
                None
            }
            Ok(cj) => {
                if cj.c2w.len() != cj.intrinsics.len() {
                    c.add(
                        &json,
                        format!(
                            "`c2w` has {} rows but `intrinsics` has {}",
                            cj.c2w.len(),
                            cj.intrinsics.len()
                        ),
                    );
                    return None;
                }
                let mats = cj
                    .c2w
                    .iter()
                    .map(|m| Matrix4::from_fn(|r, col| m[r][col]))
                    .collect();
                let ks = cj
                    .intrinsics
                    .iter()
                    .map(|m| Matrix3::from_fn(|r, col| m[r][col]))
                    .collect();
                if let Some([sw, sh]) = cj.size {
                    if let Err(m) = check_size_array(&[f64::from(sw), f64::from(sh)]) {
                        c.add(&json, m);
                        return None;
                    }
                }
                Some((mats, ks, cj.size, json))
            }
        }
    } else {
        c.add(&dir.join("tracking"), "no cameras: expected tracking/cameras.npz or tracking/cameras.json (intrinsics are required; c2w may be the identity)");
        None
    }
}

/// `size` `[W, H]`: two positive integers (pixels) at most 16384.
fn check_size_array(data: &[f64]) -> std::result::Result<[u32; 2], String> {
    let ok = |v: f64| (1.0..=16384.0).contains(&v) && v.fract() == 0.0;
    if data.len() != 2 || !data.iter().all(|&v| ok(v)) {
        return Err(format!(
            "`size` must be [W, H], two positive integers (pixels) at most 16384; got {data:?}"
        ));
    }
    Ok([data[0] as u32, data[1] as u32])
}

/// A `c2w` row of `tracking/cameras.*` as the reader takes it: a rigid camera-to-world
/// transform (bottom row `[0, 0, 0, 1]`, orthonormal rotation).
pub(crate) fn rigid_from_c2w(m: &Matrix4) -> std::result::Result<Rigid, String> {
    check_bottom_row(m).and_then(|()| rigid_from_matrix(m).map_err(|e| e.to_string()))
}

/// The bottom row of a `c2w` matrix must be `[0, 0, 0, 1]`.
fn check_bottom_row(m: &Matrix4) -> std::result::Result<(), String> {
    let row = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]];
    let want = [0.0, 0.0, 0.0, 1.0];
    if row
        .iter()
        .zip(want)
        .any(|(a, b)| (a - b).abs().is_nan() || (a - b).abs() > 1e-6)
    {
        return Err(format!(
            "the bottom row is {row:?}; a rigid camera-to-world matrix ends in [0, 0, 0, 1]"
        ));
    }
    Ok(())
}

fn open_inner(dir: &Path, c: &mut Collector, check_files: bool) -> Option<Capture> {
    let mpath = Capture::manifest_path(dir);
    let text = match read_text(&mpath) {
        Ok(t) => t,
        Err(e) => {
            let message = if std::fs::symlink_metadata(&mpath).is_ok() {
                // It exists but cannot be read: say why (a device, too large, not UTF-8…).
                match e {
                    DataError::Invalid { message, .. } => message,
                    DataError::Io { error, .. } => error.to_string(),
                    other => other.to_string(),
                }
            } else if dir.is_dir() {
                "missing: a capture directory needs capture.json".into()
            } else {
                "the capture directory does not exist".into()
            };
            c.add(&mpath, message);
            return None;
        }
    };
    let manifest: Manifest = match crate::parse_json(&text) {
        Ok(m) => m,
        Err(e) => {
            c.add(&mpath, format!("invalid manifest: {e}"));
            return None;
        }
    };
    if manifest.format != FORMAT {
        c.add(
            &mpath,
            format!(
                "unknown format \"{}\"; expected \"{FORMAT}\"",
                manifest.format
            ),
        );
    }
    let [w, h] = manifest.image_size;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        c.add(
            &mpath,
            format!("image_size [{w}, {h}] must be positive and at most 16384"),
        );
        return None;
    }
    if manifest.frames.is_empty() {
        c.add(&mpath, "`frames` is empty");
        return None;
    }
    if let Some(d) = manifest.downscale {
        if !(d.is_finite() && d > 0.0) {
            c.add(
                &mpath,
                format!("downscale {d} must be a positive, finite factor"),
            );
        }
    }
    if let Some(s) = manifest.depth_scale {
        if !(s.is_finite() && s > 0.0) {
            c.add(&mpath, format!("depth_scale {s} must be positive"));
        }
    }
    // Frames: integer stems, unique, present, right size.
    let mut frames_meta: Vec<(String, String, u64)> = Vec::new();
    for name in &manifest.frames {
        let stem = stem_of(name).to_string();
        let Ok(number) = stem.parse::<u64>() else {
            c.add(&mpath, format!("frame `{name}`: the file stem must be a zero-padded integer (it orders frames in time)"));
            continue;
        };
        if frames_meta.iter().any(|(n, s, _)| n == name || *s == stem) {
            c.add(&mpath, format!("frame `{name}` is listed twice"));
            continue;
        }
        if check_files {
            let fp = dir.join("frames").join(name);
            if !fp.is_file() {
                c.add(&fp, "missing frame image");
            } else {
                match image_size(&fp) {
                    Ok((fw, fh)) if [fw, fh] != manifest.image_size => c.add(
                        &fp,
                        format!("size {fw}×{fh} differs from image_size {w}×{h}"),
                    ),
                    Err(e) => c.add(
                        &fp,
                        e.to_string()
                            .rsplit(": ")
                            .next()
                            .unwrap_or("unreadable")
                            .to_string(),
                    ),
                    _ => {}
                }
            }
            let mp = dir.join("mask_object").join(format!("{stem}.png"));
            if !mp.is_file() {
                c.add(&mp, format!("missing object mask for frame `{name}`"));
            } else if let Ok((mw, mh)) = image_size(&mp) {
                if [mw, mh] != manifest.image_size {
                    c.add(
                        &mp,
                        format!("size {mw}×{mh} differs from image_size {w}×{h}"),
                    );
                }
            } else {
                c.add(&mp, "unreadable mask image");
            }
            let hp = dir.join("mask_hand").join(format!("{stem}.png"));
            if hp.is_file() {
                match image_size(&hp) {
                    Ok((hw, hh)) if [hw, hh] != manifest.image_size => c.add(
                        &hp,
                        format!("size {hw}×{hh} differs from image_size {w}×{h}"),
                    ),
                    Err(_) => c.add(&hp, "unreadable hand mask image"),
                    _ => {}
                }
            }
            if manifest.depth != "none" {
                let has = dir.join("depth").join(format!("{stem}.npz")).is_file()
                    || dir.join("depth").join(format!("{stem}.png")).is_file();
                if !has {
                    c.add(&dir.join("depth"), format!("capture.json declares depth \"{}\" but frame `{name}` has no depth/{stem}.npz or .png", manifest.depth));
                }
            }
        }
        frames_meta.push((name.clone(), stem, number));
    }
    frames_meta.sort_by_key(|f| f.2);
    let ref_name = manifest
        .ref_frame
        .clone()
        .unwrap_or_else(|| manifest.frames[0].clone());
    let ref_index = frames_meta
        .iter()
        .position(|(n, s, _)| *n == ref_name || *s == stem_of(&ref_name));
    if ref_index.is_none() {
        c.add(
            &mpath,
            format!("ref_frame `{ref_name}` is not one of the frames"),
        );
    }
    // Cameras.
    let (c2w, ks, cam_size, cam_path) = read_cameras(dir, c)?;
    let mut notes = Vec::new();
    let mut cameras = Vec::with_capacity(c2w.len());
    for (i, (m, k)) in c2w.iter().zip(&ks).enumerate() {
        let rigid = match rigid_from_c2w(m) {
            Ok(r) => Some(r),
            Err(e) => {
                c.add(&cam_path, format!("c2w[{i}]: {e}"));
                None
            }
        };
        let (mut cw, mut ch) = (w, h);
        if let Some([sw, sh]) = cam_size {
            (cw, ch) = (sw, sh);
        }
        let cam = match PinholeCamera::from_matrix(k, cw.max(1), ch.max(1)) {
            Ok(cam) => Some(if (cw, ch) != (w, h) {
                cam.resized(w, h)
            } else {
                cam
            }),
            Err(e) => {
                c.add(&cam_path, format!("intrinsics[{i}]: {e}"));
                None
            }
        };
        cameras.push(rigid.zip(cam));
    }
    if let Some([sw, sh]) = cam_size {
        if [sw, sh] != manifest.image_size {
            notes.push(format!(
                "intrinsics were given for {sw}×{sh} and are rescaled to the image size {w}×{h}"
            ));
        }
    }
    // Frame → camera row.
    let kf_path = dir.join("tracking/keyframes.json");
    let mut view_of: Vec<Option<usize>> = vec![None; frames_meta.len()];
    let mut times: Vec<Option<f64>> = vec![None; frames_meta.len()];
    if kf_path.exists() {
        match read_text(&kf_path)
            .map_err(|e| e.to_string())
            .and_then(|t| crate::parse_json::<Vec<Keyframe>>(&t))
        {
            Err(e) => c.add(&kf_path, format!("invalid keyframes list: {e}")),
            Ok(list) => {
                let mut row_of_frame: Vec<Option<usize>> = vec![None; frames_meta.len()];
                for (row, kf) in list.into_iter().enumerate() {
                    if let Some(t) = kf.time_s {
                        if !t.is_finite() {
                            c.add(
                                &kf_path,
                                format!(
                                    "row {row} (`{}`): time_s {t} is not finite",
                                    kf.frame_name
                                ),
                            );
                        }
                    }
                    match frames_meta
                        .iter()
                        .position(|(n, s, _)| *n == kf.frame_name || *s == stem_of(&kf.frame_name))
                    {
                        Some(fi) if row_of_frame[fi].is_some() => c.add(
                            &kf_path,
                            format!(
                                "rows {} and {row} both list frame `{}`; each frame has one row",
                                row_of_frame[fi].unwrap_or(0),
                                kf.frame_name
                            ),
                        ),
                        Some(fi) => {
                            row_of_frame[fi] = Some(row);
                            if kf.view >= cameras.len() {
                                c.add(&kf_path, format!("frame `{}`: view {} is out of range (the cameras have {} rows)", kf.frame_name, kf.view, cameras.len()));
                            } else {
                                view_of[fi] = Some(kf.view);
                                times[fi] = kf.time_s.or(kf.frame_index.map(|n| n as f64 / 30.0));
                            }
                        }
                        None => notes.push(format!(
                            "keyframes.json lists `{}`, which is not among the capture's frames",
                            kf.frame_name
                        )),
                    }
                }
                // Frames are ordered by their stems; their times must not go backwards.
                let mut last: Option<(f64, &str)> = None;
                for ((name, _, _), t) in frames_meta.iter().zip(&times) {
                    let Some(t) = *t else { continue };
                    if let Some((prev, prev_name)) = last {
                        if t < prev {
                            c.add(&kf_path, format!("time goes backwards: frame `{name}` is at {t} s but the earlier frame `{prev_name}` is at {prev} s"));
                        }
                    }
                    last = Some((t, name.as_str()));
                }
                let missing: Vec<&str> = frames_meta
                    .iter()
                    .zip(&view_of)
                    .filter(|(_, v)| v.is_none())
                    .map(|((n, _, _), _)| n.as_str())
                    .collect();
                if !missing.is_empty() && missing.len() < frames_meta.len() {
                    c.add(&kf_path, format!("frames without a camera row: {} (a frame may lack one only when no frame has one)", missing.join(", ")));
                }
            }
        }
    }
    let shared = view_of.iter().all(|v| v.is_none());
    if shared {
        if cameras.len() == 1 {
            notes.push(
                "one shared camera for every frame (identity motion unless c2w says otherwise)"
                    .into(),
            );
            view_of = vec![Some(0); frames_meta.len()];
        } else if cameras.len() == frames_meta.len() {
            notes.push(
                "no keyframes.json: camera rows are matched to frames in temporal order".into(),
            );
            view_of = (0..frames_meta.len()).map(Some).collect();
        } else {
            c.add(
                &cam_path,
                format!(
                    "{} camera rows for {} frames and no tracking/keyframes.json to link them",
                    cameras.len(),
                    frames_meta.len()
                ),
            );
            return None;
        }
    }
    let mut frames = Vec::with_capacity(frames_meta.len());
    for (fi, (name, stem, number)) in frames_meta.into_iter().enumerate() {
        let Some(view) = view_of[fi] else { continue };
        let Some(Some((rigid, cam))) = cameras.get(view).copied() else {
            continue;
        };
        frames.push(Frame {
            name,
            stem,
            number,
            camera: cam,
            world_from_camera: rigid,
            time_s: times[fi],
        });
    }
    let stated_fps = manifest
        .source
        .as_ref()
        .and_then(|s| s.get("fps"))
        .and_then(|f| f.as_f64());
    let warnings = timing_warnings(&frames, stated_fps);
    let ref_name = ref_index
        .and_then(|i| frames.get(i))
        .map(|f| f.name.clone());
    let (frames, between) = split_keyframes(&mpath, &manifest, frames, c)?;
    let ref_index = match ref_name {
        Some(name) => match frames.iter().position(|f| f.name == name) {
            Some(i) => i,
            // Without `ref_frame`, the first frame listed; when that is an in-between frame,
            // the first keyframe listed.
            None if manifest.ref_frame.is_none() => manifest
                .keyframes
                .as_ref()
                .and_then(|k| k.first())
                .and_then(|k| {
                    frames
                        .iter()
                        .position(|f| f.name == *k || f.stem == stem_of(k))
                })
                .unwrap_or(0),
            None => {
                c.add(
                    &mpath,
                    format!("ref_frame `{name}` is an in-between frame; it must be a keyframe"),
                );
                return None;
            }
        },
        None => 0,
    };
    if !between.is_empty() {
        notes.push(format!(
            "{} keyframes and {} in-between frames",
            frames.len(),
            between.len()
        ));
    }
    Some(Capture {
        dir: dir.to_path_buf(),
        manifest,
        frames,
        between,
        ref_index,
        notes,
        warnings,
    })
}

/// Splits the frames (in temporal order) into keyframes and in-between frames by the
/// manifest's `keyframes` key; every frame is a keyframe without it.
fn split_keyframes(
    mpath: &Path,
    manifest: &Manifest,
    frames: Vec<Frame>,
    c: &mut Collector,
) -> Option<(Vec<Frame>, Vec<Frame>)> {
    let Some(names) = &manifest.keyframes else {
        return Some((frames, vec![]));
    };
    if names.is_empty() {
        c.add(
            mpath,
            "`keyframes` is empty; list the frames to track, or leave the key out (every frame is then a keyframe)",
        );
        return None;
    }
    let mut is_key = vec![false; frames.len()];
    let mut bad = false;
    for name in names {
        match frames
            .iter()
            .position(|f| f.name == *name || f.stem == stem_of(name))
        {
            Some(i) if is_key[i] => {
                c.add(mpath, format!("`keyframes` lists `{name}` twice"));
                bad = true;
            }
            Some(i) => is_key[i] = true,
            None => {
                c.add(
                    mpath,
                    format!("`keyframes` lists `{name}`, which is not one of `frames`"),
                );
                bad = true;
            }
        }
    }
    if bad {
        return None;
    }
    let (mut key, mut between) = (vec![], vec![]);
    for (frame, k) in frames.into_iter().zip(is_key) {
        if k {
            key.push(frame);
        } else {
            between.push(frame);
        }
    }
    Some((key, between))
}

/// Frame rates of video that a keyframe step of one frame gives away.
const VIDEO_RATES: [f64; 5] = [24.0, 25.0, 30.0, 50.0, 60.0];

/// Warnings about `time_s` that does not fit the frames' numbers (their integer stems, the
/// frame index in the video): against the frame rate the capture states (`source.fps`), or,
/// without one, frames whose names are several frames apart but whose times are exactly one
/// video frame apart (times that count keyframes, not video frames).
pub fn timing_warnings(frames: &[Frame], stated_fps: Option<f64>) -> Vec<String> {
    let steps: Vec<(&Frame, &Frame, f64, f64)> = frames
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (&w[0], &w[1]);
            let dt = b.time_s? - a.time_s?;
            let dn = b.number.checked_sub(a.number)? as f64;
            Some((a, b, dn, dt))
        })
        .collect();
    let mut out = vec![];
    let say = |bad: &[&(&Frame, &Frame, f64, f64)], what: String| -> String {
        format!(
            "{what} ({} of {} steps between frames; time_s is in tracking/keyframes.json)",
            bad.len(),
            steps.len()
        )
    };
    match stated_fps.filter(|f| f.is_finite() && *f > 0.0) {
        Some(fps) => {
            let bad: Vec<_> = steps
                .iter()
                .filter(|(_, _, dn, dt)| (dt - dn / fps).abs() > 0.01 * dn / fps + 1e-6)
                .collect();
            if let Some((a, b, dn, dt)) = bad.first() {
                out.push(say(
                    &bad,
                    format!(
                        "time_s does not fit the stated {fps} fps: frames `{}` and `{}` are {dn} frame numbers apart ({:.4} s at {fps} fps) but {dt:.4} s apart in time",
                        a.name,
                        b.name,
                        dn / fps
                    ),
                ));
            }
        }
        None => {
            let one_frame = |dt: f64| {
                VIDEO_RATES
                    .iter()
                    .find(|r| (dt * **r - 1.0).abs() < 0.005)
                    .copied()
            };
            let bad: Vec<_> = steps
                .iter()
                .filter(|(_, _, dn, dt)| (2.0..=1000.0).contains(dn) && one_frame(*dt).is_some())
                .collect();
            if let Some((a, b, dn, dt)) = bad.first() {
                out.push(say(
                    &bad,
                    format!(
                        "frames `{}` and `{}` are {dn} frame numbers apart but their times are {dt:.4} s apart, one video frame at {} fps: time_s seems to count keyframes, not video frames",
                        a.name,
                        b.name,
                        one_frame(*dt).unwrap_or(30.0)
                    ),
                ));
            }
        }
    }
    out
}
