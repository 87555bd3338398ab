//! Batches of agentstar jobs, one per capture, for a scheduler we do not write: Slurm runs
//! them as a job array (or `agentstar batch local` runs them here), and every job leaves its
//! state in files so that a batch can be inspected, resumed and gathered from the files alone.
//!
//! ```text
//! BATCH/
//!   batch.json                 the manifest: method, resources, every job's command line
//!   jobs/NAME/job.json         one job's spec (the same as in the manifest)
//!   jobs/NAME/record.json      its attempts: host, pids, start, end, exit code, and the size and
//!                              SHA-256 of its result files when it finished (written by the job)
//!   jobs/NAME/…                the job's own output: a run directory (agent) or pose.json (track)
//!   logs/NAME.log              the job's stdout and stderr, every attempt appended
//!   slurm/array-N.sbatch       the job-array script of submission N
//!   slurm/submissions.json     what was submitted: Slurm job ids and the jobs of each array
//!   slurm/exit-codes.tsv       one line per finished array task: job id, task, exit code
//!   runs.json                  written by `gather`: the finished runs in `eval --batch` form
//! ```
//!
//! This crate does no I/O: it holds the types of those files, the script generator, the
//! parsers of `sbatch`, `squeue` and `sacct` output, the rule that turns a record and what
//! the scheduler says into a job state, and the jobs table. The binary reads and writes the
//! files and runs the processes.

mod error;
pub mod manifest;
pub mod record;
pub mod slurm;
pub mod state;
pub mod table;

pub use error::BatchError;
pub use manifest::{plan, JobSpec, Manifest, Method, MethodPlan, PlanConfig, Resources};
pub use record::{Attempt, Exit, JobRecord, OutputDigest, OutputNow, Runner};
pub use state::{classify, JobState, Observation, Queue};

/// Results of this crate.
pub type Result<T> = std::result::Result<T, BatchError>;
