//! Importing an ARCTIC sequence seen from one of its eight allocentric cameras: the object
//! array `raw_seqs/{subject}/{sequence}.object.npy` (frames × 7: articulation in radians,
//! axis-angle rotation, translation in millimetres, world frame), the two-part template
//! `meta/object_vtemplates/{object}/mesh.obj` (millimetres) with `parts.json` (per vertex:
//! 0 for the top part, 1 for the bottom), and the cameras of `meta/misc.json`
//! (`world2cam`, `intris_mat`, `image_size`, `ioi_offset` per subject).
//!
//! Decisions: the model has two parts, `bottom` (the base) and `top`, and one revolute joint
//! `articulation` with axis −Z through the template origin, as ARCTIC poses its templates
//! (the top part turns by the articulation angle about −Z, then the whole object by the
//! axis-angle and translation). A triangle belongs to the part of most of its vertices.
//! Images are `images/{subject}/{sequence}/{camera}/{number:05}.jpg`; image number `n`
//! holds object row `n − ioi_offset` (the offset from `misc.json`, overridable). ARCTIC
//! ships no masks: a mask folder (matched by stem) is used when given, else masks are
//! rendered from the ground truth (the whole object, hands not cut out), and the manifest
//! says which. The egocentric camera (view 0, a moving camera) is not supported.

use crate::import_common::{
    check_between, images_by_stem, load_kept_mask, optional_mask, select_frames, write_rows,
    GtModel, Row,
};
use crate::render_parts_mask;
use crate::FramesWritten;
use agentstar_data::capture_writer::CaptureInfo;
use agentstar_data::gt::GtJoint;
use agentstar_data::images::load_rgb;
use agentstar_data::npz::read_npy;
use agentstar_data::{read_bytes, read_text, DataError, Result};
use agentstar_geom::pose::Rigid;
use agentstar_geom::{Matrix3, PinholeCamera, Point3, TriMesh, UnitQuaternion, Vector3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What to import.
#[derive(Debug, Clone)]
pub struct ArcticImport {
    /// The ARCTIC data root (holding `meta/` and `raw_seqs/`).
    pub root: PathBuf,
    pub subject: String,
    /// E.g. `box_grab_01`; the object is the part before the first `_`.
    pub sequence: String,
    /// Allocentric camera 1–8.
    pub camera: u32,
    /// The image folder; `images/{subject}/{sequence}/{camera}` under the root by default.
    pub images: Option<PathBuf>,
    pub masks: Option<PathBuf>,
    pub hands: Option<PathBuf>,
    /// Image number minus object row; `ioi_offset` of `misc.json` by default.
    pub offset: Option<i64>,
    /// Keep every n-th image (the keyframes).
    pub every: usize,
    /// At most this many keyframes.
    pub max_frames: Option<usize>,
    /// Keep the images between keyframes too, as in-between frames (`formats.md` §2): every
    /// N-th image after each keyframe, N from 1 to `every` − 1; `None`: keyframes only.
    /// Their masks are read or rendered as the keyframes' are.
    pub between: Option<usize>,
}

/// The revolute joint's axis in the template frame.
pub const ARTICULATION_AXIS: [f64; 3] = [0.0, 0.0, -1.0];

/// One row of an ARCTIC object array.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectRow {
    pub angle_rad: f64,
    pub axis_angle: [f64; 3],
    pub translation_mm: [f64; 3],
}

impl ObjectRow {
    /// `world_from_object` in metres.
    pub fn world_from_object(&self) -> Rigid {
        let [a, b, c] = self.axis_angle;
        let [x, y, z] = self.translation_mm;
        Rigid::from_parts(
            (Vector3::new(x, y, z) * 0.001).into(),
            UnitQuaternion::from_scaled_axis(Vector3::new(a, b, c)),
        )
    }

