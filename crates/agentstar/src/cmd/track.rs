//! `agentstar track`: fit every keyframe's pose and joint states for a known model from the
//! masks, with no agent, and write `pose.json` (as a version of its history, with the
//! command, like every writer of a pose file).

use crate::cmd::bake::{store_bake, Provenance};
use crate::cmd::score::{print_table, summarise};
use crate::common::{
    open_capture, open_model, print_json, select_frames, write_tracked_version, Session, PASS_IOU,
};
use agentstar_data::bakefile::bake_path;
use agentstar_data::capture::{Capture, Frame};
use agentstar_data::posefile::{partial_path, PoseFile};
use agentstar_data::scenefile::load_model_unbaked;
use agentstar_render::BitMask;
use agentstar_render::ScoreTarget;
use agentstar_reports::{
    refused_turns_text, BasinMoveRow, RefusedTurnRow, SettledRow, TrackBakeOutcome,
    TrackBakeReport, TrackReport,
};
use agentstar_track::bake::BakeConfig;
use agentstar_track::tracker::{
    track_from_video, track_video, track_with_bake, BakeOutcome, BakePass, BasinMove, BasinPolicy,
    TrackConfig, TrackFrame, TrackObserver, TrackSwitches, BASIN_JOINT_DEG, BASIN_ROTATION_DEG,
    MIN_SETTLED,
};
use agentstar_track::GenPose;
use anyhow::{anyhow, bail, Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar track cap --model run/scene.rhai --scale 0.24 --out run/pose.json\n  agentstar track cap --model run/scene.rhai --from run/pose.json --anchors 000040,000120..000130 --out run/pose.json"
)]
pub struct Args {
    /// The capture directory.
    capture: PathBuf,
    /// The model: scene script (.rhai), URDF or mesh.
    #[arg(long)]
    model: PathBuf,
    /// The object's scale (`p_cam = s·R·p + t`); or take it from --scale-from.
    #[arg(long)]
    scale: Option<f64>,
    /// A pose file whose scale to use.
    #[arg(long)]
    scale_from: Option<PathBuf>,
    /// Refine these poses instead of tracking from scratch (a warm start; its scale is used
    /// unless --scale is given). Cheap after a shape edit.
    #[arg(long)]
    from: Option<PathBuf>,
    /// With --from: frames kept exactly as they are and carried to their neighbours (names,
    /// stems or `a..b` ranges, comma separated, as --frames takes them).
    #[arg(long)]
    anchors: Option<String>,
    /// With --from: keep every frame in its own basin: local refinement only, each frame
    /// within 45° of rotation of its starting pose (half the nearest twin, a quarter turn:
    /// no flip or twin is reached) and each joint within 30° (a prismatic joint: a sixth of
    /// its range); no wide search and none of the passes that move frames between basins.
    /// Without it, every frame moved further than 45° is named in the report.
    #[arg(long)]
    keep_basins: bool,
    /// Where to write the tracked poses. While the run goes, the poses so far are kept in
    /// OUT with the extension `.partial.json` (frames not tracked yet marked `"moved": false`),
    /// removed when the run finishes: a stopped run leaves them.
    #[arg(long)]
    out: PathBuf,
    /// Seed of every search.
    #[arg(long, default_value_t = 17)]
    seed: u64,
    /// Evaluations per local search.
    #[arg(long, default_value_t = 2400)]
    evals: usize,
    /// Skip the final consistency pass (the "no temporal" ablation).
    #[arg(long)]
    no_temporal: bool,
    /// Leave out the sequence-level choice at the end (on by default, and off with
    /// `--no-temporal`): every frame's twins (flips, principal half-turns) refined, one basin
    /// per frame by dynamic programming over the sequence.
    #[arg(long)]
    no_sequence_choice: bool,
    /// Track from the masks alone: leave the frames' colours out (the appearance term that
    /// turns silhouette twins to the pose whose colours agree with the frames before).
    #[arg(long)]
    no_appearance: bool,
    /// Leave the capture's in-between frames out (the keyframes-only ablation): by default
    /// each keyframe is reached by following the video between it and the keyframe before.
    #[arg(long)]
    no_between: bool,
    /// Also write every in-between frame's pose to OUT (entries marked `"between": true`),
    /// followed from the final keyframe poses.
    #[arg(long, conflicts_with = "no_between")]
    write_between: bool,
    /// After tracking, bake the model's colours from the keyframes whose basin the outline
    /// alone settles (no twin or turn about a principal axis explains the mask within 0.03
    /// of IoU) and track the other frames again with them, the settled frames anchored: an
    /// uncoloured mug's handle fixes the turn about its body where it is seen, and the baked print carries
    /// it where the handle is hidden. Nothing is baked (the plain track kept) with fewer
    /// than two settled frames (a can's outline settles none: it is the same upside down)
    /// or when they disagree with each other. The bake is made on the model as its file
    /// gives it (a stored bake set aside); where a settled frame saw the surface its colours
    /// replace the model's own (texture, vertex or part colours), elsewhere those stay.
    #[arg(long, conflicts_with = "no_appearance")]
    bake: bool,
    /// With --bake: store the bake beside the model (`<stem>.bake.json` and its atlas,
    /// atomically, as `agentstar bake` does), so every command loading the model uses it.
    /// Without it the bake lives in memory for this run only.
    #[arg(long, requires = "bake")]
    store_bake: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// A frame's score target (its object mask, hands as don't-care).
fn target_of(capture: &Capture, frame: &Frame) -> Result<ScoreTarget> {
    Ok(ScoreTarget::new(
        capture.load_mask_of(frame)?,
        capture.load_hand_of(frame)?,
    )?)
}

/// A frame's colour image for the appearance term; `None` (with a warning) when it cannot be
/// read or is not its camera's size: the frame is then tracked from its mask alone.
fn image_of(capture: &Capture, frame: &Frame) -> Option<image::RgbImage> {
    let cam = &frame.camera;
    match capture.load_frame_of(frame) {
        Ok(img) if img.width() == cam.width && img.height() == cam.height => Some(img),
        Ok(img) => {
            eprintln!(
                "warning: frame {}: image {}×{} is not the camera's {}×{}; tracked from its mask alone",
                frame.name,
                img.width(),
                img.height(),
                cam.width,
                cam.height
            );
            None
        }
        Err(e) => {
            eprintln!(
                "warning: frame {}: {e:#}; tracked from its mask alone",
                frame.name
            );
            None
        }
    }
}

/// The most bytes of in-between frames' images `track` holds at once (1 GiB: 1,165 frames
/// of 640×480, 172 of 1920×1080); a longer or larger video's in-between frames are tracked
/// by their masks alone, and the axis pass weighs the keyframes' colours only.
const BETWEEN_IMAGES_MAX_BYTES: u64 = 1 << 30;

/// Each gap's in-between frames' images (`None` for one that cannot be read or is not its
/// camera's size, with a warning), or none at all without the appearance term or over
/// [`BETWEEN_IMAGES_MAX_BYTES`] (said on stderr).
fn between_images(
    capture: &Capture,
    gaps: &[Vec<&Frame>],
    no_appearance: bool,
) -> Vec<Vec<Option<image::RgbImage>>> {
    let none = || gaps.iter().map(|g| vec![None; g.len()]).collect();
    if no_appearance {
        return none();
    }
    let bytes: u64 = gaps
        .iter()
        .flatten()
        .map(|f| 3 * u64::from(f.camera.width) * u64::from(f.camera.height))
        .sum();
    if bytes > BETWEEN_IMAGES_MAX_BYTES {
        eprintln!(
            "track: the in-between frames' images would take {} MiB (over {} MiB): they are tracked by their masks alone, and the axis pass weighs the keyframes' colours only",
            bytes >> 20,
            BETWEEN_IMAGES_MAX_BYTES >> 20
        );
        return none();
    }
    gaps.iter()
        .map(|g| g.iter().map(|f| image_of(capture, f)).collect())
        .collect()
}

fn track_frame<'a>(
    frame: &Frame,
    target: &'a ScoreTarget,
    image: &'a Option<image::RgbImage>,
) -> TrackFrame<'a> {
    TrackFrame {
        name: frame.name.clone(),
        camera: frame.camera,
        target,
        world_from_camera: Some(frame.world_from_camera),
        rgb: image.as_ref().map(|m| m.as_raw().as_slice()),
    }
}

