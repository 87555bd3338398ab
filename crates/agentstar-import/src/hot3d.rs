//! Importing one object of a HOT3D sequence in its CSV layout: `dynamic_objects.csv`
//! (`T_world_object` per object and timestamp), `headset_trajectory.csv` (`T_world_device`)
//! and the object library's `{object_uid}.glb` models (metres), with frames the user exported
//! from the recording.
//!
//! Decisions: HOT3D's pose CSVs share one header, `object_uid, timestamp[ns], t_wo_x[m],
//! t_wo_y[m], t_wo_z[m], q_wo_w, q_wo_x, q_wo_y, q_wo_z` (columns found by name, in any
//! order). Frames are images whose file stem is their timestamp in nanoseconds and which are
//! already undistorted to the pinhole intrinsics given (HOT3D's Aria and Quest cameras are
//! fisheye; `projectaria_tools` undistorts them). Each frame takes the object and headset
//! poses nearest in time, within `max_dt_ns`, else it is skipped with a count in the result.
//! The camera is `T_world_device · T_device_camera` (the calibration's extrinsics; identity
//! when not given). Masks come from a folder, matched by stem; without one they are rendered
//! from the ground truth (the whole object, hands not cut out), and the manifest says so.

use crate::import_common::{
    check_between, images_by_stem, load_kept_mask, optional_mask, select_frames, write_rows,
    GtModel, Row,
};
use crate::render_parts_mask;
use agentstar_data::capture_writer::CaptureInfo;
use agentstar_data::images::load_rgb;
use agentstar_data::meshio::parse_glb_file_frame;
use agentstar_data::{read_bytes, read_text, DataError, Result};
use agentstar_geom::pose::Rigid;
use agentstar_geom::{nalgebra, PinholeCamera, TriMesh, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The columns every HOT3D pose CSV holds.
pub const POSE_COLUMNS: [&str; 9] = [
    "object_uid",
    "timestamp[ns]",
    "t_wo_x[m]",
    "t_wo_y[m]",
    "t_wo_z[m]",
    "q_wo_w",
    "q_wo_x",
    "q_wo_y",
    "q_wo_z",
];

/// What to import.
#[derive(Debug, Clone)]
pub struct Hot3dImport {
    /// The sequence directory (holding `dynamic_objects.csv` and `headset_trajectory.csv`).
    pub sequence: PathBuf,
    /// The object library directory holding `{object_uid}.glb`.
    pub models: PathBuf,
    pub object_uid: String,
    /// Undistorted frames named `{timestamp_ns}.png|jpg`.
    pub frames: PathBuf,
    /// Object masks matched by stem; rendered from the ground truth when absent.
    pub masks: Option<PathBuf>,
    /// Hand masks matched by stem.
    pub hands: Option<PathBuf>,
    /// Pinhole intrinsics of the frames: fx, fy, cx, cy (pixels).
    pub intrinsics: [f64; 4],
    /// `T_device_camera`; identity when the frames are in the device frame.
    pub device_from_camera: Rigid,
    /// Largest time difference between a frame and a pose, in nanoseconds.
    pub max_dt_ns: u64,
    /// Keep every n-th frame (the keyframes).
    pub every: usize,
    /// Keep the frames between keyframes too, as in-between frames (`formats.md` §2): every
    /// N-th frame after each keyframe, N from 1 to `every` − 1; `None`: keyframes only.
    /// Their masks are read or rendered as the keyframes' are.
    pub between: Option<usize>,
}

/// What was imported.
#[derive(Debug, Clone, PartialEq)]
pub struct Hot3dSummary {
    /// Keyframes written.
    pub frames: usize,
    /// In-between frames written (0 without `between`).
    pub between: usize,
    /// Frames without an object or headset pose within `max_dt_ns`.
    pub skipped: usize,
    pub rendered_masks: bool,
}

/// Poses of one CSV by object uid, sorted by timestamp.
pub type PoseTracks = BTreeMap<String, Vec<(u64, Rigid)>>;

/// Reads a HOT3D pose CSV (`dynamic_objects.csv` or `headset_trajectory.csv`).
pub fn read_pose_csv(path: &Path) -> Result<PoseTracks> {
    let text = read_text(path)?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines
        .next()
        .ok_or_else(|| DataError::invalid(path, "empty file (expected a header line)"))?;
    let names: Vec<&str> = header.split(',').map(|s| s.trim()).collect();
    let mut col = [0usize; 9];
    for (k, want) in POSE_COLUMNS.iter().enumerate() {
        col[k] = names.iter().position(|n| n == want).ok_or_else(|| {
            DataError::invalid(
                path,
                format!(
                    "the header has no `{want}` column (found: {})",
                    names.join(", ")
                ),
            )
        })?;
    }
    let mut out: PoseTracks = BTreeMap::new();
    for (i, line) in lines {
        let cells: Vec<&str> = line.split(',').map(|s| s.trim()).collect();
        let at = |k: usize| -> Result<&str> {
            cells.get(col[k]).copied().ok_or_else(|| {
                DataError::invalid(
                    path,
                    format!("line {}: missing `{}`", i + 1, POSE_COLUMNS[k]),
                )
            })
        };
        let num = |k: usize| -> Result<f64> {
            let s = at(k)?;
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    DataError::invalid(
                        path,
                        format!(
                            "line {}: `{}` = `{s}` is not a finite number",
                            i + 1,
                            POSE_COLUMNS[k]
                        ),
                    )
                })
        };
        let uid = at(0)?.to_string();
        let t = at(1)?.parse::<u64>().map_err(|_| {
            DataError::invalid(
                path,
                format!(
                    "line {}: timestamp `{}` is not an integer",
                    i + 1,
                    cells[col[1]]
                ),
            )
        })?;
        let q = nalgebra::Quaternion::new(num(5)?, num(6)?, num(7)?, num(8)?);
        if !(q.norm() > 0.5 && q.norm() < 2.0) {
            return Err(DataError::invalid(
                path,
                format!(
                    "line {}: quaternion of norm {:.3} is not a rotation",
                    i + 1,
                    q.norm()
                ),
            ));
        }
        let pose = Rigid::from_parts(
            Vector3::new(num(2)?, num(3)?, num(4)?).into(),
            UnitQuaternion::from_quaternion(q),
        );
        out.entry(uid).or_default().push((t, pose));
    }
    for v in out.values_mut() {
        v.sort_by_key(|(t, _)| *t);
    }
    Ok(out)
}

