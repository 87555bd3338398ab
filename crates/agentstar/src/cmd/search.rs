//! The pose verbs: `sweep` and `apply` (camera-frame increments about the pivot),
//! `osweep` and `oapply` (object-frame rotations per frame) and `oapply-all` (one shared
//! object-frame rotation for every frame). Each writes a JSON report, a text table with
//! paste-ready blocks, and a candidate sheet (render over the frame and silhouette
//! comparison per finalist, labelled with rank, score and the order).

use crate::common::{
    out_dir, print_json, progress, select_frames, FrameInputs, Session, SessionArgs,
};
use agentstar_data::images::save_png_rgb;
use agentstar_data::posefile::pose_json;
use agentstar_geom::{KinematicTree, Point3, UnitQuaternion};
use agentstar_render::views::{contact_sheet, overlay, shade, silhouette_comparison, ShadeOptions};
use agentstar_render::{render_full, PosedModel};
use agentstar_track::objective::{CandidateScore, FrameProblem};
use agentstar_track::search::{sweep, Strategy, SweepConfig, SweepResult};
use agentstar_track::space::{
    build_space, parse_spec, Dof, DofRange, Grammar, SearchSpace, SpaceKind,
};
use agentstar_track::update::{apply_object_rotation, flip, rotation_vector_deg, GenPose};
use anyhow::{anyhow, bail, Context, Result};
use image::RgbImage;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Flags shared by every verb.
#[derive(clap::Args, Clone)]
pub struct Common {
    #[command(flatten)]
    session: SessionArgs,
    /// Output directory for reports and sheets.
    #[arg(long)]
    out: PathBuf,
    /// Weight of the depth term in the combined score (used when the capture has depth).
    #[arg(long, default_value_t = 0.0)]
    depth_weight: f64,
    /// Finalists rendered on the candidate sheet.
    #[arg(long, default_value_t = 6)]
    sheet: usize,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

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
    /// Grid steps for DOFs whose range gives none.
    #[arg(long, default_value_t = 5)]
    steps: usize,
    /// Grid refinement passes (each re-centres the windows on the best point).
    #[arg(long, default_value_t = 1)]
    refine: usize,
    /// Factor applied to each window's half-span per refinement pass.
    #[arg(long, default_value_t = 0.5)]
    shrink: f64,
    /// Independent DE restarts (seeds seed + i), one winner each.
    #[arg(long, default_value_t = 6)]
    restarts: usize,
    /// Objective evaluations over all restarts (split evenly).
    #[arg(long, default_value_t = 3600)]
    evals: usize,
    /// Seed of the first restart.
    #[arg(long, default_value_t = 17)]
    seed: u64,
    /// Nelder–Mead polish evaluations over all restarts (0 = none).
    #[arg(long, default_value_t = 0)]
    polish: usize,
    /// Ranked candidates kept (grid).
    #[arg(long, default_value_t = 10)]
    topk: usize,
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

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar osweep --capture cap --model run/scene.rhai --poses run/pose.json --out reports --frames 000010 --opreset z:flip"
)]
pub struct OsweepArgs {
    #[command(flatten)]
    common: Common,
    /// Frames: names, stems or `a..b` ranges, comma separated (default: all).
    #[arg(long)]
    frames: Option<String>,
    /// Grid ranges over rx, ry, rz (and joints): `rz:-180,180,9;rx:-15,15,3`.
    #[arg(long)]
    ranges: Option<String>,
    /// Preset rotations: `z:flip`, `z:quarters`, `z:octants`, `z:full`, `z:0,90,180`, `z:large`, or `so3:N` (identity plus N uniform rotations).
    #[arg(long)]
    opreset: Option<String>,
    /// Grid steps for axes whose range gives none.
    #[arg(long, default_value_t = 5)]
    steps: usize,
    /// Grid refinement passes.
    #[arg(long, default_value_t = 1)]
    refine: usize,
    /// Window shrink per refinement pass.
    #[arg(long, default_value_t = 0.5)]
    shrink: f64,
    /// Ranked candidates kept per frame.
    #[arg(long, default_value_t = 10)]
    topk: usize,
}

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar oapply --capture cap --model run/scene.rhai --poses run/pose.json --out reports --frames 000010 --set flips"
)]
pub struct OapplyArgs {
    #[command(flatten)]
    common: Common,
    /// Frames: names, stems or `a..b` ranges, comma separated (default: all).
    #[arg(long)]
    frames: Option<String>,
    /// Candidates separated by `|`, terms by `;`: `identity|flip:x|rz:90;rx:10`, or `flips`.
    #[arg(long, default_value = "flips")]
    set: String,
}

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar oapply-all --capture cap --model run/scene.rhai --poses run/pose.json --out reports --rotation 'flip:x'"
)]
pub struct OapplyAllArgs {
    #[command(flatten)]
    common: Common,
    /// Frames to rotate (default: all).
    #[arg(long)]
    frames: Option<String>,
    /// One rotation: `rz:90;rx:10` (rotation vector, degrees) or `flip:x|y|z`.
    #[arg(long)]
    rotation: String,
}

