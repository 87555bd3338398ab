//! `batch gather`: the paper's tables over every finished run, naming the runs it cannot read.

use super::*;
use crate::common::print_json;
use agentstar_batch::state::summary;
use agentstar_batch::table::jobs_table;
use agentstar_batch::{JobSpec, JobState, Method};
use agentstar_bench::table::tables;
use agentstar_data::rundir::RunDir;
use anyhow::{bail, Result};
use std::process::ExitCode;

/// The tracker's evaluations in a finished job: what `agentstar track` printed in the last
/// attempt's log (track), or the agent's `track` calls in its ledger (agent).
pub(super) fn evaluations(batch: &Batch, j: &JobSpec) -> Option<u64> {
    use agentstar_batch::table::{last_attempt_log, tracked_evaluations};
    match j.method {
        Method::Track => {
            let log = agentstar_data::read_text(&batch.log_path(j)).ok()?;
            tracked_evaluations(last_attempt_log(&log))
        }
        Method::Agent => {
            let run = RunDir::open(&batch.job_dir(j)).ok()?;
            let (entries, _) = agentstar_data::ledger::read(&run.ledger_path()).ok()?;
            entries
                .iter()
                .filter_map(|e| tracked_evaluations(&e.summary))
                .reduce(|a, b| a + b)
        }
    }
}

pub(super) fn run_gather(a: GatherArgs) -> Result<ExitCode> {
    let batch = Batch::open(&a.batch)?;
    let (records, states) = states(&batch)?;
    let rows = job_rows(&batch, &records, &states)?;
    let mut entries = Vec::new();
    for ((j, state), row) in batch.manifest.jobs.iter().zip(&states).zip(&rows) {
        match (state, &j.gt) {
            (JobState::Finished, Some(gt)) => entries.push((
                j,
                crate::cmd::eval::BatchEntry {
                    capture: j.capture.clone(),
                    model: j.model.clone(),
                    poses: j.poses.clone(),
                    gt: Some(gt.clone()),
                    label: Some(batch.manifest.label.clone()),
                    family: None,
                    seconds: row.wall_s,
                    evaluations: evaluations(&batch, j),
                },
            )),
            (JobState::Finished, None) => {
                eprintln!(
                    "job {}: finished, but its capture has no gt.json; not evaluated",
                    j.name
                )
            }
            (s, _) => eprintln!("job {}: {s}; not evaluated", j.name),
        }
    }
    if entries.is_empty() {
        bail!(
            "{}: no finished job with ground truth to evaluate ({})",
            batch.dir.display(),
            summary(&states)
        );
    }
    // Each run on its own: one that cannot be read (its capture or model changed since, a
    // result damaged past what the digests see) is reported and the rest are tabled.
    let mut results = Vec::with_capacity(entries.len());
    let mut eval_reports = Vec::with_capacity(entries.len());
    let mut evaluated = Vec::with_capacity(entries.len());
    let mut unreadable = Vec::new();
    let n = entries.len();
    for (i, (j, e)) in entries.into_iter().enumerate() {
        eprintln!("eval [{}/{n}] job {}", i + 1, j.name);
        match crate::cmd::eval::entry_result(&batch.dir, &e, a.samples) {
            Ok((r, report)) => {
                results.push(r);
                eval_reports.push(report);
                evaluated.push(e);
            }
            Err(err) => {
                eprintln!(
                    "job {}: cannot read its run: {err:#}; not evaluated",
                    j.name
                );
                unreadable.push(serde_json::json!({"job": j.name, "error": format!("{err:#}")}));
            }
        }
    }
    if evaluated.is_empty() {
        bail!(
            "{}: none of the finished jobs' runs could be read ({} job(s); see above)",
            batch.dir.display(),
            unreadable.len()
        );
    }
    // The runs in `eval --batch` form, so that the tables can be made again from the files.
    let runs = batch.dir.join("runs.json");
    agentstar_data::atomic::write_json(&runs, &evaluated)?;
    eprintln!(
        "gather: {} run(s) in {} (the same as `agentstar eval --batch {} --per-sequence`){}",
        evaluated.len(),
        runs.display(),
        runs.display(),
        if unreadable.is_empty() {
            String::new()
        } else {
            format!("; {} job(s) could not be read", unreadable.len())
        }
    );
    if a.json {
        print_json(&serde_json::json!({
            "results": eval_reports, "summary": summary(&states), "jobs": reports(&batch, &rows),
            "unreadable": unreadable
        }))?;
    } else {
        print!("{}", tables(&results, true));
        println!();
        print!("{}", jobs_table(&rows));
    }
    Ok(ExitCode::SUCCESS)
}
