//! Slurm: the job-array script of a submission, the record of submissions, and parsers of
//! what `sbatch --parsable`, `squeue` and `sacct` print.

use crate::manifest::Resources;
use crate::{BatchError, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What goes into one array script.
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptConfig<'a> {
    /// The batch directory (absolute).
    pub batch_dir: &'a Path,
    /// `--job-name`.
    pub job_name: &'a str,
    /// The manifest indices of the jobs to run (their array task ids), ascending.
    pub tasks: &'a [usize],
    /// At most this many tasks at once (`--array=…%N`).
    pub max_parallel: Option<u32>,
    pub resources: Resources,
    pub partition: Option<&'a str>,
    /// Further `#SBATCH` lines, without the prefix (`--account=lab`, `--gres=gpu:1`).
    pub extra: &'a [String],
    /// The agentstar executable as the compute nodes see it (absolute).
    pub agentstar: &'a Path,
}

/// Quotes a word for a POSIX shell.
pub fn shell_quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-=:,+@%".contains(c))
    {
        return s.to_string();
    }
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// Array task ids as Slurm's `--array` list: runs of consecutive ids become ranges
/// (`0-2,5,7-8`), with `%N` to bound how many run at once.
pub fn array_spec(tasks: &[usize], max_parallel: Option<u32>) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < tasks.len() {
        let mut j = i;
        while j + 1 < tasks.len() && tasks[j + 1] == tasks[j] + 1 {
            j += 1;
        }
        parts.push(if j == i {
            tasks[i].to_string()
        } else {
            format!("{}-{}", tasks[i], tasks[j])
        });
        i = j + 1;
    }
    let mut s = parts.join(",");
    if let Some(n) = max_parallel {
        s.push_str(&format!("%{n}"));
    }
    s
}

/// The `sbatch` script of one submission: one array task per job, each running
/// `agentstar batch exec BATCH --task $SLURM_ARRAY_TASK_ID`, which records the attempt in
/// the job's files; the script appends the task's exit status to `slurm/exit-codes.tsv`.
pub fn array_script(c: &ScriptConfig) -> Result<String> {
    if c.tasks.is_empty() {
        return Err(BatchError::Invalid("no jobs to put in an array".into()));
    }
    if c.tasks.windows(2).any(|w| w[0] >= w[1]) {
        return Err(BatchError::Invalid(
            "array task ids must be ascending and distinct".into(),
        ));
    }
    if c.max_parallel == Some(0) {
        return Err(BatchError::Invalid(
            "--max-parallel 0: at least one task must be allowed to run".into(),
        ));
    }
    for line in c.extra {
        if line.contains(['\n', '\r']) || line.trim().is_empty() {
            return Err(BatchError::Invalid(format!(
                "#SBATCH line `{}`: one non-empty line, such as --account=lab",
                line.escape_debug()
            )));
        }
    }
    let check_word = |what: &str, s: &str| {
        if s.is_empty() || s.chars().any(|c| c.is_whitespace() || c.is_control()) {
            return Err(BatchError::Invalid(format!(
                "{what} `{}`: a single word without spaces",
                s.escape_debug()
            )));
        }
        Ok(())
    };
    check_word("job name", c.job_name)?;
    if let Some(p) = c.partition {
        check_word("partition", p)?;
    }
    let batch = c.batch_dir.to_string_lossy();
    // `#SBATCH` lines are not shell words: Slurm reads them up to the first space, so the
    // log path must hold none.
    if batch.chars().any(char::is_whitespace) {
        return Err(BatchError::Invalid(format!(
            "{batch}: Slurm cannot take a log path with spaces; put the batch in a directory without them"
        )));
    }
    let r = &c.resources;
    let mut s = String::new();
    s.push_str("#!/bin/bash\n");
    s.push_str("# Written by `agentstar batch slurm`: one array task per job of the batch.\n");
    s.push_str(&format!("#SBATCH --job-name={}\n", c.job_name));
    s.push_str(&format!(
        "#SBATCH --array={}\n",
        array_spec(c.tasks, c.max_parallel)
    ));
    s.push_str(&format!("#SBATCH --time={}\n", r.slurm_time()));
    s.push_str("#SBATCH --ntasks=1\n");
    s.push_str(&format!("#SBATCH --cpus-per-task={}\n", r.cpus_per_task));
    s.push_str(&format!("#SBATCH --mem={}M\n", r.mem_mb));
    if let Some(p) = c.partition {
        s.push_str(&format!("#SBATCH --partition={p}\n"));
    }
    s.push_str(&format!("#SBATCH --output={batch}/logs/slurm-%A_%a.log\n"));
    for line in c.extra {
        s.push_str(&format!("#SBATCH {}\n", line.trim()));
    }
    let q_batch = shell_quote(&batch);
    s.push_str("\nset -u\n");
    s.push_str(&format!(
        "{} batch exec {q_batch} --task \"$SLURM_ARRAY_TASK_ID\"\n",
        shell_quote(&c.agentstar.to_string_lossy())
    ));
    s.push_str("rc=$?\n");
    s.push_str(&format!(
        "printf '%s\\t%s\\t%s\\n' \"$SLURM_ARRAY_JOB_ID\" \"$SLURM_ARRAY_TASK_ID\" \"$rc\" >> {q_batch}/slurm/exit-codes.tsv\n"
    ));
    s.push_str("exit \"$rc\"\n");
    Ok(s)
}