/// One ranked candidate for the report.
struct Row {
    rank: usize,
    label: String,
    pose: GenPose,
    score: CandidateScore,
    extra: Value,
}

fn order_string(space: &SearchSpace, x: &[f64], tree: &KinematicTree) -> String {
    space
        .ranges
        .iter()
        .zip(x)
        .map(|(r, v)| format!("{}:{}", r.dof.name(tree), fmt6(*v)))
        .collect::<Vec<_>>()
        .join(";")
}

fn fmt6(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

fn row_json(r: &Row, scale: f64, tree: &KinematicTree) -> Value {
    let p = pose_json(&r.pose.pose, Some(scale));
    json!({
        "rank": r.rank, "label": r.label,
        "pose": {"quaternion": p.quaternion, "translation": p.translation, "scale": scale},
        "joints": tree.states_to_interface(&r.pose.states),
        "iou_visible": r.score.iou_visible, "iou_raw": r.score.iou_raw, "gate": r.score.gate,
        "depth_canon": r.score.depth_canon, "combined": r.score.combined, "extra": r.extra,
    })
}

fn space_json(space: &SearchSpace, tree: &KinematicTree) -> Value {
    json!(space
        .ranges
        .iter()
        .map(|r| json!({"dof": r.dof.name(tree), "lower": r.lo, "upper": r.hi, "steps": r.steps}))
        .collect::<Vec<_>>())
}

/// The candidate sheet of one frame: per finalist, the render over the frame and the
/// silhouette comparison, labelled with rank, score and order.
fn candidate_sheet(
    s: &Session,
    i: usize,
    rows: &[Row],
    limit: usize,
    title: &str,
) -> Result<RgbImage> {
    let frame = s.capture.load_frame(i)?;
    let (target, _) = s.target(i)?;
    let cam = s.capture.frames[i].camera;
    let colors: Vec<[f32; 3]> = s.model.model.parts.iter().map(|p| p.color).collect();
    let mut tiles = Vec::new();
    for r in rows.iter().take(limit.max(1)) {
        let buffers = render_full(
            &cam,
            &PosedModel::new(
                &s.model.model,
                &r.pose.states,
                &r.pose.pose.with_scale(s.scale()),
            )
            .instances,
        );
        let over = overlay(
            &frame,
            &shade(&buffers, &colors, ShadeOptions::default()),
            0.6,
        );
        let hand = target.keep().map(|k| k.not());
        let (cmp, _) = silhouette_comparison(&buffers.silhouette(), target.mask(), hand.as_ref());
        tiles.push((
            format!("#{} IoU {:.4} {}", r.rank, r.score.gate, r.label),
            over,
        ));
        tiles.push((format!("#{} compare", r.rank), cmp));
    }
    Ok(contact_sheet(&tiles, 2, title))
}

#[allow(clippy::too_many_arguments)]
fn text_report(
    verb: &str,
    frame: &str,
    rows: &[Row],
    scale: f64,
    tree: &KinematicTree,
    notes: &[String],
    report_path: &Path,
    poses: &Path,
) -> String {
    let mut t = format!(
        "{verb} {frame}\n{:<5} {:>8} {:>8} {:>8} {:>9}  order\n",
        "rank", "combined", "iou_vis", "iou_raw", "dp_canon"
    );
    for r in rows {
        t.push_str(&format!(
            "{:<5} {:>8.4} {:>8} {:>8.4} {:>9}  {}\n",
            r.rank,
            r.score.combined,
            r.score
                .iou_visible
                .map_or("n/a".into(), |v| format!("{v:.4}")),
            r.score.iou_raw,
            r.score
                .depth_canon
                .map_or("-".into(), |v| format!("{v:.4}")),
            r.label
        ));
    }
    for n in notes {
        t.push_str(&format!("note: {n}\n"));
    }
    if let Some(b) = rows.first() {
        let p = pose_json(&b.pose.pose, None);
        let q: Vec<String> = p.quaternion.iter().map(|v| fmt6(*v)).collect();
        let tr: Vec<String> = p.translation.iter().map(|v| fmt6(*v)).collect();
        let joints: Vec<String> = tree
            .states_to_interface(&b.pose.states)
            .iter()
            .map(|(k, v)| format!("\"{k}\": {}", fmt6(*v)))
            .collect();
        t.push_str(&format!(
            "\nBEST — paste into pose.json frames[\"{frame}\"]:\n\"object_pose\": {{\"quaternion\": [{}], \"translation\": [{}], \"scale\": {}}},\n\"joints\": {{{}}}\n",
            q.join(", "),
            tr.join(", "),
            fmt6(scale),
            joints.join(", ")
        ));
        t.push_str(&format!("\nor commit it: agentstar pose commit --poses {} --report {} --rank 0 --frames {frame}\n", poses.display(), report_path.display()));
    }
    t
}

struct FrameOutput {
    frame: String,
    rows: Vec<Row>,
    extra: Value,
    notes: Vec<String>,
}

fn write_outputs(
    verb: &str,
    s: &Session,
    c: &Common,
    frames: &[usize],
    outputs: Vec<FrameOutput>,
    top: Value,
) -> Result<ExitCode> {
    let dir = out_dir(&c.out)?;
    let tree = &s.model.model.tree;
    let report_path = dir.join(format!("{verb}.json"));
    let mut text = String::new();
    let mut frames_json = Vec::new();
    for (o, &i) in outputs.iter().zip(frames) {
        let stem = &s.capture.frames[i].stem;
        let sheet = dir.join(format!("{verb}_sheet_{stem}.png"));
        save_png_rgb(
            &candidate_sheet(s, i, &o.rows, c.sheet, &format!("{verb} {}", o.frame))?,
            &sheet,
        )?;
        text.push_str(&text_report(
            verb,
            &o.frame,
            &o.rows,
            s.scale(),
            tree,
            &o.notes,
            &report_path,
            &c.session.poses,
        ));
        text.push('\n');
        frames_json.push(json!({
            "frame": o.frame, "sheet": sheet, "notes": o.notes, "search": o.extra,
            "ranked": o.rows.iter().map(|r| row_json(r, s.scale(), tree)).collect::<Vec<_>>(),
        }));
    }
    let gates: Vec<f64> = outputs
        .iter()
        .filter_map(|o| o.rows.first().map(|r| r.score.gate))
        .collect();
    let report = json!({
        "verb": verb, "capture": c.session.capture, "model": c.session.model, "poses": c.session.poses, "scale": s.scale(),
        "depth_weight": c.depth_weight, "frames": frames_json,
        "mean_gate_iou": gates.iter().sum::<f64>() / gates.len().max(1) as f64,
        "min_gate_iou": gates.iter().copied().fold(f64::INFINITY, f64::min),
        "details": top,
        "command": std::env::args().collect::<Vec<_>>().join(" "),
    });
    agentstar_data::atomic::write_json(&report_path, &report)?;
    agentstar_data::atomic::write_atomic(&dir.join(format!("{verb}.txt")), text.as_bytes())?;
    if c.json {
        print_json(&report)?;
    } else {
        print!("{text}");
        println!(
            "report: {} (and {verb}.txt, {verb}_sheet_*.png)",
            report_path.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Frame `i`'s problem around `base`, scoring against `inputs` (from [`Session::target`]).
fn problem_for<'a>(
    s: &'a Session,
    i: usize,
    inputs: &'a FrameInputs,
    w: f64,
    base: GenPose,
) -> FrameProblem<'a> {
    let mut p = FrameProblem::new(
        &s.model.model,
        s.capture.frames[i].camera,
        &inputs.0,
        s.scale(),
        base,
    );
    p.depth = inputs.1.as_ref();
    p.depth_weight = w;
    p
}

fn rows_from(result: SweepResult, space: &SearchSpace, tree: &KinematicTree) -> Vec<Row> {
    result
        .ranked
        .into_iter()
        .map(|c| Row {
            rank: c.rank,
            label: order_string(space, &c.x, tree),
            extra: json!({"restart": c.restart, "seed": c.seed, "pass": c.pass, "x": c.x}),
            pose: c.pose,
            score: c.score,
        })
        .collect()
}

fn default_frame(s: &Session, spec: Option<&str>) -> Result<Vec<usize>> {
    match spec {
        None => Ok(vec![s.capture.ref_index]),
        Some(sp) => select_frames(&s.capture, Some(sp)),
    }
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
        "grid" => Strategy::Grid {
            default_steps: a.steps,
            refine: a.refine,
            shrink: a.shrink,
        },
        o => bail!("unknown strategy `{o}`; use de or grid"),
    };
    let cfg = SweepConfig {
        strategy,
        restarts: a.restarts,
        total_evals: a.evals,
        seed: a.seed,
        polish_evals: a.polish,
        topk: a.topk,
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
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows: rows_from(r, &space, tree),
            extra,
            notes,
        });
    }
    write_outputs("sweep", &s, &a.common, &frames, outputs, json!({}))
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
                }
            })
            .collect();
        rows.sort_by(|x, y| y.score.combined.total_cmp(&x.score.combined));
        for (k, r) in rows.iter_mut().enumerate() {
            r.rank = k;
        }
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows,
            extra: json!({"method": "candidates", "n": orders.len()}),
            notes: vec![],
        });
    }
    write_outputs("sweep", s, &a.common, &frames, outputs, json!({}))
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
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows: rows_from(r, &space, tree),
            extra: json!({"method": "apply", "order": a.order}),
            notes: space.notes.clone(),
        });
    }
    write_outputs("apply", &s, &a.common, &frames, outputs, json!({}))
}

