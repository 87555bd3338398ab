//! Hypotheses refined before they are compared. A flip or a covering rotation placed on the
//! mask scores what its unrefined pose scores (the right flip of a slightly wrong pose may
//! score 0.7 against a wrong pose's 0.93); only after a local search around each does the
//! comparison say which basin is right. Shared by the tracker and the object verbs
//! (`oapply`, `osweep`).

use crate::objective::{CandidateScore, FrameProblem};
use crate::search::{rank, sweep, Candidate, SweepConfig, SweepResult};
use crate::space::{joint_default, pose_ranges, Dof, DofRange, SearchSpace};
use crate::symmetry::fold_turns;
use crate::update::{apply_object_rotation, flip, GenPose};
use crate::TrackError;
use agentstar_geom::nalgebra::{Matrix3, Quaternion, Unit};
use agentstar_geom::{ObjectModel, Point3, UnitQuaternion, Vector3};
use agentstar_optim::{cma_es, CmaConfig, Rng};
use rayon::prelude::*;

/// The box of a local refinement around a pose: camera-frame rotation and image-plane
/// shift (fractions of the depth), depth (fraction), joints (degrees, or that share of a
/// prismatic joint's range per 180°), and the evaluations of its first pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalWindow {
    pub angle_deg: f64,
    pub shift: f64,
    pub depth: f64,
    pub joint_deg: f64,
    pub evals: usize,
}

impl LocalWindow {
    /// Around a pose that is already close: 12°, 4% shift, 8% depth, 20° of joint, 1,200
    /// evaluations in the first pass (about 2,500 in all, and 100 of Nelder–Mead a dimension):
    /// the tracker's polish.
    pub fn polish() -> Self {
        LocalWindow {
            angle_deg: 12.0,
            shift: 0.04,
            depth: 0.08,
            joint_deg: 20.0,
            evals: 1200,
        }
    }

    /// Around a pose found on a simplified stand-in of the model ([`crate::standin`]), within
    /// a fraction of a pixel of the model's optimum: 3°, 1% shift, 2% depth, 5° of joint,
    /// 120 evaluations in the first pass (about 500 in all).
    pub fn on_model() -> Self {
        LocalWindow {
            angle_deg: 3.0,
            shift: 0.01,
            depth: 0.02,
            joint_deg: 5.0,
            evals: 120,
        }
    }

    /// Around a candidate that may be a whole basin away from where it was placed (a flip,
    /// a covering rotation): 25°, 6% shift, 15% depth, 60° of joint.
    pub fn basin() -> Self {
        LocalWindow {
            angle_deg: 25.0,
            shift: 0.06,
            depth: 0.15,
            joint_deg: 60.0,
            evals: 2400,
        }
    }

    /// Around a neighbouring keyframe's pose carried into a frame: the rotation a whole
    /// basin wide (25°), the position close (6% shift, 5% depth: a hand moves an object a few
    /// centimetres between keyframes; a silhouette mostly under a hand would otherwise pull
    /// it a third of the depth away (a plain bottle: 18 cm at 57 cm)), 60° of joint.
    pub fn carried() -> Self {
        LocalWindow {
            depth: 0.05,
            ..LocalWindow::basin()
        }
    }
}

/// The local search box around a pose: camera-frame increments and joints around their state.
pub(crate) fn local_space(
    model: &ObjectModel,
    base: &GenPose,
    angle: f64,
    shift: f64,
    depth: f64,
    joint_deg: f64,
) -> SearchSpace {
    let mut ranges = pose_ranges(angle, shift, depth);
    for (j, jd) in model.tree.joints().iter().enumerate() {
        if !jd.kind.has_state() {
            continue;
        }
        let (dlo, dhi) = joint_default(&model.tree, j);
        let cur = jd.to_interface(base.states[j]);
        let span = if jd.kind.is_angular() {
            joint_deg
        } else {
            joint_deg / 180.0 * (dhi - dlo).abs().max(1e-6)
        };
        let (lo, hi) = ((cur - span).max(dlo), (cur + span).min(dhi));
        ranges.push(DofRange {
            dof: Dof::Joint(j),
            lo: lo.min(hi),
            hi: hi.max(lo),
            steps: None,
        });
    }
    SearchSpace {
        ranges,
        notes: vec![],
    }
}

/// A refined hypothesis.
#[derive(Debug, Clone, PartialEq)]
pub struct Refined {
    pub pose: GenPose,
    pub score: CandidateScore,
    /// What the hypothesis scored where it was placed, before the refinement.
    pub unrefined: CandidateScore,
    pub evals: usize,
}

/// Differential evolution around `base` in the window, then passes in shrinking boxes
/// re-centred on the best so far (each re-based, so its pivot follows), the last with a
/// Nelder–Mead polish. `problem` supplies the model, camera, target, depth and scale; its
/// base is ignored. Never worse than `base`: every pass starts from the best so far.
pub fn refine_local(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    window: &LocalWindow,
    seed: u64,
) -> Result<(GenPose, f64, usize), TrackError> {
    refine_local_with(problem, base, window, seed, LastPass::NelderMead)
}

/// How the narrow end of a local refinement searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LastPass {
    /// Differential evolution in boxes a tenth and a twenty-fifth of the window, the last
    /// ending in a Nelder–Mead polish of [`POLISH_PER_DOF`] evaluations a dimension: what the
    /// tracker and the tools run.
    #[default]
    NelderMead,
    /// CMA-ES at full resolution in a box [`CMA_SHARE`] of the window, on the sub-pixel score
    /// ([`crate::objective::Evaluator::soft_combined`]) and then settled on the score itself
    /// ([`cma_pass`]). Not yet what the tracker runs: see [`CMA_PER_DOF`] for what it gains
    /// and what it cost the hard suite.
    CmaSoft,
}

/// [`refine_local`] with its narrow end searched as `last` says.
pub fn refine_local_with(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    window: &LocalWindow,
    seed: u64,
    last: LastPass,
) -> Result<(GenPose, f64, usize), TrackError> {
    refine_passes_from(problem, base, base, window, seed, (0..LOCAL_PASSES, last))
}

/// The passes `range` of [`refine_local`] from `from`, its narrow end searched as `last`
/// says, never worse than `base` (with the evaluation that scores `base` counted).
fn refine_passes_from(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    from: &GenPose,
    window: &LocalWindow,
    seed: u64,
    (range, last): (std::ops::Range<usize>, LastPass),
) -> Result<(GenPose, f64, usize), TrackError> {
    let (start_score, n_start) = start_score(problem, base);
    let (pose, score, n) = refine_local_passes(
        problem,
        from,
        window,
        seed,
        range,
        Some((base, start_score)),
        last,
    )?;
    Ok((pose, score, n + n_start))
}

