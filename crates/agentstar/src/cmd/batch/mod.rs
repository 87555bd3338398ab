//! `agentstar batch plan|slurm|local|exec|status|gather`: one job per capture, run by Slurm
//! as a job array or here, each leaving its state in files; then the paper's tables over
//! every finished run. The types, the script and the parsers are in `agentstar-batch`; this
//! file reads and writes the files and runs `sbatch`, `squeue`, `sacct` and the jobs.

use agentstar_batch::manifest::FORMAT;
use agentstar_batch::slurm::{self, Submissions};
use agentstar_batch::{JobRecord, JobSpec, Manifest, OutputDigest, OutputNow, Resources};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

mod gather;
mod jobs;
mod plan;
mod status;

use gather::*;
use jobs::*;
use plan::*;
use status::*;

#[derive(clap::Subcommand)]
pub enum BatchCommand {
    /// One job per capture: a run directory made as `agentstar init` makes it (agent) or a
    /// track job, with its command line and resources, and the manifest `BATCH/batch.json`.
    #[command(
        after_help = "Examples:\n  agentstar batch plan caps/* --out b1                                   # track with each capture's model/ (agentstar synth)\n  agentstar batch plan caps/* --out b2 --method agent --model anthropic:claude-sonnet-4-5 --job-arg=--max-steps --job-arg=150"
    )]
    Plan(PlanArgs),
    /// Write a Slurm job-array script for the jobs that still need a run; `--submit` submits it.
    #[command(
        after_help = "Examples:\n  agentstar batch slurm b1 --partition cpu --time 120 --mem 8G --submit\n  agentstar batch slurm b1 --sbatch=--account=lab --sbatch=--qos=long --max-parallel 20 --submit\nResubmitting skips finished, queued and running jobs; failed, cut and timed-out jobs run again\n(agent runs resume from their ledger, track jobs start over)."
    )]
    Slurm(SlurmArgs),
    /// Run the jobs that still need a run on this machine, N at a time.
    #[command(after_help = "Example:\n  agentstar batch local b1 -j 2")]
    Local(LocalArgs),
    /// Run one job of the batch here, recording the attempt (what every array task runs).
    #[command(after_help = "Example:\n  agentstar batch exec b1 --job laptop")]
    Exec(ExecArgs),
    /// Which jobs finished, failed, were cut or are running: from the files, and from squeue
    /// and sacct when present.
    #[command(after_help = "Example:\n  agentstar batch status b1")]
    Status(StatusArgs),
    /// Evaluate every finished run with ground truth and print the paper's tables with
    /// per-sequence rows (as `agentstar eval --batch BATCH/runs.json --per-sequence`), then the
    /// jobs with wall times, agent steps and tokens.
    #[command(after_help = "Example:\n  agentstar batch gather b1")]
    Gather(GatherArgs),
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum MethodArg {
    Track,
    Agent,
}

