//! Running the `colmap` executable: finding it, one stage at a time under a deadline, its
//! output kept in a log file and read line by line for progress.

use crate::SfmError;
use std::ffi::OsString;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How to install COLMAP, for the message when it is missing.
pub const INSTALL_HINT: &str = "install COLMAP: `apt install colmap` (Debian, Ubuntu), `brew install colmap` (macOS), `conda install -c conda-forge colmap`, or a release from https://github.com/colmap/colmap/releases; set AGENTSTAR_COLMAP to the executable when it is not on PATH";

/// The longest `colmap help` may take to answer.
pub const PROBE_LIMIT: Duration = Duration::from_secs(30);
/// The most of the probe's output kept (COLMAP's help is a few kilobytes).
const PROBE_BYTES: u64 = 1 << 20;

/// Runs `program help` until it exits or `limit` passes (then it is killed): its exit status
/// and (at most [`PROBE_BYTES`] of) its stdout.
fn probe(program: &Path, limit: Duration) -> Result<(std::process::ExitStatus, Vec<u8>), SfmError> {
    let missing = |reason: String| SfmError::ColmapMissing {
        program: program.to_path_buf(),
        reason,
    };
    let mut child = Command::new(program)
        .arg("help")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .env("QT_QPA_PLATFORM", "offscreen")
        .spawn()
        .map_err(|e| missing(e.to_string()))?;
    // Read on a thread: a child of the program may hold the pipe open after it is killed,
    // and the reader is then left behind rather than waited for.
    let (tx, rx) = mpsc::channel::<Vec<u8>>();
    if let Some(out) = child.stdout.take() {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            let _ = out.take(PROBE_BYTES).read_to_end(&mut buf);
            let _ = tx.send(buf);
        });
    }
    let deadline = Instant::now() + limit;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) => {}
            Err(e) => return Err(missing(e.to_string())),
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Err(SfmError::ProbeTimedOut {
                program: program.to_path_buf(),
                seconds: limit.as_secs_f64(),
            });
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    // The program exited; its output is whole once the pipe closes (bounded wait).
    let stdout = rx
        .recv_timeout(Duration::from_secs(2).min(limit.max(Duration::from_millis(200))))
        .unwrap_or_default();
    Ok((status, stdout))
}

/// Lines of output kept in memory for error messages (the whole output is in the log).
const TAIL_LINES: usize = 15;
/// Longest line kept (bytes); COLMAP's lines are short, so longer ones are cut.
const MAX_LINE: usize = 4096;

/// A COLMAP executable that answered `colmap help`.
#[derive(Debug, Clone)]
pub struct Colmap {
    pub program: PathBuf,
    /// The first line of `colmap help`, e.g. `COLMAP 3.8 -- Structure-from-Motion …`.
    pub version: String,
    /// Whether the banner says it was built with CUDA (`… with CUDA`, not `without CUDA`).
    pub cuda: bool,
}

/// Whether this machine shows an NVIDIA device (`/dev/nvidia0`, or a GPU listed by the
/// driver under `/proc/driver/nvidia/gpus`).
pub fn nvidia_device_present() -> bool {
    Path::new("/dev/nvidia0").exists()
        || std::fs::read_dir("/proc/driver/nvidia/gpus")
            .map(|mut d| d.next().is_some())
            .unwrap_or(false)
}

/// Whether a banner of `colmap help` names a CUDA build.
pub fn banner_has_cuda(banner: &str) -> bool {
    banner.contains("with CUDA") && !banner.contains("without CUDA")
}

impl Colmap {
    /// Finds COLMAP: `explicit`, else `$AGENTSTAR_COLMAP`, else `colmap` on PATH; the probe
    /// (`colmap help`) gets at most [`PROBE_LIMIT`].
    pub fn find(explicit: Option<&Path>) -> Result<Colmap, SfmError> {
        Colmap::find_within(explicit, PROBE_LIMIT)
    }

