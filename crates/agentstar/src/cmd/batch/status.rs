//! `batch status`: job states from their records and files, what the scheduler says of them,
//! and the jobs table.

use super::*;
use crate::common::print_json;
use agentstar_batch::slurm::{self, TaskState};
use agentstar_batch::state::summary;
use agentstar_batch::table::{jobs_table, AgentSpend, JobRow};
use agentstar_batch::{classify, JobRecord, JobSpec, JobState, Method, Observation, Queue, Runner};
use agentstar_data::rundir::RunDir;
use anyhow::Result;
use serde::Serialize;
use std::path::PathBuf;
use std::process::{Command, ExitCode};

/// What Slurm says about the batch's submissions, where it can be asked.
pub(super) struct SchedulerView {
    /// `None`: no squeue, or no submissions to ask about.
    queue: Option<Vec<TaskState>>,
    accounting: Vec<TaskState>,
    job_ids: Vec<u64>,
}

pub(super) fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join(program).is_file()))
}

/// How long `sbatch`, `squeue` or `sacct` may take.
const SCHEDULER_LIMIT: std::time::Duration = std::time::Duration::from_secs(60);

/// Runs a scheduler command with a bound on its time; stdout, stderr and success. Its output
/// is read while it runs: a queue listing longer than a pipe holds (64 KiB) once stalled
/// the command until it was stopped at the limit.
pub(super) fn scheduler_command(program: &str, args: &[String]) -> Result<(String, String, bool)> {
    let out =
        agentstar_import::process::output_within(Command::new(program).args(args), SCHEDULER_LIMIT)
            .map_err(|e| {
                if e.kind() == std::io::ErrorKind::TimedOut {
                    anyhow::anyhow!(
                        "{program} did not answer within {} s",
                        SCHEDULER_LIMIT.as_secs()
                    )
                } else {
                    anyhow::Error::new(e).context(format!("starting {program}"))
                }
            })?;
    Ok((
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        out.status.success(),
    ))
}

pub(super) fn scheduler_view(
    batch: &Batch,
    records: &[Option<JobRecord>],
) -> Result<SchedulerView> {
    let mut job_ids = batch.submissions()?.job_ids();
    for r in records.iter().flatten() {
        for a in &r.attempts {
            if let Runner::Slurm { job_id, .. } = a.runner {
                if !job_ids.contains(&job_id) {
                    job_ids.push(job_id);
                }
            }
        }
    }
    job_ids.sort_unstable();
    let mut view = SchedulerView {
        queue: None,
        accounting: vec![],
        job_ids,
    };
    if view.job_ids.is_empty() {
        return Ok(view);
    }
    let ids = view
        .job_ids
        .iter()
        .map(u64::to_string)
        .collect::<Vec<_>>()
        .join(",");
    if on_path("squeue") {
        let args = [
            "-h".to_string(),
            "-o".into(),
            slurm::SQUEUE_FORMAT.into(),
            "-j".into(),
            ids.clone(),
        ];
        match scheduler_command("squeue", &args) {
            Ok((out, _, true)) => view.queue = Some(slurm::parse_squeue(&out)?),
            // Slurm forgets finished jobs; asked only about forgotten ones it says so.
            Ok((_, err, false)) if err.contains("Invalid job id") => view.queue = Some(vec![]),
            Ok((_, err, false)) => eprintln!(
                "note: squeue failed ({}); the files alone decide",
                err.trim()
            ),
            Err(e) => eprintln!("note: {e:#}; the files alone decide"),
        }
    }
    if on_path("sacct") {
        let args = [
            "-n".to_string(),
            "-P".into(),
            "-X".into(),
            "-o".into(),
            slurm::SACCT_FIELDS.into(),
            "-j".into(),
            ids,
        ];
        // Without an accounting database sacct fails; it only refines why a job ended.
        if let Ok((out, _, true)) = scheduler_command("sacct", &args) {
            view.accounting = slurm::parse_sacct(&out).unwrap_or_default();
        }
    }
    Ok(view)
}

/// Every job's record and state.
pub(super) fn states(batch: &Batch) -> Result<(Vec<Option<JobRecord>>, Vec<JobState>)> {
    let records: Vec<Option<JobRecord>> = batch
        .manifest
        .jobs
        .iter()
        .map(|j| batch.record(j))
        .collect::<Result<_>>()?;
    let view = scheduler_view(batch, &records)?;
    let host = host_name();
    let damaged: Vec<bool> = batch
        .manifest
        .jobs
        .iter()
        .zip(&records)
        .map(|(j, r)| {
            let Some(r) = r else { return Ok(false) };
            Ok(match batch.damage(j, r)? {
                Some(why) => {
                    eprintln!(
                        "note: job {}: {why}; it no longer counts as finished and runs again",
                        j.name
                    );
                    true
                }
                None => false,
            })
        })
        .collect::<Result<_>>()?;
    let states = batch
        .manifest
        .jobs
        .iter()
        .zip(&records)
        .zip(&damaged)
        .map(|((j, r), &damaged)| {
            let last = r.as_ref().and_then(JobRecord::last);
            let task = j.index as u64;
            let queue = match &view.queue {
                None => Queue::Unknown,
                Some(q) => match slurm::task_state(q, &view.job_ids, task) {
                    Some(t) => Queue::Listed(t.state.as_str()),
                    // A local attempt is none of the queue's business.
                    None if last.is_some_and(|a| a.runner == Runner::Local) => Queue::Unknown,
                    None => Queue::Absent,
                },
            };
            let alive = last
                .filter(|a| a.exit.is_none() && a.host == host)
                .and_then(|a| exec_alive(a.pid));
            classify(&Observation {
                record: r.as_ref(),
                queue,
                accounting: slurm::task_state(&view.accounting, &view.job_ids, task)
                    .map(|t| t.state.as_str()),
                alive,
                damaged,
            })
        })
        .collect();
    Ok((records, states))
}