/// Rotation-vector candidates from an object preset.
fn opreset_candidates(spec: &str, seed: u64) -> Result<Vec<(String, [f64; 3])>> {
    let spec = spec.trim();
    if let Some(n) = spec.strip_prefix("so3:") {
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| anyhow!("`{spec}`: so3:N needs a whole number N"))?;
        let mut rng = agentstar_optim::Rng::new(seed);
        let mut v = vec![("identity".to_string(), [0.0; 3])];
        for k in 0..n {
            let q = UnitQuaternion::from_quaternion(agentstar_geom::nalgebra::Quaternion::new(
                rng.normal(),
                rng.normal(),
                rng.normal(),
                rng.normal(),
            ));
            let r = q.scaled_axis().map(f64::to_degrees);
            v.push((format!("so3#{k}"), [r.x, r.y, r.z]));
        }
        return Ok(v);
    }
    let mut per_axis: Vec<(usize, Vec<f64>)> = Vec::new();
    for term in spec.split(';').map(str::trim).filter(|t| !t.is_empty()) {
        let (axis, val) = term.split_once(':').ok_or_else(|| anyhow!("`{term}`: expected `axis:preset`, e.g. `z:flip`, `z:quarters`, `z:0,90,180`, `so3:24`"))?;
        let ax = match axis.trim() {
            "x" | "rx" => 0,
            "y" | "ry" => 1,
            "z" | "rz" => 2,
            o => bail!("`{term}`: axis `{o}` must be x, y or z"),
        };
        let values: Vec<f64> = match val.trim() {
            "flip" => vec![0.0, 180.0],
            "quarters" => vec![0.0, 90.0, 180.0, 270.0],
            "octants" => (0..8).map(|k| 45.0 * k as f64).collect(),
            "full" => (0..12).map(|k| -180.0 + 30.0 * k as f64).collect(),
            p if agentstar_track::space::preset_half_span(p).is_some() => {
                let h = agentstar_track::space::preset_half_span(p).unwrap_or(15.0);
                vec![-h, -h / 2.0, 0.0, h / 2.0, h]
            }
            list => list
                .split(',')
                .map(|t| {
                    t.trim()
                        .parse::<f64>()
                        .map_err(|_| anyhow!("`{term}`: `{t}` is not an angle"))
                })
                .collect::<Result<_>>()?,
        };
        per_axis.push((ax, values));
    }
    let mut out: Vec<(String, [f64; 3])> = vec![(String::new(), [0.0; 3])];
    for (ax, values) in per_axis {
        out = out
            .into_iter()
            .flat_map(|(l, r)| {
                values.iter().map(move |&v| {
                    let mut r2 = r;
                    r2[ax] = v;
                    (format!("{l}{}{:+04}", ["rx", "ry", "rz"][ax], v as i64), r2)
                })
            })
            .collect();
    }
    for o in &mut out {
        if o.1 == [0.0; 3] {
            o.0 = "identity".into();
        }
    }
    out.dedup_by(|a, b| a.1 == b.1);
    Ok(out)
}

