//! Camera sources for captures made from a video: COLMAP models (text and binary), nerfstudio
//! `transforms.json`, or one static pinhole camera. Each gives, per image file name, the
//! intrinsics (for the size the source states) and `world_from_camera` in OpenCV axes.
//!
//! COLMAP stores `camera_from_world` as a quaternion (w, x, y, z) and a translation in OpenCV
//! axes; nerfstudio stores `world_from_camera` in OpenGL axes (+Y up, +Z backward), turned
//! into OpenCV axes by flipping the camera's Y and Z. Distortion parameters are ignored with
//! a warning (captures are assumed undistorted).

use agentstar_data::{read_bytes, read_text, DataError, Result};
use agentstar_geom::pose::Rigid;
use agentstar_geom::{Matrix3, Matrix4};
use std::collections::BTreeMap;
use std::path::Path;

/// One image's camera as a source states it.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceCamera {
    /// fx, fy, cx, cy for `size`.
    pub intrinsics: [f64; 4],
    pub size: [u32; 2],
    pub world_from_camera: Rigid,
}

/// Cameras by image file stem, and warnings for people to read.
#[derive(Debug, Clone, Default)]
pub struct CameraSet {
    pub by_stem: BTreeMap<String, SourceCamera>,
    pub warnings: Vec<String>,
}

fn stem_of(name: &str) -> String {
    Path::new(name)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(name)
        .to_string()
}

/// Pinhole parameters of a COLMAP camera model; distortion is dropped with a warning.
fn colmap_pinhole(
    model: &str,
    params: &[f64],
    warnings: &mut Vec<String>,
    id: i64,
) -> std::result::Result<[f64; 4], String> {
    let need = |n: usize| {
        if params.len() < n {
            Err(format!(
                "camera {id}: model {model} needs {n} parameters, got {}",
                params.len()
            ))
        } else {
            Ok(())
        }
    };
    Ok(match model {
        "SIMPLE_PINHOLE"
        | "SIMPLE_RADIAL"
        | "RADIAL"
        | "SIMPLE_RADIAL_FISHEYE"
        | "RADIAL_FISHEYE" => {
            need(3)?;
            if model != "SIMPLE_PINHOLE" {
                warnings.push(format!(
                    "camera {id}: {model} distortion ignored (undistort the images first)"
                ));
            }
            [params[0], params[0], params[1], params[2]]
        }
        "PINHOLE" | "OPENCV" | "FULL_OPENCV" | "OPENCV_FISHEYE" | "THIN_PRISM_FISHEYE" => {
            need(4)?;
            if model != "PINHOLE" {
                warnings.push(format!(
                    "camera {id}: {model} distortion ignored (undistort the images first)"
                ));
            }
            [params[0], params[1], params[2], params[3]]
        }
        _ => {
            return Err(format!(
                "camera {id}: unsupported COLMAP camera model {model}"
            ))
        }
    })
}

/// COLMAP's model ids (as in its source) with their parameter counts.
fn colmap_model(id: i32) -> Option<(&'static str, usize)> {
    Some(match id {
        0 => ("SIMPLE_PINHOLE", 3),
        1 => ("PINHOLE", 4),
        2 => ("SIMPLE_RADIAL", 4),
        3 => ("RADIAL", 5),
        4 => ("OPENCV", 8),
        5 => ("OPENCV_FISHEYE", 8),
        6 => ("FULL_OPENCV", 12),
        7 => ("FOV", 5),
        8 => ("SIMPLE_RADIAL_FISHEYE", 4),
        9 => ("RADIAL_FISHEYE", 5),
        10 => ("THIN_PRISM_FISHEYE", 12),
        _ => return None,
    })
}

fn camera_from_world(q: [f64; 4], t: [f64; 3]) -> std::result::Result<Rigid, String> {
    let quat = agentstar_geom::pose::quat_from_wxyz(q).map_err(|e| e.to_string())?;
    if t.iter().any(|v| !v.is_finite()) {
        return Err("translation is not finite".into());
    }
    Ok(Rigid::from_parts(
        agentstar_geom::nalgebra::Translation3::new(t[0], t[1], t[2]),
        quat,
    ))
}

