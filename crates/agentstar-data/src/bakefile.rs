//! A model's baked appearance on disk, beside the model file: `<stem>.bake.json` (what was
//! baked from what: the capture, its frames, the pose file and its version, and the
//! fingerprint of the tessellation it was baked on) and the atlas it names,
//! `<stem>.bake-<hash>.png` (RGBA: the colours, alpha 255 where a frame saw the texel).
//!
//! Writing: the atlas under a name of its own content first, then the JSON (the commit
//! point), then older atlases of the same model are removed; a writer stopped anywhere
//! leaves the previous bake whole or the new one.
//!
//! Loading ([`crate::scenefile::load_model`] for every command): a bake whose tessellation
//! fingerprint is the model's is applied (every part textured by the atlas); a stale one
//! (the script changed the shape since) or a broken one is ignored with a warning naming
//! the file, never applied to a shape it was not made for.

use crate::{DataError, Result};
use agentstar_geom::{tessellation_fingerprint, with_atlas, AtlasLayout, ObjectModel, Texture};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The format tag of a bake file.
pub const BAKE_FORMAT: &str = "agentstar-bake/1";

/// `<stem>.bake.json`: a baked appearance and its provenance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BakeFile {
    pub format: String,
    /// The model file it belongs to (its name, beside it).
    pub model: String,
    /// [`tessellation_fingerprint`] of the model it was baked on.
    pub tessellation: String,
    /// The atlas image's file name, beside this file.
    pub atlas: String,
    pub atlas_width: u32,
    pub atlas_height: u32,
    /// The atlas's density, texels per model unit of length.
    pub texels_per_unit: f64,
    /// The capture, pose file and keyframes it was baked from.
    pub capture: PathBuf,
    pub poses: PathBuf,
    /// The pose file's history version baked from (`None`: the file did not match its
    /// newest version, or had no history).
    pub pose_version: Option<u64>,
    pub frames: Vec<String>,
    /// Share of the triangles' texels some frame saw.
    pub seen_fraction: f64,
    /// Weighted colour spread over texels seen by two frames or more (8-bit units).
    pub spread: Option<f64>,
    /// Frames that disagreed with the others (stored only with `forced`).
    pub disagreeing: Vec<String>,
    /// Stored although frames disagreed (`bake --force`).
    pub forced: bool,
    pub command: String,
    pub time_unix_s: u64,
}

/// `<dir>/<stem>.bake.json` for the model file `model`.
pub fn bake_path(model: &Path) -> PathBuf {
    let stem = model
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("model");
    model.with_file_name(format!("{stem}.bake.json"))
}

fn atlas_prefix(model: &Path) -> String {
    let stem = model
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("model");
    format!("{stem}.bake-")
}

