//! The batch manifest (`batch.json`) and the plan that makes it: one job per capture, each
//! with the command line it runs, the files it produces for evaluation, and its resources.

use crate::{BatchError, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The format tag of `batch.json`.
pub const FORMAT: &str = "agentstar-batch/v1";

/// How a job works on its capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// `agentstar track` with a known model: no agent.
    Track,
    /// `agentstar run` on a run directory made by `agentstar init`: the agent loop.
    Agent,
}

impl Method {
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Track => "track",
            Method::Agent => "agent",
        }
    }
}

/// What one job may use, per Slurm array task.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Resources {
    /// Wall-time limit, minutes.
    pub time_min: u64,
    pub cpus_per_task: u32,
    /// Memory, megabytes.
    pub mem_mb: u64,
}

/// The longest wall-time limit, minutes: Slurm keeps time limits in 32 bits.
pub const MAX_TIME_MIN: u64 = u32::MAX as u64 - 1;
/// The most memory a job may ask for, megabytes (1 PiB; no node has more).
pub const MAX_MEM_MB: u64 = 1 << 30;

impl Resources {
    /// Defaults by method: a track job is minutes on two cores; an agent job is the paper's
    /// long budget (it resumes from its ledger when the limit cuts it).
    pub fn default_for(method: Method) -> Resources {
        match method {
            Method::Track => Resources {
                time_min: 60,
                cpus_per_task: 2,
                mem_mb: 4096,
            },
            Method::Agent => Resources {
                time_min: 600,
                cpus_per_task: 4,
                mem_mb: 8192,
            },
        }
    }

    /// Refuses what no scheduler can carry out: a zero or overlong time limit, no CPUs, no
    /// memory or more than [`MAX_MEM_MB`]. The message names the flag (`--time`, …).
    pub fn check(&self) -> Result<()> {
        check_time_min(self.time_min)?;
        check_cpus(self.cpus_per_task)?;
        if self.mem_mb == 0 || self.mem_mb > MAX_MEM_MB {
            return Err(BatchError::Invalid(format!(
                "--mem {} MB: out of range (1 MB to {MAX_MEM_MB} MB, i.e. 1024T)",
                self.mem_mb
            )));
        }
        Ok(())
    }

    /// `--time` in Slurm's `D-HH:MM:00` form.
    pub fn slurm_time(&self) -> String {
        let (d, rem) = (self.time_min / 1440, self.time_min % 1440);
        format!("{d}-{:02}:{:02}:00", rem / 60, rem % 60)
    }
}

/// A wall-time limit in minutes: at least 1, at most [`MAX_TIME_MIN`].
pub fn check_time_min(t: u64) -> Result<u64> {
    if t == 0 {
        return Err(BatchError::Invalid(
            "--time 0: a job needs a wall-time limit of at least 1 minute".into(),
        ));
    }
    if t > MAX_TIME_MIN {
        return Err(BatchError::Invalid(format!(
            "--time {t}: out of range (at most {MAX_TIME_MIN} minutes, Slurm's largest limit)"
        )));
    }
    Ok(t)
}

/// CPUs per task: at least 1.
pub fn check_cpus(c: u32) -> Result<u32> {
    if c == 0 {
        return Err(BatchError::Invalid(
            "--cpus-per-task 0: a job needs at least 1 CPU".into(),
        ));
    }
    Ok(c)
}

/// Parses a memory size: `4096` (MB), `512M`, `8G`, `1T`; from 1 MB to [`MAX_MEM_MB`].
pub fn parse_mem_mb(s: &str) -> Result<u64> {
    let t = s.trim();
    let bad = || BatchError::Invalid(format!("memory `{s}`: a size such as 4096, 512M, 8G or 1T"));
    let (num, mult) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let mult: Option<u64> = match c.to_ascii_uppercase() {
                // Kilobytes: rounded up to whole megabytes.
                'K' => None,
                'M' => Some(1),
                'G' => Some(1024),
                'T' => Some(1024 * 1024),
                _ => return Err(bad()),
            };
            (&t[..i], mult)
        }
        _ => (t, Some(1)),
    };
    let n = parse_number(num, s)?;
    if n == 0 {
        return Err(BatchError::Invalid(format!(
            "memory `{s}`: must be more than zero"
        )));
    }
    let mb = match mult {
        None => Some(n.div_ceil(1024)),
        Some(m) => n.checked_mul(m),
    };
    match mb {
        Some(mb) if mb <= MAX_MEM_MB => Ok(mb),
        _ => Err(BatchError::Invalid(format!(
            "memory `{s}`: out of range (at most {MAX_MEM_MB} MB, i.e. 1024T)"
        ))),
    }
}

fn parse_number(num: &str, whole: &str) -> Result<u64> {
    num.parse::<u64>().map_err(|_| {
        BatchError::Invalid(format!(
            "memory `{whole}`: a size such as 4096, 512M, 8G or 1T"
        ))
    })
}

