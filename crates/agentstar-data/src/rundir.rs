//! A run directory's layout: where its run file, ledger, notes, scene versions and step
//! folders lie, its step and scene locks, and its state read back from the ledger. Nothing
//! here drives a model: `agentstar-agent` makes runs (`init_run`) and works in them; the
//! commands that only read a run (`batch status`, `batch gather`) open it here.
//!
//! ```text
//! RUN/
//!   run.json        where the capture is; the model and pose file names
//!   TASK.md         the task document the agent reads
//!   NOTES.md        the agent's memory across contexts (appended by the `notes` tool)
//!   scene.rhai      the current model
//!   pose.json       the current poses (versions under .agentstar/history/, kept by `pose commit`)
//!   ledger.jsonl    one line per step
//!   images/         what each step produced, under step_NNNN_tool/
//!   .agentstar/scenes/NNNN.rhai   every scene version
//! ```

use crate::history::{self, HistoryError, PoseHistory, PoseLock, StepTag};
use crate::ledger::{self, LedgerEntry};
use crate::runfile::{FinishPolicy, RunFile};
use crate::DataError;

use std::path::{Path, PathBuf};

type Result<T, E = HistoryError> = std::result::Result<T, E>;

/// A run directory opened for work.
#[derive(Debug, Clone)]
pub struct RunDir {
    pub dir: PathBuf,
    pub capture: PathBuf,
    pub scene: PathBuf,
    pub poses: PathBuf,
    /// What `finish` accepts (from `run.json`).
    pub finish: FinishPolicy,
}

/// Where a run stands, read back from its ledger (to resume).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunState {
    pub steps: u64,
    /// Seconds the earlier sessions took.
    pub elapsed_s: f64,
    pub scene_version: u64,
    pub finished: bool,
    /// Ledger lines that could not be read (a cut last line after a crash).
    pub notes: Vec<String>,
    /// The last entries, for a summary to the model on resume.
    pub recent: Vec<LedgerEntry>,
}

impl RunDir {
    /// Opens an existing run (it must hold `run.json`).
    pub fn open(dir: &Path) -> Result<RunDir> {
        let rf = RunFile::read(dir)?.ok_or_else(|| {
            DataError::invalid(
                dir,
                format!(
                    "not a run directory (no run.json); make one with `agentstar init {} --capture CAPTURE`",
                    dir.display()
                ),
            )
        })?;
        let run = RunDir {
            dir: dir.to_path_buf(),
            capture: rf.capture,
            scene: rf.model,
            poses: rf.poses,
            finish: rf.finish,
        };
        run.sweep_temporaries();
        run.record_orphaned_steps()?;
        Ok(run)
    }

    /// Records the ledger steps of pose versions whose server was killed (`kill -9`) after
    /// its tool's command had recorded the version and before the server wrote the step: a
    /// version whose command names a step (`[step S of process P]`, see
    /// `crate::history::StepTag`) that the ledger lacks, of a process that no longer
    /// runs, gets a `system` entry numbered S naming it. Only where `/proc` says which
    /// processes run; under the step lock, so no server numbers a step meanwhile.
    fn record_orphaned_steps(&self) -> Result<()> {
        if !Path::new("/proc/self").exists() {
            return Ok(());
        }
        let history = PoseHistory::new(&self.poses);
        let Ok(versions) = history.versions() else {
            return Ok(());
        };
        let tagged: Vec<(u64, StepTag)> = versions
            .iter()
            .filter_map(|(n, p)| {
                let entry = PoseHistory::read_entry(p).ok()?;
                Some((*n, StepTag::in_command(&entry.command)?))
            })
            .collect();
        if tagged.is_empty() {
            return Ok(());
        }
        let _lock = self.step_lock()?;
        let state = self.state()?;
        let (entries, _) = match self.ledger_path().is_file() {
            true => ledger::read(&self.ledger_path())?,
            false => (vec![], vec![]),
        };
        let taken: std::collections::BTreeSet<u64> = entries.iter().map(|e| e.step).collect();
        let mut orphans: std::collections::BTreeMap<u64, (u32, Vec<u64>)> = Default::default();
        for (version, tag) in tagged {
            let gone = tag.pid != std::process::id()
                && !Path::new("/proc").join(tag.pid.to_string()).exists();
            if gone && !taken.contains(&tag.step) {
                orphans
                    .entry(tag.step)
                    .or_insert((tag.pid, vec![]))
                    .1
                    .push(version);
            }
        }
        for (step, (pid, versions)) in orphans {
            let newest = versions.iter().copied().max();
            let list = versions
                .iter()
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(", ");
            self.record(&LedgerEntry {
                step,
                time_s: state.elapsed_s,
                kind: "system".into(),
                tool: "recovered".into(),
                args: serde_json::Value::Null,
                summary: format!(
                    "pose version {list} was made by step {step}, whose server (process {pid}) stopped before writing the step; recorded when the run was opened again"
                ),
                scores: Default::default(),
                images: vec![],
                scene_version: None,
                pose_version: newest,
            })?;
        }
        Ok(())
    }

    /// The run's step lock (`.agentstar/steps.lock`), held while a step number is given.
    fn step_lock(&self) -> Result<PoseLock> {
        history::lock_file(&self.dir.join(".agentstar").join("steps.lock"))
    }

    /// Removes what writers killed mid-write (`kill -9`) left in the run's directories: the
    /// run itself, `.agentstar/`, its scene versions and the pose file's history (the
    /// temporaries of processes that no longer run; see `crate::atomic`).
    fn sweep_temporaries(&self) {
        let history = PoseHistory::new(&self.poses).dir();
        let poses_dir = self.poses.parent().map(Path::to_path_buf);
        for dir in [
            Some(self.dir.clone()),
            Some(self.dir.join(".agentstar")),
            Some(self.scene_versions()),
            Some(history),
            poses_dir,
        ]
        .into_iter()
        .flatten()
        {
            crate::atomic::remove_stale_temporaries(&dir);
        }
    }

