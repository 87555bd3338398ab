//! Scene tools: the task document, reading, writing and restoring `scene.rhai`.

use super::*;
use crate::task::task_document;
use crate::{AgentError, Result};
use agentstar_reports::CheckReport;
use schemars::JsonSchema;
use serde::Deserialize;
use std::path::Path;

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
    /// The part to keep in place when pose.json is carried to the new shape (a part of
    /// both the old and the new script). Default: the part with the most visible pixels in
    /// the keyframes at the current poses.
    #[schemars(length(min = 1))]
    pub hold: Option<String>,
}

/// The longest scene script `scene_write` takes, in bytes (its schema's bound on `script`).
pub(super) const SCENE_SCRIPT_MAX_BYTES: usize = 262_144;

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

tool!(Task, "task", Note, Nothing, NoArgs,
    "Return TASK.md: the goal, the conventions, how to work, how to read the images, the gates before finishing, and the whole scene API with a worked example. Read it first.",
    |_tb, _a, _step| Ok(ToolOutput::text(task_document())));

tool!(SceneRead, "scene_read", Diagnostic, Nothing, NoArgs,
    "Return the current scene.rhai and its check: parts, joints, the canonical frame (bounding box, centre) and warnings.",
    |tb, _a, _step| tb.scene_read());

tool!(SceneWrite, "scene_write", Shape, Scene, SceneWriteArgs,
    "Replace scene.rhai with a whole new script (a shape step), given as `script` or as `path` (a file in the run directory holding it). The script is built in the sandbox first: on an error you get the message with its line and nothing changes. On success a new scene version is saved and pose.json gains new joints at rest (removed joints are dropped); where the edit moved the canonical origin under the held part (`hold`, default the part most in view in the keyframes), every pose is carried so that part stays where it was in every image, and the result says which part was held. Check the shape with `turntable` afterwards.",
    |tb, a, step| tb.scene_write(&a.script(tb)?, nonblank(&a.hold), step));

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
        tb.scene_write(&script, None, step)
    }
);

impl Toolbox {
    pub(super) fn scene_read(&self) -> Result<ToolOutput> {
        let script = agentstar_data::read_text(&self.run.scene)?;
        let (_, check, stderr) = self.exec(check_call(&self.run.scene)?.args())?;
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
    pub(super) fn scene_write(
        &self,
        script: &str,
        hold: Option<&str>,
        step: u64,
    ) -> Result<ToolOutput> {
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
        let (ok, check, stderr) = self.exec(check_call(Path::new(&shown))?.args())?;
        if !ok {
            return Ok(ToolOutput::error(format!(
                "the scene was not changed: {}",
                failure_text(&stderr).replace(&shown, "scene.rhai")
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
        let (_, before_check, _) = self.exec(check_call(&self.run.scene)?.args())?;
        let before_warnings = serde_json::from_str::<CheckReport>(&before_check)
            .map(|r| r.warnings)
            .unwrap_or_default();
        // The model the poses were made for: a moved origin is compensated against it,
        // holding the part named, or the one most in view, in place.
        let before = agentstar_data::scenefile::load_model(&self.run.scene)
            .ok()
            .map(|m| m.model);
        let held = match (
            &before,
            agentstar_data::scenefile::load_model(candidate.path()),
        ) {
            (Some(old), Ok(new)) => {
                let visible = visible_pixels(old, &self.run.capture, &self.run.poses);
                match agentstar_geom::held_part(
                    old,
                    &new.model,
                    hold,
                    visible.as_ref().map(|(v, n)| (v.as_slice(), *n)),
                ) {
                    Ok(h) => Some(h),
                    Err(e) if hold.is_some() => {
                        return Ok(ToolOutput::error(format!(
                            "the scene was not changed: `hold`: {e}"
                        )))
                    }
                    Err(_) => None,
                }
            }
            _ => None,
        };
        // The scene and its version change together under the run's scene lock, which
        // every process serving this run (two MCP servers, the loop) takes.
        let _scene_lock = self.run.lock_scene()?;
        // The version first, then the scene: a writer killed between the two leaves a
        // version `scene_restore` can bring back, never a scene no version records.
        let version = self.run.list_scene_versions().last().copied().unwrap_or(0) + 1;
        self.run.save_scene_text(version, script)?;
        candidate
            .persist(&self.run.scene)
            .map_err(|e| agentstar_data::DataError::io(&self.run.scene, e.error))?;
        let (joints, pose_version) = agentstar_data::poses::reconcile(
            &self.run.scene,
            &self.run.poses,
            before.as_ref().zip(held.as_ref()),
            &format!("scene version {version} (step {step}): joints reconciled"),
        )?;
        Ok(ToolOutput {
            text: format!(
                "scene version {version} saved.{}{}{}\ncheck:\n{}",
                held.as_ref().map_or(String::new(), |h| format!(
                    " Held in place: part `{}` ({}).",
                    h.name, h.why
                )),
                pose_line(&joints, pose_version),
                self.mechanism_reminder()
                    .map(|r| format!("\n{r}"))
                    .unwrap_or_default(),
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
}

/// Each part's visible pixels in the keyframes at their poses (at most
/// [`HELD_FRAMES`] of them, evenly spread), and how many keyframes were measured; `None`
/// when the capture or the poses cannot be read or no keyframe has a pose of its own.
pub(super) fn visible_pixels(
    model: &agentstar_geom::ObjectModel,
    capture: &Path,
    poses: &Path,
) -> Option<(Vec<u64>, usize)> {
    let capture = agentstar_data::capture::Capture::open(capture).ok()?;
    let pf = agentstar_data::posefile::PoseFile::read(poses).ok()?;
    let resolved = pf.resolve(&capture, &model.tree).ok()?;
    let posed: Vec<usize> = (0..resolved.len().min(capture.frames.len()))
        .filter(|&i| !resolved[i].seeded)
        .collect();
    if posed.is_empty() {
        return None;
    }
    let stride = posed.len().div_ceil(HELD_FRAMES).max(1);
    let chosen: Vec<usize> = posed.into_iter().step_by(stride).collect();
    let views = chosen.iter().map(|&i| {
        let g = &resolved[i].generalised;
        (
            &capture.frames[i].camera,
            g.pose.with_scale(pf.scale),
            g.states.as_slice(),
        )
    });
    Some((
        agentstar_render::visible_part_pixels(model, views),
        chosen.len(),
    ))
}

/// What a scene edit did to pose.json, in the reply: what changed with the version it
/// made, or that nothing did (then no version was made: the two always agree; play-test 15
/// read "unchanged" beside a new pose version).
pub(super) fn pose_line(changes: &[String], pose_version: Option<u64>) -> String {
    match (changes.is_empty(), pose_version) {
        // Said, not left out (play-test 11 could not tell whether its poses had been carried).
        (true, None) => " pose.json unchanged: no joint, part or joint definition changed and the canonical origin did not move, so every pose stands as it was (no pose version).".to_string(),
        (true, Some(v)) => format!(" pose.json version {v}: its header brought in step with the scene; every pose stands as it was."),
        (false, Some(v)) => format!(" pose.json version {v}: {}.", changes.join("; ")),
        (false, None) => format!(" pose.json: {}.", changes.join("; ")),
    }
}

/// Keyframes measured to find the part most in view.
const HELD_FRAMES: usize = 24;

/// `agentstar check SCRIPT --json`.
pub(super) fn check_call(script: &Path) -> Result<Invocation> {
    #[derive(serde::Serialize)]
    struct Check {
        json: bool,
    }
    Invocation::new(&["check".to_string(), script.display().to_string()])
        .with(&Check { json: true })
}