    /// `bottom_from_top`: the articulation.
    pub fn bottom_from_top(&self) -> Rigid {
        let [x, y, z] = ARTICULATION_AXIS;
        Rigid::from_parts(
            Vector3::zeros().into(),
            UnitQuaternion::from_scaled_axis(Vector3::new(x, y, z) * self.angle_rad),
        )
    }
}

/// Reads an object array (frames × 7).
pub fn read_object_rows(path: &Path) -> Result<Vec<ObjectRow>> {
    let a = read_npy(path)?;
    if a.shape.len() != 2 || a.shape[1] != 7 {
        return Err(DataError::invalid(
            path,
            format!(
                "expected an array of shape (frames, 7), found {:?}",
                a.shape
            ),
        ));
    }
    a.data
        .chunks_exact(7)
        .enumerate()
        .map(|(i, r)| {
            if r.iter().all(|v| v.is_finite()) {
                Ok(ObjectRow {
                    angle_rad: r[0],
                    axis_angle: [r[1], r[2], r[3]],
                    translation_mm: [r[4], r[5], r[6]],
                })
            } else {
                Err(DataError::invalid(
                    path,
                    format!("row {i} is not finite: {r:?}"),
                ))
            }
        })
        .collect()
}

/// The template's vertices (in file order) and triangles, from the `v` and `f` lines of an
/// OBJ (faces fanned into triangles; texture and normal indices ignored).
fn read_template(path: &Path) -> Result<(Vec<Point3>, Vec<[u32; 3]>)> {
    let text = String::from_utf8(read_bytes(path)?)
        .map_err(|_| DataError::invalid(path, "not a UTF-8 OBJ file"))?;
    let mut v = vec![];
    let mut faces: Vec<Vec<i64>> = vec![];
    for (i, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f64> = it.take(3).filter_map(|s| s.parse().ok()).collect();
                if c.len() != 3 {
                    return Err(DataError::invalid(
                        path,
                        format!("line {}: bad vertex", i + 1),
                    ));
                }
                v.push(Point3::new(c[0], c[1], c[2]));
            }
            Some("f") => faces.push(
                it.map(|s| s.split('/').next().and_then(|x| x.parse::<i64>().ok()))
                    .collect::<Option<Vec<_>>>()
                    .ok_or_else(|| DataError::invalid(path, format!("line {}: bad face", i + 1)))?,
            ),
            _ => {}
        }
    }
    let n = v.len() as i64;
    let mut tris = vec![];
    for f in faces {
        let idx: Vec<u32> =
            f.iter()
                .map(|&k| {
                    let k = if k < 0 { n + k } else { k - 1 };
                    (0..n).contains(&k).then_some(k as u32).ok_or_else(|| {
                        DataError::invalid(path, format!("face index {k} out of range"))
                    })
                })
                .collect::<Result<_>>()?;
        for j in 1..idx.len().saturating_sub(1) {
            tris.push([idx[0], idx[j], idx[j + 1]]);
        }
    }
    Ok((v, tris))
}

/// Splits the template into its `top` and `bottom` meshes (metres) by `parts.json`.
pub fn template_parts(mesh_obj: &Path, parts_json: &Path) -> Result<BTreeMap<String, TriMesh>> {
    let (v, tris) = read_template(mesh_obj)?;
    let labels: Vec<f64> = serde_json::from_str(&read_text(parts_json)?)
        .map_err(|e| DataError::invalid(parts_json, format!("expected a list of 0/1: {e}")))?;
    if labels.len() != v.len() {
        return Err(DataError::invalid(
            parts_json,
            format!("{} labels for {} template vertices", labels.len(), v.len()),
        ));
    }
    let is_top = |i: u32| labels[i as usize] < 0.5;
    let mut out = BTreeMap::new();
    for (name, top) in [("bottom", false), ("top", true)] {
        let mut remap = vec![u32::MAX; v.len()];
        let mut mesh = TriMesh::default();
        for t in &tris {
            let tops = t.iter().filter(|&&i| is_top(i)).count();
            if (tops >= 2) != top {
                continue;
            }
            let mut nt = [0u32; 3];
            for (k, &i) in t.iter().enumerate() {
                if remap[i as usize] == u32::MAX {
                    remap[i as usize] = mesh.positions.len() as u32;
                    mesh.positions.push(v[i as usize] * 0.001);
                }
                nt[k] = remap[i as usize];
            }
            mesh.triangles.push(nt);
        }
        if mesh.triangles.is_empty() {
            return Err(DataError::invalid(
                parts_json,
                format!("the {name} part has no triangles"),
            ));
        }
        out.insert(name.to_string(), mesh);
    }
    Ok(out)
}