#[derive(Serialize)]
pub(super) struct JobReport {
    name: String,
    index: usize,
    #[serde(flatten)]
    state: JobState,
    attempts: usize,
    wall_s: Option<f64>,
    total_wall_s: f64,
    agent_steps: Option<u64>,
    input_tokens: Option<u64>,
    output_tokens: Option<u64>,
    log: PathBuf,
}

/// The agent's spend from the run's ledger (agent jobs).
pub(super) fn agent_spend(batch: &Batch, j: &JobSpec) -> Result<Option<AgentSpend>> {
    if j.method != Method::Agent {
        return Ok(None);
    }
    let run = RunDir::open(&batch.job_dir(j))?;
    let p = run.ledger_path();
    if !p.is_file() {
        return Ok(Some(AgentSpend::default()));
    }
    let (entries, _) = agentstar_data::ledger::read(&p)?;
    Ok(Some(AgentSpend::from_ledger(
        entries
            .iter()
            .map(|e| (e.step, e.time_s, e.tool.as_str(), &e.scores)),
    )))
}

pub(super) fn job_rows(
    batch: &Batch,
    records: &[Option<JobRecord>],
    states: &[JobState],
) -> Result<Vec<JobRow>> {
    batch
        .manifest
        .jobs
        .iter()
        .zip(records.iter().zip(states))
        .map(|(j, (r, &state))| {
            let agent = agent_spend(batch, j)?;
            let finishing = r
                .as_ref()
                .filter(|r| r.finished())
                .and_then(|r| r.last())
                .and_then(|a| a.wall_s());
            Ok(JobRow {
                name: j.name.clone(),
                method: batch.manifest.label.clone(),
                state,
                attempts: r.as_ref().map_or(0, |r| r.attempts.len()),
                wall_s: match agent {
                    Some(s) if s.steps > 0 => Some(s.elapsed_s),
                    _ => finishing,
                },
                total_wall_s: r.as_ref().map_or(0.0, JobRecord::total_wall_s),
                agent,
            })
        })
        .collect()
}

pub(super) fn reports(batch: &Batch, rows: &[JobRow]) -> Vec<JobReport> {
    batch
        .manifest
        .jobs
        .iter()
        .zip(rows)
        .map(|(j, r)| JobReport {
            name: j.name.clone(),
            index: j.index,
            state: r.state,
            attempts: r.attempts,
            wall_s: r.wall_s,
            total_wall_s: r.total_wall_s,
            agent_steps: r.agent.map(|a| a.steps),
            input_tokens: r.agent.map(|a| a.input_tokens),
            output_tokens: r.agent.map(|a| a.output_tokens),
            log: batch.log_path(j),
        })
        .collect()
}

/// Prints the batch's summary (and, with `table`, the jobs table), or everything as JSON.
pub(super) fn print_status(batch: &Batch, json: bool, table: bool) -> Result<()> {
    let (records, states) = states(batch)?;
    let rows = job_rows(batch, &records, &states)?;
    if json {
        print_json(&serde_json::json!({
            "batch": batch.dir, "summary": summary(&states), "jobs": reports(batch, &rows)
        }))?;
    } else if table {
        println!("{}: {}\n", batch.dir.display(), summary(&states));
        print!("{}", jobs_table(&rows));
    } else {
        println!("{}: {}", batch.dir.display(), summary(&states));
    }
    Ok(())
}

pub(super) fn run_status(a: StatusArgs) -> Result<ExitCode> {
    let batch = Batch::open(&a.batch)?;
    print_status(&batch, a.json, true)?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scheduler that prints more than a pipe holds is read while it runs (it was read
    /// only after it exited, so it stalled until stopped at the limit).
    #[test]
    fn a_long_queue_listing_is_read_whole() {
        let start = std::time::Instant::now();
        let (out, _, ok) = scheduler_command(
            "sh",
            &["-c".into(), "head -c 1000000 /dev/zero | tr '\\0' x".into()],
        )
        .expect("runs");
        assert!(ok);
        assert_eq!(out.len(), 1_000_000);
        assert!(start.elapsed() < std::time::Duration::from_secs(30));
    }
}
