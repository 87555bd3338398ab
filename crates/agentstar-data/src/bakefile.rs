//! A model's baked appearance on disk, beside the model file: `<stem>.bake.json` (what was
//! baked from what: the capture, its frames, the pose file and its version, and the
//! fingerprint of the tessellation it was baked on), the atlas it names,
//! `<stem>.bake-<hash>.png` (RGBA: the colours, alpha 255 where a frame saw the texel), and
//! the triangles it was laid out on, `<stem>.bake-<hash>.tris` (per part, each triangle's
//! corners as little-endian f64).
//!
//! Writing: the atlas under a name of its own content first, then the JSON (the commit
//! point), then older atlases of the same model are removed; a writer stopped anywhere
//! leaves the previous bake whole or the new one.
//!
//! Loading ([`crate::scenefile::load_model`] for every command): a bake whose tessellation
//! fingerprint is the model's is applied (every part textured by the atlas). Another
//! triangulation of the same surface (a script's booleans may split a flat face along other
//! diagonals from one build to the next) gets the atlas moved onto its own layout, each
//! texel reading the baked triangle that holds its point ([`AtlasTransfer`]). A stale bake
//! (some texel's point lies on no baked triangle: the script changed the shape since) or a
//! broken one is ignored with a warning naming the file, never applied to a shape it was
//! not made for.

use crate::{DataError, Result};
use agentstar_geom::{
    tessellation_fingerprint, with_atlas, AtlasLayout, AtlasTransfer, KinematicTree, ObjectModel,
    Part, Point3, Texture, TriMesh,
};
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
    /// The file of the triangles it was laid out on, beside this file.
    pub triangles: String,
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

const TRIANGLES_MAGIC: &[u8; 8] = b"ASTRIS1\0";

/// The triangles of every part of `model`, as the `.tris` file holds them.
fn encode_triangles(model: &ObjectModel) -> Vec<u8> {
    let mut out = TRIANGLES_MAGIC.to_vec();
    out.extend((model.parts.len() as u64).to_le_bytes());
    for part in &model.parts {
        out.extend((part.mesh.triangles.len() as u64).to_le_bytes());
        for t in 0..part.mesh.triangles.len() {
            for p in part.mesh.triangle(t) {
                for v in [p.x, p.y, p.z] {
                    out.extend(v.to_le_bytes());
                }
            }
        }
    }
    out
}

