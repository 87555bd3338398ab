//! `sweep` and `apply`: camera-frame increments about the pivot and joint states, searched
//! (differential evolution or grids, or explicit candidate lists) or scored as given.

use super::*;
use crate::common::OpenSession as _;

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar sweep --capture cap --model run/scene.rhai --poses run/pose.json --out reports --frames 000010 --ranges 'yaw:-20,20;hinge:20,60'"
)]
pub struct SweepArgs {
    #[command(flatten)]
    common: Common,
    /// Frames to search, each for its own winner (default: the reference frame).
    #[arg(long)]
    frames: Option<String>,
    /// pose | joint | both (inferred from --ranges when omitted; pose when both are omitted).
    #[arg(long)]
    space: Option<String>,
    /// Ranges, e.g. `yaw:-20,20;pitch:standard_topcloser;hinge:20,60` (see the grammar in the error text).
    #[arg(long)]
    ranges: Option<String>,
    /// de | grid
    #[arg(long, default_value = "de")]
    strategy: String,
    #[command(flatten)]
    grid: GridArgs,
    /// Independent DE restarts (seeds seed + i), one winner each.
    #[arg(long, default_value_t = 6)]
    restarts: usize,
    /// Objective evaluations over all restarts (split evenly). Default: 3600, or for DE
    /// enough for 20 generations of every restart's population (8 per searched dimension)
    /// where that is more, at most 20000: 6720 for 7 dimensions.
    #[arg(long)]
    evals: Option<usize>,
    /// Seed of the first restart.
    #[arg(long, default_value_t = 17)]
    seed: u64,
    /// Nelder–Mead polish evaluations over all restarts (0 = none).
    #[arg(long, default_value_t = 0)]
    polish: usize,
    /// Ranked candidates kept (grid).
    #[arg(long, default_value_t = 10)]
    topk: usize,
    /// DE: other places the search passed through, ranked beside the restarts' results (the
    /// best points it evaluated at least 10° from every candidate kept, not refined; their
    /// label starts with `seen`): another basin where the box holds one.
    #[arg(long, default_value_t = 3)]
    runners_up: usize,
    /// Apply this order before searching, so the window centres on the shifted pose.
    #[arg(long)]
    start_shift: Option<String>,
    /// Score these orders exactly instead of searching: `yaw:10;hinge:40|yaw:-10;hinge:60`,
    /// or `@FILE` with one order per line.
    #[arg(long, conflicts_with_all = ["start_shift", "ranges"])]
    candidates: Option<String>,
}

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar apply --capture cap --model run/scene.rhai --poses run/pose.json --out reports --frame 000010 --order 'pitch:17;dpx:0.05;hinge:70'"
)]
pub struct ApplyArgs {
    #[command(flatten)]
    common: Common,
    /// The frame (default: the reference frame).
    #[arg(long)]
    frame: Option<String>,
    /// One value per DOF: `pitch:17;dpx:0.05;hinge:70` (increments; joint states absolute).
    #[arg(long)]
    order: String,
}