pub fn run(a: Args) -> Result<ExitCode> {
    // The rule the `track` tool checks too: anchors and keep-basins need --from.
    agentstar_requests::WarmStart {
        from: a.from.as_deref(),
        anchors: a.anchors.as_deref(),
        keep_basins: a.keep_basins,
    }
    .check()
    .map_err(|e| anyhow::anyhow!("track: {e}"))?;
    let capture = open_capture(&a.capture)?;
    // A bake is made on the model as its file gives it: a stored bake is set aside.
    let model = if a.bake {
        let m = load_model_unbaked(&a.model)?;
        for w in &m.warnings {
            eprintln!("warning: {}: {w}", a.model.display());
        }
        if bake_path(&a.model).is_file() {
            eprintln!(
                "track: --bake: the stored bake {} is set aside; this run bakes from its own settled frames",
                bake_path(&a.model).display()
            );
        }
        m
    } else {
        open_model(&a.model)?
    };
    let from = a.from.as_deref().map(PoseFile::read).transpose()?;
    let scale = match (a.scale, &a.scale_from, &from) {
        (Some(s), _, _) => s,
        (None, Some(p), _) => PoseFile::read(p)?.scale,
        (None, None, Some(f)) => f.scale,
        (None, None, None) => bail!("the tracker needs the object's scale: give --scale S (p_cam = s·R·p + t), --scale-from pose.json or --from pose.json"),
    };
    let targets: Vec<ScoreTarget> = capture
        .frames
        .iter()
        .map(|f| target_of(&capture, f))
        .collect::<Result<_>>()?;
    let images: Vec<Option<image::RgbImage>> = capture
        .frames
        .iter()
        .map(|f| (!a.no_appearance).then(|| image_of(&capture, f)).flatten())
        .collect();
    let frames: Vec<TrackFrame> = capture
        .frames
        .iter()
        .zip(&targets)
        .zip(&images)
        .map(|((f, t), img)| track_frame(f, t, img))
        .collect();
    // The in-between frames, gap by gap (gap g: between keyframes g and g + 1).
    let gaps: Vec<Vec<&Frame>> = if a.no_between {
        vec![]
    } else {
        (0..capture.frames.len().saturating_sub(1))
            .map(|g| capture.between_keyframes(g))
            .collect()
    };
    let between_targets: Vec<Vec<ScoreTarget>> = gaps
        .iter()
        .map(|gap| gap.iter().map(|f| target_of(&capture, f)).collect())
        .collect::<Result<_>>()?;
    // Their images, for the axis pass's colours between neighbouring video frames (a chain
    // searches each in-between frame by its silhouette alone), within a bound on memory.
    let between_images = between_images(&capture, &gaps, a.no_appearance);
    let between: Vec<Vec<TrackFrame>> = gaps
        .iter()
        .zip(&between_targets)
        .zip(&between_images)
        .map(|((gap, targets), images)| {
            gap.iter()
                .zip(targets)
                .zip(images)
                .map(|((f, t), img)| track_frame(f, t, img))
                .collect()
        })
        .collect();
    if a.no_between && !capture.between.is_empty() {
        eprintln!(
            "track: --no-between: the capture's {} in-between frames are left out",
            capture.between.len()
        );
    }
    let cfg = TrackConfig::from(TrackSwitches {
        seed: a.seed,
        local_evals: a.evals,
        temporal: !a.no_temporal,
        sequence_choice: !a.no_sequence_choice,
        appearance: !a.no_appearance,
    });
    let cfg = TrackConfig {
        between_poses: a.write_between,
        ..cfg
    };
    let t0 = std::time::Instant::now();
    let bar = crate::common::progress(frames.len(), "track");
    let partial_path = partial_path(&a.out);
    // An earlier stopped run's partial poses are superseded by this run's.
    if let Err(e) = std::fs::remove_file(&partial_path) {
        if e.kind() != std::io::ErrorKind::NotFound {
            bail!("cannot remove {}: {e}", partial_path.display());
        }
    }
    let observe = Observer {
        bar: &bar,
        partial: Partial {
            capture: &capture,
            tree: &model.model.tree,
            scale,
            path: &partial_path,
            failed: std::sync::atomic::AtomicBool::new(false),
        },
    };
    let mut basin_moves = Vec::new();
    let r = match (&from, &a.from) {
        (Some(f), Some(path)) => {
            let start: Vec<GenPose> = f
                .resolve(&capture, &model.model.tree)
                .map_err(|e| anyhow!("{}: {e}", path.display()))?
                .into_iter()
                .map(|p| p.generalised)
                .collect();
            let anchors = match &a.anchors {
                Some(spec) => select_frames(&capture, Some(spec)).context("--anchors")?,
                None => vec![],
            };
            let policy = if a.keep_basins {
                BasinPolicy::Keep
            } else {
                BasinPolicy::Search
            };
            let w = track_from_video(
                &model.model,
                scale,
                (&frames, &between),
                (&start, &anchors),
                policy,
                &cfg,
                &observe,
            )?;
            basin_moves = basin_move_rows(&w.basin_moves, |k| capture.frames[k].name.clone());
            w.result
        }
        _ => track_video(&model.model, scale, &frames, &between, &cfg, &observe)?,
    };
    let (r, baked) = if a.bake {
        let hands: Vec<Option<BitMask>> =
            targets.iter().map(|t| t.keep().map(BitMask::not)).collect();
        let pass = track_with_bake(
            &model.model,
            scale,
            (&frames, &between),
            &hands,
            &r,
            &cfg,
            &BakeConfig::default(),
            &observe,
        )?;
        let mut log = r.log.clone();
        let result = match &pass.outcome {
            BakeOutcome::Used(_, w) => {
                let mut result = w.result.clone();
                log.extend(result.log);
                result.log = log;
                result.evaluations += r.evaluations;
                result.init_frame = r.init_frame;
                result
            }
            _ => r,
        };
        (result, Some(pass))
    } else {
        (r, None)
    };
    let between_poses: Vec<(String, GenPose)> = gaps
        .iter()
        .zip(&r.between)
        .flat_map(|(gap, poses)| {
            gap.iter()
                .zip(poses)
                .map(|(f, (g, _))| (f.name.clone(), g.clone()))
        })
        .collect();
    bar.finish_and_clear();
    let seconds = t0.elapsed().as_secs_f64();
    // Written as a version of the pose file's history, with this command.
    let (pose_file, written, version) = write_tracked_version(
        &capture,
        &model.model.tree,
        scale,
        &r.poses,
        &between_poses,
        &a.out,
    )?;
    // The run finished: its partial results are superseded.
    if let Err(e) = std::fs::remove_file(&partial_path) {
        if e.kind() != std::io::ErrorKind::NotFound {
            eprintln!("track: could not remove {}: {e}", partial_path.display());
        }
    }
    let bake_report = match &baked {
        Some(pass) => Some(bake_report(&capture, &a, &model.model, pass, version)?),
        None => None,
    };
    // Scored from what is in memory: the poses as written, not read back.
    let s = Session::from_memory(capture, model, pose_file, written);
    let capture = &s.capture;
    let scores: Vec<_> = (0..capture.frames.len())
        .map(|i| s.score(i, 0.0))
        .collect::<Result<_>>()?;
    let summary = summarise(&scores, PASS_IOU);
    let refused_turns: Vec<RefusedTurnRow> = r
        .refused_turns
        .iter()
        .map(|t| RefusedTurnRow {
            frame: capture.frames[t.frame].name.clone(),
            what: t.what.clone(),
        })
        .collect();
    if a.json {
        print_json(&TrackReport {
            poses: a.out.clone(),
            seconds,
            evaluations: r.evaluations,
            init_frame: capture.frames[r.init_frame].name.clone(),
            log: r.log.clone(),
            frames: scores,
            sequence: summary,
            pose_version: Some(version),
            keep_basins: a.keep_basins,
            basin_moves,
            bake: bake_report,
            refused_turns,
        })?;
    } else {
        println!(
            "tracked {} frames in {seconds:.1} s ({} evaluations), initialised on {}; wrote {} (version {version} of its history)",
            capture.frames.len(),
            r.evaluations,
            capture.frames[r.init_frame].name,
            a.out.display()
        );
        if a.keep_basins {
            println!(
                "basins kept: every frame within {BASIN_ROTATION_DEG}° of rotation and {BASIN_JOINT_DEG}° of joint of its starting pose"
            );
        }
        if !basin_moves.is_empty() {
            println!(
                "{} frame(s) moved to another basin (further than {BASIN_ROTATION_DEG}° from the --from pose; a turn about a round body's axis only keeps the outline and says so; --keep-basins keeps them):",
                basin_moves.len()
            );
            for m in &basin_moves {
                println!("  {}", m.line());
            }
        }
        if let Some(b) = &bake_report {
            print_bake(b);
        }
        print!("{}", refused_turns_text(&refused_turns));
        print_table(&scores, &summary);
    }
    Ok(ExitCode::SUCCESS)
}