    /// As [`Colmap::find`], with the probe stopped after `limit`: a program that does not
    /// answer `help` (a hung COLMAP, a wrapper waiting for a display or a licence) is an
    /// error that names the probe, never a hang.
    pub fn find_within(explicit: Option<&Path>, limit: Duration) -> Result<Colmap, SfmError> {
        let program = explicit
            .map(Path::to_path_buf)
            .or_else(|| std::env::var_os("AGENTSTAR_COLMAP").map(PathBuf::from))
            .unwrap_or_else(|| PathBuf::from("colmap"));
        let (status, stdout) = probe(&program, limit)?;
        let text = String::from_utf8_lossy(&stdout);
        let version = text
            .lines()
            .map(str::trim)
            .find(|l| l.starts_with("COLMAP"))
            .map(|l| l.split(" -- ").next().unwrap_or(l).trim().to_string())
            .ok_or_else(|| SfmError::ColmapMissing {
                program: program.clone(),
                reason: format!(
                    "`{} help` did not print COLMAP's banner (exit {status})",
                    program.display(),
                ),
            })?;
        let cuda = banner_has_cuda(&text);
        Ok(Colmap {
            program,
            version,
            cuda,
        })
    }

    /// Runs `colmap COMMAND ARGS…` until it exits or `deadline` passes (then it is killed).
    /// Every line it prints goes to `log` and to `on_line`. Fails with the stage's name, its
    /// exit status and the last lines of its output.
    pub fn run(
        &self,
        command: &str,
        args: &[OsString],
        log: &Path,
        deadline: Instant,
        on_line: &mut dyn FnMut(&str),
    ) -> Result<(), SfmError> {
        let mut file = std::fs::File::create(log).map_err(|e| SfmError::io(log, e))?;
        let _ = writeln!(
            file,
            "$ {} {command} {}",
            self.program.display(),
            args.iter()
                .map(|a| a.to_string_lossy())
                .collect::<Vec<_>>()
                .join(" ")
        );
        let mut child = Command::new(&self.program)
            .arg(command)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            // The CPU paths need no display; Qt must not look for one.
            .env("QT_QPA_PLATFORM", "offscreen")
            .spawn()
            .map_err(|e| SfmError::ColmapMissing {
                program: self.program.clone(),
                reason: e.to_string(),
            })?;
        let (tx, rx) = mpsc::channel::<String>();
        let mut readers = vec![];
        if let Some(out) = child.stdout.take() {
            readers.push(spawn_reader(out, tx.clone()));
        }
        if let Some(err) = child.stderr.take() {
            readers.push(spawn_reader(err, tx.clone()));
        }
        drop(tx);
        let mut tail: std::collections::VecDeque<String> = Default::default();
        let mut timed_out = false;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                timed_out = true;
                let _ = child.kill();
                break;
            }
            match rx.recv_timeout(left.min(Duration::from_millis(200))) {
                Ok(line) => {
                    let _ = writeln!(file, "{line}");
                    on_line(&line);
                    if tail.len() == TAIL_LINES {
                        tail.pop_front();
                    }
                    tail.push_back(line);
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        let status = child.wait().map_err(|e| SfmError::io(&self.program, e))?;
        for r in readers {
            let _ = r.join();
        }
        let _ = file.flush();
        if timed_out {
            return Err(SfmError::TimedOut {
                stage: command.to_string(),
                command: command.to_string(),
                limit_s: 0.0,
                log: log.to_path_buf(),
            });
        }
        if !status.success() {
            return Err(SfmError::ToolFailed {
                stage: command.to_string(),
                status: status.to_string(),
                log: log.to_path_buf(),
                tail: tail.into_iter().collect::<Vec<_>>().join("\n"),
            });
        }
        Ok(())
    }
}

fn spawn_reader(
    stream: impl Read + Send + 'static,
    tx: mpsc::Sender<String>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let mut reader = BufReader::new(stream);
        let mut buf = Vec::new();
        loop {
            buf.clear();
            match reader.read_until(b'\n', &mut buf) {
                Ok(0) | Err(_) => break,
                Ok(_) => {
                    buf.truncate(MAX_LINE);
                    let line = String::from_utf8_lossy(&buf).trim_end().to_string();
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            }
        }
    })
}