/// One `sbatch` of the batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Submission {
    /// Slurm's job id of the array.
    pub job_id: u64,
    /// The script, relative to the batch directory.
    pub script: PathBuf,
    /// The manifest indices submitted (the array task ids).
    pub tasks: Vec<usize>,
    pub submitted_unix_s: f64,
}

/// `slurm/submissions.json`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Submissions {
    pub submissions: Vec<Submission>,
}

impl Submissions {
    /// Job ids of every submission, oldest first.
    pub fn job_ids(&self) -> Vec<u64> {
        self.submissions.iter().map(|s| s.job_id).collect()
    }
}

/// The job id in `sbatch --parsable` output (`123` or `123;cluster`).
pub fn parse_sbatch(stdout: &str) -> Result<u64> {
    let line = stdout
        .lines()
        .map(str::trim)
        .rfind(|l| !l.is_empty())
        .unwrap_or("");
    let id = line.split(';').next().unwrap_or("");
    id.parse().map_err(|_| BatchError::Parse {
        command: "sbatch --parsable",
        message: "expected a job id".into(),
        line: line.to_string(),
    })
}

/// Task ids as Slurm lists them: `3`, `3,5-7`, `[3,5-7%2]`.
fn parse_task_list(s: &str) -> Option<Vec<u64>> {
    let s = s.trim().trim_start_matches('[').trim_end_matches(']');
    let s = s.split('%').next()?;
    let mut out = Vec::new();
    for part in s.split(',') {
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b): (u64, u64) = (a.parse().ok()?, b.parse().ok()?);
                if b < a || b - a > 1_000_000 {
                    return None;
                }
                out.extend(a..=b);
            }
            None => out.push(part.parse().ok()?),
        }
    }
    Some(out)
}

/// A job id as Slurm prints it: `123`, `123_4` or `123_[5-7%2]`; the array id and its tasks
/// (none for a job that is not an array task).
fn parse_job_id(s: &str) -> Option<(u64, Vec<u64>)> {
    match s.split_once('_') {
        Some((id, tasks)) => Some((id.parse().ok()?, parse_task_list(tasks)?)),
        None => Some((s.parse().ok()?, vec![])),
    }
}

/// What the scheduler says of some array tasks.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskState {
    /// The array's job id.
    pub job_id: u64,
    /// The array task ids this line covers.
    pub tasks: Vec<u64>,
    /// Slurm's state name (`PENDING`, `RUNNING`, `COMPLETED`, `TIMEOUT`, …).
    pub state: String,
    /// `sacct`'s exit code (`0:15`: status 0, signal 15), where known.
    pub exit_code: Option<String>,
}

/// The squeue format this crate reads.
pub const SQUEUE_FORMAT: &str = "%i|%T";

