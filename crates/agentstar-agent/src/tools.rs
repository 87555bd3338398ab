//! The tool catalogue shared by the MCP server and the built-in loop: names, descriptions
//! that teach each tool, JSON schemas, and their execution.
//!
//! Every tool that renders or searches runs the `agentstar` executable as a child process
//! with `--json` (so a broken scene script or a crash in one tool never takes the harness
//! down, and the scene sandbox is the one every command uses); the tool's files land in
//! `RUN/images/step_NNNN_tool/`, and PNGs there come back as images.

use crate::run::RunDir;
use crate::task::{task_document, GATE_IOU};
use crate::{AgentError, Result};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

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

/// One tool as offered to a model.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    pub name: &'static str,
    pub kind: Kind,
    pub description: &'static str,
    /// JSON Schema of the arguments (an object).
    pub schema: Value,
}

fn obj(props: Value, required: &[&str]) -> Value {
    json!({"type": "object", "properties": props, "required": required, "additionalProperties": false})
}

const FRAMES: &str = "Keyframes: `all`, names (`000010.png`), stems (`000010`), indices, or ranges `a..b` of stems, comma separated.";

/// Every tool, in the order offered.
pub fn catalogue() -> Vec<ToolSpec> {
    vec![
        ToolSpec {
            name: "task",
            kind: Kind::Note,
            description: "Return TASK.md: the goal, the conventions, how to work, how to read the images, the gates before finishing, and the whole scene API with a worked example. Read it first.",
            schema: obj(json!({}), &[]),
        },
        ToolSpec {
            name: "scene_read",
            kind: Kind::Diagnostic,
            description: "Return the current scene.rhai and its check: parts, joints, the canonical frame (bounding box, centre) and warnings.",
            schema: obj(json!({}), &[]),
        },
        ToolSpec {
            name: "scene_write",
            kind: Kind::Shape,
            description: "Replace scene.rhai with a whole new script (a shape step). The script is built in the sandbox first: on an error you get the message with its line and nothing changes. On success a new scene version is saved and pose.json gains new joints at rest (removed joints are dropped). Check the shape with `turntable` afterwards.",
            schema: obj(json!({"script": {"type": "string", "description": "The whole scene script (Rhai)."}}), &["script"]),
        },
        ToolSpec {
            name: "scene_restore",
            kind: Kind::Shape,
            description: "Make an earlier scene version current again (versions are listed by scene_read).",
            schema: obj(json!({"version": {"type": "integer", "minimum": 1}}), &["version"]),
        },
        ToolSpec {
            name: "render",
            kind: Kind::Diagnostic,
            description: "Render the posed model into keyframes: `overlay` (shaded model over the frame) and `compare` (green agree, red mask not covered, blue model outside the mask, grey hand). Also returns a contact sheet of the overlays.",
            schema: obj(json!({
                "frames": {"type": "string", "description": FRAMES},
                "views": {"type": "string", "description": "Comma separated: overlay, compare, ids, shaded. Default overlay,compare."}
            }), &[]),
        },
        ToolSpec {
            name: "score",
            kind: Kind::Diagnostic,
            description: "Per keyframe: visible IoU (hands excluded; the gate is 0.98), raw IoU, pixel counts, depth error when the capture has depth. Lists the keyframes under the gate.",
            schema: obj(json!({"frames": {"type": "string", "description": FRAMES}}), &[]),
        },
        ToolSpec {
            name: "turntable",
            kind: Kind::Diagnostic,
            description: "Eight views around the model, once per distinct joint state in pose.json: the 3-D shape check after every shape step (parts floating, intersecting or missing from the back).",
            schema: obj(json!({}), &[]),
        },
        ToolSpec {
            name: "track",
            kind: Kind::Pose,
            description: "Run the automatic tracker over every keyframe with the current model and scale (a pose step for all keyframes; the previous pose.json is kept as a version). Use it once the shape is right, then fix the frames it gets wrong with sweeps and flips.",
            schema: obj(json!({"scale": {"type": "number", "exclusiveMinimum": 0, "description": "Metres per model unit (default: the scale in pose.json)."}}), &[]),
        },
        ToolSpec {
            name: "sweep",
            kind: Kind::Pose,
            description: "Search a bounded region around the current pose of each given keyframe by silhouette IoU (differential evolution, 6 seeded restarts) and return the ranked candidates with a candidate sheet. Ranges are camera-frame increments and absolute joint states, e.g. `yaw:-30,30;pitch:-20,20;tz:-0.1,0.1;lid_hinge:0,90`. Commit a candidate with pose_commit (the result names its report).",
            schema: obj(json!({
                "frames": {"type": "string", "description": FRAMES},
                "ranges": {"type": "string", "description": "DOF:min,max terms separated by `;` (roll, yaw, pitch in degrees; dpx, dpy, tz fractions; joints by name)."},
                "strategy": {"type": "string", "enum": ["de", "grid"]},
                "evals": {"type": "integer", "minimum": 50, "maximum": 50000, "description": "Evaluations over all restarts (default 3600)."}
            }), &["frames", "ranges"]),
        },
        ToolSpec {
            name: "apply",
            kind: Kind::Pose,
            description: "Score one explicit order on one keyframe, e.g. `yaw:15;hinge:40`, and return it as a candidate (to compare with a sweep's).",
            schema: obj(json!({
                "frame": {"type": "string"},
                "order": {"type": "string"}
            }), &["frame", "order"]),
        },
        ToolSpec {
            name: "osweep",
            kind: Kind::Pose,
            description: "Search object-frame rotations per keyframe: a preset (`z:flip`, `z:quarters`, `z:octants`, `so3:24`) or grid ranges (`rz:-180,180,9;rx:-15,15,3`). For objects that look alike from several sides.",
            schema: obj(json!({
                "frames": {"type": "string", "description": FRAMES},
                "opreset": {"type": "string"},
                "ranges": {"type": "string"}
            }), &[]),
        },
        ToolSpec {
            name: "oapply",
            kind: Kind::Pose,
            description: "Score a set of object-frame rotations on each keyframe, default `flips` (identity and the 180° flips about x, y, z). The flip check for near-symmetric objects: a flipped pose can score as well as the right one, so look at the sheet.",
            schema: obj(json!({
                "frames": {"type": "string", "description": FRAMES},
                "set": {"type": "string", "description": "`flips`, or candidates separated by `|`, terms by `;`: `identity|flip:x|rz:90;rx:10`."}
            }), &[]),
        },
        ToolSpec {
            name: "oapply_all",
            kind: Kind::Pose,
            description: "Apply one object-frame rotation to every keyframe (`rz:90` or `flip:x`): for a model built the wrong way round.",
            schema: obj(json!({
                "rotation": {"type": "string"},
                "frames": {"type": "string", "description": FRAMES}
            }), &["rotation"]),
        },
        ToolSpec {
            name: "pose_commit",
            kind: Kind::Pose,
            description: "Commit a candidate of a search report to pose.json (atomically; the previous pose.json becomes a version). `report` is the path a search returned.",
            schema: obj(json!({
                "report": {"type": "string"},
                "rank": {"type": "integer", "minimum": 0},
                "frames": {"type": "string", "description": "Only these frames of the report (comma separated names)."}
            }), &["report"]),
        },
        ToolSpec {
            name: "pose_history",
            kind: Kind::Diagnostic,
            description: "List the committed pose versions with the command that made each.",
            schema: obj(json!({}), &[]),
        },
        ToolSpec {
            name: "pose_restore",
            kind: Kind::Pose,
            description: "Make an earlier pose version current again.",
            schema: obj(json!({"version": {"type": "integer", "minimum": 1}}), &["version"]),
        },
        ToolSpec {
            name: "temporal",
            kind: Kind::Diagnostic,
            description: "The temporal report: rotation, translation and radial velocity and acceleration from keyframe to keyframe (camera motion removed), joint velocities, and a plot. Large steps are either real or wrong poses (often flips): confirm them in the frames or fix them.",
            schema: obj(json!({"sort_by": {"type": "string", "description": "e.g. vel.rot, accel.rot, vel.trans, <joint>.vel"}}), &[]),
        },
        ToolSpec {
            name: "pose_diff",
            kind: Kind::Diagnostic,
            description: "The residual between two keyframes' poses (rotation in degrees, translation, joint changes).",
            schema: obj(json!({"a": {"type": "string"}, "b": {"type": "string"}}), &["a", "b"]),
        },
        ToolSpec {
            name: "critic",
            kind: Kind::Diagnostic,
            description: "Ask a separate model to criticise one keyframe: it sees the frame, the overlay and the turntable and returns realism and identity scores and discrepancies tagged shape, pose, joint state or joint definition, with a severity and a direction of change. Skipped with a note when no critic model is configured.",
            schema: obj(json!({"frame": {"type": "string"}}), &["frame"]),
        },
        ToolSpec {
            name: "notes",
            kind: Kind::Note,
            description: "Append to NOTES.md, your memory across contexts (what the object is, which parts move, what you ruled out).",
            schema: obj(json!({"text": {"type": "string"}}), &["text"]),
        },
        ToolSpec {
            name: "finish",
            kind: Kind::Diagnostic,
            description: "Check the gates and end the run when they hold: every keyframe's visible IoU ≥ 0.98 or a reason for it in `unreachable`; a turntable after the last shape change; a temporal report after the last pose change. Returns what is missing otherwise.",
            schema: obj(json!({
                "unreachable": {"type": "object", "additionalProperties": {"type": "string"}, "description": "Keyframe name → why it cannot reach the gate."},
                "summary": {"type": "string"}
            }), &[]),
        },
    ]
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
    /// Set when the tool changed the scene (the new version) or committed poses.
    pub scene_version: Option<u64>,
    pub pose_changed: bool,
    /// `finish` passed.
    pub finished: bool,
}