/// `track --bake`'s report: each frame's verdict, what was baked, the frames it moved, and
/// where it was stored (`--store-bake`, through the bake file with the poses just written as
/// its provenance).
fn bake_report(
    capture: &Capture,
    a: &Args,
    model: &agentstar_geom::ObjectModel,
    pass: &BakePass,
    version: u64,
) -> Result<TrackBakeReport> {
    let name = |i: usize| capture.frames[i].name.clone();
    let frames: Vec<SettledRow> = pass
        .settled
        .iter()
        .map(|f| SettledRow {
            frame: name(f.frame),
            iou: f.iou,
            rival_deg: f.rival.map(|r| r.0),
            rival_iou: f.rival.map(|r| r.1),
            settled: f.settled,
        })
        .collect();
    let mut report = TrackBakeReport {
        outcome: TrackBakeOutcome::TooFewSettled,
        frames,
        baked_from: vec![],
        min_settled: MIN_SETTLED,
        surface_texels: None,
        seen_texels: None,
        disagreeing: vec![],
        left_out: pass.left_out.iter().map(|&i| name(i)).collect(),
        basin_moves: vec![],
        stored: None,
    };
    let b = match &pass.outcome {
        BakeOutcome::TooFewSettled => return Ok(report),
        BakeOutcome::Refused(b) => {
            report.outcome = TrackBakeOutcome::Refused;
            report.disagreeing = b.disagreeing().iter().map(|f| f.name.clone()).collect();
            b
        }
        BakeOutcome::Used(b, w) => {
            report.outcome = TrackBakeOutcome::Used;
            report.basin_moves = basin_move_rows(&w.basin_moves, name);
            b
        }
    };
    report.baked_from = b.frames.iter().map(|f| f.name.clone()).collect();
    report.surface_texels = Some(b.surface_texels);
    report.seen_texels = Some(b.seen_texels);
    if a.store_bake {
        if report.outcome == TrackBakeOutcome::Used {
            let provenance = Provenance {
                capture: &a.capture,
                poses: &a.out,
                pose_version: Some(version),
                frames: report.baked_from.clone(),
                forced: false,
            };
            report.stored = Some(store_bake(&a.model, model, b, provenance)?.0);
        } else {
            eprintln!("track: --store-bake: the bake was not used; nothing stored");
        }
    }
    Ok(report)
}

