//! Running the `agentstar` executable for a tool: one runner of child processes with a
//! bounded output, its last stderr line as the call's activity, and the verb runner
//! ([`Toolbox::cli`]) every view and search tool uses.

use super::*;
use crate::{AgentError, Result};
use agentstar_requests::Output;
use std::path::PathBuf;
use std::process::Command;
use std::sync::{Arc, Mutex};

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
    /// The ledger step whose tool runs on this thread.
    static STEP: std::cell::Cell<Option<u64>> = const { std::cell::Cell::new(None) };
}

/// Runs `f` with the child commands it starts on this thread told the step they serve
/// (`AGENTSTAR_STEP`, which `agentstar_data::history::command_line` records with a version).
pub(super) fn with_step<T>(step: u64, f: impl FnOnce() -> T) -> T {
    struct Reset(Option<u64>);
    impl Drop for Reset {
        fn drop(&mut self) {
            STEP.with(|s| s.set(self.0));
        }
    }
    let _reset = Reset(STEP.with(|s| s.replace(Some(step))));
    f()
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
pub(super) const ACTIVITY_LINE_BYTES: usize = 300;

/// A reader that hands each complete line it passes through to an [`Activity`].
pub(super) struct LastLine<R> {
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

pub(super) fn read_capped(r: impl std::io::Read) -> String {
    read_capped_to(r, MAX_TOOL_OUTPUT_BYTES)
}

pub(super) fn read_capped_to(mut r: impl std::io::Read, cap: usize) -> String {
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

/// An optional text argument as the command should see it: absent when blank, trimmed.
pub(super) fn nonblank(value: &Option<String>) -> Option<&str> {
    value.as_deref().map(str::trim).filter(|v| !v.is_empty())
}

/// A child command of the `agentstar` executable: its words (the subcommand and its
/// positional arguments), then the flags of its typed request parts, each turned into
/// arguments by [`agentstar_requests::to_args`]. No tool writes flag text by hand; the
/// binary's `tool_args` test parses what every tool builds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Invocation {
    args: Vec<String>,
}

impl Invocation {
    pub fn new<S: AsRef<str>>(words: &[S]) -> Invocation {
        Invocation {
            args: words.iter().map(|w| w.as_ref().to_string()).collect(),
        }
    }

    /// Appends the flags of one typed part of the request.
    pub fn with(mut self, part: &impl serde::Serialize) -> Result<Invocation> {
        let flags = agentstar_requests::to_args(part)
            .map_err(|e| AgentError::Tool(format!("{}: {e}", self.args.join(" "))))?;
        self.args.extend(flags);
        Ok(self)
    }

    pub fn args(&self) -> &[String] {
        &self.args
    }
}

/// A failed child command's stderr as the call's error: without the lines the commands
/// print for a person at a terminal before they start (`note: …`, such as how many in-between
/// frames the capture holds besides its keyframes), which read as the error's first line;
/// all of it where nothing else is left (a child that died without a word of its own).
pub(super) fn failure_text(stderr: &str) -> String {
    let error = stderr
        .lines()
        .filter(|l| !l.starts_with("note: "))
        .collect::<Vec<_>>()
        .join("\n")
        .trim()
        .to_string();
    if error.is_empty() {
        stderr.trim().to_string()
    } else {
        error
    }
}

impl Toolbox {
    /// Runs the executable (the one runner of every child tool); returns (success,
    /// stdout, stderr). A child that runs past `timeout_s` is killed.
    pub fn exec(&self, args: &[String]) -> Result<(bool, String, String)> {
        let mut command = Command::new(&self.exe);
        if let Some(step) = STEP.with(|s| s.get()) {
            command.env(
                agentstar_data::history::STEP_ENV,
                agentstar_data::history::StepTag::of_this_process(step).to_string(),
            );
        }
        let mut child = command
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

    /// Runs `verb` with the session's inputs and `--out` the step's directory.
    pub(super) fn cli(
        &self,
        verb: &[&str],
        step: u64,
        tool: &str,
        request: &impl serde::Serialize,
    ) -> Result<(ToolOutput, PathBuf, String)> {
        let out = self.run.step_dir(step, tool);
        let call = Invocation::new(verb)
            .with(&self.session())?
            .with(&Output {
                out: out.clone(),
                json: true,
            })?
            .with(request)?;
        let (ok, stdout, stderr) = self.exec(call.args())?;
        if !ok {
            return Ok((ToolOutput::error(failure_text(&stderr)), out, stdout));
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
}
