//! The searcher every pass uses: one model at one scale over every frame's targets, with
//! its refinements, the global search, twins, rescue, the wide search and settling.

use super::*;
use crate::appearance::{
    appearance_score, model_has_appearance, AppearanceConfig, ModelColours, ReferenceView,
};
use crate::axis::SymmetryAxis;
use crate::hypotheses::{
    principal_axes, refine_above, refine_each_above, refine_first_pass, refine_local, refine_rest,
    twin_candidates, LocalWindow, PRUNE_SLACK,
};
use crate::objective::FrameProblem;
use crate::space::joint_default;
use crate::temporal::{angle_deg, signed_deg};
use crate::update::{apply_object_rotation, flip, GenPose};
use crate::TrackError;
use agentstar_geom::{ObjectModel, Point3, UnitQuaternion, Vector3};
use agentstar_render::{ScoreTarget, DEFAULT_BAND_PX};

pub(super) struct Searcher<'m> {
    pub(super) model: &'m ObjectModel,
    pub(super) scale: f64,
    pub(super) cfg: TrackConfig,
    pub(super) evals: std::sync::atomic::AtomicUsize,
    /// Each frame's target with the boundary band excluded ([`DEFAULT_BAND_PX`]): what
    /// [`Searcher::band_iou`] reads to tell a right pose from a wrong basin on noisy masks.
    pub(super) banded: Vec<ScoreTarget>,
    /// Each frame's target at half the resolution, for the wide passes of local searches
    /// ([`FrameProblem::with_coarse`]).
    pub(super) halved: Vec<ScoreTarget>,
    /// The address of each frame's target: how [`Searcher::halved_of`] tells frames apart.
    pub(super) targets: Vec<usize>,
    /// The motion the video between keyframes g and g + 1 measured ([`Gap`]), where a chain
    /// followed it: how [`Searcher::carried`] carries a pose across that gap.
    pub(super) gaps: std::sync::RwLock<Vec<Option<Gap>>>,
    /// The model's outline axis ([`crate::axis::outline_axis`], at rest), found when first
    /// asked: a chain cannot measure a turn about it.
    pub(super) outline_axis: std::sync::OnceLock<Option<crate::axis::SymmetryAxis>>,
    /// The model's round body's axis ([`crate::axis::body_axis`], at rest), found when first
    /// asked for.
    pub(super) body_axis: std::sync::OnceLock<Option<crate::axis::SymmetryAxis>>,
    /// How the model's own colours count ([`ModelColours`]): as painted until the tracker
    /// judges them no likeness of the frames ([`super::judge_model_colours`]).
    pub(super) model_colours: std::sync::RwLock<ModelColours>,
}

/// The least difference [`Searcher::hold_unseen`] sets back, in a joint's units or radians of
/// turn: 0.5° of a turn or of a revolute joint, 0.0087 model units (under 1% of the model's
/// longest side) of a prismatic one.
const HOLD_MIN: f64 = 0.5 * std::f64::consts::PI / 180.0;

