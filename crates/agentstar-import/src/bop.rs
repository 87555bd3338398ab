//! Importing one object of a BOP scene (`scene_gt.json`, `scene_camera.json`, `rgb/` or
//! `gray/`, `mask_visib/`, optional `depth/`, models in millimetres) as a `capture/v1`
//! directory with its `gt.json`. HOT3D clips converted to BOP load the same way.
//!
//! Decisions: the object is the first instance with `obj_id` in each image (images without
//! it are skipped); the visible masks of the other instances become don't-care occluder
//! masks (`mask_hand/`), as hands are; millimetres become metres; `cam_R_w2c`/`cam_t_w2c`
//! give the camera trajectory when present, else the camera is static; depth PNGs keep their
//! values converted to metres with each image's `depth_scale` (written as point maps); discrete and
//! continuous symmetries of `models_info.json` become `gt.json` symmetries as the BOP toolkit
//! lists them (continuous ones in its steps, [`agentstar_geom::truth::continuous_symmetry`],
//! alone and after each discrete one).

use crate::import_common::{check_between, select_frames, write_rows, GtModel, Row};
use crate::FramesWritten;
use agentstar_data::capture_writer::CaptureInfo;
use agentstar_data::images::{load_mask, load_rgb};
use agentstar_data::meshio::load_mesh;
use agentstar_data::{read_text, DataError, Result};
use agentstar_geom::pose::{quat_to_wxyz, Rigid};
use agentstar_geom::{Matrix3, PinholeCamera, UnitQuaternion, Vector3};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize)]
struct GtEntry {
    #[serde(rename = "cam_R_m2c")]
    cam_r_m2c: [f64; 9],
    cam_t_m2c: [f64; 3],
    obj_id: u32,
}

#[derive(Debug, Deserialize)]
struct CamEntry {
    #[serde(rename = "cam_K")]
    cam_k: [f64; 9],
    #[serde(default)]
    depth_scale: Option<f64>,
    #[serde(default, rename = "cam_R_w2c")]
    cam_r_w2c: Option<[f64; 9]>,
    #[serde(default)]
    cam_t_w2c: Option<[f64; 3]>,
}

/// What to import.
#[derive(Debug, Clone)]
pub struct BopImport {
    /// The scene directory (holding `scene_gt.json`).
    pub scene: PathBuf,
    /// The models directory (holding `obj_XXXXXX.ply`, optionally `models_info.json`).
    pub models: PathBuf,
    pub obj_id: u32,
    /// Keep every n-th image holding the object (the keyframes).
    pub every: usize,
    /// Keep the images between keyframes too, as in-between frames (`formats.md` §2):
    /// every N-th image holding the object after each keyframe, N from 1 to `every` − 1;
    /// `None`: keyframes only.
    pub between: Option<usize>,
    pub depth: bool,
}

fn rotation(r: &[f64; 9], path: &Path, what: &str) -> Result<UnitQuaternion> {
    let m = Matrix3::from_row_slice(r);
    let err = (m.transpose() * m - Matrix3::identity()).abs().max();
    if !(err < 1e-3 && (m.determinant() - 1.0).abs() < 1e-3) {
        return Err(DataError::invalid(
            path,
            format!(
                "{what} is not a rotation (‖RᵀR − I‖ = {err:.2e}, det {:.4})",
                m.determinant()
            ),
        ));
    }
    Ok(UnitQuaternion::from_matrix(&m))
}

fn symmetries(models: &Path, obj_id: u32) -> Result<Vec<[f64; 4]>> {
    let info = models.join("models_info.json");
    if !info.is_file() {
        return Ok(vec![]);
    }
    let v: serde_json::Value = serde_json::from_str(&read_text(&info)?)
        .map_err(|e| DataError::invalid(&info, format!("invalid JSON: {e}")))?;
    let o = &v[obj_id.to_string()];
    let mut discrete: Vec<UnitQuaternion> = vec![];
    if let Some(list) = o["symmetries_discrete"].as_array() {
        for m in list {
            let vals: Vec<f64> = m
                .as_array()
                .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
                .unwrap_or_default();
            if vals.len() == 16 {
                let r = [
                    vals[0], vals[1], vals[2], vals[4], vals[5], vals[6], vals[8], vals[9],
                    vals[10],
                ];
                discrete.push(rotation(&r, &info, "a discrete symmetry")?);
            }
        }
    }
    let mut continuous: Vec<UnitQuaternion> = vec![];
    if let Some(list) = o["symmetries_continuous"].as_array() {
        for s in list {
            let axis: Vec<f64> = s["axis"]
                .as_array()
                .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
                .unwrap_or_default();
            if axis.len() == 3 {
                let a = agentstar_geom::nalgebra::Unit::new_normalize(Vector3::new(
                    axis[0], axis[1], axis[2],
                ));
                continuous.extend(agentstar_geom::truth::continuous_symmetry(&a));
            }
        }
    }
    // As the BOP toolkit lists them: every discrete one, every continuous turn, and each
    // turn after each discrete one (a flip, then a turn about the axis).
    let mut out: Vec<[f64; 4]> = discrete.iter().map(quat_to_wxyz).collect();
    out.extend(continuous.iter().map(quat_to_wxyz));
    for c in &continuous {
        out.extend(discrete.iter().map(|d| quat_to_wxyz(&(c * d))));
    }
    Ok(out)
}