/// `squeue -h -o '%i|%T' -j IDS` output.
pub fn parse_squeue(stdout: &str) -> Result<Vec<TaskState>> {
    let mut out = Vec::new();
    for line in stdout.lines().map(str::trim).filter(|l| !l.is_empty()) {
        let bad = |message: &str| BatchError::Parse {
            command: "squeue",
            message: message.into(),
            line: line.to_string(),
        };
        let (id, state) = line
            .split_once('|')
            .ok_or_else(|| bad("expected JOBID|STATE"))?;
        let (job_id, tasks) = parse_job_id(id.trim()).ok_or_else(|| bad("a job id"))?;
        out.push(TaskState {
            job_id,
            tasks,
            state: state.trim().to_string(),
            exit_code: None,
        });
    }
    Ok(out)
}

/// The fields this crate asks `sacct` for.
pub const SACCT_FIELDS: &str = "JobID,State,ExitCode";

/// `sacct -n -P -X -o JobID,State,ExitCode -j IDS` output. Job steps (`123_4.batch`) are
/// skipped; a state such as `CANCELLED by 0` keeps its first word.
pub fn parse_sacct(stdout: &str) -> Result<Vec<TaskState>> {
    let mut out = Vec::new();
    for line in stdout.lines().map(str::trim).filter(|l| !l.is_empty()) {
        let bad = |message: &str| BatchError::Parse {
            command: "sacct",
            message: message.into(),
            line: line.to_string(),
        };
        let f: Vec<&str> = line.split('|').collect();
        if f.len() < 3 {
            return Err(bad("expected JobID|State|ExitCode"));
        }
        if f[0].contains('.') {
            continue;
        }
        let (job_id, tasks) = parse_job_id(f[0].trim()).ok_or_else(|| bad("a job id"))?;
        out.push(TaskState {
            job_id,
            tasks,
            state: f[1].split_whitespace().next().unwrap_or("").to_string(),
            exit_code: Some(f[2].trim().to_string()),
        });
    }
    Ok(out)
}

