//! `batch plan`: every capture checked (once each), the scene and resources refused when out
//! of range, then the batch directory and its manifest written.

use super::*;
use crate::common::print_json;
use agentstar_agent::run::init_run;
use agentstar_batch::manifest::{parse_mem_mb, CaptureInput};
use agentstar_batch::{plan, Method, MethodPlan, PlanConfig, Resources};
use anyhow::{anyhow, bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

pub(super) fn mem_flag(mem: Option<&str>) -> Result<Option<u64>> {
    mem.map(|m| parse_mem_mb(m).map_err(|e| anyhow!("--mem: {e}")))
        .transpose()
}

/// `--scene`: a model file that loads now, not in every job later. Only a regular file is
/// read, and only as far as its kind's limit (`/dev/zero`, a FIFO or a directory is refused
/// before anything is read).
pub(super) fn checked_scene(p: &Path) -> Result<PathBuf> {
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

pub(super) fn run_plan(a: PlanArgs) -> Result<ExitCode> {
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