/// The passes of [`refine_local`].
const LOCAL_PASSES: usize = 4;

/// The full-resolution score of `base` when the problem has a coarse level (whose passes
/// may leave its basin for a worse one), with the evaluations spent; else nothing to keep.
fn start_score(problem: &FrameProblem<'_>, base: &GenPose) -> (f64, usize) {
    match problem.coarsened() {
        Some(_) => (problem.evaluator().combined(base), 1),
        None => (f64::NEG_INFINITY, 0),
    }
}

/// The passes `range` of [`refine_local`] (the same windows, budgets and seeds) from `base`;
/// the score returned is at full resolution, and `origin` (a pose and its score) is
/// returned instead when it scores better.
/// With [`LastPass::CmaSoft`], one CMA-ES pass ([`cma_pass`]) instead of the passes after
/// the half-resolution ones.
fn refine_local_passes(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    window: &LocalWindow,
    seed: u64,
    range: std::ops::Range<usize>,
    origin: Option<(&GenPose, f64)>,
    last: LastPass,
) -> Result<(GenPose, f64, usize), TrackError> {
    let evals = window.evals;
    // (the window's share, the DE budget, whether the pass ends with a Nelder–Mead polish)
    let passes: [(f64, usize, bool); LOCAL_PASSES] = [
        (1.0, evals, false),
        (0.3, evals / 2, false),
        (0.1, evals / 3, false),
        (0.04, evals / 4, true),
    ];
    let mut best = base.clone();
    let mut best_score = f64::NEG_INFINITY;
    let mut n_evals = 0;
    // The wide passes at half the resolution when the problem has it (a quarter of the
    // pixels to fill and count); the narrow ones, and the score returned, at full resolution.
    let coarse = problem.coarsened();
    let mut last_coarse = false;
    for (k, &(f, n, polish)) in passes.iter().enumerate() {
        if !range.contains(&k) || (last == LastPass::CmaSoft && f < COARSE_PASS) {
            continue;
        }
        last_coarse = coarse.is_some() && f >= COARSE_PASS;
        let level = match &coarse {
            Some(c) if f >= COARSE_PASS => c,
            _ => problem,
        };
        if coarse.is_some() && f < COARSE_PASS && k > range.start && passes[k - 1].0 >= COARSE_PASS
        {
            // Scores of the two resolutions do not compare: the first fine pass starts from
            // the coarse passes' best and keeps its own.
            best_score = f64::NEG_INFINITY;
        }
        let (p, space) = rebased(level, &best, window, f);
        let cfg = SweepConfig {
            restarts: 2,
            total_evals: n.max(40),
            seed: seed + 1000 * k as u64,
            polish_evals: if polish {
                POLISH_PER_DOF * space.ranges.len()
            } else {
                0
            },
            ..SweepConfig::default()
        }
        .scipy_stop();
        let r = sweep(&p, &space, &cfg)?;
        n_evals += r.n_evals;
        let top = r
            .ranked
            .into_iter()
            .next()
            .ok_or_else(|| TrackError::Invalid("empty search".into()))?;
        if top.score.combined >= best_score {
            best_score = top.score.combined;
            best = top.pose;
        }
    }
    if last == LastPass::CmaSoft && range.end == LOCAL_PASSES {
        let (p, space) = rebased(problem, &best, window, CMA_SHARE);
        let (pose, score, n) = cma_pass(&p, &space, seed + 1000 * LOCAL_PASSES as u64)?;
        n_evals += n;
        // The passes before were at half the resolution, or the same pass's start scores
        // no better on the score: the CMA-ES result is never worse than where it started.
        best = pose;
        best_score = score;
        last_coarse = false;
    }
    if last_coarse {
        // Stopped after a coarse pass: its score is at the other resolution.
        best_score = problem.evaluator().combined(&best);
        n_evals += 1;
    }
    match origin {
        // The coarse passes left the start's basin for a worse one at full resolution.
        Some((origin, origin_score)) if origin_score > best_score => {
            Ok((origin.clone(), origin_score, n_evals))
        }
        _ => Ok((best, best_score, n_evals)),
    }
}

/// `level` re-based on `best` (its pivot following) and the box of one pass around it:
/// `share` of the window, never under 0.5°, 0.2% shift, 0.4% depth and 1° of joint.
pub(crate) fn rebased<'a>(
    level: &FrameProblem<'a>,
    best: &GenPose,
    window: &LocalWindow,
    share: f64,
) -> (FrameProblem<'a>, SearchSpace) {
    let mut p = level.clone();
    p.pivot = p.model.pivot(&best.states);
    p.base = best.clone();
    let space = local_space(
        p.model,
        best,
        (window.angle_deg * share).max(0.5),
        (window.shift * share).max(0.002),
        (window.depth * share).max(0.004),
        (window.joint_deg * share).max(1.0),
    );
    (p, space)
}

/// CMA-ES over `space` from `problem`'s base (the search's start vector), first on the
/// sub-pixel score ([`crate::objective::Evaluator::soft_combined`]), which climbs a ridge
/// smoothly, then briefly on the score itself from there, with a step a fifth as long
/// ([`CMA_SETTLE_STEP`], [`CMA_SETTLE_PER_DOF`]): the sub-pixel score fits the mask's pixel
/// staircase, whose best may sit a degree or two from the pixel-exact best along a flat
/// ridge. The best pose of the second run (never worse than where it started on the score),
/// its combined score and the evaluations spent.
fn cma_pass(
    problem: &FrameProblem<'_>,
    space: &SearchSpace,
    seed: u64,
) -> Result<(GenPose, f64, usize), TrackError> {
    let mut evaluator = problem.evaluator();
    cma_pass_by(
        problem,
        space,
        seed,
        CmaBudget {
            step: CMA_STEP,
            per_dof: CMA_PER_DOF,
        },
        &mut |g, soft| {
            if soft {
                evaluator.soft_combined(g)
            } else {
                evaluator.combined(g)
            }
        },
    )
}

/// The first step (a share of the box) and the evaluations per searched dimension of a
/// [`cma_pass_by`]'s climb on the sub-pixel score; its settling run takes
/// [`CMA_SETTLE_PER_DOF`] a dimension and a step a fifth as long.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CmaBudget {
    pub step: f64,
    pub per_dof: usize,
}