/// Imports one object of a BOP scene into `out` (a new directory). Returns the frames
/// written.
pub fn import_bop(cfg: &BopImport, out: &Path) -> Result<FramesWritten> {
    check_between(&cfg.scene, cfg.every, cfg.between)?;
    let gt_path = cfg.scene.join("scene_gt.json");
    let cam_path = cfg.scene.join("scene_camera.json");
    let scene_gt: BTreeMap<String, Vec<GtEntry>> = serde_json::from_str(&read_text(&gt_path)?)
        .map_err(|e| DataError::invalid(&gt_path, format!("invalid scene_gt: {e}")))?;
    let scene_cam: BTreeMap<String, CamEntry> = serde_json::from_str(&read_text(&cam_path)?)
        .map_err(|e| DataError::invalid(&cam_path, format!("invalid scene_camera: {e}")))?;
    let mut ids: Vec<u64> = scene_gt
        .keys()
        .map(|k| {
            k.parse::<u64>().map_err(|_| {
                DataError::invalid(&gt_path, format!("image id `{k}` is not an integer"))
            })
        })
        .collect::<Result<_>>()?;
    ids.sort_unstable();
    let model_path = cfg.models.join(format!("obj_{:06}.ply", cfg.obj_id));
    let mesh_mm = load_mesh(&model_path)?;
    let mesh_m = mesh_mm.transformed(&(Matrix3::identity() * 0.001), &Vector3::zeros());
    // The images holding the object, with the object's entry in each.
    let holding: Vec<(u64, usize)> = ids
        .iter()
        .filter_map(|&id| {
            scene_gt[&id.to_string()]
                .iter()
                .position(|e| e.obj_id == cfg.obj_id)
                .map(|gi| (id, gi))
        })
        .collect();
    let mut rows: Vec<Row> = vec![];
    for (at, keyframe) in select_frames(holding.len(), cfg.every, cfg.between, None) {
        let (id, gi) = holding[at];
        let key = id.to_string();
        let entries = &scene_gt[&key];
        let cam = scene_cam
            .get(&key)
            .ok_or_else(|| DataError::invalid(&cam_path, format!("image {id} has no camera")))?;
        let stem = format!("{id:06}");
        let rgb_path = ["rgb", "gray"]
            .iter()
            .flat_map(|d| {
                ["png", "jpg", "tif"].map(|e| cfg.scene.join(d).join(format!("{stem}.{e}")))
            })
            .find(|p| p.is_file())
            .ok_or_else(|| {
                DataError::invalid(&cfg.scene, format!("image {id}: no rgb/{stem}.png or .jpg"))
            })?;
        let rgb = load_rgb(&rgb_path)?;
        let (w, h) = rgb.dimensions();
        let k = &cam.cam_k;
        let camera = PinholeCamera::new(k[0], k[4], k[2], k[5], w, h)
            .map_err(|e| DataError::invalid(&cam_path, format!("image {id}: {e}")))?;
        let c2w = match (&cam.cam_r_w2c, &cam.cam_t_w2c) {
            (Some(r), Some(t)) => {
                let q = rotation(r, &cam_path, &format!("image {id}: cam_R_w2c"))?;
                Rigid::from_parts(
                    agentstar_geom::nalgebra::Translation3::from(
                        Vector3::new(t[0], t[1], t[2]) * 0.001,
                    ),
                    q,
                )
                .inverse()
            }
            _ => Rigid::identity(),
        };
        let mask_path = |i: usize| {
            cfg.scene
                .join("mask_visib")
                .join(format!("{stem}_{i:06}.png"))
        };
        let mask = load_mask(&mask_path(gi))?;
        let mut occluders: Option<agentstar_mask::BitMask> = None;
        for (i, _) in entries.iter().enumerate().filter(|(i, _)| *i != gi) {
            let p = mask_path(i);
            if p.is_file() {
                let m = load_mask(&p)?;
                occluders = Some(match occluders {
                    Some(o) => o.or(&m),
                    None => m,
                });
            }
        }
        let depth = if cfg.depth {
            let p = cfg.scene.join("depth").join(format!("{stem}.png"));
            let img = agentstar_data::images::decode_image(&p, "depth")?.to_luma16();
            let s = cam.depth_scale.unwrap_or(1.0) * 0.001;
            Some(
                img.pixels()
                    .map(|p| {
                        if p[0] == 0 {
                            f32::NAN
                        } else {
                            (p[0] as f64 * s) as f32
                        }
                    })
                    .collect(),
            )
        } else {
            None
        };
        let e = &entries[gi];
        let q = rotation(&e.cam_r_m2c, &gt_path, &format!("image {id}: cam_R_m2c"))?;
        let t = Vector3::new(e.cam_t_m2c[0], e.cam_t_m2c[1], e.cam_t_m2c[2]) * 0.001;
        rows.push(Row {
            name: format!("{stem}.png"),
            keyframe,
            frame_index: Some(id as i64),
            time_s: None,
            camera,
            world_from_camera: c2w,
            rgb,
            mask,
            hand: occluders,
            depth_m: depth,
            parts: BTreeMap::from([("object".to_string(), Rigid::from_parts(t.into(), q))]),
            states: BTreeMap::new(),
        });
    }
    if rows.is_empty() {
        return Err(DataError::invalid(
            &gt_path,
            format!("no image holds object {}", cfg.obj_id),
        ));
    }
    let info = CaptureInfo {
        dataset: Some("bop".into()),
        source: Some(serde_json::json!({"producer": "agentstar capture from-bop",
            "scene": cfg.scene, "obj_id": cfg.obj_id, "every": cfg.every,
            "between": cfg.between})),
        keyframes: None,
    };
    let model = GtModel {
        base_part: "object".into(),
        meshes: BTreeMap::from([("object".to_string(), mesh_m)]),
        joints: vec![],
        symmetries: symmetries(&cfg.models, cfg.obj_id)?,
    };
    write_rows(out, &rows, &info, &model)
}