/// A model of the parts a `.tris` file holds (unwelded: three vertices per triangle).
fn decode_triangles(bytes: &[u8]) -> std::result::Result<ObjectModel, String> {
    let mut at = 0usize;
    let mut take = |n: usize| -> std::result::Result<&[u8], String> {
        let s = bytes
            .get(at..at + n)
            .ok_or_else(|| "the triangles file ends early".to_string())?;
        at += n;
        Ok(s)
    };
    if take(8)? != TRIANGLES_MAGIC {
        return Err("not a triangles file".into());
    }
    let u64_of = |b: &[u8]| u64::from_le_bytes(b.try_into().unwrap_or([0; 8]));
    let parts = u64_of(take(8)?);
    if parts > 65_535 {
        return Err(format!("{parts} parts"));
    }
    let mut out = Vec::new();
    for i in 0..parts {
        let n = u64_of(take(8)?) as usize;
        if n.saturating_mul(72) > bytes.len() {
            return Err(format!(
                "part {i}: {n} triangles in a file of {} bytes",
                bytes.len()
            ));
        }
        let mut positions = Vec::with_capacity(3 * n);
        for _ in 0..3 * n {
            let mut v = [0.0; 3];
            for c in &mut v {
                *c = f64::from_le_bytes(take(8)?.try_into().unwrap_or([0; 8]));
            }
            if v.iter().any(|c| !c.is_finite()) {
                return Err(format!("part {i}: a corner that is not finite"));
            }
            positions.push(Point3::new(v[0], v[1], v[2]));
        }
        let triangles = (0..n as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        out.push(Part::new(
            format!("part {i}"),
            TriMesh::new(positions, triangles),
            [0.5; 3],
        ));
    }
    Ok(ObjectModel {
        tree: KinematicTree::rigid(out.len()),
        parts: out,
    })
}

/// Writes the bake of the model file `model` (`baked`: the model as it was baked on):
/// `atlas` (RGBA, `file.atlas_width` × `file.atlas_height`) and the triangles under names of
/// the atlas's content, then `file` naming them; older ones of this model are removed after.
/// Returns the JSON's path.
pub fn write_bake(
    model: &Path,
    baked: &ObjectModel,
    file: &mut BakeFile,
    atlas: &image::RgbaImage,
) -> Result<PathBuf> {
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
    let hash = fnv_hex(&png);
    let name = format!("{}{hash}.png", atlas_prefix(model));
    let tris = format!("{}{hash}.tris", atlas_prefix(model));
    crate::atomic::write_atomic(&model.with_file_name(&name), &png)?;
    crate::atomic::write_atomic(&model.with_file_name(&tris), &encode_triangles(baked))?;
    file.atlas = name.clone();
    file.triangles = tris.clone();
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
            if n != name
                && n != tris
                && n.starts_with(&prefix)
                && (n.ends_with(".png") || n.ends_with(".tris"))
            {
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
            format!(
                "format `{}`; this agentstar reads `{BAKE_FORMAT}`",
                file.format
            ),
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

/// A file name beside the bake file, refused when it is not one.
fn beside(path: &Path, name: &str) -> std::result::Result<PathBuf, String> {
    let n = Path::new(name);
    if n.components().count() != 1 || n.is_absolute() || name.is_empty() {
        return Err(format!(
            "{}: `{name}` is not a file name beside it; the baked colours are ignored",
            path.display()
        ));
    }
    Ok(path.with_file_name(name))
}

fn apply_bake(path: &Path, model: &ObjectModel) -> std::result::Result<ObjectModel, String> {
    let file = read_bake(path).map_err(|e| format!("{e}; the baked colours are ignored"))?;
    let ignored =
        |what: String| format!("{}: {what}; the baked colours are ignored", path.display());
    let atlas_path = beside(path, &file.atlas)?;
    let img = crate::images::decode_image(&atlas_path, "a baked atlas")
        .map_err(|e| format!("{e}; the baked colours are ignored"))?
        .to_rgba8();
    if (img.width(), img.height()) != (file.atlas_width, file.atlas_height) {
        return Err(ignored(format!(
            "{} has {}×{} texels, the bake says {}×{}",
            atlas_path.display(),
            img.width(),
            img.height(),
            file.atlas_width,
            file.atlas_height
        )));
    }
    let layout = |m: &ObjectModel| -> std::result::Result<AtlasLayout, String> {
        let l = AtlasLayout::new(m, file.texels_per_unit, file.atlas_width)
            .map_err(|e| ignored(e.to_string()))?;
        Ok(l)
    };
    let now = tessellation_fingerprint(model);
    let rgba = if file.tessellation == now {
        let l = layout(model)?;
        if l.height != file.atlas_height {
            return Err(ignored(format!(
                "the atlas lays out {} texels high, the bake says {}",
                l.height, file.atlas_height
            )));
        }
        (l, img.into_raw())
    } else {
        // Another triangulation: of the same surface, or of another shape.
        let stale = |why: &str| {
            format!(
                "{} is stale: it was baked on tessellation {}, the model's is now {now} ({why}); the baked colours are ignored — run `agentstar bake` again",
                path.display(),
                file.tessellation
            )
        };
        let tris_path = beside(path, &file.triangles)?;
        let bytes = crate::read_bounded(&tris_path, crate::limits::BINARY_BYTES)
            .map_err(|e| format!("{e}; the baked colours are ignored"))?;
        let baked = decode_triangles(&bytes)
            .map_err(|e| ignored(format!("{}: {e}", tris_path.display())))?;
        if tessellation_fingerprint(&baked) != file.tessellation {
            return Err(ignored(format!(
                "{} is not the tessellation the bake names",
                tris_path.display()
            )));
        }
        let baked_layout = layout(&baked)?;
        if baked_layout.height != file.atlas_height {
            return Err(ignored(
                "the atlas does not lay out on its triangles".into(),
            ));
        }
        let l = layout(model).map_err(|_| stale("its shape changed"))?;
        let size = model
            .parts
            .iter()
            .map(|p| (p.bounds.max - p.bounds.min).norm())
            .fold(0.0, f64::max);
        let raw = img.into_raw();
        let moved = AtlasTransfer {
            baked: &baked,
            baked_layout: &baked_layout,
            baked_rgba: &raw,
        }
        .onto(model, &l, 1e-6 * size.max(1e-9))
        .map_err(|_| stale("its shape changed"))?;
        (l, moved)
    };
    let (l, rgba) = rgba;
    let rgb: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|c| [c[0], c[1], c[2]])
        .collect();
    let texture = Texture::new(atlas_path.display().to_string(), l.width, l.height, rgb)
        .map_err(|e| ignored(e.to_string()))?;
    with_atlas(model, &l, Arc::new(texture)).map_err(|e| ignored(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::{KinematicTree, Part};

    fn model(depth: f64) -> ObjectModel {
        ObjectModel {
            parts: vec![Part::new(
                "body",
                cuboid(1.0, 0.5, depth).expect("box"),
                [0.5; 3],
            )],
            tree: KinematicTree::rigid(1),
        }
    }

    fn bake_of(m: &ObjectModel) -> (BakeFile, image::RgbaImage) {
        let layout = AtlasLayout::new(m, 16.0, 64).expect("layout");
        let atlas = image::RgbaImage::from_pixel(
            layout.width,
            layout.height,
            image::Rgba([200, 30, 40, 255]),
        );
        let file = BakeFile {
            format: BAKE_FORMAT.into(),
            model: "scene.rhai".into(),
            tessellation: tessellation_fingerprint(m),
            atlas: String::new(),
            triangles: String::new(),
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
        let json = write_bake(&script, &m, &mut file, &atlas).expect("write");
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
        write_bake(&script, &m, &mut again, &atlas2).expect("again");
        assert_ne!(again.atlas, file.atlas);
        assert!(!first.exists() && dir.path().join(&again.atlas).is_file());
        assert!(!dir.path().join(&file.triangles).exists());
        assert!(dir.path().join(&again.triangles).is_file());
        // The same surface with its triangles in another order and its vertices renumbered
        // (what a script's booleans may return): applied, the same colours.
        let mesh = &m.parts[0].mesh;
        let mut reordered = m.clone();
        let mut triangles = mesh.triangles.clone();
        triangles.reverse();
        reordered.parts[0] = Part::new(
            "body",
            TriMesh::new(mesh.positions.clone(), triangles),
            [0.5; 3],
        );
        let (moved, pickup) = pick_up_bake(&script, &reordered);
        assert!(matches!(pickup, BakePickup::Applied(_)), "{pickup:?}");
        let c = moved.expect("model").parts[0].color;
        assert!((c[0] - 200.0 / 255.0).abs() < 1e-2, "{c:?}");
        // A missing atlas: ignored, naming it.
        std::fs::remove_file(dir.path().join(&again.atlas)).expect("rm");
        match pick_up_bake(&script, &m).1 {
            BakePickup::Ignored(w) => assert!(w.contains(&again.atlas), "{w}"),
            other => panic!("{other:?}"),
        }
    }
}
