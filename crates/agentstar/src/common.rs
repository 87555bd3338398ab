//! Shared wiring of the subcommands: loading a capture, a model and poses; frame selection;
//! rendering one frame; printing results.

use agentstar_data::capture::Capture;
use agentstar_data::posefile::{FramePose, PoseFile};
use agentstar_data::scenefile::{load_model, LoadedModel};
use agentstar_render::score::{combined_score, depth_score, DepthScore, DEFAULT_BAND_PX};
use agentstar_render::{
    render_full, IouScore, PosedModel, RenderBuffers, ScoreTarget, SilhouetteRenderer,
};
use agentstar_reports::limits::{AcknowledgedLimits, JointAtLimit, LimitEnd};
pub use agentstar_reports::FrameScore;
use anyhow::{anyhow, Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Opens a capture, turning its problem list into one error. A capture with in-between
/// frames says so on stderr: the commands that open it this way work on its keyframes.
pub fn open_capture(dir: &Path) -> Result<Capture> {
    let capture = Capture::open(dir)?;
    if let Some(note) = capture.between_note() {
        eprintln!("note: {note}");
    }
    Ok(capture)
}

pub fn open_model(path: &Path) -> Result<LoadedModel> {
    let m = load_model(path)?;
    for w in &m.warnings {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok(m)
}

/// The three inputs of every command that works on a posed model (a request type: the
/// agent's tools build it, the commands flatten it).
pub use agentstar_requests::SessionArgs;

/// Opens what a [`SessionArgs`] names.
pub trait OpenSession {
    fn open(&self) -> Result<Session>;
}

impl OpenSession for SessionArgs {
    fn open(&self) -> Result<Session> {
        Session::open(&self.capture, &self.model, &self.poses)
    }
}

/// One frame's observation: the score target (mask, hands excluded) and observed depth.
pub type FrameInputs = (ScoreTarget, Option<agentstar_render::DepthObservation>);

/// Capture, model and resolved poses of a run.
pub struct Session {
    pub capture: Capture,
    pub model: LoadedModel,
    pub pose_file: PoseFile,
    pub poses: Vec<FramePose>,
    /// The boundary band (half-width in pixels) that scores and targets exclude for the band
    /// IoU; 0 scores no band. [`DEFAULT_BAND_PX`] unless a command's `--band-px` says otherwise.
    pub band_px: f64,
}

impl Session {
    pub fn open(capture: &Path, model: &Path, poses: &Path) -> Result<Session> {
        let capture = open_capture(capture)?;
        let model = open_model(model)?;
        let pose_file = PoseFile::read(poses)?;
        let resolved = pose_file
            .resolve(&capture, &model.model.tree)
            .map_err(|e| anyhow!("{}: {e}", poses.display()))?;
        Ok(Session {
            capture,
            model,
            pose_file,
            poses: resolved,
            band_px: DEFAULT_BAND_PX,
        })
    }

    /// A session on what a command already holds (the tracker's result), without reading
    /// the files again.
    pub fn from_memory(
        capture: Capture,
        model: LoadedModel,
        pose_file: PoseFile,
        poses: Vec<FramePose>,
    ) -> Session {
        Session {
            capture,
            model,
            pose_file,
            poses,
            band_px: DEFAULT_BAND_PX,
        }
    }

    pub fn scale(&self) -> f64 {
        self.pose_file.scale
    }

    pub fn posed(&self, i: usize) -> PosedModel<'_> {
        let p = &self.poses[i];
        PosedModel::new(
            &self.model.model,
            &p.generalised.states,
            &p.generalised.pose.with_scale(self.scale()),
        )
    }

    pub fn render_buffers(&self, i: usize) -> RenderBuffers {
        render_full(&self.capture.frames[i].camera, &self.posed(i).instances)
    }

    /// Frame `i`'s full render and the model drawn from it with its textures, vertex
    /// colours and part colours.
    pub fn render_shaded(
        &self,
        i: usize,
        opts: agentstar_render::views::ShadeOptions,
    ) -> (RenderBuffers, image::RgbaImage) {
        let camera = &self.capture.frames[i].camera;
        let posed = self.posed(i);
        let buffers = render_full(camera, &posed.instances);
        let shaded = agentstar_render::views::shade_model(
            &self.model.model,
            &posed.instances,
            camera,
            &buffers,
            opts,
        );
        (buffers, shaded)
    }

    /// The score target (mask with hands excluded) and observed depth of frame `i`.
    pub fn target(&self, i: usize) -> Result<FrameInputs> {
        let target = ScoreTarget::new(self.capture.load_mask(i)?, self.capture.load_hand(i)?)?
            .with_band(self.band_px);
        Ok((target, self.capture.load_depth(i)?))
    }

    /// The generalised pose of frame `i`.
    pub fn gen_pose(&self, i: usize) -> agentstar_track::GenPose {
        self.poses[i].generalised.clone()
    }

    /// Which side of the model and of each part faces the camera in frame `i` (its full
    /// render `buffers`), with each part's pixels in view; `None` when the camera sits at the
    /// model's centre.
    pub fn facing_in(
        &self,
        i: usize,
        buffers: &RenderBuffers,
    ) -> Option<agentstar_reports::view::FrameFacing> {
        let p = &self.poses[i].generalised;
        let mut f = agentstar_geom::facing::facing(
            &self.model.model,
            &p.states,
            &p.pose.with_scale(self.scale()),
        )?;
        // Each part's pixels in view: a part turned toward the camera may still be hidden
        // (play-test 16 read `label +Y at 23°` for a label on the far side).
        let seen = buffers.part_pixels(self.model.model.parts.len());
        for side in &mut f.parts {
            side.pixels_seen = self
                .model
                .model
                .parts
                .iter()
                .position(|m| m.name == side.part)
                .and_then(|k| seen.get(k).copied());
        }
        Some(agentstar_reports::view::FrameFacing {
            frame: self.capture.frames[i].name.clone(),
            toward: f.model.axis.to_string(),
            angle_deg: f.model.angle.to_degrees(),
            axis_angles_deg: f.model.axis_angles.map(f64::to_degrees),
            parts: f
                .parts
                .iter()
                .map(|p| agentstar_reports::view::PartFacing {
                    part: p.part.clone(),
                    toward: p.side.axis.to_string(),
                    angle_deg: p.side.angle.to_degrees(),
                    moved: p.moved,
                    pixels_seen: p.pixels_seen,
                })
                .collect(),
            line: f.line(6),
        })
    }

    /// Scores frame `i`; `depth_weight` enters the combined score when the capture has depth.
    pub fn score(&self, i: usize, depth_weight: f64) -> Result<FrameScore> {
        let inputs = self.target(i)?;
        let buffers = inputs.1.as_ref().map(|_| self.render_buffers(i));
        self.score_on(i, &inputs, buffers.as_ref(), depth_weight)
    }

    /// [`Self::score`] on frame `i`'s inputs read already ([`Self::target`]); `buffers`: its
    /// full render at its pose, which the depth term needs (rendered here when the capture
    /// has depth and none is given).
    pub fn score_on(
        &self,
        i: usize,
        (target, observed_depth): &FrameInputs,
        buffers: Option<&RenderBuffers>,
        depth_weight: f64,
    ) -> Result<FrameScore> {
        let f = &self.capture.frames[i];
        let mut r = SilhouetteRenderer::new(f.camera.width, f.camera.height);
        let s = target.score(r.render(&f.camera, &self.posed(i).instances));
        let depth = match observed_depth {
            Some(obs) => match buffers {
                Some(b) => depth_score(b, obs, target, self.scale(), 0.1)?,
                None => depth_score(&self.render_buffers(i), obs, target, self.scale(), 0.1)?,
            },
            None => None,
        };
        let combined = combined_score(s.gate(), depth.as_ref(), depth_weight);
        Ok(frame_score(&f.name, &s, target.band_px(), depth, combined))
    }
}

/// Frame `i`'s colour image and its visible object mask (hands removed), what the
/// appearance term reads; `None` when the image cannot be read or is not its camera's size
/// (the frame then has no appearance figure; its masks' errors are errors).
pub fn appearance_inputs(
    cap: &agentstar_data::capture::Capture,
    i: usize,
) -> Result<Option<(image::RgbImage, agentstar_render::BitMask)>> {
    let camera = &cap.frames[i].camera;
    let image = match cap.load_frame(i) {
        Ok(img) if (img.width(), img.height()) == (camera.width, camera.height) => img,
        _ => return Ok(None),
    };
    let mask = match cap.load_hand(i)? {
        Some(hand) => cap.load_mask(i)?.and_not(&hand),
        None => cap.load_mask(i)?,
    };
    Ok(Some((image, mask)))
}

/// One frame's score from the renderer's scores (the report type is shared with the tools).
pub fn frame_score(
    frame: &str,
    s: &IouScore,
    band_px: Option<f64>,
    d: Option<DepthScore>,
    combined: f64,
) -> FrameScore {
    FrameScore {
        frame: frame.to_string(),
        iou_visible: s.iou_visible,
        iou_raw: s.iou_raw,
        render_px: s.render_px,
        mask_px: s.mask_px,
        hand_px: s.hand_px,
        depth_mae: d.map(|d| d.mae),
        depth_mae_canon: d.map(|d| d.mae_canon),
        depth_bias: d.map(|d| d.bias),
        combined,
        band_px,
        iou_band: s.iou_band,
        band_share: s.band_share,
    }
}

/// Parses `--frames` with the one frame grammar ([`Capture::select`]). Returns capture
/// indices in temporal order.
pub fn select_frames(capture: &Capture, spec: Option<&str>) -> Result<Vec<usize>> {
    Ok(capture.select(spec)?)
}

/// Writes tracked generalised poses, one per frame of `capture` in order, as a pose file;
/// returns the file and the poses as written.
pub fn write_tracked_poses(
    capture: &Capture,
    tree: &agentstar_geom::KinematicTree,
    scale: f64,
    poses: &[agentstar_track::GenPose],
    path: &Path,
) -> Result<(PoseFile, Vec<FramePose>)> {
    let (pf, frames) = tracked_pose_file(capture, tree, scale, poses)?;
    pf.write(path)?;
    Ok((pf, frames))
}

/// Like [`write_tracked_poses`], but the file is written as a version of its history
/// (`agentstar_data::history`) with this process's command: what `track` does. Returns
/// the version too.
/// In-between frames' poses are written too (`"between": true`), where given.
pub fn write_tracked_version(
    capture: &Capture,
    tree: &agentstar_geom::KinematicTree,
    scale: f64,
    poses: &[agentstar_track::GenPose],
    between: &[(String, agentstar_track::GenPose)],
    path: &Path,
) -> Result<(PoseFile, Vec<FramePose>, u64)> {
    let (mut pf, frames) = tracked_pose_file(capture, tree, scale, poses)?;
    pf.set_between(tree, between.iter().map(|(n, g)| (n.as_str(), g)));
    let version = agentstar_data::history::PoseHistory::new(path)
        .write(&pf, &agentstar_data::history::command_line())?;
    Ok((pf, frames, version))
}

fn tracked_pose_file(
    capture: &Capture,
    tree: &agentstar_geom::KinematicTree,
    scale: f64,
    poses: &[agentstar_track::GenPose],
) -> Result<(PoseFile, Vec<FramePose>)> {
    let frames: Vec<FramePose> = poses
        .iter()
        .map(|g| FramePose {
            generalised: g.clone(),
            seeded: false,
            moved: true,
        })
        .collect();
    let reference = frames
        .get(capture.ref_index)
        .ok_or_else(|| anyhow!("no pose for the reference frame"))?;
    let mut pf = PoseFile::initial(capture, tree, scale, &reference.generalised.pose);
    pf.set_frames(capture, tree, &frames);
    Ok((pf, frames))
}

/// Prints JSON to stdout.
/// A joint piled at a limit as the reports carry it.
pub fn joint_at_limit(at: agentstar_geom::kinematics::AtLimit) -> JointAtLimit {
    JointAtLimit {
        joint: at.joint,
        end: match at.end {
            agentstar_geom::kinematics::LimitEnd::Lower => LimitEnd::Lower,
            agentstar_geom::kinematics::LimitEnd::Upper => LimitEnd::Upper,
        },
        bound: at.bound,
        frames: at.frames,
        keyframes: at.keyframes,
    }
}

/// The joint-limit warnings acknowledged in `path` (none where there is no such file).
pub fn read_acknowledged_limits(path: Option<&Path>) -> Result<AcknowledgedLimits> {
    let Some(path) = path.filter(|p| p.is_file()) else {
        return Ok(AcknowledgedLimits::default());
    };
    let text = agentstar_data::read_text(path)?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not a record of acknowledged limits", path.display()))
}

pub fn print_json<T: Serialize>(value: &T) -> Result<()> {
    println!(
        "{}",
        serde_json::to_string_pretty(value).context("serialising the result")?
    );
    Ok(())
}

pub fn out_dir(dir: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir.to_path_buf())
}

/// The gate every keyframe must reach (defined once, with the reports).
pub use agentstar_render::GATE_IOU as PASS_IOU;

/// A progress bar on stderr (drawn only when stderr is a terminal, so logs and pipes stay
/// clean) for `len` steps of `what`.
pub fn progress(len: usize, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(len as u64),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{prefix} [{bar:30}] {pos}/{len} {elapsed_precise} {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(what.to_string());
    bar.with_finish(indicatif::ProgressFinish::AndClear)
}