/// One job: a capture and the command that works on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobSpec {
    /// The job's position in the manifest; also its Slurm array task id.
    pub index: usize,
    /// Unique in the batch; names the job's directory and log.
    pub name: String,
    pub method: Method,
    /// The capture (absolute).
    pub capture: PathBuf,
    /// The job's directory, relative to the batch directory (`jobs/NAME`).
    pub dir: PathBuf,
    /// The arguments after `agentstar` (absolute paths: jobs run wherever the scheduler starts them).
    pub argv: Vec<String>,
    /// The model file that gets evaluated (the known model of a track job; the run's scene).
    pub model: PathBuf,
    /// The pose file the job writes.
    pub poses: PathBuf,
    /// The capture's ground truth, when it has one (`CAPTURE/gt.json`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gt: Option<PathBuf>,
    pub resources: Resources,
}

/// `batch.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// [`FORMAT`].
    pub format: String,
    pub method: Method,
    /// The label of the method in the tables (`track`, or the agent's `PROVIDER:MODEL`).
    pub label: String,
    pub jobs: Vec<JobSpec>,
}

impl Manifest {
    /// Checks what serde cannot: the format tag, indices in order, unique names.
    pub fn check(&self) -> Result<()> {
        if self.format != FORMAT {
            return Err(BatchError::Invalid(format!(
                "format `{}`: this agentstar reads `{FORMAT}`",
                self.format
            )));
        }
        let mut names = BTreeSet::new();
        let mut captures = BTreeSet::new();
        for (i, j) in self.jobs.iter().enumerate() {
            if !captures.insert(&j.capture) {
                return Err(BatchError::Invalid(format!(
                    "job `{}`: capture {} appears twice",
                    j.name,
                    j.capture.display()
                )));
            }
            if j.index != i {
                return Err(BatchError::Invalid(format!(
                    "job `{}` has index {} at position {i}",
                    j.name, j.index
                )));
            }
            if !names.insert(&j.name) {
                return Err(BatchError::Invalid(format!(
                    "job name `{}` appears twice",
                    j.name
                )));
            }
            j.resources
                .check()
                .map_err(|e| BatchError::Invalid(format!("job `{}`: {e}", j.name)))?;
        }
        Ok(())
    }

    /// The job named `name`, or the one at index `name` when it is a number.
    pub fn job(&self, name: &str) -> Option<&JobSpec> {
        self.jobs
            .iter()
            .find(|j| j.name == name)
            .or_else(|| name.parse::<usize>().ok().and_then(|i| self.jobs.get(i)))
    }
}

/// The method of a plan, with what it needs.
#[derive(Debug, Clone, PartialEq)]
pub enum MethodPlan {
    /// Track every capture with a known model.
    Track {
        /// One model for every capture; `None`: each capture's own `model/scene.rhai`
        /// (what `agentstar synth` writes).
        model: Option<PathBuf>,
        /// Metres per model unit; `None`: each capture's `model/pose.json` scale.
        scale: Option<f64>,
    },
    /// An agent per capture, on a run made by `agentstar init`.
    Agent {
        /// `PROVIDER:MODEL`.
        model: String,
        base_url: Option<String>,
    },
}

/// What `plan` needs besides the captures.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanConfig {
    /// The batch directory (absolute).
    pub batch_dir: PathBuf,
    pub method: MethodPlan,
    /// Arguments appended to every job's command line (`--evals 600`, `--max-steps 150`).
    pub extra_args: Vec<String>,
    pub resources: Resources,
}

/// A capture to plan a job for (absolute path), and whether it has `gt.json`.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureInput {
    pub path: PathBuf,
    pub has_gt: bool,
}

/// A job name from a capture directory's name: letters, digits, `.`, `_` and `-`; others
/// become `_`.
fn base_name(capture: &Path) -> String {
    let raw = capture
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let s: String = raw
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect();
    let s = s.trim_start_matches('.').to_string();
    if s.is_empty() {
        "capture".into()
    } else {
        s
    }
}

