//! Running the jobs: `batch slurm` (a job array, resubmissions), `batch exec` (one job, as
//! the array task or `local` runs it) and `batch local`.

use super::*;
use crate::common::print_json;
use agentstar_batch::slurm::{self, ScriptConfig, Submission};
use agentstar_batch::state::summary;
use agentstar_batch::{Exit, JobSpec, Method, Runner};
use anyhow::{anyhow, bail, Context, Result};
use std::path::PathBuf;
use std::process::{Command, ExitCode, Stdio};

pub(super) fn run_slurm(a: SlurmArgs) -> Result<ExitCode> {
    let batch = Batch::open(&a.batch)?;
    let (_, states) = states(&batch)?;
    let tasks: Vec<usize> = batch
        .manifest
        .jobs
        .iter()
        .zip(&states)
        .filter(|(_, s)| s.needs_run())
        .map(|(j, _)| j.index)
        .collect();
    if tasks.is_empty() {
        let msg = format!(
            "{}: nothing to submit ({})",
            batch.dir.display(),
            summary(&states)
        );
        if a.json {
            print_json(
                &serde_json::json!({"submitted": false, "tasks": [], "summary": summary(&states)}),
            )?;
        } else {
            println!("{msg}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    let mut resources = batch.resources();
    if let Some(t) = a.time {
        resources.time_min = t;
    }
    if let Some(c) = a.cpus_per_task {
        resources.cpus_per_task = c;
    }
    if let Some(m) = mem_flag(a.mem.as_deref())? {
        resources.mem_mb = m;
    }
    resources.check()?;
    let agentstar = match &a.agentstar {
        Some(p) => absolute(p)?,
        None => std::env::current_exe().context("finding the agentstar executable")?,
    };
    let job_name = a.job_name.clone().unwrap_or_else(|| {
        format!(
            "agentstar-{}",
            batch.dir.file_name().map_or("batch".into(), |n| n
                .to_string_lossy()
                .replace(char::is_whitespace, "_"))
        )
    });
    let script = slurm::array_script(&ScriptConfig {
        batch_dir: &batch.dir,
        job_name: &job_name,
        tasks: &tasks,
        max_parallel: a.max_parallel,
        resources,
        partition: a.partition.as_deref(),
        extra: &a.sbatch_lines,
        agentstar: &agentstar,
    })?;
    let mut subs = batch.submissions()?;
    let n = subs.submissions.len() + 1;
    let script_rel = PathBuf::from("slurm").join(format!("array-{n}.sbatch"));
    let script_path = batch.dir.join(&script_rel);
    agentstar_data::atomic::write_atomic(&script_path, script.as_bytes())?;
    std::fs::create_dir_all(batch.dir.join("logs"))?;
    let spec = slurm::array_spec(&tasks, a.max_parallel);
    if !a.submit {
        if a.json {
            print_json(
                &serde_json::json!({"submitted": false, "script": script_path, "tasks": tasks}),
            )?;
        } else {
            println!(
                "wrote {} ({} task(s): {spec}); submit it with\n  agentstar batch slurm {} --submit   (records the submission for status)\n  or: sbatch {}",
                script_path.display(),
                tasks.len(),
                batch.dir.display(),
                script_path.display()
            );
        }
        return Ok(ExitCode::SUCCESS);
    }
    if !on_path("sbatch") {
        bail!(
            "sbatch is not on PATH: run this on a Slurm login node, or run the jobs here with `agentstar batch local {}`",
            batch.dir.display()
        );
    }
    let (out, err, ok) = scheduler_command(
        "sbatch",
        &[
            "--parsable".to_string(),
            script_path.to_string_lossy().into_owned(),
        ],
    )?;
    if !ok {
        bail!("sbatch {} failed: {}", script_path.display(), err.trim());
    }
    let job_id = slurm::parse_sbatch(&out)?;
    subs.submissions.push(Submission {
        job_id,
        script: script_rel,
        tasks: tasks.clone(),
        submitted_unix_s: now_unix_s(),
    });
    agentstar_data::atomic::write_json(&batch.submissions_path(), &subs)?;
    if a.json {
        print_json(
            &serde_json::json!({"submitted": true, "job_id": job_id, "script": script_path, "tasks": tasks}),
        )?;
    } else {
        println!("{job_id}");
        eprintln!(
            "submitted job {job_id}: {} task(s) ({spec}) of {}; logs in {}",
            tasks.len(),
            batch.dir.display(),
            batch.dir.join("logs").display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

// ---------------------------------------------------------------------------------------
// exec and local

#[cfg(unix)]
pub(super) fn exit_of(status: std::process::ExitStatus) -> Exit {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => Exit::Code(c),
        (None, Some(s)) => Exit::Signal(s),
        (None, None) => Exit::Code(-1),
    }
}

#[cfg(not(unix))]
pub(super) fn exit_of(status: std::process::ExitStatus) -> Exit {
    Exit::Code(status.code().unwrap_or(-1))
}

pub(super) fn exit_code_of(e: Exit) -> ExitCode {
    match e {
        Exit::Code(c) => ExitCode::from(u8::try_from(c).unwrap_or(1)),
        Exit::Signal(s) => ExitCode::from(u8::try_from(128 + s).unwrap_or(1)),
    }
}

pub(super) fn slurm_runner() -> Option<Runner> {
    let get = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<u64>().ok());
    Some(Runner::Slurm {
        job_id: get("SLURM_ARRAY_JOB_ID")?,
        task_id: get("SLURM_ARRAY_TASK_ID")?,
    })
}

pub(super) fn run_exec(a: ExecArgs) -> Result<ExitCode> {
    let batch = Batch::open(&a.batch)?;
    let j = match (&a.job, a.task) {
        (Some(name), _) => batch.manifest.job(name).ok_or_else(|| {
            anyhow!(
                "{}: no job named `{name}` in the batch",
                batch.dir.display()
            )
        })?,
        (None, Some(i)) => batch.manifest.jobs.get(i).ok_or_else(|| {
            anyhow!(
                "{}: no job {i} (the batch has {} jobs, 0 to {})",
                batch.dir.display(),
                batch.manifest.jobs.len(),
                batch.manifest.jobs.len().saturating_sub(1)
            )
        })?,
        (None, None) => bail!("give --task N or --job NAME"),
    };
    let mut record = batch.record(j)?.unwrap_or_default();
    if record.finished() {
        match batch.damage(j, &record)? {
            None => {
                eprintln!("job {}: already finished; nothing to do", j.name);
                return Ok(ExitCode::SUCCESS);
            }
            Some(why) => {
                eprintln!("note: job {}: {why}; running it again", j.name);
                // A track job starts over: what is left of its poses is kept aside, for a
                // look, and does not stand in the new run's way.
                if j.method == Method::Track {
                    let poses = batch.dir.join(&j.poses);
                    if poses.exists() {
                        let aside = poses.with_extension("json.damaged");
                        std::fs::rename(&poses, &aside).with_context(|| {
                            format!("{}: cannot move it aside", poses.display())
                        })?;
                        eprintln!("note: job {}: kept as {}", j.name, aside.display());
                    }
                }
            }
        }
    }
    let host = host_name();
    if let Some(last) = record.last() {
        if last.exit.is_none() && last.host == host && exec_alive(last.pid) == Some(true) {
            bail!(
                "job {}: already running here (pid {}); see `agentstar batch status {}`",
                j.name,
                last.pid,
                batch.dir.display()
            );
        }
    }
    let runner = slurm_runner().unwrap_or(Runner::Local);
    record.start(runner, &host, std::process::id(), now_unix_s());
    batch.write_record(j, &record)?;

    let log_path = batch.log_path(j);
    if let Some(p) = log_path.parent() {
        std::fs::create_dir_all(p)?;
    }
    let mut log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&log_path)
        .with_context(|| format!("{}: cannot open the log", log_path.display()))?;
    {
        use std::io::Write;
        writeln!(
            log,
            "== attempt {} of job {} on {host} ({runner:?}): agentstar {}",
            record.attempts.len(),
            j.name,
            shell_line(&j.argv)
        )?;
    }
    let exe = std::env::current_exe().context("finding the agentstar executable")?;
    let mut cmd = Command::new(exe);
    cmd.args(&j.argv)
        .current_dir(batch.job_dir(j))
        .stdin(Stdio::null())
        .stdout(log.try_clone()?)
        .stderr(log);
    // The job uses the CPUs it was given, not every core of the node.
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        let cpus = std::env::var("SLURM_CPUS_PER_TASK")
            .ok()
            .and_then(|v| v.parse::<u32>().ok())
            .unwrap_or(j.resources.cpus_per_task);
        cmd.env("RAYON_NUM_THREADS", cpus.max(1).to_string());
    }
    eprintln!(
        "job {} (attempt {}): agentstar {}",
        j.name,
        record.attempts.len(),
        shell_line(&j.argv)
    );
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => {
            record.end(Exit::Code(127), now_unix_s());
            batch.write_record(j, &record)?;
            return Err(e).context("starting the job's command");
        }
    };
    if let Some(a) = record.attempts.last_mut() {
        a.child_pid = Some(child.id());
    }
    batch.write_record(j, &record)?;
    let status = child.wait().context("waiting for the job's command")?;
    let exit = exit_of(status);
    // The results as the job left them, so that a later change to them is noticed.
    let outputs = if exit.success() {
        batch.digests(j)?
    } else {
        vec![]
    };
    record.end_with(exit, now_unix_s(), outputs);
    batch.write_record(j, &record)?;
    let wall = record.last().and_then(|a| a.wall_s()).unwrap_or(0.0);
    eprintln!(
        "job {}: {} after {wall:.1} s (log: {})",
        j.name,
        if exit.success() {
            "finished".to_string()
        } else {
            exit.to_string()
        },
        log_path.display()
    );
    Ok(exit_code_of(exit))
}

pub(super) fn run_local(a: LocalArgs) -> Result<ExitCode> {
    let batch = Batch::open(&a.batch)?;
    let (_, states) = states(&batch)?;
    let todo: Vec<&JobSpec> = batch
        .manifest
        .jobs
        .iter()
        .zip(&states)
        .filter(|(_, s)| s.needs_run())
        .map(|(j, _)| j)
        .collect();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let width = a
        .jobs
        .unwrap_or_else(|| cores / batch.resources().cpus_per_task.max(1) as usize)
        .max(1);
    eprintln!(
        "{}: {} job(s) to run, {width} at a time ({})",
        batch.dir.display(),
        todo.len(),
        summary(&states)
    );
    let exe = std::env::current_exe().context("finding the agentstar executable")?;
    let mut running: Vec<(&JobSpec, std::process::Child)> = Vec::new();
    let mut queue = todo.into_iter();
    let mut failed = 0usize;
    loop {
        while running.len() < width {
            let Some(j) = queue.next() else { break };
            let child = Command::new(&exe)
                .args(["batch", "exec"])
                .arg(&batch.dir)
                .args(["--job", &j.name])
                .env_remove("SLURM_ARRAY_JOB_ID")
                .env_remove("SLURM_ARRAY_TASK_ID")
                .stdin(Stdio::null())
                .spawn()
                .with_context(|| format!("starting job {}", j.name))?;
            running.push((j, child));
        }
        if running.is_empty() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
        let mut k = 0;
        while k < running.len() {
            if let Some(status) = running[k].1.try_wait()? {
                if !status.success() {
                    failed += 1;
                }
                running.swap_remove(k);
            } else {
                k += 1;
            }
        }
    }
    print_status(&batch, a.json, false)?;
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
