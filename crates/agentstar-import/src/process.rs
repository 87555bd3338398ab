//! Child processes under a deadline: every program agentstar runs (`ffmpeg`, `ffprobe`, an
//! agent's `--version` probe) is killed when it runs past its limit, so a program that does
//! not answer can never hang a command. Its output is read on threads while it runs (no pipe
//! fills and stalls it) and kept up to a bound.

use std::io::Read;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The most of a child's stdout or stderr that is kept (the rest is read and dropped).
pub const MAX_OUTPUT_BYTES: usize = 64 << 20;

/// How long a probe (`ffprobe`, `PROGRAM --version`) may take.
pub const PROBE_LIMIT: Duration = Duration::from_secs(30);

/// Runs `command` (stdin closed) until it exits or `limit` passes. `Err` with
/// [`std::io::ErrorKind::TimedOut`] when it ran past the limit (it is killed), or the error
/// of starting it.
pub fn output_within(command: &mut Command, limit: Duration) -> std::io::Result<Output> {
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let read_all = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut kept = Vec::new();
            if let Some(mut pipe) = pipe {
                let mut buf = [0u8; 64 * 1024];
                loop {
                    match pipe.read(&mut buf) {
                        Ok(0) => break,
                        Ok(n) => {
                            let room = MAX_OUTPUT_BYTES.saturating_sub(kept.len());
                            kept.extend_from_slice(&buf[..n.min(room)]);
                        }
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(_) => break,
                    }
                }
            }
            kept
        })
    };
    let stdout = read_all(
        child
            .stdout
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let stderr = read_all(
        child
            .stderr
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let deadline = Instant::now() + limit;
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!(
                    "did not finish within {:.0} s and was stopped",
                    limit.as_secs_f64()
                ),
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Ok(Output {
        status,
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_child_past_its_limit_is_stopped_and_one_within_it_answers() {
        let t0 = Instant::now();
        let e = output_within(Command::new("sleep").arg("30"), Duration::from_millis(300))
            .expect_err("sleep outlives its limit");
        assert_eq!(e.kind(), std::io::ErrorKind::TimedOut, "{e}");
        assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", t0.elapsed());
        let out = output_within(
            Command::new("sh").args(["-c", "echo out; echo err >&2"]),
            Duration::from_secs(30),
        )
        .expect("sh");
        assert!(out.status.success());
        assert_eq!(String::from_utf8_lossy(&out.stdout), "out\n");
        assert_eq!(String::from_utf8_lossy(&out.stderr), "err\n");
        let e = output_within(
            &mut Command::new("/nonexistent/program"),
            Duration::from_secs(1),
        )
        .expect_err("missing");
        assert_eq!(e.kind(), std::io::ErrorKind::NotFound);
    }
}
