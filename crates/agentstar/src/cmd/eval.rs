//! `agentstar eval`: the paper's metrics for a run against a capture's ground truth; with
//! `--batch`, many runs at once and the paper's tables.

use crate::common::OpenSession as _;
use crate::common::{print_json, Session, SessionArgs};
use agentstar_bench::table::{result_table, tables};
use agentstar_bench::{RunInfo, SequenceResult};
use agentstar_data::gt::GroundTruth;
use agentstar_eval::sequence::{evaluate, EvalConfig, PredSequence, SequenceMetrics};
use agentstar_reports::{EvalBatchReport, EvalReport};
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar eval --capture cap --model run/scene.rhai --poses run/pose.json\n  agentstar eval --batch runs.json --per-sequence   # runs.json: [{\"capture\": …, \"model\": …, \"poses\": …, \"label\": \"ours\", \"family\": \"arctic\"}]"
)]
pub struct Args {
    /// The capture directory (holding capture.json).
    #[arg(long, required_unless_present = "batch")]
    capture: Option<PathBuf>,
    /// The model: scene script (.rhai), URDF or mesh.
    #[arg(long, required_unless_present = "batch")]
    model: Option<PathBuf>,
    /// The pose file.
    #[arg(long, required_unless_present = "batch")]
    poses: Option<PathBuf>,
    /// The ground truth (default: CAPTURE/gt.json).
    #[arg(long)]
    gt: Option<PathBuf>,
    /// A JSON list of runs to evaluate together (capture, model, poses; optional gt, label,
    /// family: arctic, hot3d or itaco, seconds of wall time, the tracker's evaluations);
    /// prints the paper's tables.
    #[arg(long, conflicts_with_all = ["capture", "model", "poses", "gt"])]
    batch: Option<PathBuf>,
    /// With --batch: a row per sequence in the tables.
    #[arg(long)]
    per_sequence: bool,
    /// Surface samples per mesh for Chamfer distances.
    #[arg(long, default_value_t = 10_000)]
    samples: usize,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// One entry of a `--batch` file (also written by `agentstar batch gather`).
#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct BatchEntry {
    pub(crate) capture: PathBuf,
    pub(crate) model: PathBuf,
    pub(crate) poses: PathBuf,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) gt: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) label: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) family: Option<String>,
    /// The run's wall time in seconds, for the tables' wall-time columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) seconds: Option<f64>,
    /// The tracker's evaluations in the run, for the per-sequence table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) evaluations: Option<u64>,
}

/// The metrics of one run, and the ground truth's joints for the table rows.
pub(crate) fn evaluate_run(
    s: &Session,
    gt_path: &Path,
    samples: usize,
) -> Result<(SequenceMetrics, agentstar_eval::sequence::GtSequence)> {
    let gt = GroundTruth::load(gt_path)?;
    let frames: Vec<String> = s.capture.frames.iter().map(|f| f.name.clone()).collect();
    let seq = gt.sequence(&frames)?;
    let pred = PredSequence {
        model: &s.model.model,
        scale: s.scale(),
        poses: s
            .poses
            .iter()
            .map(|p| agentstar_geom::GenPose::new(p.generalised.pose, p.generalised.states.clone()))
            .collect(),
    };
    let cams: Vec<_> = s.capture.frames.iter().map(|f| f.camera).collect();
    let m = evaluate(
        &seq,
        &pred,
        &cams,
        &EvalConfig {
            samples,
            ..EvalConfig::default()
        },
    );
    Ok((m, seq))
}

/// The dataset family of a capture: given, or read from `capture.json`'s `dataset`.
fn family_of(s: &Session, given: Option<&str>) -> Result<String> {
    if let Some(f) = given {
        if !["arctic", "hot3d", "itaco"].contains(&f) {
            bail!("family `{f}` must be arctic, hot3d or itaco");
        }
        return Ok(f.to_string());
    }
    let d = s
        .capture
        .manifest
        .dataset
        .as_deref()
        .unwrap_or("")
        .to_lowercase();
    Ok(["arctic", "hot3d", "itaco"]
        .into_iter()
        .find(|f| d.contains(f))
        .unwrap_or("other")
        .to_string())
}

