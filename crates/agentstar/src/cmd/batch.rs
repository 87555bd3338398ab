//! `agentstar batch plan|slurm|local|exec|status|gather`: one job per capture, run by Slurm
//! as a job array or here, each leaving its state in files; then the paper's tables over
//! every finished run. The types, the script and the parsers are in `agentstar-batch`; this
//! file reads and writes the files and runs `sbatch`, `squeue`, `sacct` and the jobs.

use crate::common::print_json;
use agentstar_agent::run::{init_run, RunDir};
use agentstar_batch::manifest::{parse_mem_mb, CaptureInput, FORMAT};
use agentstar_batch::slurm::{self, ScriptConfig, Submission, Submissions, TaskState};
use agentstar_batch::state::summary;
use agentstar_batch::table::{jobs_table, AgentSpend, JobRow};
use agentstar_batch::{
    classify, plan, Exit, JobRecord, JobSpec, JobState, Manifest, Method, MethodPlan, Observation,
    OutputDigest, OutputNow, PlanConfig, Queue, Resources, Runner,
};
use agentstar_bench::table::tables;
use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};

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

fn mem_flag(mem: Option<&str>) -> Result<Option<u64>> {
    mem.map(|m| parse_mem_mb(m).map_err(|e| anyhow!("--mem: {e}")))
        .transpose()
}

// ---------------------------------------------------------------------------------------
// plan

fn absolute(p: &Path) -> Result<PathBuf> {
    p.canonicalize()
        .with_context(|| format!("{}: not found", p.display()))
}

/// `--scene`: a model file that loads now, not in every job later. Only a regular file is
/// read, and only as far as its kind's limit (`/dev/zero`, a FIFO or a directory is refused
/// before anything is read).
fn checked_scene(p: &Path) -> Result<PathBuf> {
    let path = absolute(p)?;
    let meta = std::fs::metadata(&path)
        .with_context(|| format!("--scene {}: cannot read", p.display()))?;
    if !meta.is_file() {
        bail!(
            "--scene {}: not a regular file (a directory, device, FIFO or socket); give a scene script (.rhai), a URDF or a mesh",
            p.display()
        );
    }
    agentstar_data::scenefile::load_model(&path)
        .map_err(|e| anyhow!("--scene {}: {e}", p.display()))?;
    Ok(path)
}

