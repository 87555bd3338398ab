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
//! ([`crate::reports`]).
//!
//! Tools that write (`pose.json`, the scene, the notes) run one at a time per run, whoever
//! calls them (MCP requests served concurrently, pose sub-agents in parallel); searches and
//! diagnostics run in parallel. Pose files change only through [`PoseHistory`], which
//! also serialises against `agentstar pose commit` run from a shell.

use crate::run::RunDir;
use crate::task::task_document;
use crate::{AgentError, Result};
use agentstar_data::history::PoseHistory;
use agentstar_data::posefile::PoseFile;
use agentstar_render::GATE_IOU;
use agentstar_reports::view::{RenderReport, TurntableReport};
use agentstar_reports::{
    CheckReport, CommitReport, FrameHistoryReport, HistoryReport, PoseDiffReport, RestoreReport,
    ScoreReport, SearchReport, SearchVerb, TrackReport,
};
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
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

const FRAMES: &str = "Keyframes: `all`, names (`000010.png`), stems (`000010`), frame numbers, or ranges `a..b`, comma separated.";

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
            call: call_typed::<T>,
        }
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

/// The JSON Schema of `A`, self-contained (no `$schema`, no references), options not
/// nullable.
pub fn schema_of<A: JsonSchema>() -> Value {
    let generator = schemars::generate::SchemaSettings::draft2020_12()
        .with(|s| {
            s.meta_schema = None;
            s.inline_subschemas = true;
        })
        .into_generator();
    let mut v = generator.into_root_schema_for::<A>().to_value();
    if let Some(o) = v.as_object_mut() {
        // The struct's own doc comment is for people reading the code.
        o.remove("title");
        o.remove("description");
        let props = o
            .entry("properties")
            .or_insert_with(|| Value::Object(Default::default()));
        // An optional argument is left out, not sent as null: say so in its schema, at
        // every depth (the fields of `finish`'s reasons too).
        if let Some(props) = props.as_object_mut() {
            for p in props.values_mut() {
                drop_null(p);
                tidy(p);
            }
        }
    }
    v
}

/// The most bytes of a tool's stdout or stderr the toolbox keeps (a report, a log).
pub const MAX_TOOL_OUTPUT_BYTES: usize = 16 << 20;

/// Reads `r` to its end, keeping the first [`MAX_TOOL_OUTPUT_BYTES`] (cut at a character
/// boundary) and a line saying how much was dropped.
/// The last line a running child command wrote on stderr (the tracker writes one per frame
/// tracked): what the tool is doing now, for whoever reports on it while it runs (the MCP
/// server's progress notifications). The child commands that the calls inside
/// [`with_activity`] start on that thread report to it.
#[derive(Debug, Clone, Default)]
pub struct Activity(Arc<Mutex<String>>);

impl Activity {
    /// The last non-empty line, or "" before the first.
    pub fn last_line(&self) -> String {
        self.0.lock().map(|l| l.clone()).unwrap_or_default()
    }

    fn set(&self, line: &str) {
        if let Ok(mut l) = self.0.lock() {
            line.clone_into(&mut l);
        }
    }
}

thread_local! {
    static ACTIVITY: std::cell::RefCell<Option<Activity>> = const { std::cell::RefCell::new(None) };
}

/// Runs `f` with the child commands it starts on this thread reporting their stderr lines
/// to `activity`.
pub fn with_activity<T>(activity: &Activity, f: impl FnOnce() -> T) -> T {
    /// Unsets the thread's activity however `f` ends (a pool thread runs other calls later).
    struct Reset;
    impl Drop for Reset {
        fn drop(&mut self) {
            ACTIVITY.with(|a| *a.borrow_mut() = None);
        }
    }
    ACTIVITY.with(|a| *a.borrow_mut() = Some(activity.clone()));
    let _reset = Reset;
    f()
}

/// Longest line kept for [`Activity`] (bytes; the rest of a longer line is dropped).
const ACTIVITY_LINE_BYTES: usize = 300;

/// A reader that hands each complete line it passes through to an [`Activity`].
struct LastLine<R> {
    inner: R,
    activity: Option<Activity>,
    pending: Vec<u8>,
}

impl<R: std::io::Read> std::io::Read for LastLine<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Some(activity) = &self.activity {
            for &b in &buf[..n] {
                if b == b'\n' {
                    let line = String::from_utf8_lossy(&self.pending);
                    if !line.trim().is_empty() {
                        activity.set(line.trim());
                    }
                    self.pending.clear();
                } else if self.pending.len() < ACTIVITY_LINE_BYTES {
                    self.pending.push(b);
                }
            }
        }
        Ok(n)
    }
}

fn read_capped(r: impl std::io::Read) -> String {
    read_capped_to(r, MAX_TOOL_OUTPUT_BYTES)
}

fn read_capped_to(mut r: impl std::io::Read, cap: usize) -> String {
    let mut kept = Vec::new();
    let mut dropped = 0u64;
    let mut buf = [0u8; 64 * 1024];
    loop {
        match r.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                let room = cap.saturating_sub(kept.len()).min(n);
                kept.extend_from_slice(&buf[..room]);
                dropped += (n - room) as u64;
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(_) => break,
        }
    }
    let mut text = String::from_utf8_lossy(&kept).into_owned();
    if dropped > 0 {
        text.push_str(&format!(
            "\n[{dropped} more bytes of output dropped: the toolbox keeps {cap}]\n"
        ));
    }
    text
}

/// A track's result as an MCP client reads it: the summary first, then what the tracker
/// did (its log), then one line per frame; the whole report is the structured content. (The
/// report's JSON as text buried the summary under the per-frame figures: a play-test agent
/// ran `track` again to read its log.) With the pose file it wrote, each frame's line ends
/// with its joint states (pose.json's units: degrees or metres): play-test 6 read pose.json
/// in a shell to see how far a lid had opened.
fn track_text(r: &TrackReport, poses: Option<&agentstar_data::posefile::PoseFile>) -> String {
    let q = &r.sequence;
    let mut text = format!(
        "tracked {} frame(s) in {:.1} s ({} evaluations), initialised on {}\n",
        q.frames, r.seconds, r.evaluations, r.init_frame
    );
    match (q.band_px, q.mean_iou_band, q.min_iou_band) {
        (Some(px), Some(mean), Some(min)) => text.push_str(&format!(
            "band IoU (±{px} px boundary excluded, the gate {}) mean {mean:.4}, min {min:.4} ({}); ",
            q.pass_iou, q.worst_frame
        )),
        _ => text.push_str(&format!("gate {} on the visible IoU; ", q.pass_iou)),
    }
    text.push_str(&format!(
        "visible IoU mean {:.4}, min {:.4} ({})\n",
        q.mean_iou_visible, q.min_iou_visible, q.min_visible_frame
    ));
    if q.below_gate.is_empty() {
        text.push_str("every frame passes the gate\n");
    } else {
        text.push_str(&format!(
            "under the gate, worst first: {}\n",
            q.below_gate.join(", ")
        ));
    }
    text.push_str("\nwhat the tracker did:\n");
    for line in &r.log {
        text.push_str(&format!("  {line}\n"));
    }
    let joints_of = |frame: &str| poses.and_then(|p| p.frames.get(frame)).map(|e| &e.joints);
    let with_joints = r
        .frames
        .iter()
        .any(|f| joints_of(&f.frame).is_some_and(|j| !j.is_empty()));
    text.push_str(&format!(
        "\nframe        iou_band  iou_visible{}\n",
        if with_joints { "  joints" } else { "" }
    ));
    for f in &r.frames {
        let band = f
            .iou_band
            .map_or("     -".to_string(), |b| format!("{b:.4}"));
        let visible = f
            .iou_visible
            .map_or("     -".to_string(), |v| format!("{v:.4}"));
        let joints: String = joints_of(&f.frame)
            .into_iter()
            .flatten()
            .map(|(name, v)| format!("  {name} {v:.1}"))
            .collect();
        text.push_str(&format!(
            "{:<12} {band:>8}  {visible:>11}{joints}\n",
            f.frame
        ));
    }
    text.push('\n');
    text
}

/// Whether a fitted parameter moved by more than a thousandth of its range.
fn param_moved(p: &agentstar_reports::fit::FitParam) -> bool {
    (p.after - p.before).abs() > 1e-3 * (p.max - p.min)
}

/// The line a fit adds when some parameters moved and others did not (play-test 7: 9 of
/// 10 stayed at their values, and one restarted elsewhere by hand gained 0.05 IoU); `None`
/// when all moved or none did (then [`fit_saves_nothing`] says why).
fn unmoved_line(report: &agentstar_reports::fit::FitReport) -> Option<String> {
    let unmoved: Vec<&str> = report
        .params
        .iter()
        .filter(|p| !param_moved(p))
        .map(|p| p.name.as_str())
        .collect();
    (!unmoved.is_empty() && unmoved.len() < report.params.len()).then(|| {
        format!(
            "did not move: {}. Along these the IoU is flat or at a local optimum at these poses; where the silhouettes still disagree there, set another value in the script (scene_write) and fit them again, alone.\n",
            unmoved.join(", ")
        )
    })
}

/// Why a shape fit's result is not saved, if it is not: no parameter moved by more than a
/// thousandth of its range (the gain, if any, came from refining the poses alone: play-test,
/// 2026-12-02, a fit from wrong poses saved an unchanged scene as a new version), or the
/// mean IoU did not rise.
fn fit_saves_nothing(report: &agentstar_reports::fit::FitReport) -> Option<&'static str> {
    let moved = report.params.iter().any(param_moved);
    if !moved {
        Some("No parameter moved: at these poses (held, refined only locally) no change of the parameters raises the IoU. That does not make the shape right: poses fitted to a wrong shape hold it where it is, and any rise of the mean above came from refining the poses alone. The scene and pose.json are unchanged (no version saved). If the silhouettes still disagree, change the shape by hand (scene_write), track from pose.json, then fit again.\n")
    } else if report.iou_mean_after <= report.iou_mean_before + 1e-4 {
        Some("The fit did not raise the mean IoU: the scene and pose.json are unchanged.\n")
    } else {
        None
    }
}