impl<'m> Searcher<'m> {
    /// Checks the inputs every tracker shares.
    pub(super) fn new(
        model: &'m ObjectModel,
        scale: f64,
        frames: &[TrackFrame<'_>],
        cfg: &TrackConfig,
    ) -> Result<Self, TrackError> {
        if frames.is_empty() {
            return Err(TrackError::Invalid("no frames to track".into()));
        }
        if !(scale.is_finite() && scale > 0.0) {
            return Err(TrackError::Invalid(format!(
                "scale {scale} must be positive"
            )));
        }
        Ok(Searcher {
            model,
            scale,
            cfg: cfg.clone(),
            evals: Default::default(),
            banded: frames
                .iter()
                .map(|f| f.target.clone().with_band(DEFAULT_BAND_PX))
                .collect(),
            halved: frames.iter().map(|f| f.target.halved()).collect(),
            targets: frames
                .iter()
                .map(|f| std::ptr::from_ref(f.target) as usize)
                .collect(),
            gaps: std::sync::RwLock::new(vec![None; frames.len().saturating_sub(1)]),
            outline_axis: std::sync::OnceLock::new(),
            body_axis: std::sync::OnceLock::new(),
            model_colours: std::sync::RwLock::new(ModelColours::AsPainted),
        })
    }

    /// The appearance term's settings, with the model's colours counted as judged
    /// ([`Self::model_colours`]).
    pub(super) fn appearance_cfg(&self) -> AppearanceConfig {
        AppearanceConfig {
            model_colours: self
                .model_colours
                .read()
                .map_or(ModelColours::AsPainted, |m| *m),
            ..AppearanceConfig::default()
        }
    }

    /// Counts another searcher's evaluations as this one's (and zeroes them there): the
    /// in-between frames' searcher reports through the keyframes'.
    pub(super) fn absorb_evals(&self, other: &Searcher<'_>) {
        use std::sync::atomic::Ordering::Relaxed;
        self.evals.fetch_add(other.evals.swap(0, Relaxed), Relaxed);
    }

    /// Records the motion a chain measured across gap `g` (keyframes g → g + 1).
    pub(super) fn set_gap(&self, g: usize, gap: Gap) {
        if let Ok(mut gaps) = self.gaps.write() {
            if let Some(slot) = gaps.get_mut(g) {
                *slot = Some(gap);
            }
        }
    }

    /// Forgets the motion recorded across gap `g` (its chain's arrival was replaced).
    pub(super) fn clear_gap(&self, g: usize) {
        if let Ok(mut gaps) = self.gaps.write() {
            if let Some(slot) = gaps.get_mut(g) {
                *slot = None;
            }
        }
    }

    /// The model's outline axis ([`crate::axis::outline_axis`], at rest), found when first
    /// asked for.
    pub(super) fn round_outline_axis(&self) -> Option<crate::axis::SymmetryAxis> {
        *self
            .outline_axis
            .get_or_init(|| crate::axis::outline_axis(self.model, &self.model.tree.rest_states()))
    }

    /// How far `to` is turned from the pose a chain predicts (`predicted`; both rotations of
    /// one frame's camera from the object), in radians, leaving out any turn about the
    /// model's outline axis ([`crate::axis::outline_axis`]: a can's, a bottle's): the masks
    /// the chain followed cannot measure that turn, so a chain's motion is no evidence about
    /// it (hard suite labelcan with in-between frames: the appearance pass's turns of 50–100°
    /// about the can's axis, which its colours wanted, were refused as leaving the chain).
    pub(super) fn off_chain(
        &self,
        predicted: &agentstar_geom::UnitQuaternion,
        to: &agentstar_geom::UnitQuaternion,
    ) -> f64 {
        // The turn in the object's frame.
        let turn = predicted.inverse() * to;
        match self.round_outline_axis() {
            Some(axis) => crate::axis::angle_across(&turn, &axis.axis),
            None => turn.angle(),
        }
    }

    /// The motion measured across gap `g`, where a chain followed it.
    pub(super) fn gap(&self, g: usize) -> Option<Gap> {
        self.gaps
            .read()
            .ok()
            .and_then(|gaps| gaps.get(g).copied().flatten())
    }

    /// Frame `from`'s pose carried into frame `to`: through the cameras (the object held
    /// still), and, between neighbouring keyframes whose video a chain followed, turned by
    /// the motion it measured ([`Gap`]), with its joint states.
    pub(super) fn carried(
        &self,
        frames: &[TrackFrame<'_>],
        poses: &[GenPose],
        from: usize,
        to: usize,
    ) -> GenPose {
        let mut pose = poses[from].pose;
        if to == from + 1 {
            if let Some(gap) = self.gap(from) {
                pose = transfer(&pose, &frames[from], &frames[to]);
                pose.rotation = gap.rotation * pose.rotation;
                return GenPose {
                    pose,
                    states: poses[from].states.clone(),
                };
            }
        } else if from == to + 1 {
            if let Some(gap) = self.gap(to) {
                // R_from = W · C · R_to, so R_to = C⁻¹ · W⁻¹ · R_from (C: the cameras').
                pose.rotation = gap.rotation.inverse() * pose.rotation;
            }
        }
        GenPose {
            pose: transfer(&pose, &frames[from], &frames[to]),
            states: poses[from].states.clone(),
        }
    }

    /// [`refine_local`] around `base` in `window`, counting its evaluations.
    pub(super) fn refine(
        &self,
        frame: &TrackFrame<'_>,
        base: &GenPose,
        window: &LocalWindow,
        seed: u64,
    ) -> Result<(GenPose, f64), TrackError> {
        let problem = self.problem_of(frame, base);
        let (best, score, n) = refine_local(&problem, base, window, seed)?;
        self.evals
            .fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        Ok((best, score))
    }

    /// The model's round body's axis ([`crate::axis::body_axis`], at rest; found when first
    /// asked for): what the passes turn a pose about where only colours, or the motion, see
    /// the turn.
    pub(super) fn round_body(&self) -> Option<&crate::axis::SymmetryAxis> {
        self.body_axis
            .get_or_init(|| crate::axis::body_axis(self.model, &self.model.tree.rest_states()))
            .as_ref()
    }

    /// `fitted` (scoring `score` on `frame`) with what the mask does not see of it held where
    /// `predicted` has it: its turn about the model's round body's axis ([`Self::round_body`]),
    /// then each joint state, each set back to the prediction's and kept when the score stays
    /// within `tie` of the pose before it (so `k` directions held may lose `k · tie`; the
    /// figures of 2026-12-05 were measured so). A search ends
    /// anywhere along a direction the mask cannot see (a round body's turn while its lever is
    /// hidden, a hidden part's joint); the motion's prediction is the better guess there, and
    /// where the mask does see the direction (the lever in view), setting it back costs more
    /// than the tie and the fit stays. Differences under [`HOLD_MIN`] are left as they are.
    pub(super) fn hold_unseen(
        &self,
        frame: &TrackFrame<'_>,
        (fitted, score): (GenPose, f64),
        predicted: &GenPose,
        tie: f64,
    ) -> (GenPose, f64) {
        let problem = self.problem_of(frame, &fitted);
        let mut ev = problem.evaluator();
        let mut tried = 0;
        let mut try_back = |(g, sc): (GenPose, f64), back: GenPose| {
            let back_score = ev.combined(&back);
            tried += 1;
            if back_score >= sc - tie {
                (back, back_score)
            } else {
                (g, sc)
            }
        };
        let mut held = (fitted, score);
        if let Some(axis) = self.round_body() {
            let deg = crate::axis::twist_deg(
                &(predicted.pose.rotation.inverse() * held.0.pose.rotation),
                &axis.axis,
            );
            if deg.abs().to_radians() > HOLD_MIN {
                let back = axis.turn(&held.0, self.scale, -deg);
                held = try_back(held, back);
            }
        }
        for j in 0..held.0.states.len().min(predicted.states.len()) {
            if (held.0.states[j] - predicted.states[j]).abs() > HOLD_MIN {
                let mut back = held.0.clone();
                back.states[j] = predicted.states[j];
                held = try_back(held, back);
            }
        }
        self.evals
            .fetch_add(tried, std::sync::atomic::Ordering::Relaxed);
        held
    }

    /// `frame`'s target at half the resolution (frames are the ones the searcher was made
    /// for, told apart by their target).
    pub(super) fn halved_of(&self, frame: &TrackFrame<'_>) -> Option<&ScoreTarget> {
        self.targets
            .iter()
            .position(|&t| t == std::ptr::from_ref(frame.target) as usize)
            .map(|i| &self.halved[i])
    }

    /// The narrow refinement around a pose that is already close ([`LocalWindow::polish`]),
    /// with half the local budget.
    pub(super) fn polish(
        &self,
        frame: &TrackFrame<'_>,
        base: &GenPose,
        seed: u64,
    ) -> Result<(GenPose, f64), TrackError> {
        self.refine(frame, base, &self.polish_window(), seed)
    }

    /// The polish's window: [`LocalWindow::polish`] with half the local budget.
    pub(super) fn polish_window(&self) -> LocalWindow {
        LocalWindow {
            evals: self.cfg.local_evals / 2,
            ..LocalWindow::polish()
        }
    }

    /// [`Searcher::polish`] that stops after its first pass when it scores under `floor`
    /// there (a seed that cannot beat the frame's pose).
    pub(super) fn polish_above(
        &self,
        frame: &TrackFrame<'_>,
        base: &GenPose,
        seed: u64,
        floor: f64,
    ) -> Result<(GenPose, f64), TrackError> {
        self.refine_above(frame, base, &self.polish_window(), seed, floor)
    }

    /// [`refine_above`] in `window`, counting its evaluations; the pose with its score.
    pub(super) fn refine_above(
        &self,
        frame: &TrackFrame<'_>,
        base: &GenPose,
        window: &LocalWindow,
        seed: u64,
        floor: f64,
    ) -> Result<(GenPose, f64), TrackError> {
        let problem = self.problem_of(frame, base);
        let (pose, n) = refine_above(&problem, base, window, seed, floor)?;
        self.evals
            .fetch_add(n + 1, std::sync::atomic::Ordering::Relaxed);
        let score = problem.evaluator().combined(&pose);
        Ok((pose, score))
    }

    /// The refinement around a hypothesis that may be a whole basin away from where it was
    /// placed ([`LocalWindow::basin`]), with the whole local budget.
    pub(super) fn basin(
        &self,
        frame: &TrackFrame<'_>,
        base: &GenPose,
        seed: u64,
    ) -> Result<(GenPose, f64), TrackError> {
        self.refine(frame, base, &self.basin_window(), seed)
    }

    /// The basin's window: [`LocalWindow::basin`] with the whole local budget.
    pub(super) fn basin_window(&self) -> LocalWindow {
        LocalWindow {
            evals: self.cfg.local_evals,
            ..LocalWindow::basin()
        }
    }

    /// [`Searcher::basin`] that stops after its first pass when it scores under `floor`
    /// there ([`refine_above`]; with `f64::NEG_INFINITY`, exactly [`Searcher::basin`]).
    pub(super) fn basin_above(
        &self,
        frame: &TrackFrame<'_>,
        base: &GenPose,
        seed: u64,
        floor: f64,
    ) -> Result<(GenPose, f64), TrackError> {
        if floor == f64::NEG_INFINITY {
            return self.basin(frame, base, seed);
        }
        self.refine_above(frame, base, &self.basin_window(), seed, floor)
    }

    /// The band IoU of `g` in frame `i` (the visible IoU without the ±[`DEFAULT_BAND_PX`]
    /// boundary band of the observed mask, as the gate reads it): true poses on masks with
    /// a segmenter's 1–2 px boundary errors score 0.995–1.0 on it, poses a few degrees off
    /// or in a wrong basin clearly less.
    pub(super) fn band_iou(&self, frame: &TrackFrame<'_>, i: usize, g: &GenPose) -> f64 {
        self.evals
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        crate::objective::band_iou(self.model, frame.camera, &self.banded[i], self.scale, g)
    }

    /// A search of the whole rotation space for one frame, as the initialisation does it:
    /// a covering of rotations and joint states placed on the mask, the best distinct
    /// hypotheses refined in the basin window (those under `floor` after its first pass
    /// left there: [`refine_above`]). Every refined hypothesis, best first (empty when the
    /// mask is).
    pub(super) fn global(
        &self,
        frame: &TrackFrame<'_>,
        rotations: &[UnitQuaternion],
        joint_sets: &[Vec<f64>],
        seed: u64,
        floor: f64,
    ) -> Result<Vec<(GenPose, f64)>, TrackError> {
        let hyps = self.covering(frame, rotations, joint_sets);
        let top = diverse(&hyps, GLOBAL_KEEP, 30.0);
        let Some(problem) = top.first().map(|g| self.problem_of(frame, g)) else {
            return Ok(vec![]);
        };
        let window = self.basin_window();
        let count = |n: usize| {
            self.evals
                .fetch_add(n, std::sync::atomic::Ordering::Relaxed)
        };
        // Every hypothesis through the widest pass first; only those that may still be
        // chosen (within a tie and the narrower passes' reach of the best so far, and of
        // `floor`) are refined further.
        let first: Vec<(GenPose, f64)> = top
            .par_iter()
            .enumerate()
            .map(|(k, g)| {
                let (pose, score, n) =
                    refine_first_pass(&problem, g, &window, seed + 100 * k as u64)?;
                count(n);
                Ok::<_, TrackError>((pose, score))
            })
            .collect::<Result<_, _>>()?;
        let best_first = first.iter().map(|x| x.1).fold(f64::NEG_INFINITY, f64::max);
        let floor = floor.max(best_first - APPEARANCE_TIE - PRUNE_SLACK);
        let mut refined: Vec<(GenPose, f64)> = first
            .into_par_iter()
            .zip(top.par_iter())
            .enumerate()
            .map(|(k, ((pose, score), start))| {
                if score < floor {
                    return Ok((pose, score));
                }
                let (pose, score, n) =
                    refine_rest(&problem, start, &pose, &window, seed + 100 * k as u64)?;
                count(n);
                Ok::<_, TrackError>((pose, score))
            })
            .collect::<Result<_, _>>()?;
        refined.sort_by(|a, b| b.1.total_cmp(&a.1));
        Ok(refined)
    }

    /// `frame`'s problem around `base` (the frame's target, at half resolution too).
    pub(super) fn problem_of<'s>(
        &'s self,
        frame: &TrackFrame<'s>,
        base: &GenPose,
    ) -> FrameProblem<'s> {
        let problem = FrameProblem::new(
            self.model,
            frame.camera,
            frame.target,
            self.scale,
            base.clone(),
        )
        .with_held_axis(self.round_outline_axis());
        match self.halved_of(frame) {
            Some(h) => problem.with_coarse(h),
            None => problem,
        }
    }

