//! The paper's tables as Markdown, from sequence results: ARCTIC-like 3-D tracking and
//! geometry, HOT3D-like pose tracking, iTACO-like articulation (mean ± std, the published
//! units), the ablation over methods, and wall time per sequence.

use crate::misses::Weighed;
use crate::run::SequenceResult;
use std::fmt::Write;

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn std_dev(v: &[f64]) -> Option<f64> {
    let m = mean(v)?;
    Some((v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt())
}

fn fmt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.digits$}"))
}

/// Method labels in order of first appearance.
/// Four decimals, or three significant digits for small figures (squared Chamfer in m²).
fn sig(x: f64) -> String {
    if x != 0.0 && x.abs() < 0.01 {
        format!("{x:.2e}")
    } else {
        format!("{x:.4}")
    }
}

fn methods(results: &[SequenceResult]) -> Vec<&str> {
    let mut m: Vec<&str> = Vec::new();
    for r in results {
        if !m.contains(&r.info.method.as_str()) {
            m.push(&r.info.method);
        }
    }
    m
}

fn of<'a>(
    results: &'a [SequenceResult],
    family: Option<&'a str>,
    method: &'a str,
) -> impl Iterator<Item = &'a SequenceResult> + 'a {
    results
        .iter()
        .filter(move |r| r.info.method == method && family.is_none_or(|f| r.info.family == f))
}

fn collect(
    results: &[SequenceResult],
    family: Option<&str>,
    method: &str,
    f: impl Fn(&SequenceResult) -> Option<f64>,
) -> Vec<f64> {
    of(results, family, method).filter_map(f).collect()
}