pub fn run_osweep(a: OsweepArgs) -> Result<ExitCode> {
    let s = a.common.session.open()?;
    let tree = &s.model.model.tree;
    let frames = select_frames(&s.capture, a.frames.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "osweep").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let p = problem_for(&s, i, &inputs, a.common.depth_weight, s.gen_pose(i));
        let (space, cfg) = if let Some(pre) = &a.opreset {
            let cands = opreset_candidates(pre, 0x5EED)?;
            let space = SearchSpace {
                ranges: [Dof::Rx, Dof::Ry, Dof::Rz]
                    .into_iter()
                    .map(|d| DofRange {
                        dof: d,
                        lo: -360.0,
                        hi: 360.0,
                        steps: None,
                    })
                    .collect(),
                notes: vec![],
            };
            (
                space,
                SweepConfig {
                    strategy: Strategy::Candidates(cands.iter().map(|c| c.1.to_vec()).collect()),
                    topk: a.topk,
                    ..SweepConfig::default()
                },
            )
        } else {
            let space = build_space(a.ranges.as_deref(), None, tree, Grammar::Object)?;
            (
                space,
                SweepConfig {
                    strategy: Strategy::Grid {
                        default_steps: a.steps,
                        refine: a.refine,
                        shrink: a.shrink,
                    },
                    topk: a.topk,
                    ..SweepConfig::default()
                },
            )
        };
        let r = sweep(&p, &space, &cfg)?;
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows: rows_from(r, &space, tree),
            extra: json!({"method": "osweep", "space": space_json(&space, tree)}),
            notes: space.notes.clone(),
        });
    }
    write_outputs("osweep", &s, &a.common, &frames, outputs, json!({}))
}

