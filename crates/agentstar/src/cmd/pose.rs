//! `agentstar pose commit | history | restore`: put poses from a search report, a pose file
//! (a track's `pose.json`) or a history version into `pose.json` atomically; list the
//! versions, or one frame's pose and score in every version; restore a version, whole or
//! for chosen frames. Every change holds the pose file's lock and is recorded as a version
//! with its command (`agentstar_data::history`), so concurrent commits from shells and
//! agents all land.

use crate::common::{open_capture, open_model, print_json};
use agentstar_data::capture::Capture;
use agentstar_data::history::HistoryError;
use agentstar_data::history::{command_line, PoseHistory};
use agentstar_data::posefile::{FrameEntry, PoseFile, PoseJson};
use agentstar_data::runfile::RunFile;
use agentstar_render::{PosedModel, ScoreTarget, SilhouetteRenderer};
use agentstar_reports::{
    CandidatePick, CommitReport, FrameHistoryReport, HistoryReport, PoseSource, RestoreReport,
};
use anyhow::{anyhow, bail, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Subcommand)]
pub enum PoseCommand {
    /// Put poses into pose.json from a search report (a ranked candidate: sweep, apply,
    /// osweep, oapply, oapply-all), a pose file (a track's pose.json) or a history version.
    #[command(
        after_help = "Examples:\n  agentstar pose commit --poses run/pose.json --report reports/oapply.json --rank 1 --frames 000010\n  agentstar pose commit --poses run/pose.json --report reports/oapply.json --label swap:hinge --frames 000010..000020\n  agentstar pose commit --poses run/pose.json --report tracked/pose.json --frames 000040..000060\n  agentstar pose commit --poses run/pose.json --report run/.agentstar/history/pose/000012.json --frames 000010"
    )]
    Commit {
        #[arg(long)]
        poses: PathBuf,
        /// The source: a search report, a pose file, a track report or a history version.
        #[arg(long, visible_alias = "from")]
        report: PathBuf,
        /// The candidate's rank in a search report (0 = best; only for search reports).
        #[arg(long)]
        rank: Option<usize>,
        /// The candidate's label in a search report (`swap:hinge`, `flip:x`; for `osweep`
        /// the grid start before `→`): the same candidate in every frame, whatever its rank
        /// there.
        #[arg(long)]
        label: Option<String>,
        /// Only these frames (the frame grammar: names, stems, numbers, `a..b`); default
        /// every frame the source has a pose for.
        #[arg(long)]
        frames: Option<String>,
        /// The capture that resolves --frames (default: the report's, or the run's when
        /// pose.json is in a run directory).
        #[arg(long)]
        capture: Option<PathBuf>,
        /// Print the result as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// List the versions of pose.json, or one frame's pose (and score) in every version.
    #[command(
        after_help = "Examples:\n  agentstar pose history --poses run/pose.json --last 20\n  agentstar pose history --poses run/pose.json --frame 000040 --capture cap --model run/scene.rhai"
    )]
    History {
        #[arg(long)]
        poses: PathBuf,
        /// One frame (name, stem or number): its pose in every version, where it changed,
        /// and its visible IoU with the current model when the capture and model are known.
        #[arg(long)]
        frame: Option<String>,
        /// The capture (default: the run's when pose.json is in a run directory).
        #[arg(long)]
        capture: Option<PathBuf>,
        /// The model that scores --frame's poses (default: the run's).
        #[arg(long)]
        model: Option<PathBuf>,
        /// Only the last N versions.
        #[arg(long)]
        last: Option<usize>,
        /// Print the result as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Restore an earlier version, whole or for some frames (recorded as a new version).
    #[command(
        after_help = "Examples:\n  agentstar pose restore --poses run/pose.json --version 3\n  agentstar pose restore --poses run/pose.json --version 3 --frames 000010,000020..000030"
    )]
    Restore {
        #[arg(long)]
        poses: PathBuf,
        #[arg(long)]
        version: u64,
        /// Only these frames (the frame grammar); the others stay as they are.
        #[arg(long)]
        frames: Option<String>,
        /// The capture that resolves --frames (default: the run's).
        #[arg(long)]
        capture: Option<PathBuf>,
        /// Print the result as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
}

/// The run file of the run directory holding `poses`, if it is in one.
fn run_of(poses: &Path) -> Option<RunFile> {
    let dir = poses.parent().filter(|d| !d.as_os_str().is_empty())?;
    RunFile::read(dir).ok().flatten()
}