/// [`cma_pass`] on a score of the caller's (`score(pose, soft)`: the sub-pixel score when
/// `soft`, the score itself otherwise; higher is better), over `problem`'s candidates (its
/// held axis held): what a refinement on more than the frame's own mask searches by (the
/// video refinement: the keyframe and the in-between frames beside it). The best pose of
/// the settling run, its score and the evaluations spent.
pub(crate) fn cma_pass_by(
    problem: &FrameProblem<'_>,
    space: &SearchSpace,
    seed: u64,
    budget: CmaBudget,
    score: &mut dyn FnMut(&GenPose, bool) -> f64,
) -> Result<(GenPose, f64, usize), TrackError> {
    let bounds: Vec<(f64, f64)> = space.ranges.iter().map(|r| (r.lo, r.hi)).collect();
    let start = problem.start_vector(space);
    let dims = space.ranges.len();
    // The candidate with the turn about a held axis set back to the base's: the silhouette
    // cannot measure it, and CMA-ES wanders along a flat direction.
    let at = |x: &[f64]| {
        let c = problem.candidate(space, x);
        match &problem.held_axis {
            Some(axis) => axis.without_twist(&problem.base, &c, problem.scale),
            None => c,
        }
    };
    let climb = cma_es(
        &mut |x| -score(&at(x), true),
        &bounds,
        &start,
        &CmaConfig {
            max_evals: budget.per_dof * dims,
            initial_step: budget.step,
            xtol: 1e-4,
            ftol: 1e-9,
            seed,
        },
    )
    .map_err(|e| TrackError::Invalid(format!("local refinement: {e}")))?;
    let settle = cma_es(
        &mut |x| -score(&at(x), false),
        &bounds,
        &climb.x,
        &CmaConfig {
            max_evals: CMA_SETTLE_PER_DOF * dims,
            initial_step: CMA_SETTLE_STEP,
            xtol: 1e-4,
            ftol: 1e-9,
            seed: seed + 1,
        },
    )
    .map_err(|e| TrackError::Invalid(format!("local refinement: {e}")))?;
    let pose = at(&settle.x);
    let s = score(&pose, false);
    Ok((pose, s, climb.nfev + settle.nfev + 1))
}

/// The last polish of a pose already refined: CMA-ES in a box [`CMA_SHARE`] of `window`
/// around `base`, on the sub-pixel score and then settled on the score ([`cma_pass`]), at
/// full resolution, with `problem`'s held axis held. `base` itself (and its score) where the
/// polish does not score strictly higher, so it never loses; with the evaluations spent
/// (scoring `base` included).
///
/// This is [`LastPass::CmaSoft`] run once more after a refinement's own passes instead of
/// in place of them: the box (3.6° and 6° of joint in the polish window) reaches no other
/// basin, so it cannot undo a choice made before it.
pub fn polish_last(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    window: &LocalWindow,
    seed: u64,
) -> Result<(GenPose, f64, usize), TrackError> {
    let base_score = problem.evaluator().combined(base);
    let (p, space) = rebased(problem, base, window, CMA_SHARE);
    let (pose, score, n) = cma_pass(&p, &space, seed)?;
    if score > base_score {
        Ok((pose, score, n + 1))
    } else {
        Ok((base.clone(), base_score, n + 1))
    }
}

/// Like [`refine_each`] (which is this with no floor, `f64::NEG_INFINITY`), but a
/// hypothesis whose score after the first (widest) pass is under `floor` stops there: its
/// pose and score are that pass's. For callers that drop every
/// hypothesis under a bound anyway (a floor that bound minus [`PRUNE_SLACK`]): the
/// narrower passes would only polish a hypothesis that cannot be chosen.
pub fn refine_each_above(
    problem: &FrameProblem<'_>,
    hypotheses: &[GenPose],
    window: &LocalWindow,
    seed: u64,
    floor: f64,
) -> Result<Vec<Refined>, TrackError> {
    hypotheses
        .par_iter()
        .enumerate()
        .map(|(k, h)| {
            let unrefined = problem.evaluator().score(h);
            let seed = seed + k as u64;
            let (pose, evals) = if floor == f64::NEG_INFINITY {
                let (pose, _, evals) = refine_local(problem, h, window, seed)?;
                (pose, evals)
            } else {
                refine_above(problem, h, window, seed, floor)?
            };
            let score = problem.evaluator().score(&pose);
            Ok(Refined {
                pose,
                score,
                unrefined,
                evals,
            })
        })
        .collect()
}

/// The first (widest) pass of [`refine_local`]: its best pose (which may score under
/// `base`), that pose's full-resolution score and the evaluations spent. [`refine_rest`]
/// from it finishes the refinement exactly as [`refine_local`] would have.
pub fn refine_first_pass(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    window: &LocalWindow,
    seed: u64,
) -> Result<(GenPose, f64, usize), TrackError> {
    refine_local_passes(
        problem,
        base,
        window,
        seed,
        0..1,
        None,
        LastPass::NelderMead,
    )
}

/// The passes of [`refine_local`] after [`refine_first_pass`] (same window and seed) from
/// its pose `first`; `base` (the pose the first pass started from) is returned instead
/// where it scores better.
pub fn refine_rest(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    first: &GenPose,
    window: &LocalWindow,
    seed: u64,
) -> Result<(GenPose, f64, usize), TrackError> {
    refine_passes_from(
        problem,
        base,
        first,
        window,
        seed,
        (1..LOCAL_PASSES, LastPass::NelderMead),
    )
}

/// [`refine_local`] that stops after its first pass when the score there (or `base`'s)
/// is under `floor`, with the better of the two; the pose and the evaluations spent.
/// Above the floor the result is [`refine_local`]'s.
pub fn refine_above(
    problem: &FrameProblem<'_>,
    base: &GenPose,
    window: &LocalWindow,
    seed: u64,
    floor: f64,
) -> Result<(GenPose, usize), TrackError> {
    let (first, first_score, n_first) = refine_first_pass(problem, base, window, seed)?;
    if first_score < floor {
        let (start_score, n_start) = start_score(problem, base);
        if start_score < floor {
            let pose = if start_score > first_score {
                base.clone()
            } else {
                first
            };
            return Ok((pose, n_first + n_start));
        }
    }
    let (pose, _, n_rest) = refine_rest(problem, base, &first, window, seed)?;
    Ok((pose, n_first + n_rest))
}

