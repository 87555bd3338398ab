//! Committed versions of a pose file (`.agentstar/history/STEM/NNNNNN.json` beside it) and
//! the one way to change a pose file that keeps them: [`PoseHistory::update`].
//!
//! Every change (a `pose commit`, a restore, the tracker's result, a shape step's joint
//! reconciliation) holds an exclusive lock on `.agentstar/STEM.lock` for its whole
//! read-modify-write, across threads and processes (`agentstar pose commit` from a shell
//! and an MCP server on the same run serialise on it). Version numbers are allocated under
//! that lock and each version file is created with a no-replace link, so two writers can
//! never claim the same number.

use crate::reports::{HistoryEntry, HistoryRow};
use crate::{AgentError, Result};
use agentstar_data::posefile::PoseFile;
use agentstar_data::DataError;
use std::io::Write;
use std::path::{Path, PathBuf};

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
        let base = self.base();
        std::fs::create_dir_all(&base).map_err(|e| DataError::io(&base, e))?;
        let path = base.join(format!("{}.lock", self.stem()));
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| DataError::io(&path, e))?;
        file.lock().map_err(|e| DataError::io(&path, e))?;
        Ok(PoseLock { file })
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

    /// Reads version file `path`.
    pub fn read_entry(path: &Path) -> Result<HistoryEntry> {
        let text = agentstar_data::read_text(path)?;
        serde_json::from_str(&text).map_err(|e| {
            AgentError::Data(DataError::invalid(
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
                .prefix(".agentstar-")
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

    /// Changes the pose file under its lock: reads it, applies `change`, writes it
    /// atomically and records the result as a new version (the file as it was becomes
    /// version 0 when there is no history yet). Returns `change`'s value and the version.
    pub fn update<T>(
        &self,
        command: &str,
        change: impl FnOnce(&mut PoseFile) -> Result<T>,
    ) -> Result<(T, u64)> {
        let lock = self.lock()?;
        let mut pf = PoseFile::read(&self.poses)?;
        if self.versions()?.is_empty() {
            self.record(&lock, &pf, "initial version (before the first commit)")?;
        }
        let out = change(&mut pf)?;
        pf.write(&self.poses)?;
        let v = self.record(&lock, &pf, command)?;
        Ok((out, v))
    }

    /// Like [`PoseHistory::update`], but writes and records only when `change` changed
    /// the file; returns the version when it did.
    pub fn update_if_changed<T>(
        &self,
        command: &str,
        change: impl FnOnce(&mut PoseFile) -> Result<T>,
    ) -> Result<(T, Option<u64>)> {
        let lock = self.lock()?;
        let before = PoseFile::read(&self.poses)?;
        let mut pf = before.clone();
        let out = change(&mut pf)?;
        if pf == before {
            return Ok((out, None));
        }
        if self.versions()?.is_empty() {
            self.record(&lock, &before, "initial version (before the first commit)")?;
        }
        pf.write(&self.poses)?;
        let v = self.record(&lock, &pf, command)?;
        Ok((out, Some(v)))
    }

    /// Replaces the pose file with `pose` (recorded as a new version).
    pub fn replace(&self, pose: PoseFile, command: &str) -> Result<u64> {
        self.update(command, |pf| {
            *pf = pose;
            Ok(())
        })
        .map(|(_, v)| v)
    }

    /// Makes version `version` current again (recorded as a new version).
    pub fn restore(&self, version: u64) -> Result<u64> {
        let list = self.versions()?;
        let Some((_, path)) = list.iter().find(|(n, _)| *n == version) else {
            return Err(AgentError::Invalid(format!(
                "no version {version} of {}; versions are {:?}",
                self.poses.display(),
                list.iter().map(|(n, _)| *n).collect::<Vec<_>>()
            )));
        };
        let entry = Self::read_entry(path)?;
        self.replace(entry.pose, &format!("restore version {version}"))
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
                            Ok(())
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
            Ok(())
        })
        .expect("update");
        assert_eq!(h.restore(0).expect("restore"), 2);
        assert_eq!(PoseFile::read(h.poses()).expect("read").scale, 0.2);
    }
}
