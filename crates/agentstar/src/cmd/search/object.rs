//! `osweep`, `oapply` and `oapply-all`: object-frame rotations per frame (presets, grids,
//! rotation sets) and one shared rotation for every frame, with their grammars.

use super::*;
use crate::common::OpenSession as _;
use agentstar_requests as requests;

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar osweep --capture cap --model run/scene.rhai --poses run/pose.json --out reports --frames 000010 --opreset z:flip"
)]
pub struct OsweepArgs {
    #[command(flatten)]
    common: Common,
    /// Where to search (the `osweep` tool's arguments). Presets: `z:flip`, `z:quarters`,
    /// `z:octants`, `z:full`, `z:0,90,180`, `z:large`, or `so3:N` (identity plus N uniform
    /// rotations).
    #[command(flatten)]
    request: requests::OsweepArgs,
    #[command(flatten)]
    grid: GridArgs,
    /// Ranked candidates kept per frame.
    #[arg(long, default_value_t = 10)]
    topk: usize,
    /// Rank the candidates as placed, without refining each locally first.
    #[arg(long)]
    no_refine: bool,
}

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar oapply --capture cap --model run/scene.rhai --poses run/pose.json --out reports --frames 000010 --set flips"
)]
pub struct OapplyArgs {
    #[command(flatten)]
    common: Common,
    /// What to score (the `oapply` tool's arguments; the set defaults to `flips|swaps`).
    /// rx/ry/rz terms make one rotation vector (degrees); a flip splits a candidate into
    /// factors applied left to right about the turned object axes. Each candidate turns the
    /// object about its box centre (at the frame's joint states). `swaps`: for each revolute
    /// joint, the half-turn through the hinge that puts each of its two sides where the other
    /// was, labelled `swap:JOINT`; none for a rigid model.
    #[command(flatten)]
    request: requests::OapplyArgs,
    /// Rank the candidates as placed, without refining each locally first.
    #[arg(long)]
    no_refine: bool,
}

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar oapply-all --capture cap --model run/scene.rhai --poses run/pose.json --out reports --rotation 'flip:x'"
)]
pub struct OapplyAllArgs {
    #[command(flatten)]
    common: Common,
    /// The rotation and the frames (the `oapply_all` tool's arguments). The rotation turns
    /// every frame about the canonical origin (the translation is kept).
    #[command(flatten)]
    request: requests::OapplyAllArgs,
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

/// How far apart the grid points that `osweep` adds as runners-up lie (rotation, or a
/// joint): past the reach of the refinement that follows ([`LocalWindow::basin`]: 25°), so
/// that each refines to a basin of its own.
const OSWEEP_BASIN_APART_DEG: f64 = 30.0;

/// The window each candidate of `osweep` and `oapply` is refined in: the basin's, or, held,
/// the basin's position and joints with the rotation kept near the turn asked (the
/// window's bound is about each of three axes; [`requests::OapplyArgs::HOLD_TURN_DEG`]).
fn refine_window(hold: bool) -> LocalWindow {
    if hold {
        LocalWindow {
            angle_deg: requests::OapplyArgs::HOLD_TURN_DEG / 3f64.sqrt(),
            ..LocalWindow::basin()
        }
    } else {
        LocalWindow::basin()
    }
}

pub fn run_osweep(a: OsweepArgs) -> Result<ExitCode> {
    // One of --opreset and --ranges (the rule the `osweep` tool checks too).
    let region = a.request.region().map_err(|e| anyhow!(e))?;
    let s = a.common.session.open()?;
    let tree = &s.model.model.tree;
    let frames = select_frames(&s.capture, a.request.frames.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "osweep").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let p = problem_for(&s, i, &inputs, a.common.depth_weight, s.gen_pose(i));
        let (space, cfg) = if let requests::Region::Preset(pre) = region {
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
                    // Every candidate of the preset is ranked (and drawn).
                    topk: a.topk.max(cands.len()),
                    strategy: Strategy::Candidates(cands.iter().map(|c| c.1.to_vec()).collect()),
                    ..SweepConfig::default()
                },
            )
        } else {
            let space = build_space(a.request.ranges.as_deref(), None, tree, Grammar::Object)?;
            (
                space,
                SweepConfig {
                    strategy: a.grid.strategy(),
                    topk: a.topk,
                    // The grid's best points lie around one basin, and refined they end at
                    // its optimum (play-test, 2026-12-05: every row of a whole-turn grid
                    // within 38° of the frame's pose): as many again of its best points a
                    // refinement's reach from those and from each other, one per basin.
                    runners_up: if a.no_refine { 0 } else { a.topk },
                    runner_up_deg: OSWEEP_BASIN_APART_DEG,
                    ..SweepConfig::default()
                },
            )
        };
        let mut r = sweep(&p, &space, &cfg)?;
        let mut notes = space.notes.clone();
        if !a.no_refine {
            let placed = r.ranked.len();
            r = refine_ranked(&p, r, &refine_window(a.request.hold), 17)?;
            let merged = placed - r.ranked.len();
            if merged > 0 {
                notes.push(format!(
                    "{merged} candidate(s) refined to the pose of a better-ranked one and are listed once, under its start"
                ));
            }
        }
        let mut rows = rows_from(r, &space, tree);
        annotate(&s, i, &mut rows)?;
        let order = a.request.order.unwrap_or_default();
        order_rows(&mut rows, order);
        notes.extend(order_note(order));
        if !a.no_refine {
            // Each row names its grid start and where the refinement took it.
            for row in &mut rows {
                row.label = format!("{} → {}", row.label, refined_to(&p.base, &row.pose, tree));
            }
        }
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows,
            extra: json!({"method": "osweep", "space": space_json(&space, tree), "hold": a.request.hold}),
            notes,
            pages: vec![],
            // Every candidate of a preset or a set is drawn.
            draw_all: a.request.opreset.is_some(),
        });
    }
    write_outputs(
        SearchVerb::Osweep,
        &s,
        &a.common,
        &frames,
        outputs,
        json!({}),
    )
}