/// Parses a candidate set: `identity|flip:x|rz:90;rx:10`, `flips`.
fn rotation_set(spec: &str) -> Result<Vec<(String, UnitQuaternion)>> {
    let expanded = spec.replace("flips", "identity|flip:x|flip:y|flip:z");
    let mut out: Vec<(String, UnitQuaternion)> = Vec::new();
    for cand in expanded.split('|').map(str::trim).filter(|c| !c.is_empty()) {
        let q = parse_rotation(cand)?;
        if !out.iter().any(|(_, o)| o.angle_to(&q) < 1e-9) {
            out.push((cand.to_string(), q));
        }
    }
    if out.is_empty() {
        bail!("the candidate set is empty; e.g. `identity|flip:x|rz:90`");
    }
    Ok(out)
}

fn parse_rotation(cand: &str) -> Result<UnitQuaternion> {
    if cand == "identity" {
        return Ok(UnitQuaternion::identity());
    }
    if let Some(ax) = cand.strip_prefix("flip:") {
        let c = ax.trim().chars().next().unwrap_or(' ');
        return flip(c).ok_or_else(|| anyhow!("`{cand}`: flip axis must be x, y or z"));
    }
    let mut r = [0.0; 3];
    for term in cand.split(';').map(str::trim).filter(|t| !t.is_empty()) {
        let (k, v) = term.split_once(':').ok_or_else(|| {
            anyhow!("`{term}`: expected `rx:deg`, `ry:deg`, `rz:deg`, `flip:x` or `identity`")
        })?;
        let idx = match k.trim() {
            "rx" => 0,
            "ry" => 1,
            "rz" => 2,
            o if ["roll", "yaw", "pitch", "dpx", "dpy", "tz"].contains(&o) => {
                bail!("`{o}` is a camera-frame increment; use sweep/apply for it")
            }
            o => bail!("`{o}` is not an object-frame axis (rx, ry, rz)"),
        };
        r[idx] = v
            .trim()
            .parse::<f64>()
            .map_err(|_| anyhow!("`{term}`: `{v}` is not an angle"))?;
    }
    Ok(rotation_vector_deg(r))
}