/// The report's rows of the frames a warm start moved to another basin, named by `name`.
fn basin_move_rows(moves: &[BasinMove], name: impl Fn(usize) -> String) -> Vec<BasinMoveRow> {
    moves
        .iter()
        .map(|m| BasinMoveRow {
            frame: name(m.frame),
            rotation_deg: m.rotation_deg,
            bound_deg: BASIN_ROTATION_DEG,
            iou_before: m.iou_before,
            iou_after: m.iou_after,
            pass: m.pass.clone(),
            across_axis_deg: m.across_axis_deg,
        })
        .collect()
}

/// `track --bake`'s lines for people: the report's own, and where the bake went.
fn print_bake(b: &TrackBakeReport) {
    for line in b.lines() {
        println!("{line}");
    }
    match &b.stored {
        Some(p) => println!("bake: stored in {}", p.display()),
        None if b.outcome == TrackBakeOutcome::Used => {
            println!("bake: kept in memory for this run (--store-bake stores it)")
        }
        None => {}
    }
}

/// The command's observer: each log line on stderr (under the progress bar), and the poses
/// so far in the partial file.
struct Observer<'a> {
    bar: &'a indicatif::ProgressBar,
    partial: Partial<'a>,
}

impl TrackObserver for Observer<'_> {
    fn line(&self, line: &str) {
        if self.bar.position() < self.bar.length().unwrap_or(0) {
            self.bar.inc(1);
        }
        self.bar.suspend(|| eprintln!("track: {line}"));
    }

    fn poses(&self, poses: &[Option<GenPose>]) {
        use std::sync::atomic::Ordering;
        // After the first failed write (reported), no more are tried.
        if self.partial.failed.load(Ordering::Relaxed) {
            return;
        }
        if let Err(e) = self.partial.write(poses) {
            self.partial.failed.store(true, Ordering::Relaxed);
            self.bar.suspend(|| {
                eprintln!(
                    "track: could not keep the partial poses in {}: {e}",
                    self.partial.path.display()
                )
            });
        }
    }
}