/// How much the narrower passes of a local refinement may still add to the score of its
/// first pass, for [`refine_each_above`]'s floors. Not a bound. Measured over the hard suite
/// (seed 17, 2026-12-03, every pruned refinement also finished to see where it would end):
/// of 1,044 refinements above their floors the rest added 0.0055 median, 0.055 at the 99th
/// percentile, 0.084 at most; of 961 pruned ones 0.024 median, 0.19 at the 99th percentile,
/// 0.34 at most, and 19 (2%) would have ended within the keep line (first passes of
/// 0.58–0.77 that a wide window left far from the basin's optimum, ending 0.83–0.90).
/// Whether any of those 19 would have changed a chosen pose is not measured.
pub const PRUNE_SLACK: f64 = 0.05;

/// The passes of [`refine_local`] whose window is at least this share of the whole run at
/// half the resolution when the problem has it ([`FrameProblem::with_coarse`]).
const COARSE_PASS: f64 = 0.3;

/// The Nelder–Mead evaluations per searched dimension that polish a local refinement's last
/// pass (over its two restarts), so that the budget grows with the 6 to 8 dimensions of a
/// pose with joints. A fixed 300 stopped it short: the 20-keyframe benchmark's keyframe 17
/// ended 7.6° and 8° of joint off with 300, and 2.0° and 2.3° with 700 or 1,000 in its 7
/// dimensions. Those two budgets gave the same poses, so the simplex stopped on its own
/// tolerance there (inferred from that, not logged).
const POLISH_PER_DOF: usize = 100;

/// [`LastPass::CmaSoft`] searches this share of the window: 3.6° about each axis of the
/// tracker's polish window (12°), wide enough to follow a valley a few degrees long from
/// where the differential evolution passes stop.
const CMA_SHARE: f64 = 0.3;

/// The first step of [`LastPass::CmaSoft`]'s CMA-ES, as a share of its box: about 0.7° in
/// the polish window.
const CMA_STEP: f64 = 0.1;

/// [`LastPass::CmaSoft`]'s CMA-ES evaluations per searched dimension on the sub-pixel
/// score (about 1,000 for a pose with a joint; it stops sooner where its steps shrink below
/// 10⁻⁴ of the box or its best stalls).
///
/// Why CMA-ES on a sub-pixel score (2026-12-06, `cargo bench -p agentstar-track --bench
/// search -- refine`: 60 polishes from 2.5° and 3° of joint off exact-mask truths). The
/// silhouette score's ridge couples an out-of-plane turn with a sideways shift and the
/// joint: every move along one search axis lowers the score while the straight line to the
/// truth raises it steadily (one start: 0.9693 → 1.0000). The passes the tracker runs
/// ([`LastPass::NelderMead`]) stall 1–6° away: 25 of 60 over 1°, median 0.65°. CMA-ES
/// learns the ridge's direction from the steps that paid: 7 of 60 over 1° on the score
/// itself, median 0.04°, but near the truth the score is a staircase of single pixels and
/// its steps collapse on a stair 2–3° out (keyframe 2 of the 10-keyframe tracking test, IoU
/// 0.9990). On the
/// sub-pixel score, then settled on the score: 3 of 60 over 1°, median 0.07°, 90% 0.68°, in
/// 20% more evaluations.
///
/// Why the tracker does not run it yet (every refinement of the tracker on it, 9 in-between
/// frames, tracker seed 17): the general suite 58 → **62 of 72** (no sequence lost) and the
/// 20-keyframe benchmark's worst frame 2.20° / 3.14° → 1.09° / 1.55°, but the hard suite
/// went from 21 to 15 of 21 (seeds 17, 18, 19): the labelled can on every seed (41.7°,
/// 34.3°, 3.0° mean), the drawer box on seeds 18 and 19 (14.2°), the plain bottle on 18
/// (1.15 cm). Turns about the can's axis, which leave the
/// outline alike, drift under a search that follows every small gain; a penalty of 10⁻⁵ a
/// squared degree of turn brought seed 17 back (2.6°) and not seed 18 (21.5°). Holding the
/// turn about the outline's axis at the base's ([`FrameProblem::held_axis`], which the
/// tracker's problems carry for a round outline; 2026-12-06) brought the hard suite to 17 of
/// 21: the labelled can on seeds 17 and 19 (0.19 and 0.20 cm) but not 18 (a block of
/// keyframes turned end over end, 2.70 cm), the plain bottle on 17 (1.02 cm), the printed
/// mug (3.7°) and the drawer box (14.2°) on 19; and every labelled-can run 30–45% faster (16 s against
/// 23–31 s).
const CMA_PER_DOF: usize = 140;

/// The settling run of the last pass ([`cma_pass`]): its evaluations per searched dimension
/// and its first step as a share of the box (about 0.15° in the polish window).
const CMA_SETTLE_PER_DOF: usize = 40;
const CMA_SETTLE_STEP: f64 = 0.02;

/// Every hypothesis refined in `window` (in parallel, seeds `seed + k`), in input order.
/// Rank them by `score`, not `unrefined`.
pub fn refine_each(
    problem: &FrameProblem<'_>,
    hypotheses: &[GenPose],
    window: &LocalWindow,
    seed: u64,
) -> Result<Vec<Refined>, TrackError> {
    refine_each_above(problem, hypotheses, window, seed, f64::NEG_INFINITY)
}

/// Refined candidates this close to a better-ranked one are the same pose reached from two
/// starts ([`refine_ranked`] lists it once): 1° of rotation, 0.5% of the depth, 0.02 of
/// every joint state (about 1°, or 0.02 model units).
const CONVERGED_DEG: f64 = 1.0;
const CONVERGED_DEPTH: f64 = 0.005;
const CONVERGED_STATE: f64 = 0.02;

/// Whether two refined poses are one ([`CONVERGED_DEG`] and the rest).
fn converged(a: &GenPose, b: &GenPose) -> bool {
    let depth = a
        .pose
        .translation
        .z
        .abs()
        .max(b.pose.translation.z.abs())
        .max(1e-9);
    a.pose.rotation.angle_to(&b.pose.rotation).to_degrees() < CONVERGED_DEG
        && (a.pose.translation - b.pose.translation).norm() < CONVERGED_DEPTH * depth
        && a.states.len() == b.states.len()
        && a.states
            .iter()
            .zip(&b.states)
            .all(|(x, y)| (x - y).abs() < CONVERGED_STATE)
}