/// The capture to resolve frames with: the one given, else `hint`, else the run's.
fn capture_for(given: Option<&Path>, hint: Option<&Path>, poses: &Path) -> Result<Option<Capture>> {
    if let Some(c) = given {
        return Ok(Some(open_capture(c)?));
    }
    let found = hint
        .map(Path::to_path_buf)
        .or_else(|| run_of(poses).map(|r| r.capture));
    Ok(found.and_then(|c| open_capture(&c).ok()))
}

/// Frame names of `spec` by the frame grammar when a capture is known; otherwise the
/// comma-separated names as given (ranges need the capture).
fn frame_names(spec: &str, capture: Option<&Capture>) -> Result<Vec<String>> {
    match capture {
        Some(cap) => Ok(cap
            .select(Some(spec))?
            .into_iter()
            .map(|i| cap.frames[i].name.clone())
            .collect()),
        None => {
            let names: Vec<String> = spec
                .split(',')
                .map(|s| s.trim().to_string())
                .filter(|s| !s.is_empty())
                .collect();
            if names.iter().any(|n| n.contains("..") || n == "all") {
                bail!("`{spec}`: ranges and `all` need the capture; give --capture");
            }
            Ok(names)
        }
    }
}

pub fn run(cmd: PoseCommand) -> Result<ExitCode> {
    match cmd {
        PoseCommand::Commit {
            poses,
            report,
            rank,
            label,
            frames,
            capture,
            json: as_json,
        } => {
            // The rule the `pose_commit` tool checks too: a rank or a label, not both.
            let pick = CandidatePick::new(rank, label.as_deref())
                .map_err(|e| anyhow!("pose commit: {e}"))?;
            let source = PoseSource::read(&report)?;
            let hint = match &source {
                PoseSource::Search(r) => Some(r.capture.clone()),
                _ => None,
            };
            let wanted = match &frames {
                None => None,
                Some(spec) => {
                    let cap = capture_for(capture.as_deref(), hint.as_deref(), &poses)?;
                    Some(frame_names(spec, cap.as_ref())?)
                }
            };
            let (committed, v) = PoseHistory::new(&poses)
                .update(&command_line(), |pf| {
                    commit(pf, &source, &pick, wanted.as_deref())
                        .map_err(|e| HistoryError::Invalid(format!("{}: {e}", report.display())))
                })
                .map_err(|e| anyhow!("{e}"))?;
            if as_json {
                print_json(&CommitReport {
                    committed,
                    version: v,
                    poses,
                    source: source.describe(),
                })?;
            } else {
                println!(
                    "committed {} frame(s) ({}) from the {} into {} as version {v}",
                    committed.len(),
                    committed.join(", "),
                    source.describe(),
                    poses.display()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        PoseCommand::History {
            poses,
            frame: Some(frame),
            capture,
            model,
            last,
            json: as_json,
        } => {
            let report = frame_history(&poses, &frame, capture, model, last)?;
            if as_json {
                print_json(&report)?;
            } else {
                print!("{}", frame_history_text(&report));
            }
            Ok(ExitCode::SUCCESS)
        }
        PoseCommand::History {
            poses,
            frame: None,
            last,
            json: as_json,
            ..
        } => {
            let mut rows = PoseHistory::new(&poses).rows()?;
            let total = rows.len();
            if let Some(n) = last {
                rows.drain(..rows.len().saturating_sub(n));
            }
            if as_json {
                print_json(&HistoryReport {
                    poses,
                    total,
                    versions: rows,
                })?;
            } else if rows.is_empty() {
                println!("no committed versions of {} yet", poses.display());
            } else {
                for r in rows {
                    println!("{:>4}  {}  {}", r.version, r.time_unix_s, r.command);
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        PoseCommand::Restore {
            poses,
            version,
            frames,
            capture,
            json: as_json,
        } => {
            let wanted = match &frames {
                None => None,
                Some(spec) => {
                    let cap = capture_for(capture.as_deref(), None, &poses)?;
                    Some(frame_names(spec, cap.as_ref())?)
                }
            };
            let (restored, n) =
                PoseHistory::new(&poses).restore_frames(version, wanted.as_deref())?;
            if as_json {
                print_json(&RestoreReport {
                    from_version: version,
                    frames: restored,
                    version: n,
                    poses,
                })?;
            } else if wanted.is_some() {
                println!(
                    "restored {} frame(s) ({}) of version {version} into {} (recorded as version {n}); the other frames are unchanged",
                    restored.len(),
                    restored.join(", "),
                    poses.display()
                );
            } else {
                println!(
                    "restored version {version} of {} (recorded as version {n})",
                    poses.display()
                );
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// One frame of a commit's source: its name, pose and joint states.
type SourceFrame = (String, PoseJson, BTreeMap<String, f64>);

/// Writes the wanted frames of `source` into `pf` (the candidate `pick` names in each frame
/// of a search report); returns the frames written.
fn commit(
    pf: &mut PoseFile,
    source: &PoseSource,
    pick: &CandidatePick,
    wanted: Option<&[String]>,
) -> std::result::Result<Vec<String>, String> {
    // The frames of the source, each with its pose and joints.
    let (scale, what, frames): (f64, String, Vec<SourceFrame>) = match source {
        PoseSource::Search(rep) => {
            let mut v = Vec::new();
            for fr in &rep.frames {
                if wanted.is_some_and(|w| !w.contains(&fr.frame)) {
                    continue;
                }
                let cand = pick.find(fr)?;
                let pose = PoseJson {
                    scale: None,
                    ..cand.pose.clone()
                };
                v.push((fr.frame.clone(), pose, cand.joints.clone()));
            }
            (
                rep.scale,
                format!("run the {} again", rep.verb.command()),
                v,
            )
        }
        PoseSource::Poses(_) | PoseSource::Version(_) => {
            match pick {
                CandidatePick::Rank(Some(r)) if *r != 0 => {
                    return Err(format!(
                        "--rank applies to search reports; this is a {}",
                        source.describe()
                    ))
                }
                CandidatePick::Label(_) => {
                    return Err(format!(
                        "--label applies to search reports; this is a {}",
                        source.describe()
                    ))
                }
                CandidatePick::Rank(_) => {}
            }
            let src: &PoseFile = match source {
                PoseSource::Poses(p) => p.as_ref(),
                PoseSource::Version(e) => &e.pose,
                PoseSource::Search(_) => unreachable!("handled above"),
            };
            let key_of = |name: &str| -> Option<(&String, &FrameEntry)> {
                src.frames.get_key_value(name).or_else(|| {
                    let stem = Path::new(name).file_stem()?.to_str()?;
                    src.frames.iter().find(|(k, _)| {
                        Path::new(k.as_str()).file_stem().and_then(|s| s.to_str()) == Some(stem)
                    })
                })
            };
            let mut v = Vec::new();
            match wanted {
                Some(w) => {
                    for name in w {
                        let (_, e) = key_of(name).ok_or_else(|| {
                            format!("the {} has no frame {name}", source.describe())
                        })?;
                        let pose = e.object_pose.clone().ok_or_else(|| {
                            format!("the {} has no pose for {name}", source.describe())
                        })?;
                        v.push((name.clone(), pose, e.joints.clone()));
                    }
                }
                None => {
                    for (name, e) in &src.frames {
                        if let Some(p) = &e.object_pose {
                            v.push((name.clone(), p.clone(), e.joints.clone()));
                        }
                    }
                }
            }
            (src.scale, "rescale one of them first".to_string(), v)
        }
    };
    if (scale - pf.scale).abs() > 1e-9 * pf.scale {
        return Err(format!(
            "the {} is at scale {scale} but the pose file has scale {}; {what}",
            source.describe(),
            pf.scale
        ));
    }
    let known: Vec<&str> = pf.joint_defs.iter().map(|j| j.name.as_str()).collect();
    let mut committed = Vec::new();
    for (name, mut pose, joints) in frames {
        // Frames are named as the pose file names them (a name or its stem); a frame it
        // does not hold yet (seeded from the reference) is added under its name.
        let key = if pf.frames.contains_key(&name) {
            name.clone()
        } else {
            let stem = Path::new(&name).file_stem().and_then(|s| s.to_str());
            pf.frames
                .keys()
                .find(|k| Path::new(k.as_str()).file_stem().and_then(|s| s.to_str()) == stem)
                .cloned()
                .unwrap_or_else(|| name.clone())
        };
        if let Some(j) = joints
            .keys()
            .find(|j| !known.is_empty() && !known.contains(&j.as_str()))
        {
            return Err(format!(
                "frame {name}: joint `{j}` is not in the pose file's model (joints {})",
                known.join(", ")
            ));
        }
        pose.scale = Some(pf.scale);
        let e: &mut FrameEntry = pf.frames.entry(key.clone()).or_default();
        e.object_pose = Some(pose);
        for (j, value) in joints {
            e.joints.insert(j, value);
        }
        e.moved = true;
        committed.push(key);
    }
    if committed.is_empty() {
        return Err(format!(
            "nothing to commit: the {} has no matching frames",
            source.describe()
        ));
    }
    Ok(committed)
}

/// One frame in every version, scored with the current model where capture and model are
/// known (each distinct pose once).
fn frame_history(
    poses: &Path,
    frame: &str,
    capture: Option<PathBuf>,
    model: Option<PathBuf>,
    last: Option<usize>,
) -> Result<FrameHistoryReport> {
    let run = run_of(poses);
    let capture_path = capture.or_else(|| run.as_ref().map(|r| r.capture.clone()));
    let model_path = model.or_else(|| run.as_ref().map(|r| r.model.clone()));
    let cap = capture_path.as_deref().map(open_capture).transpose()?;
    // The frame by the frame grammar when the capture is known.
    let (name, index) = match &cap {
        Some(c) => {
            let idx = c.select(Some(frame))?;
            let [i] = idx.as_slice() else {
                bail!("--frame `{frame}` names {} frames; name one", idx.len());
            };
            (c.frames[*i].name.clone(), Some(*i))
        }
        None => (frame.to_string(), None),
    };
    let history = PoseHistory::new(poses);
    let mut versions = history.frame_versions(&name)?;
    if versions.is_empty() {
        bail!("{} has no versions yet", poses.display());
    }
    if let Some(n) = last {
        versions.drain(..versions.len().saturating_sub(n));
    }
    let mut notes = Vec::new();
    let mut scored_with = None;
    if let (Some(cap), Some(i), Some(mp)) = (&cap, index, &model_path) {
        let model = open_model(mp)?;
        scored_with = Some(mp.clone());
        let f = &cap.frames[i];
        let target = ScoreTarget::new(cap.load_mask(i)?, cap.load_hand(i)?)?;
        let mut renderer = SilhouetteRenderer::new(f.camera.width, f.camera.height);
        let mut by_version: BTreeMap<u64, Option<f64>> = BTreeMap::new();
        for row in versions.iter_mut() {
            if let Some(score) = row.same_as.and_then(|v| by_version.get(&v).copied()) {
                row.iou_visible = score;
                continue;
            }
            let entry = history.entry(row.version)?;
            let score = match entry.pose.resolve(cap, &model.model.tree) {
                Ok(resolved) => {
                    let p = &resolved[i];
                    let posed = PosedModel::new(
                        &model.model,
                        &p.generalised.states,
                        &p.generalised.pose.with_scale(entry.pose.scale),
                    );
                    Some(
                        target
                            .score(renderer.render(&f.camera, &posed.instances))
                            .gate(),
                    )
                }
                Err(e) => {
                    notes.push(format!(
                        "version {}: not scored with the current model ({e})",
                        row.version
                    ));
                    None
                }
            };
            by_version.insert(row.version, score);
            row.iou_visible = score;
        }
    } else {
        notes.push(
            "not scored: give --capture and --model (or keep pose.json in a run directory)".into(),
        );
    }
    Ok(FrameHistoryReport {
        poses: poses.to_path_buf(),
        frame: name,
        model: scored_with,
        versions,
        notes,
    })
}

fn frame_history_text(r: &FrameHistoryReport) -> String {
    let mut t = format!(
        "{} in {} version(s) of {}\n{:>4}  {:>8}  {:<38}  command\n",
        r.frame,
        r.versions.len(),
        r.poses.display(),
        "v",
        "iou_vis",
        "pose (quaternion wxyz | translation), joints"
    );
    for v in &r.versions {
        let iou = v.iou_visible.map_or("-".to_string(), |x| format!("{x:.4}"));
        let pose = match (&v.same_as, &v.pose) {
            (Some(s), _) => format!("same as version {s}"),
            (None, None) => "no pose".to_string(),
            (None, Some(p)) => {
                let q: Vec<String> = p.quaternion.iter().map(|x| format!("{x:.3}")).collect();
                let tr: Vec<String> = p.translation.iter().map(|x| format!("{x:.3}")).collect();
                let j: Vec<String> = v
                    .joints
                    .iter()
                    .map(|(k, x)| format!("{k} {x:.2}"))
                    .collect();
                format!("{} | {} {}", q.join(" "), tr.join(" "), j.join(" "))
            }
        };
        t.push_str(&format!(
            "{:>4}  {:>8}  {:<38}  {}\n",
            v.version, iou, pose, v.command
        ));
    }
    for n in &r.notes {
        t.push_str(&format!("note: {n}\n"));
    }
    t
}