    /// The twins of `pose` ([`twin_candidates`]) refined in the basin window (those under
    /// `floor` after its first pass left there).
    pub(super) fn twins(
        &self,
        frame: &TrackFrame<'_>,
        pose: &GenPose,
        seed: u64,
        floor: f64,
    ) -> Result<Vec<(GenPose, f64)>, TrackError> {
        let problem = self.problem_of(frame, pose);
        let refined = refine_each_above(
            &problem,
            &twin_candidates(self.model, self.scale, pose),
            &LocalWindow::basin(),
            seed,
            floor,
        )?;
        Ok(refined
            .into_iter()
            .map(|r| {
                self.evals
                    .fetch_add(r.evals, std::sync::atomic::Ordering::Relaxed);
                (r.pose, r.score.combined)
            })
            .collect())
    }

    /// The global search of one frame ([`Searcher::global`] over `joint_sets`, each once),
    /// the twins of its best basin ([`Searcher::twins`]) and any `extra` hypotheses, and the
    /// choice among them ([`Searcher::pick`]): the hypothesis that replaces `current` and why,
    /// or `None`. `seeds`: the covering's refinements', the twins'.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rescue(
        &self,
        frame: &TrackFrame<'_>,
        current: (&GenPose, f64),
        rotations: &[UnitQuaternion],
        mut joint_sets: Vec<Vec<f64>>,
        extra: Vec<(GenPose, f64)>,
        refs: &[ReferenceView<'_>],
        seeds: (u64, u64),
    ) -> Result<Rescue, TrackError> {
        // A rigid model's sets are all empty, and a state found here may be the neighbour's:
        // each set once, or the covering places the same hypotheses again.
        let mut seen: Vec<Vec<f64>> = Vec::with_capacity(joint_sets.len());
        joint_sets.retain(|set| {
            let new = !seen.contains(set);
            if new {
                seen.push(set.clone());
            }
            new
        });
        // A hypothesis under the current pose's score by more than a tie cannot be picked
        // ([`Searcher::pick`]): its refinement stops after the first pass.
        let floor = current.1 - APPEARANCE_TIE - PRUNE_SLACK;
        let mut found = self.global(frame, rotations, &joint_sets, seeds.0, floor)?;
        // The twins of the best basin found (flips, principal half-turns: a laptop's lid
        // and base swapped), refined, so that colours can choose between them.
        if let Some((best, _)) = found.first().cloned() {
            found.extend(self.twins(frame, &best, seeds.1, floor)?);
        }
        found.extend(extra);
        found.sort_by(|a, b| b.1.total_cmp(&a.1));
        // Every distinct basin that explains the mask nearly as well, for the sequence-level
        // choice: it may need one the colours of this frame alone turned down.
        let top = found.first().map_or(current.1, |f| f.1.max(current.1));
        let mut basins: Vec<(GenPose, f64)> = Vec::new();
        for (g, sc) in &found {
            let distinct = basins.iter().all(|(b, _)| {
                angle_deg(&(b.pose.rotation * g.pose.rotation.inverse())) >= DISTINCT_DEG
            });
            if *sc >= top - CHOICE_KEEP && distinct {
                basins.push((g.clone(), *sc));
            }
        }
        let chosen = self
            .pick(frame, current, &found, refs)
            .map(|(k, text)| (found.swap_remove(k), text));
        Ok(Rescue { chosen, basins })
    }