/// A sweep's ranked candidates each refined in `window` and ranked again by their refined
/// scores (the start, when kept, stays as it is): what `oapply` and `osweep` rank by default.
/// Candidates whose refinements end at one pose ([`converged`]) are listed once, the best
/// of them kept with its own start (play-test, 2026-12-05: `osweep` listed one pose twice,
/// from `rz:-30` and from `rz:-15`); the result's list is that much shorter.
pub fn refine_ranked(
    problem: &FrameProblem<'_>,
    mut result: SweepResult,
    window: &LocalWindow,
    seed: u64,
) -> Result<SweepResult, TrackError> {
    let poses: Vec<GenPose> = result.ranked.iter().map(|c| c.pose.clone()).collect();
    let refined = refine_each(problem, &poses, window, seed)?;
    let n = result.ranked.len();
    for (c, r) in result.ranked.iter_mut().zip(refined) {
        if c.kept_start {
            continue;
        }
        result.n_evals += r.evals;
        c.unrefined = Some(c.score);
        c.pose = r.pose;
        c.score = r.score;
    }
    let ranked = rank(result.ranked, n);
    let mut kept: Vec<Candidate> = Vec::with_capacity(ranked.len());
    for c in ranked {
        if !kept.iter().any(|k| converged(&k.pose, &c.pose)) {
            kept.push(c);
        }
    }
    result.ranked = rank(kept, n);
    Ok(result)
}

/// The posed model's principal axes (exact second moments, in the canonical frame at these
/// joint states), largest spread first, and a centre for turns about them: the middle of the
/// model's extent along each axis, which lies on every axis of the outline's symmetry. A half-turn about a principal axis is
/// the twin of any shape symmetric about it, whatever the joint state makes of it: two slabs
/// of one outline hinged together (lid ↔ base) are swapped by the half-turn about the axis
/// that bisects them, which is principal.
///
/// The moments are those of the solid (signed tetrahedra from the origin) when every part is
/// closed ([`TriMesh::is_watertight`](agentstar_geom::TriMesh::is_watertight)) with a
/// positive volume, so a thin part (a label sleeve on a can, a badge on a mug) barely moves
/// the axes that the outline keeps; an open part makes them the surface's (area-weighted
/// triangles), where a label's two faces would pull the centroid off the can's axis. Either
/// way they are exact, not one sample per triangle, so the axes keep the shape's symmetry
/// whatever its triangulation: a face split along one diagonal tilted them by several
/// degrees, and the half-turn then missed the twin.
pub fn principal_axes(model: &ObjectModel, states: &[f64]) -> Option<(Point3, [Vector3; 3])> {
    principal_frame(model, states).map(|f| (f.middle, f.axes))
}

/// What [`principal_axes`] computes, with what it computes it from.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PrincipalFrame {
    /// The centroid of the solid (or of the surface, when a part is open).
    pub centroid: Point3,
    /// The middle of the posed vertices' extent along each axis: [`principal_axes`]'s centre.
    pub middle: Point3,
    /// Largest spread first.
    pub axes: [Vector3; 3],
    /// Whether the moments are the solid's (every part closed with a positive volume).
    pub solid: bool,
}

/// [`principal_axes`] with its centroid and the kind of moments it used.
pub(crate) fn principal_frame(model: &ObjectModel, states: &[f64]) -> Option<PrincipalFrame> {
    let transforms = model.tree.part_transforms(states);
    let solid = model
        .parts
        .iter()
        .all(|p| p.mesh.is_watertight() && p.mesh.volume() > 0.0);
    let mut total = 0.0;
    let mut first = Vector3::zeros();
    let mut second = Matrix3::zeros();
    for (part, t) in model.parts.iter().zip(&transforms) {
        let m = &part.mesh;
        for tri in &m.triangles {
            let [a, b, c] = tri.map(|k| (t * m.positions[k as usize]).coords);
            let sum = a + b + c;
            let outer = a * a.transpose() + b * b.transpose() + c * c.transpose();
            if solid {
                // The tetrahedron (0, a, b, c) of signed volume V: ∫ x dV = V·s/4,
                // ∫ x xᵀ dV = V/20·(a aᵀ + b bᵀ + c cᵀ + s sᵀ).
                let volume = a.dot(&b.cross(&c)) / 6.0;
                if !volume.is_finite() {
                    continue;
                }
                total += volume;
                first += sum * (volume / 4.0);
                second += (outer + sum * sum.transpose()) * (volume / 20.0);
            } else {
                let area = 0.5 * (b - a).cross(&(c - a)).norm();
                if !(area > 0.0 && area.is_finite()) {
                    continue;
                }
                // Over a triangle of area A: ∫ x dA = A·s/3, ∫ x xᵀ dA = A/12·(a aᵀ + b bᵀ + c cᵀ + s sᵀ).
                total += area;
                first += sum * (area / 3.0);
                second += (outer + sum * sum.transpose()) * (area / 12.0);
            }
        }
    }
    if total <= 0.0 || !total.is_finite() {
        return None;
    }
    let centre = first / total;
    let cov = second - centre * centre.transpose() * total;
    let eig = (cov / total).symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let axes = order.map(|i| eig.eigenvectors.column(i).into_owned().normalize());
    if !axes.iter().all(|a| a.iter().all(|v| v.is_finite())) {
        return None;
    }
    // The centre: the middle of the posed vertices' extent along each axis. A half-turn
    // about an axis of the outline's symmetry maps the extents across it onto themselves,
    // so their middle lies on the axis whatever the mass does (a mug's solid bottom and open
    // top put its centroid 0.07 below the middle, and the half-turn through it moved the
    // outline by twice that).
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (part, t) in model.parts.iter().zip(&transforms) {
        for p in &part.mesh.positions {
            let q = (t * p).coords - centre;
            for k in 0..3 {
                let d = q.dot(&axes[k]);
                lo[k] = lo[k].min(d);
                hi[k] = hi[k].max(d);
            }
        }
    }
    let middle = (0..3).fold(centre, |c, k| {
        if lo[k].is_finite() && hi[k].is_finite() {
            c + axes[k] * (0.5 * (lo[k] + hi[k]))
        } else {
            c
        }
    });
    Some(PrincipalFrame {
        centroid: Point3::from(centre),
        middle: Point3::from(middle),
        axes,
        solid,
    })
}

/// The least ratio of the reaches of a hinge's two sides (their farthest points from its
/// axis) for [`hinge_swaps`] to swap them: a side half as long as the other leaves most of
/// the other's outline uncovered in its place.
const HINGE_SWAP_REACH: f64 = 0.5;