/// The state of array task `task`, taking the newest submission that lists it.
pub fn task_state<'a>(
    states: &'a [TaskState],
    submissions: &[u64],
    task: u64,
) -> Option<&'a TaskState> {
    submissions.iter().rev().find_map(|&id| {
        states
            .iter()
            .find(|s| s.job_id == id && s.tasks.contains(&task))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config<'a>(tasks: &'a [usize], extra: &'a [String]) -> ScriptConfig<'a> {
        ScriptConfig {
            batch_dir: Path::new("/scratch/b1"),
            job_name: "agentstar-b1",
            tasks,
            max_parallel: Some(8),
            resources: Resources {
                time_min: 90,
                cpus_per_task: 4,
                mem_mb: 8192,
            },
            partition: Some("gpu"),
            extra,
            agentstar: Path::new("/opt/agent star/bin/agentstar"),
        }
    }

    #[test]
    fn the_array_script_carries_resources_logs_and_exit_codes() {
        let extra = vec!["--account=lab".to_string(), "--gres=gpu:1".to_string()];
        let s = array_script(&config(&[0, 1, 2, 5], &extra)).expect("script");
        let expected = "#!/bin/bash\n\
# Written by `agentstar batch slurm`: one array task per job of the batch.\n\
#SBATCH --job-name=agentstar-b1\n\
#SBATCH --array=0-2,5%8\n\
#SBATCH --time=0-01:30:00\n\
#SBATCH --ntasks=1\n\
#SBATCH --cpus-per-task=4\n\
#SBATCH --mem=8192M\n\
#SBATCH --partition=gpu\n\
#SBATCH --output=/scratch/b1/logs/slurm-%A_%a.log\n\
#SBATCH --account=lab\n\
#SBATCH --gres=gpu:1\n\
\n\
set -u\n\
'/opt/agent star/bin/agentstar' batch exec /scratch/b1 --task \"$SLURM_ARRAY_TASK_ID\"\n\
rc=$?\n\
printf '%s\\t%s\\t%s\\n' \"$SLURM_ARRAY_JOB_ID\" \"$SLURM_ARRAY_TASK_ID\" \"$rc\" >> /scratch/b1/slurm/exit-codes.tsv\n\
exit \"$rc\"\n";
        assert_eq!(s, expected);
    }

    #[test]
    fn scripts_refuse_what_slurm_would_misread() {
        let none: Vec<String> = vec![];
        assert!(array_script(&config(&[], &none)).is_err());
        assert!(array_script(&config(&[2, 1], &none)).is_err());
        assert!(array_script(&config(&[1, 1], &none)).is_err());
        assert!(array_script(&config(&[0], &["--a\n#SBATCH --b".to_string()])).is_err());
        let mut c = config(&[0], &none);
        c.partition = Some("two words");
        assert!(array_script(&c).is_err());
        let mut c = config(&[0], &none);
        c.max_parallel = Some(0);
        assert!(array_script(&c).is_err());
        let mut c = config(&[0], &none);
        c.batch_dir = Path::new("/with space/b");
        assert!(array_script(&c).is_err());
    }

    #[test]
    fn array_specs_compress_runs() {
        assert_eq!(array_spec(&[0], None), "0");
        assert_eq!(array_spec(&[0, 1, 2], None), "0-2");
        assert_eq!(array_spec(&[1, 3, 4, 5, 9, 10], Some(2)), "1,3-5,9-10%2");
    }

    #[test]
    fn shell_quoting_survives_quotes_and_spaces() {
        assert_eq!(shell_quote("/a/b-c_d.e"), "/a/b-c_d.e");
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
        assert_eq!(shell_quote(""), "''");
        assert_eq!(shell_quote("$HOME"), "'$HOME'");
    }

    #[test]
    fn sbatch_output_gives_the_job_id() {
        assert_eq!(parse_sbatch("123\n").ok(), Some(123));
        assert_eq!(parse_sbatch("456;cluster\n").ok(), Some(456));
        assert!(parse_sbatch("Submitted batch job 1\n").is_err());
        assert!(parse_sbatch("").is_err());
    }

    #[test]
    fn squeue_lines_expand_to_tasks() {
        // As squeue 22.05 prints them (recorded on this project's one-node cluster).
        let out = "4_[3,5-7%2]|PENDING\n4_1|RUNNING\n99|RUNNING\n";
        let s = parse_squeue(out).expect("parse");
        assert_eq!(s.len(), 3);
        assert_eq!(s[0].tasks, [3, 5, 6, 7]);
        assert_eq!(s[0].state, "PENDING");
        assert_eq!((s[1].job_id, s[1].tasks.clone()), (4, vec![1]));
        assert!(s[2].tasks.is_empty());
        assert_eq!(
            task_state(&s, &[4], 6).map(|t| t.state.as_str()),
            Some("PENDING")
        );
        assert_eq!(task_state(&s, &[4], 2), None);
        assert_eq!(task_state(&s, &[5], 1), None);
        assert!(parse_squeue("garbage\n").is_err());
        assert!(parse_squeue("4_x|RUNNING\n").is_err());
        assert!(parse_squeue("4_[9-1]|RUNNING\n").is_err());
    }

    #[test]
    fn sacct_lines_skip_steps_and_keep_the_state_word() {
        let out = "7_0|COMPLETED|0:0\n7_0.batch|COMPLETED|0:0\n7_1|TIMEOUT|0:15\n7_2|CANCELLED by 0|0:15\n8_[3-4]|PENDING|0:0\n";
        let s = parse_sacct(out).expect("parse");
        assert_eq!(s.len(), 4);
        assert_eq!(s[1].state, "TIMEOUT");
        assert_eq!(s[1].exit_code.as_deref(), Some("0:15"));
        assert_eq!(s[2].state, "CANCELLED");
        // The newest submission listing a task wins.
        let both = [s.clone(), parse_sacct("9_1|RUNNING|0:0\n").expect("parse")].concat();
        assert_eq!(
            task_state(&both, &[7, 9], 1).map(|t| t.state.as_str()),
            Some("RUNNING")
        );
        assert!(parse_sacct("7_0|COMPLETED\n").is_err());
    }
}