/// Below the top level: nested properties lose their `null` like the top-level ones, and
/// descriptions from multi-line doc comments become one line per paragraph (a model reads
/// the schema as text; line breaks from the source's wrapping are noise there).
fn tidy(v: &mut Value) {
    match v {
        Value::Object(o) => {
            if let Some(Value::String(d)) = o.get_mut("description") {
                *d = one_line_paragraphs(d);
            }
            if let Some(Value::Object(props)) = o.get_mut("properties") {
                for p in props.values_mut() {
                    drop_null(p);
                }
            }
            for (k, child) in o.iter_mut() {
                if k != "description" && k != "enum" && k != "const" && k != "default" {
                    tidy(child);
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(tidy),
        _ => {}
    }
}

/// `"a\nb\n\nc"` → `"a b\n\nc"`.
fn one_line_paragraphs(text: &str) -> String {
    text.split("\n\n")
        .map(|para| para.split_whitespace().collect::<Vec<_>>().join(" "))
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join("\n\n")
}

/// Removes `null` from a property's types (`["string", "null"]` → `"string"`, an
/// `anyOf` with a null branch → the other branch).
fn drop_null(p: &mut Value) {
    let Some(o) = p.as_object_mut() else { return };
    if let Some(Value::Array(types)) = o.get_mut("type") {
        types.retain(|t| t != "null");
        if types.len() == 1 {
            let t = types[0].clone();
            o.insert("type".into(), t);
        }
    }
    if let Some(Value::Array(values)) = o.get_mut("enum") {
        values.retain(|v| !v.is_null());
    }
    if let Some(Value::Array(branches)) = o.get("anyOf").cloned().as_ref() {
        let rest: Vec<&Value> = branches.iter().filter(|b| b["type"] != "null").collect();
        if let [only] = rest.as_slice() {
            o.remove("anyOf");
            if let Some(inner) = only.as_object() {
                for (k, v) in inner {
                    o.entry(k.clone()).or_insert_with(|| v.clone());
                }
            }
        }
    }
}

/// Deserialises a tool's arguments (missing = `{}`); the error names the tool.
pub fn parse_args<A: DeserializeOwned>(tool: &str, args: &Value) -> Result<A> {
    let v = match args {
        Value::Null => Value::Object(Default::default()),
        Value::Object(_) => args.clone(),
        other => {
            return Err(AgentError::Tool(format!(
                "{tool}: the arguments must be an object, not {other}"
            )))
        }
    };
    serde_json::from_value(v).map_err(|e| AgentError::Tool(format!("{tool}: bad arguments: {e}")))
}

/// The bounds of a schema that `serde` does not check: `minimum`, `maximum`,
/// `exclusiveMinimum`, `minLength`, `maxLength` of each property given.
pub fn check_bounds(tool: &str, schema: &Value, args: &Value) -> std::result::Result<(), String> {
    let (Some(props), Some(given)) = (
        schema.get("properties").and_then(Value::as_object),
        args.as_object(),
    ) else {
        return Ok(());
    };
    let num = |s: &Value, k: &str| s.get(k).and_then(Value::as_f64);
    for (key, value) in given {
        let Some(s) = props.get(key) else { continue };
        if let Some(x) = value.as_f64() {
            if let Some(min) = num(s, "minimum").filter(|m| x < *m) {
                return Err(format!(
                    "{tool}: `{key}` is {value}, under its minimum {min}"
                ));
            }
            if let Some(max) = num(s, "maximum").filter(|m| x > *m) {
                return Err(format!(
                    "{tool}: `{key}` is {value}, over its maximum {max}"
                ));
            }
            if let Some(min) = num(s, "exclusiveMinimum").filter(|m| x <= *m) {
                return Err(format!("{tool}: `{key}` is {value}; it must be over {min}"));
            }
            if !x.is_finite() {
                return Err(format!("{tool}: `{key}` must be finite"));
            }
        }
        if let Some(text) = value.as_str() {
            let n = text.chars().count();
            if let Some(min) = num(s, "minLength").filter(|m| (n as f64) < *m) {
                return Err(format!(
                    "{tool}: `{key}` must have at least {min} character(s)"
                ));
            }
            if let Some(max) = num(s, "maxLength").filter(|m| (n as f64) > *m) {
                return Err(format!(
                    "{tool}: `{key}` has {n} characters, over its limit of {max}"
                ));
            }
        }
    }
    Ok(())
}

/// A JSON schema's type as an agent reads it: `list of string`, `integer 1–10`,
/// `{category: "out_of_reach", note: string}`, `map of key → …`, alternatives with `|`.
fn schema_type(s: &Value) -> String {
    if let Some(c) = s.get("const") {
        return c.to_string();
    }
    if let Some(Value::Array(values)) = s.get("enum") {
        return values
            .iter()
            .map(Value::to_string)
            .collect::<Vec<_>>()
            .join(" | ");
    }
    for key in ["oneOf", "anyOf"] {
        if let Some(Value::Array(branches)) = s.get(key) {
            return branches
                .iter()
                .filter(|b| b["type"] != "null")
                .map(schema_type)
                .collect::<Vec<_>>()
                .join(" | ");
        }
    }
    let kind = match s.get("type") {
        Some(Value::String(t)) => t.as_str(),
        Some(Value::Array(ts)) => ts
            .iter()
            .filter_map(Value::as_str)
            .find(|t| *t != "null")
            .unwrap_or("any"),
        _ => "any",
    };
    let bound = |k: &str| s.get(k).and_then(Value::as_f64);
    match kind {
        "array" => format!(
            "list of {}",
            s.get("items").map_or("any".to_string(), schema_type)
        ),
        "integer" | "number" => match (bound("minimum"), bound("maximum")) {
            (Some(lo), Some(hi)) => format!("{kind} {lo}–{hi}"),
            (Some(lo), None) => format!("{kind} ≥ {lo}"),
            (None, Some(hi)) => format!("{kind} ≤ {hi}"),
            (None, None) => kind.to_string(),
        },
        "object" => {
            if let Some(props) = s.get("properties").and_then(Value::as_object) {
                let required = required_of(s);
                let fields: Vec<String> = props
                    .iter()
                    .map(|(k, v)| {
                        let mark = if required.contains(&k.as_str()) {
                            ""
                        } else {
                            "?"
                        };
                        format!("{k}{mark}: {}", schema_type(v))
                    })
                    .collect();
                format!("{{{}}}", fields.join(", "))
            } else if let Some(values) = s.get("additionalProperties").filter(|v| v.is_object()) {
                format!("map of key → {}", schema_type(values))
            } else {
                "object".to_string()
            }
        }
        other => other.to_string(),
    }
}

fn required_of(s: &Value) -> Vec<&str> {
    s.get("required")
        .and_then(Value::as_array)
        .map(|r| r.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default()
}

/// What a tool takes, one line per argument (name, required or not, type, the first
/// sentence of its description): appended to a bad call's error, for agents that do not
/// read the schema.
pub fn arguments_help(tool: &str, schema: &Value) -> String {
    let Some(props) = schema.get("properties").and_then(Value::as_object) else {
        return String::new();
    };
    if props.is_empty() {
        return format!("{tool} takes no arguments: call it with {{}}");
    }
    let required = required_of(schema);
    let mut out = format!("{tool} takes:");
    for (name, s) in props {
        let first = s
            .get("description")
            .and_then(Value::as_str)
            .map(|d| {
                let sentence = d.split(". ").next().unwrap_or(d).trim_end_matches('.');
                let short: String = sentence.chars().take(140).collect();
                if short.len() < sentence.len() {
                    format!(": {short}…")
                } else {
                    format!(": {short}")
                }
            })
            .unwrap_or_default();
        out.push_str(&format!(
            "\n- `{name}` ({}{}){first}",
            if required.contains(&name.as_str()) {
                "required, "
            } else {
                ""
            },
            schema_type(s)
        ));
    }
    out
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

/// No arguments.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NoArgs {}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SceneWriteArgs {
    /// The whole scene script (Rhai). Or give `path` instead.
    #[schemars(length(min = 1, max = 262144))]
    pub script: Option<String>,
    /// A text file holding the whole script (at most 256 KiB), in the run directory or
    /// relative to it (e.g. `draft.rhai`, written with your own editor): no escaping of the
    /// script into a JSON string. Give `script` or `path`, not both.
    #[schemars(length(min = 1))]
    pub path: Option<String>,
}

/// The longest scene script `scene_write` takes, in bytes (its schema's bound on `script`).
const SCENE_SCRIPT_MAX_BYTES: usize = 262_144;

impl SceneWriteArgs {
    /// The script given, or read from the file given (inside the run directory or the
    /// capture, bounded).
    fn script(&self, tb: &Toolbox) -> Result<String> {
        match (&self.script, &self.path) {
            (Some(script), None) => Ok(script.clone()),
            (None, Some(path)) => {
                let file = tb.confine(path).map_err(AgentError::Tool)?;
                let len = std::fs::metadata(&file)
                    .map_err(|e| agentstar_data::DataError::io(&file, e))?
                    .len();
                if len > SCENE_SCRIPT_MAX_BYTES as u64 {
                    return Err(AgentError::Tool(format!(
                        "`{path}` holds {len} bytes; a scene script may have at most {SCENE_SCRIPT_MAX_BYTES}"
                    )));
                }
                let script = agentstar_data::read_text(&file)?;
                if script.trim().is_empty() {
                    return Err(AgentError::Tool(format!(
                        "`{path}` is empty; the scene was not changed"
                    )));
                }
                Ok(script)
            }
            (Some(_), Some(_)) => Err(AgentError::Tool(
                "give `script` or `path`, not both; the scene was not changed".into(),
            )),
            (None, None) => Err(AgentError::Tool(
                "give `script` (the whole scene script) or `path` (a file in the run directory holding it)"
                    .into(),
            )),
        }
    }
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VersionArgs {
    /// A scene version (they start at 1, the starting scene).
    #[schemars(range(min = 1))]
    pub version: u64,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseRestoreArgs {
    /// A pose version as `pose_history` lists them (0 is the first).
    #[schemars(range(min = 0))]
    pub version: u64,
    /// Only these keyframes (same grammar as `frames`); the others stay as they are.
    /// Default: the whole file.
    pub frames: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseHistoryArgs {
    /// One keyframe (name, stem or number): its pose and visible IoU (with the current
    /// model) in every version, and where it changed.
    #[schemars(length(min = 1))]
    pub frame: Option<String>,
    /// Only the last N versions (default 50).
    #[schemars(range(min = 1))]
    pub last: Option<u64>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RenderArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Comma separated: overlay, compare, ids, shaded, side (the keyframe cropped around its
    /// mask beside the model rendered opaque over the same crop, with a sheet: to compare a
    /// print without one showing through the other). Default overlay,compare.
    pub views: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FramesArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
}

/// What the keyframe view draws over the raw pixels.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Outline {
    /// The raw pixels only.
    None,
    /// The object mask's boundary (magenta) and the hand mask's (cyan).
    Mask,
    /// The posed model's silhouette boundary (yellow).
    Model,
    /// Both.
    Both,
}

impl Outline {
    fn as_str(self) -> &'static str {
        match self {
            Outline::None => "none",
            Outline::Mask => "mask",
            Outline::Model => "model",
            Outline::Both => "both",
        }
    }
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct KeyframesArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Margin around the mask's box, a fraction of its longer side (default 0.25).
    #[schemars(range(min = 0.0, max = 4.0))]
    pub margin: Option<f64>,
    /// Scale of the crop: 1 = the frame's own pixels (default), up to 8 to look at thin
    /// parts; reduced where an image would pass the size limits.
    #[schemars(range(min = 0.1, max = 8.0))]
    pub zoom: Option<f64>,
    /// Boundaries drawn over the raw pixels (default none).
    pub outline: Option<Outline>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TurntableArgs {
    /// Joint states to show: `representative` (each joint's min, median and max over the
    /// keyframes; the default), `all` (every distinct state: many sheets), keyframes in
    /// the frame grammar (`000010,000040`), or states given outright (degrees, canonical
    /// units; joints not named at rest): `hinge:90|hinge:0;drawer:0.2`, one sheet each, also
    /// before any pose is tracked.
    #[schemars(length(min = 1, max = 4000))]
    pub states: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrackArgs {
    /// Metres per model unit (default: the scale in pose.json, or in `from`).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub scale: Option<f64>,
    /// Refine these poses instead of tracking from scratch (a warm start, cheap after a
    /// shape edit): `pose.json` for the current poses, or another pose file in the run.
    #[schemars(length(min = 1))]
    pub from: Option<String>,
    /// With `from`: keyframes kept exactly and carried to their neighbours (same grammar
    /// as `frames`).
    #[schemars(length(min = 1))]
    pub anchors: Option<String>,
}

/// A sweep's search strategy.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Strategy {
    De,
    Grid,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SweepArgs {
    #[schemars(description = FRAMES, length(min = 1))]
    pub frames: String,
    /// DOF:min,max terms separated by `;` (roll, yaw, pitch in degrees; dpx, dpy, tz fractions; joints by name).
    #[schemars(length(min = 1))]
    pub ranges: String,
    pub strategy: Option<Strategy>,
    /// Evaluations over all restarts (default 3600, or for DE 20 generations of its
    /// population, 8 per searched dimension, where that is more, at most 20000: 6720 for 7
    /// dimensions).
    #[schemars(range(min = 50, max = 50000))]
    pub evals: Option<u64>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ApplyArgs {
    /// One keyframe (name, stem or number).
    #[schemars(length(min = 1))]
    pub frame: String,
    /// One value per DOF: `yaw:15;hinge:40` (increments; joint states absolute).
    #[schemars(length(min = 1))]
    pub order: String,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OsweepArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// A preset: `z:flip`, `z:quarters`, `z:octants`, `so3:24`. Give this or `ranges`.
    pub opreset: Option<String>,
    /// Grid ranges over rx, ry, rz (degrees) and joints: `rz:-180,180,9;rx:-15,15,3`, each
    /// `dof:lower,upper,steps` with `steps` grid values from lower to upper, both included.
    /// The grid is then refined around its best points (finer spacing) and every candidate
    /// refined locally before ranking: each row names its grid start and, after `→`, the
    /// rotation (one rotation vector, as `oapply` reads it) and joint states it was refined to.
    /// Give this or `opreset`.
    pub ranges: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OapplyArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// `flips`, `swaps` (for each hinge, the half-turn that puts its two sides in each
    /// other's place: a laptop's lid and base), or candidates separated by `|`, terms by `;`:
    /// `identity|flip:x|rz:90;rx:10|swaps`; a term `JOINT:value` sets a joint in that
    /// candidate (degrees, or canonical units for a prismatic joint): `flip:x;hinge:115`.
    pub set: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OapplyAllArgs {
    /// One rotation: `rz:90;rx:10` (rotation vector, degrees) or `flip:x|y|z`.
    #[schemars(length(min = 1))]
    pub rotation: String,
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseCommitArgs {
    /// Where the poses come from (inside the run directory): the report a search returned,
    /// a pose file (a track's pose.json) or a history version file.
    #[schemars(length(min = 1))]
    pub report: String,
    /// The candidate's rank in a search report (0 = best).
    #[schemars(range(min = 0))]
    pub rank: Option<u64>,
    /// Instead of `rank`: the candidate's label in a search report (`swap:hinge`, `flip:x`;
    /// for osweep the grid start before `→`), the same candidate in every frame whatever its
    /// rank there.
    pub label: Option<String>,
    /// Only these frames of the report (same grammar as `frames`).
    pub frames: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TemporalArgs {
    /// e.g. vel.rot, accel.rot, vel.trans, <joint>.vel
    pub sort_by: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseDiffArgs {
    #[schemars(length(min = 1))]
    pub a: String,
    #[schemars(length(min = 1))]
    pub b: String,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CriticArgs {
    /// One keyframe.
    #[schemars(length(min = 1))]
    pub frame: String,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NotesArgs {
    #[schemars(length(min = 1, max = 4000))]
    pub text: String,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FinishArgs {
    /// Keyframes (a name, stem, number or `a..b` range) → why they cannot reach the gate,
    /// one of the categories.
    pub unreachable: Option<BTreeMap<String, Unreachable>>,
    /// Each large step of the `temporal` report (over 90°) you checked: `A->B` (the step as
    /// `temporal` prints it; names or stems) → what you found, e.g. `oapply on B: no twin
    /// within 0.01`. One of the step's frames must have been looked at (`oapply`, `osweep`,
    /// `render` or `frames`) since either frame's pose last changed. A step that is no longer
    /// large is ignored.
    pub steps_checked: Option<BTreeMap<String, String>>,
    #[schemars(length(max = 4000))]
    pub summary: Option<String>,
}

/// The frames a ledger entry's arguments name (`frames`; all when absent): what `finish`
/// reads back of the calls that looked at a large step's frames.
#[derive(Debug, Deserialize)]
struct FramesOf {
    #[serde(default)]
    frames: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FitShapeArgs {
    /// The parameters to fit: names of the scene's `param("name", value, min, max)` calls. Only these move, and only within their bounds; every other parameter keeps its value.
    #[schemars(length(min = 1, max = 12))]
    pub params: Vec<String>,
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Rounds of (parameters with the poses held, then every pose refined locally); default 3.
    #[schemars(range(min = 1, max = 10))]
    pub rounds: Option<u64>,
    /// Model builds per round (default 60).
    #[schemars(range(min = 5, max = 500))]
    pub evals: Option<u64>,
}

/// A model axis a stated size is along.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum SizeAxis {
    X,
    Y,
    Z,
    Longest,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ScaleArgs {
    /// `depth` (the capture's depth against the render), `parallax` (metric cameras moving around an object that stays put) or `size` (give `axis` and `metres`).
    pub method: agentstar_reports::fit::ScaleMethod,
    /// With `size`: the model axis the size is along (default the longest side).
    pub axis: Option<SizeAxis>,
    /// With `size`: the object's size along `axis`, metres ("the laptop is 30 cm wide": axis x, metres 0.3).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub metres: Option<f64>,
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Rescale pose.json to the estimate (a pose version); default false: estimate only.
    pub apply: Option<bool>,
}

/// Why a keyframe cannot reach the gate: the categories `finish` accepts, each checked.
#[derive(Debug, Clone, PartialEq, Deserialize, JsonSchema)]
#[serde(tag = "category", rename_all = "snake_case", deny_unknown_fields)]
pub enum Unreachable {
    /// Hands or other occluders hide much of the object: accepted when the hidden share
    /// of the rendered model is over the run's threshold (`finish.min_occlusion_percent`
    /// in run.json, default 30).
    Occlusion {
        /// The share of the object you judge hidden, percent.
        percent: f64,
    },
    /// The mask is wrong here: name an image of this run that shows it (a render or a
    /// frames view).
    MaskError {
        /// Path of the image (inside the run directory or the capture).
        image: String,
        note: Option<String>,
    },
    /// The object is cut by the frame border (accepted when its mask touches the border).
    Truncated { note: Option<String> },
    /// The model cannot reach it (a deforming part, a part the model lacks): say what.
    OutOfReach {
        /// What the model cannot do here (at least 20 characters).
        note: String,
    },
}

impl Unreachable {
    fn label(&self) -> &'static str {
        match self {
            Unreachable::Occlusion { .. } => "occlusion",
            Unreachable::MaskError { .. } => "mask error",
            Unreachable::Truncated { .. } => "truncated",
            Unreachable::OutOfReach { .. } => "out of reach",
        }
    }
}

/// The arguments of the built-in loop's `delegate_pose` (run by the loop, not the toolbox).
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DelegateArgs {
    /// Each window's keyframes, e.g. `000000..000020`.
    #[schemars(length(min = 1))]
    pub windows: Vec<String>,
    #[schemars(length(min = 1))]
    pub brief: String,
}

fn flag(value: &Option<String>, name: &str) -> Vec<String> {
    value
        .as_deref()
        .map(str::trim)
        .filter(|v| !v.is_empty())
        .map(|v| vec![name.to_string(), v.to_string()])
        .unwrap_or_default()
}

tool!(Task, "task", Note, Nothing, NoArgs,
    "Return TASK.md: the goal, the conventions, how to work, how to read the images, the gates before finishing, and the whole scene API with a worked example. Read it first.",
    |_tb, _a, _step| Ok(ToolOutput::text(task_document())));

tool!(SceneRead, "scene_read", Diagnostic, Nothing, NoArgs,
    "Return the current scene.rhai and its check: parts, joints, the canonical frame (bounding box, centre) and warnings.",
    |tb, _a, _step| tb.scene_read());

tool!(SceneWrite, "scene_write", Shape, Scene, SceneWriteArgs,
    "Replace scene.rhai with a whole new script (a shape step), given as `script` or as `path` (a file in the run directory holding it). The script is built in the sandbox first: on an error you get the message with its line and nothing changes. On success a new scene version is saved and pose.json gains new joints at rest (removed joints are dropped). Check the shape with `turntable` afterwards.",
    |tb, a, step| tb.scene_write(&a.script(tb)?, step));

tool!(
    SceneRestore,
    "scene_restore",
    Shape,
    Scene,
    VersionArgs,
    "Make an earlier scene version current again (versions are listed by scene_read).",
    |tb, a, step| {
        let p = tb
            .run
            .scene_versions()
            .join(format!("{:04}.rhai", a.version));
        let script = agentstar_data::read_text(&p).map_err(|_| {
            AgentError::Tool(format!(
                "there is no scene version {}; the versions are {:?}",
                a.version,
                tb.run.list_scene_versions()
            ))
        })?;
        tb.scene_write(&script, step)
    }
);

tool!(Render, "render", Diagnostic, Nothing, RenderArgs,
    "Render the posed model into keyframes: `overlay` (shaded model over the frame) and `compare` (silhouette comparison: green model and mask agree, magenta mask not covered by the model, yellow model outside the mask, grey hand (ignored), blue model under the hand, on a near-black background; the legend is on each image), `ids` (parts in flat colours, visible pixels each). With `overlay`, also a contact sheet of the overlays; with `compare`, a sheet of every frame's comparison cropped around mask and model. For the raw keyframes without the model, use `frames`.",
    |tb, a, step| {
        let views = a.views.clone().filter(|v| !v.trim().is_empty()).unwrap_or_else(|| "overlay,compare".into());
        let (mut o, out, _) = tb.cli(
            &["render"],
            step,
            Render::NAME,
            [flag(&a.frames, "--frames"), vec!["--views".into(), views]].concat(),
        )?;
        if o.is_error {
            return Ok(o);
        }
        let written = o.images.len();
        o.images.truncate(MAX_IMAGES_RETURNED);
        o.text = format!(
            "render: wrote {written} image(s) in {}; {} returned (sheets first){}",
            out.display(),
            o.images.len(),
            if written > o.images.len() { "; the rest are files there" } else { "" }
        );
        Ok(o)
    });

tool!(Keyframes, "frames", Diagnostic, Nothing, KeyframesArgs,
    "Look at the raw keyframes (the input itself, no model): each keyframe cropped around its object mask with a margin, optionally zoomed (to judge thin parts: an edge, a handle) and outlined (`mask`: the mask's boundary in magenta and the hand's in cyan; `model`: the posed model's boundary in yellow). Returns sheets of the crops (each labelled with the frame and the crop's position in the frame) and, for a few frames, the crops themselves.",
    |tb, a, step| {
        let mut extra = [
            flag(&a.frames, "--frames"),
            vec!["--views".into(), "frame".into()],
        ]
        .concat();
        if let Some(m) = a.margin {
            extra.extend(["--margin".into(), m.to_string()]);
        }
        if let Some(z) = a.zoom {
            extra.extend(["--zoom".into(), z.to_string()]);
        }
        if let Some(ol) = a.outline {
            extra.extend(["--outline".into(), ol.as_str().into()]);
        }
        let (mut o, out, stdout) = tb.cli(&["render"], step, Keyframes::NAME, extra)?;
        if o.is_error {
            return Ok(o);
        }
        let report: RenderReport = serde_json::from_str(&stdout)
            .map_err(|e| AgentError::Tool(format!("render printed no render report ({e})")))?;
        let crops = report.frames.len();
        let sheets = report.sheets.len();
        o.images.truncate(MAX_IMAGES_RETURNED);
        let mut text = format!(
            "frames: {crops} keyframe crop(s) and {sheets} sheet(s) in {}; {} image(s) returned (sheets first){}",
            out.display(),
            o.images.len(),
            if crops + sheets > o.images.len() {
                "; the rest are files there"
            } else {
                ""
            }
        );
        for f in &report.frames {
            if let (Some([x, y, w, h]), Some(z)) = (f.crop, f.zoom) {
                text.push_str(&format!("\n- {}: crop at ({x}, {y}), {w}×{h} frame pixels, zoom {z:.2}", f.frame));
            }
        }
        for n in &report.notes {
            text.push_str(&format!("\nnote: {n}"));
        }
        o.text = text;
        Ok(o)
    });

tool!(Score, "score", Diagnostic, Nothing, FramesArgs,
    "Per keyframe: band IoU (the visible IoU without ±2 px around the mask's outline, where segmenters err: the gate is 0.98 on it), visible IoU (hands excluded), raw IoU, pixel counts, depth error when the capture has depth, and the appearance figure (colour agreement with the neighbouring keyframes and, where the model's parts differ in colour, with the model's own colours, pooled), with the agreement with the model's own colours alone beside it (`model_ncc`: does the pose put the model's print where the frame shows it). Lists the keyframes under the gate.",
    |tb, a, _step| {
        let report = tb.score_report(a.frames.as_deref())?;
        let mut o = ToolOutput::default();
        let mut head = format!("score: {} keyframe(s)", report.frames.len());
        if !report.frames.is_empty() {
            let gates: Vec<f64> = report.frames.iter().map(|f| f.gate()).collect();
            let min = gates.iter().copied().fold(1.0, f64::min);
            let mean = gates.iter().sum::<f64>() / gates.len() as f64;
            let below: Vec<&str> = report
                .frames
                .iter()
                .filter(|f| f.gate() < GATE_IOU)
                .map(|f| f.frame.as_str())
                .collect();
            o.scores.insert("iou_min".into(), min);
            o.scores.insert("iou_mean".into(), mean);
            head.push_str(&format!(
                ", gate IoU (visible, boundary band excluded) mean {mean:.4}, min {min:.4}; under the gate: {}",
                if below.is_empty() { "none".to_string() } else { below.join(", ") }
            ));
        }
        // The table a person reads; the report's numbers are the structured content.
        o.text = format!(
            "{head}\n{}",
            agentstar_reports::score_table(&report.frames, &report.sequence, &report.appearance)
        );
        o.structured = serde_json::to_value(&report).ok();
        Ok(o)
    });

tool!(Turntable, "turntable", Diagnostic, Nothing, TurntableArgs,
    "Eight views around the upright model (canonical +Z up) on a light background, one sheet per joint state: by default each joint's min, median and max over the keyframes (`states`: `all` or keyframes for others). The 3-D shape check after every shape step: parts floating, intersecting or missing from the back, and joints that move the wrong part or the wrong way.",
    |tb, a, step| {
        let (mut o, out, stdout) = tb.cli(
            &["turntable"],
            step,
            Turntable::NAME,
            flag(&a.states, "--states"),
        )?;
        if o.is_error {
            return Ok(o);
        }
        let report: TurntableReport = serde_json::from_str(&stdout)
            .map_err(|e| AgentError::Tool(format!("turntable printed no turntable report ({e})")))?;
        o.images = report.sheets.clone();
        o.images.truncate(MAX_IMAGES_RETURNED);
        let mut text = format!(
            "turntable: {} sheet(s) for {} joint state(s) in {}; {} returned",
            report.sheets.len(),
            report.states.len(),
            out.display(),
            o.images.len()
        );
        for st in &report.states {
            let joints: Vec<String> = st.joints.iter().map(|(k, v)| format!("{k} = {v:.2}")).collect();
            text.push_str(&format!(
                "\n- {} ({}): {}",
                st.label,
                st.source,
                if joints.is_empty() { "no joints".to_string() } else { joints.join(", ") }
            ));
        }
        for w in &report.warnings {
            text.push_str(&format!("\nwarning: {w}"));
        }
        o.text = text;
        Ok(o)
    });

tool!(Track, "track", Pose, Poses, TrackArgs,
    "Run the automatic tracker over every keyframe with the current model and scale (a pose step for all keyframes; the result is a new pose version, the previous ones stay in pose_history). Use it once the shape is right, then fix the frames it gets wrong with sweeps and flips. After a shape edit, `from: \"pose.json\"` refines the current poses instead of starting over (cheap), and `anchors` keeps the keyframes you trust exactly and carries them to their neighbours. Progress notifications carry its latest line; a run that is stopped keeps what it had tracked in pose.partial.json.",
    |tb, a, step| tb.track(&a, step));

tool!(Sweep, "sweep", Pose, Nothing, SweepArgs,
    "Search a bounded region around the current pose of each given keyframe by silhouette IoU (differential evolution, 6 seeded restarts) and return the ranked candidates with a candidate sheet; rows labelled `seen` are other places the search passed through (at least 10° from the rest, not refined; another basin where the box holds one, else the slope of the same one: refine one with a narrower sweep around it). Ranges are camera-frame increments and absolute joint states, e.g. `yaw:-30,30;pitch:-20,20;tz:-0.1,0.1;lid_hinge:0,90`. Commit a candidate with pose_commit (the result names its report).",
    |tb, a, step| {
        let extra = [
            vec!["--frames".into(), a.frames.clone()],
            vec!["--ranges".into(), a.ranges.clone()],
            a.strategy
                .map(|s| vec!["--strategy".into(), match s { Strategy::De => "de", Strategy::Grid => "grid" }.into()])
                .unwrap_or_default(),
            a.evals.map(|e| vec!["--evals".into(), e.to_string()]).unwrap_or_default(),
        ]
        .concat();
        tb.search(SearchVerb::Sweep, Some(&a.frames), extra, step)
    });

tool!(Apply, "apply", Pose, Nothing, ApplyArgs,
    "Score one explicit order on one keyframe, e.g. `yaw:15;hinge:40`, and return it as a candidate (to compare with a sweep's).",
    |tb, a, step| {
        let extra = vec!["--frame".into(), a.frame.clone(), "--order".into(), a.order.clone()];
        tb.search(SearchVerb::Apply, Some(&a.frame), extra, step)
    });

tool!(Osweep, "osweep", Pose, Nothing, OsweepArgs,
    "Search object-frame rotations per keyframe: a preset (`z:flip`, `z:quarters`, `z:octants`, `so3:24`) or grid ranges (`rz:-180,180,9;rx:-15,15,3`). For objects that look alike from several sides.",
    |tb, a, step| {
        // The region is the agent's decision: no silent default grid, and not two at once.
        match (&a.opreset, &a.ranges) {
            (None, None) => return Ok(ToolOutput::error(
                "osweep needs a region and searched nothing: give `opreset` (`z:flip`, `z:quarters`, `z:octants`, `so3:24`) or `ranges` (`rz:-180,180,9;rx:-15,15,3`), and `frames` (default: every keyframe)",
            )),
            (Some(_), Some(_)) => return Ok(ToolOutput::error(
                "osweep takes `opreset` or `ranges`, not both: nothing was searched",
            )),
            _ => {}
        }
        let extra = [flag(&a.frames, "--frames"), flag(&a.opreset, "--opreset"), flag(&a.ranges, "--ranges")].concat();
        tb.search(SearchVerb::Osweep, a.frames.as_deref(), extra, step)
    });

tool!(Oapply, "oapply", Pose, Nothing, OapplyArgs,
    "Score a set of object-frame rotations on each keyframe, default `flips|swaps` (identity, the 180° flips about x, y, z, and for each hinge the half-turn that swaps its two sides: lid and base), each refined before ranking. The flip check for near-symmetric objects: a flipped or swapped pose can score as well as the right one, so look at the sheet.",
    |tb, a, step| {
        let extra = [flag(&a.frames, "--frames"), flag(&a.set, "--set")].concat();
        tb.search(SearchVerb::Oapply, a.frames.as_deref(), extra, step)
    });

tool!(OapplyAll, "oapply_all", Pose, Nothing, OapplyAllArgs,
    "Apply one object-frame rotation to every keyframe (`rz:90` or `flip:x`): for a model built the wrong way round; or to a block of keyframes (`frames`), to try a twin for a run of frames chained from a wrong pose: where the block meets the other frames, each frame's note gives the temporal step before and after the rotation. Nothing changes until `pose_commit`.",
    |tb, a, step| {
        let extra = [vec!["--rotation".into(), a.rotation.clone()], flag(&a.frames, "--frames")].concat();
        tb.search(SearchVerb::OapplyAll, a.frames.as_deref(), extra, step)
    });

tool!(PoseCommit, "pose_commit", Pose, Poses, PoseCommitArgs,
    "Put poses into pose.json (atomically, as a new pose version). `report` is the path a search returned (then `rank` picks the candidate, or `label` the same candidate in every frame, e.g. `swap:hinge`), a pose file (a track's pose.json) or a history version file; `frames` limits it to some keyframes.",
    |tb, a, _step| tb.pose_commit(&a));

tool!(
    PoseHistoryTool,
    "pose_history",
    Diagnostic,
    Nothing,
    PoseHistoryArgs,
    "List the pose versions with the command that made each (the last 50 unless `last` says). With `frame`: that keyframe's pose and visible IoU (with the current model) in every version, and where it changed; restore a good one with pose_restore and `frames`.",
    |tb, a, _step| tb.pose_history(&a)
);

tool!(
    PoseRestore,
    "pose_restore",
    Pose,
    Poses,
    PoseRestoreArgs,
    "Make an earlier pose version current again (recorded as a new version), whole or only for some keyframes (`frames`; the others stay as they are). Versions are listed by pose_history.",
    |tb, a, _step| tb.pose_restore(&a)
);

tool!(Temporal, "temporal", Diagnostic, Nothing, TemporalArgs,
    "The temporal report: rotation (with the step's axis in the model's frame: `+z` is a spin about the model's z axis), translation and radial velocity and acceleration from keyframe to keyframe (camera motion removed), joint velocities, and a plot. Large steps are either real or wrong poses (often flips): confirm them in the frames or fix them.",
    |tb, a, step| {
        let out = tb.run.step_dir(step, Temporal::NAME);
        std::fs::create_dir_all(&out).map_err(|e| agentstar_data::DataError::io(&out, e))?;
        let plot = out.join("temporal.png");
        let mut args: Vec<String> = vec!["temporal".into()];
        args.extend(tb.session_args());
        args.extend(["--plot".into(), plot.display().to_string()]);
        args.extend(flag(&a.sort_by, "--sort-by"));
        let (ok, stdout, stderr) = tb.exec(&args)?;
        if !ok {
            return Ok(ToolOutput::error(stderr.trim().to_string()));
        }
        Ok(ToolOutput { text: stdout, images: pngs(&out), ..Default::default() })
    });

tool!(
    PoseDiff,
    "pose_diff",
    Diagnostic,
    Nothing,
    PoseDiffArgs,
    "The residual between two keyframes' poses (rotation in degrees, translation, joint changes).",
    |tb, a, _step| {
        let mut args: Vec<String> = vec!["pose-diff".into()];
        args.extend(tb.session_args());
        args.extend(["--a".into(), a.a.clone(), "--b".into(), a.b.clone()]);
        let (ok, stdout, stderr) = tb.exec(&args)?;
        if !ok {
            return Ok(ToolOutput::error(stderr.trim().to_string()));
        }
        let report: PoseDiffReport = serde_json::from_str(&stdout)
            .map_err(|e| AgentError::Tool(format!("pose-diff printed no report ({e})")))?;
        Ok(ToolOutput {
            text: stdout,
            structured: serde_json::to_value(&report).ok(),
            ..Default::default()
        })
    }
);

tool!(Critic, "critic", Diagnostic, Nothing, CriticArgs,
    "Ask a separate model to criticise one keyframe: it sees the frame, the overlay and the turntable and returns realism and identity scores and discrepancies tagged shape, pose, joint state or joint definition, with a severity and a direction of change. Skipped with a note when no critic model is configured.",
    |tb, a, step| tb.critic(&a.frame, step));

tool!(Notes, "notes", Note, Notes, NotesArgs,
    "Append to NOTES.md, your memory across contexts (what the object is, which parts move, what you ruled out).",
    |tb, a, step| {
        let p = tb.run.notes_path();
        let mut all = agentstar_data::read_text(&p).unwrap_or_default();
        let line = format!("\n- (step {step}) {}\n", a.text.trim());
        if all.len() + line.len() > MAX_NOTES_BYTES {
            return Ok(ToolOutput::error(format!(
                "NOTES.md is full ({} of {MAX_NOTES_BYTES} bytes): it is in every request, so keep notes short; nothing was added",
                all.len()
            )));
        }
        all.push_str(&line);
        agentstar_data::atomic::write_atomic(&p, all.as_bytes())?;
        Ok(ToolOutput::text("noted"))
    });

tool!(FitShape, "fit_shape", Shape, Scene, FitShapeArgs,
    "Fit shape parameters the scene declares with `let d = param(\"depth\", 0.6, 0.4, 0.9);` (value, min, max) against the committed poses over the keyframes (default all): only the parameters you name move, within their bounds, while every keyframe's pose is refined locally. Returns the values, the IoU change per keyframe and before/after silhouette comparisons; when the mean IoU rises, the fitted values become the script's `param` values (a new scene version) and the refined poses a pose version. Fit proportions you judged wrong by eye on poses that are right otherwise; then look at a turntable (a shape that games IoU from these views can still be wrong in 3-D).",
    |tb, a, step| tb.fit_shape(&a, step));

tool!(Scale, "scale", Pose, Poses, ScaleArgs,
    "Estimate the scale (metres per model unit) from the capture's depth, from the parallax of metric cameras moving around an object that stays put, or from a size you state along a model axis; with `apply: true` rescale pose.json to it (rotations kept, translations scaled, so every silhouette and IoU stays the same; a pose version). Silhouettes never say the scale: use this before reporting metric results.",
    |tb, a, step| tb.scale(&a, step));

tool!(Finish, "finish", Diagnostic, Nothing, FinishArgs,
    "Check the gates and end the run when they hold: every keyframe's band IoU (the gate `score` reports) ≥ 0.98 or a checked reason for it in `unreachable` (categories: occlusion over the run's threshold, a mask error shown on an image, truncated by the frame border, out of the model's reach with a note); at most a quarter of the keyframes (the run's `finish.max_share_under_gate`) under the gate even with reasons; a turntable after the last shape change; a temporal report after the last change of the poses (a commit, track, restore, fit or rescale; searches that were not committed do not count); every large step of the current poses (over 90°, as `temporal` warns) named in `steps_checked` with what you found, after looking at one of its frames (`oapply`, `osweep`, `render` or `frames`). Returns what is missing otherwise.",
    |tb, a, _step| tb.finish(&a));

/// Every tool, in the order offered.
pub static REGISTRY: &[ToolDef] = &[
    ToolDef::of::<Task>(),
    ToolDef::of::<SceneRead>(),
    ToolDef::of::<SceneWrite>(),
    ToolDef::of::<SceneRestore>(),
    ToolDef::of::<FitShape>(),
    ToolDef::of::<Render>(),
    ToolDef::of::<Keyframes>(),
    ToolDef::of::<Score>(),
    ToolDef::of::<Turntable>(),
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

/// PNG files under `dir`, sheets first, then by name.
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
        (!n.contains("sheet"), n)
    });
    v
}

/// A search's result as an MCP client should read it: per frame the ranked candidates
/// (rank, scores, the order that made each), then what to do with them — look at the
/// sheet and keep one with `pose_commit` by report and rank. No pose numbers and no shell
/// commands: the agent never types poses.
pub fn search_text(report: &SearchReport, path: &Path) -> String {
    let mut t = String::new();
    for f in &report.frames {
        let with_model = f.ranked.iter().any(|c| c.model_ncc.is_some());
        t.push_str(&format!(
            "{} {}\n{:<5} {:>8} {:>8} {:>8} {:>8}{}  order\n",
            report.verb.stem(),
            f.frame,
            "rank",
            "score",
            "iou_band",
            "iou_vis",
            "iou_raw",
            if with_model { "    model" } else { "" }
        ));
        let or_na = |v: Option<f64>| v.map_or("n/a".into(), |v| format!("{v:.4}"));
        for c in &f.ranked {
            let model = if with_model {
                format!(
                    " {:>8}",
                    c.model_ncc.map_or("n/a".into(), |v| format!("{v:.2}"))
                )
            } else {
                String::new()
            };
            t.push_str(&format!(
                "{:<5} {:>8.4} {:>8} {:>8} {:>8.4}{model}  {}\n",
                c.rank,
                c.gate,
                or_na(c.iou_band),
                or_na(c.iou_visible),
                c.iou_raw,
                c.label
            ));
        }
        if with_model {
            t.push_str("model: the frame's colours against the model's own part colours at the candidate (NCC, −1..1): where candidates tie in IoU (a flipped or swapped twin), the higher one puts the model's print where the frame shows it.\n");
        }
        for n in &f.notes {
            t.push_str(&format!("note: {n}\n"));
        }
        if f.ranked.iter().any(|c| c.label.starts_with("seen ")) {
            t.push_str("seen: a place the search passed through, at least 10° in rotation or in a joint from every row above it, and not refined: another basin where the region holds one, else the slope of the same one (refine one with a narrow `sweep` around its order before trusting its score).\n");
        }
        if let Some(first) = f.ranked.first().filter(|c| !c.outside_region.is_empty()) {
            t.push_str(&format!(
                "note: rank 0 is the start, which lies outside the region you named ({}): it is first only because nothing inside the region scored higher{}.\n",
                first.outside_region.join(", "),
                if f.ranked.len() > 1 {
                    "; the region's best is rank 1"
                } else {
                    ""
                }
            ));
        }
        if let [only] = &f.ranked[..] {
            // (A start outside the region has its own note above: it may well not be the
            // best pose here.)
            if only.label.starts_with(agentstar_reports::KEPT_START)
                && only.outside_region.is_empty()
            {
                t.push_str("note: nothing the search evaluated in this region scored above the start. Either the start is already the best pose here (a sharp optimum: `apply` single small steps to see the surface), or a better pose lies outside the region (widen it, or try the flips with `osweep`).\n");
            }
        }
    }
    let frames: Vec<&str> = report.frames.iter().map(|f| f.frame.as_str()).collect();
    if report.frames.iter().any(|f| !f.ranked.is_empty()) {
        t.push_str(&format!(
            "Ranked by score (the visible IoU the search optimises, with depth where weighted); the gate ({GATE_IOU}) is on iou_band, the visible IoU without the mask's uncertain outline.\n"
        ));
        t.push_str(&format!(
            "To keep a candidate, look at its tiles on the sheet first (a flipped twin can score as high), then call `pose_commit` with report = \"{}\" and its rank (0 = best) or, for the same candidate in every frame, its label{}. Nothing is changed until you commit.\n",
            path.display(),
            if frames.len() > 1 {
                format!("; add frames = \"…\" to commit only some of {}", frames.join(", "))
            } else {
                String::new()
            }
        ));
    }
    t
}

/// The frames of `spec` outside `window` (names), after resolving the spec to names.
fn outside_window(window: &[String], names: &[String]) -> Vec<String> {
    names
        .iter()
        .filter(|n| !window.contains(n))
        .cloned()
        .collect()
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

    pub fn session_args(&self) -> Vec<String> {
        vec![
            "--capture".into(),
            self.run.capture.display().to_string(),
            "--model".into(),
            self.run.scene.display().to_string(),
            "--poses".into(),
            self.run.poses.display().to_string(),
        ]
    }

    /// Opens the run's capture.
    pub fn capture(&self) -> Result<agentstar_data::capture::Capture> {
        agentstar_data::capture::Capture::open(&self.run.capture).map_err(|problems| {
            AgentError::Tool(format!(
                "the capture {} cannot be opened: {}",
                self.run.capture.display(),
                problems
                    .iter()
                    .map(|p| p.to_string())
                    .collect::<Vec<_>>()
                    .join("; ")
            ))
        })
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
        let mut a: Vec<String> = vec!["score".into()];
        a.extend(self.session_args());
        a.extend(flag(&frames.map(str::to_string), "--frames"));
        a.push("--json".into());
        let (_, stdout, stderr) = self.exec(&a)?;
        // `score` exits 1 when a frame is under the gate; its JSON is the result.
        serde_json::from_str(&stdout).map_err(|_| AgentError::Tool(stderr.trim().to_string()))
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

    /// Runs the executable (the one runner of every child tool); returns (success,
    /// stdout, stderr). A child that runs past `timeout_s` is killed.
    pub fn exec(&self, args: &[String]) -> Result<(bool, String, String)> {
        let mut child = Command::new(&self.exe)
            .args(args)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .map_err(|e| AgentError::Tool(format!("cannot run {}: {e}", self.exe.display())))?;
        // Read both pipes on threads so a large output never blocks the child, each kept up
        // to MAX_TOOL_OUTPUT_BYTES (the rest is drained and dropped, and the text says so).
        let out = child.stdout.take();
        let err = child.stderr.take();
        let t_out = std::thread::spawn(move || out.map(read_capped).unwrap_or_default());
        let activity = ACTIVITY.with(|a| a.borrow().clone());
        let t_err = std::thread::spawn(move || {
            err.map(|inner| {
                read_capped(LastLine {
                    inner,
                    activity,
                    pending: Vec::new(),
                })
            })
            .unwrap_or_default()
        });
        let start = std::time::Instant::now();
        let status = loop {
            match child.try_wait() {
                Ok(Some(s)) => break s,
                Ok(None) if start.elapsed().as_secs() > self.timeout_s => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Ok((
                        false,
                        String::new(),
                        format!("the tool ran past {} s and was stopped", self.timeout_s),
                    ));
                }
                Ok(None) => std::thread::sleep(std::time::Duration::from_millis(20)),
                Err(e) => return Err(AgentError::Tool(format!("waiting for a tool: {e}"))),
            }
        };
        let stdout = t_out.join().unwrap_or_default();
        let stderr = t_err.join().unwrap_or_default();
        Ok((status.success(), stdout, stderr))
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
        let run = || match (def.call)(self, args, step) {
            Ok(o) => o,
            Err(e) => ToolOutput::error(e.to_string()),
        };
        if def.writes == Writes::Nothing {
            run()
        } else {
            // A poisoned lock only means another writer panicked; the files are whole.
            let _guard = self
                .writer
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            run()
        }
    }

    /// Runs `verb` with the session's inputs and `--out` the step's directory.
    fn cli(
        &self,
        verb: &[&str],
        step: u64,
        tool: &str,
        extra: Vec<String>,
    ) -> Result<(ToolOutput, PathBuf, String)> {
        let out = self.run.step_dir(step, tool);
        let mut a: Vec<String> = verb.iter().map(|s| s.to_string()).collect();
        a.extend(self.session_args());
        a.push("--out".into());
        a.push(out.display().to_string());
        a.extend(extra);
        a.push("--json".into());
        let (ok, stdout, stderr) = self.exec(&a)?;
        if !ok {
            return Ok((ToolOutput::error(stderr.trim().to_string()), out, stdout));
        }
        let images = pngs(&out);
        Ok((
            ToolOutput {
                text: format!(
                    "{tool}: done, {} image(s) in {}\n{stdout}",
                    images.len(),
                    out.display()
                ),
                images,
                ..Default::default()
            },
            out,
            stdout,
        ))
    }

    /// A search verb: its report read back as a [`SearchReport`], its text table as the
    /// result, its sheets as images.
    fn search(
        &self,
        verb: SearchVerb,
        frames: Option<&str>,
        extra: Vec<String>,
        step: u64,
    ) -> Result<ToolOutput> {
        if let Err(e) = self.check_window(frames) {
            return Ok(ToolOutput::error(e));
        }
        let (o, out, _) = self.cli(&[verb.command()], step, verb.stem(), extra)?;
        if o.is_error {
            return Ok(o);
        }
        let path = verb.report_path(&out);
        let report = SearchReport::read(&path)?;
        let mut images = o.images;
        let written = images.len();
        images.truncate(MAX_IMAGES_RETURNED);
        let mut scores = BTreeMap::new();
        if let Some(min) = report.min_gate_iou {
            scores.insert("best_iou_min".into(), min);
        }
        let mut text = search_text(&report, &path);
        if written > images.len() {
            text.push_str(&format!(
                "{written} sheet page(s) written in {}; {} returned\n",
                out.display(),
                images.len()
            ));
        }
        Ok(ToolOutput {
            // The path first (play-test, 2026-12-02): it is what `pose_commit` needs, and
            // step numbers cannot be predicted.
            text: format!("report: {}\n{text}", path.display()),
            images,
            scores,
            structured: serde_json::to_value(&report).ok(),
            ..Default::default()
        })
    }

    fn pose_commit(&self, a: &PoseCommitArgs) -> Result<ToolOutput> {
        if self.window.is_some() {
            let frames = a.frames.as_deref().filter(|f| !f.trim().is_empty());
            if let Err(e) = self.check_window(frames) {
                return Ok(ToolOutput::error(e));
            }
        }
        let report = match self.confine(&a.report) {
            Ok(p) => p,
            Err(e) => return Ok(ToolOutput::error(format!("pose_commit: {e}"))),
        };
        let mut args = vec![
            "pose".to_string(),
            "commit".into(),
            "--poses".into(),
            self.run.poses.display().to_string(),
            "--report".into(),
            report.display().to_string(),
            "--json".into(),
        ];
        let label = a.label.as_deref().map(str::trim).filter(|l| !l.is_empty());
        match (label, a.rank) {
            (Some(_), Some(_)) => {
                return Ok(ToolOutput::error(
                    "pose_commit: give `rank` or `label`, not both".to_string(),
                ))
            }
            (Some(l), None) => args.extend(["--label".to_string(), l.to_string()]),
            (None, rank) => args.extend(["--rank".to_string(), rank.unwrap_or(0).to_string()]),
        }
        let which = match label {
            Some(l) => format!("candidate `{l}`"),
            None => format!("candidate rank {}", a.rank.unwrap_or(0)),
        };
        args.extend(flag(&a.frames, "--frames"));
        let (ok, stdout, stderr) = self.exec(&args)?;
        if !ok {
            return Ok(ToolOutput::error(stderr.trim().to_string()));
        }
        let r: CommitReport = serde_json::from_str(&stdout).map_err(|e| {
            AgentError::Tool(format!(
                "pose commit printed no commit report ({e}): {stdout}"
            ))
        })?;
        Ok(ToolOutput {
            text: format!(
                "committed {which} in each of {} frame(s) ({}) to pose.json as version {}",
                r.committed.len(),
                r.committed.join(", "),
                r.version
            ),
            pose_changed: true,
            pose_version: Some(r.version),
            structured: serde_json::to_value(&r).ok(),
            ..Default::default()
        })
    }

    /// `agentstar track` writing pose.json itself, as a version of its history (the
    /// command that made it is recorded there, the step in the ledger).
    fn track(&self, a: &TrackArgs, _step: u64) -> Result<ToolOutput> {
        if self.window.is_some() {
            return Ok(ToolOutput::error(
                "track changes every keyframe; a pose sub-agent works on its window with sweeps and flips",
            ));
        }
        let mut args = vec![
            "track".to_string(),
            self.run.capture.display().to_string(),
            "--model".into(),
            self.run.scene.display().to_string(),
            "--out".into(),
            self.run.poses.display().to_string(),
            "--json".into(),
        ];
        let from = a.from.as_deref().map(str::trim).filter(|f| !f.is_empty());
        let anchors = a
            .anchors
            .as_deref()
            .map(str::trim)
            .filter(|f| !f.is_empty());
        match (from, anchors) {
            (None, Some(_)) => {
                return Ok(ToolOutput::error(
                    "track: `anchors` keeps keyframes of a warm start; give `from` too (\"pose.json\" for the current poses)",
                ))
            }
            (Some(f), _) => {
                let path = match self.confine(f) {
                    Ok(p) => p,
                    Err(e) => return Ok(ToolOutput::error(format!("track: {e}"))),
                };
                args.extend(["--from".into(), path.display().to_string()]);
                if let Some(spec) = anchors {
                    // The frame grammar, checked here so a bad name is the tool's error.
                    let names = self.frame_names(Some(spec))?;
                    args.extend(["--anchors".into(), names.join(",")]);
                }
            }
            (None, None) => {}
        }
        match (a.scale, from) {
            (Some(s), _) => args.extend(["--scale".into(), s.to_string()]),
            (None, Some(_)) => {}
            (None, None) => {
                args.extend(["--scale-from".into(), self.run.poses.display().to_string()])
            }
        }
        let (ok, stdout, stderr) = self.exec(&args)?;
        if !ok {
            let mut text = stderr.trim().to_string();
            // What the stopped run had tracked (the command keeps it beside the pose file).
            let partial = agentstar_data::posefile::partial_path(&self.run.poses);
            if partial.is_file() {
                let name = partial
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                text.push_str(&format!(
                    "\nThe poses it had tracked are kept in {name} (frames marked \"moved\": true); track with `from: \"{name}\"` and `anchors` on those frames goes on from them."
                ));
            }
            return Ok(ToolOutput::error(text));
        }
        let report: TrackReport = serde_json::from_str(&stdout)
            .map_err(|e| AgentError::Tool(format!("track printed no track report ({e})")))?;
        let version = report
            .pose_version
            .ok_or_else(|| AgentError::Tool("track recorded no pose version".into()))?;
        let mut scores = BTreeMap::new();
        scores.insert("iou_min".into(), report.sequence.min_iou_visible);
        scores.insert("iou_mean".into(), report.sequence.mean_iou_visible);
        Ok(ToolOutput {
            text: {
                // The joint states come from the pose file the tracker wrote; should it not
                // read, the table says so rather than losing its column unannounced.
                let poses = agentstar_data::posefile::PoseFile::read(&report.poses);
                let unread = match &poses {
                    Err(e) => format!("(joint states not shown: {e})\n"),
                    Ok(_) => String::new(),
                };
                format!(
                    "{}{unread}pose.json is version {version}; the earlier versions are in pose_history.",
                    track_text(&report, poses.ok().as_ref())
                )
            },
            pose_changed: true,
            pose_version: Some(version),
            scores,
            structured: serde_json::to_value(&report).ok(),
            ..Default::default()
        })
    }

    /// Whether this toolbox serves the tool called `name`: every tool but `critic`, which
    /// needs a critic model (play-tests 5 and 6 found it listed and unusable).
    pub fn offers(&self, name: &str) -> bool {
        name != Critic::NAME || self.critic.is_some()
    }

    fn critic(&self, frame: &str, step: u64) -> Result<ToolOutput> {
        let Some(critic) = &self.critic else {
            return Ok(ToolOutput::text(
                "critic skipped: no critic model is configured (agentstar run --critic PROVIDER:MODEL, or AGENTSTAR_CRITIC for the MCP server)",
            ));
        };
        let names = self.frame_names(Some(frame))?;
        let [name] = names.as_slice() else {
            return Ok(ToolOutput::error(format!(
                "critic: `{frame}` names {} frames; name one",
                names.len()
            )));
        };
        let (r, _, _) = self.cli(
            &["render"],
            step,
            Critic::NAME,
            vec![
                "--frames".into(),
                name.clone(),
                "--views".into(),
                "overlay,compare,frame".into(),
            ],
        )?;
        if r.is_error {
            return Ok(r);
        }
        let tt = self.call(Turntable::NAME, &Value::Null, step);
        // The keyframe first (cropped around its mask, within the image limits), then the
        // overlay and the comparison, then one turntable sheet.
        let mut images: Vec<PathBuf> = r
            .images
            .into_iter()
            .filter(|p| !p.to_string_lossy().contains("sheet"))
            .collect();
        images.sort_by_key(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("frame_"))
        });
        images.extend(tt.images.into_iter().take(1));
        match critic(name, &images) {
            Ok(text) => Ok(ToolOutput {
                text,
                images,
                ..Default::default()
            }),
            Err(e) => Ok(ToolOutput::error(format!("the critic failed: {e}"))),
        }
    }

    fn scene_read(&self) -> Result<ToolOutput> {
        let script = agentstar_data::read_text(&self.run.scene)?;
        let (_, check, stderr) = self.exec(&[
            "check".into(),
            self.run.scene.display().to_string(),
            "--json".into(),
        ])?;
        // The check's report, typed (absent when the scene does not build: then its error).
        let report: Option<CheckReport> = serde_json::from_str(&check).ok();
        Ok(ToolOutput {
            // The file's path: a coding agent edits the script there and passes it back
            // whole (play-test 7 cut the script out of this text to edit it).
            text: format!(
                "scene.rhai ({}; versions saved: {:?}):\n```rhai\n{}\n```\ncheck:\n{}{}",
                self.run.scene.display(),
                self.run.list_scene_versions(),
                script.trim_end(),
                report
                    .as_ref()
                    .map(|r| agentstar_reports::check_text(r, None))
                    .unwrap_or_default(),
                stderr.trim()
            ),
            structured: report.and_then(|r| serde_json::to_value(&r).ok()),
            ..Default::default()
        })
    }

    /// Checks `script` in the sandbox from a candidate file of its own (beside the scene,
    /// so it reaches the same mesh files), then makes it the scene and a new version.
    /// Runs under the writer lock.
    fn scene_write(&self, script: &str, step: u64) -> Result<ToolOutput> {
        if self.window.is_some() {
            return Ok(ToolOutput::error(
                "a pose sub-agent cannot change the shape",
            ));
        }
        let dir = self
            .run
            .scene
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let mut candidate = tempfile::Builder::new()
            .prefix(".scene_candidate-")
            .suffix(".rhai")
            .tempfile_in(dir)
            .map_err(|e| agentstar_data::DataError::io(dir, e))?;
        std::io::Write::write_all(&mut candidate, script.as_bytes())
            .and_then(|_| candidate.as_file().sync_all())
            .map_err(|e| agentstar_data::DataError::io(candidate.path(), e))?;
        let shown = candidate.path().display().to_string();
        let (ok, check, stderr) = self.exec(&["check".into(), shown.clone(), "--json".into()])?;
        if !ok {
            return Ok(ToolOutput::error(format!(
                "the scene was not changed: {}",
                stderr.trim().replace(&shown, "scene.rhai")
            )));
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = candidate
                .as_file()
                .set_permissions(std::fs::Permissions::from_mode(0o644));
        }
        // The check passed; its report typed (its raw text shown should it not parse).
        let report: Option<CheckReport> =
            serde_json::from_str::<CheckReport>(&check)
                .ok()
                .map(|mut r| {
                    r.model = self.run.scene.clone();
                    r
                });
        // The warnings of the scene this replaces (none when it does not build).
        let (_, before_check, _) = self.exec(&[
            "check".into(),
            self.run.scene.display().to_string(),
            "--json".into(),
        ])?;
        let before_warnings = serde_json::from_str::<CheckReport>(&before_check)
            .map(|r| r.warnings)
            .unwrap_or_default();
        // The model the poses were made for: a moved origin is compensated against it.
        let before = agentstar_data::scenefile::load_model(&self.run.scene)
            .ok()
            .map(|m| m.model);
        // The scene and its version change together under the run's scene lock, which
        // every process serving this run (two MCP servers, the loop) takes.
        let _scene_lock = self.run.lock_scene()?;
        candidate
            .persist(&self.run.scene)
            .map_err(|e| agentstar_data::DataError::io(&self.run.scene, e.error))?;
        let version = self.run.list_scene_versions().last().copied().unwrap_or(0) + 1;
        self.run.save_scene_version(version)?;
        let (joints, pose_version) = agentstar_data::poses::reconcile(
            &self.run.scene,
            &self.run.poses,
            before.as_ref(),
            &format!("scene version {version} (step {step}): joints reconciled"),
        )?;
        Ok(ToolOutput {
            text: format!(
                "scene version {version} saved.{}\ncheck:\n{}",
                if joints.is_empty() {
                    String::new()
                } else {
                    format!(" pose.json: {}.", joints.join("; "))
                },
                report.as_ref().map_or_else(
                    || check.trim().to_string(),
                    |r| agentstar_reports::check_text(r, Some(&before_warnings))
                )
            ),
            structured: report.as_ref().and_then(|r| serde_json::to_value(r).ok()),
            scene_version: Some(version),
            pose_changed: pose_version.is_some(),
            pose_version,
            ..Default::default()
        })
    }

    /// `scale`: `agentstar scale`, its rescaled poses committed as a pose version when asked.
    fn scale(&self, a: &ScaleArgs, step: u64) -> Result<ToolOutput> {
        let apply = a.apply.unwrap_or(false);
        if apply && self.window.is_some() {
            return Ok(ToolOutput::error(
                "a pose sub-agent cannot rescale every keyframe",
            ));
        }
        let out = self.run.step_dir(step, Scale::NAME);
        std::fs::create_dir_all(&out).map_err(|e| agentstar_data::DataError::io(&out, e))?;
        let scaled = out.join("scaled_pose.json");
        let method = match a.method {
            agentstar_reports::fit::ScaleMethod::Depth => "depth",
            agentstar_reports::fit::ScaleMethod::Parallax => "parallax",
            agentstar_reports::fit::ScaleMethod::Size => "size",
        };
        let mut args: Vec<String> = vec!["scale".into()];
        args.extend(self.session_args());
        args.extend([
            "--from".into(),
            method.into(),
            "--out".into(),
            scaled.display().to_string(),
            "--json".into(),
        ]);
        if let Some(axis) = a.axis {
            let axis = match axis {
                SizeAxis::X => "x",
                SizeAxis::Y => "y",
                SizeAxis::Z => "z",
                SizeAxis::Longest => "longest",
            };
            args.extend(["--axis".into(), axis.into()]);
        }
        if let Some(m) = a.metres {
            args.extend(["--metres".into(), m.to_string()]);
        }
        args.extend(flag(&a.frames, "--frames"));
        let (ok, stdout, stderr) = self.exec(&args)?;
        if !ok {
            return Ok(ToolOutput::error(stderr.trim().to_string()));
        }
        let report: agentstar_reports::fit::ScaleReport =
            serde_json::from_str(&stdout).map_err(|e| {
                AgentError::Tool(format!("scale printed no scale report ({e}): {stdout}"))
            })?;
        let mut text = format!(
            "scale from {method}: {} → {:.6} m per model unit (translations × {:.4}; spread {:.2}%, {} sample(s))\n",
            report.scale_before,
            report.scale_after,
            report.ratio,
            100.0 * report.spread,
            report.samples
        );
        for n in &report.notes {
            text.push_str(&format!("note: {n}\n"));
        }
        let mut scores = BTreeMap::new();
        scores.insert("scale".to_string(), report.scale_after);
        let structured = serde_json::to_value(&report).ok();
        if !apply {
            text.push_str(if !report.weak {
                "pose.json is unchanged; call scale again with `apply: true` to rescale it.\n"
            } else {
                // A play-test agent was offered a parallax estimate of an object moving in
                // the world (spread 61%) with the same line as a sound one.
                "pose.json is unchanged. The notes above say this estimate is weak: apply it only if you can rule them out. Otherwise state a size you can judge in the frames (method `size` with `axis` and `metres`), or use depth where the capture has it.\n"
            });
            return Ok(ToolOutput {
                text,
                scores,
                structured,
                ..Default::default()
            });
        }
        let pf = PoseFile::read(&scaled)?;
        let version = PoseHistory::new(&self.run.poses).replace(
            pf,
            &format!(
                "scale from {method} (step {step}): {} -> {:.6} m per unit",
                report.scale_before, report.scale_after
            ),
        )?;
        text.push_str(&format!(
            "pose.json rescaled (version {version}); every IoU is as it was.\n"
        ));
        Ok(ToolOutput {
            text,
            scores,
            structured,
            pose_changed: true,
            pose_version: Some(version),
            ..Default::default()
        })
    }

    /// `fit_shape`: `agentstar fit-shape` in the step's directory; when the mean IoU rose,
    /// its script becomes the scene (a new version) and its poses a pose version. Runs
    /// under the writer lock.
    fn fit_shape(&self, a: &FitShapeArgs, step: u64) -> Result<ToolOutput> {
        if self.window.is_some() {
            return Ok(ToolOutput::error(
                "a pose sub-agent cannot change the shape",
            ));
        }
        let names: Vec<String> = a.params.iter().map(|p| p.trim().to_string()).collect();
        if let Some(bad) = names.iter().find(|n| n.is_empty() || n.contains(',')) {
            return Ok(ToolOutput::error(format!(
                "fit_shape: `{bad}` is not a parameter name (one name per list entry)"
            )));
        }
        let extra = [
            vec!["--params".to_string(), names.join(",")],
            flag(&a.frames, "--frames"),
            a.rounds
                .map(|r| vec!["--rounds".into(), r.to_string()])
                .unwrap_or_default(),
            a.evals
                .map(|e| vec!["--evals".into(), e.to_string()])
                .unwrap_or_default(),
        ]
        .concat();
        let (o, _, stdout) = self.cli(&["fit-shape"], step, FitShape::NAME, extra)?;
        if o.is_error {
            return Ok(o);
        }
        let report: agentstar_reports::fit::FitReport =
            serde_json::from_str(&stdout).map_err(|e| {
                AgentError::Tool(format!("fit-shape printed no fit report ({e}): {stdout}"))
            })?;
        let values: Vec<String> = report
            .params
            .iter()
            .map(|p| {
                format!(
                    "{} {} → {} (bounds [{}, {}]{})",
                    p.name,
                    agentstar_scene::format_param_value(p.before),
                    agentstar_scene::format_param_value(p.after),
                    p.min,
                    p.max,
                    if p.at_bound { ", AT A BOUND" } else { "" }
                )
            })
            .collect();
        let mut text = format!(
            "fit_shape: {}\nvisible IoU over {} keyframe(s): mean {:.4} → {:.4}, min {:.4} → {:.4}\n",
            values.join("; "),
            report.frames.len(),
            report.iou_mean_before,
            report.iou_mean_after,
            report.iou_min_before,
            report.iou_min_after
        );
        if let Some(line) = unmoved_line(&report) {
            text.push_str(&line);
        }
        if !report.held.is_empty() {
            text.push_str(&format!(
                "held as they are: {}\n",
                report
                    .held
                    .iter()
                    .map(|h| format!(
                        "{} {}",
                        h.name,
                        agentstar_scene::format_param_value(h.value)
                    ))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        for f in &report.frames {
            let band = f
                .iou_band_after
                .map(|b| format!("  (band {b:.4})"))
                .unwrap_or_default();
            text.push_str(&format!(
                "  {}  {:.4} → {:.4}{band}\n",
                f.frame, f.iou_before, f.iou_after
            ));
        }
        let mut scores = BTreeMap::new();
        scores.insert("iou_mean_before".to_string(), report.iou_mean_before);
        scores.insert("iou_mean_after".to_string(), report.iou_mean_after);
        let images = report.sheets.clone();
        let structured = serde_json::to_value(&report).ok();
        let under_gate = report
            .frames
            .iter()
            .filter(|f| f.gate_after() < GATE_IOU)
            .count();
        if let Some(why) = fit_saves_nothing(&report) {
            text.push_str(why);
            if under_gate > 0 {
                text.push_str(&format!(
                    "{under_gate} keyframe(s) stay under the {GATE_IOU} gate (band IoU, as `score` reads it): a shape fit cannot repair a pose in a wrong basin (a flip or a twin). Check `temporal` for large steps and try the flips (`osweep`) or `track` with trusted anchors before fitting again.\n"
                ));
            }
            return Ok(ToolOutput {
                text,
                images,
                scores,
                structured,
                ..Default::default()
            });
        }
        let script = agentstar_data::read_text(&report.scene)?;
        let written = self.scene_write(&script, step)?;
        if written.is_error {
            return Ok(written);
        }
        let fitted = PoseFile::read(&report.poses)?;
        let pose_version = PoseHistory::new(&self.run.poses).replace(
            fitted,
            &format!(
                "fit_shape (step {step}): poses refined for scene version {}",
                written.scene_version.unwrap_or(0)
            ),
        )?;
        text.push_str(&format!(
            "scene version {} saved with the fitted values; pose.json version {pose_version} holds the refined poses. Look at a `turntable` before finishing.\n",
            written.scene_version.unwrap_or(0)
        ));
        Ok(ToolOutput {
            text,
            images,
            scores,
            scene_version: written.scene_version,
            pose_changed: true,
            pose_version: Some(pose_version),
            structured,
            ..Default::default()
        })
    }

    /// Checks a reason given for keyframe `i` (score `f`) being under the gate.
    fn check_reason(
        &self,
        i: usize,
        f: &agentstar_reports::FrameScore,
        why: &Unreachable,
    ) -> std::result::Result<(), String> {
        match why {
            Unreachable::Occlusion { percent } => {
                if !(percent.is_finite() && *percent > 0.0 && *percent <= 100.0) {
                    return Err(format!("`percent` is {percent}; a share in (0, 100]"));
                }
                // The hidden share of the rendered model: what the mask (hands excluded)
                // does not show of it.
                if f.render_px == 0 {
                    return Err("the model is not in view here, so nothing is hidden".into());
                }
                let hidden = 100.0 * (1.0 - f.mask_px as f64 / f.render_px as f64).max(0.0);
                let min = self.run.finish.min_occlusion_percent;
                if hidden < min {
                    return Err(format!(
                        "about {hidden:.0}% of the rendered model is hidden (1 − mask/render pixels), under the run's {min:.0}% threshold"
                    ));
                }
                Ok(())
            }
            Unreachable::MaskError { image, .. } => {
                let p = self.confine(image)?;
                let is_image = p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg")
                });
                if !p.is_file() || !is_image {
                    return Err(format!("`{image}` is not an image file (PNG or JPEG)"));
                }
                Ok(())
            }
            Unreachable::Truncated { .. } => {
                let cap = self.capture().map_err(|e| e.to_string())?;
                let m = cap.load_mask(i).map_err(|e| e.to_string())?;
                let (w, h) = (m.width(), m.height());
                let touches = (0..w).any(|x| m.get(x, 0) || m.get(x, h - 1))
                    || (0..h).any(|y| m.get(0, y) || m.get(w - 1, y));
                if touches {
                    Ok(())
                } else {
                    Err("its mask does not touch the frame border".into())
                }
            }
            Unreachable::OutOfReach { note } => {
                if note.trim().chars().count() < 20 {
                    Err(
                        "say in `note` (at least 20 characters) what the model cannot do here"
                            .into(),
                    )
                } else {
                    Ok(())
                }
            }
        }
    }

    /// `pose_history`: the versions, or one frame across them (scored by the CLI, which
    /// has the renderer).
    fn pose_history(&self, a: &PoseHistoryArgs) -> Result<ToolOutput> {
        let last = a.last.unwrap_or(50).to_string();
        let mut args = vec![
            "pose".to_string(),
            "history".into(),
            "--poses".into(),
            self.run.poses.display().to_string(),
            "--last".into(),
            last,
            "--json".into(),
        ];
        let Some(frame) = a.frame.as_deref().map(str::trim).filter(|f| !f.is_empty()) else {
            let (ok, stdout, stderr) = self.exec(&args)?;
            if !ok {
                return Ok(ToolOutput::error(stderr.trim().to_string()));
            }
            let r: HistoryReport = serde_json::from_str(&stdout).map_err(|e| {
                AgentError::Tool(format!("pose history printed no history report ({e})"))
            })?;
            let mut text = if r.versions.is_empty() {
                "no committed pose versions yet\n".to_string()
            } else if r.versions.len() < r.total {
                format!("the last {} of {} versions:\n", r.versions.len(), r.total)
            } else {
                String::new()
            };
            for row in &r.versions {
                text.push_str(&format!("{:>4}  {}\n", row.version, row.command));
            }
            return Ok(ToolOutput {
                text,
                structured: serde_json::to_value(&r).ok(),
                ..Default::default()
            });
        };
        args.extend([
            "--frame".into(),
            frame.to_string(),
            "--capture".into(),
            self.run.capture.display().to_string(),
            "--model".into(),
            self.run.scene.display().to_string(),
        ]);
        let (ok, stdout, stderr) = self.exec(&args)?;
        if !ok {
            return Ok(ToolOutput::error(stderr.trim().to_string()));
        }
        let r: FrameHistoryReport = serde_json::from_str(&stdout).map_err(|e| {
            AgentError::Tool(format!("pose history printed no frame history ({e})"))
        })?;
        let mut text = format!(
            "{} in {} version(s) (visible IoU with the current model):\n",
            r.frame,
            r.versions.len()
        );
        for v in &r.versions {
            let iou = v.iou_visible.map_or("-".to_string(), |x| format!("{x:.4}"));
            let what = match v.same_as {
                Some(s) => format!("same pose as version {s}"),
                None if v.pose.is_none() => "no pose".into(),
                None => "a new pose".into(),
            };
            text.push_str(&format!(
                "{:>4}  IoU {iou:>6}  {what:<24}  {}\n",
                v.version, v.command
            ));
            // The pose itself where it is new (play-test: the description promised it).
            if let (None, Some(p)) = (v.same_as, &v.pose) {
                let joints: Vec<String> = v
                    .joints
                    .iter()
                    .map(|(name, value)| format!("{name} {value:.2}"))
                    .collect();
                let [w, x, y, z] = p.quaternion;
                let [tx, ty, tz] = p.translation;
                text.push_str(&format!(
                    "      quaternion (w,x,y,z) [{w:.4}, {x:.4}, {y:.4}, {z:.4}]  translation [{tx:.4}, {ty:.4}, {tz:.4}]{}\n",
                    if joints.is_empty() {
                        String::new()
                    } else {
                        format!("  joints {}", joints.join(", "))
                    }
                ));
            }
        }
        for n in &r.notes {
            text.push_str(&format!("note: {n}\n"));
        }
        let mut o = ToolOutput {
            text,
            structured: serde_json::to_value(&r).ok(),
            ..Default::default()
        };
        if let Some(best) = r
            .versions
            .iter()
            .filter_map(|v| v.iou_visible)
            .reduce(f64::max)
        {
            o.scores.insert("best_iou".into(), best);
        }
        Ok(o)
    }

    /// `pose_restore`: a version, whole or for some frames (a sub-agent only its window's).
    fn pose_restore(&self, a: &PoseRestoreArgs) -> Result<ToolOutput> {
        let frames = a.frames.as_deref().map(str::trim).filter(|f| !f.is_empty());
        if self.window.is_some() && frames.is_none() {
            return Ok(ToolOutput::error(
                "a pose sub-agent cannot restore the whole pose file; name its frames",
            ));
        }
        if let Err(e) = self.check_window(frames) {
            return Ok(ToolOutput::error(e));
        }
        let history = PoseHistory::new(&self.run.poses);
        let wanted = frames.map(|f| self.frame_names(Some(f))).transpose()?;
        let (restored, v) = history.restore_frames(a.version, wanted.as_deref())?;
        let r = RestoreReport {
            from_version: a.version,
            frames: restored,
            version: v,
            poses: self.run.poses.clone(),
        };
        Ok(ToolOutput {
            text: match &wanted {
                Some(_) => format!(
                    "restored {} of version {} (recorded as version {v}); the other keyframes are unchanged",
                    r.frames.join(", "),
                    a.version
                ),
                None => format!(
                    "restored version {} of pose.json (recorded as version {v})",
                    a.version
                ),
            },
            pose_changed: true,
            pose_version: Some(v),
            structured: serde_json::to_value(&r).ok(),
            ..Default::default()
        })
    }

    /// `agentstar temporal --json` over every keyframe, as its report.
    pub fn temporal_report(&self) -> Result<agentstar_reports::TemporalReport> {
        let mut a: Vec<String> = vec!["temporal".into()];
        a.extend(self.session_args());
        a.push("--json".into());
        let (ok, stdout, stderr) = self.exec(&a)?;
        if !ok {
            return Err(AgentError::Tool(stderr.trim().to_string()));
        }
        serde_json::from_str(&stdout)
            .map_err(|e| AgentError::Tool(format!("temporal printed no report ({e})")))
    }

    /// What `finish` still needs about the large steps of the current poses: each one named
    /// in `checked` with a note, and one of its two frames looked at with a tool that shows
    /// or scores its twins (`entries`: the ledger) since either frame's pose last changed.
    /// A key that does not read as a step of two keyframes is reported; one naming a step
    /// that is not large (fixed since) is ignored.
    fn unchecked_steps(
        &self,
        checked: Option<&BTreeMap<String, String>>,
        entries: &[agentstar_data::ledger::LedgerEntry],
    ) -> Vec<String> {
        let report = match self.temporal_report() {
            Ok(r) => r,
            Err(e) => return vec![format!("the temporal report could not be made: {e}")],
        };
        let large: Vec<(String, String, f64)> = report
            .large_steps
            .iter()
            .map(|s| (s.from.clone(), s.to.clone(), s.rotation_deg))
            .collect();
        let mut missing = Vec::new();
        // The large steps named with a note, resolved to frame names.
        let mut named: Vec<(String, String)> = Vec::new();
        for (key, note) in checked.into_iter().flatten() {
            let Some((a, b)) = key.split_once("->") else {
                missing.push(format!(
                    "`steps_checked` key `{key}` is not a step: write it `A->B`, as `temporal` prints it"
                ));
                continue;
            };
            let one = |spec: &str| -> std::result::Result<String, String> {
                match self.frame_names(Some(spec.trim())) {
                    Ok(v) if v.len() == 1 => Ok(v[0].clone()),
                    Ok(v) => Err(format!(
                        "`{}` names {} keyframes, not one",
                        spec.trim(),
                        v.len()
                    )),
                    Err(e) => Err(e.to_string()),
                }
            };
            match (one(a), one(b)) {
                (Ok(a), Ok(b)) => {
                    // A step that is no longer large (fixed since) is no gate: nothing to
                    // check there.
                    if !large
                        .iter()
                        .any(|(f, t, _)| (f, t) == (&a, &b) || (f, t) == (&b, &a))
                    {
                        continue;
                    }
                    if note.trim().is_empty() {
                        missing.push(format!(
                            "`steps_checked` {a}->{b} has no note: say what you checked and found"
                        ));
                    } else {
                        named.push((a, b));
                    }
                }
                (Err(e), _) | (_, Err(e)) => {
                    missing.push(format!("`steps_checked` key `{key}`: {e}"));
                }
            }
        }
        // Whether a ledger entry's `frames` (all when absent) name `name`; `unknown` when its
        // arguments do not read.
        let names = |e: &agentstar_data::ledger::LedgerEntry, name: &str, unknown: bool| {
            match serde_json::from_value::<FramesOf>(e.args.clone()) {
                Ok(FramesOf { frames: None }) => true,
                Ok(FramesOf { frames: Some(spec) }) => self
                    .frame_names(Some(&spec))
                    .is_ok_and(|v| v.iter().any(|n| n == name)),
                Err(_) => unknown,
            }
        };
        let ok = |e: &agentstar_data::ledger::LedgerEntry| !e.scores.contains_key("error");
        // A step is checked by a call that scores or shows the twins of one of its frames,
        // or shows the frame, when no pose change of either frame came after it (a look at
        // poses since replaced is no check of these; play-test 8: a change elsewhere did
        // not need new looks here).
        let looks = [Oapply::NAME, Osweep::NAME, Render::NAME, Keyframes::NAME];
        let checked_since = |from: &str, to: &str| {
            entries.iter().any(|look| {
                looks.contains(&look.tool.as_str())
                    && ok(look)
                    && (names(look, from, false) || names(look, to, false))
                    && !entries.iter().any(|change| {
                        change.step > look.step
                            && change.pose_version.is_some()
                            && ok(change)
                            && (names(change, from, true) || names(change, to, true))
                    })
            })
        };
        for (from, to, deg) in &large {
            let done = named
                .iter()
                .any(|(a, b)| (a, b) == (from, to) || (a, b) == (to, from));
            if !done {
                missing.push(format!(
                    "step {from} -> {to} turns the object by {deg:.0}° (over {:.0}°): check it (`oapply` on {to} scores its flips and swaps, each refined; a twin within about 0.01 IoU means look by eye) and name it in `steps_checked`, e.g. {{\"steps_checked\": {{\"{from}->{to}\": \"oapply on {to}: no twin within 0.01\"}}}}",
                    report.large_step_deg
                ));
            } else if !checked_since(from, to) {
                missing.push(format!(
                    "step {from} -> {to} is named in `steps_checked`, but neither frame was looked at since their poses last changed: run `oapply` (or `osweep`, `render`, `frames`) on {to}"
                ));
            }
        }
        missing
    }

    /// The gates: IoU (or reasons), a turntable after the last shape change, a temporal
    /// report after the last pose change (both read from the ledger), and each large step
    /// of the poses checked ([`Toolbox::unchecked_steps`]).
    fn finish(&self, args: &FinishArgs) -> Result<ToolOutput> {
        let summary = args.summary.as_deref().unwrap_or("");
        if let Some(window) = &self.window {
            // A pose sub-agent ends its window; the orchestrator owns the gates.
            let score = self.call(
                Score::NAME,
                &serde_json::json!({"frames": window.join(",")}),
                0,
            );
            let mut o = ToolOutput {
                text: format!("window done. {}\n{summary}", first_line_of(&score.text)),
                finished: true,
                scores: score.scores,
                ..Default::default()
            };
            o.scores.insert("window".into(), 1.0);
            return Ok(o);
        }
        let policy = self.run.finish;
        let mut missing = vec![];
        let mut scores = BTreeMap::new();
        // The reasons, by frame name (a key may name several frames).
        let mut reasons: BTreeMap<String, &Unreachable> = BTreeMap::new();
        for (spec, why) in args.unreachable.iter().flatten() {
            match self.frame_names(Some(spec)) {
                Ok(names) => {
                    for n in names {
                        reasons.insert(n, why);
                    }
                }
                Err(e) => missing.push(format!("`unreachable` names `{spec}`: {e}")),
            }
        }
        let mut accepted: Vec<String> = vec![];
        match self.score_report(None) {
            Ok(report) => {
                let n = report.frames.len();
                let under: Vec<(usize, &agentstar_reports::FrameScore)> = report
                    .frames
                    .iter()
                    .enumerate()
                    .filter(|(_, f)| f.gate() < GATE_IOU)
                    .collect();
                let min = report.frames.iter().map(|f| f.gate()).fold(1.0, f64::min);
                scores.insert("iou_min".to_string(), min);
                scores.insert("under_gate".to_string(), under.len() as f64);
                let mut without = vec![];
                for (i, f) in &under {
                    match reasons.get(&f.frame) {
                        None => without.push(format!("{} ({:.4})", f.frame, f.gate())),
                        Some(why) => match self.check_reason(*i, f, why) {
                            Ok(()) => accepted.push(format!("{} ({})", f.frame, why.label())),
                            Err(e) => missing.push(format!(
                                "{} ({:.4}): the {} reason is not accepted: {e}",
                                f.frame,
                                f.gate(),
                                why.label()
                            )),
                        },
                    }
                }
                if !without.is_empty() {
                    missing.push(format!(
                        "keyframes under the {GATE_IOU} gate without a reason: {}",
                        without.join(", ")
                    ));
                }
                let share = under.len() as f64 / n.max(1) as f64;
                if share > policy.max_share_under_gate {
                    missing.push(format!(
                        "{} of {n} keyframes ({:.0}%) are under the gate; at most {:.0}% may finish with reasons (run.json `finish.max_share_under_gate`): fix the poses or the shape",
                        under.len(),
                        100.0 * share,
                        100.0 * policy.max_share_under_gate
                    ));
                }
            }
            Err(e) => missing.push(format!("the poses could not be scored: {e}")),
        }
        let (entries, _) = if self.run.ledger_path().is_file() {
            agentstar_data::ledger::read(&self.run.ledger_path())?
        } else {
            (vec![], vec![])
        };
        let last = |pred: &dyn Fn(&agentstar_data::ledger::LedgerEntry) -> bool| {
            entries.iter().filter(|e| pred(e)).map(|e| e.step).max()
        };
        let ok = |e: &agentstar_data::ledger::LedgerEntry| !e.scores.contains_key("error");
        let shape = last(&|e| e.kind == "shape" && ok(e)).unwrap_or(0);
        // The last step that wrote the poses (a search that was not committed changes
        // nothing; play-test 2026-12-02: `finish` asked for `temporal` again after uncommitted
        // `osweep`s); in a run without any, the last pose step, as before.
        let pose = last(&|e| e.pose_version.is_some() && ok(e))
            .or_else(|| last(&|e| e.kind == "pose" && ok(e)))
            .unwrap_or(0);
        let turntable = last(&|e| e.tool == "turntable" && ok(e));
        let temporal = last(&|e| e.tool == "temporal" && ok(e));
        if turntable.is_none_or(|t| t < shape) {
            missing.push("look at a `turntable` after the last shape change".into());
        }
        if temporal.is_none_or(|t| t < pose) {
            missing.push("review the `temporal` report after the last pose change".into());
        }
        missing.extend(self.unchecked_steps(args.steps_checked.as_ref(), &entries));
        let passed = missing.is_empty();
        let mut o = ToolOutput {
            text: if passed {
                format!(
                    "All gates hold. The run is finished.{}",
                    if accepted.is_empty() {
                        String::new()
                    } else {
                        format!(" Keyframes with accepted reasons: {}.", accepted.join(", "))
                    }
                )
            } else {
                format!("Not finished:\n- {}", missing.join("\n- "))
            },
            finished: passed,
            scores,
            ..Default::default()
        };
        o.scores
            .insert("passed".into(), if passed { 1.0 } else { 0.0 });
        Ok(o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tracks_text_leads_with_its_summary_then_its_log_then_the_frames() {
        let frame = |name: &str, visible: f64| agentstar_reports::FrameScore {
            frame: name.into(),
            iou_visible: Some(visible),
            iou_raw: visible,
            render_px: 100,
            mask_px: 100,
            hand_px: 0,
            depth_mae: None,
            depth_mae_canon: None,
            depth_bias: None,
            combined: visible,
            band_px: None,
            iou_band: None,
            band_share: None,
        };
        let frames = vec![frame("000000.png", 0.99), frame("000005.png", 0.95)];
        let report = TrackReport {
            poses: "run/pose.json".into(),
            seconds: 4.0,
            evaluations: 1000,
            init_frame: "000000.png".into(),
            log: vec!["000005.png: refined from its pose, IoU 0.9400 → 0.9500".into()],
            sequence: agentstar_reports::SequenceScore::of(&frames, GATE_IOU),
            frames,
            pose_version: Some(3),
        };
        let text = track_text(&report, None);
        assert!(text.starts_with("tracked 2 frame(s) in 4.0 s"), "{text}");
        assert!(
            text.contains("under the gate, worst first: 000005.png"),
            "{text}"
        );
        let log = text.find("refined from its pose").expect("the log");
        let table = text.find("frame        iou_band").expect("the table");
        assert!(log < table, "{text}");
        // No JSON: the report is the structured content.
        assert!(!text.contains('{'), "{text}");
        assert!(!text.contains("joints"), "a rigid model's table: {text}");
        // With the pose file: each frame's joint states end its line.
        let poses: agentstar_data::posefile::PoseFile = serde_json::from_value(json!({
            "scale": 0.2,
            "reference_frame": "000000.png",
            "frames": {
                "000000.png": {"joints": {"lid_hinge": 0.5}},
                "000005.png": {"joints": {"lid_hinge": 195.25}}
            }
        }))
        .expect("a pose file");
        let text = track_text(&report, Some(&poses));
        assert!(text.contains("iou_visible  joints\n"), "{text}");
        let line = text
            .lines()
            .find(|l| l.starts_with("000005.png"))
            .expect("the frame's line");
        assert!(line.ends_with("0.9500  lid_hinge 195.2"), "{line}");
    }
    use serde_json::json;

    #[test]
    fn a_tools_output_is_kept_up_to_its_cap_and_the_rest_is_counted() {
        let big = vec![b'x'; 1000];
        let t = read_capped_to(&big[..], 100);
        assert!(t.starts_with(&"x".repeat(100)), "{t}");
        assert!(t.contains("[900 more bytes of output dropped"), "{t}");
        assert_eq!(read_capped_to(&b"short"[..], 100), "short");
    }

    #[test]
    fn a_fit_is_saved_only_when_a_parameter_moved_and_the_iou_rose() {
        let report = |before: f64, after: f64, iou_before: f64, iou_after: f64| {
            agentstar_reports::fit::FitReport {
                params: vec![agentstar_reports::fit::FitParam {
                    name: "width".into(),
                    before,
                    after,
                    min: 0.8,
                    max: 1.2,
                    at_bound: false,
                }],
                held: vec![],
                frames: vec![],
                iou_mean_before: iou_before,
                iou_mean_after: iou_after,
                iou_min_before: iou_before,
                iou_min_after: iou_after,
                rounds: vec![],
                origin_shift: [0.0; 3],
                scene: "s.rhai".into(),
                poses: "p.json".into(),
                sheets: vec![],
                builds: 1,
                evaluations: 1,
                seconds: 0.0,
                written: false,
            }
        };
        // The play-test's case: the IoU rose (the poses were refined) but the width stayed.
        let why = fit_saves_nothing(&report(1.0, 1.0002, 0.93, 0.99)).expect("not saved");
        assert!(why.contains("No parameter moved"), "{why}");
        let why = fit_saves_nothing(&report(1.0, 1.05, 0.99, 0.99)).expect("not saved");
        assert!(why.contains("did not raise"), "{why}");
        assert_eq!(fit_saves_nothing(&report(1.0, 1.05, 0.93, 0.99)), None);
        // One parameter: it moved or not, nothing to single out.
        assert_eq!(unmoved_line(&report(1.0, 1.05, 0.93, 0.99)), None);
        assert_eq!(unmoved_line(&report(1.0, 1.0002, 0.93, 0.99)), None);
        // Of two, the one that stayed is named.
        let mut two = report(1.0, 1.05, 0.93, 0.99);
        let mut depth = two.params[0].clone();
        depth.name = "depth".into();
        depth.after = depth.before;
        two.params.push(depth);
        let line = unmoved_line(&two).expect("a line");
        assert!(line.starts_with("did not move: depth."), "{line}");
    }

    /// Every schema, at every depth: no `null` types (optional fields are left out) and no
    /// line breaks inside a paragraph of a description (review, 2026-12-02: `finish`'s
    /// reasons showed `["string","null"]` and descriptions kept the source's wrapping).
    #[test]
    fn schemas_have_no_null_types_and_no_wrapped_descriptions() {
        fn walk(tool: &str, path: &str, v: &Value, problems: &mut Vec<String>) {
            match v {
                Value::Object(o) => {
                    if let Some(t) = o.get("type") {
                        let has_null = t == "null"
                            || t.as_array().is_some_and(|a| a.iter().any(|x| x == "null"));
                        if has_null {
                            problems.push(format!("{tool}{path}: type {t}"));
                        }
                    }
                    if let Some(Value::String(d)) = o.get("description") {
                        if d.replace("\n\n", "").contains('\n') {
                            problems.push(format!("{tool}{path}: description {d:?}"));
                        }
                    }
                    for (k, c) in o {
                        if k != "enum" && k != "const" && k != "default" {
                            walk(tool, &format!("{path}/{k}"), c, problems);
                        }
                    }
                }
                Value::Array(a) => {
                    for (i, c) in a.iter().enumerate() {
                        walk(tool, &format!("{path}/{i}"), c, problems);
                    }
                }
                _ => {}
            }
        }
        let mut problems = vec![];
        for t in registry() {
            walk(t.name, "", &t.schema(), &mut problems);
        }
        assert!(problems.is_empty(), "{}", problems.join("\n"));
        assert_eq!(one_line_paragraphs("a\n b\n\nc\nd"), "a b\n\nc d");
    }

    #[test]
    fn a_child_commands_last_stderr_line_is_the_activity_of_the_call() {
        let activity = Activity::default();
        let mut t = toolbox(None);
        t.exe = "sh".into();
        let script = "printf 'track: 000000.png init\\n\\ntrack: 000005.png from 000000.png' >&2; echo ' tail' >&2; echo done";
        let (ok, stdout, stderr) =
            with_activity(&activity, || t.exec(&["-c".into(), script.into()])).expect("exec");
        assert!(ok, "{stderr}");
        assert_eq!(stdout.trim(), "done");
        // The last complete non-empty line, blank lines skipped.
        assert_eq!(
            activity.last_line(),
            "track: 000005.png from 000000.png tail"
        );
        assert!(stderr.contains("000000.png init"), "{stderr}");
        // Outside with_activity nothing reports, and the thread's activity is unset.
        let other = Activity::default();
        let (ok, _, _) = t
            .exec(&["-c".into(), "echo quiet >&2".into()])
            .expect("exec");
        assert!(ok);
        assert_eq!(
            activity.last_line(),
            "track: 000005.png from 000000.png tail"
        );
        assert_eq!(other.last_line(), "");
    }

    fn toolbox(window: Option<&[&str]>) -> Toolbox {
        let run = RunDir {
            dir: "run".into(),
            capture: "cap".into(),
            scene: "run/scene.rhai".into(),
            poses: "run/pose.json".into(),
            finish: Default::default(),
        };
        let t = Toolbox::new("agentstar".into(), run);
        match window {
            Some(w) => t.for_window(w.iter().map(|s| s.to_string()).collect()),
            None => t,
        }
    }

    #[test]
    fn a_sub_agent_may_change_only_its_window() {
        let w = ["000000.png".to_string(), "000005.png".to_string()];
        assert!(outside_window(&w, &["000000.png".into()]).is_empty());
        assert_eq!(
            outside_window(&w, &["000005.png".into(), "000010.png".into()]),
            ["000010.png"]
        );
        let t = toolbox(Some(&["000000.png", "000005.png"]));
        assert!(t.check_window(None).is_err());
        // Shape changes, whole-file restores and the tracker are refused outright.
        for (tool, args) in [
            (
                "scene_write",
                json!({"script": "part(\"a\", box(1, 1, 1));"}),
            ),
            ("pose_restore", json!({"version": 1})),
            ("track", json!({})),
        ] {
            let o = t.call(tool, &args, 1);
            assert!(o.is_error, "{tool}: {}", o.text);
        }
        assert!(toolbox(None).check_window(None).is_ok());
    }

    #[test]
    fn every_tool_has_a_generated_object_schema_and_unknown_tools_are_named() {
        let all = catalogue();
        let mut names: Vec<&str> = all.iter().map(|t| t.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), all.len(), "duplicate tool names");
        for t in &all {
            assert_eq!(t.schema["type"], "object", "{}", t.name);
            assert_eq!(t.schema["additionalProperties"], false, "{}", t.name);
            assert!(t.schema.get("$schema").is_none() && t.schema.get("$defs").is_none());
            assert!(
                t.description.len() > 40,
                "{} needs a description that teaches it",
                t.name
            );
        }
        let sweep = find("sweep").expect("sweep").schema();
        assert_eq!(sweep["required"], json!(["frames", "ranges"]));
        assert_eq!(sweep["properties"]["evals"]["minimum"], 50);
        assert_eq!(
            sweep["properties"]["strategy"]["enum"],
            json!(["de", "grid"])
        );
        let o = toolbox(None).call("fly", &json!({}), 1);
        assert!(o.is_error && o.text.contains("sweep"));
        // `finish` takes reasons from a fixed set, named in its schema.
        let finish = find("finish").expect("finish").schema();
        let reason = &finish["properties"]["unreachable"]["additionalProperties"];
        let categories: Vec<&str> = reason["oneOf"]
            .as_array()
            .expect("one schema per category")
            .iter()
            .map(|v| {
                let c = &v["properties"]["category"];
                c["const"]
                    .as_str()
                    .or_else(|| c["enum"][0].as_str())
                    .expect("a category")
            })
            .collect();
        assert_eq!(
            categories,
            ["occlusion", "mask_error", "truncated", "out_of_reach"],
            "{reason}"
        );
        // Pose versions start at 0 (as the CLI's), scene versions at 1.
        let restore = find("pose_restore").expect("tool").schema();
        assert_eq!(restore["properties"]["version"]["minimum"], 0);
        let track = find("track").expect("tool").schema();
        assert!(
            track["properties"]["from"].is_object() && track["properties"]["anchors"].is_object()
        );
    }

    #[test]
    fn the_render_description_names_the_colours_the_images_use() {
        let d = find("render").expect("render").description;
        for e in agentstar_render::views::COMPARE_LEGEND {
            assert!(d.contains(e.name), "{}: {d}", e.name);
        }
        // The search text tells an MCP client what to call, never pose numbers or a shell.
        let report = SearchReport {
            verb: SearchVerb::Oapply,
            capture: "cap".into(),
            model: "m.rhai".into(),
            poses: "p.json".into(),
            scale: 0.2,
            depth_weight: 0.0,
            frames: vec![agentstar_reports::SearchFrame {
                frame: "000000.png".into(),
                sheet: "run/images/x/oapply_sheet_000000.png".into(),
                notes: vec![],
                search: json!({}),
                ranked: vec![agentstar_reports::Candidate {
                    rank: 0,
                    label: "flip:y;rz:30".into(),
                    pose: agentstar_reports::CandidatePose {
                        quaternion: [0.5, 0.5, 0.5, 0.5],
                        translation: [0.1, 0.2, 0.9],
                        scale: 0.2,
                    },
                    joints: BTreeMap::new(),
                    iou_visible: Some(0.97),
                    iou_raw: 0.95,
                    iou_band: None,
                    gate: 0.97,
                    depth_canon: None,
                    combined: 0.97,
                    model_ncc: None,
                    outside_region: vec![],
                    extra: json!({}),
                }],
            }],
            mean_gate_iou: 0.97,
            min_gate_iou: Some(0.97),
            details: json!({}),
            command: "agentstar oapply".into(),
        };
        let t = search_text(&report, Path::new("run/images/x/oapply.json"));
        assert!(!t.contains("paste") && !t.contains("agentstar "), "{t}");
        assert!(!t.contains("0.5, 0.5") && !t.contains("quaternion"), "{t}");
        assert!(
            t.contains("`pose_commit`") && t.contains("run/images/x/oapply.json"),
            "{t}"
        );
        assert!(t.contains("flip:y;rz:30") && t.contains("0.9700"), "{t}");
        assert!(!t.contains("nothing the search evaluated"), "{t}");
        // A search that kept only its start says so, and what to try (play-test 2026-12-02:
        // three sweeps came back with the start alone and the agent could not tell why).
        let mut kept = report.clone();
        kept.frames[0].ranked[0].label = agentstar_reports::KEPT_START.into();
        let t = search_text(&kept, Path::new("run/images/x/sweep.json"));
        assert!(
            t.contains("nothing the search evaluated in this region scored above the start"),
            "{t}"
        );
        assert!(!t.contains("seen: a place"), "{t}");
        assert!(!t.contains("outside the region you named"), "{t}");
        // A start outside the region named is first only for want of better (play-test 6
        // took it for the region's best).
        kept.frames[0].ranked[0].outside_region = vec!["hinge 10 not in 100..120".into()];
        let t = search_text(&kept, Path::new("run/images/x/sweep.json"));
        assert!(
            t.contains("rank 0 is the start, which lies outside the region you named (hinge 10 not in 100..120): it is first only because nothing inside the region scored higher."),
            "{t}"
        );
        // Not also the note that calls such a start the best pose here.
        assert!(!t.contains("nothing the search evaluated"), "{t}");
        // With a row after it, that row is the region's best.
        let mut two = kept.clone();
        let mut second = two.frames[0].ranked[0].clone();
        second.rank = 1;
        second.outside_region.clear();
        second.label = "hinge:120".into();
        two.frames[0].ranked.push(second);
        let t = search_text(&two, Path::new("run/images/x/sweep.json"));
        assert!(t.contains("; the region's best is rank 1."), "{t}");
        // A runner-up row is explained where it appears (play-test 5: `seen` was a mystery).
        let mut seen = report.clone();
        seen.frames[0].ranked[0].label = "seen yaw:40".into();
        let t = search_text(&seen, Path::new("run/images/x/sweep.json"));
        assert!(t.contains("seen: a place the search passed through"), "{t}");
    }

    #[test]
    fn arguments_are_checked_against_the_schema_before_anything_runs() {
        let t = toolbox(None);
        for (tool, args, says) in [
            ("score", json!({"frames": 12345}), "invalid type"),
            ("score", json!({"frames": ["nope.png"]}), "invalid type"),
            ("score", json!({"frame": "000000"}), "unknown field"),
            ("score", json!("all"), "must be an object"),
            (
                "sweep",
                json!({"frames": "000000"}),
                "missing field `ranges`",
            ),
            (
                "sweep",
                json!({"frames": "0", "ranges": "yaw:-1,1", "evals": 10}),
                "under its minimum 50",
            ),
            (
                "sweep",
                json!({"frames": "0", "ranges": "yaw:-1,1", "strategy": "anneal"}),
                "unknown variant",
            ),
            ("track", json!({"scale": 0}), "must be over 0"),
            ("track", json!({"scale": -2.5}), "must be over 0"),
            (
                "scene_restore",
                json!({"version": 0}),
                "under its minimum 1",
            ),
            ("pose_restore", json!({"version": -1}), "invalid value"),
            (
                "finish",
                json!({"unreachable": {"000000": {"category": "glare"}}}),
                "unknown variant",
            ),
            (
                "finish",
                json!({"unreachable": {"000000": {"category": "out_of_reach"}}}),
                "missing field `note`",
            ),
            (
                "sweep",
                json!({"frames": "", "ranges": "yaw:-1,1"}),
                "at least 1",
            ),
            (
                "notes",
                json!({"text": "x".repeat(MAX_NOTE_CHARS + 1)}),
                "over its limit",
            ),
        ] {
            let o = t.call(tool, &args, 1);
            assert!(o.is_error, "{tool} {args}: {}", o.text);
            assert!(o.text.contains(says), "{tool} {args}: {}", o.text);
            assert!(o.text.starts_with(tool), "{}", o.text);
        }
        // The schema's limits are the constants the tools use.
        let scene = find("scene_write").expect("tool").schema();
        assert_eq!(
            scene["properties"]["script"]["maxLength"],
            json!(MAX_SCRIPT_CHARS)
        );
        let notes = find("notes").expect("tool").schema();
        assert_eq!(
            notes["properties"]["text"]["maxLength"],
            json!(MAX_NOTE_CHARS)
        );
    }

    #[test]
    fn paths_outside_the_run_and_the_capture_are_refused() {
        let dir = tempfile::tempdir().expect("tmp");
        let run_dir = dir.path().join("run");
        let cap = dir.path().join("cap");
        std::fs::create_dir_all(run_dir.join("images")).expect("mkdir");
        std::fs::create_dir_all(&cap).expect("mkdir");
        std::fs::write(run_dir.join("images/r.json"), "{}").expect("w");
        std::fs::write(dir.path().join("secret.json"), "{}").expect("w");
        let t = Toolbox::new(
            "agentstar".into(),
            RunDir {
                dir: run_dir.clone(),
                capture: cap,
                scene: run_dir.join("scene.rhai"),
                poses: run_dir.join("pose.json"),
                finish: Default::default(),
            },
        );
        assert!(t.confine("images/r.json").is_ok());
        assert!(t
            .confine(&run_dir.join("images/r.json").display().to_string())
            .is_ok());
        for bad in ["/etc/passwd", "../secret.json", "images/../../secret.json"] {
            let e = t.confine(bad).expect_err(bad);
            assert!(e.contains("outside the run directory"), "{bad}: {e}");
        }
        let o = t.call("pose_commit", &json!({"report": "/etc/passwd"}), 1);
        assert!(o.is_error && o.text.contains("outside"), "{}", o.text);
    }

    #[test]
    fn a_bad_call_is_answered_with_what_the_tool_takes() {
        let fit = arguments_help("fit_shape", &schema_of::<FitShapeArgs>());
        assert!(fit.starts_with("fit_shape takes:"), "{fit}");
        assert!(
            fit.contains("- `params` (required, list of string): The parameters to fit"),
            "{fit}"
        );
        assert!(fit.contains("- `rounds` (integer 1–10)"), "{fit}");
        // A nested argument shows its shape: each category with its own fields.
        let finish = arguments_help("finish", &schema_of::<FinishArgs>());
        assert!(
            finish.contains("- `unreachable` (map of key → {category: \"occlusion\", percent: number} | {category: \"mask_error\", image: string, note?: string}"),
            "{finish}"
        );
        assert!(
            finish.contains("{category: \"out_of_reach\", note: string}"),
            "{finish}"
        );
        assert_eq!(
            arguments_help("task", &schema_of::<NoArgs>()),
            "task takes no arguments: call it with {}"
        );
    }
}
