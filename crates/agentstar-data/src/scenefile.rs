//! Loading an object model from a file: a scene script (`.rhai`, sandboxed, mesh files only
//! from beside the script), a URDF, or a single mesh file (one rigid part per GLB root node,
//! else one part). A script that fails leaves the last good model in place: every good
//! build is remembered in `.agentstar/last_good.rhai` beside the script.

use crate::meshio::{load_appeared_mesh, parse_glb_appearance, MESH_EXTENSIONS};
use crate::texture::SideFiles;
use crate::urdf::load_urdf_with_warnings;
use crate::{read_bytes, read_text, DataError, Result};
use agentstar_geom::{AppearedMesh, KinematicTree, ObjectModel, Part};
use agentstar_scene::{build_scene, Limits, MeshSource, SceneBuild};
use std::path::{Component, Path, PathBuf};

/// Mesh files for a script: relative paths inside the script's directory only.
pub struct ScriptDirMeshes {
    dir: PathBuf,
}

impl ScriptDirMeshes {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        let dir: PathBuf = dir.into();
        // The parent of `scene.rhai` is "", which `canonicalize` cannot open.
        let dir = if dir.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            dir
        };
        ScriptDirMeshes { dir }
    }
}

impl MeshSource for ScriptDirMeshes {
    fn load(&self, path: &str) -> std::result::Result<AppearedMesh, String> {
        let p = Path::new(path);
        if p.is_absolute() || p.components().any(|c| !matches!(c, Component::Normal(_))) {
            return Err(format!("`{path}` must be a relative path inside the script's directory (no `..`, no absolute paths)"));
        }
        let ext = p
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        if !MESH_EXTENSIONS.contains(&ext.as_str()) {
            return Err(format!(
                "`{path}` is not a mesh file; use one of .{}",
                MESH_EXTENSIONS.join(", .")
            ));
        }
        let full = self.dir.join(p);
        let root = self.dir.canonicalize().map_err(|e| {
            format!(
                "the script's directory {} cannot be opened: {e}",
                self.dir.display()
            )
        })?;
        // Refuse symlinks that lead outside the directory, saying so.
        let link = std::fs::symlink_metadata(&full)
            .ok()
            .filter(|m| m.file_type().is_symlink())
            .and_then(|_| std::fs::read_link(&full).ok());
        let real = match (full.canonicalize(), &link) {
            (Ok(r), _) => r,
            (Err(_), Some(target)) => {
                return Err(format!(
                    "`{path}` is a symbolic link to {}, which does not exist",
                    target.display()
                ))
            }
            (Err(_), None) => {
                return Err(format!(
                    "no file `{path}` beside the script (looked at {})",
                    full.display()
                ))
            }
        };
        if !real.starts_with(&root) {
            return Err(match link {
                Some(_) => format!(
                    "`{path}` is a symbolic link to {}, outside the script's directory {}; mesh files must be inside it (copy the file there)",
                    real.display(),
                    root.display()
                ),
                None => format!("`{path}` leads outside the script's directory"),
            });
        }
        // The files it names (material library, textures) are held to the same directory.
        let files = SideFiles::confined(real.parent().unwrap_or(&root), &root);
        load_appeared_mesh(&real, &files).map_err(|e| e.to_string())
    }
}

/// What a model file turned into.
#[derive(Debug, Clone)]
pub struct LoadedModel {
    pub model: ObjectModel,
    /// Warnings and the canonical report's observations, for people and models to read.
    pub warnings: Vec<String>,
    pub printed: Vec<String>,
    /// The bake whose colours the model carries (`<stem>.bake.json` beside the file), when
    /// one was applied.
    pub bake: Option<PathBuf>,
}

fn last_good_path(script: &Path) -> PathBuf {
    let dir = script.parent().unwrap_or(Path::new("."));
    let stem = script
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("scene");
    dir.join(".agentstar")
        .join(format!("{stem}.last_good.rhai"))
}

/// Evaluates a scene script file. On success the script is remembered as the last good one.
pub fn load_scene_script(path: &Path, limits: &Limits) -> Result<SceneBuild> {
    let source = read_text(path)?;
    // `scene.rhai` has the parent "", which names no directory: meshes are beside it in ".".
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match build_scene(&source, &ScriptDirMeshes::new(dir), limits) {
        Ok(b) => {
            // Remembering is best effort: a read-only directory must not fail a good build.
            let _ = crate::atomic::write_atomic(&last_good_path(path), source.as_bytes());
            Ok(b)
        }
        Err(e) => {
            let mut e = e;
            let last = last_good_path(path);
            if last.is_file() {
                e.message.push_str(&format!(
                    "; the last good model ({}) stays in place",
                    last.display()
                ));
            }
            Err(DataError::invalid(path, e.to_string()))
        }
    }
}