/// The pose nearest to `t` within `max_dt`.
fn nearest(track: &[(u64, Rigid)], t: u64, max_dt: u64) -> Option<Rigid> {
    let i = track.partition_point(|(s, _)| *s < t);
    [i.checked_sub(1), Some(i)]
        .into_iter()
        .flatten()
        .filter_map(|j| track.get(j))
        .min_by_key(|(s, _)| s.abs_diff(t))
        .filter(|(s, _)| s.abs_diff(t) <= max_dt)
        .map(|(_, p)| *p)
}

/// Loads a model GLB as one mesh in the file's own frame (every primitive, node transforms
/// applied), as HOT3D's poses refer to it.
pub fn load_glb_mesh(path: &Path) -> Result<TriMesh> {
    let meshes =
        parse_glb_file_frame(&read_bytes(path)?).map_err(|e| DataError::invalid(path, e))?;
    let mut all = TriMesh::new(vec![], vec![]);
    for (_, m) in &meshes {
        all.append(m);
    }
    if all.triangles.is_empty() {
        return Err(DataError::invalid(path, "the model has no triangles"));
    }
    Ok(all)
}

/// Imports one object of a HOT3D sequence into `out` (a new directory).
pub fn import_hot3d(cfg: &Hot3dImport, out: &Path) -> Result<Hot3dSummary> {
    check_between(&cfg.frames, cfg.every, cfg.between)?;
    let objects_csv = cfg.sequence.join("dynamic_objects.csv");
    let headset_csv = cfg.sequence.join("headset_trajectory.csv");
    let objects = read_pose_csv(&objects_csv)?;
    let headset = read_pose_csv(&headset_csv)?;
    let object_track = objects.get(&cfg.object_uid).ok_or_else(|| {
        DataError::invalid(
            &objects_csv,
            format!(
                "no poses of object `{}` (objects: {})",
                cfg.object_uid,
                objects.keys().cloned().collect::<Vec<_>>().join(", ")
            ),
        )
    })?;
    if headset.len() != 1 {
        return Err(DataError::invalid(
            &headset_csv,
            format!("expected the poses of one headset, found {}", headset.len()),
        ));
    }
    let headset_track = headset.values().next().map(Vec::as_slice).unwrap_or(&[]);
    let mesh = load_glb_mesh(&cfg.models.join(format!("{}.glb", cfg.object_uid)))?;
    let frames = images_by_stem(&cfg.frames)?;
    let masks = cfg.masks.as_deref().map(images_by_stem).transpose()?;
    let hands = cfg.hands.as_deref().map(images_by_stem).transpose()?;
    let mut stamped: Vec<(u64, &String, &PathBuf)> = frames
        .iter()
        .filter_map(|(s, p)| s.parse::<u64>().ok().map(|t| (t, s, p)))
        .collect();
    stamped.sort();
    if stamped.is_empty() {
        return Err(DataError::invalid(
            &cfg.frames,
            "no frame is named by its timestamp in nanoseconds (e.g. 43455445512000.png)",
        ));
    }
    let [fx, fy, cx, cy] = cfg.intrinsics;
    let mut rows = vec![];
    let mut skipped = 0usize;
    let t0 = stamped[0].0;
    for (k, keyframe) in select_frames(stamped.len(), cfg.every, cfg.between, None) {
        let (t, stem, path) = stamped[k];
        let (Some(world_from_object), Some(world_from_device)) = (
            nearest(object_track, t, cfg.max_dt_ns),
            nearest(headset_track, t, cfg.max_dt_ns),
        ) else {
            skipped += 1;
            continue;
        };
        let rgb = load_rgb(path)?;
        let (w, h) = rgb.dimensions();
        let camera = PinholeCamera::new(fx, fy, cx, cy, w, h)
            .map_err(|e| DataError::invalid(path, format!("intrinsics: {e}")))?;
        let world_from_camera = world_from_device * cfg.device_from_camera;
        let camera_from_object = world_from_camera.inverse() * world_from_object;
        let mask = match &masks {
            Some(m) => load_kept_mask(m, cfg.masks.as_deref(), stem, keyframe, "frame")?,
            None => render_parts_mask(&camera, &[(&mesh, camera_from_object)]),
        };
        let hand = optional_mask(hands.as_ref(), stem)?;
        rows.push(Row {
            name: format!("{stem}.png"),
            keyframe,
            frame_index: Some(k as i64),
            time_s: Some((t - t0) as f64 * 1e-9),
            camera,
            world_from_camera,
            rgb,
            mask,
            hand,
            depth_m: None,
            parts: BTreeMap::from([("object".to_string(), camera_from_object)]),
            states: BTreeMap::new(),
        });
    }
    if rows.is_empty() {
        return Err(DataError::invalid(
            &cfg.frames,
            format!(
                "no frame has object and headset poses within {} ns",
                cfg.max_dt_ns
            ),
        ));
    }
    let info = CaptureInfo {
        dataset: Some("hot3d".into()),
        source: Some(
            serde_json::json!({"producer": "agentstar capture from-hot3d",
            "sequence": cfg.sequence, "object_uid": cfg.object_uid, "every": cfg.every,
            "between": cfg.between,
            "masks": if cfg.masks.is_some() { "given" } else { "rendered from the ground truth (hands not cut out)" }}),
        ),
        keyframes: None,
    };
    let model = GtModel {
        base_part: "object".into(),
        meshes: BTreeMap::from([("object".to_string(), mesh)]),
        joints: vec![],
        symmetries: vec![],
    };
    let written = write_rows(out, &rows, &info, &model)?;
    Ok(Hot3dSummary {
        frames: written.keyframes,
        between: written.between,
        skipped,
        rendered_masks: cfg.masks.is_none(),
    })
}
