//! The tool registry shared by the MCP server and the built-in loop: one type per tool
//! (name, kind, what it writes, its argument struct, its handler), and the toolbox that runs
//! them on one run directory.
//!
//! A tool's JSON Schema is generated from its argument struct (`schemars`), and a call's
//! arguments are checked against it (types, required and unknown fields by `serde`; bounds
//! and lengths by [`check_bounds`]) before anything runs. The catalogue, the MCP
//! `tools/list` and the built-in loop's tool list are views of [`registry`].
//!
//! Every tool that renders or searches runs the `agentstar` executable as a child process
//! with `--json` (so a broken scene script or a crash in one tool never takes the harness
//! down, and the scene sandbox is the one every command uses) through one runner,
//! [`Toolbox::exec`]; the tool's files land in `RUN/images/step_NNNN_tool/`, and PNGs there
//! come back as images. The reports the children print are read into their types
//! ([`agentstar_reports`]).
//!
//! Where things are: this file holds the registry ([`REGISTRY`], the `tool!` macro, [`Tool`],
//! [`ToolDef`]), [`ToolOutput`] and the [`Toolbox`] with its shared checks (window, paths);
//! `schema.rs` the schemas and argument checks; `exec.rs` the child-process runner; and one
//! file per tool family, each with its argument types, its `tool!` entries and its handlers:
//! `scene.rs` (task, scene_read, scene_write, scene_restore), `views.rs` (render, frames,
//! score, turntable), `mechanism.rs` (mechanism, mechanism_pick: the blind arms of each joint
//! and the picks `finish` reads), `pose.rs` (track, the search verbs, pose_commit, pose_history,
//! pose_restore, temporal, pose_diff), `shape.rs` (fit_shape, scale), `bake.rs` (bake) and `finish.rs`
//! (critic, notes, finish).
//!
//! Tools that write (`pose.json`, the scene, the notes) run one at a time per run, whoever
//! calls them (MCP requests served concurrently, pose sub-agents in parallel); searches and
//! diagnostics run in parallel. Pose files change only through [`PoseHistory`], which
//! also serialises against `agentstar pose commit` run from a shell.

use crate::run::RunDir;
use crate::{AgentError, Result};
use agentstar_reports::ScoreReport;
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// What kind of step a tool is (the ledger's `kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Shape,
    Pose,
    Diagnostic,
    Note,
}

impl Kind {
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Shape => "shape",
            Kind::Pose => "pose",
            Kind::Diagnostic => "diagnostic",
            Kind::Note => "note",
        }
    }
}

/// What a tool changes in the run (writers run one at a time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Writes {
    Nothing,
    /// `pose.json` (and its history).
    Poses,
    /// `scene.rhai`, its versions, and `pose.json`'s joints.
    Scene,
    /// `NOTES.md`.
    Notes,
    /// The mechanism picks (`.agentstar/mechanism/picks.json`).
    Picks,
}

/// One tool as offered to a model (a view of a [`ToolDef`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    pub name: &'static str,
    pub kind: Kind,
    pub description: &'static str,
    /// JSON Schema of the arguments (an object).
    pub schema: Value,
}

/// Longest scene script `scene_write` takes, characters.
pub const MAX_SCRIPT_CHARS: usize = 256 * 1024;
/// Longest single note, characters.
pub const MAX_NOTE_CHARS: usize = 4000;
/// Largest `NOTES.md` the `notes` tool appends to (it is in every model request).
pub const MAX_NOTES_BYTES: usize = 64 * 1024;

/// Most images one tool call returns inline (the rest stay files, named in the text).
pub const MAX_IMAGES_RETURNED: usize = 8;

use agentstar_requests::FRAMES;

/// Said after a call that changed the poses or the scene of a run whose `finish` had passed
/// (play-test 16 baked after finishing, and nothing said the gates were checked on what the
/// run no longer ends with).
pub const AFTER_FINISH: &str = "\nnote: this run had finished (`finish` passed); this call changed what the gates checked: call `finish` again so that they hold for what the run ends with.";

/// One tool: its name, kind, what it writes, its arguments and its handler.
pub trait Tool {
    const NAME: &'static str;
    const KIND: Kind;
    const WRITES: Writes;
    const DESCRIPTION: &'static str;
    /// The arguments; its schema is the tool's input schema.
    type Args: DeserializeOwned + JsonSchema;
    fn run(tb: &Toolbox, args: Self::Args, step: u64) -> Result<ToolOutput>;
}

/// A registry entry: a [`Tool`] with its type erased.
#[derive(Clone, Copy)]
pub struct ToolDef {
    pub name: &'static str,
    pub kind: Kind,
    pub writes: Writes,
    pub description: &'static str,
    schema: fn() -> Value,
    parse: fn(&Value) -> Result<()>,
    call: fn(&Toolbox, &Value, u64) -> Result<ToolOutput>,
}

