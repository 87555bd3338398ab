//! A run directory: what the agent works on and everything it did. Its layout, locks and
//! state (`RunDir`, `RunState`) live in `agentstar_data::rundir`, re-exported here; this
//! module makes new runs, with the task document.

use crate::{AgentError, Result};
use agentstar_data::ledger::LedgerEntry;

use std::path::Path;

pub use agentstar_data::rundir::{RunDir, RunState};
pub use agentstar_data::runfile::{default_model, default_poses, FinishPolicy, RunFile};

/// The starting scene of a new run: one box, to be replaced.
pub const STARTING_SCENE: &str = r##"// The model of the object, as code: replace this box (see TASK.md for the API).
part("body", box(1.0, 0.6, 0.4).color("#b05a3c"));
"##;

/// Makes a new run directory for `capture`: `run.json`, the starting scene (or `scene`'s
/// text), an initial `pose.json` (the object 0.5 m before the reference camera at scale
/// `scale`), `TASK.md`, `NOTES.md` and an empty ledger. Fails when `dir` exists and is not
/// empty. Everything is written into a temporary sibling renamed into place.
pub fn init_run(dir: &Path, capture: &Path, scene: Option<&str>, scale: f64) -> Result<RunDir> {
    if dir.exists()
        && std::fs::read_dir(dir)
            .map_err(|e| agentstar_data::DataError::io(dir, e))?
            .next()
            .is_some()
    {
        return Err(AgentError::Invalid(format!(
            "{}: exists and is not empty; choose a new run directory",
            dir.display()
        )));
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(AgentError::Invalid(format!(
            "scale {scale}: metres per model unit, a positive number"
        )));
    }
    let cap = agentstar_data::capture::Capture::open(capture)
        .map_err(|problems| AgentError::Invalid(problems.brief()))?;
    let parent = dir
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| agentstar_data::DataError::io(parent, e))?;
    let tmp = tempfile::Builder::new()
        .prefix(".agentstar-init-")
        .tempdir_in(parent)
        .map_err(|e| agentstar_data::DataError::io(parent, e))?;
    let root = tmp.path();
    let capture_abs = capture
        .canonicalize()
        .map_err(|e| agentstar_data::DataError::io(capture, e))?;
    let rf = RunFile {
        capture: capture_abs,
        model: default_model(),
        poses: default_poses(),
        finish: FinishPolicy::default(),
    };
    let write = |name: &str, bytes: &[u8]| -> Result<()> {
        Ok(agentstar_data::atomic::write_atomic(
            &root.join(name),
            bytes,
        )?)
    };
    write(
        "run.json",
        serde_json::to_string_pretty(&rf)
            .map_err(|e| AgentError::Invalid(e.to_string()))?
            .as_bytes(),
    )?;
    let script = scene.unwrap_or(STARTING_SCENE);
    write("scene.rhai", script.as_bytes())?;
    let model = agentstar_data::scenefile::load_model(&root.join("scene.rhai"))?;
    // The object half a metre before the reference camera, unrotated.
    let reference = agentstar_geom::pose::ObjectPose::new(
        agentstar_geom::UnitQuaternion::identity(),
        agentstar_geom::Vector3::new(0.0, 0.0, 0.5),
    );
    let mut pf =
        agentstar_data::posefile::PoseFile::initial(&cap, &model.model.tree, scale, &reference);
    pf.parts = Some(model.model.part_names());
    pf.write(&root.join("pose.json"))?;
    write("TASK.md", crate::task::task_document().as_bytes())?;
    write(
        "NOTES.md",
        b"# Notes\n\nWhat I learned about this capture and model (kept across contexts).\n",
    )?;
    write("ledger.jsonl", b"")?;
    let versions = root.join(".agentstar").join("scenes");
    std::fs::create_dir_all(&versions).map_err(|e| agentstar_data::DataError::io(&versions, e))?;
    write(".agentstar/scenes/0001.rhai", script.as_bytes())?;
    let kept = tmp.keep();
    if dir.exists() {
        std::fs::remove_dir(dir).map_err(|e| agentstar_data::DataError::io(dir, e))?;
    }
    std::fs::rename(&kept, dir).map_err(|e| agentstar_data::DataError::io(dir, e))?;
    let run = RunDir::open(dir)?;
    run.record(&LedgerEntry {
        step: 0,
        time_s: 0.0,
        kind: "system".into(),
        tool: "init".into(),
        args: serde_json::json!({"capture": capture, "scale": scale}),
        summary: format!(
            "run made for {} ({} keyframes)",
            capture.display(),
            cap.frames.len()
        ),
        scores: Default::default(),
        images: vec![],
        scene_version: Some(1),
        pose_version: None,
    })?;
    Ok(run)
}
