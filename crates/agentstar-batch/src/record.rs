//! A job's record (`jobs/NAME/record.json`): every attempt to run it, written by the job
//! itself when it starts and when its command ends, so that the files say what happened
//! even where no scheduler is left to ask.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Who started an attempt.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Runner {
    /// `agentstar batch local` or a direct `agentstar batch exec`.
    Local,
    /// A Slurm array task.
    Slurm { job_id: u64, task_id: u64 },
}

/// How a command ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Exit {
    /// It exited with this status.
    Code(i32),
    /// A signal ended it.
    Signal(i32),
}

impl Exit {
    pub fn success(self) -> bool {
        self == Exit::Code(0)
    }
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Exit::Code(c) => write!(f, "exit {c}"),
            Exit::Signal(s) => write!(f, "signal {s}"),
        }
    }
}

/// A file a job produced, as it was when the attempt that made it finished: what later
/// checks compare the file with, so that a result truncated, emptied, deleted or swapped
/// after the job finished is not taken for the job's.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputDigest {
    /// Relative to the batch directory (`jobs/NAME/pose.json`).
    pub path: PathBuf,
    pub bytes: u64,
    /// SHA-256 of the contents, lowercase hexadecimal.
    pub sha256: String,
}

/// What a file of a finished job is now, compared with its digest.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OutputNow {
    /// It cannot be read (gone, or not a regular file).
    Missing,
    /// Its size and digest now.
    Present { bytes: u64, sha256: String },
}

impl OutputDigest {
    /// Why the file no longer is what the job left, or `None` when it is.
    pub fn damage(&self, now: &OutputNow) -> Option<String> {
        let p = self.path.display();
        match now {
            OutputNow::Missing => Some(format!("{p} was deleted after the job finished")),
            OutputNow::Present { bytes: 0, .. } if self.bytes > 0 => {
                Some(format!("{p} was emptied after the job finished"))
            }
            OutputNow::Present { bytes, sha256 } if *bytes != self.bytes || *sha256 != self.sha256 => {
                Some(format!(
                    "{p} was changed after the job finished (truncated, rewritten or swapped: {bytes} bytes now, {} then, and its SHA-256 differs from the one recorded)",
                    self.bytes
                ))
            }
            OutputNow::Present { .. } => None,
        }
    }
}

/// One attempt at a job.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Attempt {
    pub runner: Runner,
    pub host: String,
    /// The process that supervises the command (`agentstar batch exec`).
    pub pid: u32,
    /// The command's process, once started.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub child_pid: Option<u32>,
    /// Seconds since the Unix epoch.
    pub started_unix_s: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ended_unix_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exit: Option<Exit>,
    /// The job's result files as this attempt left them (recorded when it finished).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<OutputDigest>,
}

impl Attempt {
    /// Seconds it ran, once it ended.
    pub fn wall_s(&self) -> Option<f64> {
        self.ended_unix_s
            .map(|e| (e - self.started_unix_s).max(0.0))
    }
}

/// Every attempt at one job, oldest first.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobRecord {
    pub attempts: Vec<Attempt>,
}

impl JobRecord {
    pub fn last(&self) -> Option<&Attempt> {
        self.attempts.last()
    }

    /// Whether the last attempt ended with status 0.
    pub fn finished(&self) -> bool {
        self.last().and_then(|a| a.exit).is_some_and(Exit::success)
    }

    /// Seconds of every attempt that ended, together (what the batch spent on the job).
    pub fn total_wall_s(&self) -> f64 {
        self.attempts.iter().filter_map(Attempt::wall_s).sum()
    }

    /// Starts a new attempt (the previous one, if it never ended, stays as it was: cut).
    pub fn start(&mut self, runner: Runner, host: &str, pid: u32, now_unix_s: f64) {
        self.attempts.push(Attempt {
            runner,
            host: host.to_string(),
            pid,
            child_pid: None,
            started_unix_s: now_unix_s,
            ended_unix_s: None,
            exit: None,
            outputs: vec![],
        });
    }

    /// Ends the last attempt.
    pub fn end(&mut self, exit: Exit, now_unix_s: f64) {
        if let Some(a) = self.attempts.last_mut() {
            a.exit = Some(exit);
            a.ended_unix_s = Some(now_unix_s);
        }
    }

    /// Ends the last attempt with the digests of the files it left.
    pub fn end_with(&mut self, exit: Exit, now_unix_s: f64, outputs: Vec<OutputDigest>) {
        self.end(exit, now_unix_s);
        if let Some(a) = self.attempts.last_mut() {
            a.outputs = outputs;
        }
    }

    /// The digests the finishing attempt recorded (none for a job that has not finished, or
    /// that finished before digests were recorded).
    pub fn outputs(&self) -> &[OutputDigest] {
        match self.last() {
            Some(a) if self.finished() => &a.outputs,
            _ => &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attempts_accumulate_and_the_last_decides() {
        let mut r = JobRecord::default();
        assert!(!r.finished());
        r.start(Runner::Local, "h", 10, 100.0);
        r.end(Exit::Signal(9), 130.0);
        assert!(!r.finished());
        r.start(
            Runner::Slurm {
                job_id: 7,
                task_id: 2,
            },
            "h",
            11,
            200.0,
        );
        assert_eq!(r.last().and_then(Attempt::wall_s), None);
        r.end(Exit::Code(0), 250.5);
        assert!(r.finished());
        assert!((r.total_wall_s() - 80.5).abs() < 1e-9);
        let text = serde_json::to_string(&r).expect("json");
        assert!(text.contains(r#""runner":{"kind":"slurm","job_id":7,"task_id":2}"#));
        assert!(text.contains(r#""exit":{"signal":9}"#));
        let back: JobRecord = serde_json::from_str(&text).expect("parse");
        assert_eq!(back, r);
        assert_eq!(Exit::Code(3).to_string(), "exit 3");
        // A record without digests (written before they were) still reads.
        assert!(r.outputs().is_empty());
    }

    #[test]
    fn a_finished_jobs_outputs_are_compared_with_their_digests() {
        let d = OutputDigest {
            path: "jobs/a/pose.json".into(),
            bytes: 100,
            sha256: "ab".into(),
        };
        let mut r = JobRecord::default();
        r.start(Runner::Local, "h", 1, 0.0);
        r.end_with(Exit::Code(0), 1.0, vec![d.clone()]);
        assert_eq!(r.outputs(), std::slice::from_ref(&d));
        let text = serde_json::to_string(&r).expect("json");
        assert_eq!(serde_json::from_str::<JobRecord>(&text).expect("parse"), r);
        let same = OutputNow::Present {
            bytes: 100,
            sha256: "ab".into(),
        };
        assert_eq!(d.damage(&same), None);
        for (now, word) in [
            (OutputNow::Missing, "deleted"),
            (
                OutputNow::Present {
                    bytes: 0,
                    sha256: "e3".into(),
                },
                "emptied",
            ),
            (
                OutputNow::Present {
                    bytes: 40,
                    sha256: "cd".into(),
                },
                "changed",
            ),
            (
                OutputNow::Present {
                    bytes: 100,
                    sha256: "cd".into(),
                },
                "changed",
            ),
        ] {
            let why = d.damage(&now).expect(word);
            assert!(
                why.contains(word) && why.contains("jobs/a/pose.json"),
                "{why}"
            );
        }
    }
}