/// Every table, in the order of the paper; `per_sequence` adds a row per sequence.
pub fn tables(results: &[SequenceResult], per_sequence: bool) -> String {
    let mut out = String::new();
    let ms = methods(results);
    let has = |fam: &str| results.iter().any(|r| r.info.family == fam);

    if has("arctic") {
        let _ = writeln!(
            out,
            "### ARCTIC-like: 3-D tracking and geometry (cm)\n\n| method | sequences | 3D EPE (cm) ↓ | Chamfer (cm) ↓ |\n|---|---|---|---|"
        );
        for &m in &ms {
            let n = of(results, Some("arctic"), m).count();
            let _ = writeln!(
                out,
                "| {} | {n} | {} | {} |",
                m,
                fmt(
                    mean(&collect(results, Some("arctic"), m, |r| r.metrics.epe_cm)),
                    2
                ),
                fmt(
                    mean(&collect(results, Some("arctic"), m, |r| r
                        .metrics
                        .chamfer_cm)),
                    2
                )
            );
        }
        if per_sequence {
            for r in results.iter().filter(|r| r.info.family == "arctic") {
                let _ = writeln!(
                    out,
                    "| {} · {} | 1 | {} | {} |",
                    r.info.method,
                    r.info.id,
                    fmt(r.metrics.epe_cm, 2),
                    fmt(r.metrics.chamfer_cm, 2)
                );
            }
        }
        out.push('\n');
    }

    if has("hot3d") {
        let _ = writeln!(
            out,
            "### HOT3D-like: pose tracking (per-trajectory mean and median, averaged over trajectories)\n\n| method | sequences | trans. mean (cm) ↓ | trans. median (cm) ↓ | rot. mean (°) ↓ | rot. median (°) ↓ |\n|---|---|---|---|---|---|"
        );
        let row = |label: String, rs: &[&SequenceResult]| {
            let g = |f: fn(&SequenceResult) -> Option<f64>| {
                fmt(mean(&rs.iter().filter_map(|r| f(r)).collect::<Vec<_>>()), 2)
            };
            format!(
                "| {label} | {} | {} | {} | {} | {} |",
                rs.len(),
                g(|r| r.metrics.translation_mean_cm),
                g(|r| r.metrics.translation_median_cm),
                g(|r| r.metrics.rotation_mean_deg),
                g(|r| r.metrics.rotation_median_deg)
            )
        };
        for &m in &ms {
            let rs: Vec<&SequenceResult> = of(results, Some("hot3d"), m).collect();
            let _ = writeln!(out, "{}", row(m.into(), &rs));
        }
        if per_sequence {
            for r in results.iter().filter(|r| r.info.family == "hot3d") {
                let _ = writeln!(
                    out,
                    "{}",
                    row(format!("{} · {}", r.info.method, r.info.id), &[r])
                );
            }
        }
        out.push('\n');
    }

    if has("itaco") {
        let _ = write!(
            out,
            "### iTACO-like: articulation (mean ± std over sequences)\n\n| | metric |"
        );
        for m in &ms {
            let _ = write!(out, " {} |", m);
        }
        let _ = write!(out, "\n|---|---|");
        for _ in &ms {
            out.push_str("---|");
        }
        out.push('\n');
        type Getter = Box<dyn Fn(&SequenceResult) -> Vec<f64>>;
        let joint =
            |revolute: bool, f: fn(&agentstar_eval::JointRecord) -> Option<f64>| -> Getter {
                Box::new(move |r: &SequenceResult| {
                    r.metrics
                        .joints
                        .iter()
                        .filter(|j| j.revolute == revolute)
                        .filter_map(f)
                        .collect()
                })
            };
        let rows: Vec<(&str, &str, Getter)> = vec![
            (
                "Geometry",
                "CD-w (m²) ↓",
                Box::new(|r: &SequenceResult| r.metrics.cd_w_m2.into_iter().collect()),
            ),
            (
                "",
                "CD-m (m²) ↓",
                Box::new(|r: &SequenceResult| r.metrics.cd_m_m2.into_iter().collect()),
            ),
            (
                "",
                "CD-s (m²) ↓",
                Box::new(|r: &SequenceResult| r.metrics.cd_s_m2.into_iter().collect()),
            ),
            (
                "Revolute",
                "Axis (rad) ↓",
                joint(true, |j| j.axis_angle_rad),
            ),
            ("", "Position (m) ↓", joint(true, |j| j.axis_distance_m)),
            ("", "State (rad) ↓", joint(true, |j| j.state_error)),
            (
                "Prismatic",
                "Axis (rad) ↓",
                joint(false, |j| j.axis_angle_rad),
            ),
            ("", "State (m) ↓", joint(false, |j| j.state_error)),
        ];
        for (group, metric, get) in &rows {
            let _ = write!(out, "| {group} | {metric} |");
            for &m in &ms {
                let v: Vec<f64> = of(results, Some("itaco"), m).flat_map(get).collect();
                let cell = match (mean(&v), std_dev(&v)) {
                    (Some(a), Some(s)) => format!("{} ± {}", sig(a), sig(s)),
                    _ => "–".into(),
                };
                let _ = write!(out, " {cell} |");
            }
            out.push('\n');
        }
        out.push('\n');
    }

    // The ablation: EPE of every method over the same sequences, as the paper's table.
    let _ = writeln!(
        out,
        "### Ablation: 3D EPE (cm) over every sequence\n\n| variant | sequences | EPE (cm) ↓ | IoU mean | wall time (s, median per sequence) |\n|---|---|---|---|---|"
    );
    for &m in &ms {
        let epe = collect(results, None, m, |r| r.metrics.epe_cm);
        let iou = collect(results, None, m, |r| Some(r.iou_mean));
        let mut secs = collect(results, None, m, |r| Some(r.info.seconds));
        secs.sort_by(f64::total_cmp);
        let median = secs.get(secs.len() / 2).copied();
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            m,
            epe.len(),
            fmt(mean(&epe), 2),
            fmt(mean(&iou), 4),
            fmt(median, 1)
        );
    }
    out.push('\n');

    let _ = writeln!(
        out,
        "### Per sequence\n\n| sequence | method | frames | wall time (s) | s / frame | evaluations | IoU mean | IoU min | EPE (cm) | rot. median (°) |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in results {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.1} | {:.2} | {} | {:.4} | {:.4} | {} | {} |",
            r.info.id,
            r.info.method,
            r.metrics.frames,
            r.info.seconds,
            r.info.seconds / r.metrics.frames.max(1) as f64,
            r.info.evaluations,
            r.iou_mean,
            r.iou_min,
            fmt(r.metrics.epe_cm, 2),
            fmt(r.metrics.rotation_median_deg, 2)
        );
    }
    out
}