impl ToolOutput {
    fn error(text: impl Into<String>) -> Self {
        ToolOutput {
            text: text.into(),
            is_error: true,
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
}

fn arg_str<'a>(args: &'a Value, key: &str) -> Option<&'a str> {
    args.get(key)
        .and_then(Value::as_str)
        .filter(|s| !s.trim().is_empty())
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

impl Toolbox {
    pub fn new(exe: PathBuf, run: RunDir) -> Self {
        Toolbox {
            exe,
            run,
            critic: None,
            window: None,
            timeout_s: 900,
        }
    }

    fn session_args(&self) -> Vec<String> {
        vec![
            "--capture".into(),
            self.run.capture.display().to_string(),
            "--model".into(),
            self.run.scene.display().to_string(),
            "--poses".into(),
            self.run.poses.display().to_string(),
        ]
    }

    /// Each keyframe's visible IoU (0 where no mask pixel is visible), in capture order, and
    /// `agentstar score`'s JSON.
    pub fn ious(&self, frames: Option<&str>) -> Result<(Vec<(String, f64)>, String)> {
        let mut a: Vec<String> = ["score".to_string()]
            .into_iter()
            .chain(self.session_args())
            .collect();
        if let Some(f) = frames {
            a.extend(["--frames".into(), f.into()]);
        }
        a.push("--json".into());
        let (_, stdout, stderr) = self.exec(&a)?;
        // `score` exits 1 when a frame is under the gate; its JSON is the result.
        let v: Value = serde_json::from_str(&stdout)
            .map_err(|_| AgentError::Tool(stderr.trim().to_string()))?;
        let rows = v["frames"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|r| {
                (
                    r["frame"].as_str().unwrap_or("").to_string(),
                    r["iou_visible"].as_f64().unwrap_or(0.0),
                )
            })
            .collect();
        Ok((rows, stdout))
    }

