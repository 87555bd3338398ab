//! `agentstar pose commit | history | restore`: apply a chosen candidate from a verb's report
//! to `pose.json` atomically; every committed version is kept with the command that made
//! it, and any earlier version can be restored.

use crate::common::print_json;
use agentstar_data::posefile::{FrameEntry, PoseFile, PoseJson};
use anyhow::{anyhow, bail, Context, Result};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Subcommand)]
pub enum PoseCommand {
    /// Apply a ranked candidate of a report (sweep, apply, osweep, oapply, oapply-all) to pose.json.
    #[command(
        after_help = "Example:\n  agentstar pose commit --poses run/pose.json --report report.json --rank 0"
    )]
    Commit {
        #[arg(long)]
        poses: PathBuf,
        /// The verb's JSON report.
        #[arg(long)]
        report: PathBuf,
        /// The candidate's rank (0 = best).
        #[arg(long, default_value_t = 0)]
        rank: usize,
        /// Only these frames of the report (comma separated names); default every frame in it.
        #[arg(long)]
        frames: Option<String>,
        /// Print the result as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// List the committed versions of pose.json.
    #[command(after_help = "Example:\n  agentstar pose history --poses run/pose.json")]
    History {
        #[arg(long)]
        poses: PathBuf,
        /// Print the result as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Restore an earlier version (recorded as a new version).
    #[command(after_help = "Example:\n  agentstar pose restore --poses run/pose.json --version 3")]
    Restore {
        #[arg(long)]
        poses: PathBuf,
        #[arg(long)]
        version: usize,
    },
}

fn history_dir(poses: &Path) -> PathBuf {
    let dir = poses
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let stem = poses.file_stem().and_then(|s| s.to_str()).unwrap_or("pose");
    dir.join(".agentstar").join("history").join(stem)
}

fn versions(poses: &Path) -> Result<Vec<(usize, PathBuf)>> {
    let dir = history_dir(poses);
    let mut v = Vec::new();
    if let Ok(rd) = std::fs::read_dir(&dir) {
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            if let Some(n) = name
                .strip_suffix(".json")
                .and_then(|s| s.parse::<usize>().ok())
            {
                v.push((n, e.path()));
            }
        }
    }
    v.sort();
    Ok(v)
}

/// Records `pf` as the next version, with the command that made it.
fn record(poses: &Path, pf: &PoseFile, command: &str) -> Result<usize> {
    let next = versions(poses)?.last().map_or(0, |(n, _)| n + 1);
    let time_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    let entry = json!({"version": next, "time_unix_s": time_s, "command": command, "pose": pf});
    agentstar_data::atomic::write_json(
        &history_dir(poses).join(format!("{next:06}.json")),
        &entry,
    )?;
    Ok(next)
}

fn pose_from(v: &Value, what: &str) -> Result<(PoseJson, BTreeMap<String, f64>)> {
    let p: PoseJson = serde_json::from_value(
        json!({"quaternion": v["pose"]["quaternion"], "translation": v["pose"]["translation"]}),
    )
    .with_context(|| format!("{what}: no pose"))?;
    let joints: BTreeMap<String, f64> =
        serde_json::from_value(v["joints"].clone()).unwrap_or_default();
    Ok((p, joints))
}

pub fn run(cmd: PoseCommand) -> Result<ExitCode> {
    match cmd {
        PoseCommand::Commit {
            poses,
            report,
            rank,
            frames,
            json: as_json,
        } => {
            let mut pf = PoseFile::read(&poses)?;
            let text = agentstar_data::read_text(&report)?;
            let rep: Value = serde_json::from_str(&text)
                .map_err(|e| anyhow!("{}: not a report: {e}", report.display()))?;
            if let Some(scale) = rep["scale"].as_f64() {
                if (scale - pf.scale).abs() > 1e-9 * pf.scale {
                    bail!("{}: the report was made at scale {scale} but {} has scale {}; run the verb again", report.display(), poses.display(), pf.scale);
                }
            }
            let wanted: Option<Vec<String>> =
                frames.map(|f| f.split(',').map(|s| s.trim().to_string()).collect());
            if history_dir(&poses).read_dir().is_err() {
                record(&poses, &pf, "initial version (before the first commit)")?;
            }
            let mut committed = Vec::new();
            for fr in rep["frames"]
                .as_array()
                .ok_or_else(|| anyhow!("{}: no `frames` in the report", report.display()))?
            {
                let name = fr["frame"].as_str().unwrap_or_default().to_string();
                if wanted.as_ref().is_some_and(|w| {
                    !w.iter()
                        .any(|x| *x == name || name.starts_with(&format!("{x}.")))
                }) {
                    continue;
                }
                let ranked = fr["ranked"]
                    .as_array()
                    .ok_or_else(|| anyhow!("frame {name}: no ranked candidates"))?;
                let cand = ranked
                    .iter()
                    .find(|c| c["rank"].as_u64() == Some(rank as u64))
                    .ok_or_else(|| {
                        anyhow!(
                            "frame {name}: no candidate of rank {rank} (ranks 0..{})",
                            ranked.len().saturating_sub(1)
                        )
                    })?;
                let (p, joints) = pose_from(cand, &name)?;
                let e: &mut FrameEntry = pf.frames.entry(name.clone()).or_default();
                e.object_pose = Some(PoseJson {
                    scale: Some(pf.scale),
                    ..p
                });
                if !joints.is_empty() {
                    e.joints = joints;
                }
                e.moved = true;
                committed.push(name);
            }
            if committed.is_empty() {
                bail!("nothing to commit: the report has no matching frames");
            }
            pf.write(&poses)?;
            let cmdline = std::env::args().collect::<Vec<_>>().join(" ");
            let v = record(&poses, &pf, &cmdline)?;
            if as_json {
                print_json(&json!({"committed": committed, "version": v, "poses": poses}))?;
            } else {
                println!(
                    "committed rank {rank} for {} frame(s) ({}) into {} as version {v}",
                    committed.len(),
                    committed.join(", "),
                    poses.display()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        PoseCommand::History {
            poses,
            json: as_json,
        } => {
            let list = versions(&poses)?;
            let mut rows = Vec::new();
            for (n, p) in &list {
                let v: Value = serde_json::from_str(&agentstar_data::read_text(p)?)?;
                rows.push(
                    json!({"version": n, "time_unix_s": v["time_unix_s"], "command": v["command"]}),
                );
            }
            if as_json {
                print_json(&rows)?;
            } else if rows.is_empty() {
                println!("no committed versions of {} yet", poses.display());
            } else {
                for r in rows {
                    println!(
                        "{:>4}  {}  {}",
                        r["version"],
                        r["time_unix_s"],
                        r["command"].as_str().unwrap_or("")
                    );
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        PoseCommand::Restore { poses, version } => {
            let list = versions(&poses)?;
            let (_, path) = list.iter().find(|(n, _)| *n == version).ok_or_else(|| {
                anyhow!(
                    "no version {version} of {}; versions are {:?}",
                    poses.display(),
                    list.iter().map(|(n, _)| *n).collect::<Vec<_>>()
                )
            })?;
            let v: Value = serde_json::from_str(&agentstar_data::read_text(path)?)?;
            let pf: PoseFile = serde_json::from_value(v["pose"].clone())
                .map_err(|e| anyhow!("{}: {e}", path.display()))?;
            pf.write(&poses)?;
            let n = record(&poses, &pf, &format!("restore version {version}"))?;
            println!(
                "restored version {version} of {} (recorded as version {n})",
                poses.display()
            );
            Ok(ExitCode::SUCCESS)
        }
    }
}