/// The rows in `order`, ranked again from 0 ([`requests::RowOrder`]): by the mask they come
/// ranked already; by the model's colours, the best figure first, rows without one last,
/// ties kept in the mask's order (play-test 15: an `so3:24` osweep put the basin its print
/// settled at rank 7 of 25, behind twins whose outlines scored better).
fn order_rows(rows: &mut [Row], order: requests::RowOrder) {
    if order == requests::RowOrder::Model {
        rows.sort_by(|a, b| {
            let key = |r: &Row| r.model_ncc.unwrap_or(f64::NEG_INFINITY);
            key(b).total_cmp(&key(a))
        });
    }
    for (k, r) in rows.iter_mut().enumerate() {
        r.rank = k;
    }
}

/// The note of a frame whose rows are not in the mask's order.
fn order_note(order: requests::RowOrder) -> Option<String> {
    (order == requests::RowOrder::Model).then(|| {
        "rows ranked by the model's colours (`model`, best first; the mask's IoU is each row's own): commit by the rank shown here".to_string()
    })
}

/// Where a refined candidate ended, relative to the frame's pose: its object-frame rotation
/// as one rotation vector (`rx:…;ry:…;rz:…`, degrees, as `oapply` reads it) and its final
/// joint states (interface units), then in brackets the whole turn as an angle about an
/// object axis and the named turn it is near, if any (not part of the order: copy up to the
/// bracket). Play-test: an `oapply` row labelled `rz:-135` whose refinement ended 180° away
/// moved the print by 180° when committed.
fn refined_to(base: &GenPose, pose: &GenPose, tree: &KinematicTree) -> String {
    let q = base.pose.rotation.inverse() * pose.pose.rotation;
    let turn = q.scaled_axis().map(f64::to_degrees);
    let mut out = format!("rx:{:.1};ry:{:.1};rz:{:.1}", turn.x, turn.y, turn.z);
    for (name, value) in tree.states_to_interface(&pose.states) {
        out.push_str(&format!(";{name}:{value:.1}"));
    }
    let angle = q.angle().to_degrees();
    let about = match q.axis() {
        Some(a) if angle >= 0.05 => {
            format!("{angle:.0}° about ({:.2}, {:.2}, {:.2})", a.x, a.y, a.z)
        }
        _ => "no turn".to_string(),
    };
    match nearest_named_turn(&q) {
        Some((name, deg)) => out.push_str(&format!(" [{about}; ≈ {name}, {deg:.0}° from it]")),
        None => out.push_str(&format!(" [{about}]")),
    }
    out
}

