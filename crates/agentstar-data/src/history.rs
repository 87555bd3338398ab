//! Committed versions of a pose file (`.agentstar/history/STEM/NNNNNN.json` beside it) and
//! the two ways to change a pose file that keep them: [`PoseHistory::update`] (a change of
//! what is there: a commit, a restore of some frames, a rescale) and [`PoseHistory::write`]
//! (a whole new file: the tracker's result, a shape fit). Every writer of a pose file calls
//! one of them with its command ([`command_line`] for a command run from a shell), so every
//! change is a version that names what made it.
//!
//! Every change holds an exclusive lock on `.agentstar/STEM.lock` for its whole
//! read-modify-write, across threads and processes (`agentstar pose commit` from a shell
//! and an MCP server on the same run serialise on it). Version numbers are allocated under
//! that lock and each version file is created with a no-replace link, so two writers can
//! never claim the same number.
//!
//! Versions are read back whole ([`PoseHistory::read_entry`]), frame by frame
//! ([`PoseHistory::frame_versions`]: one frame's pose in every version) or restored, whole
//! or for chosen frames ([`PoseHistory::restore_frames`]).

use crate::posefile::{FrameEntry, PoseFile, PoseJson};
use crate::DataError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// What can go wrong with a pose file's history: a file that does not read, or a request
/// that cannot be met (a version that does not exist, a frame it does not hold).
#[derive(Debug, thiserror::Error)]
pub enum HistoryError {
    #[error("{0}")]
    Data(#[from] DataError),
    #[error("{0}")]
    Invalid(String),
}

pub type Result<T, E = HistoryError> = std::result::Result<T, E>;

/// One committed version of a pose file (`.agentstar/history/STEM/NNNNNN.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistoryEntry {
    pub version: u64,
    pub time_unix_s: u64,
    /// The command (or tool) that made it.
    pub command: String,
    pub pose: PoseFile,
}

/// One row of `pose history --json`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistoryRow {
    pub version: u64,
    pub time_unix_s: u64,
    pub command: String,
}

/// One frame in one version of a pose file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameVersion {
    pub version: u64,
    pub time_unix_s: u64,
    pub command: String,
    /// The version's shared scale.
    pub scale: f64,
    /// The frame's pose in that version (`None`: the version has none for it).
    pub pose: Option<PoseJson>,
    /// Joint states in interface units (degrees, metres).
    pub joints: BTreeMap<String, f64>,
    /// The first earlier version with the same pose, joint states and scale.
    pub same_as: Option<u64>,
    /// The visible IoU of that pose with the current model (when scored).
    pub iou_visible: Option<f64>,
}

/// The process dies here, as `kill -9` would, when `AGENTSTAR_FAILPOINT` is
/// `between-version-and-file`: the kill tests' one way to land exactly between a version and
/// the file it versions (random kills almost never do).
fn failpoint_between_version_and_file() {
    if std::env::var_os("AGENTSTAR_FAILPOINT").is_some_and(|v| v == "between-version-and-file") {
        std::process::abort();
    }
}

/// What the first version says when a history starts on a file that already existed.
pub const INITIAL: &str = "initial version (before the first commit)";

/// The start of the command of a version that records the pose file as it was found when it
/// no longer held the newest version's poses (see [`PoseHistory::catch_up`]).
pub const FOUND: &str = "pose file as found";

/// The environment variable through which an agent's tool tells the command it runs which
/// ledger step it serves and which process will write that step (`S of process P`).
pub const STEP_ENV: &str = "AGENTSTAR_STEP";

/// A ledger step and the process that allocated it, as a version's command names them
/// (`… [step 18 of process 4242]`): when that process is gone and the ledger has no step 18,
/// the run records the step on reopening (`agentstar_agent::run`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepTag {
    pub step: u64,
    pub pid: u32,
}

impl StepTag {
    pub fn of_this_process(step: u64) -> StepTag {
        StepTag {
            step,
            pid: std::process::id(),
        }
    }