/// `[i/N]` in a line that starts with `prefix` (after spaces): COLMAP's progress lines
/// (`Processed file [3/40]`, `Matching image [3/40]`, `Matching block [1/2, 1/2]`).
pub fn progress_in(line: &str, prefix: &str) -> Option<(u64, u64)> {
    let rest = line.trim_start().strip_prefix(prefix)?;
    let open = rest.find('[')?;
    let inner = &rest[open + 1..];
    let close = inner.find([']', ','])?;
    let (i, n) = inner[..close].split_once('/')?;
    Some((i.trim().parse().ok()?, n.trim().parse().ok()?))
}

/// Feature counts per image from `feature_extractor`'s output (`Name: …` then `Features: N`).
#[derive(Debug, Default)]
pub struct FeatureCounts {
    current: Option<String>,
    pub by_name: Vec<(String, usize)>,
}

impl FeatureCounts {
    pub fn line(&mut self, line: &str) {
        let l = line.trim();
        if let Some(name) = l.strip_prefix("Name:") {
            self.current = Some(name.trim().to_string());
        } else if let Some(n) = l.strip_prefix("Features:") {
            if let (Some(name), Ok(n)) = (self.current.take(), n.trim().parse()) {
                self.by_name.push((name, n));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_lines_are_read() {
        assert_eq!(
            progress_in("Processed file [3/40]", "Processed file"),
            Some((3, 40))
        );
        assert_eq!(
            progress_in("Matching block [1/2, 2/2] in 1.2s", "Matching block"),
            Some((1, 2))
        );
        assert_eq!(
            progress_in("  Matching image [12/40] in 0.5s", "Matching image"),
            Some((12, 40))
        );
        assert_eq!(progress_in("Features: 12", "Processed file"), None);
    }

    #[test]
    fn feature_counts_pair_names_and_counts() {
        let mut c = FeatureCounts::default();
        for l in [
            "Processed file [1/2]",
            "  Name:            000000.png",
            "  Dimensions:      320 x 240",
            "  Features:        588",
            "Processed file [2/2]",
            "  Name:            000001.png",
            "  Features:        12",
        ] {
            c.line(l);
        }
        assert_eq!(
            c.by_name,
            vec![("000000.png".into(), 588), ("000001.png".into(), 12)]
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_colmap_that_does_not_answer_the_probe_is_stopped_in_time() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().expect("tmp");
        let fake = dir.path().join("colmap");
        std::fs::write(&fake, "#!/bin/sh\nsleep 30\n").expect("write");
        std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).expect("chmod");
        let t0 = Instant::now();
        let e = Colmap::find_within(Some(&fake), Duration::from_millis(500)).expect_err("hung");
        assert!(t0.elapsed() < Duration::from_secs(5), "{:?}", t0.elapsed());
        let m = e.to_string();
        assert!(m.contains("help") && m.contains("did not answer"), "{m}");
        // One that answers is found, with its banner's first words as the version.
        let ok = dir.path().join("colmap-ok");
        std::fs::write(
            &ok,
            "#!/bin/sh\necho 'COLMAP 3.9 -- Structure-from-Motion and Multi-View Stereo'\n",
        )
        .expect("write");
        std::fs::set_permissions(&ok, std::fs::Permissions::from_mode(0o755)).expect("chmod");
        let c = Colmap::find_within(Some(&ok), Duration::from_secs(10)).expect("found");
        assert_eq!(c.version, "COLMAP 3.9");
        assert!(!c.cuda, "no build line: no CUDA");
    }

    #[test]
    fn the_banner_says_whether_colmap_has_cuda() {
        assert!(banner_has_cuda(
            "COLMAP 3.8 -- Structure-from-Motion\n(Commit 1 on 2023-01-31 with CUDA)"
        ));
        assert!(!banner_has_cuda(
            "COLMAP 3.8 -- Structure-from-Motion\n(Commit Unknown on Unknown without CUDA)"
        ));
    }

    #[test]
    fn a_missing_program_says_how_to_install_colmap() {
        let e = Colmap::find(Some(Path::new("/nonexistent/colmap"))).expect_err("missing");
        let m = e.to_string();
        assert!(
            m.contains("apt install colmap") && m.contains("/nonexistent/colmap"),
            "{m}"
        );
    }
}