#[derive(clap::Args)]
pub struct PlanArgs {
    /// Capture directories (capture/v1), one job each.
    #[arg(required = true)]
    captures: Vec<PathBuf>,
    /// The batch directory to make (new, or empty).
    #[arg(long)]
    out: PathBuf,
    /// `track`: the tracker with a known model; `agent`: the agent loop on an `init` run.
    #[arg(long, value_enum, default_value = "track")]
    method: MethodArg,
    /// With --method agent: the model, PROVIDER:MODEL.
    #[arg(long)]
    model: Option<String>,
    /// With --method agent: the server's base URL.
    #[arg(long)]
    base_url: Option<String>,
    /// Track: the known model for every capture (default: each capture's model/scene.rhai);
    /// agent: the scene to start from (default: one box).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Metres per model unit (track default: each capture's model/pose.json; agent default 0.2).
    #[arg(long)]
    scale: Option<f64>,
    /// An argument appended to every job's command line (repeat; e.g. --job-arg=--evals --job-arg=600).
    #[arg(long = "job-arg", allow_hyphen_values = true)]
    job_args: Vec<String>,
    /// Wall-time limit per job, minutes (default: 60 for track, 600 for agent).
    #[arg(long)]
    time: Option<u64>,
    /// CPUs per job (default: 2 for track, 4 for agent).
    #[arg(long)]
    cpus_per_task: Option<u32>,
    /// Memory per job: 4096 (MB), 512M, 8G (default: 4G for track, 8G for agent).
    #[arg(long)]
    mem: Option<String>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct SlurmArgs {
    /// The batch directory (made by `agentstar batch plan`).
    batch: PathBuf,
    /// Wall-time limit per task, minutes (default: the plan's).
    #[arg(long)]
    time: Option<u64>,
    /// CPUs per task (default: the plan's).
    #[arg(long)]
    cpus_per_task: Option<u32>,
    /// Memory per task: 4096 (MB), 512M, 8G (default: the plan's).
    #[arg(long)]
    mem: Option<String>,
    /// The partition.
    #[arg(long)]
    partition: Option<String>,
    /// A further #SBATCH line without its prefix (repeat; e.g. --sbatch=--account=lab).
    #[arg(long = "sbatch", allow_hyphen_values = true)]
    sbatch_lines: Vec<String>,
    /// At most this many tasks at once (`--array=…%N`).
    #[arg(long)]
    max_parallel: Option<u32>,
    /// The array's job name (default: agentstar-BATCHNAME).
    #[arg(long)]
    job_name: Option<String>,
    /// The agentstar executable as the compute nodes see it (default: this one).
    #[arg(long)]
    agentstar: Option<PathBuf>,
    /// Submit the script with sbatch and print the job id.
    #[arg(long)]
    submit: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct LocalArgs {
    /// The batch directory.
    batch: PathBuf,
    /// Jobs at once (default: the cores divided by the plan's CPUs per job, at least 1).
    #[arg(short = 'j', long)]
    jobs: Option<usize>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct ExecArgs {
    /// The batch directory.
    batch: PathBuf,
    /// The job by its array task id (its index in the manifest).
    #[arg(long, conflicts_with = "job", required_unless_present = "job")]
    task: Option<usize>,
    /// The job by name.
    #[arg(long)]
    job: Option<String>,
}

#[derive(clap::Args)]
pub struct StatusArgs {
    /// The batch directory.
    batch: PathBuf,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct GatherArgs {
    /// The batch directory.
    batch: PathBuf,
    /// Surface samples per mesh for Chamfer distances (as `eval`).
    #[arg(long, default_value_t = 10_000)]
    samples: usize,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(c: BatchCommand) -> Result<ExitCode> {
    match c {
        BatchCommand::Plan(a) => run_plan(a),
        BatchCommand::Slurm(a) => run_slurm(a),
        BatchCommand::Local(a) => run_local(a),
        BatchCommand::Exec(a) => run_exec(a),
        BatchCommand::Status(a) => run_status(a),
        BatchCommand::Gather(a) => run_gather(a),
    }
}

// ---------------------------------------------------------------------------------------
// Files of a batch.

/// An opened batch: its directory (absolute) and manifest.
struct Batch {
    dir: PathBuf,
    manifest: Manifest,
}

impl Batch {
    fn open(dir: &Path) -> Result<Batch> {
        let dir = dir
            .canonicalize()
            .with_context(|| format!("{}: no such batch directory", dir.display()))?;
        let path = dir.join("batch.json");
        if !path.is_file() {
            bail!(
                "{}: not a batch (no batch.json); make one with `agentstar batch plan CAPTURES… --out {}`",
                dir.display(),
                dir.display()
            );
        }
        let manifest: Manifest = serde_json::from_str(&agentstar_data::read_text(&path)?)
            .with_context(|| format!("{}: not a {FORMAT} manifest", path.display()))?;
        manifest
            .check()
            .with_context(|| format!("{}", path.display()))?;
        Ok(Batch { dir, manifest })
    }

    fn job_dir(&self, j: &JobSpec) -> PathBuf {
        self.dir.join(&j.dir)
    }
    fn record_path(&self, j: &JobSpec) -> PathBuf {
        self.job_dir(j).join("record.json")
    }
    fn log_path(&self, j: &JobSpec) -> PathBuf {
        self.dir.join("logs").join(format!("{}.log", j.name))
    }
    fn submissions_path(&self) -> PathBuf {
        self.dir.join("slurm").join("submissions.json")
    }

    fn record(&self, j: &JobSpec) -> Result<Option<JobRecord>> {
        let p = self.record_path(j);
        if !p.is_file() {
            return Ok(None);
        }
        let r = serde_json::from_str(&agentstar_data::read_text(&p)?)
            .with_context(|| format!("{}: not a job record", p.display()))?;
        Ok(Some(r))
    }

    fn write_record(&self, j: &JobSpec, r: &JobRecord) -> Result<()> {
        Ok(agentstar_data::atomic::write_json(&self.record_path(j), r)?)
    }

    /// The job's result files inside the batch (relative): its poses and, for an agent
    /// run, its scene. A track job's known model is an input, not a result.
    fn outputs(&self, j: &JobSpec) -> Vec<PathBuf> {
        let mut v = vec![j.poses.clone()];
        if j.model.is_relative() && j.model != j.poses {
            v.push(j.model.clone());
        }
        v
    }

    /// What a result file is now: its size and SHA-256, or missing.
    fn output_now(&self, rel: &Path) -> Result<OutputNow> {
        use sha2::{Digest, Sha256};
        use std::io::Read;
        let path = self.dir.join(rel);
        match std::fs::metadata(&path) {
            Ok(m) if m.is_file() => {}
            _ => return Ok(OutputNow::Missing),
        }
        let mut file = std::fs::File::open(&path)
            .with_context(|| format!("{}: cannot read", path.display()))?;
        let mut hasher = Sha256::new();
        let mut buf = vec![0u8; 1 << 16];
        let mut bytes = 0u64;
        loop {
            let n = file
                .read(&mut buf)
                .with_context(|| format!("{}: cannot read", path.display()))?;
            if n == 0 {
                break;
            }
            bytes += n as u64;
            hasher.update(&buf[..n]);
        }
        let sha256 = hasher
            .finalize()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        Ok(OutputNow::Present { bytes, sha256 })
    }

    /// The digests of the job's result files as they are now (those that exist).
    fn digests(&self, j: &JobSpec) -> Result<Vec<OutputDigest>> {
        let mut v = vec![];
        for rel in self.outputs(j) {
            if let OutputNow::Present { bytes, sha256 } = self.output_now(&rel)? {
                v.push(OutputDigest {
                    path: rel,
                    bytes,
                    sha256,
                });
            }
        }
        Ok(v)
    }

    /// Why a finished job's results are no longer what it left (`None`: intact, or not
    /// finished). A record from before digests were kept is checked for a missing or empty
    /// result only.
    fn damage(&self, j: &JobSpec, r: &JobRecord) -> Result<Option<String>> {
        if !r.finished() {
            return Ok(None);
        }
        let recorded = r.outputs();
        let mut paths = self.outputs(j);
        for d in recorded {
            if !paths.contains(&d.path) {
                paths.push(d.path.clone());
            }
        }
        for rel in paths {
            let now = self.output_now(&rel)?;
            let why = match recorded.iter().find(|d| d.path == rel) {
                Some(d) => d.damage(&now),
                None => match now {
                    OutputNow::Missing => Some(format!("{} is missing", rel.display())),
                    OutputNow::Present { bytes: 0, .. } => {
                        Some(format!("{} is empty", rel.display()))
                    }
                    OutputNow::Present { .. } => None,
                },
            };
            if why.is_some() {
                return Ok(why);
            }
        }
        Ok(None)
    }

    fn submissions(&self) -> Result<Submissions> {
        let p = self.submissions_path();
        if !p.is_file() {
            return Ok(Submissions::default());
        }
        serde_json::from_str(&agentstar_data::read_text(&p)?)
            .with_context(|| format!("{}: not a submissions file", p.display()))
    }

    /// The resources of the jobs together: the largest of each.
    fn resources(&self) -> Resources {
        let mut r = Resources {
            time_min: 1,
            cpus_per_task: 1,
            mem_mb: 1,
        };
        for j in &self.manifest.jobs {
            r.time_min = r.time_min.max(j.resources.time_min);
            r.cpus_per_task = r.cpus_per_task.max(j.resources.cpus_per_task);
            r.mem_mb = r.mem_mb.max(j.resources.mem_mb);
        }
        r
    }
}

fn now_unix_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "unknown".into())
}

/// Whether `pid` is an `agentstar batch exec` on this machine (`None` where the process
/// table cannot be read).
fn exec_alive(pid: u32) -> Option<bool> {
    if !Path::new("/proc/self").exists() {
        return None;
    }
    let Ok(cmdline) = std::fs::read(format!("/proc/{pid}/cmdline")) else {
        return Some(false);
    };
    let is_zombie = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            s.rsplit_once(')')
                .map(|(_, rest)| rest.trim_start().starts_with('Z'))
        })
        .unwrap_or(false);
    let args: Vec<&[u8]> = cmdline.split(|&b| b == 0).collect();
    let is_exec = args.windows(2).any(|w| w[0] == b"batch" && w[1] == b"exec");
    Some(is_exec && !is_zombie)
}

fn absolute(p: &Path) -> Result<PathBuf> {
    p.canonicalize()
        .with_context(|| format!("{}: not found", p.display()))
}

fn shell_line(argv: &[String]) -> String {
    argv.iter()
        .map(|a| slurm::shell_quote(a))
        .collect::<Vec<_>>()
        .join(" ")
}

/// A temporary directory beside `target`, removed unless kept.
struct TempDir {
    path: PathBuf,
    keep: bool,
}

impl TempDir {
    fn keep(mut self) {
        self.keep = true;
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !self.keep {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

fn tempfile_dir(target: &Path) -> Result<TempDir> {
    let parent = target.parent().unwrap_or(Path::new("."));
    let stem = target
        .file_name()
        .map_or("batch".into(), |n| n.to_string_lossy().into_owned());
    for k in 0..1000u32 {
        let path = parent.join(format!(".{stem}.plan-{}-{k}", std::process::id()));
        match std::fs::create_dir(&path) {
            Ok(()) => return Ok(TempDir { path, keep: false }),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e).with_context(|| format!("{}: cannot make", path.display())),
        }
    }
    bail!("{}: no free temporary name", parent.display())
}
