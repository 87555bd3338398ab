//! A job's state, from its record and from what the scheduler says, when it says anything.

use crate::record::{Exit, JobRecord};
use serde::Serialize;

/// Where a job stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "state", rename_all = "lowercase")]
pub enum JobState {
    /// Never started, not queued.
    Pending,
    /// Waiting in the scheduler's queue.
    Queued,
    Running,
    /// Its command exited with status 0.
    Finished,
    /// Its command ended otherwise (`exit` is unknown when the job never recorded an attempt
    /// and only the scheduler's accounting says it failed).
    Failed {
        exit: Option<Exit>,
    },
    /// It finished, but a result file it left was changed, emptied or deleted since: it
    /// needs a run again.
    Damaged,
    /// Started but cut without recording an end (killed, node lost, preempted).
    Interrupted,
    /// Slurm's time limit ended it.
    Timeout,
    /// Cancelled (`scancel`).
    Cancelled,
}

impl JobState {
    /// Whether a (re)submission should run it: everything but finished, queued and running.
    pub fn needs_run(self) -> bool {
        !matches!(
            self,
            JobState::Finished | JobState::Queued | JobState::Running
        )
    }

    pub fn name(self) -> &'static str {
        match self {
            JobState::Pending => "pending",
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Finished => "finished",
            JobState::Damaged => "damaged",
            JobState::Failed { .. } => "failed",
            JobState::Interrupted => "interrupted",
            JobState::Timeout => "timeout",
            JobState::Cancelled => "cancelled",
        }
    }
}

impl std::fmt::Display for JobState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            JobState::Failed { exit: Some(e) } => write!(f, "failed ({e})"),
            s => f.write_str(s.name()),
        }
    }
}

/// What the queue says of a job's array task.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Queue<'a> {
    /// No queue was asked (no Slurm here, or no submission).
    Unknown,
    /// The queue answered and does not list the task.
    Absent,
    /// `squeue`'s state of the task (`PENDING`, `RUNNING`, …).
    Listed(&'a str),
}

/// Everything known about one job.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation<'a> {
    pub record: Option<&'a JobRecord>,
    pub queue: Queue<'a>,
    /// `sacct`'s state of the task, where accounting is on.
    pub accounting: Option<&'a str>,
    /// Whether the last attempt's process is alive, where it ran on this host.
    pub alive: Option<bool>,
    /// Whether a result file of a finished job no longer is what the job left.
    pub damaged: bool,
}

fn queued(s: &str) -> bool {
    matches!(
        s,
        "PENDING" | "CONFIGURING" | "REQUEUED" | "REQUEUE_HOLD" | "REQUEUE_FED" | "RESV_DEL_HOLD"
    )
}

fn running(s: &str) -> bool {
    matches!(
        s,
        "RUNNING" | "COMPLETING" | "SUSPENDED" | "STAGE_OUT" | "SIGNALING" | "RESIZING"
    )
}

/// A cut or failed job's state, refined by accounting where it knows why.
fn ended_badly(accounting: Option<&str>, otherwise: JobState) -> JobState {
    match accounting {
        Some("TIMEOUT" | "DEADLINE") => JobState::Timeout,
        Some("CANCELLED") => JobState::Cancelled,
        _ => otherwise,
    }
}

/// The job's state. The record is the truth about what the command did; the queue and the
/// process table say whether an unended attempt is still going; accounting says why a job
/// ended that did not say so itself.
///
/// A finished job whose results were damaged since is [`JobState::Damaged`] until it is
/// queued or running again.
pub fn classify(o: &Observation) -> JobState {
    let finished = o.record.is_some_and(JobRecord::finished);
    if finished && !o.damaged {
        return JobState::Finished;
    }
    if let Queue::Listed(s) = o.queue {
        if queued(s) {
            return JobState::Queued;
        }
        if running(s) {
            return JobState::Running;
        }
    }
    if finished {
        return JobState::Damaged;
    }
    let Some(last) = o.record.and_then(JobRecord::last) else {
        return match o.accounting {
            Some(s) if queued(s) && o.queue == Queue::Unknown => JobState::Queued,
            Some(s) if running(s) && o.queue == Queue::Unknown => JobState::Running,
            Some("TIMEOUT" | "DEADLINE") => JobState::Timeout,
            Some("CANCELLED") => JobState::Cancelled,
            Some("FAILED" | "NODE_FAIL" | "OUT_OF_MEMORY" | "BOOT_FAIL") => {
                JobState::Failed { exit: None }
            }
            _ => JobState::Pending,
        };
    };
    match last.exit {
        Some(exit) => ended_badly(o.accounting, JobState::Failed { exit: Some(exit) }),
        None => {
            let gone = match (o.alive, o.queue) {
                (Some(alive), _) => !alive,
                (None, Queue::Absent) => true,
                // Elsewhere and no queue to ask: take the record's word.
                (None, _) => false,
            };
            if gone {
                ended_badly(o.accounting, JobState::Interrupted)
            } else {
                JobState::Running
            }
        }
    }
}