/// Reads a COLMAP model directory: `cameras.txt` + `images.txt`, or `cameras.bin` +
/// `images.bin`.
pub fn read_colmap(dir: &Path) -> Result<CameraSet> {
    let mut set = CameraSet::default();
    let mut intr: BTreeMap<i64, ([f64; 4], [u32; 2])> = BTreeMap::new();
    let mut images: Vec<(String, [f64; 4], [f64; 3], i64)> = vec![];
    let (cam_path, img_path);
    if dir.join("cameras.txt").is_file() {
        cam_path = dir.join("cameras.txt");
        img_path = dir.join("images.txt");
        for (ln, line) in read_text(&cam_path)?.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let f: Vec<&str> = line.split_whitespace().collect();
            let bad = |m: String| DataError::invalid(&cam_path, format!("line {}: {m}", ln + 1));
            if f.len() < 5 {
                return Err(bad("expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS…".into()));
            }
            let id: i64 = f[0]
                .parse()
                .map_err(|_| bad(format!("camera id `{}`", f[0])))?;
            let w: u32 = f[2].parse().map_err(|_| bad(format!("width `{}`", f[2])))?;
            let h: u32 = f[3]
                .parse()
                .map_err(|_| bad(format!("height `{}`", f[3])))?;
            let params: Vec<f64> = f[4..]
                .iter()
                .map(|v| v.parse().map_err(|_| bad(format!("parameter `{v}`"))))
                .collect::<Result<_>>()?;
            let k = colmap_pinhole(f[1], &params, &mut set.warnings, id).map_err(bad)?;
            intr.insert(id, (k, [w, h]));
        }
        let text = read_text(&img_path)?;
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim_start().starts_with('#'));
        while let Some((ln, line)) = lines.next() {
            if line.trim().is_empty() {
                continue;
            }
            let f: Vec<&str> = line.split_whitespace().collect();
            let bad = |m: String| DataError::invalid(&img_path, format!("line {}: {m}", ln + 1));
            if f.len() < 10 {
                return Err(bad(
                    "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME".into()
                ));
            }
            let num = |i: usize| -> Result<f64> {
                f[i].parse().map_err(|_| bad(format!("value `{}`", f[i])))
            };
            let q = [num(1)?, num(2)?, num(3)?, num(4)?];
            let t = [num(5)?, num(6)?, num(7)?];
            let cam: i64 = f[8]
                .parse()
                .map_err(|_| bad(format!("camera id `{}`", f[8])))?;
            images.push((f[9..].join(" "), q, t, cam));
            // Each image line is followed by its 2-D points line (possibly empty).
            lines.next();
        }
    } else if dir.join("cameras.bin").is_file() {
        cam_path = dir.join("cameras.bin");
        img_path = dir.join("images.bin");
        let b = read_bytes(&cam_path)?;
        let mut r = Reader::new(&b, &cam_path);
        let n = r.u64()?;
        for _ in 0..n {
            let id = r.i32()? as i64;
            let model = r.i32()?;
            let w = r.u64()? as u32;
            let h = r.u64()? as u32;
            let (name, count) = colmap_model(model).ok_or_else(|| {
                DataError::invalid(&cam_path, format!("camera {id}: unknown model id {model}"))
            })?;
            let params: Vec<f64> = (0..count).map(|_| r.f64()).collect::<Result<_>>()?;
            let k = colmap_pinhole(name, &params, &mut set.warnings, id)
                .map_err(|m| DataError::invalid(&cam_path, m))?;
            intr.insert(id, (k, [w, h]));
        }
        let b = read_bytes(&img_path)?;
        let mut r = Reader::new(&b, &img_path);
        let n = r.u64()?;
        for _ in 0..n {
            let _id = r.i32()?;
            let q = [r.f64()?, r.f64()?, r.f64()?, r.f64()?];
            let t = [r.f64()?, r.f64()?, r.f64()?];
            let cam = r.i32()? as i64;
            let name = r.cstr()?;
            let points = r.u64()? as usize;
            r.skip(
                points
                    .checked_mul(24)
                    .ok_or_else(|| DataError::invalid(&img_path, "point count overflows"))?,
            )?;
            images.push((name, q, t, cam));
        }
    } else {
        return Err(DataError::invalid(
            dir,
            "no COLMAP model here (cameras.txt + images.txt, or cameras.bin + images.bin)",
        ));
    }
    for (name, q, t, cam) in images {
        let (k, size) = *intr.get(&cam).ok_or_else(|| {
            DataError::invalid(&img_path, format!("image {name}: unknown camera {cam}"))
        })?;
        let cfw = camera_from_world(q, t)
            .map_err(|m| DataError::invalid(&img_path, format!("image {name}: {m}")))?;
        set.by_stem.insert(
            stem_of(&name),
            SourceCamera {
                intrinsics: k,
                size,
                world_from_camera: cfw.inverse(),
            },
        );
    }
    Ok(set)
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], path: &'a Path) -> Self {
        Reader { bytes, at: 0, path }
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| {
                DataError::invalid(self.path, format!("truncated at byte {}", self.at))
            })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn skip(&mut self, n: usize) -> Result<()> {
        self.take(n).map(|_| ())
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or([0; 8]),
        ))
    }
    fn i32(&mut self) -> Result<i32> {
        Ok(i32::from_le_bytes(
            self.take(4)?.try_into().unwrap_or([0; 4]),
        ))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or([0; 8]),
        ))
    }
    fn cstr(&mut self) -> Result<String> {
        let end = self.bytes[self.at..]
            .iter()
            .position(|&b| b == 0)
            .ok_or_else(|| {
                DataError::invalid(self.path, format!("unterminated name at byte {}", self.at))
            })?;
        let s = String::from_utf8_lossy(&self.bytes[self.at..self.at + end]).into_owned();
        self.at += end + 1;
        Ok(s)
    }
}