/// One sequence's figures as a two-column table.
pub fn result_table(r: &SequenceResult) -> String {
    let mut out = String::from("| metric | value |\n|---|---|\n");
    let mut row = |k: &str, v: String| {
        let _ = writeln!(out, "| {k} | {v} |");
    };
    row("frames", r.metrics.frames.to_string());
    row(
        "IoU (hands excluded) mean / min",
        format!("{:.4} / {:.4}", r.iou_mean, r.iou_min),
    );
    row(
        "scale alignment ŝ",
        format!("{:.4}", r.metrics.scale_alignment),
    );
    row("3D EPE (cm)", fmt(r.metrics.epe_cm, 3));
    row("Chamfer (cm)", fmt(r.metrics.chamfer_cm, 3));
    let mean_median = |mean, median| format!("{} / {}", fmt(mean, 3), fmt(median, 3));
    row(
        "rotation error mean / median (°)",
        mean_median(r.metrics.rotation_mean_deg, r.metrics.rotation_median_deg),
    );
    row(
        "translation error mean / median (cm)",
        mean_median(
            r.metrics.translation_mean_cm,
            r.metrics.translation_median_cm,
        ),
    );
    if !r.metrics.joints.is_empty() {
        row(
            "CD-w / CD-m / CD-s (m²)",
            [r.metrics.cd_w_m2, r.metrics.cd_m_m2, r.metrics.cd_s_m2]
                .map(|v| v.map_or("–".into(), sig))
                .join(" / "),
        );
    }
    for j in &r.metrics.joints {
        row(
            &format!(
                "joint {} ↔ {}",
                j.gt_joint,
                j.pred_joint.as_deref().unwrap_or("unmatched")
            ),
            format!(
                "axis {} rad, position {} m, state {} {}",
                fmt(j.axis_angle_rad, 4),
                fmt(j.axis_distance_m, 4),
                fmt(j.state_error, 4),
                if j.revolute { "rad" } else { "m" }
            ),
        );
    }
    out
}

/// The hard suite's table: per sequence, the capture's difficulty, the gate IoU, the errors
/// raw and reduced by the listed symmetries (HOT3D/BOP; the same as raw where the object lists
/// none), the wall time, and whether the bar (3-D EPE ≤ 1 cm and rotation error
/// ≤ 3° mean, symmetry-reduced) is met.
pub fn hard_table(results: &[SequenceResult]) -> String {
    let mut out = String::from(
        "### Hard suite: per sequence\n\n| sequence | method | steps mean / max (°) | hands max | IoU mean / min | EPE raw (cm) | EPE sym. (cm) | rot. mean raw / sym. (°) | rot. median raw / sym. (°) | trans. median (cm) | time (s) | ≤ 1 cm, ≤ 3° |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        let stats = r.capture_stats.as_ref().map_or("–".into(), |c| {
            format!("{:.0} / {:.0}", c.step_mean_deg, c.step_max_deg)
        });
        let hands = r.capture_stats.as_ref().map_or("–".into(), |c| {
            format!("{:.0}%", 100.0 * c.hand_coverage_max)
        });
        let pass = within_1cm_3deg(r);
        let _ = writeln!(
            out,
            "| {} | {} | {stats} | {hands} | {:.4} / {:.4} | {} | {} | {} / {} | {} / {} | {} | {:.1} | {} |",
            r.info.id,
            r.info.method,
            r.iou_mean,
            r.iou_min,
            fmt(r.metrics.epe_cm, 2),
            fmt(r.metric("sym_epe_cm"), 2),
            fmt(r.metrics.rotation_mean_deg, 1),
            fmt(r.metric("sym_rotation_mean_deg"), 1),
            fmt(r.metrics.rotation_median_deg, 1),
            fmt(r.metric("sym_rotation_median_deg"), 1),
            fmt(r.metrics.translation_median_cm, 2),
            r.info.seconds,
            if pass { "yes" } else { "no" }
        );
    }
    let passed = results.iter().filter(|r| within_1cm_3deg(r)).count();
    let _ = writeln!(
        out,
        "\n{passed} of {} sequence(s) meet 3-D EPE ≤ 1 cm and rotation error ≤ 3° mean. \"sym.\": reduced by the object's listed symmetries (shape and appearance); objects that list none (a can whose label breaks its axial symmetry) have sym. = raw.\n",
        results.len()
    );
    out
}

/// Whether a sequence meets 3-D EPE ≤ 1 cm and mean rotation error ≤ 3°, both after the
/// object's symmetries.
pub fn within_1cm_3deg(r: &SequenceResult) -> bool {
    matches!(
        (r.metric("sym_epe_cm"), r.metric("sym_rotation_mean_deg")),
        (Some(e), Some(a)) if e <= 1.0 && a <= 3.0
    )
}

/// The `q` quantile (0 to 1) of `sorted` by linear interpolation between order statistics.
pub fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    let last = sorted.len().checked_sub(1)?;
    let at = q.clamp(0.0, 1.0) * last as f64;
    let (lo, hi) = (at.floor() as usize, at.ceil() as usize);
    Some(sorted[lo] + (sorted[hi] - sorted[lo]) * (at - lo as f64))
}