/// The poses found so far, kept in a pose file (atomically: a stopped run leaves the last
/// complete one) so that a run stopped by a signal, a timeout or an error leaves them. A frame
/// not tracked yet carries the pose of the nearest tracked frame through the cameras and is
/// marked `"moved": false`; `track --from PARTIAL --anchors FRAMES-MARKED-MOVED` resumes.
struct Partial<'a> {
    capture: &'a agentstar_data::capture::Capture,
    tree: &'a agentstar_geom::KinematicTree,
    scale: f64,
    path: &'a std::path::Path,
    /// Set after the first failed write.
    failed: std::sync::atomic::AtomicBool,
}

impl Partial<'_> {
    /// Writes the poses so far (nothing before the first is tracked).
    fn write(&self, poses: &[Option<GenPose>]) -> agentstar_data::Result<()> {
        if poses.len() != self.capture.frames.len() {
            return Ok(());
        }
        let tracked: Vec<usize> = (0..poses.len()).filter(|&i| poses[i].is_some()).collect();
        if tracked.is_empty() {
            return Ok(());
        }
        let mut frames: Vec<agentstar_data::posefile::FramePose> = Vec::with_capacity(poses.len());
        for i in 0..poses.len() {
            // The frame itself when tracked, else the nearest tracked one.
            let Some((k, g)) = tracked
                .iter()
                .min_by_key(|&&k| (k.abs_diff(i), k))
                .and_then(|&k| Some((k, poses[k].as_ref()?)))
            else {
                return Ok(());
            };
            let pose = if k == i {
                g.pose
            } else {
                agentstar_geom::pose::seed_from_reference(
                    &self.capture.frames[i].world_from_camera,
                    &self.capture.frames[k].world_from_camera,
                    &g.pose,
                )
            };
            frames.push(agentstar_data::posefile::FramePose {
                generalised: GenPose::new(pose, g.states.clone()),
                seeded: k != i,
                moved: k == i,
            });
        }
        let reference = &frames[self.capture.ref_index.min(frames.len() - 1)];
        let mut pf = PoseFile::initial(
            self.capture,
            self.tree,
            self.scale,
            &reference.generalised.pose,
        );
        pf.set_frames(self.capture, self.tree, &frames);
        pf.write(self.path)
    }
}