/// A refined candidate within this of the identity or of a half-turn about a canonical axis
/// is labelled with it (play-test 9 worked out by hand which `so3:24` row was the flip).
const NAMED_TURN_DEG: f64 = 20.0;

/// The named turn (`identity`, `flip:x`, `flip:y`, `flip:z`) nearest `turn`, and how far
/// from it, if within [`NAMED_TURN_DEG`].
fn nearest_named_turn(turn: &UnitQuaternion) -> Option<(&'static str, f64)> {
    [
        ("identity", UnitQuaternion::identity()),
        ("flip:x", flip('x')?),
        ("flip:y", flip('y')?),
        ("flip:z", flip('z')?),
    ]
    .into_iter()
    .map(|(name, q)| (name, q.angle_to(turn).to_degrees()))
    .filter(|&(_, deg)| deg <= NAMED_TURN_DEG)
    .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// One candidate of a set: its label, the rotation about the box centre, and the joint
/// states it sets (joint index, internal units).
type SetCandidate = (String, UnitQuaternion, Vec<(usize, f64)>);

/// A parsed candidate set: rotations about the box centre (each with the joint states it
/// sets), and whether the hinge swaps (`swaps`) are in it.
struct RotationSet {
    rotations: Vec<SetCandidate>,
    swaps: bool,
    /// The turns of the model's n-fold outline (`folds`).
    folds: bool,
}

/// Parses a candidate set of the model with joints `tree`: `identity|flip:x|rz:90;rx:10`,
/// `flips`, `swaps`, and joint terms in a candidate (`flip:x;hinge:115`).
fn rotation_set(spec: &str, tree: &KinematicTree) -> Result<RotationSet> {
    let expanded = spec.replace("flips", "identity|flip:x|flip:y|flip:z");
    let mut out: Vec<SetCandidate> = Vec::new();
    let (mut swaps, mut folds) = (false, false);
    for cand in expanded.split('|').map(str::trim).filter(|c| !c.is_empty()) {
        if cand == "swaps" {
            swaps = true;
            continue;
        }
        if cand == "folds" {
            folds = true;
            continue;
        }
        let (q, joints) = parse_candidate(cand, tree)?;
        if !out
            .iter()
            .any(|(_, o, j)| o.angle_to(&q) < 1e-9 && *j == joints)
        {
            out.push((cand.to_string(), q, joints));
        }
    }
    if out.is_empty() && !swaps && !folds {
        bail!("the candidate set is empty; e.g. `identity|flip:x|rz:90`");
    }
    Ok(RotationSet {
        rotations: out,
        swaps,
        folds,
    })
}

/// One candidate of `oapply`: a rotation ([`parse_rotation`]) with terms `JOINT:value` among
/// its terms that set a joint of `tree` (interface units: degrees, or canonical units for a
/// prismatic joint; within its limits): `flip:x;hinge:115` is the flip about x with the hinge
/// at 115°, `hinge:40` the pose as it is with the hinge at 40°. The joint states come back
/// in internal units, by joint index.
fn parse_candidate(
    cand: &str,
    tree: &KinematicTree,
) -> Result<(UnitQuaternion, Vec<(usize, f64)>)> {
    let mut joints: Vec<(usize, f64)> = Vec::new();
    let mut rotation_terms: Vec<&str> = Vec::new();
    for term in cand.split(';').map(str::trim).filter(|t| !t.is_empty()) {
        let joint = term.split_once(':').and_then(|(k, v)| {
            let j = tree.joint_index(k.trim())?;
            Some((j, k.trim(), v.trim()))
        });
        let Some((j, name, v)) = joint else {
            rotation_terms.push(term);
            continue;
        };
        let value = v
            .parse::<f64>()
            .map_err(|_| anyhow!("`{term}`: `{v}` is not a joint state"))?;
        let internal = tree
            .state_from_interface(j, value)
            .map_err(|e| anyhow!("`{term}`: {e}"))?;
        if joints.iter().any(|(k, _)| *k == j) {
            bail!("`{cand}`: joint `{name}` is set twice");
        }
        joints.push((j, internal));
    }
    // A term that is neither a rotation nor a joint: say which joints there are.
    for term in &rotation_terms {
        let key = term.split_once(':').map_or(*term, |(k, _)| k).trim();
        // (Camera-frame increments get parse_rotation's own hint.)
        let known = ["identity", "flip", "rx", "ry", "rz"];
        let camera = ["roll", "yaw", "pitch", "dpx", "dpy", "tz"];
        if !known.contains(&key) && !camera.contains(&key) {
            let joints = tree.moving_joint_names();
            bail!(
                "`{term}`: `{key}` is not an object-frame rotation (identity, flip:x|y|z, rx, ry, rz) or a joint ({})",
                if joints.is_empty() {
                    "the model has none".to_string()
                } else {
                    joints.join(", ")
                }
            );
        }
    }
    let q = if rotation_terms.is_empty() {
        UnitQuaternion::identity()
    } else {
        parse_rotation(&rotation_terms.join(";"))?
    };
    Ok((q, joints))
}

/// One candidate rotation: `identity`, `flip:x|y|z` (180°), `rx`/`ry`/`rz` terms in degrees,
/// or a compound of them separated by `;`. Consecutive `rx`/`ry`/`rz` terms make one
/// rotation vector (`rz:90;rx:10` is the vector (10, 0, 90)°, not two turns); a `flip`
/// term splits the candidate into factors applied left to right, each about the object's
/// axes as the factors before it have turned them: `flip:y;rz:30` is the flip about y, then
/// 30° about the flipped z. The product right-multiplies the pose's rotation.
fn parse_rotation(cand: &str) -> Result<UnitQuaternion> {
    let mut total = UnitQuaternion::identity();
    let mut vector = [0.0; 3];
    let mut given = [false; 3];
    let mut any = false;
    let flush = |total: &mut UnitQuaternion, vector: &mut [f64; 3], given: &mut [bool; 3]| {
        if given.iter().any(|g| *g) {
            *total *= rotation_vector_deg(*vector);
        }
        *vector = [0.0; 3];
        *given = [false; 3];
    };
    for term in cand.split(';').map(str::trim).filter(|t| !t.is_empty()) {
        any = true;
        if term == "identity" {
            continue;
        }
        let (k, v) = term.split_once(':').ok_or_else(|| {
            anyhow!("`{term}`: expected `rx:deg`, `ry:deg`, `rz:deg`, `flip:x` or `identity`")
        })?;
        let idx = match k.trim() {
            "flip" => {
                let axis = v.trim();
                let q = match axis {
                    "x" | "y" | "z" | "X" | "Y" | "Z" => axis.chars().next().and_then(flip),
                    _ => None,
                }
                .ok_or_else(|| anyhow!("`{term}`: flip axis must be x, y or z"))?;
                flush(&mut total, &mut vector, &mut given);
                total *= q;
                continue;
            }
            "rx" => 0,
            "ry" => 1,
            "rz" => 2,
            o if ["roll", "yaw", "pitch", "dpx", "dpy", "tz"].contains(&o) => {
                bail!("`{o}` is a camera-frame increment; use sweep/apply for it")
            }
            o => bail!("`{o}` is not an object-frame axis (rx, ry, rz) or `flip`"),
        };
        if given[idx] {
            bail!(
                "`{cand}`: `{}` is given twice in one rotation vector; write one value (or separate them with a flip)",
                ["rx", "ry", "rz"][idx]
            );
        }
        let deg = v
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|d| d.is_finite())
            .ok_or_else(|| anyhow!("`{term}`: `{v}` is not an angle"))?;
        vector[idx] = deg;
        given[idx] = true;
    }
    if !any {
        bail!("`{cand}`: an empty rotation; e.g. `identity`, `flip:x`, `rz:90;rx:10`");
    }
    flush(&mut total, &mut vector, &mut given);
    Ok(total)
}