/// Counts of `values` in the bins bounded by `edges` (≤ the first, between, > the last).
pub fn histogram(values: &[f64], edges: &[f64]) -> Vec<usize> {
    let mut counts = vec![0; edges.len() + 1];
    for &v in values {
        counts[edges.iter().position(|&e| v <= e).unwrap_or(edges.len())] += 1;
    }
    counts
}

fn histogram_line(
    label: &str,
    unit: &str,
    values: &[f64],
    edges: &[f64],
    missing: usize,
) -> String {
    let counts = histogram(values, edges);
    let mut bins = Vec::new();
    for (i, c) in counts.iter().enumerate() {
        let name = match i {
            0 => format!("≤ {}", edges[0]),
            i if i == edges.len() => format!("> {}", edges[i - 1]),
            i => format!("{}–{}", edges[i - 1], edges[i]),
        };
        bins.push(format!("{name}: {c}"));
    }
    if missing > 0 {
        bins.push(format!("not measured: {missing}"));
    }
    format!("{label} ({unit}): {}", bins.join(" · "))
}

/// The general suite's table: per method and kind of object (rigid or articulated, with
/// symmetries or none), the share of sequences within 1 cm EPE and 3° mean rotation error
/// after each object's true symmetries, and the quantiles of both errors; histograms of
/// both; then a row per sequence.
pub fn general_table(results: &[SequenceResult]) -> String {
    let mut out = String::from(
        "### General suite: generated objects, errors after each object's true symmetries\n\n| method | objects | sequences | ≤ 1 cm and ≤ 3° | EPE sym. (cm): min / 25% / median / 75% / 90% / max | rot. mean sym. (°): min / 25% / median / 75% / 90% / max |\n|---|---|---|---|---|---|\n",
    );
    let quantiles = |v: &mut Vec<f64>, digits: usize| {
        v.sort_by(f64::total_cmp);
        [0.0, 0.25, 0.5, 0.75, 0.9, 1.0]
            .iter()
            .map(|&q| fmt(quantile(v, q), digits))
            .collect::<Vec<_>>()
            .join(" / ")
    };
    type Kind = (&'static str, fn(&SequenceResult) -> bool);
    let kinds: [Kind; 5] = [
        ("all", |_| true),
        ("rigid", |r| r.info.family == "hot3d"),
        ("articulated", |r| r.info.family != "hot3d"),
        ("with symmetries", |r| r.symmetry_reduced.is_some()),
        ("no symmetry", |r| r.symmetry_reduced.is_none()),
    ];
    for m in methods(results) {
        for (kind, keep) in kinds {
            let rs: Vec<&SequenceResult> = of(results, None, m).filter(|r| keep(r)).collect();
            if rs.is_empty() {
                continue;
            }
            let mut objects: Vec<&str> = rs.iter().map(|r| r.info.object.as_str()).collect();
            objects.sort_unstable();
            objects.dedup();
            let within = rs.iter().filter(|r| within_1cm_3deg(r)).count();
            let mut epe: Vec<f64> = rs.iter().filter_map(|r| r.metric("sym_epe_cm")).collect();
            let mut rot: Vec<f64> = rs
                .iter()
                .filter_map(|r| r.metric("sym_rotation_mean_deg"))
                .collect();
            let _ = writeln!(
                out,
                "| {m} · {kind} | {} | {} | {within} ({:.0}%) | {} | {} |",
                objects.len(),
                rs.len(),
                100.0 * within as f64 / rs.len() as f64,
                quantiles(&mut epe, 2),
                quantiles(&mut rot, 1)
            );
        }
    }
    out.push('\n');
    for m in methods(results) {
        let rs: Vec<&SequenceResult> = of(results, None, m).collect();
        let epe: Vec<f64> = rs.iter().filter_map(|r| r.metric("sym_epe_cm")).collect();
        let rot: Vec<f64> = rs
            .iter()
            .filter_map(|r| r.metric("sym_rotation_mean_deg"))
            .collect();
        let _ = writeln!(
            out,
            "{m}: {}  \n{m}: {}\n",
            histogram_line(
                "EPE sym.",
                "cm",
                &epe,
                &[0.5, 1.0, 2.0, 5.0, 10.0],
                rs.len() - epe.len()
            ),
            histogram_line(
                "rot. mean sym.",
                "°",
                &rot,
                &[1.0, 3.0, 10.0, 30.0, 90.0],
                rs.len() - rot.len()
            )
        );
    }
    out.push_str("### General suite: per sequence\n\n| sequence | method | kind | symmetries | steps mean / max (°) | hands max | IoU mean / min | EPE raw / sym. (cm) | rot. mean raw / sym. (°) | time (s) | ≤ 1 cm, ≤ 3° |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in results {
        let stats = r.capture_stats.as_ref().map_or("–".into(), |c| {
            format!("{:.0} / {:.0}", c.step_mean_deg, c.step_max_deg)
        });
        let hands = r.capture_stats.as_ref().map_or("–".into(), |c| {
            format!("{:.0}%", 100.0 * c.hand_coverage_max)
        });
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {stats} | {hands} | {:.4} / {:.4} | {} / {} | {} / {} | {:.1} | {} |",
            r.info.id,
            r.info.method,
            if r.info.family == "hot3d" { "rigid" } else { "articulated" },
            r.symmetry_reduced.as_ref().map_or(0, |s| s.symmetries),
            r.iou_mean,
            r.iou_min,
            fmt(r.metrics.epe_cm, 2),
            fmt(r.metric("sym_epe_cm"), 2),
            fmt(r.metrics.rotation_mean_deg, 1),
            fmt(r.metric("sym_rotation_mean_deg"), 1),
            r.info.seconds,
            if within_1cm_3deg(r) { "yes" } else { "no" }
        );
    }
    out.push_str("\n\"sym.\": reduced by the object's true symmetries (shape, print and joints; BOP's nearest equivalent pose per frame); \"symmetries\": how many rotations besides the identity (a continuous turn as 315). Objects with none have sym. = raw. A sequence not measured counts as outside 1 cm and 3°.\n");
    out
}