/// The half-turns that swap the two sides of each hinge of the model at `states`: for a
/// revolute joint, the turn of half a revolution about the line through the hinge that
/// bisects the directions from it to the parts it moves and to the parts of its parent
/// (the joint's axis reversed, the states kept). Where the two sides have the same outline
/// (a laptop's lid and base, a notebook's covers, the blades of shears) it puts each side
/// where the other was: a twin no turn about the object's own axes or principal axes reaches
/// unless the sides are equal and the hinge half open. `(joint, rotation, centre)` in the
/// object's canonical frame, one per revolute joint whose two sides lie off its axis and
/// reach about as far from it ([`HINGE_SWAP_REACH`]).
pub fn hinge_swaps(model: &ObjectModel, states: &[f64]) -> Vec<(usize, UnitQuaternion, Point3)> {
    let tree = &model.tree;
    let joint_tfs = tree.joint_transforms(states);
    let part_tfs = tree.part_transforms(states);
    let centres: Vec<Option<Point3>> = model
        .parts
        .iter()
        .zip(&part_tfs)
        .map(|(part, t)| vertex_mean(&part.mesh).map(|c| t * c))
        .collect();
    let mut out = Vec::new();
    for (j, joint) in tree.joints().iter().enumerate() {
        if !matches!(
            joint.kind,
            agentstar_geom::kinematics::JointKind::Revolute
                | agentstar_geom::kinematics::JointKind::Continuous
        ) {
            continue;
        }
        let parent = joint.parent.as_deref().and_then(|p| tree.joint_index(p));
        let parent_tf = parent.map_or_else(agentstar_geom::pose::Rigid::identity, |p| joint_tfs[p]);
        let axis = parent_tf.rotation * tree.unit_axis(j).into_inner();
        let origin = parent_tf * Point3::from(joint.origin);
        // A point's offset from the hinge's axis, across it.
        let across = |p: &Point3| {
            let d = p - origin;
            d - axis * axis.dot(&d)
        };
        // One side's direction from the hinge (to the mean of its part centres) and its
        // reach (the farthest of its vertices from the hinge's axis); `None` when the side
        // has no part or lies on the axis.
        let side = |carried_by: Option<usize>| -> Option<(Vector3, f64)> {
            let parts: Vec<(usize, Point3)> = (0..model.parts.len())
                .filter(|&k| tree.part_joint(k) == carried_by)
                .filter_map(|k| Some((k, centres[k]?)))
                .collect();
            let mean =
                parts.iter().map(|(_, c)| c.coords).sum::<Vector3>() / parts.len().max(1) as f64;
            let direction = across(&Point3::from(mean));
            let reach = parts
                .iter()
                .flat_map(|&(k, _)| {
                    let t = part_tfs[k];
                    model.parts[k].mesh.positions.iter().map(move |v| t * v)
                })
                .map(|v| across(&v).norm())
                .fold(0.0, f64::max);
            (!parts.is_empty() && direction.norm() > 1e-9).then(|| (direction.normalize(), reach))
        };
        let (Some((moved, moved_reach)), Some((fixed, fixed_reach))) =
            (side(Some(j)), side(parent))
        else {
            continue;
        };
        // A side that reaches half as far as the other cannot take its place (a lock lever
        // on a blade): no twin there.
        if moved_reach.min(fixed_reach) < HINGE_SWAP_REACH * moved_reach.max(fixed_reach) {
            continue;
        }
        let bisector = moved + fixed;
        // Opposite sides (a hinge opened flat): the half-turn about the normal of their plane.
        let bisector = if bisector.norm() > 1e-6 {
            bisector
        } else {
            axis.cross(&fixed)
        };
        out.push((
            j,
            UnitQuaternion::from_axis_angle(&Unit::new_normalize(bisector), std::f64::consts::PI),
            origin,
        ));
    }
    out
}

/// The twins of a pose that every comparison of basins should include: its 180° flips about
/// the object's axes through the pivot, the half-turns about the model's principal axes
/// through its centroid (lid ↔ base swaps and the symmetries of box-like shapes), the turns
/// of an n-fold outline ([`fold_turns`]: a square prism's quarter turns and the half-turns
/// across them, which compose the flips into the whole group), and the half-turns that
/// swap the sides of each hinge ([`hinge_swaps`]).
pub fn twin_candidates(model: &ObjectModel, scale: f64, around: &GenPose) -> Vec<GenPose> {
    let pivot = model.pivot(&around.states);
    let mut moves: Vec<(UnitQuaternion, Point3)> = ['x', 'y', 'z']
        .iter()
        .filter_map(|&a| flip(a))
        .map(|q| (q, pivot))
        .collect();
    if let Some((centre, axes)) = principal_axes(model, &around.states) {
        moves.extend(axes.iter().map(|a| {
            (
                UnitQuaternion::from_axis_angle(&Unit::new_normalize(*a), std::f64::consts::PI),
                centre,
            )
        }));
    }
    let place = |(q, c): &(UnitQuaternion, Point3)| GenPose {
        pose: apply_object_rotation(&around.pose, scale, c, q),
        states: around.states.clone(),
    };
    let mut twins: Vec<GenPose> = moves.iter().map(place).collect();
    // The turns of an n-fold outline (a square prism's quarter turns and the half-turns
    // across them), each unless a flip or a principal half-turn already is it.
    for turn in fold_turns(model, &around.states) {
        let g = place(&turn);
        if !twins.iter().any(|t| same_basin(t, &g)) {
            twins.push(g);
        }
    }
    // A hinge swap that a principal half-turn already nearly makes (two like slabs: the
    // bisector through the hinge is about a principal axis through the centroid) is not
    // searched twice: one refinement reaches both.
    for swap in hinge_swaps(model, &around.states) {
        let g = place(&(swap.1, swap.2));
        if !twins.iter().any(|t| same_basin(t, &g)) {
            twins.push(g);
        }
    }
    twins
}

/// Two poses of one frame lie in the same basin (one refinement reaches both) when they are
/// turned under 5° and placed under 2% of the depth apart.
pub(crate) fn same_basin(a: &GenPose, b: &GenPose) -> bool {
    let depth = a.pose.translation.z.abs().max(1e-9);
    a.pose.rotation.angle_to(&b.pose.rotation) < 5f64.to_radians()
        && (a.pose.translation - b.pose.translation).norm() < 0.02 * depth
}

/// The mean of a mesh's vertices; `None` for a mesh without any.
fn vertex_mean(mesh: &agentstar_geom::TriMesh) -> Option<Point3> {
    let n = mesh.positions.len();
    (n > 0)
        .then(|| Point3::from(mesh.positions.iter().map(|p| p.coords).sum::<Vector3>() / n as f64))
}