    /// The tag at the end of a version's command.
    pub fn in_command(command: &str) -> Option<StepTag> {
        let inner = command.strip_suffix(']')?.rsplit_once(" [")?.1;
        let (step, pid) = inner.strip_prefix("step ")?.split_once(" of process ")?;
        Some(StepTag {
            step: step.parse().ok()?,
            pid: pid.parse().ok()?,
        })
    }

    fn from_env(value: &str) -> Option<StepTag> {
        StepTag::in_command(&format!("x [step {value}]"))
    }
}

impl std::fmt::Display for StepTag {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} of process {}", self.step, self.pid)
    }
}

/// This process's command as it is recorded in a history: `agentstar` and its arguments
/// (arguments with spaces or quotes are quoted), and the step it serves when an agent's tool
/// ran it (`[step S of process P]`, from [`STEP_ENV`]).
pub fn command_line() -> String {
    let mut words = vec!["agentstar".to_string()];
    words.extend(std::env::args().skip(1).map(|a| {
        if a.is_empty() || a.contains(|c: char| c.is_whitespace() || c == '\'' || c == '"') {
            format!("'{}'", a.replace('\'', "'\\''"))
        } else {
            a
        }
    }));
    let mut line = words.join(" ");
    if let Some(tag) = std::env::var(STEP_ENV)
        .ok()
        .and_then(|v| StepTag::from_env(&v))
    {
        line.push_str(&format!(" [step {tag}]"));
    }
    line
}

/// An exclusive lock on a file (`flock`), released when dropped; waits for other holders,
/// across threads and processes. Creates the file and its directory when missing.
pub fn lock_file(path: &Path) -> Result<PoseLock> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| DataError::io(dir, e))?;
    }
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(path)
        .map_err(|e| DataError::io(path, e))?;
    file.lock().map_err(|e| DataError::io(path, e))?;
    Ok(PoseLock { file })
}

/// The entry of `frame` (a name or its stem) in `pf`.
fn entry_of<'a>(pf: &'a PoseFile, frame: &str) -> Option<(&'a String, &'a FrameEntry)> {
    pf.frames.get_key_value(frame).or_else(|| {
        let stem = Path::new(frame).file_stem()?.to_str()?;
        pf.frames
            .iter()
            .find(|(k, _)| Path::new(k.as_str()).file_stem().and_then(|s| s.to_str()) == Some(stem))
    })
}

/// The history of the pose file at `poses`.
#[derive(Debug, Clone)]
pub struct PoseHistory {
    poses: PathBuf,
}

/// An exclusive lock on a pose file; released when dropped.
#[derive(Debug)]
pub struct PoseLock {
    file: std::fs::File,
}

impl Drop for PoseLock {
    fn drop(&mut self) {
        let _ = self.file.unlock();
    }
}

fn now_unix_s() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

impl PoseHistory {
    pub fn new(poses: &Path) -> PoseHistory {
        PoseHistory {
            poses: poses.to_path_buf(),
        }
    }

    pub fn poses(&self) -> &Path {
        &self.poses
    }

    fn base(&self) -> PathBuf {
        let dir = self
            .poses
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        dir.join(".agentstar")
    }

    fn stem(&self) -> String {
        self.poses
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("pose")
            .to_string()
    }

    /// The directory of the versions.
    pub fn dir(&self) -> PathBuf {
        self.base().join("history").join(self.stem())
    }

    /// Takes the pose file's lock, waiting for other writers.
    pub fn lock(&self) -> Result<PoseLock> {
        lock_file(&self.base().join(format!("{}.lock", self.stem())))
    }

