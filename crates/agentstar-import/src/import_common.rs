//! What the dataset importers share: which source frames are kept (keyframes and, on
//! request, in-between frames), an owned frame row, stem matching of mask folders, and the
//! ground truth written beside the capture (keyframes only).

use crate::video::FrameFiles;
use crate::FramesWritten;
use agentstar_data::capture_writer::{write_capture, CaptureInfo, FrameOut};
use agentstar_data::gt::{GroundTruth, GtFile, GtFrame, GtJoint, GtPartFile, FORMAT};
use agentstar_data::posefile::PoseJson;
use agentstar_data::{DataError, Result};
use agentstar_geom::pose::{quat_to_wxyz, Rigid};
use agentstar_geom::{PinholeCamera, TriMesh};
use agentstar_mask::BitMask;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The positions an import keeps among `n` source frames in order, each with whether it is
/// a keyframe, ascending: every `every`-th from the first as keyframes (at most
/// `max_keyframes`), and with `between` every N-th frame after each keyframe, before the
/// next, as in-between frames (`formats.md` §2; the rule of `capture from-video --between`,
/// [`FrameFiles::between_indices`]). The stride is checked by
/// [`crate::between_stride_problem`] first.
pub(crate) fn select_frames(
    n: usize,
    every: usize,
    between: Option<usize>,
    max_keyframes: Option<usize>,
) -> Vec<(usize, bool)> {
    let keyframes: Vec<usize> = (0..n)
        .step_by(every.max(1))
        .take(max_keyframes.unwrap_or(usize::MAX))
        .collect();
    let in_between = between
        .map(|stride| FrameFiles::between_indices(&keyframes, stride))
        .unwrap_or_default();
    let mut kept: Vec<(usize, bool)> = keyframes
        .iter()
        .map(|&i| (i, true))
        .chain(in_between.iter().map(|&i| (i, false)))
        .collect();
    kept.sort_unstable();
    kept
}

/// Refuses an in-between stride that keeps nothing ([`crate::between_stride_problem`]),
/// naming the source.
pub(crate) fn check_between(source: &Path, every: usize, between: Option<usize>) -> Result<()> {
    match crate::between_stride_problem(every, between) {
        Some(problem) => Err(DataError::invalid(source, problem)),
        None => Ok(()),
    }
}

/// One imported frame, owned.
pub(crate) struct Row {
    pub name: String,
    /// A keyframe, or an in-between frame (kept on request; no ground truth is written for
    /// it).
    pub keyframe: bool,
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
/// into place). Where some rows are in-between frames, `capture.json` lists the keyframes
/// (`info.keyframes` is set here) and `gt.json` holds the keyframes only.
pub(crate) fn write_rows(
    out: &Path,
    rows: &[Row],
    info: &CaptureInfo,
    model: &GtModel,
) -> Result<FramesWritten> {
    let keyframes: Vec<&Row> = rows.iter().filter(|r| r.keyframe).collect();
    if keyframes.is_empty() {
        return Err(DataError::invalid(
            out,
            format!(
                "none of the {} frames kept is a keyframe (every keyframe was skipped); keep keyframes closer together (a smaller --every)",
                rows.len()
            ),
        ));
    }
    let info = CaptureInfo {
        keyframes: (keyframes.len() < rows.len())
            .then(|| keyframes.iter().map(|r| r.name.clone()).collect()),
        ..info.clone()
    };
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
    write_capture(out, &frames, &info, |root| {
        let mut joints = model.joints.clone();
        for j in &mut joints {
            j.states = keyframes
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
            frames: keyframes
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
    })?;
    Ok(FramesWritten {
        keyframes: keyframes.len(),
        between: rows.len() - keyframes.len(),
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

/// The mask of a kept frame `stem` in a folder `dir` indexed by [`images_by_stem`]
/// ([`mask_for`]), read; where there is none, an error naming the keyframe or in-between
/// `unit` (`image`, `frame`: what the dataset calls one).
pub(crate) fn load_kept_mask(
    masks: &BTreeMap<String, PathBuf>,
    dir: Option<&Path>,
    stem: &str,
    keyframe: bool,
    unit: &str,
) -> Result<BitMask> {
    let path = mask_for(masks, stem).ok_or_else(|| {
        DataError::invalid(
            dir.unwrap_or(Path::new("")),
            format!(
                "no mask for {} `{stem}` (every {unit} kept needs one)",
                if keyframe {
                    "keyframe".to_string()
                } else {
                    format!("in-between {unit}")
                }
            ),
        )
    })?;
    agentstar_data::images::load_mask(path)
}

/// The mask of frame `stem` in a folder indexed by [`images_by_stem`] ([`mask_for`]), read,
/// where there is a folder and it has one (hand masks: a frame without one has no hands).
pub(crate) fn optional_mask(
    masks: Option<&BTreeMap<String, PathBuf>>,
    stem: &str,
) -> Result<Option<BitMask>> {
    masks
        .and_then(|m| mask_for(m, stem))
        .map(|p| agentstar_data::images::load_mask(p))
        .transpose()
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