/// The last good script beside `path`, if a build ever succeeded.
pub fn last_good_script(path: &Path) -> Option<PathBuf> {
    let p = last_good_path(path);
    p.is_file().then_some(p)
}

/// Loads any supported model file by extension, with the colours baked for it
/// (`<stem>.bake.json` beside it, [`crate::bakefile`]) where the bake is for its shape; a
/// stale or broken bake is ignored with a warning naming it.
pub fn load_model(path: &Path) -> Result<LoadedModel> {
    let mut loaded = load_model_unbaked(path)?;
    let (baked, pickup) = crate::bakefile::pick_up_bake(path, &loaded.model);
    match pickup {
        crate::bakefile::BakePickup::None => {}
        crate::bakefile::BakePickup::Applied(p) => {
            if let Some(m) = baked {
                loaded.model = m;
                loaded.bake = Some(p);
            }
        }
        crate::bakefile::BakePickup::Ignored(why) => loaded.warnings.push(why),
    }
    Ok(loaded)
}

/// Loads a model file as its file gives it, without a bake beside it (what `bake` bakes on).
pub fn load_model_unbaked(path: &Path) -> Result<LoadedModel> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "rhai" => {
            let b = load_scene_script(path, &Limits::default())?;
            Ok(LoadedModel { model: b.model, warnings: b.warnings, printed: b.printed, bake: None })
        }
        "urdf" => {
            let (model, mut warnings) = load_urdf_with_warnings(path)?;
            warnings.extend(model.canonical_report().warnings);
            Ok(LoadedModel { model, warnings, printed: vec![], bake: None })
        }
        "glb" => {
            let files = SideFiles::beside(path.parent().unwrap_or(Path::new(".")));
            let nodes = parse_glb_appearance(&read_bytes(path)?, &files).map_err(|e| DataError::invalid(path, e))?;
            let mut warnings = Vec::new();
            let mut parts = Vec::new();
            for (i, (n, m)) in nodes.into_iter().enumerate() {
                warnings.extend(m.warnings.iter().map(|w| format!("{}: node `{n}`: {w}", path.display())));
                parts.push(appeared_part(n, m, palette(i)).map_err(|e| DataError::invalid(path, e))?);
            }
            rigid(parts, warnings)
        }
        e if MESH_EXTENSIONS.contains(&e) => {
            let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("object").to_string();
            let files = SideFiles::beside(path.parent().unwrap_or(Path::new(".")));
            let m = load_appeared_mesh(path, &files)?;
            let warnings = m.warnings.iter().map(|w| format!("{}: {w}", path.display())).collect();
            rigid(vec![appeared_part(name, m, palette(0)).map_err(|e| DataError::invalid(path, e))?], warnings)
        }
        "" => Err(DataError::invalid(path, format!("has no file extension, so it is not a model file; use a scene script (.rhai), a URDF (.urdf) or a mesh (.{})", MESH_EXTENSIONS.join(", .")))),
        other => Err(DataError::invalid(path, format!("unknown model type `.{other}`; use a scene script (.rhai), a URDF (.urdf) or a mesh (.{})", MESH_EXTENSIONS.join(", .")))),
    }
}

/// The part of a mesh read with its appearance: one colour where the file gave it one
/// plain material (or `fallback` where it gave none), else its surface.
pub fn appeared_part(
    name: String,
    m: AppearedMesh,
    fallback: [f32; 3],
) -> std::result::Result<Part, String> {
    match m.surface {
        None => Ok(Part::new(name, m.mesh, fallback)),
        Some(s) if !s.varies() => Ok(Part::new(name, m.mesh, s.materials()[0].color)),
        Some(s) => Part::new(name, m.mesh, fallback)
            .with_surface(s)
            .map_err(|e| e.to_string()),
    }
}

fn rigid(parts: Vec<Part>, mut warnings: Vec<String>) -> Result<LoadedModel> {
    let model = ObjectModel {
        tree: KinematicTree::rigid(parts.len()),
        parts,
    };
    warnings.extend(model.canonical_report().warnings);
    Ok(LoadedModel {
        model,
        warnings,
        printed: vec![],
        bake: None,
    })
}

fn palette(i: usize) -> [f32; 3] {
    [
        [0.85, 0.33, 0.25],
        [0.25, 0.55, 0.85],
        [0.35, 0.75, 0.35],
        [0.9, 0.7, 0.2],
    ][i % 4]
}