/// The turns of one n-fold axis of the model's outline as `oapply` candidates, about the
/// axis through the section's centroid: `fold4:turn:90` (a quarter turn about the axis),
/// `fold4:across:45` (the half-turn about the direction across it at 45° from the first of
/// them).
fn fold_moves(fold: &agentstar_track::symmetry::Fold) -> Vec<(SetCandidate, Point3)> {
    let n = fold.order;
    fold.turns()
        .into_iter()
        .enumerate()
        .map(|(k, (q, c))| {
            let label = if k + 1 < n {
                format!("fold{n}:turn:{}", fmt6(360.0 * (k + 1) as f64 / n as f64))
            } else {
                format!(
                    "fold{n}:across:{}",
                    fmt6(180.0 * (k + 1 - n) as f64 / n as f64)
                )
            };
            ((label, q, vec![]), c)
        })
        .collect()
}

pub fn run_oapply(a: OapplyArgs) -> Result<ExitCode> {
    let s = a.common.session.open()?;
    let set = rotation_set(a.request.set(), &s.model.model.tree)?;
    let frames = select_frames(&s.capture, a.request.frames.as_deref())?;
    let mut outputs = Vec::new();
    for &i in progress(frames.len(), "oapply").wrap_iter(frames.iter()) {
        let inputs = s.target(i)?;
        let p = problem_for(&s, i, &inputs, a.common.depth_weight, s.gen_pose(i));
        let mut ev = p.evaluator();
        // The rotations about the box centre, then the hinge swaps about their hinges.
        let mut moves: Vec<(SetCandidate, Point3)> =
            set.rotations.iter().map(|c| (c.clone(), p.pivot)).collect();
        if set.swaps {
            let tree = &s.model.model.tree;
            moves.extend(
                hinge_swaps(&s.model.model, &p.base.states)
                    .into_iter()
                    .map(|(j, q, c)| ((format!("swap:{}", tree.joints()[j].name), q, vec![]), c)),
            );
        }
        if set.folds {
            for fold in agentstar_track::symmetry::folds(&s.model.model, &p.base.states) {
                moves.extend(fold_moves(&fold));
            }
        }
        if moves.is_empty() {
            bail!(
                "`{}`: the model has no revolute joint to swap the sides of nor an n-fold outline to turn, and the set names no other rotation; e.g. `flips|swaps|folds`",
                a.request.set()
            );
        }
        let mut rows: Vec<Row> = moves
            .iter()
            .map(|((label, q, joints), centre)| {
                let pose = apply_object_rotation(&p.base.pose, s.scale(), centre, q);
                let mut states = p.base.states.clone();
                for &(j, v) in joints {
                    states[j] = v;
                }
                let g = GenPose { pose, states };
                let score = ev.score(&g);
                Row {
                    rank: 0,
                    label: label.clone(),
                    pose: g,
                    score,
                    extra: json!({}),
                    model_ncc: None,
                    neighbour_steps: vec![],
                    outside_region: vec![],
                }
            })
            .collect();
        if !a.no_refine {
            let placed: Vec<GenPose> = rows.iter().map(|r| r.pose.clone()).collect();
            let window = refine_window(a.request.hold);
            for (r, f) in rows.iter_mut().zip(refine_each(&p, &placed, &window, 17)?) {
                r.extra = json!({"unrefined": f.unrefined.combined});
                (r.pose, r.score) = (f.pose, f.score);
            }
        }
        rows.sort_by(|x, y| y.score.combined.total_cmp(&x.score.combined));
        for (k, r) in rows.iter_mut().enumerate() {
            r.rank = k;
            // The candidate as asked, then where it ended (refined or as placed): its turn
            // from the frame's pose and its final joint states.
            r.label = format!(
                "{} → {}",
                r.label,
                refined_to(&p.base, &r.pose, &s.model.model.tree)
            );
        }
        annotate(&s, i, &mut rows)?;
        let order = a.request.order.unwrap_or_default();
        order_rows(&mut rows, order);
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows,
            extra: json!({"method": "oapply", "set": a.request.set(), "hold": a.request.hold}),
            notes: order_note(order).into_iter().collect(),
            pages: vec![],
            // Every candidate of a preset or a set is drawn.
            draw_all: true,
        });
    }
    write_outputs(
        SearchVerb::Oapply,
        &s,
        &a.common,
        &frames,
        outputs,
        json!({}),
    )
}