fn run_plan(a: PlanArgs) -> Result<ExitCode> {
    let method = a.method;
    if method == MethodArg::Track && (a.model.is_some() || a.base_url.is_some()) {
        bail!("--model and --base-url are for --method agent; a track job's model is --scene FILE");
    }
    if let Some(s) = a.scale {
        if !(s.is_finite() && s > 0.0) {
            bail!("--scale {s}: metres per model unit, a positive number");
        }
    }
    // Everything is checked before anything is written.
    let mut captures: Vec<CaptureInput> = Vec::with_capacity(a.captures.len());
    for (k, c) in a.captures.iter().enumerate() {
        let path = absolute(c)?;
        // The same capture under two spellings (`caps/box caps/../caps/box`, a symlink)
        // would be two jobs on one capture, counted twice in the tables.
        if let Some(first) = captures.iter().position(|x| x.path == path) {
            bail!(
                "{} and {} are the same capture ({}); give each capture once",
                a.captures[first].display(),
                a.captures[k].display(),
                path.display()
            );
        }
        agentstar_data::capture::Capture::open(&path).map_err(|problems| {
            anyhow!(
                "{}: not a valid capture ({} problem(s); run `agentstar validate {}`): {}",
                c.display(),
                problems.len(),
                c.display(),
                problems
                    .iter()
                    .take(3)
                    .map(|p| format!("{}: {}", p.path.display(), p.message))
                    .collect::<Vec<_>>()
                    .join("; ")
            )
        })?;
        captures.push(CaptureInput {
            has_gt: path.join("gt.json").is_file(),
            path,
        });
    }
    let scene = a.scene.as_deref().map(checked_scene).transpose()?;
    let method_plan = match method {
        MethodArg::Track => {
            for c in &captures {
                if scene.is_none() && !c.path.join("model").join("scene.rhai").is_file() {
                    bail!(
                        "{}: has no model/scene.rhai to track with; give --scene FILE (the known model)",
                        c.path.display()
                    );
                }
                if a.scale.is_none() && !c.path.join("model").join("pose.json").is_file() {
                    bail!(
                        "{}: has no model/pose.json to take the scale from; give --scale S",
                        c.path.display()
                    );
                }
            }
            MethodPlan::Track {
                model: scene.clone(),
                scale: a.scale,
            }
        }
        MethodArg::Agent => {
            let model = a
                .model
                .clone()
                .ok_or_else(|| anyhow!("--method agent needs --model PROVIDER:MODEL"))?;
            if let Err(e) = agentstar_agent::llm::ModelConfig::parse(&model, a.base_url.as_deref())
            {
                if e.starts_with("no API key") {
                    eprintln!("note: {e}; the jobs need it in their environment");
                } else {
                    bail!("--model {e}");
                }
            }
            MethodPlan::Agent {
                model,
                base_url: a.base_url.clone(),
            }
        }
    };
    let batch_method = match method {
        MethodArg::Track => Method::Track,
        MethodArg::Agent => Method::Agent,
    };
    let defaults = Resources::default_for(batch_method);
    let resources = Resources {
        time_min: a.time.unwrap_or(defaults.time_min),
        cpus_per_task: a.cpus_per_task.unwrap_or(defaults.cpus_per_task),
        mem_mb: mem_flag(a.mem.as_deref())?.unwrap_or(defaults.mem_mb),
    };
    resources.check()?;
    if a.out.exists()
        && std::fs::read_dir(&a.out)
            .with_context(|| format!("{}: cannot list", a.out.display()))?
            .next()
            .is_some()
    {
        bail!(
            "{}: exists and is not empty; choose a new batch directory",
            a.out.display()
        );
    }
    let name = a
        .out
        .file_name()
        .ok_or_else(|| anyhow!("{}: name a directory", a.out.display()))?
        .to_owned();
    let parent = a
        .out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent)
        .with_context(|| format!("{}: cannot make the directory", parent.display()))?;
    let batch_dir = absolute(parent)?.join(&name);
    let manifest = plan(
        &captures,
        &PlanConfig {
            batch_dir: batch_dir.clone(),
            method: method_plan,
            extra_args: a.job_args.clone(),
            resources,
        },
    )?;

    // Built in a temporary sibling and renamed into place: a failed plan leaves nothing.
    let tmp = tempfile_dir(&batch_dir)?;
    let root = tmp.path.clone();
    let scene_text = match (&scene, method) {
        (Some(p), MethodArg::Agent) => Some(agentstar_data::read_text(p)?),
        _ => None,
    };
    for j in &manifest.jobs {
        let dir = root.join(&j.dir);
        match j.method {
            Method::Agent => {
                init_run(
                    &dir,
                    &j.capture,
                    scene_text.as_deref(),
                    a.scale.unwrap_or(0.2),
                )
                .with_context(|| format!("job {}", j.name))?;
            }
            Method::Track => std::fs::create_dir_all(&dir)
                .with_context(|| format!("{}: cannot make the directory", dir.display()))?,
        }
        agentstar_data::atomic::write_json(&dir.join("job.json"), j)?;
    }
    for d in ["logs", "slurm"] {
        std::fs::create_dir_all(root.join(d))
            .with_context(|| format!("{}: cannot make the directory", root.join(d).display()))?;
    }
    agentstar_data::atomic::write_json(&root.join("batch.json"), &manifest)?;
    if batch_dir.exists() {
        std::fs::remove_dir(&batch_dir).with_context(|| {
            format!(
                "{}: cannot replace the empty directory",
                batch_dir.display()
            )
        })?;
    }
    std::fs::rename(&root, &batch_dir)
        .with_context(|| format!("{}: cannot move the batch into place", batch_dir.display()))?;
    tmp.keep();

    let with_gt = manifest.jobs.iter().filter(|j| j.gt.is_some()).count();
    if a.json {
        print_json(&manifest)?;
    } else {
        println!(
            "planned {} {} job(s) in {} ({with_gt} with ground truth; {} min, {} CPUs, {} MB each)",
            manifest.jobs.len(),
            manifest.label,
            batch_dir.display(),
            resources.time_min,
            resources.cpus_per_task,
            resources.mem_mb
        );
        for j in &manifest.jobs {
            println!(
                "  {:>3} {}: agentstar {}",
                j.index,
                j.name,
                shell_line(&j.argv)
            );
        }
        println!(
            "then: agentstar batch slurm {0} --submit   (or: agentstar batch local {0} -j N)",
            batch_dir.display()
        );
    }
    Ok(ExitCode::SUCCESS)
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