impl std::fmt::Debug for ToolDef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ToolDef").field("name", &self.name).finish()
    }
}

impl ToolDef {
    pub const fn of<T: Tool>() -> ToolDef {
        ToolDef {
            name: T::NAME,
            kind: T::KIND,
            writes: T::WRITES,
            description: T::DESCRIPTION,
            schema: schema_of::<T::Args>,
            parse: parse_typed::<T>,
            call: call_typed::<T>,
        }
    }

    /// Parses `args` into the tool's argument type and checks it against the schema, as a
    /// call does before anything runs (the error is the one a call would answer with).
    pub fn parse_args(&self, args: &Value) -> Result<()> {
        (self.parse)(args)
    }

    /// The generated JSON Schema of the arguments.
    pub fn schema(&self) -> Value {
        (self.schema)()
    }

    pub fn spec(&self) -> ToolSpec {
        ToolSpec {
            name: self.name,
            kind: self.kind,
            description: self.description,
            schema: self.schema(),
        }
    }

    /// Parses `args` against the schema (without running the tool).
    pub fn check_args(&self, args: &Value) -> std::result::Result<(), String> {
        check_bounds(self.name, &self.schema(), args)
    }
}

fn parse_typed<T: Tool>(args: &Value) -> Result<()> {
    parse_args::<T::Args>(T::NAME, args)?;
    check_bounds(T::NAME, &schema_of::<T::Args>(), args).map_err(AgentError::Tool)
}

fn call_typed<T: Tool>(tb: &Toolbox, args: &Value, step: u64) -> Result<ToolOutput> {
    let a: T::Args = parse_args(T::NAME, args).map_err(|e| {
        AgentError::Tool(format!(
            "{}\n{}",
            match e {
                AgentError::Tool(m) => m,
                other => other.to_string(),
            },
            arguments_help(T::NAME, &schema_of::<T::Args>())
        ))
    })?;
    check_bounds(T::NAME, &schema_of::<T::Args>(), args).map_err(AgentError::Tool)?;
    T::run(tb, a, step)
}

macro_rules! tool {
    ($(#[$doc:meta])* $ty:ident, $name:literal, $kind:ident, $writes:ident, $args:ty, $desc:expr,
     |$tb:ident, $a:pat_param, $step:pat_param| $body:expr) => {
        $(#[$doc])*
        pub struct $ty;
        impl Tool for $ty {
            const NAME: &'static str = $name;
            const KIND: Kind = Kind::$kind;
            const WRITES: Writes = Writes::$writes;
            const DESCRIPTION: &'static str = $desc;
            type Args = $args;
            fn run($tb: &Toolbox, $a: $args, $step: u64) -> Result<ToolOutput> {
                $body
            }
        }
    };
}

mod bake;
mod exec;
mod finish;
mod limits;
mod mechanism;
mod pose;
mod scene;
mod schema;
mod shape;
#[cfg(test)]
mod tests;
mod views;

pub use bake::*;
pub use exec::*;
pub use finish::*;
pub use mechanism::*;
pub use pose::*;
pub use scene::*;
pub use schema::*;
pub use shape::*;
pub use views::*;

/// No arguments.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NoArgs {}

/// Every tool, in the order offered.
pub static REGISTRY: &[ToolDef] = &[
    ToolDef::of::<Task>(),
    ToolDef::of::<SceneRead>(),
    ToolDef::of::<SceneWrite>(),
    ToolDef::of::<SceneRestore>(),
    ToolDef::of::<FitShape>(),
    ToolDef::of::<Bake>(),
    ToolDef::of::<Render>(),
    ToolDef::of::<Keyframes>(),
    ToolDef::of::<Score>(),
    ToolDef::of::<Turntable>(),
    ToolDef::of::<Mechanism>(),
    ToolDef::of::<MechanismPick>(),
    ToolDef::of::<Track>(),
    ToolDef::of::<Scale>(),
    ToolDef::of::<Sweep>(),
    ToolDef::of::<Apply>(),
    ToolDef::of::<Osweep>(),
    ToolDef::of::<Oapply>(),
    ToolDef::of::<OapplyAll>(),
    ToolDef::of::<PoseCommit>(),
    ToolDef::of::<PoseHistoryTool>(),
    ToolDef::of::<PoseRestore>(),
    ToolDef::of::<Temporal>(),
    ToolDef::of::<PoseDiff>(),
    ToolDef::of::<Critic>(),
    ToolDef::of::<Notes>(),
    ToolDef::of::<Finish>(),
];

/// The registry: every tool, in the order offered.
pub fn registry() -> &'static [ToolDef] {
    REGISTRY
}

/// The tool called `name`.
pub fn find(name: &str) -> Option<&'static ToolDef> {
    registry().iter().find(|t| t.name == name)
}