pub fn run_oapply_all(a: OapplyAllArgs) -> Result<ExitCode> {
    let s = a.common.session.open()?;
    let q = parse_rotation(a.request.rotation.trim()).context("--rotation")?;
    let frames = select_frames(&s.capture, a.request.frames.as_deref())?;
    let mut outputs = Vec::new();
    // The temporal steps before the rotation, and the samples it will change.
    let before = crate::cmd::temporal::samples(&s);
    let mut after = before.clone();
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
        after[i].pose = g.pose;
        outputs.push(FrameOutput {
            frame: s.capture.frames[i].name.clone(),
            rows: vec![Row {
                rank: 0,
                label: a.request.rotation.clone(),
                pose: g,
                score,
                extra: json!({}),
                model_ncc: None,
                neighbour_steps: vec![],
                outside_region: vec![],
            }],
            extra: json!({"method": "oapply_all"}),
            notes: vec![],
            pages: vec![],
            // Every candidate of a preset or a set is drawn.
            draw_all: false,
        });
    }
    // Where the rotated frames meet the others, the step before and after it: turning a
    // block of frames moves a large step to its edges, or removes it (play-test 8 committed
    // and restored by hand to see this).
    let tree = &s.model.model.tree;
    let rows_before = agentstar_track::temporal::report(&before, s.scale(), tree).rows;
    let rows_after = agentstar_track::temporal::report(&after, s.scale(), tree).rows;
    let chosen: Vec<bool> = (0..s.capture.frames.len())
        .map(|i| frames.contains(&i))
        .collect();
    for k in 1..chosen.len() {
        if chosen[k] == chosen[k - 1] {
            continue;
        }
        let (Some(was), Some(now)) = (rows_before[k].vel_rot_deg, rows_after[k].vel_rot_deg) else {
            continue;
        };
        let inside = if chosen[k] { k } else { k - 1 };
        let name = &s.capture.frames[inside].name;
        if let Some(o) = outputs.iter_mut().find(|o| &o.frame == name) {
            o.notes.push(format!(
                "step {} -> {}: {was:.0}° now, {now:.0}° with this rotation",
                s.capture.frames[k - 1].name,
                s.capture.frames[k].name
            ));
        }
    }
    let r = q.scaled_axis().map(f64::to_degrees);
    write_outputs(
        SearchVerb::OapplyAll,
        &s,
        &a.common,
        &frames,
        outputs,
        json!({"shared_rotation": {"rx": r.x, "ry": r.y, "rz": r.z, "quaternion": [q.w, q.i, q.j, q.k]}}),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    use agentstar_geom::Vector3;

    #[test]
    fn an_n_fold_axis_gives_its_turns_and_half_turns_labelled_by_angle() {
        let fold = agentstar_track::symmetry::Fold {
            axis: Vector3::z(),
            centre: Point3::new(0.1, 0.0, 0.0),
            order: 4,
            across: Vector3::x(),
        };
        let moves = fold_moves(&fold);
        let labels: Vec<&str> = moves.iter().map(|((l, _, _), _)| l.as_str()).collect();
        assert_eq!(
            labels,
            [
                "fold4:turn:90",
                "fold4:turn:180",
                "fold4:turn:270",
                "fold4:across:0",
                "fold4:across:45",
                "fold4:across:90",
                "fold4:across:135"
            ]
        );
        let ((_, quarter, _), centre) = &moves[0];
        assert!((quarter * Vector3::x() - Vector3::y()).norm() < 1e-12);
        assert_eq!(*centre, fold.centre);
        let ((_, diagonal, _), _) = &moves[4];
        let axis = Vector3::new(1.0, 1.0, 0.0).normalize();
        assert!((diagonal * axis - axis).norm() < 1e-12);
        assert!((diagonal.angle() - std::f64::consts::PI).abs() < 1e-9);
    }

    #[test]
    fn flips_compose_with_rotation_vectors_in_a_compound_candidate() {
        let close = |a: &UnitQuaternion, b: &UnitQuaternion| a.angle_to(b) < 1e-9;
        let fy = flip('y').expect("axis");
        // The documented compound: a flip then a turn about the flipped axes.
        let q = parse_rotation("flip:y;rz:30").expect("parses");
        assert!(close(&q, &(fy * rotation_vector_deg([0.0, 0.0, 30.0]))));
        let q = parse_rotation("rz:90;flip:y;rx:10").expect("parses");
        assert!(close(
            &q,
            &(rotation_vector_deg([0.0, 0.0, 90.0]) * fy * rotation_vector_deg([10.0, 0.0, 0.0]))
        ));
        // rx/ry/rz together are one rotation vector, as before.
        let q = parse_rotation("rz:90;rx:10").expect("parses");
        assert!(close(&q, &rotation_vector_deg([10.0, 0.0, 90.0])));
        assert!(close(
            &parse_rotation("identity").expect("id"),
            &UnitQuaternion::identity()
        ));
        for bad in [
            "flip:w",
            "flip:yy",
            "rx:10;rx:5",
            "yaw:10",
            "rx:abc",
            "rx:NaN",
            "",
            "flip",
        ] {
            assert!(parse_rotation(bad).is_err(), "{bad}");
        }
        // A whole set with flips inside compounds.
        let rigid = KinematicTree::rigid(1);
        let set = rotation_set("identity|flip:x;rz:15|flips", &rigid).expect("set");
        assert_eq!(
            set.rotations.len(),
            5,
            "{:?}",
            set.rotations.iter().map(|s| &s.0).collect::<Vec<_>>()
        );
        assert!(!set.swaps);
        // The hinge swaps alone are a set (of none for a rigid model: the run says so).
        let set = rotation_set("swaps", &rigid).expect("set");
        assert!(set.swaps && !set.folds && set.rotations.is_empty());
        let set = rotation_set("flips|swaps", &rigid).expect("set");
        assert!(set.swaps && set.rotations.len() == 4);
        let set = rotation_set("folds", &rigid).expect("set");
        assert!(set.folds && !set.swaps && set.rotations.is_empty());
        // A joint name is not a rotation of a rigid model.
        assert!(rotation_set("flip:x;hinge:115", &rigid).is_err());
    }

    /// A box with a lid on a hinge limited to [0, 120]°.
    fn hinged() -> KinematicTree {
        let def = agentstar_geom::JointDef {
            name: "hinge".into(),
            kind: agentstar_geom::JointKind::Revolute,
            parent: None,
            child: vec!["lid".into()],
            origin: agentstar_geom::Vector3::zeros(),
            axis: agentstar_geom::Vector3::x(),
            limit: Some((0.0, 120.0)),
        };
        KinematicTree::new(vec![def], &["base".into(), "lid".into()]).expect("tree")
    }

    #[test]
    fn a_candidate_sets_joint_states_beside_its_rotation() {
        let tree = hinged();
        let (q, joints) = parse_candidate("flip:x;hinge:115", &tree).expect("parses");
        assert!(q.angle_to(&flip('x').expect("axis")) < 1e-9);
        assert_eq!(joints.len(), 1);
        assert_eq!(joints[0].0, 0);
        assert!((joints[0].1 - 115f64.to_radians()).abs() < 1e-12);
        // A joint alone keeps the rotation.
        let (q, joints) = parse_candidate("hinge:40", &tree).expect("parses");
        assert!(q.angle_to(&UnitQuaternion::identity()) < 1e-12 && joints.len() == 1);
        // The same rotation with two joint states is two candidates.
        let set = rotation_set("identity|hinge:40|hinge:80|identity", &tree).expect("set");
        assert_eq!(set.rotations.len(), 3);
        for (bad, says) in [
            (
                "flip:x;hinge:150",
                "invalid joint `hinge`: state 150 is outside its limit [0, 120]",
            ),
            ("hinge:NaN", "state NaN is not finite"),
            ("hinge:40;hinge:50", "set twice"),
            ("hinge:wide", "is not a joint state"),
            ("lid:40", "or a joint (hinge)"),
            ("yaw:10", "camera-frame increment"),
        ] {
            let e = parse_candidate(bad, &tree).expect_err(bad).to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn a_refined_turn_near_a_flip_is_named_and_a_far_one_is_not() {
        use agentstar_geom::Vector3;
        let about = |axis: Vector3, deg: f64| {
            UnitQuaternion::from_axis_angle(
                &agentstar_geom::nalgebra::Unit::new_normalize(axis),
                deg.to_radians(),
            )
        };
        let (name, deg) = nearest_named_turn(&about(Vector3::x(), 172.0)).expect("named");
        assert_eq!(name, "flip:x");
        assert!((deg - 8.0).abs() < 1e-6, "{deg}");
        let near_identity = about(Vector3::new(1.0, 1.0, 0.0), 5.0);
        assert_eq!(
            nearest_named_turn(&near_identity).map(|n| n.0),
            Some("identity")
        );
        assert_eq!(nearest_named_turn(&about(Vector3::z(), 90.0)), None);
    }
}