// ---------------------------------------------------------------------------------------
// status

/// What Slurm says about the batch's submissions, where it can be asked.
struct SchedulerView {
    /// `None`: no squeue, or no submissions to ask about.
    queue: Option<Vec<TaskState>>,
    accounting: Vec<TaskState>,
    job_ids: Vec<u64>,
}

fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join(program).is_file()))
}

/// Runs a scheduler command with a bound on its time; stdout, stderr and success.
fn scheduler_command(program: &str, args: &[String]) -> Result<(String, String, bool)> {
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("starting {program}"))?;
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        if child.try_wait()?.is_some() {
            break;
        }
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            bail!("{program} did not answer within 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let out = child.wait_with_output()?;
    Ok((
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        out.status.success(),
    ))
}

fn scheduler_view(batch: &Batch, records: &[Option<JobRecord>]) -> Result<SchedulerView> {
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
fn states(batch: &Batch) -> Result<(Vec<Option<JobRecord>>, Vec<JobState>)> {
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
struct JobReport {
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
fn agent_spend(batch: &Batch, j: &JobSpec) -> Result<Option<AgentSpend>> {
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

fn job_rows(
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

fn reports(batch: &Batch, rows: &[JobRow]) -> Vec<JobReport> {
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

fn run_status(a: StatusArgs) -> Result<ExitCode> {
    let batch = Batch::open(&a.batch)?;
    let (records, states) = states(&batch)?;
    let rows = job_rows(&batch, &records, &states)?;
    if a.json {
        print_json(&serde_json::json!({
            "batch": batch.dir, "summary": summary(&states), "jobs": reports(&batch, &rows)
        }))?;
    } else {
        println!("{}: {}\n", batch.dir.display(), summary(&states));
        print!("{}", jobs_table(&rows));
    }
    Ok(ExitCode::SUCCESS)
}

// ---------------------------------------------------------------------------------------
// slurm

fn run_slurm(a: SlurmArgs) -> Result<ExitCode> {
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
fn exit_of(status: std::process::ExitStatus) -> Exit {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => Exit::Code(c),
        (None, Some(s)) => Exit::Signal(s),
        (None, None) => Exit::Code(-1),
    }
}

#[cfg(not(unix))]
fn exit_of(status: std::process::ExitStatus) -> Exit {
    Exit::Code(status.code().unwrap_or(-1))
}

fn exit_code_of(e: Exit) -> ExitCode {
    match e {
        Exit::Code(c) => ExitCode::from(u8::try_from(c).unwrap_or(1)),
        Exit::Signal(s) => ExitCode::from(u8::try_from(128 + s).unwrap_or(1)),
    }
}

fn slurm_runner() -> Option<Runner> {
    let get = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<u64>().ok());
    Some(Runner::Slurm {
        job_id: get("SLURM_ARRAY_JOB_ID")?,
        task_id: get("SLURM_ARRAY_TASK_ID")?,
    })
}

fn run_exec(a: ExecArgs) -> Result<ExitCode> {
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

fn run_local(a: LocalArgs) -> Result<ExitCode> {
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
    let (records, states) = self::states(&batch)?;
    let rows = job_rows(&batch, &records, &states)?;
    if a.json {
        print_json(&serde_json::json!({
            "batch": batch.dir, "summary": summary(&states), "jobs": reports(&batch, &rows)
        }))?;
    } else {
        println!("{}: {}", batch.dir.display(), summary(&states));
    }
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

// ---------------------------------------------------------------------------------------
// gather

/// The tracker's evaluations in a finished job: what `agentstar track` printed in the last
/// attempt's log (track), or the agent's `track` calls in its ledger (agent).
fn evaluations(batch: &Batch, j: &JobSpec) -> Option<u64> {
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

fn run_gather(a: GatherArgs) -> Result<ExitCode> {
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