struct SubjectCamera {
    camera_from_world: Rigid,
    k: Matrix3,
    size: [u32; 2],
    ioi_offset: i64,
}

fn subject_camera(misc: &Path, subject: &str, camera: u32) -> Result<SubjectCamera> {
    let v: serde_json::Value = serde_json::from_str(&read_text(misc)?)
        .map_err(|e| DataError::invalid(misc, format!("invalid JSON: {e}")))?;
    let s = v
        .get(subject)
        .ok_or_else(|| DataError::invalid(misc, format!("no subject `{subject}`")))?;
    if !(1..=8).contains(&camera) {
        return Err(DataError::invalid(
            misc,
            format!("camera {camera}: ARCTIC's allocentric cameras are 1–8 (the egocentric view 0 is not supported)"),
        ));
    }
    let c = (camera - 1) as usize;
    let matrix = |key: &str, n: usize| -> Result<Vec<f64>> {
        let rows = s[key][c]
            .as_array()
            .ok_or_else(|| DataError::invalid(misc, format!("{subject}: no {key}[{c}]")))?;
        let flat: Vec<f64> = rows
            .iter()
            .flat_map(|r| {
                r.as_array()
                    .into_iter()
                    .flatten()
                    .filter_map(|x| x.as_f64())
            })
            .collect();
        if flat.len() != n * n {
            return Err(DataError::invalid(
                misc,
                format!("{subject}: {key}[{c}] is not {n}×{n}"),
            ));
        }
        Ok(flat)
    };
    let w2c = matrix("world2cam", 4)?;
    let m = agentstar_geom::Matrix4::from_row_slice(&w2c);
    let camera_from_world = agentstar_geom::pose::rigid_from_matrix(&m)
        .map_err(|e| DataError::invalid(misc, format!("{subject}: world2cam[{c}]: {e}")))?;
    let k = Matrix3::from_row_slice(&matrix("intris_mat", 3)?);
    let size = s["image_size"][camera as usize]
        .as_array()
        .and_then(|a| Some([a.first()?.as_u64()? as u32, a.get(1)?.as_u64()? as u32]))
        .ok_or_else(|| DataError::invalid(misc, format!("{subject}: no image_size[{camera}]")))?;
    Ok(SubjectCamera {
        camera_from_world,
        k,
        size,
        ioi_offset: s["ioi_offset"].as_i64().unwrap_or(0),
    })
}