pub fn run_sweep(a: SweepArgs) -> Result<ExitCode> {
    let s = a.common.session.open()?;
    let tree = &s.model.model.tree;
    let kind = match a.space.as_deref() {
        None => None,
        Some("pose") => Some(SpaceKind::Pose),
        Some("joint") => Some(SpaceKind::Joint),
        Some("both") => Some(SpaceKind::Both),
        Some(o) => bail!("unknown space `{o}`; use pose, joint or both"),
    };
    if let Some(list) = &a.candidates {
        return run_candidates(&a, &s, list);
    }
    let space = build_space(a.ranges.as_deref(), kind, tree, Grammar::Camera)?;
    if space.is_empty() {
        bail!("the search space is empty (a rigid model has no joints to search); name pose ranges or use --space pose");
    }
    let strategy = match a.strategy.as_str() {
        "de" => Strategy::De,
        "grid" => a.grid.strategy(),
        o => bail!("unknown strategy `{o}`; use de or grid"),
    };
    let cfg = SweepConfig {
        strategy: strategy.clone(),
        restarts: a.restarts,
        total_evals: a
            .evals
            .unwrap_or_else(|| default_evals(&strategy, space.ranges.len(), a.restarts)),
        seed: a.seed,
        polish_evals: a.polish,
        topk: a.topk,
        // DE's (a grid ranks its own best points).
        runners_up: if matches!(strategy, Strategy::De) {
            a.runners_up
        } else {
            0
        },
        ..SweepConfig::default()
    };
    let frames = default_frame(&s, a.frames.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "sweep").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let mut base = s.gen_pose(i);
        if let Some(shift) = &a.start_shift {
            let sp = parse_spec_values(shift, tree)?;
            let p = problem_for(&s, i, &inputs, a.common.depth_weight, base.clone());
            base = p.candidate(&sp.0, &sp.1);
        }
        let p = problem_for(&s, i, &inputs, a.common.depth_weight, base);
        let r = sweep(&p, &space, &cfg)?;
        let extra = json!({
            "method": a.strategy, "space": space_json(&space, tree), "n_evals": r.n_evals,
            "pivot": {"canonical": <[f64; 3]>::from(p.pivot.coords), "depth_z": agentstar_track::update::pivot_in_camera(&p.base.pose, s.scale(), &p.pivot).z},
            "restarts": r.restarts.iter().map(|x| json!({"restart": x.restart, "seed": x.seed, "budget": x.budget, "population_size": x.population_size, "generations": x.generations, "nfev": x.nfev, "polish_nfev": x.polish_nfev, "best": x.best, "termination": x.termination, "generation_best": x.generation_best})).collect::<Vec<_>>(),
            "score_field": r.score_field.as_ref().map(|f| json!({"dofs": [space.ranges[0].dof.name(tree), space.ranges[1].dof.name(tree)], "a_values": f.a, "b_values": f.b, "scores": f.scores})),
        });
        let mut notes = space.notes.clone();
        notes.extend(held_note(&space, tree));
        if r.ranked
            .first()
            .is_some_and(|c| !c.kept_start && converged_to(&c.pose, &p.base, tree))
        {
            notes.push(CONVERGED_NOTE.to_string());
        }
        if let Some(f) = &r.score_field {
            notes.push(heat_map(f, &space, tree));
            let img = agentstar_render::views::heat_map(
                &space.ranges[0].dof.name(tree),
                &f.a,
                &space.ranges[1].dof.name(tree),
                &f.b,
                &f.scores,
            );
            let p = out_dir(&a.common.out)?
                .join(format!("sweep_heatmap_{}.png", s.capture.frames[i].stem));
            save_png_rgb(&img, &p)?;
            notes.push(format!("heat map: {}", p.display()));
        }
        // Each row's agreement with the model's own colours, as the object-frame verbs give it
        // (play-test 14 committed candidates only to read their colour figure in `score`).
        let mut rows = rows_from(r, &space, tree);
        annotate(&s, i, &mut rows)?;
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows,
            extra,
            notes,
            pages: vec![],
            draw_all: false,
        });
    }
    write_outputs(
        SearchVerb::Sweep,
        &s,
        &a.common,
        &frames,
        outputs,
        json!({}),
    )
}