fn fnv_hex(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Writes the bake of the model file `model`: `atlas` (RGBA, `file.atlas_width` ×
/// `file.atlas_height`) under a name of its content, then `file` naming it; older atlases of
/// this model are removed after. Returns the JSON's path.
pub fn write_bake(model: &Path, file: &mut BakeFile, atlas: &image::RgbaImage) -> Result<PathBuf> {
    let json = bake_path(model);
    if (atlas.width(), atlas.height()) != (file.atlas_width, file.atlas_height) {
        return Err(DataError::invalid(
            &json,
            format!(
                "an atlas of {}×{} for a bake of {}×{}",
                atlas.width(),
                atlas.height(),
                file.atlas_width,
                file.atlas_height
            ),
        ));
    }
    let mut png = std::io::Cursor::new(Vec::new());
    atlas
        .write_to(&mut png, image::ImageFormat::Png)
        .map_err(|e| DataError::invalid(&json, format!("cannot encode the atlas: {e}")))?;
    let png = png.into_inner();
    let name = format!("{}{}.png", atlas_prefix(model), fnv_hex(&png));
    let atlas_path = model.with_file_name(&name);
    crate::atomic::write_atomic(&atlas_path, &png)?;
    file.atlas = name.clone();
    crate::atomic::write_json(&json, file)?;
    // Older atlases of this model (best effort: a leftover is never read).
    let dir = match model.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if let Ok(rd) = std::fs::read_dir(dir) {
        let prefix = atlas_prefix(model);
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().to_string();
            if n != name && n.starts_with(&prefix) && n.ends_with(".png") {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
    Ok(json)
}

/// Reads a bake file.
pub fn read_bake(path: &Path) -> Result<BakeFile> {
    let text = crate::read_text(path)?;
    let file: BakeFile = crate::parse_json(&text)
        .map_err(|e| DataError::invalid(path, format!("not a bake file: {e}")))?;
    if file.format != BAKE_FORMAT {
        return Err(DataError::invalid(
            path,
            format!("format `{}`; this agentstar reads `{BAKE_FORMAT}`", file.format),
        ));
    }
    Ok(file)
}

/// What loading a model did with the bake beside it.
#[derive(Debug, Clone, PartialEq)]
pub enum BakePickup {
    /// No bake file beside the model.
    None,
    /// Applied: the model is textured by it.
    Applied(PathBuf),
    /// Not applied, with the warning that says why (stale or unreadable).
    Ignored(String),
}

/// `model` (loaded from the file `model_path`) with the bake beside it applied where it is
/// for this tessellation.
pub fn pick_up_bake(model_path: &Path, model: &ObjectModel) -> (Option<ObjectModel>, BakePickup) {
    let path = bake_path(model_path);
    if !path.is_file() {
        return (None, BakePickup::None);
    }
    match apply_bake(&path, model) {
        Ok(m) => (Some(m), BakePickup::Applied(path)),
        Err(why) => (None, BakePickup::Ignored(why)),
    }
}

fn apply_bake(path: &Path, model: &ObjectModel) -> std::result::Result<ObjectModel, String> {
    let file = read_bake(path).map_err(|e| format!("{e}; the baked colours are ignored"))?;
    let now = tessellation_fingerprint(model);
    if file.tessellation != now {
        return Err(format!(
            "{} is stale: it was baked on tessellation {}, the model's is now {now} (its shape changed); the baked colours are ignored — run `agentstar bake` again",
            path.display(),
            file.tessellation
        ));
    }
    let atlas_name = Path::new(&file.atlas);
    if atlas_name.components().count() != 1 || atlas_name.is_absolute() {
        return Err(format!(
            "{}: the atlas `{}` is not a file name beside it; the baked colours are ignored",
            path.display(),
            file.atlas
        ));
    }
    let atlas_path = path.with_file_name(&file.atlas);
    let img = crate::images::decode_image(&atlas_path, "a baked atlas")
        .map_err(|e| format!("{e}; the baked colours are ignored"))?
        .to_rgb8();
    if (img.width(), img.height()) != (file.atlas_width, file.atlas_height) {
        return Err(format!(
            "{}: {}×{} texels, the bake says {}×{}; the baked colours are ignored",
            atlas_path.display(),
            img.width(),
            img.height(),
            file.atlas_width,
            file.atlas_height
        ));
    }
    let fail = |e: agentstar_geom::GeomError| {
        format!(
            "{}: {e}; the baked colours are ignored",
            path.display()
        )
    };
    let layout = AtlasLayout::new(model, file.texels_per_unit, file.atlas_width).map_err(fail)?;
    if layout.height != file.atlas_height {
        return Err(format!(
            "{}: the atlas lays out {} texels high, the bake says {}; the baked colours are ignored",
            path.display(),
            layout.height,
            file.atlas_height
        ));
    }
    let texture = Texture::new(
        atlas_path.display().to_string(),
        img.width(),
        img.height(),
        img.into_raw(),
    )
    .map_err(fail)?;
    with_atlas(model, &layout, Arc::new(texture)).map_err(fail)
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::{KinematicTree, Part};

    fn model(depth: f64) -> ObjectModel {
        ObjectModel {
            parts: vec![Part::new("body", cuboid(1.0, 0.5, depth).expect("box"), [0.5; 3])],
            tree: KinematicTree::rigid(1),
        }
    }

    fn bake_of(m: &ObjectModel) -> (BakeFile, image::RgbaImage) {
        let layout = AtlasLayout::new(m, 16.0, 64).expect("layout");
        let atlas = image::RgbaImage::from_pixel(layout.width, layout.height, image::Rgba([200, 30, 40, 255]));
        let file = BakeFile {
            format: BAKE_FORMAT.into(),
            model: "scene.rhai".into(),
            tessellation: tessellation_fingerprint(m),
            atlas: String::new(),
            atlas_width: layout.width,
            atlas_height: layout.height,
            texels_per_unit: 16.0,
            capture: "capture".into(),
            poses: "pose.json".into(),
            pose_version: Some(3),
            frames: vec!["000000.png".into()],
            seen_fraction: 1.0,
            spread: None,
            disagreeing: vec![],
            forced: false,
            command: "test".into(),
            time_unix_s: 0,
        };
        (file, atlas)
    }

    #[test]
    fn a_bake_is_applied_to_its_shape_and_ignored_with_a_warning_when_stale() {
        let dir = tempfile::tempdir().expect("dir");
        let script = dir.path().join("scene.rhai");
        let m = model(0.25);
        assert_eq!(pick_up_bake(&script, &m).1, BakePickup::None);
        let (mut file, atlas) = bake_of(&m);
        let json = write_bake(&script, &mut file, &atlas).expect("write");
        assert_eq!(json, dir.path().join("scene.bake.json"));
        let (applied, pickup) = pick_up_bake(&script, &m);
        assert_eq!(pickup, BakePickup::Applied(json.clone()));
        let c = applied.expect("model").parts[0].color;
        assert!((c[0] - 200.0 / 255.0).abs() < 1e-3, "{c:?}");
        // The shape changed: stale, named, not applied.
        let (none, pickup) = pick_up_bake(&script, &model(0.3));
        assert!(none.is_none());
        match pickup {
            BakePickup::Ignored(w) => {
                assert!(w.contains("scene.bake.json") && w.contains("stale"), "{w}")
            }
            other => panic!("{other:?}"),
        }
        // A second bake replaces the atlas; the first one's image is gone.
        let first = dir.path().join(&file.atlas);
        let (mut again, mut atlas2) = bake_of(&m);
        atlas2.put_pixel(0, 0, image::Rgba([1, 2, 3, 255]));
        write_bake(&script, &mut again, &atlas2).expect("again");
        assert_ne!(again.atlas, file.atlas);
        assert!(!first.exists() && dir.path().join(&again.atlas).is_file());
        // A missing atlas: ignored, naming it.
        std::fs::remove_file(dir.path().join(&again.atlas)).expect("rm");
        match pick_up_bake(&script, &m).1 {
            BakePickup::Ignored(w) => assert!(w.contains(&again.atlas), "{w}"),
            other => panic!("{other:?}"),
        }
    }
}