/// Distinct basins of one frame around a pose: the pose itself, its 180° flips about the
/// object's axes through the pivot, the candidate twins of the model's own shape (half and
/// quarter turns about its principal axes through its centroid, the turns of an n-fold
/// outline ([`fold_turns`]), half turns about 24 axes spread over the sphere), and
/// `covering` seeded uniform rotations about the pivot. The
/// pose, its flips and the principal half-turns are always refined; the rest by their
/// placed score, at least 30° apart, up to `refine` in all. The refined hypotheses come back
/// best first, merged where two reached the same basin (within 5° of rotation and of every
/// joint), so a caller sees every basin that explains the mask.
pub fn basins(
    problem: &FrameProblem<'_>,
    around: &GenPose,
    covering: usize,
    refine: usize,
    window: &LocalWindow,
    seed: u64,
) -> Result<Vec<Refined>, TrackError> {
    let pivot = problem.model.pivot(&around.states);
    let half_turn = |axis: &Vector3| {
        UnitQuaternion::from_axis_angle(&Unit::new_normalize(*axis), std::f64::consts::PI)
    };
    // (rotation, centre) pairs; the first `always` are refined whatever they score.
    let mut moves: Vec<(UnitQuaternion, Point3)> = vec![(UnitQuaternion::identity(), pivot)];
    moves.extend(
        ['x', 'y', 'z']
            .iter()
            .filter_map(|&a| flip(a))
            .map(|q| (q, pivot)),
    );
    let mut always = moves.len();
    if let Some((centre, axes)) = principal_axes(problem.model, &around.states) {
        moves.extend(axes.iter().map(|a| (half_turn(a), centre)));
        always = moves.len();
        for a in &axes {
            for sign in [-1.0, 1.0] {
                let q = UnitQuaternion::from_axis_angle(
                    &Unit::new_normalize(*a),
                    sign * std::f64::consts::FRAC_PI_2,
                );
                moves.push((q, centre));
            }
        }
        // The turns of an n-fold outline: where two moments are equal the principal
        // quarter turns above are about arbitrary axes across the third.
        moves.extend(fold_turns(problem.model, &around.states));
        // Half turns about axes spread over a hemisphere (golden-angle spiral).
        let n = 24;
        for k in 0..n {
            let z = (k as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = k as f64 * 2.399_963_229_728_653;
            let axis = axes[0] * (r * phi.cos()) + axes[1] * (r * phi.sin()) + axes[2] * z;
            moves.push((half_turn(&axis), centre));
        }
    }
    let mut rng = Rng::new(seed);
    let target_len = moves.len() + covering;
    while moves.len() < target_len {
        let q = Quaternion::new(rng.normal(), rng.normal(), rng.normal(), rng.normal());
        if q.norm() > 1e-6 {
            moves.push((UnitQuaternion::from_quaternion(q), pivot));
        }
    }
    let placed: Vec<GenPose> = moves
        .iter()
        .map(|(q, c)| GenPose {
            pose: apply_object_rotation(&around.pose, problem.scale, c, q),
            states: around.states.clone(),
        })
        .collect();
    let scores: Vec<f64> = placed
        .par_iter()
        .map_init(|| problem.evaluator(), |ev, g| ev.combined(g))
        .collect();
    let mut order: Vec<usize> = (0..placed.len()).collect();
    order[always..].sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
    let mut chosen: Vec<GenPose> = Vec::new();
    for (rank, &k) in order.iter().enumerate() {
        if chosen.len() >= refine.max(always) {
            break;
        }
        let g = &placed[k];
        if rank < always
            || chosen
                .iter()
                .all(|c| c.pose.rotation.angle_to(&g.pose.rotation).to_degrees() >= 30.0)
        {
            chosen.push(g.clone());
        }
    }
    let mut refined = refine_each(problem, &chosen, window, seed)?;
    refined.sort_by(|a, b| b.score.combined.total_cmp(&a.score.combined));
    let mut distinct: Vec<Refined> = Vec::new();
    for r in refined {
        let same = distinct.iter().any(|d| {
            d.pose
                .pose
                .rotation
                .angle_to(&r.pose.pose.rotation)
                .to_degrees()
                < 5.0
                && d.pose
                    .states
                    .iter()
                    .zip(&r.pose.states)
                    .all(|(a, b)| (a - b).abs().to_degrees() < 5.0)
        });
        if !same {
            distinct.push(r);
        }
    }
    Ok(distinct)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::appearance::tests::labelled_model;

    #[test]
    fn a_thin_label_part_keeps_the_principal_axes_on_the_cans_axis() {
        // The solid's moments: the sleeve's volume is about 1% of the can's. The surface's
        // would count its two faces, about a third of the can's area, and pull the centroid
        // some 0.06 toward the label, so that a turn about the axis moved the outline.
        let (centre, axes) = principal_axes(&labelled_model(), &[]).expect("axes");
        let off_axis = (centre.x * centre.x + centre.y * centre.y).sqrt();
        assert!(off_axis < 0.005, "centre {centre:?}");
        let tilt = axes[0].dot(&Vector3::z()).abs().acos().to_degrees();
        assert!(tilt < 1.0, "longest axis {:?} is {tilt:.2}° off Z", axes[0]);
    }

    /// Two slabs of one outline hinged along an edge (a notebook's covers, a laptop's lid
    /// and base), at `deg`, the back 1.5 times as thick as the cover.
    fn hinged_slabs() -> ObjectModel {
        use agentstar_geom::kinematics::{JointDef, JointKind};
        use agentstar_geom::primitives::cuboid;
        use agentstar_geom::{KinematicTree, Part};
        let back = cuboid(1.0, 0.7, 0.03)
            .expect("box")
            .translated(Vector3::new(0.0, 0.0, -0.015));
        let cover = cuboid(1.0, 0.7, 0.02)
            .expect("box")
            .translated(Vector3::new(0.0, 0.0, 0.01));
        let hinge = JointDef {
            name: "spine".into(),
            kind: JointKind::Revolute,
            parent: None,
            child: vec!["cover".into()],
            origin: Vector3::new(-0.5, 0.0, 0.0),
            axis: -Vector3::y(),
            limit: Some((0.0, 180.0)),
        };
        ObjectModel {
            tree: KinematicTree::new(vec![hinge], &["back".to_string(), "cover".to_string()])
                .expect("tree"),
            parts: vec![
                Part::new("back", back, [0.2, 0.6, 0.5]),
                Part::new("cover", cover, [0.9, 0.8, 0.4]),
            ],
        }
    }

    /// The placed vertex mean of `part` under `states`, turned by `swap` (about its centre).
    fn placed_centre(
        model: &ObjectModel,
        states: &[f64],
        part: usize,
        swap: Option<&(usize, UnitQuaternion, Point3)>,
    ) -> Point3 {
        let t = model.tree.part_transforms(states)[part];
        let p = t * vertex_mean(&model.parts[part].mesh).expect("vertices");
        match swap {
            Some((_, q, c)) => c + q * (p - c),
            None => p,
        }
    }

    #[test]
    fn a_hinge_swap_puts_each_side_where_the_other_was() {
        let model = hinged_slabs();
        for deg in [30.0f64, 95.0, 160.0, 180.0] {
            let states = [deg.to_radians()];
            let swaps = hinge_swaps(&model, &states);
            assert_eq!(swaps.len(), 1, "{deg}°: one revolute joint, one swap");
            let swap = &swaps[0];
            // The cover's centre goes where the back's was, and the back's where the cover's
            // was (both lie half a slab from the hinge; their thicknesses differ by 0.005).
            let back = placed_centre(&model, &states, 0, None);
            let cover = placed_centre(&model, &states, 1, None);
            let cover_swapped = placed_centre(&model, &states, 1, Some(swap));
            let back_swapped = placed_centre(&model, &states, 0, Some(swap));
            assert!(
                (cover_swapped - back).norm() < 0.01,
                "{deg}°: {cover_swapped:?} vs {back:?}"
            );
            assert!(
                (back_swapped - cover).norm() < 0.01,
                "{deg}°: {back_swapped:?} vs {cover:?}"
            );
            // A half-turn: its axis is perpendicular to the hinge, which it reverses.
            assert_eq!(swap.0, 0, "{deg}°: the spine");
            assert!((swap.1.angle() - std::f64::consts::PI).abs() < 1e-9);
            let hinge_axis = swap.1 * Vector3::y();
            assert!(
                (hinge_axis + Vector3::y()).norm() < 1e-9,
                "{deg}°: {hinge_axis:?}"
            );
        }
        // A lever a third as long as the slab it is hinged to cannot take its place.
        let mut lever = hinged_slabs();
        lever.parts[1] = agentstar_geom::Part::new(
            "cover",
            agentstar_geom::primitives::cuboid(0.3, 0.7, 0.02)
                .expect("box")
                .translated(Vector3::new(-0.35, 0.0, 0.01)),
            [0.9, 0.8, 0.4],
        );
        assert!(hinge_swaps(&lever, &[1.0]).is_empty());
        // A model without joints has no hinge to swap.
        let rigid = ObjectModel {
            tree: agentstar_geom::KinematicTree::rigid(1),
            parts: vec![model.parts[0].clone()],
        };
        assert!(hinge_swaps(&rigid, &[]).is_empty());
    }

    #[test]
    fn the_twins_of_a_square_prism_are_its_whole_group_of_eight() {
        // A box 0.83 × 0.83 × 1 with a thin badge: its principal axes across the long one are
        // arbitrary (equal moments), so their half-turns are no symmetry. The seven other
        // poses of its outline (three turns about the long axis, four half-turns across it,
        // among them the products of a quarter turn and a flip) must all be twins.
        use agentstar_geom::primitives::cuboid;
        let body = cuboid(0.83, 0.83, 1.0).expect("box");
        let badge = cuboid(0.005, 0.17, 0.27)
            .expect("badge")
            .translated(Vector3::new(0.4175, 0.16, 0.15));
        let model = ObjectModel {
            tree: agentstar_geom::KinematicTree::rigid(2),
            parts: vec![
                agentstar_geom::Part::new("body", body, [0.2, 0.3, 0.3]),
                agentstar_geom::Part::new("badge", badge, [0.4, 0.3, 0.6]),
            ],
        };
        let turn = |axis: Vector3, deg: f64| {
            UnitQuaternion::from_axis_angle(&Unit::new_normalize(axis), deg.to_radians())
        };
        let pose = GenPose {
            pose: agentstar_geom::pose::ObjectPose::new(
                turn(Vector3::new(0.3, 1.0, 0.2), 50.0),
                Vector3::new(0.05, -0.02, 3.0),
            ),
            states: vec![],
        };
        let twins = twin_candidates(&model, 1.0, &pose);
        let group = [
            turn(Vector3::z(), 90.0),
            turn(Vector3::z(), 180.0),
            turn(Vector3::z(), 270.0),
            turn(Vector3::x(), 180.0),
            turn(Vector3::y(), 180.0),
            turn(Vector3::new(1.0, 1.0, 0.0), 180.0),
            turn(Vector3::new(1.0, -1.0, 0.0), 180.0),
        ];
        for symmetry in group {
            // The box is centred at the origin: the symmetry turns about it.
            let want = GenPose {
                pose: agentstar_geom::pose::ObjectPose::new(
                    pose.pose.rotation * symmetry,
                    pose.pose.translation,
                ),
                states: vec![],
            };
            let nearest = twins
                .iter()
                .map(|t| {
                    let angle = t.pose.rotation.angle_to(&want.pose.rotation).to_degrees();
                    (angle, (t.pose.translation - want.pose.translation).norm())
                })
                .fold((f64::INFINITY, f64::INFINITY), |a, b| {
                    if b.0 < a.0 {
                        b
                    } else {
                        a
                    }
                });
            assert!(
                nearest.0 < 0.5 && nearest.1 < 0.01,
                "{symmetry:?}: nearest twin {:.2}° and {:.3} away",
                nearest.0,
                nearest.1
            );
        }
    }

    #[test]
    fn the_twins_of_an_open_hinged_pose_include_the_swap_of_its_sides() {
        // Without the hinge swap no twin puts the cover where the back is: the flips and the
        // principal half-turns keep the back on its own side of the hinge.
        let model = hinged_slabs();
        let states = vec![70f64.to_radians()];
        let pose = GenPose {
            pose: agentstar_geom::pose::ObjectPose::new(
                UnitQuaternion::identity(),
                Vector3::new(0.0, 0.0, 2.0),
            ),
            states: states.clone(),
        };
        let back = placed_centre(&model, &states, 0, None);
        let found = twin_candidates(&model, 1.0, &pose).iter().any(|g| {
            // The twin's cover centre in the original pose's object frame.
            let cover = placed_centre(&model, &g.states, 1, None);
            let in_camera = g.pose.rotation * cover.coords + g.pose.translation;
            let in_object = pose.pose.rotation.inverse() * (in_camera - pose.pose.translation);
            (Point3::from(in_object) - back).norm() < 0.01
        });
        assert!(found, "no twin puts the cover where the back is");
    }
}