/// `sweep --candidates`: every order scored exactly, ranked per frame.
fn run_candidates(a: &SweepArgs, s: &Session, list: &str) -> Result<ExitCode> {
    let tree = &s.model.model.tree;
    let text = match list.strip_prefix('@') {
        Some(path) => agentstar_data::read_text(Path::new(path))?,
        None => list.replace('|', "\n"),
    };
    let orders: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    if orders.is_empty() {
        bail!("--candidates holds no order; write `yaw:10;hinge:40|yaw:-10` or @FILE with one order per line");
    }
    let parsed: Vec<(SearchSpace, Vec<f64>)> = orders
        .iter()
        .map(|o| parse_spec_values(o, tree))
        .collect::<Result<_>>()?;
    let frames = default_frame(s, a.frames.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "sweep").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let p = problem_for(s, i, &inputs, a.common.depth_weight, s.gen_pose(i));
        let mut ev = p.evaluator();
        let mut rows: Vec<Row> = parsed
            .iter()
            .zip(&orders)
            .enumerate()
            .map(|(k, ((space, x), order))| {
                let pose = p.candidate(space, x);
                let score = ev.score(&pose);
                Row {
                    rank: 0,
                    label: order.to_string(),
                    pose,
                    score,
                    extra: json!({"candidate": k}),
                    model_ncc: None,
                    neighbour_steps: vec![],
                    outside_region: vec![],
                }
            })
            .collect();
        rows.sort_by(|x, y| y.score.combined.total_cmp(&x.score.combined));
        for (k, r) in rows.iter_mut().enumerate() {
            r.rank = k;
        }
        annotate(s, i, &mut rows)?;
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows,
            extra: json!({"method": "candidates", "n": orders.len()}),
            notes: vec![],
            pages: vec![],
            draw_all: false,
        });
    }
    write_outputs(SearchVerb::Sweep, s, &a.common, &frames, outputs, json!({}))
}

/// An ASCII heat map of a 2-DOF score field.
fn heat_map(
    f: &agentstar_track::search::ScoreField,
    space: &SearchSpace,
    tree: &KinematicTree,
) -> String {
    let mut t = format!(
        "score field: rows {} , columns {}\n{:>9}",
        space.ranges[0].dof.name(tree),
        space.ranges[1].dof.name(tree),
        ""
    );
    for b in &f.b {
        t.push_str(&format!(" {:>7}", fmt6(*b)));
    }
    for (ia, a) in f.a.iter().enumerate() {
        t.push_str(&format!("\n{:>9}", fmt6(*a)));
        for v in &f.scores[ia] {
            t.push_str(&format!(
                " {:>7}",
                v.map_or("-".into(), |x| format!("{x:.4}"))
            ));
        }
    }
    t
}

/// Parses `dof:value;…` into a one-point space and its vector.
fn parse_spec_values(order: &str, tree: &KinematicTree) -> Result<(SearchSpace, Vec<f64>)> {
    let spec: Vec<String> = order
        .split(';')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| {
            let (k, v) = t.split_once(':').ok_or_else(|| {
                anyhow!("`{t}`: expected `dof:value`, e.g. `pitch:17;dpx:0.05;hinge:70`")
            })?;
            Ok(format!("{k}:{v},{v}"))
        })
        .collect::<Result<_>>()?;
    let space = parse_spec(&spec.join(";"), tree, Grammar::Camera)?;
    let x = space.ranges.iter().map(|r| r.lo).collect();
    Ok((space, x))
}

/// Evaluations of a sweep that names none: [`DEFAULT_EVALS`], or for DE
/// [`DE_GENERATIONS`] generations of every restart's population (8 per dimension) where that
/// is more. A fixed 3600 gave a 7-dimensional DE sweep 10 generations a restart, and it came
/// back to its start beside a pose 0.04 IoU better (play-test 9).
fn default_evals(strategy: &Strategy, dims: usize, restarts: usize) -> usize {
    match strategy {
        Strategy::De => {
            let population = (SweepConfig::default().popsize * dims).max(5);
            (restarts.max(1) * population * DE_GENERATIONS).clamp(DEFAULT_EVALS, MAX_DEFAULT_EVALS)
        }
        _ => DEFAULT_EVALS,
    }
}
const DEFAULT_EVALS: usize = 3600;
const DE_GENERATIONS: usize = 20;
/// The most a sweep takes without being asked: 20 generations of a model with many joints
/// would be (12 dimensions: 11,520; 30: 28,800).
const MAX_DEFAULT_EVALS: usize = 20_000;