pub fn run_oapply(a: OapplyArgs) -> Result<ExitCode> {
    let s = a.common.session.open()?;
    let set = rotation_set(&a.set)?;
    let frames = select_frames(&s.capture, a.frames.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "oapply").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let p = problem_for(&s, i, &inputs, a.common.depth_weight, s.gen_pose(i));
        let mut ev = p.evaluator();
        let mut rows: Vec<Row> = set
            .iter()
            .map(|(label, q)| {
                let pose = apply_object_rotation(&p.base.pose, s.scale(), &p.pivot, q);
                let g = GenPose {
                    pose,
                    states: p.base.states.clone(),
                };
                let score = ev.score(&g);
                Row {
                    rank: 0,
                    label: label.clone(),
                    pose: g,
                    score,
                    extra: json!({}),
                }
            })
            .collect();
        rows.sort_by(|x, y| y.score.combined.total_cmp(&x.score.combined));
        for (k, r) in rows.iter_mut().enumerate() {
            r.rank = k;
        }
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows,
            extra: json!({"method": "oapply", "set": a.set}),
            notes: vec![],
        });
    }
    write_outputs("oapply", &s, &a.common, &frames, outputs, json!({}))
}

pub fn run_oapply_all(a: OapplyAllArgs) -> Result<ExitCode> {
    let s = a.common.session.open()?;
    let q = parse_rotation(a.rotation.trim()).context("--rotation")?;
    let frames = select_frames(&s.capture, a.frames.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "oapply-all").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let p = problem_for(&s, i, &inputs, a.common.depth_weight, s.gen_pose(i));
        // About the canonical origin: translation unchanged.
        let pose = apply_object_rotation(&p.base.pose, s.scale(), &Point3::origin(), &q);
        let g = GenPose {
            pose,
            states: p.base.states.clone(),
        };
        let score = p.evaluator().score(&g);
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows: vec![Row {
                rank: 0,
                label: a.rotation.clone(),
                pose: g,
                score,
                extra: json!({}),
            }],
            extra: json!({"method": "oapply_all"}),
            notes: vec![],
        });
    }
    let r = q.scaled_axis().map(f64::to_degrees);
    write_outputs(
        "oapply_all",
        &s,
        &a.common,
        &frames,
        outputs,
        json!({"shared_rotation": {"rx": r.x, "ry": r.y, "rz": r.z, "quaternion": [q.w, q.i, q.j, q.k]}}),
    )
}