/// Where the misses come from ([`crate::misses`]): per method, the keyframes more than
/// [`crate::misses::MISS_DEG`] off after the symmetries, by the evidence that preferred the
/// truth there; then a row per sequence with any. Empty when no result has a miss.
pub fn misses_table(results: &[SequenceResult]) -> String {
    let with: Vec<&SequenceResult> = results
        .iter()
        .filter(|r| r.misses.as_ref().is_some_and(|m| m.total() > 0))
        .collect();
    if with.is_empty() {
        return String::new();
    }
    let mut out = String::from(
        "### Where the misses come from\n\nKeyframes more than 3° off after the symmetries, by what scored the truth higher there: **search**: the mask (gate IoU over 0.005 better; no search reached the truth), **colours**: the masks tie and the model's own colours prefer the truth (the choice did not weigh them), **evidence**: neither (only the frames' colours against each other, or the motion, could tell). **Choice**: what the sequence-level choice did with the truth (a hypothesis within 3° of it): **taken** (a pass after the choice moved the frame away), **not taken** (weighed, another preferred), **none** (no search proposed it).\n\n| method | keyframes | missed | search | colours | evidence | choice: taken / not taken / none |\n|---|---|---|---|---|---|---|\n",
    );
    for m in methods(results) {
        let rs: Vec<&SequenceResult> = of(results, None, m).collect();
        let keyframes: usize = rs.iter().map(|r| r.metrics.frames).sum();
        let sum = |f: fn(&crate::misses::Misses) -> usize| -> usize {
            rs.iter().filter_map(|r| r.misses.as_ref()).map(f).sum()
        };
        let _ = writeln!(
            out,
            "| {m} | {keyframes} | {} | {} | {} | {} | {} / {} / {} |",
            sum(|x| x.total()),
            sum(|x| x.search),
            sum(|x| x.colours),
            sum(|x| x.evidence),
            sum(|x| x.weighed(Weighed::Taken)),
            sum(|x| x.weighed(Weighed::NotTaken)),
            sum(|x| x.weighed(Weighed::Absent))
        );
    }
    out.push_str("\n| sequence | method | missed | search | colours | evidence | choice: taken / not taken / none | worst frame: rotation (°), gate IoU tracked / truth, model colours (`score`'s `model`) tracked / truth |\n|---|---|---|---|---|---|---|---|\n");
    for r in with {
        let Some(m) = &r.misses else { continue };
        let worst = m
            .frames
            .iter()
            .max_by(|a, b| a.rotation_deg.total_cmp(&b.rotation_deg))
            .map_or("–".into(), |f| {
                format!(
                    "{}: {:.1}°, {:.4} / {:.4}, {} / {}",
                    f.frame,
                    f.rotation_deg,
                    f.gate_tracked,
                    f.gate_truth,
                    fmt(f.model_ncc_tracked, 2),
                    fmt(f.model_ncc_truth, 2)
                )
            });
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} / {} / {} | {worst} |",
            r.info.id,
            r.info.method,
            m.total(),
            m.search,
            m.colours,
            m.evidence,
            m.weighed(Weighed::Taken),
            m.weighed(Weighed::NotTaken),
            m.weighed(Weighed::Absent)
        );
    }
    out.push('\n');
    out
}
