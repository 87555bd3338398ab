//! What the dataset importers share: an owned frame row, stem matching of mask folders, and
//! a single-part ground truth written beside the capture.

use agentstar_data::capture_writer::{write_capture, CaptureInfo, FrameOut};
use agentstar_data::gt::{GroundTruth, GtFile, GtFrame, GtJoint, GtPartFile, FORMAT};
use agentstar_data::posefile::PoseJson;
use agentstar_data::{DataError, Result};
use agentstar_geom::pose::{quat_to_wxyz, Rigid};
use agentstar_geom::{PinholeCamera, TriMesh};
use agentstar_mask::BitMask;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One imported frame, owned.
pub(crate) struct Row {
    pub name: String,
    pub frame_index: Option<i64>,
    pub time_s: Option<f64>,
    pub camera: PinholeCamera,
    pub world_from_camera: Rigid,
    pub rgb: image::RgbImage,
    pub mask: BitMask,
    pub hand: Option<BitMask>,
    pub depth_m: Option<Vec<f32>>,
    /// `camera_from_part` of every ground-truth part, by part name.
    pub parts: BTreeMap<String, Rigid>,
    /// Joint states by joint name.
    pub states: BTreeMap<String, f64>,
}

/// The ground-truth model of an import: part meshes (metres, own frames) and joints.
pub(crate) struct GtModel {
    pub base_part: String,
    pub meshes: BTreeMap<String, TriMesh>,
    pub joints: Vec<GtJoint>,
    pub symmetries: Vec<[f64; 4]>,
}

/// Writes the rows as a capture with its `gt.json` (all into a temporary sibling renamed
/// into place).
pub(crate) fn write_rows(
    out: &Path,
    rows: &[Row],
    info: &CaptureInfo,
    model: &GtModel,
) -> Result<()> {
    let frames: Vec<FrameOut<'_>> = rows
        .iter()
        .map(|r| FrameOut {
            name: &r.name,
            frame_index: r.frame_index,
            time_s: r.time_s,
            camera: &r.camera,
            world_from_camera: &r.world_from_camera,
            rgb: &r.rgb,
            mask: &r.mask,
            hand: r.hand.as_ref(),
            depth_m: r.depth_m.as_deref(),
        })
        .collect();
    write_capture(out, &frames, info, |root| {
        let mut joints = model.joints.clone();
        for j in &mut joints {
            j.states = rows
                .iter()
                .filter_map(|r| r.states.get(&j.name).map(|s| (r.name.clone(), *s)))
                .collect();
        }
        let file = GtFile {
            format: FORMAT.into(),
            units: "m".into(),
            base_part: model.base_part.clone(),
            parts: model
                .meshes
                .keys()
                .map(|p| {
                    (
                        p.clone(),
                        GtPartFile {
                            mesh: format!("gt_meshes/{p}.obj"),
                        },
                    )
                })
                .collect(),
            frames: rows
                .iter()
                .map(|r| {
                    let mut f = GtFrame::default();
                    for (p, pose) in &r.parts {
                        f.parts.insert(
                            p.clone(),
                            PoseJson {
                                quaternion: quat_to_wxyz(&pose.rotation),
                                translation: pose.translation.vector.into(),
                                scale: None,
                            },
                        );
                    }
                    (r.name.clone(), f)
                })
                .collect(),
            joints,
            symmetries: model.symmetries.clone(),
        };
        GroundTruth::from_parts(&root.join("gt.json"), file, model.meshes.clone()).write(root)
    })
}

/// Images in `dir` (png, jpg, …) by file stem.
pub(crate) fn images_by_stem(dir: &Path) -> Result<BTreeMap<String, PathBuf>> {
    const EXTS: [&str; 6] = ["png", "jpg", "jpeg", "bmp", "tif", "tiff"];
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir).map_err(|e| DataError::io(dir, e))? {
        let p = e.map_err(|e| DataError::io(dir, e))?.path();
        let ext_ok = p
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| EXTS.contains(&e.to_ascii_lowercase().as_str()));
        if let (true, Some(stem)) = (ext_ok, p.file_stem().and_then(|s| s.to_str())) {
            out.insert(stem.to_string(), p.clone());
        }
    }
    Ok(out)
}

/// The mask of frame `stem` in a folder indexed by [`images_by_stem`]: `stem.png`, or a
/// name that starts with the stem and a separator (`stem_mask.png`).
pub(crate) fn mask_for<'a>(
    masks: &'a BTreeMap<String, PathBuf>,
    stem: &str,
) -> Option<&'a PathBuf> {
    masks.get(stem).or_else(|| {
        masks
            .range(stem.to_string()..)
            .take_while(|(k, _)| k.starts_with(stem))
            .find(|(k, _)| k[stem.len()..].starts_with(['_', '-', '.']))
            .map(|(_, p)| p)
    })
}
