//! `agentstar pose commit | history | restore`: apply a chosen candidate from a verb's report
//! to `pose.json` atomically; every committed version is kept with the command that made
//! it, and any earlier version can be restored. Every change holds the pose file's lock
//! (`agentstar_agent::history`), so concurrent commits from shells and agents all land.

use crate::common::print_json;
use agentstar_agent::history::PoseHistory;
use agentstar_agent::reports::{CommitReport, SearchReport};
use agentstar_agent::AgentError;
use agentstar_data::posefile::{FrameEntry, PoseFile, PoseJson};
use anyhow::{anyhow, Result};
use std::path::PathBuf;
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
        version: u64,
    },
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
            let rep = SearchReport::read(&report)?;
            let capture = crate::common::open_capture(&rep.capture).ok();
            // The frames wanted, with the frame grammar when the report's capture opens.
            let wanted: Option<Vec<String>> = match (&frames, &capture) {
                (None, _) => None,
                (Some(spec), Some(cap)) => Some(
                    cap.select(Some(spec))?
                        .into_iter()
                        .map(|i| cap.frames[i].name.clone())
                        .collect(),
                ),
                (Some(spec), None) => Some(spec.split(',').map(|s| s.trim().to_string()).collect()),
            };
            let cmdline = std::env::args().collect::<Vec<_>>().join(" ");
            let history = PoseHistory::new(&poses);
            let (committed, v) = history
                .update(&cmdline, |pf| {
                    commit(pf, &rep, rank, wanted.as_deref())
                        .map_err(|e| AgentError::Invalid(format!("{}: {e}", report.display())))
                })
                .map_err(|e| anyhow!("{e}"))?;
            if as_json {
                print_json(&CommitReport {
                    committed,
                    version: v,
                    poses,
                })?;
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
            let rows = PoseHistory::new(&poses).rows()?;
            if as_json {
                print_json(&rows)?;
            } else if rows.is_empty() {
                println!("no committed versions of {} yet", poses.display());
            } else {
                for r in rows {
                    println!("{:>4}  {}  {}", r.version, r.time_unix_s, r.command);
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        PoseCommand::Restore { poses, version } => {
            let n = PoseHistory::new(&poses).restore(version)?;
            println!(
                "restored version {version} of {} (recorded as version {n})",
                poses.display()
            );
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Writes rank `rank` of each wanted frame of `rep` into `pf`; returns the frames.
fn commit(
    pf: &mut PoseFile,
    rep: &SearchReport,
    rank: usize,
    wanted: Option<&[String]>,
) -> std::result::Result<Vec<String>, String> {
    if (rep.scale - pf.scale).abs() > 1e-9 * pf.scale {
        return Err(format!(
            "the report was made at scale {} but the pose file has scale {}; run the {} again",
            rep.scale,
            pf.scale,
            rep.verb.command()
        ));
    }
    let mut committed = Vec::new();
    for fr in &rep.frames {
        if wanted.is_some_and(|w| !w.contains(&fr.frame)) {
            continue;
        }
        let cand = fr.ranked.iter().find(|c| c.rank == rank).ok_or_else(|| {
            format!(
                "frame {}: no candidate of rank {rank} (ranks 0..{})",
                fr.frame,
                fr.ranked.len().saturating_sub(1)
            )
        })?;
        let e: &mut FrameEntry = pf.frames.entry(fr.frame.clone()).or_default();
        e.object_pose = Some(PoseJson {
            quaternion: cand.pose.quaternion,
            translation: cand.pose.translation,
            scale: Some(pf.scale),
        });
        if !cand.joints.is_empty() {
            e.joints = cand.joints.clone();
        }
        e.moved = true;
        committed.push(fr.frame.clone());
    }
    if committed.is_empty() {
        return Err("nothing to commit: the report has no matching frames".into());
    }
    Ok(committed)
}
