//! Searches over a frame problem: differential evolution with seeded restarts (run in
//! parallel, one winner per restart, ranked), a refined grid with its 2-DOF score field, and
//! explicit candidate lists scored exactly.

use crate::objective::{CandidateScore, FrameProblem};
use crate::space::SearchSpace;
use crate::update::GenPose;
use crate::TrackError;
use agentstar_optim::{differential_evolution, grid_search, DeConfig, GridConfig};
use rayon::prelude::*;

#[derive(Debug, Clone, PartialEq)]
pub enum Strategy {
    /// Differential evolution with `restarts` independent runs (seeds `seed + i`).
    De,
    /// Cartesian grid (`steps` per DOF from the space or `default_steps`), refined.
    Grid {
        default_steps: usize,
        refine: usize,
        shrink: f64,
    },
    /// Score exactly these search vectors.
    Candidates(Vec<Vec<f64>>),
}

#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    pub strategy: Strategy,
    pub restarts: usize,
    /// Evaluations over all restarts (split evenly, at least 5 each).
    pub total_evals: usize,
    pub seed: u64,
    pub popsize: usize,
    pub mutation: (f64, f64),
    pub recombination: f64,
    /// Nelder–Mead polish evaluations over all restarts (0 = none).
    pub polish_evals: usize,
    /// How many ranked candidates to return (grid and candidate lists; DE returns one per restart).
    pub topk: usize,
    /// DE convergence in IoU units: a restart stops once the standard deviation of its
    /// population's scores is at most this, after `min_generations`. (A tolerance relative to
    /// the scores, SciPy's, stops a population that scores 0.95 ± 0.005 before it searched.)
    pub tol_iou: f64,
    /// Generations every DE restart runs (budget permitting) before it may stop as converged.
    pub min_generations: usize,
    /// SciPy's relative tolerance, `std ≤ tol_relative · |mean|`, added to `tol_iou` (0 = off).
    pub tol_relative: f64,
    /// Up to this many other places the search passed through, ranked beside its results
    /// (DE: the restarts' results; a grid: its best points): the best evaluated points turned
    /// at least [`SweepConfig::runner_up_deg`] (or a joint that far) from every candidate
    /// kept, as evaluated (not refined). Where the box holds another basin they show it;
    /// where it holds one, they are its slope that far out. 0 keeps none and records nothing
    /// (the tracker's refinements).
    pub runners_up: usize,
    /// How far a runner-up lies from every candidate kept and from each other:
    /// [`RUNNER_UP_DEG`] unless a caller that refines the candidates afterwards wants them a
    /// refinement's reach apart (`osweep`).
    pub runner_up_deg: f64,
}

/// How far a runner-up of a DE sweep ([`SweepConfig::runners_up`]) lies from every
/// candidate kept: in rotation, or in any joint (degrees; radians' worth for a slider).
pub const RUNNER_UP_DEG: f64 = 10.0;

impl Default for SweepConfig {
    fn default() -> Self {
        SweepConfig {
            strategy: Strategy::De,
            restarts: 6,
            total_evals: 3600,
            seed: 17,
            popsize: 8,
            mutation: (0.5, 1.0),
            recombination: 0.8,
            polish_evals: 0,
            topk: 10,
            tol_iou: 1e-3,
            min_generations: 10,
            tol_relative: 0.0,
            runners_up: 0,
            runner_up_deg: RUNNER_UP_DEG,
        }
    }
}

impl SweepConfig {
    /// SciPy's stop rule (relative tolerance 0.01 from the first generation): the cheap local
    /// refinements of the tracker, whose boxes are small and searched again in later passes.
    pub fn scipy_stop(self) -> Self {
        SweepConfig {
            tol_iou: 0.0,
            min_generations: 0,
            tol_relative: 0.01,
            ..self
        }
    }
}

/// One ranked finalist.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    pub rank: usize,
    /// The search vector (interface units, in the space's DOF order).
    pub x: Vec<f64>,
    pub pose: GenPose,
    pub score: CandidateScore,
    pub restart: Option<usize>,
    pub seed: Option<u64>,
    pub pass: usize,
    /// The unchanged starting pose, ranked because no searched candidate beat it (a search
    /// never returns a best candidate worse than where it started).
    pub kept_start: bool,
    /// The score where the candidate was placed, when it was refined before ranking
    /// ([`crate::hypotheses::refine_ranked`]); `x` is then the placed candidate's vector.
    pub unrefined: Option<CandidateScore>,
    /// A point a DE restart evaluated on its way, at least [`RUNNER_UP_DEG`] from the
    /// candidates kept, not refined ([`SweepConfig::runners_up`]).
    pub runner_up: bool,
}