    /// Which of a global search's hypotheses (`found`, best first) replaces the pose found
    /// from the neighbours (`current`), if any, and why. Hypotheses within
    /// [`APPEARANCE_TIE`] of the best score explain the mask alike (twins); among distinct
    /// ones the frames' colours decide (NCC against `refs`, by the appearance margin), and
    /// without a clear colour winner the current pose is kept while it is among them
    /// (continuity), else the best score is taken. A hypothesis that is not a tie must beat
    /// the current pose by [`RESCUE_MARGIN`].
    pub(super) fn pick(
        &self,
        frame: &TrackFrame<'_>,
        current: (&GenPose, f64),
        found: &[(GenPose, f64)],
        refs: &[ReferenceView<'_>],
    ) -> Option<(usize, String)> {
        let top = found.first()?.1.max(current.1);
        let distinct = |a: &GenPose, b: &GenPose| {
            angle_deg(&(a.pose.rotation * b.pose.rotation.inverse())) >= DISTINCT_DEG
        };
        let current_in = current.1 >= top - APPEARANCE_TIE;
        // Tied hypotheses of other basins than the current pose's (and than each other's).
        let mut tied: Vec<usize> = Vec::new();
        for (k, (g, sc)) in found.iter().enumerate() {
            if *sc >= top - APPEARANCE_TIE
                && (!current_in || distinct(g, current.0))
                && tied.iter().all(|&t| distinct(g, &found[t].0))
            {
                tied.push(k);
            }
        }
        if tied.is_empty() {
            // Only the current basin ties (the current pose is among the best, or tied would
            // hold the best): keep it unless the search refined it further.
            return (found[0].1 > current.1 + RESCUE_MARGIN)
                .then(|| (0, format!("refined globally to IoU {:.4}", found[0].1)));
        }
        // The frames' colours against `refs`, and the model's own colours where it has them.
        let evidence = !refs.is_empty() || model_has_appearance(self.model);
        if let Some(app) = frame.appearance().filter(|_| evidence) {
            let cfg = self.appearance_cfg();
            let ncc =
                |g: &GenPose| appearance_score(self.model, self.scale, &app, g, refs, &cfg).ncc;
            let mut scored: Vec<(Option<usize>, f64)> = tied
                .par_iter()
                .filter_map(|&k| ncc(&found[k].0).map(|v| (Some(k), v)))
                .collect();
            if current_in {
                if let Some(v) = ncc(current.0) {
                    scored.push((None, v));
                }
            }
            self.evals
                .fetch_add(scored.len(), std::sync::atomic::Ordering::Relaxed);
            scored.sort_by(|a, b| b.1.total_cmp(&a.1));
            if let [(best, v0), (_, v1), ..] = scored[..] {
                if v0 - v1 > cfg.margin {
                    return best.map(|k| {
                        (
                            k,
                            format!(
                                "colours chose among {} twins (NCC {v0:.2} against {v1:.2})",
                                scored.len()
                            ),
                        )
                    });
                }
            }
        }
        if current_in {
            return None;
        }
        let k = tied[0];
        (found[k].1 > current.1 + RESCUE_MARGIN).then(|| {
            let why = match tied.len() {
                1 => format!(
                    "its best basin scores IoU {:.4} above the pose from the neighbour",
                    found[k].1 - current.1
                ),
                n => format!(
                    "{n} basins tie within {APPEARANCE_TIE} IoU and colours do not tell them apart; the best IoU taken"
                ),
            };
            (k, why)
        })
    }

    /// The wide search after a drop: the 180° flips of the best pose so far, and a covering
    /// of rotations within 120° of the seed with the joint grid, placed on the mask; the
    /// best four refined in the basin window, those under `floor` after its first pass left
    /// there ([`refine_above`]: callers keep the result only above a score, and `floor` is
    /// that score less [`PRUNE_SLACK`], or `f64::NEG_INFINITY` to refine all four fully).
    pub(super) fn wide(
        &self,
        frame: &TrackFrame<'_>,
        best: &GenPose,
        seed_pose: &GenPose,
        (rotation_seed, seed): (u64, u64),
        floor: f64,
    ) -> Result<Option<(GenPose, f64)>, TrackError> {
        let pivot = self.model.pivot(&best.states);
        let mut rots: Vec<UnitQuaternion> = ['x', 'y', 'z']
            .iter()
            .filter_map(|&a| flip(a))
            .map(|f| apply_object_rotation(&best.pose, self.scale, &pivot, &f).rotation)
            .collect();
        for q in haar_rotations(self.cfg.rotations / 2, rotation_seed) {
            let cand = q * seed_pose.pose.rotation;
            if angle_deg(&(cand * seed_pose.pose.rotation.inverse())) <= 120.0 {
                rots.push(cand);
            }
        }
        let mut joint_sets = self.joint_grid();
        joint_sets.push(best.states.clone());
        let hyps = self.covering(frame, &rots, &joint_sets);
        let wide: Vec<Result<(GenPose, f64), TrackError>> = hyps
            .iter()
            .take(4)
            .enumerate()
            .map(|(k, h)| (k, h.0.clone()))
            .collect::<Vec<_>>()
            .par_iter()
            .map(|(k, h)| self.basin_above(frame, h, seed + *k as u64, floor))
            .collect();
        best_of(wide)
    }

    /// Appearance among silhouette twins: the turns of `pose` about the model's principal
    /// axes through its centroid (every [`TURN_STEP_DEG`]) that explain the mask as well
    /// (within [`APPEARANCE_TIE`] of `score`, as turned or moved back onto the mask by
    /// [`realign`], without a search: a turn about a symmetry axis keeps the outline), scored
    /// by photometric consistency with `refs` (frames already tracked). A turn that comes
    /// within [`SETTLE_NEAR`] only (a mug turned about its body with the handle under a hand:
    /// the principal axis is tilted a few degrees off the body's) and whose colours beat
    /// every placed one is refined on the masks first, and counts if it then ties. The best
    /// is taken when its NCC beats the pose's own by the appearance margin, then turned
    /// finely (10°, 5° and 2.5° steps) about the same axis while its NCC improves and its
    /// outline holds. Without such a winner, a pose on an axis of continuous symmetry (every
    /// turn ties) is turned finely about it while its NCC gains [`CONTINUOUS_GAIN`] a step.
    /// `None` when appearance keeps the pose (no twin, no evidence, or no clear winner: an
    /// untextured object).
    ///
    /// No turn is taken into a `barred` basin (one the sequence choice weighed and did not
    /// take): a candidate within half [`REJECTED_BASIN_DEG`] of one is passed over, and the
    /// next best may win.
    pub(super) fn settle(
        &self,
        frame: &TrackFrame<'_>,
        pose: &GenPose,
        score: f64,
        refs: &[ReferenceView<'_>],
        barred: &[UnitQuaternion],
    ) -> Option<(GenPose, f64, String)> {
        let in_barred = |g: &GenPose| {
            barred
                .iter()
                .any(|r| g.pose.rotation.angle_to(r) < 0.5 * REJECTED_BASIN_DEG.to_radians())
        };
        let app = frame.appearance()?;
        if refs.is_empty() && !model_has_appearance(self.model) {
            return None;
        }
        let (centre, axes) = principal_axes(self.model, &pose.states)?;
        let problem = FrameProblem::new(
            self.model,
            frame.camera,
            frame.target,
            self.scale,
            pose.clone(),
        );
        let turn = |from: &GenPose, axis: &Vector3, deg: f64| {
            SymmetryAxis {
                centre,
                axis: *axis,
            }
            .turn(from, self.scale, deg)
        };
        let cfg = self.appearance_cfg();
        let ncc = |g: &GenPose| appearance_score(self.model, self.scale, &app, g, refs, &cfg).ncc;
        // A turn as it best explains the mask: as turned, or else moved back onto the mask
        // ([`realign`]: the axes pass through the centroid, which a handle pulls off the
        // axis of the body's outline).
        let stats = mask_stats(frame.target);
        let pivot = posed_extent(self.model, &pose.states).0;
        let aligned =
            |ev: &mut crate::objective::Evaluator<'_, '_>, g: GenPose| -> (GenPose, f64) {
                let raw = ev.combined(&g);
                self.evals
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                match stats {
                    Some(stats) if raw < score - APPEARANCE_TIE => {
                        let (moved, sc) = realign(self.model, frame, self.scale, &g, stats, pivot);
                        self.evals
                            .fetch_add(3, std::sync::atomic::Ordering::Relaxed);
                        if sc > raw {
                            (moved, sc)
                        } else {
                            (g, raw)
                        }
                    }
                    _ => (g, raw),
                }
            };
        let steps = (360.0 / TURN_STEP_DEG).round() as usize;
        let turns: Vec<(usize, f64)> = (0..3)
            .flat_map(|k| (1..steps).map(move |m| (k, m as f64 * TURN_STEP_DEG)))
            .collect();
        // Each turn placed independently (an evaluator per thread).
        let turned: Vec<(GenPose, f64)> = turns
            .par_iter()
            .map_init(
                || problem.evaluator(),
                |ev, &(k, deg)| aligned(ev, turn(pose, &axes[k], deg)),
            )
            .collect();
        let mut placed: Vec<(usize, f64, GenPose, f64)> = Vec::new();
        let mut near: Vec<(usize, f64, GenPose, f64)> = Vec::new();
        for (&(k, deg), (g, sc)) in turns.iter().zip(turned) {
            if sc >= score - APPEARANCE_TIE {
                placed.push((k, deg, g, sc));
            } else if sc >= score - SETTLE_NEAR {
                near.push((k, deg, g, sc));
            }
        }
        // The near turns best on the masks, NEAR_PER_AXIS per axis: each is scored in colour
        // (a full render), and a box's twins can put most turns near.
        near.sort_by(|a, b| b.3.total_cmp(&a.3));
        let mut per_axis = [0usize; 3];
        near.retain(|c| {
            per_axis[c.0] += 1;
            per_axis[c.0] <= NEAR_PER_AXIS
        });
        if placed.is_empty() && near.is_empty() {
            return None;
        }
        let own = ncc(pose)?;
        let best_by_ncc = |cands: &[(usize, f64, GenPose, f64)]| -> Option<(usize, f64)> {
            let scored: Vec<Option<f64>> = cands
                .par_iter()
                .map(|(_, _, g, _)| if in_barred(g) { None } else { ncc(g) })
                .collect();
            scored
                .iter()
                .enumerate()
                .filter_map(|(i, n)| n.map(|n| (i, n)))
                .max_by(|a, b| a.1.total_cmp(&b.1))
        };
        let mut best = best_by_ncc(&placed).map(|(i, n)| (placed[i].clone(), n));
        // A turn near the outline (a handle under a hand, a few degrees of tilt between the
        // principal axis and the body's) whose colours beat every placed turn's: refined on
        // the masks, it is a twin if it then explains them as well and its colours still win
        // by the margin. Refined by the polish, or else in a narrow window: about the hidden
        // axis the masks are flat, and the polish's 12° can drift back along it.
        let beaten = best.as_ref().map_or(own, |b| b.1.max(own));
        if let Some((i, near_ncc)) = best_by_ncc(&near) {
            if near_ncc > beaten {
                let (k, deg, g, _) = &near[i];
                let seed = self.cfg.seed + 8_191 * (*k as u64 + 1) + deg.round() as u64;
                let narrow = LocalWindow {
                    angle_deg: NEAR_REFINE_DEG,
                    ..LocalWindow::on_model()
                };
                // The polish first; the narrow window only where the polish drifted back.
                let refined = [self.polish_window(), narrow].iter().find_map(|window| {
                    let (r, rsc) = self.refine(frame, g, window, seed).ok()?;
                    let rn = ncc(&r)?;
                    (rsc >= score - APPEARANCE_TIE && rn > beaten + cfg.margin && !in_barred(&r))
                        .then_some((r, rsc, rn))
                });
                if let Some((r, rsc, rn)) = refined {
                    best = Some(((*k, *deg, r, rsc), rn));
                }
            }
        }
        // A turn clearly better in colour than the pose, or else (about an axis of
        // continuous symmetry, where every turn keeps the outline: a can, a bottle) the pose
        // itself, whose angle about that axis only the colours fix: it is turned finely
        // too, by at least CONTINUOUS_GAIN of NCC a step, so that the small error of each
        // frame does not add up along the sequence.
        let continuous = best.as_ref().is_none_or(|b| b.1 - own <= cfg.margin);
        let (axis, mut deg, mut g, mut sc, mut n_best) = if continuous {
            let axis = (0..3).find(|&k| placed.iter().filter(|p| p.0 == k).count() + 1 == steps)?;
            (axis, 0.0, pose.clone(), score, own)
        } else {
            let ((axis, deg, g, sc), n) = best?;
            (axis, deg, g, sc, n)
        };
        let gain = if continuous { CONTINUOUS_GAIN } else { 0.0 };
        let mut ev = problem.evaluator();
        for step in [10.0, 5.0, 2.5] {
            let from = g.clone();
            for dir in [-1.0, 1.0] {
                let (cand, csc) = aligned(&mut ev, turn(&from, &axes[axis], dir * step));
                if csc < score - APPEARANCE_TIE {
                    continue;
                }
                if let Some(cn) = ncc(&cand).filter(|&cn| cn > n_best + gain) {
                    (g, sc, n_best) = (cand, csc, cn);
                    deg += dir * step;
                }
            }
        }
        if (continuous && deg == 0.0) || in_barred(&g) {
            return None;
        }
        let deg = signed_deg(deg);
        let note = format!(
            "appearance: turned {deg:+.0}° about the model's {} (principal axis {axis}; NCC {own:.2} → {n_best:.2}, IoU {score:.4} → {sc:.4})",
            crate::temporal::axis_label(&[axes[axis].x, axes[axis].y, axes[axis].z])
        );
        Some((g, sc, note))
    }

    pub(super) fn joint_grid(&self) -> Vec<Vec<f64>> {
        let tree = &self.model.tree;
        let mut combos: Vec<Vec<f64>> = vec![tree.rest_states()];
        for (j, jd) in tree.joints().iter().enumerate() {
            if !jd.kind.has_state() {
                continue;
            }
            let (lo, hi) = joint_default(tree, j);
            let n = self.cfg.joint_samples.max(1);
            let values: Vec<f64> = (0..n)
                .map(|k| {
                    jd.to_internal(if n == 1 {
                        0.5 * (lo + hi)
                    } else {
                        lo + (hi - lo) * (k as f64 + 0.5) / n as f64
                    })
                })
                .collect();
            combos = combos
                .iter()
                .flat_map(|c| {
                    values.iter().map(move |&v| {
                        let mut c = c.clone();
                        c[j] = v;
                        c
                    })
                })
                .collect();
            if combos.len() > 64 {
                break;
            }
        }
        combos
    }

    /// Hypotheses placed on the mask, best first.
    pub(super) fn covering(
        &self,
        frame: &TrackFrame<'_>,
        rotations: &[UnitQuaternion],
        joint_sets: &[Vec<f64>],
    ) -> Vec<(GenPose, f64)> {
        let Some(stats) = mask_stats(frame.target) else {
            return vec![];
        };
        let extents: Vec<(Point3, f64)> = joint_sets
            .par_iter()
            .map(|s| posed_extent(self.model, s))
            .collect();
        let hyps: Vec<(UnitQuaternion, &Vec<f64>, (Point3, f64))> = rotations
            .iter()
            .flat_map(|r| {
                joint_sets
                    .iter()
                    .zip(&extents)
                    .map(move |(s, e)| (*r, s, *e))
            })
            .collect();
        self.evals
            .fetch_add(hyps.len() * 3, std::sync::atomic::Ordering::Relaxed);
        let mut placed: Vec<(GenPose, f64)> = hyps
            .par_iter()
            .map(|(r, s, e)| place(self.model, frame, self.scale, *r, s, stats, Some(*e)))
            .collect();
        placed.sort_by(|a, b| b.1.total_cmp(&a.1));
        placed
    }
}

/// What a global search of one frame ([`Searcher::rescue`]) found: the pose that replaces
/// the current one and why, if any, and every distinct basin within [`CHOICE_KEEP`] of the
/// best score, for the sequence-level choice.
pub(super) struct Rescue {
    pub(super) chosen: Option<(Scored, String)>,
    pub(super) basins: Vec<(GenPose, f64)>,
}

/// A frame whose band IoU ([`Searcher::band_iou`]) falls under this after the searches
/// from its neighbours is searched globally: true poses on segmenter-noisy masks score
/// 0.9956–1.0 there and wrong basins 0.93–0.997 (hard suite, 2026-12-02: drawerbox and
/// twinlaptop, every frame's truth against the tracked pose). At 0.995, 2 of drawerbox's 9
/// wrong frames escaped the search; at 0.998 none did. Its cost: 2–6 s a sequence on that
/// suite, 33 s on the three-part shears, whose truth scores 0.97–1.0 (thin parts).
pub(super) const RESCUE_BAND: f64 = 0.998;
/// ... or this far under the median band IoU of the frames tracked so far, if that is lower:
/// on thin parts a segmenter's 2 px noise covers much of the object, and the right poses of
/// the whole sequence score under [`RESCUE_BAND`] (the shears: 0.969–0.9997, median 0.995),
/// where the global search at every frame cost 1.4 M of its 4.1 M evaluations and changed
/// nothing.
pub(super) const RESCUE_BELOW_TYPICAL: f64 = 0.0015;

/// The band IoU under which a frame is searched globally: [`RESCUE_BAND`], or
/// [`RESCUE_BELOW_TYPICAL`] under the median of `bands` (the frames tracked so far) when
/// that is lower.
pub(super) fn rescue_band(bands: &[f64]) -> f64 {
    let mut sorted = bands.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.get(sorted.len() / 2) {
        Some(median) => RESCUE_BAND.min(median - RESCUE_BELOW_TYPICAL),
        None => RESCUE_BAND,
    }
}
/// How much better (visible IoU) the global search's pose must score to replace the one
/// found from the neighbours (within it, continuity wins: twins score alike).
pub(super) const RESCUE_MARGIN: f64 = 0.002;
/// Poses this far apart in rotation are different basins for the global search's choice.
pub(super) const DISTINCT_DEG: f64 = 20.0;

/// The NCC a fine turn about an axis of continuous symmetry must gain to be taken (the
/// colours' noise between two near turns is about half of it).
pub(super) const CONTINUOUS_GAIN: f64 = 0.01;
/// The turns about the principal axes that [`Searcher::settle`] compares.
pub(super) const TURN_STEP_DEG: f64 = 30.0;
/// A turn that explains the mask within this of the pose's IoU (after [`realign`]) but not
/// within [`APPEARANCE_TIE`] is refined by [`Searcher::settle`] when its colours win.
pub(super) const SETTLE_NEAR: f64 = 0.05;
/// The near turns per principal axis that [`Searcher::settle`] scores in colour, best on the
/// masks first.
pub(super) const NEAR_PER_AXIS: usize = 2;
/// A narrow rotation window in which such a near turn is refined (besides the polish's):
/// enough for the tilt a turn about a principal axis a few degrees off the body's gives it,
/// not enough to turn it back (about the hidden axis the masks are flat, and the polish's
/// 12° window drifts with them).
pub(super) const NEAR_REFINE_DEG: f64 = 4.0;
