//! The object model as code: `scene.rhai`, a script in the embedded language Rhai that
//! builds named parts from primitives and declares joints. Only the functions registered
//! here are reachable; the script has no file or network access (mesh files come through a
//! caller-provided [`MeshSource`]) and runs under bounds on operations, call depth, sizes,
//! triangles and wall time.
//!
//! Errors are written for the model that reads them: line and column, what was expected,
//! the valid names, and the parts defined so far.

mod api;
mod api_table;
mod colors;
mod diagnostics;
mod params;
mod preload;

pub use api_table::{api_markdown, api_names, ApiEntry, API};
pub use diagnostics::{SceneError, SceneErrorKind};
pub use params::{format_param_value, set_param_values};

use agentstar_geom::{AppearedMesh, CanonicalReport, ObjectModel};
use std::collections::BTreeMap;
use std::time::Duration;

/// Loads mesh files that a script names (`mesh("handle.obj")`) with their appearance
/// (materials, textures, vertex colours) and the warnings reading it gave. Implementations
/// decide which paths are allowed, for the mesh and the files it names; the scene layer
/// itself never touches the file system.
pub trait MeshSource: Send + Sync {
    fn load(&self, path: &str) -> Result<AppearedMesh, String>;
}

/// A source that refuses every mesh file (for scripts evaluated without a directory).
pub struct NoMeshFiles;

impl MeshSource for NoMeshFiles {
    fn load(&self, path: &str) -> Result<AppearedMesh, String> {
        Err(format!(
            "mesh files are not available here (asked for `{path}`)"
        ))
    }
}

/// Bounds on what a script may do.
#[derive(Debug, Clone)]
pub struct Limits {
    pub max_operations: u64,
    pub max_call_depth: usize,
    pub max_wall_time: Duration,
    /// Total triangles over every solid the script creates (intermediate ones included).
    pub max_triangles: usize,
    pub max_parts: usize,
    pub max_script_bytes: usize,
    pub max_array_len: usize,
    pub max_string_len: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_operations: 20_000_000,
            max_call_depth: 48,
            max_wall_time: Duration::from_secs(20),
            max_triangles: 4_000_000,
            max_parts: 256,
            max_script_bytes: 512 * 1024,
            max_array_len: 200_000,
            max_string_len: 64 * 1024,
        }
    }
}

/// A successfully built scene.
#[derive(Debug, Clone)]
pub struct SceneBuild {
    pub model: ObjectModel,
    pub report: CanonicalReport,
    /// Non-fatal observations (rest state outside a limit, drifting canonical frame…).
    pub warnings: Vec<String>,
    /// Lines the script printed with `print`/`debug`, in order.
    pub printed: Vec<String>,
    /// The shape parameters the script declared with `param(...)`, in order.
    pub params: Vec<ParamDecl>,
}

/// One `param(name, value, min, max)` of a script.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamDecl {
    pub name: String,
    /// The value written in the script.
    pub default: f64,
    /// The value this build used (the default, or an override).
    pub value: f64,
    pub min: f64,
    pub max: f64,
    /// Where the call is (1-based line and column).
    pub line: Option<usize>,
    pub column: Option<usize>,
}

/// Evaluates a scene script under `limits`.
pub fn build_scene(
    source: &str,
    meshes: &dyn MeshSource,
    limits: &Limits,
) -> Result<SceneBuild, SceneError> {
    api::build(source, meshes, limits, &BTreeMap::new())
}

/// Evaluates a scene script with some of its `param(...)` values replaced by `overrides`
/// (each must be declared by the script and lie within its bounds).
pub fn build_scene_with(
    source: &str,
    meshes: &dyn MeshSource,
    limits: &Limits,
    overrides: &BTreeMap<String, f64>,
) -> Result<SceneBuild, SceneError> {
    api::build(source, meshes, limits, overrides)
}