    /// The versions kept, in order.
    pub fn versions(&self) -> Result<Vec<(u64, PathBuf)>> {
        let dir = self.dir();
        let mut v = Vec::new();
        let rd = match std::fs::read_dir(&dir) {
            Ok(rd) => rd,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(v),
            Err(e) => return Err(DataError::io(&dir, e).into()),
        };
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            if let Some(n) = name
                .strip_suffix(".json")
                .and_then(|s| s.parse::<u64>().ok())
            {
                v.push((n, e.path()));
            }
        }
        v.sort();
        Ok(v)
    }

    /// The newest version when it holds `pose` (the file as read), else `None`: which
    /// version a reader of the file is working from.
    pub fn version_of(&self, pose: &PoseFile) -> Result<Option<u64>> {
        let Some((n, path)) = self.versions()?.pop() else {
            return Ok(None);
        };
        Ok((Self::read_entry(&path)?.pose == *pose).then_some(n))
    }

    /// Reads version file `path`.
    pub fn read_entry(path: &Path) -> Result<HistoryEntry> {
        let text = crate::read_text(path)?;
        serde_json::from_str(&text).map_err(|e| {
            HistoryError::Data(DataError::invalid(
                path,
                format!("not a pose history entry: {e}"),
            ))
        })
    }

    /// The versions without their poses (what `pose history` lists).
    pub fn rows(&self) -> Result<Vec<HistoryRow>> {
        self.versions()?
            .iter()
            .map(|(_, p)| {
                let e = Self::read_entry(p)?;
                Ok(HistoryRow {
                    version: e.version,
                    time_unix_s: e.time_unix_s,
                    command: e.command,
                })
            })
            .collect()
    }

    /// Records `pose` as the next version. The caller holds the lock; the file is created
    /// with a link that never replaces, so a number is never given twice even then.
    fn record(&self, _lock: &PoseLock, pose: &PoseFile, command: &str) -> Result<u64> {
        let dir = self.dir();
        std::fs::create_dir_all(&dir).map_err(|e| DataError::io(&dir, e))?;
        // What a writer killed mid-version left (issue 16: `kill -9` during `track`).
        crate::atomic::remove_stale_temporaries(&dir);
        let mut next = self.versions()?.last().map_or(0, |(n, _)| n + 1);
        loop {
            let entry = HistoryEntry {
                version: next,
                time_unix_s: now_unix_s(),
                command: command.to_string(),
                pose: pose.clone(),
            };
            let text = serde_json::to_string_pretty(&entry)
                .map_err(|e| DataError::invalid(&dir, format!("cannot encode a version: {e}")))?;
            let mut tmp = tempfile::Builder::new()
                .prefix(&crate::atomic::temporary_prefix())
                .suffix(".tmp")
                .tempfile_in(&dir)
                .map_err(|e| DataError::io(&dir, e))?;
            tmp.write_all(text.as_bytes())
                .and_then(|_| tmp.write_all(b"\n"))
                .and_then(|_| tmp.as_file().sync_all())
                .map_err(|e| DataError::io(tmp.path(), e))?;
            let target = dir.join(format!("{next:06}.json"));
            match std::fs::hard_link(tmp.path(), &target) {
                Ok(()) => {
                    #[cfg(unix)]
                    {
                        use std::os::unix::fs::PermissionsExt;
                        let _ = std::fs::set_permissions(
                            &target,
                            std::fs::Permissions::from_mode(0o644),
                        );
                    }
                    return Ok(next);
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => next += 1,
                Err(e) => return Err(DataError::io(&target, e).into()),
            }
        }
    }

    /// Makes the newest version hold `found`, the pose file as it stands, before a change is
    /// recorded: the file as it was becomes version 0 when there is no history yet, and
    /// when the newest version holds other poses (a writer killed between recording its
    /// version and writing the file, or an edit outside agentstar) the file is recorded as
    /// found. So the pose file is always the newest version's poses or, while a writer is
    /// stopped between the two, the version before it, however many writers are stopped.
    fn catch_up(&self, lock: &PoseLock, found: &PoseFile) -> Result<()> {
        let versions = self.versions()?;
        let Some((n, path)) = versions.last() else {
            return self.record(lock, found, INITIAL).map(|_| ());
        };
        if Self::read_entry(path)?.pose != *found {
            self.record(
                lock,
                found,
                &format!("{FOUND} (version {n} was recorded but never written to it: a writer stopped between the two, or an edit outside agentstar)"),
            )?;
        }
        Ok(())
    }

    /// Changes the pose file under its lock: reads it, applies `change`, records the result
    /// as a new version and writes it atomically (the file as it was becomes
    /// version 0 when there is no history yet). Returns `change`'s value and the version.
    pub fn update<T, E: From<HistoryError> + From<DataError>>(
        &self,
        command: &str,
        change: impl FnOnce(&mut PoseFile) -> Result<T, E>,
    ) -> Result<(T, u64), E> {
        let lock = self.lock()?;
        let mut pf = PoseFile::read(&self.poses)?;
        self.catch_up(&lock, &pf)?;
        let out = change(&mut pf)?;
        // The version first, then the file: a writer killed between the two leaves a
        // version that `restore` can bring back, never a pose file no version records.
        let v = self.record(&lock, &pf, command)?;
        failpoint_between_version_and_file();
        pf.write(&self.poses)?;
        Ok((out, v))
    }

    /// Like [`PoseHistory::update`], but writes and records only when `change` changed
    /// the file; returns the version when it did.
    pub fn update_if_changed<T, E: From<HistoryError> + From<DataError>>(
        &self,
        command: &str,
        change: impl FnOnce(&mut PoseFile) -> Result<T, E>,
    ) -> Result<(T, Option<u64>), E> {
        let lock = self.lock()?;
        let before = PoseFile::read(&self.poses)?;
        let mut pf = before.clone();
        let out = change(&mut pf)?;
        if pf == before {
            return Ok((out, None));
        }
        self.catch_up(&lock, &before)?;
        // The version first, then the file: a writer killed between the two leaves a
        // version that `restore` can bring back, never a pose file no version records.
        let v = self.record(&lock, &pf, command)?;
        failpoint_between_version_and_file();
        pf.write(&self.poses)?;
        Ok((out, Some(v)))
    }

    /// Writes `pose` as the whole pose file and records it as a new version (the one call
    /// of every writer that makes a new file: the tracker, a shape fit). The file need not
    /// exist; when it does and has no history yet, it becomes version 0 first. A file
    /// there that is not a pose file is left alone (an error), never overwritten.
    pub fn write(&self, pose: &PoseFile, command: &str) -> Result<u64> {
        let lock = self.lock()?;
        if self.versions()?.is_empty() && self.poses.exists() {
            let before = PoseFile::read(&self.poses).map_err(|e| {
                HistoryError::Invalid(format!(
                    "{} exists and is not a pose file, so it is not overwritten ({e})",
                    self.poses.display()
                ))
            })?;
            if before != *pose {
                self.record(&lock, &before, INITIAL)?;
            }
        } else if let Ok(before) = PoseFile::read(&self.poses) {
            if before != *pose {
                self.catch_up(&lock, &before)?;
            }
        }
        let v = self.record(&lock, pose, command)?;
        failpoint_between_version_and_file();
        pose.write(&self.poses)?;
        Ok(v)
    }

    /// Replaces the pose file with `pose` (recorded as a new version).
    pub fn replace(&self, pose: PoseFile, command: &str) -> Result<u64> {
        self.write(&pose, command)
    }

    /// The entry of version `version`; an error listing the versions when there is none.
    pub fn entry(&self, version: u64) -> Result<HistoryEntry> {
        let list = self.versions()?;
        let Some((_, path)) = list.iter().find(|(n, _)| *n == version) else {
            return Err(HistoryError::Invalid(format!(
                "no version {version} of {}; {}",
                self.poses.display(),
                if list.is_empty() {
                    "it has no versions yet".to_string()
                } else {
                    format!(
                        "versions are {}..{} ({} kept)",
                        list[0].0,
                        list[list.len() - 1].0,
                        list.len()
                    )
                }
            )));
        };
        Self::read_entry(path)
    }

    /// Makes version `version` current again (recorded as a new version).
    pub fn restore(&self, version: u64) -> Result<u64> {
        self.restore_frames(version, None).map(|(_, v)| v)
    }

    /// Restores `frames` (names as the pose file keys them, or their stems) from version
    /// `version`, leaving every other frame as it is; `None` restores the whole file. The
    /// restored frames get the version's pose and joint states (joints the current file no
    /// longer has are dropped, new ones keep their current value). Refused when the
    /// version's scale differs (its translations mean something else). Returns the frames
    /// restored and the new version.
    pub fn restore_frames(
        &self,
        version: u64,
        frames: Option<&[String]>,
    ) -> Result<(Vec<String>, u64)> {
        let entry = self.entry(version)?;
        let Some(frames) = frames else {
            let names: Vec<String> = entry.pose.frames.keys().cloned().collect();
            let v = self.write(&entry.pose, &format!("restore version {version}"))?;
            return Ok((names, v));
        };
        if frames.is_empty() {
            return Err(HistoryError::Invalid("no frame to restore".into()));
        }
        let command = format!("restore {} of version {version}", frames.join(","));
        self.update(&command, |pf| {
            if (entry.pose.scale - pf.scale).abs() > 1e-9 * pf.scale.abs() {
                return Err(HistoryError::Invalid(format!(
                    "version {version} has scale {} but {} has scale {}; restore the whole version, or frames of a version at this scale",
                    entry.pose.scale,
                    self.poses.display(),
                    pf.scale
                )));
            }
            let known: Vec<String> = pf.joint_defs.iter().map(|j| j.name.clone()).collect();
            let mut done = Vec::new();
            for f in frames {
                let Some((_, old)) = entry_of(&entry.pose, f) else {
                    return Err(HistoryError::Invalid(format!(
                        "version {version} has no pose for frame {f}"
                    )));
                };
                let key = entry_of(pf, f)
                    .map(|(k, _)| k.clone())
                    .unwrap_or_else(|| f.clone());
                let e = pf.frames.entry(key.clone()).or_default();
                e.object_pose = old.object_pose.clone();
                if let Some(p) = e.object_pose.as_mut() {
                    p.scale = Some(pf.scale);
                }
                for (name, value) in &old.joints {
                    if known.is_empty() || known.contains(name) {
                        e.joints.insert(name.clone(), *value);
                    }
                }
                e.moved = true;
                done.push(key);
            }
            Ok(done)
        })
    }

    /// Frame `frame` (a name or its stem) in every version, oldest first: its pose and
    /// joint states, and the earlier version it is identical to (so a person sees where it
    /// changed). Scores are left for the caller, who has the renderer.
    pub fn frame_versions(&self, frame: &str) -> Result<Vec<FrameVersion>> {
        let mut out: Vec<FrameVersion> = Vec::new();
        for (_, path) in self.versions()? {
            let e = Self::read_entry(&path)?;
            let entry = entry_of(&e.pose, frame).map(|(_, v)| v.clone());
            let pose = entry.as_ref().and_then(|x| x.object_pose.clone());
            let joints = entry.map(|x| x.joints).unwrap_or_default();
            let same_as = out
                .iter()
                .rev()
                .find(|o| o.pose == pose && o.joints == joints && o.scale == e.pose.scale)
                .map(|o| o.same_as.unwrap_or(o.version));
            out.push(FrameVersion {
                version: e.version,
                time_unix_s: e.time_unix_s,
                command: e.command,
                scale: e.pose.scale,
                pose,
                joints,
                same_as,
                iou_visible: None,
            });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose_file(dir: &Path) -> PathBuf {
        let p = dir.join("pose.json");
        std::fs::write(
            &p,
            serde_json::json!({
                "scale": 0.2, "reference_frame": "a.png", "frames": {
                    "a.png": {"object_pose": {"quaternion": [1, 0, 0, 0], "translation": [0, 0, 1]}}
                }
            })
            .to_string(),
        )
        .expect("write");
        p
    }

    #[test]
    fn concurrent_updates_keep_every_change_and_every_version() {
        let dir = tempfile::tempdir().expect("tmp");
        let poses = pose_file(dir.path());
        let h = PoseHistory::new(&poses);
        let versions: Vec<u64> = std::thread::scope(|s| {
            let hs: Vec<_> = (0..8)
                .map(|k| {
                    let h = h.clone();
                    s.spawn(move || {
                        h.update(&format!("writer {k}"), |pf| {
                            pf.frames.entry(format!("f{k}.png")).or_default().moved = true;
                            Ok::<(), HistoryError>(())
                        })
                        .expect("update")
                        .1
                    })
                })
                .collect();
            hs.into_iter().map(|h| h.join().expect("join")).collect()
        });
        let mut sorted = versions.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (1..=8).collect::<Vec<u64>>(), "{versions:?}");
        let pf = PoseFile::read(&poses).expect("read");
        for k in 0..8 {
            assert!(pf.frames.contains_key(&format!("f{k}.png")), "lost {k}");
        }
        let rows = h.rows().expect("rows");
        assert_eq!(rows.len(), 9);
        assert_eq!(rows[0].command, "initial version (before the first commit)");
        // The last version is the file.
        let (_, last) = h.versions().expect("v").pop().expect("one");
        assert_eq!(PoseHistory::read_entry(&last).expect("e").pose, pf);
    }

    #[test]
    fn restore_names_the_versions_it_has() {
        let dir = tempfile::tempdir().expect("tmp");
        let h = PoseHistory::new(&pose_file(dir.path()));
        let e = h.restore(3).expect_err("none yet");
        assert!(e.to_string().contains("no version 3"), "{e}");
        h.update("scale", |pf| {
            pf.scale = 0.3;
            Ok::<(), HistoryError>(())
        })
        .expect("update");
        assert_eq!(h.restore(0).expect("restore"), 2);
        assert_eq!(PoseFile::read(h.poses()).expect("read").scale, 0.2);
    }

    fn moved_to(pf: &mut PoseFile, frame: &str, x: f64) {
        let e = pf.frames.entry(frame.to_string()).or_default();
        e.object_pose = Some(crate::posefile::PoseJson {
            quaternion: [1.0, 0.0, 0.0, 0.0],
            translation: [x, 0.0, 1.0],
            scale: Some(pf.scale),
        });
        e.moved = true;
    }

    #[test]
    fn restoring_frames_of_an_old_version_leaves_the_others() {
        let dir = tempfile::tempdir().expect("tmp");
        let h = PoseHistory::new(&pose_file(dir.path()));
        // v0 the file, v1 both frames at x = 1, v2 both at x = 2.
        for x in [1.0, 2.0] {
            h.update(&format!("move to {x}"), |pf| {
                moved_to(pf, "a.png", x);
                moved_to(pf, "b.png", x);
                Ok::<(), HistoryError>(())
            })
            .expect("update");
        }
        let (done, v) = h
            .restore_frames(1, Some(&["a".to_string()]))
            .expect("restore a");
        assert_eq!((done, v), (vec!["a.png".to_string()], 3));
        let pf = PoseFile::read(h.poses()).expect("read");
        let x = |f: &str| pf.frames[f].object_pose.as_ref().expect("pose").translation[0];
        assert_eq!((x("a.png"), x("b.png")), (1.0, 2.0));
        assert_eq!(h.rows().expect("rows")[3].command, "restore a of version 1");
        // A frame the version lacks, and a version at another scale, are refused.
        let e = h
            .restore_frames(0, Some(&["b.png".to_string()]))
            .expect_err("b not in v0");
        assert!(e.to_string().contains("no pose for frame b.png"), "{e}");
        h.update("rescale", |pf| {
            pf.scale = 0.4;
            for e in pf.frames.values_mut() {
                if let Some(p) = e.object_pose.as_mut() {
                    p.scale = Some(0.4);
                }
            }
            Ok::<(), HistoryError>(())
        })
        .expect("update");
        let e = h
            .restore_frames(1, Some(&["a.png".to_string()]))
            .expect_err("scale");
        assert!(e.to_string().contains("scale 0.2"), "{e}");
        // One frame across the versions: where it changed and where it came back.
        let rows = h.frame_versions("a").expect("frame versions");
        let xs: Vec<Option<f64>> = rows
            .iter()
            .map(|r| r.pose.as_ref().map(|p| p.translation[0]))
            .collect();
        assert_eq!(xs, [Some(0.0), Some(1.0), Some(2.0), Some(1.0), Some(1.0)]);
        let same: Vec<Option<u64>> = rows.iter().map(|r| r.same_as).collect();
        // v3 restored v1's pose; v4 changed the scale, so it is a pose of its own.
        assert_eq!(same, [None, None, None, Some(1), None]);
    }

    #[test]
    fn a_whole_file_write_starts_or_extends_the_history_and_never_clobbers() {
        let dir = tempfile::tempdir().expect("tmp");
        let src = PoseFile::read(&pose_file(dir.path())).expect("read");
        // No file yet: the write is version 0.
        let fresh = PoseHistory::new(&dir.path().join("out/tracked.json"));
        assert_eq!(fresh.write(&src, "track").expect("write"), 0);
        assert_eq!(fresh.rows().expect("rows")[0].command, "track");
        // An existing file without a history becomes version 0 first.
        let h = PoseHistory::new(&dir.path().join("pose.json"));
        let mut tracked = src.clone();
        moved_to(&mut tracked, "a.png", 3.0);
        assert_eq!(h.write(&tracked, "track again").expect("write"), 1);
        assert_eq!(h.rows().expect("rows")[0].command, INITIAL);
        // Something that is not a pose file is left as it is.
        let junk = dir.path().join("junk.json");
        std::fs::write(&junk, "{\"not\": 1}").expect("w");
        let e = PoseHistory::new(&junk).write(&src, "x").expect_err("junk");
        assert!(e.to_string().contains("not a pose file"), "{e}");
        assert_eq!(std::fs::read_to_string(&junk).expect("r"), "{\"not\": 1}");
    }

    /// Two writers each stopped between recording a version and writing the file leave the
    /// file two versions behind; the next change records the file as found first, so the
    /// newest version is the file again (and, stopped once more, the one before it).
    #[test]
    fn a_change_after_interrupted_writes_records_the_file_as_found() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = pose_file(dir.path());
        let pf = PoseFile::read(&p).expect("read");
        let h = PoseHistory::new(&p);
        h.update::<_, HistoryError>("first", |_| Ok(()))
            .expect("update");
        // Stopped between the two, twice: versions the file never held.
        for cmd in ["lost 1", "lost 2"] {
            let lock = h.lock().expect("lock");
            let mut moved = pf.clone();
            moved.scale *= 2.0;
            h.record(&lock, &moved, cmd).expect("record");
        }
        h.update::<_, HistoryError>("next", |_| Ok(()))
            .expect("update");
        let rows = h.rows().expect("rows");
        let commands: Vec<&str> = rows.iter().map(|r| r.command.as_str()).collect();
        assert_eq!(commands.len(), 6, "{commands:?}");
        assert!(
            commands[4].starts_with(FOUND) && commands[4].contains("version 3"),
            "{commands:?}"
        );
        assert_eq!(commands[5], "next");
        let newest = PoseHistory::read_entry(&h.versions().expect("v")[5].1).expect("entry");
        assert_eq!(newest.pose, PoseFile::read(&p).expect("read"));
        // Nothing out of step: no version as found.
        h.update::<_, HistoryError>("again", |_| Ok(()))
            .expect("update");
        assert_eq!(h.rows().expect("rows").len(), 7);
    }

    #[test]
    fn a_step_tag_reads_back_from_a_command_and_nothing_else_does() {
        let tag = StepTag {
            step: 18,
            pid: 4242,
        };
        let command = format!("agentstar pose commit --poses=p.json [step {tag}]");
        assert_eq!(StepTag::in_command(&command), Some(tag));
        assert_eq!(StepTag::from_env(&tag.to_string()), Some(tag));
        for other in [
            "agentstar pose commit --poses=p.json",
            INITIAL,
            "restore version 3",
            "x [step 1 of process]",
            "x [step a of process 2]",
        ] {
            assert_eq!(StepTag::in_command(other), None, "{other}");
        }
    }
}
