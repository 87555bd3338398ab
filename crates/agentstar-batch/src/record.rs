//! A job's record (`jobs/NAME/record.json`): every attempt to run it, written by the job
//! itself when it starts and when its command ends, so that the files say what happened
//! even where no scheduler is left to ask.

use serde::{Deserialize, Serialize};

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
        });
    }

    /// Ends the last attempt.
    pub fn end(&mut self, exit: Exit, now_unix_s: f64) {
        if let Some(a) = self.attempts.last_mut() {
            a.exit = Some(exit);
            a.ended_unix_s = Some(now_unix_s);
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
    }
}