/// One run evaluated: its table row and its report.
#[allow(clippy::too_many_arguments)]
fn result_of(
    s: &Session,
    capture: &Path,
    model: &Path,
    poses: &Path,
    gt_path: &Path,
    label: &str,
    family: Option<&str>,
    samples: usize,
) -> Result<(SequenceResult, EvalReport)> {
    let (m, seq) = evaluate_run(s, gt_path, samples)?;
    let iou: Vec<f64> = (0..s.capture.frames.len())
        .map(|i| s.score(i, 0.0).map(|f| f.iou_visible.unwrap_or(0.0)))
        .collect::<Result<_>>()?;
    let id = capture
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| capture.display().to_string());
    let family = family_of(s, family)?;
    let r = SequenceResult::from_metrics(
        RunInfo {
            id,
            // The model file names the object (a scene's first part is only a part).
            object: model
                .file_stem()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned()),
            family: family.clone(),
            motion: String::new(),
            method: label.to_string(),
            seconds: 0.0,
            evaluations: 0,
        },
        &iou,
        &m,
        &seq,
    );
    let report = eval_report(label, &family, capture, poses, gt_path, &r);
    Ok((r, report))
}

/// The results of every run of a `--batch` file, in its order (relative paths are relative
/// to the file).
pub(crate) fn batch_results(
    path: &Path,
    samples: usize,
) -> Result<(Vec<SequenceResult>, Vec<EvalReport>)> {
    let entries: Vec<BatchEntry> = serde_json::from_str(&agentstar_data::read_text(path)?)
        .with_context(|| {
            format!(
                "{}: expected a list of {{capture, model, poses[, gt, label, family]}}",
                path.display()
            )
        })?;
    if entries.is_empty() {
        bail!("{}: the batch lists no runs", path.display());
    }
    let base = path.parent().unwrap_or(Path::new("."));
    let mut results = Vec::with_capacity(entries.len());
    let mut reports = Vec::with_capacity(entries.len());
    let bar = crate::common::progress(entries.len(), "eval");
    for (i, e) in entries.iter().enumerate() {
        bar.suspend(|| {
            eprintln!(
                "eval [{}/{}] {}",
                i + 1,
                entries.len(),
                base.join(&e.capture).display()
            )
        });
        let (r, report) = entry_result(base, e, samples)
            .with_context(|| format!("{}: run {}", path.display(), i + 1))?;
        results.push(r);
        reports.push(report);
    }
    Ok((results, reports))
}

/// One entry of a `--batch` file evaluated (relative paths are relative to `base`).
pub(crate) fn entry_result(
    base: &Path,
    e: &BatchEntry,
    samples: usize,
) -> Result<(SequenceResult, EvalReport)> {
    let (capture, model, poses) = (
        base.join(&e.capture),
        base.join(&e.model),
        base.join(&e.poses),
    );
    let s = Session::open(&capture, &model, &poses)?;
    let gt =
        e.gt.as_ref()
            .map_or_else(|| capture.join("gt.json"), |g| base.join(g));
    let (mut r, report) = result_of(
        &s,
        &capture,
        &model,
        &poses,
        &gt,
        e.label.as_deref().unwrap_or("run"),
        e.family.as_deref(),
        samples,
    )?;
    r.info.seconds = e.seconds.unwrap_or(0.0);
    r.info.evaluations = e
        .evaluations
        .map_or(0, |n| usize::try_from(n).unwrap_or(usize::MAX));
    Ok((r, report))
}

fn run_batch(a: &Args, path: &Path) -> Result<ExitCode> {
    let (results, reports) = batch_results(path, a.samples)?;
    if a.json {
        print_json(&EvalBatchReport { results: reports })?;
    } else {
        print!("{}", tables(&results, a.per_sequence));
    }
    Ok(ExitCode::SUCCESS)
}

pub fn run(a: Args) -> Result<ExitCode> {
    if let Some(b) = a.batch.clone() {
        return run_batch(&a, &b);
    }
    let (Some(capture), Some(model), Some(poses)) = (&a.capture, &a.model, &a.poses) else {
        bail!("give --capture, --model and --poses, or --batch FILE");
    };
    let session = SessionArgs {
        capture: capture.clone(),
        model: model.clone(),
        poses: poses.clone(),
    };
    let s = session.open()?;
    let gt_path = a.gt.clone().unwrap_or_else(|| capture.join("gt.json"));
    let (r, report) = result_of(&s, capture, model, poses, &gt_path, "run", None, a.samples)?;
    if a.json {
        print_json(&report)?;
        return Ok(ExitCode::SUCCESS);
    }
    print!("{}", result_table(&r));
    Ok(ExitCode::SUCCESS)
}

/// The report of one evaluated run (what `eval --json` prints).
pub(crate) fn eval_report(
    label: &str,
    family: &str,
    capture: &Path,
    poses: &Path,
    gt: &Path,
    r: &SequenceResult,
) -> EvalReport {
    EvalReport {
        label: label.to_string(),
        family: family.to_string(),
        capture: capture.to_path_buf(),
        poses: poses.to_path_buf(),
        gt: gt.to_path_buf(),
        iou_mean: r.iou_mean,
        iou_min: r.iou_min,
        metrics: r.metrics.clone(),
    }
}