/// The catalogue as offered to a model: a view of the registry.
pub fn catalogue() -> Vec<ToolSpec> {
    registry().iter().map(ToolDef::spec).collect()
}

/// What a tool returned.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ToolOutput {
    pub text: String,
    /// PNGs the tool wrote, sheets first.
    pub images: Vec<PathBuf>,
    pub is_error: bool,
    /// Scores for the ledger (e.g. `iou_min`).
    pub scores: BTreeMap<String, f64>,
    /// Set when the tool changed the scene (the new version).
    pub scene_version: Option<u64>,
    pub pose_changed: bool,
    /// The pose history version the tool recorded, when it changed `pose.json`.
    pub pose_version: Option<u64>,
    /// `finish` passed.
    pub finished: bool,
    /// The tool's typed report as JSON (MCP `structuredContent`).
    pub structured: Option<Value>,
}

impl ToolOutput {
    pub fn error(text: impl Into<String>) -> Self {
        ToolOutput {
            text: text.into(),
            is_error: true,
            ..Default::default()
        }
    }
    fn text(text: impl Into<String>) -> Self {
        ToolOutput {
            text: text.into(),
            ..Default::default()
        }
    }
}

/// A critic: asked about one keyframe with its images, returns JSON text.
pub type CriticFn = dyn Fn(&str, &[PathBuf]) -> std::result::Result<String, String> + Send + Sync;

/// Runs tools on one run directory.
pub struct Toolbox {
    /// The `agentstar` executable.
    pub exe: PathBuf,
    pub run: RunDir,
    pub critic: Option<Box<CriticFn>>,
    /// Frames this toolbox may change (a pose sub-agent's window); `None` = all.
    pub window: Option<Vec<String>>,
    /// Longest a child command may run.
    pub timeout_s: u64,
    /// Held by every writing tool; shared by the toolboxes of one run.
    writer: Arc<Mutex<()>>,
}

fn first_line_of(s: &str) -> &str {
    s.lines().next().unwrap_or("")
}

/// PNG files under `dir`, in the order a reply shows them: the sheets that draw the model
/// (side by side, compared, overlaid), then the sheet of the frames alone, then each
/// frame's image with the model beside it (`side_…`), then the rest; each kind by name. A
/// reply keeps only the first few: with `model: true` the first image must show the model
/// (play-test 2026-12-05: the frames' own sheet came first, by name, and six raw crops took
/// the rest of the slots).
fn pngs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    v.sort_by_key(|p| {
        let n = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        (image_rank(&n), n)
    });
    v
}

/// Where a PNG of a view's folder comes in a reply ([`pngs`]).
fn image_rank(name: &str) -> u8 {
    if name.starts_with("sheet_frames") {
        1
    } else if name.contains("sheet") {
        0
    } else if name.starts_with("side_") {
        2
    } else {
        3
    }
}

impl Toolbox {
    pub fn new(exe: PathBuf, run: RunDir) -> Self {
        Toolbox {
            exe,
            run,
            critic: None,
            window: None,
            timeout_s: 900,
            writer: Arc::new(Mutex::new(())),
        }
    }

    /// A toolbox for a pose sub-agent: the same run and writer lock, limited to `frames`.
    pub fn for_window(&self, frames: Vec<String>) -> Toolbox {
        Toolbox {
            exe: self.exe.clone(),
            run: self.run.clone(),
            critic: None,
            window: Some(frames),
            timeout_s: self.timeout_s,
            writer: self.writer.clone(),
        }
    }

    /// The run's capture, model and pose file, as every posed-model command takes them.
    pub fn session(&self) -> agentstar_requests::SessionArgs {
        agentstar_requests::SessionArgs {
            capture: self.run.capture.clone(),
            model: self.run.scene.clone(),
            poses: self.run.poses.clone(),
        }
    }

    /// Opens the run's capture.
    pub fn capture(&self) -> Result<agentstar_data::capture::Capture> {
        agentstar_data::capture::Capture::open(&self.run.capture)
            .map_err(|problems| AgentError::Tool(problems.brief()))
    }

    /// Resolves `spec` with the frame grammar to frame names.
    pub fn frame_names(&self, spec: Option<&str>) -> Result<Vec<String>> {
        let cap = self.capture()?;
        Ok(cap
            .select(spec)?
            .into_iter()
            .map(|i| cap.frames[i].name.clone())
            .collect())
    }