    /// Runs the executable; returns (success, stdout, stderr).
    fn exec(&self, args: &[String]) -> Result<(bool, String, String)> {
        let mut child = Command::new(&self.exe)
            .args(args)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .map_err(|e| AgentError::Tool(format!("cannot run {}: {e}", self.exe.display())))?;
        // Read both pipes on threads so a large output never blocks the child.
        let mut out = child.stdout.take();
        let mut err = child.stderr.take();
        let t_out = std::thread::spawn(move || {
            let mut s = String::new();
            if let Some(o) = out.as_mut() {
                let _ = std::io::Read::read_to_string(o, &mut s);
            }
            s
        });
        let t_err = std::thread::spawn(move || {
            let mut s = String::new();
            if let Some(e) = err.as_mut() {
                let _ = std::io::Read::read_to_string(e, &mut s);
            }
            s
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

    /// Frames outside this toolbox's window are refused for pose changes.
    fn check_window(&self, frames: Option<&str>) -> std::result::Result<(), String> {
        let Some(window) = &self.window else {
            return Ok(());
        };
        let Some(frames) = frames else {
            return Err(format!(
                "name the frames: this agent may change only {}",
                window.join(", ")
            ));
        };
        for f in frames.split(',').map(str::trim).filter(|f| !f.is_empty()) {
            let ok = window
                .iter()
                .any(|w| w == f || w.split('.').next() == Some(f));
            if !ok {
                return Err(format!(
                    "frame `{f}` is outside this agent's window ({})",
                    window.join(", ")
                ));
            }
        }
        Ok(())
    }

    /// Calls tool `name` with `args` as step `step`.
    pub fn call(&self, name: &str, args: &Value, step: u64) -> ToolOutput {
        match self.call_inner(name, args, step) {
            Ok(o) => o,
            Err(e) => ToolOutput::error(e.to_string()),
        }
    }

    fn cli(
        &self,
        verb: &[&str],
        step: u64,
        tool: &str,
        extra: Vec<String>,
    ) -> Result<(ToolOutput, PathBuf)> {
        let out = self.run.step_dir(step, tool);
        let mut a: Vec<String> = verb.iter().map(|s| s.to_string()).collect();
        a.extend(self.session_args());
        a.push("--out".into());
        a.push(out.display().to_string());
        a.extend(extra);
        a.push("--json".into());
        let (ok, stdout, stderr) = self.exec(&a)?;
        if !ok {
            return Ok((ToolOutput::error(stderr.trim().to_string()), out));
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
        ))
    }

    fn call_inner(&self, name: &str, args: &Value, step: u64) -> Result<ToolOutput> {
        let opt = |k: &str, flag: &str| -> Vec<String> {
            arg_str(args, k)
                .map(|v| vec![flag.to_string(), v.to_string()])
                .unwrap_or_default()
        };
        match name {
            "task" => Ok(ToolOutput {
                text: task_document(),
                ..Default::default()
            }),
            "scene_read" => self.scene_read(),
            "scene_write" => {
                let script = arg_str(args, "script")
                    .ok_or_else(|| AgentError::Tool("scene_write needs `script`".into()))?;
                self.scene_write(script)
            }
            "scene_restore" => {
                let v = args.get("version").and_then(Value::as_u64).ok_or_else(|| {
                    AgentError::Tool("scene_restore needs an integer `version`".into())
                })?;
                let p = self.run.scene_versions().join(format!("{v:04}.rhai"));
                let script = agentstar_data::read_text(&p)
                    .map_err(|_| AgentError::Tool(format!("there is no scene version {v}")))?;
                self.scene_write(&script)
            }
            "render" => {
                let views = arg_str(args, "views").unwrap_or("overlay,compare");
                let (mut o, _) = self.cli(
                    &["render"],
                    step,
                    name,
                    [
                        opt("frames", "--frames"),
                        vec!["--views".into(), views.into()],
                    ]
                    .concat(),
                )?;
                o.images.truncate(8);
                Ok(o)
            }
            "score" => {
                let (ious, stdout) = self.ious(arg_str(args, "frames"))?;
                let mut o = ToolOutput::default();
                let mut head = format!("score: {} keyframe(s)", ious.len());
                if !ious.is_empty() {
                    let min = ious.iter().map(|r| r.1).fold(1.0, f64::min);
                    let mean = ious.iter().map(|r| r.1).sum::<f64>() / ious.len() as f64;
                    let below: Vec<&str> = ious
                        .iter()
                        .filter(|r| r.1 < GATE_IOU)
                        .map(|r| r.0.as_str())
                        .collect();
                    o.scores.insert("iou_min".into(), min);
                    o.scores.insert("iou_mean".into(), mean);
                    head.push_str(&format!(
                        ", visible IoU mean {mean:.4}, min {min:.4}; under the gate: {}",
                        if below.is_empty() {
                            "none".to_string()
                        } else {
                            below.join(", ")
                        }
                    ));
                }
                o.text = format!("{head}\n{stdout}");
                Ok(o)
            }
            "turntable" => {
                let out = self.run.step_dir(step, name);
                let a = vec![
                    "turntable".to_string(),
                    "--model".into(),
                    self.run.scene.display().to_string(),
                    "--capture".into(),
                    self.run.capture.display().to_string(),
                    "--poses".into(),
                    self.run.poses.display().to_string(),
                    "--out".into(),
                    out.display().to_string(),
                    "--json".into(),
                ];
                let (ok, stdout, stderr) = self.exec(&a)?;
                if !ok {
                    return Ok(ToolOutput::error(stderr.trim().to_string()));
                }
                let mut images = pngs(&out);
                images.truncate(6);
                Ok(ToolOutput {
                    text: format!("turntable: {} view sheet(s)\n{stdout}", images.len()),
                    images,
                    ..Default::default()
                })
            }
            "track" => {
                if self.window.is_some() {
                    return Ok(ToolOutput::error(
                        "track changes every keyframe; a pose sub-agent works on its window with sweeps and flips",
                    ));
                }
                let out = self.run.step_dir(step, name);
                std::fs::create_dir_all(&out)
                    .map_err(|e| agentstar_data::DataError::io(&out, e))?;
                let before = out.join("pose_before.json");
                std::fs::copy(&self.run.poses, &before)
                    .map_err(|e| agentstar_data::DataError::io(&before, e))?;
                let tracked = out.join("pose.json");
                let mut a = vec![
                    "track".to_string(),
                    self.run.capture.display().to_string(),
                    "--model".into(),
                    self.run.scene.display().to_string(),
                    "--out".into(),
                    tracked.display().to_string(),
                    "--json".into(),
                ];
                match args.get("scale").and_then(Value::as_f64) {
                    Some(s) => a.extend(["--scale".into(), s.to_string()]),
                    None => a.extend(["--scale-from".into(), self.run.poses.display().to_string()]),
                }
                let (ok, stdout, stderr) = self.exec(&a)?;
                if !ok {
                    return Ok(ToolOutput::error(stderr.trim().to_string()));
                }
                let bytes = std::fs::read(&tracked)
                    .map_err(|e| agentstar_data::DataError::io(&tracked, e))?;
                agentstar_data::atomic::write_atomic(&self.run.poses, &bytes)?;
                Ok(ToolOutput {
                    text: format!(
                        "{}\nThe previous poses are kept in {}.",
                        stdout.trim(),
                        before.display()
                    ),
                    pose_changed: true,
                    ..Default::default()
                })
            }
            "sweep" | "osweep" | "oapply" | "oapply_all" | "apply" => {
                let frames = if name == "apply" {
                    arg_str(args, "frame")
                } else {
                    arg_str(args, "frames")
                };
                if let Err(e) = self.check_window(frames) {
                    return Ok(ToolOutput::error(e));
                }
                let verb = name.replace('_', "-");
                let extra: Vec<String> = match name {
                    "sweep" => [
                        opt("frames", "--frames"),
                        opt("ranges", "--ranges"),
                        opt("strategy", "--strategy"),
                        args.get("evals")
                            .and_then(Value::as_u64)
                            .map(|e| vec!["--evals".into(), e.to_string()])
                            .unwrap_or_default(),
                    ]
                    .concat(),
                    "apply" => [opt("frame", "--frame"), opt("order", "--order")].concat(),
                    "osweep" => [
                        opt("frames", "--frames"),
                        opt("opreset", "--opreset"),
                        opt("ranges", "--ranges"),
                    ]
                    .concat(),
                    "oapply" => [opt("frames", "--frames"), opt("set", "--set")].concat(),
                    _ => [opt("rotation", "--rotation"), opt("frames", "--frames")].concat(),
                };
                let (o, out) = self.cli(&[verb.as_str()], step, name, extra)?;
                if o.is_error {
                    return Ok(o);
                }
                let report = out.join(format!("{verb}.json"));
                let txt =
                    agentstar_data::read_text(&out.join(format!("{verb}.txt"))).unwrap_or_default();
                let mut images = o.images;
                images.truncate(6);
                Ok(ToolOutput {
                    text: format!("{}\nreport: {}\n", txt.trim(), report.display()),
                    images,
                    ..Default::default()
                })
            }
            "pose_commit" => {
                let report = arg_str(args, "report")
                    .ok_or_else(|| AgentError::Tool("pose_commit needs `report`".into()))?;
                if self.window.is_some() {
                    if let Err(e) = self.check_window(arg_str(args, "frames")) {
                        return Ok(ToolOutput::error(e));
                    }
                }
                let report = {
                    let p = PathBuf::from(report);
                    if p.is_relative() {
                        self.run.dir.join(p)
                    } else {
                        p
                    }
                };
                let mut a = vec![
                    "pose".to_string(),
                    "commit".into(),
                    "--poses".into(),
                    self.run.poses.display().to_string(),
                    "--report".into(),
                    report.display().to_string(),
                    "--rank".into(),
                    args.get("rank")
                        .and_then(Value::as_u64)
                        .unwrap_or(0)
                        .to_string(),
                    "--json".into(),
                ];
                a.extend(opt("frames", "--frames"));
                let (ok, stdout, stderr) = self.exec(&a)?;
                if !ok {
                    return Ok(ToolOutput::error(stderr.trim().to_string()));
                }
                Ok(ToolOutput {
                    text: format!("committed to pose.json\n{stdout}"),
                    pose_changed: true,
                    ..Default::default()
                })
            }
            "pose_history" | "pose_restore" => {
                let mut a = vec![
                    "pose".to_string(),
                    if name == "pose_history" {
                        "history"
                    } else {
                        "restore"
                    }
                    .into(),
                    "--poses".into(),
                    self.run.poses.display().to_string(),
                ];
                if name == "pose_restore" {
                    if self.window.is_some() {
                        return Ok(ToolOutput::error(
                            "a pose sub-agent cannot restore the whole pose file",
                        ));
                    }
                    let v = args.get("version").and_then(Value::as_u64).ok_or_else(|| {
                        AgentError::Tool("pose_restore needs an integer `version`".into())
                    })?;
                    a.extend(["--version".into(), v.to_string()]);
                } else {
                    a.push("--json".into());
                }
                let (ok, stdout, stderr) = self.exec(&a)?;
                if !ok {
                    return Ok(ToolOutput::error(stderr.trim().to_string()));
                }
                Ok(ToolOutput {
                    text: stdout,
                    pose_changed: name == "pose_restore",
                    ..Default::default()
                })
            }
            "temporal" => {
                let out = self.run.step_dir(step, name);
                std::fs::create_dir_all(&out)
                    .map_err(|e| agentstar_data::DataError::io(&out, e))?;
                let plot = out.join("temporal.png");
                let mut a: Vec<String> = ["temporal".to_string()]
                    .into_iter()
                    .chain(self.session_args())
                    .collect();
                a.extend(["--plot".into(), plot.display().to_string()]);
                a.extend(opt("sort_by", "--sort-by"));
                let (ok, stdout, stderr) = self.exec(&a)?;
                if !ok {
                    return Ok(ToolOutput::error(stderr.trim().to_string()));
                }
                Ok(ToolOutput {
                    text: stdout,
                    images: pngs(&out),
                    ..Default::default()
                })
            }
            "pose_diff" => {
                let mut a: Vec<String> = ["pose-diff".to_string()]
                    .into_iter()
                    .chain(self.session_args())
                    .collect();
                a.extend(opt("a", "--a"));
                a.extend(opt("b", "--b"));
                let (ok, stdout, stderr) = self.exec(&a)?;
                Ok(if ok {
                    ToolOutput {
                        text: stdout,
                        ..Default::default()
                    }
                } else {
                    ToolOutput::error(stderr.trim().to_string())
                })
            }
            "critic" => {
                let frame = arg_str(args, "frame")
                    .ok_or_else(|| AgentError::Tool("critic needs `frame`".into()))?;
                let Some(critic) = &self.critic else {
                    return Ok(ToolOutput {
                        text: "critic skipped: no critic model is configured (agentstar run --critic PROVIDER:MODEL, or AGENTSTAR_CRITIC for the MCP server)".into(),
                        ..Default::default()
                    });
                };
                let (r, _) = self.cli(
                    &["render"],
                    step,
                    name,
                    vec![
                        "--frames".into(),
                        frame.into(),
                        "--views".into(),
                        "overlay,compare".into(),
                    ],
                )?;
                if r.is_error {
                    return Ok(r);
                }
                let tt = self.call_inner("turntable", &json!({}), step)?;
                let mut images: Vec<PathBuf> = r
                    .images
                    .into_iter()
                    .filter(|p| !p.to_string_lossy().contains("sheet"))
                    .collect();
                images.extend(tt.images.into_iter().take(1));
                let frame_img = self.run.capture.join("frames").join(frame);
                if frame_img.is_file() {
                    images.insert(0, frame_img);
                }
                match critic(frame, &images) {
                    Ok(text) => Ok(ToolOutput {
                        text,
                        images,
                        ..Default::default()
                    }),
                    Err(e) => Ok(ToolOutput::error(format!("the critic failed: {e}"))),
                }
            }
            "notes" => {
                let text = arg_str(args, "text")
                    .ok_or_else(|| AgentError::Tool("notes needs `text`".into()))?;
                let p = self.run.notes_path();
                let mut all = agentstar_data::read_text(&p).unwrap_or_default();
                all.push_str(&format!("\n- (step {step}) {}\n", text.trim()));
                agentstar_data::atomic::write_atomic(&p, all.as_bytes())?;
                Ok(ToolOutput {
                    text: "noted".into(),
                    ..Default::default()
                })
            }
            "finish" => self.finish(args),
            other => Ok(ToolOutput::error(format!(
                "there is no tool `{other}`; the tools are {}",
                catalogue()
                    .iter()
                    .map(|t| t.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))),
        }
    }

    fn scene_read(&self) -> Result<ToolOutput> {
        let script = agentstar_data::read_text(&self.run.scene)?;
        let (_, check, stderr) = self.exec(&[
            "check".into(),
            self.run.scene.display().to_string(),
            "--json".into(),
        ])?;
        Ok(ToolOutput {
            text: format!(
                "scene.rhai (versions saved: {:?}):\n```rhai\n{}\n```\ncheck:\n{}{}",
                self.run.list_scene_versions(),
                script.trim_end(),
                check.trim(),
                stderr.trim()
            ),
            ..Default::default()
        })
    }

    fn scene_write(&self, script: &str) -> Result<ToolOutput> {
        if self.window.is_some() {
            return Ok(ToolOutput::error(
                "a pose sub-agent cannot change the shape",
            ));
        }
        // The candidate sits beside the scene so that it reaches the same mesh files.
        let candidate = self.run.dir.join(".scene_candidate.rhai");
        agentstar_data::atomic::write_atomic(&candidate, script.as_bytes())?;
        let (ok, check, stderr) = self.exec(&[
            "check".into(),
            candidate.display().to_string(),
            "--json".into(),
        ])?;
        if !ok {
            let _ = std::fs::remove_file(&candidate);
            return Ok(ToolOutput::error(format!(
                "the scene was not changed: {}",
                stderr
                    .trim()
                    .replace(&candidate.display().to_string(), "scene.rhai")
            )));
        }
        std::fs::rename(&candidate, &self.run.scene)
            .map_err(|e| agentstar_data::DataError::io(&self.run.scene, e))?;
        let version = self.run.list_scene_versions().last().copied().unwrap_or(0) + 1;
        self.run.save_scene_version(version)?;
        let joints = crate::poses::reconcile(&self.run.scene, &self.run.poses)?;
        Ok(ToolOutput {
            text: format!(
                "scene version {version} saved.{}\ncheck:\n{}",
                if joints.is_empty() {
                    String::new()
                } else {
                    format!(" pose.json: {}.", joints.join("; "))
                },
                check.trim()
            ),
            scene_version: Some(version),
            ..Default::default()
        })
    }

    /// The gates: IoU (or reasons), a turntable after the last shape change, a temporal
    /// report after the last pose change (both read from the ledger).
    fn finish(&self, args: &Value) -> Result<ToolOutput> {
        if let Some(window) = &self.window {
            // A pose sub-agent ends its window; the orchestrator owns the gates.
            let score = self.call_inner("score", &json!({"frames": window.join(",")}), 0)?;
            let mut o = ToolOutput {
                text: format!(
                    "window done. {}\n{}",
                    first_line_of(&score.text),
                    arg_str(args, "summary").unwrap_or("")
                ),
                finished: true,
                scores: score.scores,
                ..Default::default()
            };
            o.scores.insert("window".into(), 1.0);
            return Ok(o);
        }
        let unreachable: BTreeMap<String, String> = args
            .get("unreachable")
            .and_then(Value::as_object)
            .map(|m| {
                m.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.as_str()?.to_string())))
                    .collect()
            })
            .unwrap_or_default();
        let mut missing = vec![];
        let mut scores = BTreeMap::new();
        let below: Vec<String> = match self.ious(None) {
            Ok((ious, _)) => ious
                .into_iter()
                .inspect(|(_, iou)| {
                    let min = scores.entry("iou_min".to_string()).or_insert(1.0f64);
                    *min = min.min(*iou);
                })
                .filter(|(name, iou)| *iou < GATE_IOU && !unreachable.contains_key(name))
                .map(|(name, iou)| format!("{name} ({iou:.4})"))
                .collect(),
            Err(e) => {
                missing.push(format!("the poses could not be scored: {e}"));
                vec![]
            }
        };
        if !below.is_empty() {
            missing.push(format!(
                "keyframes under the {GATE_IOU} gate without a reason: {}",
                below.join(", ")
            ));
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
        let pose = last(&|e| e.kind == "pose" && ok(e)).unwrap_or(0);
        let turntable = last(&|e| e.tool == "turntable" && ok(e));
        let temporal = last(&|e| e.tool == "temporal" && ok(e));
        if turntable.is_none_or(|t| t < shape) {
            missing.push("look at a `turntable` after the last shape change".into());
        }
        if temporal.is_none_or(|t| t < pose) {
            missing.push("review the `temporal` report after the last pose change".into());
        }
        let passed = missing.is_empty();
        let mut o = ToolOutput {
            text: if passed {
                format!(
                    "All gates hold. The run is finished.{}",
                    if unreachable.is_empty() {
                        String::new()
                    } else {
                        format!(
                            " Keyframes with reasons: {}.",
                            unreachable.keys().cloned().collect::<Vec<_>>().join(", ")
                        )
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

    fn toolbox(window: Option<&[&str]>) -> Toolbox {
        let run = RunDir {
            dir: "run".into(),
            capture: "cap".into(),
            scene: "run/scene.rhai".into(),
            poses: "run/pose.json".into(),
        };
        let mut t = Toolbox::new("agentstar".into(), run);
        t.window = window.map(|w| w.iter().map(|s| s.to_string()).collect());
        t
    }

    #[test]
    fn a_sub_agent_may_change_only_its_window() {
        let t = toolbox(Some(&["000000.png", "000005.png"]));
        assert!(t.check_window(Some("000000.png,000005")).is_ok());
        assert!(t
            .check_window(Some("000010"))
            .expect_err("outside")
            .contains("outside"));
        assert!(t.check_window(None).is_err());
        // Shape changes, whole-file restores and the tracker are refused outright.
        for (tool, args) in [
            (
                "scene_write",
                json!({"script": "part(\"a\", box(1, 1, 1));"}),
            ),
            ("pose_restore", json!({"version": 1})),
            ("track", json!({})),
            ("sweep", json!({"frames": "000010", "ranges": "yaw:-5,5"})),
        ] {
            let o = t.call(tool, &args, 1);
            assert!(o.is_error, "{tool}: {}", o.text);
        }
        assert!(toolbox(None).check_window(None).is_ok());
    }

    #[test]
    fn every_tool_has_an_object_schema_and_unknown_tools_are_named() {
        let all = catalogue();
        let mut names: Vec<&str> = all.iter().map(|t| t.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), all.len(), "duplicate tool names");
        for t in &all {
            assert_eq!(t.schema["type"], "object", "{}", t.name);
            assert!(
                t.description.len() > 40,
                "{} needs a description that teaches it",
                t.name
            );
        }
        let o = toolbox(None).call("fly", &json!({}), 1);
        assert!(o.is_error && o.text.contains("sweep"));
    }
}