/// What a sweep says when its best is the start it began from (play-test 7 read a rank 0 of
/// zero increments above rows of `seen` as a failed search).
const CONVERGED_NOTE: &str = "the search came back to its start: rank 0 is the start pose (within 0.5° and 0.5% of its depth, every joint within 0.5°), so this search found nothing higher in this region. It samples the region, it does not cover it: a narrow basin inside a wide region can be missed (play-test 9: a 7-dimensional region missed a pose 0.04 IoU better that a narrower sweep with more `evals` found). To be sure, narrow the region around where you expect the pose or give more `evals`; to look elsewhere, widen it or try the flips (`osweep`).";

/// Whether `best` is `start` to within 0.5° of rotation, 0.5% of the depth and, in every
/// joint of `tree`, 0.5° (revolute) or 0.005 canonical units (prismatic).
fn converged_to(best: &GenPose, start: &GenPose, tree: &KinematicTree) -> bool {
    let depth = start.pose.translation.z.abs().max(1e-9);
    best.pose.rotation.angle_to(&start.pose.rotation) <= 0.5f64.to_radians()
        && (best.pose.translation - start.pose.translation).norm() <= 0.005 * depth
        && best.states.len() == start.states.len()
        && best
            .states
            .iter()
            .zip(&start.states)
            .zip(tree.joints())
            .all(|((a, b), j)| {
                let tolerance = if j.kind.is_angular() {
                    0.5f64.to_radians()
                } else {
                    0.005
                };
                (a - b).abs() <= tolerance
            })
}

pub fn run_apply(a: ApplyArgs) -> Result<ExitCode> {
    let s = a.common.session.open()?;
    let tree = &s.model.model.tree;
    let (space, x) = parse_spec_values(&a.order, tree)?;
    let frames = default_frame(&s, a.frame.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "apply").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let p = problem_for(&s, i, &inputs, a.common.depth_weight, s.gen_pose(i));
        let r = sweep(
            &p,
            &space,
            &SweepConfig {
                strategy: Strategy::Candidates(vec![x.clone()]),
                ..SweepConfig::default()
            },
        )?;
        let mut rows = rows_from(r, &space, tree);
        annotate(&s, i, &mut rows)?;
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows,
            extra: json!({"method": "apply", "order": a.order}),
            notes: space.notes.clone(),
            pages: vec![],
            draw_all: false,
        });
    }
    write_outputs(
        SearchVerb::Apply,
        &s,
        &a.common,
        &frames,
        outputs,
        json!({}),
    )
}

/// Which of the pose's and the joints' degrees of freedom a camera-frame sweep left where the
/// frame's pose has them (play-test 15 added `dpx`, `dpy` and `tz` to a sweep to learn whether
/// they were refined); `None` when it searched them all.
fn held_note(space: &agentstar_track::SearchSpace, tree: &KinematicTree) -> Option<String> {
    use agentstar_track::Dof;
    let searched = |d: &Dof| space.ranges.iter().any(|r| &r.dof == d);
    let held: Vec<String> = [Dof::Roll, Dof::Yaw, Dof::Pitch, Dof::Dpx, Dof::Dpy, Dof::Tz]
        .into_iter()
        .chain(
            (0..tree.joints().len())
                .filter(|&j| tree.joints()[j].kind.has_state())
                .map(Dof::Joint),
        )
        .filter(|d| !searched(d))
        .map(|d| d.name(tree))
        .collect();
    (!held.is_empty()).then(|| {
        format!(
            "held at the frame's pose (not searched; name them in `ranges` to search them): {}",
            held.join(", ")
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_de_sweep_without_evals_gets_twenty_generations_however_many_dimensions() {
        // 6 restarts, 8 per dimension: 7 dimensions need 6·56·20.
        assert_eq!(default_evals(&Strategy::De, 7, 6), 6 * 56 * 20);
        // Few dimensions keep the floor.
        assert_eq!(default_evals(&Strategy::De, 3, 6), DEFAULT_EVALS);
        let grid = Strategy::Grid {
            default_steps: 5,
            refine: 1,
            shrink: 0.5,
        };
        assert_eq!(default_evals(&grid, 7, 6), DEFAULT_EVALS);
        // Many joints: capped.
        assert_eq!(default_evals(&Strategy::De, 40, 6), MAX_DEFAULT_EVALS);
    }
}