    pub fn ledger_path(&self) -> PathBuf {
        self.dir.join("ledger.jsonl")
    }
    pub fn notes_path(&self) -> PathBuf {
        self.dir.join("NOTES.md")
    }
    pub fn task_path(&self) -> PathBuf {
        self.dir.join("TASK.md")
    }
    pub fn scene_versions(&self) -> PathBuf {
        self.dir.join(".agentstar").join("scenes")
    }
    /// Takes the run's scene lock (`.agentstar/scene.lock`), held while the scene and its
    /// versions change, across processes: two servers on one run never give one version
    /// twice.
    pub fn lock_scene(&self) -> Result<PoseLock> {
        history::lock_file(&self.dir.join(".agentstar").join("scene.lock"))
    }
    /// The output directory of step `step` of `tool`.
    pub fn step_dir(&self, step: u64, tool: &str) -> PathBuf {
        self.dir
            .join("images")
            .join(format!("step_{step:04}_{tool}"))
    }

    /// Saves the current scene as version `n` (`.agentstar/scenes/NNNN.rhai`).
    pub fn save_scene_version(&self, n: u64) -> Result<PathBuf> {
        let text = crate::read_text(&self.scene)?;
        self.save_scene_text(n, &text)
    }

    /// Saves `text` as scene version `n` (before it becomes the scene, so that no scene is
    /// ever current without its version).
    pub fn save_scene_text(&self, n: u64, text: &str) -> Result<PathBuf> {
        let dir = self.scene_versions();
        std::fs::create_dir_all(&dir).map_err(|e| crate::DataError::io(&dir, e))?;
        let p = dir.join(format!("{n:04}.rhai"));
        crate::atomic::write_atomic(&p, text.as_bytes())?;
        Ok(p)
    }

    /// The scene versions saved so far, in order.
    pub fn list_scene_versions(&self) -> Vec<u64> {
        let mut v: Vec<u64> = std::fs::read_dir(self.scene_versions())
            .into_iter()
            .flatten()
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.strip_suffix(".rhai")?.parse().ok()
            })
            .collect();
        v.sort_unstable();
        v
    }

    /// Reads the ledger back: steps taken, time spent, scene version, whether it finished.
    pub fn state(&self) -> Result<RunState> {
        let p = self.ledger_path();
        if !p.is_file() {
            return Ok(RunState::default());
        }
        let (entries, notes) = ledger::read(&p)?;
        let mut s = RunState {
            notes,
            ..RunState::default()
        };
        for e in &entries {
            s.steps = s.steps.max(e.step);
            s.elapsed_s = s.elapsed_s.max(e.time_s);
            if let Some(v) = e.scene_version {
                s.scene_version = s.scene_version.max(v);
            }
            if e.tool == "finish" && e.scores.get("passed").copied() == Some(1.0) {
                s.finished = true;
            }
        }
        s.recent = entries.iter().rev().take(12).rev().cloned().collect();
        Ok(s)
    }

    /// The next step number of this run, allocated under the run's step lock
    /// (`.agentstar/steps.lock`) for every process on the run: two MCP servers (or a server
    /// and the built-in loop) never number two steps alike, so their ledger entries and image
    /// folders (`images/step_NNNN_tool/`) stay apart. The last number given is kept in
    /// `.agentstar/last_step`; a run from before it starts after its ledger's last step.
    pub fn next_step(&self) -> Result<u64> {
        let dir = self.dir.join(".agentstar");
        let _lock = self.step_lock()?;
        let counter = dir.join("last_step");
        let given = if counter.is_file() {
            let text = crate::read_text(&counter)?;
            text.trim().parse::<u64>().map_err(|e| {
                DataError::invalid(
                    &counter,
                    format!(
                        "not a step number ({e}); remove it and the next step starts after the ledger's last"
                    ),
                )
            })?
        } else {
            0
        };
        let next = given.max(self.state()?.steps) + 1;
        crate::atomic::write_atomic(&counter, format!("{next}\n").as_bytes())?;
        Ok(next)
    }

    /// Appends a ledger entry.
    pub fn record(&self, e: &LedgerEntry) -> Result<()> {
        Ok(ledger::append(&self.ledger_path(), e)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opening_a_run_removes_what_a_killed_writer_left() {
        let dir = tempfile::tempdir().expect("tmp");
        let cap = dir.path().join("cap");
        std::fs::create_dir_all(&cap).expect("cap dir");
        let run = dir.path().join("run");
        std::fs::create_dir_all(run.join(".agentstar/history/pose")).expect("dirs");
        std::fs::write(
            run.join("run.json"),
            format!("{{\"capture\": \"{}\"}}", cap.display()),
        )
        .expect("run.json");
        // A pid that no process has (beyond the kernel's limit), and this process's own.
        let dead = ".agentstar-4194305-abc123.tmp";
        let mine = format!("{}abc123.tmp", crate::atomic::temporary_prefix());
        for d in [run.clone(), run.join(".agentstar/history/pose")] {
            std::fs::write(d.join(dead), b"half a pose").expect("stale");
            std::fs::write(d.join(&mine), b"in use").expect("live");
        }
        RunDir::open(&run).expect("open");
        for d in [run.clone(), run.join(".agentstar/history/pose")] {
            assert!(
                !d.join(dead).exists(),
                "{} kept the dead writer's file",
                d.display()
            );
            assert!(
                d.join(&mine).exists(),
                "{} lost a live writer's file",
                d.display()
            );
        }
    }
}