/// `3 jobs: 2 finished, 1 failed` (states in a fixed order).
pub fn summary(states: &[JobState]) -> String {
    let order = [
        "finished",
        "damaged",
        "running",
        "queued",
        "pending",
        "failed",
        "interrupted",
        "timeout",
        "cancelled",
    ];
    let parts: Vec<String> = order
        .iter()
        .filter_map(|name| {
            let n = states.iter().filter(|s| s.name() == *name).count();
            (n > 0).then(|| format!("{n} {name}"))
        })
        .collect();
    format!(
        "{} job{}: {}",
        states.len(),
        if states.len() == 1 { "" } else { "s" },
        parts.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Runner;

    fn obs<'a>(record: Option<&'a JobRecord>, queue: Queue<'a>) -> Observation<'a> {
        Observation {
            record,
            queue,
            accounting: None,
            alive: None,
            damaged: false,
        }
    }

    fn started() -> JobRecord {
        let mut r = JobRecord::default();
        r.start(Runner::Local, "h", 1, 0.0);
        r
    }

    #[test]
    fn the_record_and_the_queue_decide_together() {
        assert_eq!(classify(&obs(None, Queue::Unknown)), JobState::Pending);
        assert_eq!(classify(&obs(None, Queue::Absent)), JobState::Pending);
        assert_eq!(
            classify(&obs(None, Queue::Listed("PENDING"))),
            JobState::Queued
        );
        let r = started();
        assert_eq!(
            classify(&obs(Some(&r), Queue::Listed("RUNNING"))),
            JobState::Running
        );
        // An unended attempt the queue no longer lists was cut.
        assert_eq!(
            classify(&obs(Some(&r), Queue::Absent)),
            JobState::Interrupted
        );
        // With no queue to ask, the process table decides; without either, the record.
        let mut o = obs(Some(&r), Queue::Unknown);
        assert_eq!(classify(&o), JobState::Running);
        o.alive = Some(false);
        assert_eq!(classify(&o), JobState::Interrupted);
        o.alive = Some(true);
        assert_eq!(classify(&o), JobState::Running);
        o.alive = Some(false);
        o.accounting = Some("TIMEOUT");
        assert_eq!(classify(&o), JobState::Timeout);
        o.accounting = Some("CANCELLED");
        assert_eq!(classify(&o), JobState::Cancelled);

        let mut failed = started();
        failed.end(Exit::Code(3), 1.0);
        let s = classify(&obs(Some(&failed), Queue::Absent));
        assert_eq!(
            s,
            JobState::Failed {
                exit: Some(Exit::Code(3))
            }
        );
        assert_eq!(s.to_string(), "failed (exit 3)");
        // A resubmitted failed job waiting in the queue is queued.
        assert_eq!(
            classify(&obs(Some(&failed), Queue::Listed("PENDING"))),
            JobState::Queued
        );

        let mut done = started();
        done.end(Exit::Code(0), 1.0);
        // Finished stays finished while Slurm still shows the task completing.
        assert_eq!(
            classify(&obs(Some(&done), Queue::Listed("COMPLETING"))),
            JobState::Finished
        );
        // Finished with its results damaged since: it needs a run, until it is queued again.
        let mut o = obs(Some(&done), Queue::Absent);
        o.damaged = true;
        assert_eq!(classify(&o), JobState::Damaged);
        assert!(classify(&o).needs_run());
        o.queue = Queue::Listed("PENDING");
        assert_eq!(classify(&o), JobState::Queued);
        o.queue = Queue::Unknown;
        assert_eq!(classify(&o), JobState::Damaged);
        // Damage counts only for a finished job: a failed one stays failed.
        let mut o = obs(Some(&failed), Queue::Absent);
        o.damaged = true;
        assert_eq!(classify(&o).name(), "failed");
    }

    #[test]
    fn accounting_speaks_for_jobs_that_never_started() {
        let mut o = obs(None, Queue::Absent);
        o.accounting = Some("FAILED");
        assert_eq!(classify(&o), JobState::Failed { exit: None });
        o.accounting = Some("TIMEOUT");
        assert_eq!(classify(&o), JobState::Timeout);
        o.accounting = Some("COMPLETED");
        assert_eq!(classify(&o), JobState::Pending);
        let mut o = obs(None, Queue::Unknown);
        o.accounting = Some("PENDING");
        assert_eq!(classify(&o), JobState::Queued);
    }

    #[test]
    fn only_unfinished_idle_jobs_need_a_run() {
        let needs: Vec<bool> = [
            JobState::Pending,
            JobState::Queued,
            JobState::Running,
            JobState::Finished,
            JobState::Damaged,
            JobState::Failed { exit: None },
            JobState::Interrupted,
            JobState::Timeout,
            JobState::Cancelled,
        ]
        .iter()
        .map(|s| s.needs_run())
        .collect();
        assert_eq!(
            needs,
            [true, false, false, false, true, true, true, true, true]
        );
        assert_eq!(
            summary(&[
                JobState::Finished,
                JobState::Interrupted,
                JobState::Finished
            ]),
            "3 jobs: 2 finished, 1 interrupted"
        );
    }
}