/// Imports the sequence into `out` (a new directory); returns the frames written.
pub fn import_arctic(cfg: &ArcticImport, out: &Path) -> Result<FramesWritten> {
    let object = cfg
        .sequence
        .split('_')
        .next()
        .unwrap_or(&cfg.sequence)
        .to_string();
    check_between(&cfg.root, cfg.every, cfg.between)?;
    let meta = cfg.root.join("meta");
    let misc = meta.join("misc.json");
    let cam = subject_camera(&misc, &cfg.subject, cfg.camera)?;
    let array = cfg
        .root
        .join("raw_seqs")
        .join(&cfg.subject)
        .join(format!("{}.object.npy", cfg.sequence));
    let rows_in = read_object_rows(&array)?;
    let template = meta.join("object_vtemplates").join(&object);
    let meshes = template_parts(&template.join("mesh.obj"), &template.join("parts.json"))?;
    let images_dir = cfg.images.clone().unwrap_or_else(|| {
        cfg.root
            .join("images")
            .join(&cfg.subject)
            .join(&cfg.sequence)
            .join(cfg.camera.to_string())
    });
    let images = images_by_stem(&images_dir)?;
    let masks = cfg.masks.as_deref().map(images_by_stem).transpose()?;
    let hands = cfg.hands.as_deref().map(images_by_stem).transpose()?;
    let offset = cfg.offset.unwrap_or(cam.ioi_offset);
    let mut numbered: Vec<(i64, &String, &PathBuf)> = images
        .iter()
        .filter_map(|(s, p)| s.parse::<i64>().ok().map(|n| (n, s, p)))
        .filter(|(n, _, _)| (0..rows_in.len() as i64).contains(&(n - offset)))
        .collect();
    numbered.sort();
    if numbered.is_empty() {
        return Err(DataError::invalid(
            &images_dir,
            format!(
                "no image numbered within the object array's {} rows (offset {offset})",
                rows_in.len()
            ),
        ));
    }
    let (bottom, top) = (&meshes["bottom"], &meshes["top"]);
    let mut rows = vec![];
    for (k, keyframe) in select_frames(numbered.len(), cfg.every, cfg.between, cfg.max_frames) {
        let (n, stem, path) = numbered[k];
        let r = rows_in[(n - offset) as usize];
        let rgb = load_rgb(path)?;
        let (w, h) = rgb.dimensions();
        let kk = crate::cameras::rescaled(
            [cam.k[(0, 0)], cam.k[(1, 1)], cam.k[(0, 2)], cam.k[(1, 2)]],
            cam.size,
            [w, h],
        );
        let camera = PinholeCamera::new(kk[(0, 0)], kk[(1, 1)], kk[(0, 2)], kk[(1, 2)], w, h)
            .map_err(|e| DataError::invalid(&misc, format!("intrinsics: {e}")))?;
        let camera_from_bottom = cam.camera_from_world * r.world_from_object();
        let camera_from_top = camera_from_bottom * r.bottom_from_top();
        let mask = match &masks {
            Some(m) => load_kept_mask(m, cfg.masks.as_deref(), stem, keyframe, "image")?,
            None => render_parts_mask(
                &camera,
                &[(bottom, camera_from_bottom), (top, camera_from_top)],
            ),
        };
        let hand = optional_mask(hands.as_ref(), stem)?;
        rows.push(Row {
            name: format!("{stem}.png"),
            keyframe,
            frame_index: Some(n),
            time_s: None,
            camera,
            world_from_camera: cam.camera_from_world.inverse(),
            rgb,
            mask,
            hand,
            depth_m: None,
            parts: BTreeMap::from([
                ("bottom".to_string(), camera_from_bottom),
                ("top".to_string(), camera_from_top),
            ]),
            states: BTreeMap::from([("articulation".to_string(), r.angle_rad)]),
        });
    }
    let info = CaptureInfo {
        dataset: Some("arctic".into()),
        source: Some(
            serde_json::json!({"producer": "agentstar capture from-arctic",
            "root": cfg.root, "subject": cfg.subject, "sequence": cfg.sequence,
            "camera": cfg.camera, "offset": offset, "every": cfg.every,
            "between": cfg.between,
            "masks": if cfg.masks.is_some() { "given" } else { "rendered from the ground truth (hands not cut out)" }}),
        ),
        keyframes: None,
    };
    let model = GtModel {
        base_part: "bottom".into(),
        meshes,
        joints: vec![GtJoint {
            name: "articulation".into(),
            kind: "revolute".into(),
            parent: "bottom".into(),
            child: "top".into(),
            axis: ARTICULATION_AXIS,
            origin: [0.0; 3],
            states: BTreeMap::new(),
        }],
        symmetries: vec![],
    };
    write_rows(out, &rows, &info, &model)
}