/// Reads a nerfstudio `transforms.json` (intrinsics at the top level or per frame).
pub fn read_nerfstudio(path: &Path) -> Result<CameraSet> {
    let v: serde_json::Value = serde_json::from_str(&read_text(path)?)
        .map_err(|e| DataError::invalid(path, format!("invalid JSON: {e}")))?;
    let mut set = CameraSet::default();
    let frames = v["frames"]
        .as_array()
        .ok_or_else(|| DataError::invalid(path, "no `frames` list"))?;
    let gl_to_cv = Matrix4::from_diagonal(&agentstar_geom::nalgebra::Vector4::new(
        1.0, -1.0, -1.0, 1.0,
    ));
    for (i, f) in frames.iter().enumerate() {
        let get = |k: &str| f[k].as_f64().or_else(|| v[k].as_f64());
        let bad = |m: String| DataError::invalid(path, format!("frames[{i}]: {m}"));
        let (Some(fx), Some(cx), Some(cy), Some(w), Some(h)) =
            (get("fl_x"), get("cx"), get("cy"), get("w"), get("h"))
        else {
            return Err(bad(
                "needs fl_x, cx, cy, w and h (per frame or at the top level)".into(),
            ));
        };
        let fy = get("fl_y").unwrap_or(fx);
        if ["k1", "k2", "p1", "p2"]
            .iter()
            .any(|k| get(k).is_some_and(|x| x != 0.0))
            && set.warnings.is_empty()
        {
            set.warnings.push(
                "nerfstudio distortion coefficients ignored (undistort the images first)".into(),
            );
        }
        let name = f["file_path"]
            .as_str()
            .ok_or_else(|| bad("no file_path".into()))?;
        let rows = f["transform_matrix"]
            .as_array()
            .filter(|r| r.len() >= 3)
            .ok_or_else(|| bad("no 4×4 transform_matrix".into()))?;
        let mut m = Matrix4::identity();
        for (r, row) in rows.iter().take(4).enumerate() {
            for c in 0..4 {
                m[(r, c)] = row[c]
                    .as_f64()
                    .ok_or_else(|| bad(format!("transform_matrix[{r}][{c}]")))?;
            }
        }
        let cv = m * gl_to_cv;
        let world_from_camera = agentstar_geom::pose::rigid_from_matrix(&cv)
            .map_err(|e| bad(format!("transform_matrix: {e}")))?;
        set.by_stem.insert(
            stem_of(name),
            SourceCamera {
                intrinsics: [fx, fy, cx, cy],
                size: [w as u32, h as u32],
                world_from_camera,
            },
        );
    }
    Ok(set)
}

/// Intrinsics rescaled from the size a source states to the image size.
pub fn rescaled(k: [f64; 4], from: [u32; 2], to: [u32; 2]) -> Matrix3 {
    let (sx, sy) = (
        to[0] as f64 / from[0].max(1) as f64,
        to[1] as f64 / from[1].max(1) as f64,
    );
    Matrix3::new(
        k[0] * sx,
        0.0,
        k[2] * sx,
        0.0,
        k[1] * sy,
        k[3] * sy,
        0.0,
        0.0,
        1.0,
    )
}

/// One 3-D point of a COLMAP text model (`points3D.txt`).
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapPoint {
    /// World coordinates in the model's frame.
    pub xyz: [f64; 3],
    /// Mean reprojection error in pixels.
    pub error_px: f64,
    /// Number of image observations.
    pub track_len: usize,
}

/// Reads `points3D.txt` of a COLMAP text model.
pub fn read_colmap_points(dir: &Path) -> Result<Vec<ColmapPoint>> {
    let path = dir.join("points3D.txt");
    let mut points = vec![];
    for (ln, line) in read_text(&path)?.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        let bad = |m: String| DataError::invalid(&path, format!("line {}: {m}", ln + 1));
        if f.len() < 8 {
            return Err(bad("expected POINT3D_ID X Y Z R G B ERROR TRACK[]".into()));
        }
        let num = |i: usize| -> Result<f64> {
            f[i].parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("value `{}`", f[i])))
        };
        points.push(ColmapPoint {
            xyz: [num(1)?, num(2)?, num(3)?],
            error_px: num(7)?,
            track_len: (f.len() - 8) / 2,
        });
    }
    Ok(points)
}