fn path_arg(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// One job per capture, in the order given; names from the capture directories, made
/// unique with `-2`, `-3`, … Paths must be absolute.
pub fn plan(captures: &[CaptureInput], cfg: &PlanConfig) -> Result<Manifest> {
    if captures.is_empty() {
        return Err(BatchError::Invalid("no captures to plan jobs for".into()));
    }
    if !cfg.batch_dir.is_absolute() {
        return Err(BatchError::Invalid(format!(
            "{}: the batch directory must be an absolute path",
            cfg.batch_dir.display()
        )));
    }
    cfg.resources.check()?;
    let mut used = BTreeSet::new();
    let mut jobs = Vec::with_capacity(captures.len());
    for (index, c) in captures.iter().enumerate() {
        if !c.path.is_absolute() {
            return Err(BatchError::Invalid(format!(
                "{}: captures must be absolute paths",
                c.path.display()
            )));
        }
        if captures[..index].iter().any(|d| d.path == c.path) {
            return Err(BatchError::Invalid(format!(
                "{}: the same capture is given twice; give each capture once",
                c.path.display()
            )));
        }
        let base = base_name(&c.path);
        let mut name = base.clone();
        let mut k = 2;
        while !used.insert(name.clone()) {
            name = format!("{base}-{k}");
            k += 1;
        }
        let dir = PathBuf::from("jobs").join(&name);
        let abs_dir = cfg.batch_dir.join(&dir);
        let (method, mut argv, model, poses) = match &cfg.method {
            MethodPlan::Track { model, scale } => {
                let model = model
                    .clone()
                    .unwrap_or_else(|| c.path.join("model").join("scene.rhai"));
                let poses = abs_dir.join("pose.json");
                let mut argv = vec![
                    "track".to_string(),
                    path_arg(&c.path),
                    "--model".into(),
                    path_arg(&model),
                ];
                match scale {
                    Some(s) => argv.extend(["--scale".into(), format!("{s}")]),
                    None => argv.extend([
                        "--scale-from".into(),
                        path_arg(&c.path.join("model").join("pose.json")),
                    ]),
                }
                argv.extend(["--out".into(), path_arg(&poses)]);
                (Method::Track, argv, model, dir.join("pose.json"))
            }
            MethodPlan::Agent { model, base_url } => {
                let mut argv = vec![
                    "run".to_string(),
                    path_arg(&abs_dir),
                    "--model".into(),
                    model.clone(),
                ];
                if let Some(u) = base_url {
                    argv.extend(["--base-url".into(), u.clone()]);
                }
                (
                    Method::Agent,
                    argv,
                    dir.join("scene.rhai"),
                    dir.join("pose.json"),
                )
            }
        };
        argv.extend(cfg.extra_args.iter().cloned());
        jobs.push(JobSpec {
            index,
            name,
            method,
            capture: c.path.clone(),
            dir,
            argv,
            model,
            poses,
            gt: c.has_gt.then(|| c.path.join("gt.json")),
            resources: cfg.resources,
        });
    }
    let (method, label) = match &cfg.method {
        MethodPlan::Track { .. } => (Method::Track, "track".to_string()),
        MethodPlan::Agent { model, .. } => (Method::Agent, model.clone()),
    };
    Ok(Manifest {
        format: FORMAT.into(),
        method,
        label,
        jobs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(method: MethodPlan) -> PlanConfig {
        PlanConfig {
            batch_dir: "/b".into(),
            method,
            extra_args: vec!["--evals".into(), "300".into()],
            resources: Resources::default_for(Method::Track),
        }
    }

    fn caps(names: &[&str]) -> Vec<CaptureInput> {
        names
            .iter()
            .map(|n| CaptureInput {
                path: PathBuf::from(n),
                has_gt: n.contains("gt"),
            })
            .collect()
    }

    #[test]
    fn a_track_plan_names_jobs_uniquely_and_writes_their_command_lines() {
        let m = plan(
            &caps(&["/data/a/cap gt", "/other/cap gt", "/x/.hidden"]),
            &cfg(MethodPlan::Track {
                model: None,
                scale: None,
            }),
        )
        .expect("plan");
        m.check().expect("valid");
        let names: Vec<&str> = m.jobs.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["cap_gt", "cap_gt-2", "hidden"]);
        assert_eq!(
            m.jobs[1].argv,
            [
                "track",
                "/other/cap gt",
                "--model",
                "/other/cap gt/model/scene.rhai",
                "--scale-from",
                "/other/cap gt/model/pose.json",
                "--out",
                "/b/jobs/cap_gt-2/pose.json",
                "--evals",
                "300"
            ]
        );
        assert_eq!(m.jobs[1].poses, PathBuf::from("jobs/cap_gt-2/pose.json"));
        assert_eq!(m.jobs[1].gt, Some(PathBuf::from("/other/cap gt/gt.json")));
        assert_eq!(m.jobs[2].gt, None);
        assert_eq!(m.job("cap_gt-2").map(|j| j.index), Some(1));
        assert_eq!(m.job("2").map(|j| j.name.as_str()), Some("hidden"));
        assert_eq!(m.label, "track");
    }

    #[test]
    fn an_agent_plan_runs_the_run_directory_with_the_model() {
        let m = plan(
            &caps(&["/c/laptop"]),
            &cfg(MethodPlan::Agent {
                model: "ollama:qwen2.5vl".into(),
                base_url: Some("http://127.0.0.1:11434/v1".into()),
            }),
        )
        .expect("plan");
        assert_eq!(
            m.jobs[0].argv,
            [
                "run",
                "/b/jobs/laptop",
                "--model",
                "ollama:qwen2.5vl",
                "--base-url",
                "http://127.0.0.1:11434/v1",
                "--evals",
                "300"
            ]
        );
        assert_eq!(m.jobs[0].model, PathBuf::from("jobs/laptop/scene.rhai"));
        assert_eq!(m.label, "ollama:qwen2.5vl");
        assert_eq!(m.method, Method::Agent);
    }

    #[test]
    fn plans_refuse_relative_paths_and_empty_input() {
        let c = cfg(MethodPlan::Track {
            model: None,
            scale: Some(0.2),
        });
        assert!(plan(&[], &c).is_err());
        assert!(plan(&caps(&["rel/cap"]), &c).is_err());
        let e = plan(&caps(&["/c/box", "/d/mug", "/c/box"]), &c)
            .expect_err("a capture twice")
            .to_string();
        assert!(e.contains("/c/box") && e.contains("twice"), "{e}");
        let mut rel = c.clone();
        rel.batch_dir = "b".into();
        assert!(plan(&caps(&["/cap"]), &rel).is_err());
    }

    #[test]
    fn a_manifest_round_trips_and_its_checks_catch_edits() {
        let mut m = plan(
            &caps(&["/a", "/b"]),
            &cfg(MethodPlan::Track {
                model: Some("/m.rhai".into()),
                scale: Some(0.25),
            }),
        )
        .expect("plan");
        let text = serde_json::to_string(&m).expect("json");
        let back: Manifest = serde_json::from_str(&text).expect("parse");
        assert_eq!(back, m);
        assert!(m.jobs[0].argv.contains(&"0.25".to_string()));
        m.jobs[1].name = m.jobs[0].name.clone();
        assert!(m.check().is_err());
        m.jobs[1].name = "z".into();
        let other = m.jobs[1].capture.clone();
        m.jobs[1].capture = m.jobs[0].capture.clone();
        assert!(m.check().is_err());
        m.jobs[1].capture = other;
        m.check().expect("valid again");
        m.jobs[1].index = 5;
        assert!(m.check().is_err());
        m.jobs[1].index = 1;
        m.format = "other".into();
        assert!(m.check().is_err());
    }

    #[test]
    fn memory_sizes_and_time_limits_read_as_slurm_expects() {
        assert_eq!(parse_mem_mb("4096").ok(), Some(4096));
        assert_eq!(parse_mem_mb("512M").ok(), Some(512));
        assert_eq!(parse_mem_mb("8G").ok(), Some(8192));
        assert_eq!(parse_mem_mb("1t").ok(), Some(1 << 20));
        assert_eq!(parse_mem_mb("2048K").ok(), Some(2));
        for bad in ["", "G", "8X", "-1G", "0", "1.5G"] {
            assert!(parse_mem_mb(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_mem_mb("1024T").ok(), Some(MAX_MEM_MB));
        // Sizes whose megabytes do not fit, or are past any node, are refused, not wrapped.
        for huge in [
            "99999999999999T",
            "18446744073709551615G",
            "1025T",
            "1073741825",
        ] {
            let e = parse_mem_mb(huge).expect_err(huge).to_string();
            assert!(e.contains("out of range") && e.contains(huge), "{e}");
        }
        let r = Resources {
            time_min: 1530,
            cpus_per_task: 1,
            mem_mb: 1,
        };
        assert_eq!(r.slurm_time(), "1-01:30:00");
        r.check().expect("valid");
    }

    #[test]
    fn zero_time_and_zero_cpus_are_refused_not_raised_to_one() {
        let ok = Resources::default_for(Method::Track);
        for (bad, flag) in [
            (Resources { time_min: 0, ..ok }, "--time 0"),
            (
                Resources {
                    cpus_per_task: 0,
                    ..ok
                },
                "--cpus-per-task 0",
            ),
            (Resources { mem_mb: 0, ..ok }, "--mem"),
            (
                Resources {
                    time_min: MAX_TIME_MIN + 1,
                    ..ok
                },
                "--time",
            ),
        ] {
            let e = bad.check().expect_err(flag).to_string();
            assert!(e.contains(flag), "{e}");
            let mut c = cfg(MethodPlan::Track {
                model: None,
                scale: Some(0.2),
            });
            c.resources = bad;
            assert!(plan(&caps(&["/cap"]), &c).is_err());
        }
        let mut m = plan(
            &caps(&["/cap"]),
            &cfg(MethodPlan::Track {
                model: None,
                scale: Some(0.2),
            }),
        )
        .expect("plan");
        m.jobs[0].resources.time_min = 0;
        let e = m.check().expect_err("an edited manifest").to_string();
        assert!(e.contains("job `cap`") && e.contains("--time 0"), "{e}");
    }
}