    /// `agentstar score --json` for `frames`, as its report.
    pub fn score_report(&self, frames: Option<&str>) -> Result<ScoreReport> {
        #[derive(serde::Serialize)]
        struct Score<'a> {
            frames: Option<&'a str>,
            json: bool,
        }
        let call = Invocation::new(&["score"])
            .with(&self.session())?
            .with(&Score { frames, json: true })?;
        let (_, stdout, stderr) = self.exec(call.args())?;
        // `score` exits 1 when a frame is under the gate; its JSON is the result.
        serde_json::from_str(&stdout).map_err(|_| AgentError::Tool(failure_text(&stderr)))
    }

    /// Each keyframe's visible IoU (0 where no mask pixel is visible), in capture order.
    pub fn ious(&self, frames: Option<&str>) -> Result<Vec<(String, f64)>> {
        Ok(self
            .score_report(frames)?
            .frames
            .into_iter()
            .map(|f| {
                let g = f.gate();
                (f.frame, g)
            })
            .collect())
    }

    /// Frames outside this toolbox's window are refused for pose changes; the spec uses
    /// the one frame grammar.
    fn check_window(&self, frames: Option<&str>) -> std::result::Result<(), String> {
        let Some(window) = &self.window else {
            return Ok(());
        };
        let Some(frames) = frames.filter(|f| !f.trim().is_empty()) else {
            return Err(format!(
                "name the frames: this agent may change only {}",
                window.join(", ")
            ));
        };
        let names = self.frame_names(Some(frames)).map_err(|e| e.to_string())?;
        let outside = outside_window(window, &names);
        if outside.is_empty() {
            Ok(())
        } else {
            Err(format!(
                "frame(s) {} are outside this agent's window ({})",
                outside.join(", "),
                window.join(", ")
            ))
        }
    }

    /// `path` (relative to the run directory) if it lies inside the run directory or the
    /// capture, resolved; an error naming both otherwise.
    pub fn confine(&self, path: &str) -> std::result::Result<PathBuf, String> {
        let p = PathBuf::from(path);
        let canon = |q: &Path| q.canonicalize().ok();
        // Relative to the run directory, or (as the tools print them for a run opened by
        // a relative path) to the working directory.
        let resolved = if p.is_relative() {
            canon(&self.run.dir.join(&p)).or_else(|| canon(&p))
        } else {
            canon(&p)
        }
        .ok_or_else(|| format!("`{path}`: no such file"))?;
        let roots: Vec<PathBuf> = [&self.run.dir, &self.run.capture]
            .into_iter()
            .filter_map(|r| canon(r))
            .collect();
        if roots.iter().any(|r| resolved.starts_with(r)) {
            Ok(resolved)
        } else {
            Err(format!(
                "`{path}` is outside the run directory ({}) and the capture; tools read only files there",
                self.run.dir.display()
            ))
        }
    }

    /// Calls tool `name` with `args` as step `step`; writers run one at a time.
    pub fn call(&self, name: &str, args: &Value, step: u64) -> ToolOutput {
        let Some(def) = find(name) else {
            return ToolOutput::error(format!(
                "there is no tool `{name}`; the tools are {}",
                registry()
                    .iter()
                    .map(|t| t.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        };
        // The children it starts carry the step, so the versions they record name it.
        let run = || {
            exec::with_step(step, || match (def.call)(self, args, step) {
                Ok(o) => o,
                Err(e) => ToolOutput::error(e.to_string()),
            })
        };
        if def.writes == Writes::Nothing {
            return run();
        }
        // A poisoned lock only means another writer panicked; the files are whole.
        let _guard = self
            .writer
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let writes =
            matches!(def.writes, Writes::Poses | Writes::Scene) && def.name != Finish::NAME;
        let before = writes.then(|| self.gated_files());
        let mut out = run();
        if writes
            && !out.is_error
            && before != Some(self.gated_files())
            && self.run.state().is_ok_and(|s| s.finished)
        {
            out.text.push_str(AFTER_FINISH);
        }
        out
    }

    /// What `finish`'s gates check: the scene's text and the poses' scale and frames (`None`
    /// for a file that cannot be read). A call that leaves both as they were changed nothing
    /// the gates checked (a `fit_shape` whose parameters did not move: play-test 17; a scene
    /// saved again as it was, which lists the parts in pose.json).
    fn gated_files(&self) -> GatedInputs {
        GatedInputs {
            scene: agentstar_data::read_text(&self.run.scene).ok(),
            poses: agentstar_data::posefile::PoseFile::read(&self.run.poses)
                .ok()
                .map(|p| (p.scale, p.frames)),
        }
    }

    /// Whether this toolbox serves the tool called `name`: every tool but `critic`, which
    /// needs a critic model (play-tests 5 and 6 found it listed and unusable).
    pub fn offers(&self, name: &str) -> bool {
        name != Critic::NAME || self.critic.is_some()
    }
}

/// What `finish`'s gates read of a run ([`Toolbox::call`] compares them before and after a
/// writer).
#[derive(Debug, PartialEq)]
struct GatedInputs {
    scene: Option<String>,
    poses: Option<(
        f64,
        std::collections::BTreeMap<String, agentstar_data::posefile::FrameEntry>,
    )>,
}
