//! Atomic writes: a temporary file in the destination directory, flushed, then renamed over
//! the destination, so readers see the old file or the new one and never a partial one.
//!
//! A temporary is named `.agentstar-<pid>-XXXXXX.tmp` after the process writing it. A process
//! killed mid-write (`kill -9`) cannot remove its temporary; the next write into the same
//! directory removes temporaries whose process is gone (on systems with `/proc`).

use crate::{DataError, Result};
use std::io::Write;
use std::path::Path;

pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).map_err(|e| DataError::io(dir, e))?;
    remove_stale_temporaries(dir);
    let mut tmp = tempfile::Builder::new()
        .prefix(&temporary_prefix())
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| DataError::io(dir, e))?;
    tmp.write_all(bytes).map_err(|e| DataError::io(path, e))?;
    // Temporary files are private; results are ordinary readable files.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(|e| DataError::io(path, e))?;
    }
    tmp.as_file()
        .sync_all()
        .map_err(|e| DataError::io(path, e))?;
    tmp.persist(path)
        .map_err(|e| DataError::io(path, e.error))?;
    Ok(())
}

/// The start of this process's temporaries' names, `.agentstar-<pid>-` (with the suffix
/// `.tmp`), for writers that cannot use [`write_atomic`] (a link that must not replace):
/// with it and [`remove_stale_temporaries`], what a killed writer leaves is removed too.
pub fn temporary_prefix() -> String {
    format!(".agentstar-{}-", std::process::id())
}

/// Removes `.agentstar-<pid>-*.tmp` files left in `dir` by processes that no longer run, once
/// per directory and process. Best effort: errors are ignored, and nothing is removed where
/// `/proc` cannot tell which processes run.
pub fn remove_stale_temporaries(dir: &Path) {
    use std::collections::HashSet;
    use std::sync::{Mutex, OnceLock};
    static SWEPT: OnceLock<Mutex<HashSet<std::path::PathBuf>>> = OnceLock::new();
    let proc = Path::new("/proc/self");
    if !proc.exists() {
        return;
    }
    {
        let mut swept = SWEPT
            .get_or_init(|| Mutex::new(HashSet::new()))
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if !swept.insert(dir.to_path_buf()) {
            return;
        }
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let me = std::process::id();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(pid) = stale_pid(name) else { continue };
        if pid != me && !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The writer's process id in a temporary's name `.agentstar-<pid>-XXXXXX.tmp`.
fn stale_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(".agentstar-")?.strip_suffix(".tmp")?;
    rest.split_once('-')?.0.parse().ok()
}

pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<()> {
    let mut text = serde_json::to_string_pretty(value)
        .map_err(|e| DataError::invalid(path, format!("cannot serialise: {e}")))?;
    text.push('\n');
    write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporaries_of_dead_processes_are_removed() {
        let dir = tempfile::tempdir().expect("tempdir");
        // No process has this id (above any pid_max); our own temporaries stay.
        let stale = dir.path().join(".agentstar-999999999-Ab12Cd.tmp");
        let live = dir
            .path()
            .join(format!(".agentstar-{}-Zz99Yy.tmp", std::process::id()));
        let other = dir.path().join(".agentstar-notapid.tmp");
        for p in [&stale, &live, &other] {
            std::fs::write(p, b"half").expect("write");
        }
        write_atomic(&dir.path().join("pose.json"), b"{}").expect("write");
        if Path::new("/proc/self").exists() {
            assert!(!stale.exists(), "the dead writer's temporary is removed");
        }
        assert!(live.exists() && other.exists());
        assert_eq!(stale_pid(".agentstar-123-abc.tmp"), Some(123));
        assert_eq!(stale_pid(".agentstar-abc.tmp"), None);
    }

    #[test]
    fn replaces_whole_files_and_leaves_no_temporaries() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("sub/a.txt");
        write_atomic(&p, b"first").expect("write");
        write_atomic(&p, b"second").expect("write");
        assert_eq!(std::fs::read(&p).expect("read"), b"second");
        let names: Vec<_> = std::fs::read_dir(p.parent().expect("dir"))
            .expect("ls")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&p).expect("meta").permissions().mode() & 0o777;
            assert_eq!(mode, 0o644, "results are readable by others");
        }
    }
}