impl Candidate {
    /// A candidate scored where its search vector puts it, with nothing else set (no
    /// restart, not the kept start, not refined, not a runner-up).
    fn evaluated(x: Vec<f64>, pose: GenPose, score: CandidateScore) -> Candidate {
        Candidate {
            rank: 0,
            x,
            pose,
            score,
            restart: None,
            seed: None,
            pass: 0,
            kept_start: false,
            unrefined: None,
            runner_up: false,
        }
    }
}

/// What one DE restart did.
#[derive(Debug, Clone, PartialEq)]
pub struct RestartRecord {
    pub restart: usize,
    pub seed: u64,
    pub budget: usize,
    pub population_size: usize,
    pub generations: usize,
    pub generation_best: Vec<f64>,
    pub nfev: usize,
    pub polish_nfev: usize,
    pub best: f64,
    pub termination: &'static str,
}

/// A 2-DOF score field: `scores[i][j]` is the score at `(a[i], b[j])`, `None` where unscored.
#[derive(Debug, Clone, PartialEq)]
pub struct ScoreField {
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub scores: Vec<Vec<Option<f64>>>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct SweepResult {
    pub ranked: Vec<Candidate>,
    pub restarts: Vec<RestartRecord>,
    pub n_evals: usize,
    /// For grids over exactly two DOFs with ≥ 2 steps (first pass).
    pub score_field: Option<ScoreField>,
}

/// Adds the starting pose when it beats every searched candidate, so that rank 0 is never
/// worse than the start (a box that excludes the start, or a grid that misses it).
fn keep_start(problem: &FrameProblem<'_>, space: &SearchSpace, cands: &mut Vec<Candidate>) {
    let score = problem.evaluator().score(&problem.base);
    if cands.iter().all(|c| c.score.combined < score.combined) {
        cands.push(Candidate {
            kept_start: true,
            ..Candidate::evaluated(problem.start_vector(space), problem.base.clone(), score)
        });
    }
}

/// The candidates with repeats dropped (the first of each kept, so the lowest restart):
/// restarts that all end at the same vector (typically the start, when nothing in the box
/// beats it) are one candidate, not one per restart (play-test, 2026-12-02).
fn distinct_poses(cands: Vec<Candidate>) -> Vec<Candidate> {
    let mut out: Vec<Candidate> = Vec::with_capacity(cands.len());
    for c in cands {
        // The kept start is never a repeat: its vector may be the start clamped into the
        // box, which a restart can also reach, with another pose.
        let repeat = !c.kept_start
            && out.iter().any(|o| {
                !o.kept_start
                    && o.x.len() == c.x.len()
                    && o.x.iter().zip(&c.x).all(|(p, q)| (p - q).abs() <= 1e-9)
            });
        if !repeat {
            out.push(c);
        }
    }
    out
}

/// `cands` with [`SweepConfig::runners_up`] of the `seen` points added ([`runners_up`]).
fn add_runners_up(
    problem: &FrameProblem<'_>,
    space: &SearchSpace,
    cands: &mut Vec<Candidate>,
    seen: Vec<(Vec<f64>, f64)>,
    cfg: &SweepConfig,
) {
    let more = runners_up(
        problem,
        space,
        cands,
        seen,
        (cfg.runners_up, cfg.runner_up_deg),
    );
    cands.extend(more);
}

/// Up to `n` of the `seen` points (search vectors with their scores), best first, each
/// turned at least `apart_deg` (or a joint that far) from every candidate in `kept` and from
/// each other, scored in full.
fn runners_up(
    problem: &FrameProblem<'_>,
    space: &SearchSpace,
    kept: &[Candidate],
    mut seen: Vec<(Vec<f64>, f64)>,
    (n, apart_deg): (usize, f64),
) -> Vec<Candidate> {
    if n == 0 {
        return vec![];
    }
    seen.sort_by(|a, b| b.1.total_cmp(&a.1));
    let apart = |a: &GenPose, b: &GenPose| {
        a.pose.rotation.angle_to(&b.pose.rotation) >= apart_deg.to_radians()
            || a.states
                .iter()
                .zip(&b.states)
                .any(|(p, q)| (p - q).abs() >= apart_deg.to_radians())
    };
    let mut ev = problem.evaluator();
    let mut out: Vec<Candidate> = Vec::new();
    for (x, _) in seen {
        if out.len() >= n {
            break;
        }
        let pose = problem.candidate(space, &x);
        if kept.iter().chain(&out).all(|c| apart(&c.pose, &pose)) {
            let score = ev.score(&pose);
            out.push(Candidate {
                runner_up: true,
                ..Candidate::evaluated(x, pose, score)
            });
        }
    }
    out
}

/// Best first (a stable sort: candidates that score alike keep the order they came in).
pub(crate) fn rank(mut c: Vec<Candidate>, topk: usize) -> Vec<Candidate> {
    c.sort_by(|a, b| b.score.combined.total_cmp(&a.score.combined));
    c.truncate(topk.max(1));
    for (i, x) in c.iter_mut().enumerate() {
        x.rank = i;
    }
    c
}

/// Scores a batch of vectors in parallel, one evaluator per worker chunk.
fn score_batch(problem: &FrameProblem<'_>, space: &SearchSpace, xs: &[Vec<f64>]) -> Vec<f64> {
    let chunk = xs
        .len()
        .div_ceil(rayon::current_num_threads().max(1) * 4)
        .max(1);
    xs.par_chunks(chunk)
        .flat_map_iter(|c| {
            let mut ev = problem.evaluator();
            c.iter()
                .map(|x| ev.combined(&problem.candidate(space, x)))
                .collect::<Vec<_>>()
        })
        .collect()
}

pub fn sweep(
    problem: &FrameProblem<'_>,
    space: &SearchSpace,
    cfg: &SweepConfig,
) -> Result<SweepResult, TrackError> {
    let bounds = space.bounds();
    match &cfg.strategy {
        Strategy::Candidates(list) => {
            for (i, x) in list.iter().enumerate() {
                if x.len() != space.len() {
                    return Err(TrackError::Invalid(format!(
                        "candidate {i} has {} values for {} degrees of freedom",
                        x.len(),
                        space.len()
                    )));
                }
            }
            let cands: Vec<Candidate> = list
                .par_iter()
                .map(|x| {
                    let pose = problem.candidate(space, x);
                    let score = problem.evaluator().score(&pose);
                    Candidate::evaluated(x.clone(), pose, score)
                })
                .collect();
            let n = cands.len();
            Ok(SweepResult {
                ranked: rank(cands, cfg.topk.max(n)),
                restarts: vec![],
                n_evals: n,
                score_field: None,
            })
        }
        Strategy::Grid {
            default_steps,
            refine,
            shrink,
        } => {
            let steps: Vec<usize> = space
                .ranges
                .iter()
                .map(|r| r.steps.unwrap_or(*default_steps))
                .collect();
            let gcfg = GridConfig {
                steps: steps.clone(),
                refine_passes: *refine,
                shrink: *shrink,
                max_points: 200_000,
            };
            let pts = grid_search(
                &mut |xs| {
                    score_batch(problem, space, xs)
                        .into_iter()
                        .map(|s| -s)
                        .collect()
                },
                &bounds,
                &gcfg,
            )?;
            let score_field = (space.len() == 2 && steps.iter().all(|&s| s >= 2)).then(|| {
                let first: Vec<&agentstar_optim::GridPoint> =
                    pts.iter().filter(|p| p.pass == 0).collect();
                let mut a: Vec<f64> = first.iter().map(|p| p.x[0]).collect();
                let mut b: Vec<f64> = first.iter().map(|p| p.x[1]).collect();
                a.sort_by(f64::total_cmp);
                a.dedup();
                b.sort_by(f64::total_cmp);
                b.dedup();
                let mut cells = vec![vec![None; b.len()]; a.len()];
                for p in first {
                    let ia = a.iter().position(|&v| v == p.x[0]).unwrap_or(0);
                    let ib = b.iter().position(|&v| v == p.x[1]).unwrap_or(0);
                    cells[ia][ib] = Some(-p.f);
                }
                ScoreField {
                    a,
                    b,
                    scores: cells,
                }
            });
            let n_evals = pts.len();
            let mut best: Vec<&agentstar_optim::GridPoint> = pts.iter().collect();
            // Points that score exactly alike (a part the mask cannot see: hidden behind the
            // body or under a hand) rank by how little they change the start, each DOF as a
            // share of its range: the start's own value first where the grid holds it
            // (play-test, 2026-12-05: a flat joint grid ranked its lower bound first).
            let x0 = problem.start_vector(space);
            let change = |x: &[f64]| -> f64 {
                x.iter()
                    .zip(&x0)
                    .zip(&bounds)
                    .map(|((v, s), (lo, hi))| ((v - s) / (hi - lo).abs().max(1e-12)).powi(2))
                    .sum()
            };
            best.sort_by(|p, q| {
                p.f.total_cmp(&q.f)
                    .then_with(|| change(&p.x).total_cmp(&change(&q.x)))
            });
            best.dedup_by(|p, q| p.x == q.x);
            let mut cands: Vec<Candidate> = best
                .into_iter()
                .take(cfg.topk.max(1))
                .map(|p| {
                    let pose = problem.candidate(space, &p.x);
                    let score = problem.evaluator().score(&pose);
                    Candidate {
                        pass: p.pass,
                        ..Candidate::evaluated(p.x.clone(), pose, score)
                    }
                })
                .collect();
            keep_start(problem, space, &mut cands);
            if cfg.runners_up > 0 {
                let seen: Vec<(Vec<f64>, f64)> = pts.iter().map(|p| (p.x.clone(), -p.f)).collect();
                add_runners_up(problem, space, &mut cands, seen, cfg);
            }
            Ok(SweepResult {
                ranked: rank(cands, cfg.topk + cfg.runners_up),
                restarts: vec![],
                n_evals,
                score_field,
            })
        }
        Strategy::De => {
            let restarts = cfg.restarts.max(1);
            let per = (cfg.total_evals / restarts).max(5);
            let polish = cfg.polish_evals / restarts;
            let x0 = problem.start_vector(space);
            type Run = (Candidate, RestartRecord, Vec<(Vec<f64>, f64)>);
            let runs: Vec<Result<Run, TrackError>> = (0..restarts)
                .into_par_iter()
                .map(|i| {
                    let seed = cfg.seed + i as u64;
                    let mut ev = problem.evaluator();
                    // Every point evaluated, when runners-up are asked for.
                    let mut seen: Vec<(Vec<f64>, f64)> = Vec::new();
                    let record = cfg.runners_up > 0;
                    let de = DeConfig {
                        popsize: cfg.popsize,
                        mutation: cfg.mutation,
                        recombination: cfg.recombination,
                        tol: cfg.tol_relative,
                        atol: cfg.tol_iou,
                        min_generations: cfg.min_generations,
                        max_evals: per,
                        seed,
                        polish_evals: polish,
                    };
                    let r = differential_evolution(
                        &mut |x| {
                            let f = ev.combined(&problem.candidate(space, x));
                            if record {
                                seen.push((x.to_vec(), f));
                            }
                            -f
                        },
                        &bounds,
                        Some(&x0),
                        &de,
                    )?;
                    let pose = problem.candidate(space, &r.x);
                    let score = ev.score(&pose);
                    let rec = RestartRecord {
                        restart: i,
                        seed,
                        budget: per,
                        population_size: r.population_size,
                        generations: r.generations,
                        generation_best: r.generation_best.iter().map(|v| -v).collect(),
                        nfev: r.nfev,
                        polish_nfev: r.polish_nfev,
                        best: -r.f,
                        termination: r.termination.as_str(),
                    };
                    Ok((
                        Candidate {
                            restart: Some(i),
                            seed: Some(seed),
                            ..Candidate::evaluated(r.x, pose, score)
                        },
                        rec,
                        seen,
                    ))
                })
                .collect();
            let mut cands = Vec::new();
            let mut records = Vec::new();
            let mut seen = Vec::new();
            for r in runs {
                let (c, rec, s) = r?;
                cands.push(c);
                records.push(rec);
                seen.extend(s);
            }
            let n_evals = records.iter().map(|r| r.nfev + r.polish_nfev).sum();
            keep_start(problem, space, &mut cands);
            let mut cands = distinct_poses(cands);
            let kept = cands.len();
            add_runners_up(problem, space, &mut cands, seen, cfg);
            Ok(SweepResult {
                ranked: rank(cands, kept + cfg.runners_up),
                restarts: records,
                n_evals,
                score_field: None,
            })
        }
    }
}
