//! `agentstar mechanism`: the mechanism check. Every articulated joint is swept through its
//! range twice, about its declared axis and about the negated axis, the rest of the model
//! held at rest (or at a keyframe's states), as two arms labelled A and B blindly (a seeded
//! coin per joint decides which is the declared one; only `--json` says). Each arm is drawn
//! from two viewpoints off the swing plane (40° off the axis, away from edge-on), at
//! `--samples` states from one end of the range to the other, with the framing fixed per
//! joint (the union of both arms' swept extents) so the arms differ only in their motion.
//! The keyframe that shows the joint's part most open is written beside the sheets for
//! comparison: openness weighed by the share of the part in view that no hand covers, so a
//! frame whose hand hides the part gives way to one nearly as open that shows it.

use crate::common::{open_capture, open_model, out_dir, print_json, SessionArgs};
use agentstar_data::images::save_png_rgb;
use agentstar_data::posefile::PoseFile;
use agentstar_geom::camera::look_at;
use agentstar_geom::pose::Rigid;
use agentstar_geom::{
    JointKind, KinematicTree, ObjectModel, PinholeCamera, Point3, Similarity, Vector3,
};
use agentstar_render::frames::{frame_view, FrameViewOptions};
use agentstar_render::full::{FullRenderer, RenderBuffers};
use agentstar_render::sheet::sheet_pages;
use agentstar_render::views::{flatten, shade_model, ShadeOptions, TURNTABLE_BACKGROUND};
use agentstar_render::{render_full, BitMask, PosedModel};
use agentstar_reports::mechanism::{
    ArmLabel, MechanismFrame, MechanismFramePassedOver, MechanismJoint, MechanismReport,
    MechanismView,
};
use anyhow::{anyhow, bail, Result};
use image::RgbImage;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Angle between a viewpoint's line of sight and the joint's axis, degrees.
pub const VIEW_OFF_AXIS_DEG: f64 = 40.0;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar mechanism --capture cap --model run/scene.rhai --poses run/pose.json --out mech\n  agentstar mechanism --capture cap --model run/scene.rhai --poses run/pose.json --out mech --joints lid_hinge --json"
)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Joints to sweep, comma separated (default: every revolute, continuous and
    /// prismatic joint).
    #[arg(long)]
    joints: Option<String>,
    /// Where the other joints are held: `rest` (0 clamped into each limit; the default) or
    /// one keyframe (a name, stem or number), whose states they take.
    #[arg(long, default_value = "rest")]
    hold: String,
    /// States per arm and row, both ends of the range included (5 to 13).
    #[arg(long, default_value_t = 7)]
    samples: usize,
    /// Seed of the coin that decides which label is the declared axis.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Side of one tile in pixels (square).
    #[arg(long, default_value_t = 216)]
    size: u32,
    /// Print the report as JSON on stdout (it names the declared arm).
    #[arg(long)]
    json: bool,
}

/// FNV-1a, 64 bits: the coin's hash (stable across platforms and releases).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The label of the declared arm of `joint` under `seed`.
pub fn declared_label(seed: u64, joint: &str) -> ArmLabel {
    if fnv1a(format!("{seed}:{joint}").as_bytes()) >> 63 == 0 {
        ArmLabel::A
    } else {
        ArmLabel::B
    }
}

/// `samples` states from `lo` to `hi` (interface units), the ends exact and the interior
/// rounded to a step that reads well (whole degrees; about a hundredth of the range in
/// model units), so evidence can name them.
pub fn sweep_states(lo: f64, hi: f64, samples: usize, angular: bool) -> Vec<f64> {
    let n = samples.max(2);
    let range = (hi - lo).abs().max(1e-12);
    let step = if angular {
        1.0
    } else {
        10f64.powf(range.log10().floor() - 2.0)
    };
    (0..n)
        .map(|k| {
            if k == 0 {
                lo
            } else if k == n - 1 {
                hi
            } else {
                let v = lo + (hi - lo) * k as f64 / (n - 1) as f64;
                let r = (v / step).round() * step;
                // Tidy the float: at most 6 decimals.
                (r * 1e6).round() / 1e6
            }
        })
        .collect()
}

pub use agentstar_reports::mechanism::state_text;

/// Up to two viewpoints (unit directions from the object to the eye) at
/// [`VIEW_OFF_AXIS_DEG`] from `axis`: the first nearest the turntable's az35/el20 and not
/// from below, the second at least 90° from the first.
pub fn viewpoints(axis: &Vector3) -> Vec<Vector3> {
    let a = axis.normalize();
    let helper = if a.z.abs() < 0.9 {
        Vector3::z()
    } else {
        Vector3::x()
    };
    let u = a.cross(&helper).normalize();
    let v = a.cross(&u);
    let (ca, sa) = (
        VIEW_OFF_AXIS_DEG.to_radians().cos(),
        VIEW_OFF_AXIS_DEG.to_radians().sin(),
    );
    let (az, el) = (35f64.to_radians(), 20f64.to_radians());
    let preferred = Vector3::new(az.sin() * el.cos(), -az.cos() * el.cos(), el.sin());
    let mut candidates: Vec<Vector3> = Vec::new();
    for sign in [1.0, -1.0] {
        for k in 0..24 {
            let phi = k as f64 * std::f64::consts::TAU / 24.0;
            candidates.push(a * (sign * ca) + (u * phi.cos() + v * phi.sin()) * sa);
        }
    }
    let score = |d: &Vector3| d.dot(&preferred) + if d.z < -0.1 { -2.0 } else { 0.0 };
    let best = |pool: &mut dyn Iterator<Item = &Vector3>| {
        pool.max_by(|x, y| score(x).total_cmp(&score(y))).copied()
    };
    let Some(first) = best(&mut candidates.iter()) else {
        return vec![];
    };
    let mut out = vec![first];
    if let Some(second) = best(&mut candidates.iter().filter(|d| d.dot(&first) <= 1e-9)) {
        out.push(second);
    }
    out
}

/// A camera looking along `-direction` at the points, framing them all (with a margin)
/// in a `size`² image: `(camera, camera_from_object)`.
fn framing(points: &[Point3], direction: &Vector3, size: u32) -> (PinholeCamera, Similarity) {
    let n = points.len().max(1) as f64;
    let centre = Point3::from(points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / n);
    let radius = points
        .iter()
        .map(|p| (p - centre).norm())
        .fold(1e-6, f64::max);
    let eye = centre + direction.normalize() * (radius * 3.0);
    let up = if direction.normalize().z.abs() > 0.95 {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let cam_from_obj: Rigid = look_at(&eye, &centre, &up);
    let (mut u0, mut u1, mut v0, mut v1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in points {
        let q = cam_from_obj * p;
        let z = q.z.max(1e-9);
        let (u, v) = (q.x / z, q.y / z);
        u0 = u0.min(u);
        u1 = u1.max(u);
        v0 = v0.min(v);
        v1 = v1.max(v);
    }
    let span = (u1 - u0).max(v1 - v0).max(1e-9);
    let f = size as f64 * 0.9 / span;
    let camera = PinholeCamera {
        fx: f,
        fy: f,
        cx: size as f64 * 0.5 - f * (u0 + u1) * 0.5,
        cy: size as f64 * 0.5 - f * (v0 + v1) * 0.5,
        width: size,
        height: size,
    };
    (camera, Similarity::from_rigid(&cam_from_obj))
}

/// The corners of every part's bounds posed at `states`.
fn posed_corners(model: &ObjectModel, states: &[f64], out: &mut Vec<Point3>) {
    for (part, t) in model.parts.iter().zip(model.tree.part_transforms(states)) {
        let (lo, hi) = (part.bounds.min, part.bounds.max);
        if !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z) {
            continue;
        }
        for k in 0..8 {
            let c = Point3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            out.push(t * c);
        }
    }
}

/// `model` with joint `j`'s axis negated.
fn negated(model: &ObjectModel, j: usize) -> Result<ObjectModel> {
    let mut joints = model.tree.joints().to_vec();
    joints[j].axis = -joints[j].axis;
    let tree = KinematicTree::new(joints, &model.part_names())
        .map_err(|e| anyhow!("negating joint {}'s axis: {e}", model.tree.joints()[j].name))?;
    Ok(ObjectModel {
        parts: model.parts.clone(),
        tree,
    })
}

fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

fn render_tile(
    model: &ObjectModel,
    states: &[f64],
    camera: &PinholeCamera,
    pose: &Similarity,
) -> RgbImage {
    let posed = PosedModel::new(model, states, pose);
    let buffers = render_full(camera, &posed.instances);
    flatten(
        &shade_model(
            model,
            &posed.instances,
            camera,
            &buffers,
            ShadeOptions::default(),
        ),
        TURNTABLE_BACKGROUND,
    )
}

/// One keyframe's parts as the camera sees them: each part's pixels in view, and those the
/// hand mask leaves uncovered (indexed like the model's parts).
#[derive(Debug, Clone, PartialEq)]
pub struct PartsInView {
    pub rendered: Vec<u64>,
    pub uncovered: Vec<u64>,
}

impl PartsInView {
    /// `buffers` (the model posed in the frame) under `hand` (none: nothing covered).
    pub fn new(buffers: &RenderBuffers, parts: usize, hand: Option<&BitMask>) -> Self {
        let rendered = buffers.part_pixels(parts);
        let uncovered = match hand {
            Some(h) => buffers.part_pixels_outside(parts, h),
            None => rendered.clone(),
        };
        PartsInView {
            rendered,
            uncovered,
        }
    }

    /// The share of `parts`' rendered pixels that no hand covers; 0 where they show none.
    pub fn share(&self, parts: &[usize]) -> f64 {
        let sum = |v: &[u64]| parts.iter().filter_map(|&p| v.get(p)).sum::<u64>();
        match sum(&self.rendered) {
            0 => 0.0,
            n => sum(&self.uncovered) as f64 / n as f64,
        }
    }
}

/// A keyframe weighed for showing a joint's part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShownCandidate {
    pub frame: usize,
    /// The joint's distance from its held state (internal units).
    pub openness: f64,
    /// [`PartsInView::share`] of the joint's parts.
    pub part_in_view_share: f64,
}

/// The keyframe to show: the largest openness weighed by the share of the part in view;
/// where no frame shows any of it, the most open. Frames that do not open the joint are
/// never shown.
pub fn choose_shown(candidates: &[ShownCandidate]) -> Option<ShownCandidate> {
    let open = candidates.iter().filter(|c| c.openness > 1e-9);
    let weighed = |c: &&ShownCandidate| c.openness * c.part_in_view_share;
    let best = open
        .clone()
        .max_by(|x, y| weighed(x).total_cmp(&weighed(y)))
        .filter(|c| weighed(c) > 0.0);
    best.or_else(|| open.max_by(|x, y| x.openness.total_cmp(&y.openness)))
        .copied()
}

/// Writes `pages` as `DIR/STEM.png`, `STEM_p2.png`, …
fn save_pages(dir: &Path, stem: &str, pages: &[RgbImage]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for (k, page) in pages.iter().enumerate() {
        let p = if k == 0 {
            dir.join(format!("{stem}.png"))
        } else {
            dir.join(format!("{stem}_p{}.png", k + 1))
        };
        save_png_rgb(page, &p)?;
        out.push(p);
    }
    Ok(out)
}

pub fn run(a: Args) -> Result<ExitCode> {
    if !(5..=13).contains(&a.samples) {
        bail!("--samples {} must lie in [5, 13]", a.samples);
    }
    if !(64..=512).contains(&a.size) {
        bail!("--size {} must lie in [64, 512]", a.size);
    }
    let m = open_model(&a.session.model)?;
    let model = &m.model;
    let tree = &model.tree;
    let mut notes = Vec::new();
    // The poses: the held states and the keyframe where each joint is most open.
    let capture = open_capture(&a.session.capture)?;
    let resolved = PoseFile::read(&a.session.poses).and_then(|pf| {
        pf.resolve(&capture, tree)
            .map(|r| (pf.scale, r))
            .map_err(|e| agentstar_data::DataError::invalid(&a.session.poses, e.to_string()))
    });
    let resolved = match resolved {
        Ok(r) => Some(r),
        Err(e) if a.hold.trim() == "rest" => {
            notes.push(format!(
                "the poses were not read ({e}); no keyframe is shown for comparison"
            ));
            None
        }
        Err(e) => return Err(e.into()),
    };
    let mut hold = tree.rest_states();
    tree.clamp_states(&mut hold);
    let hold_name = match a.hold.trim() {
        "rest" | "" => "rest".to_string(),
        spec => {
            let idx = capture.select(Some(spec))?;
            let [i] = idx.as_slice() else {
                bail!("--hold `{spec}` names {} keyframes; name one", idx.len());
            };
            if let Some((_, r)) = &resolved {
                hold.clone_from(&r[*i].generalised.states);
            }
            capture.frames[*i].name.clone()
        }
    };
    // The joints to sweep.
    let wanted: Option<Vec<String>> = a.joints.as_deref().map(|s| {
        s.split(',')
            .map(|n| n.trim().to_string())
            .filter(|n| !n.is_empty())
            .collect()
    });
    if let Some(w) = &wanted {
        let unknown: Vec<&String> = w.iter().filter(|n| tree.joint_index(n).is_none()).collect();
        if !unknown.is_empty() || w.is_empty() {
            bail!(
                "--joints: no joint named {}; the model's joints are {}",
                unknown
                    .iter()
                    .map(|n| format!("`{n}`"))
                    .collect::<Vec<_>>()
                    .join(", "),
                tree.joints()
                    .iter()
                    .map(|j| j.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    let dir = out_dir(&a.out)?;
    // Each keyframe's parts in view of the hands, rendered once for every joint.
    let mut in_view = Vec::new();
    if let Some((scale, r)) = &resolved {
        let mut renderer = FullRenderer::default();
        for (i, p) in r.iter().enumerate() {
            let posed = PosedModel::new(
                model,
                &p.generalised.states,
                &p.generalised.pose.with_scale(*scale),
            );
            let buffers = renderer.render(&capture.frames[i].camera, &posed.instances);
            let hand = capture.load_hand(i)?;
            in_view.push(PartsInView::new(buffers, model.parts.len(), hand.as_ref()));
        }
    }
    let mut joints_out = Vec::new();
    for (j, def) in tree.joints().iter().enumerate() {
        if wanted.as_ref().is_some_and(|w| !w.contains(&def.name)) {
            continue;
        }
        let (lo, hi) = match (def.kind, def.limit) {
            (JointKind::Fixed, _) => {
                notes.push(format!("{}: a fixed joint does not move", def.name));
                continue;
            }
            (JointKind::Continuous, _) => (-180.0, 180.0),
            (_, Some((lo, hi))) => (lo, hi),
            (_, None) => {
                notes.push(format!("{}: no limit to sweep", def.name));
                continue;
            }
        };
        if (hi - lo).abs() < 1e-9 {
            notes.push(format!(
                "{}: its limit [{lo}, {hi}] does not move it",
                def.name
            ));
            continue;
        }
        let angular = def.kind.is_angular();
        let states = sweep_states(lo, hi, a.samples, angular);
        let other = negated(model, j)?;
        let declared = declared_label(a.seed, &def.name);
        let arm_model = |label: ArmLabel| {
            if label == declared {
                model
            } else {
                &other
            }
        };
        let internal = |v: f64| {
            let mut s = hold.clone();
            s[j] = def.to_internal(v);
            s
        };
        // Fixed framing per joint and view: every state of both arms.
        let mut corners = Vec::new();
        for &v in &states {
            posed_corners(model, &internal(v), &mut corners);
            posed_corners(&other, &internal(v), &mut corners);
        }
        let axis = tree.unit_axis(j).into_inner();
        let directions = viewpoints(&axis);
        let unit = if angular { "deg" } else { "units" };
        let suffix = if angular { " deg" } else { "" };
        let stem = file_stem(&def.name);
        let mut sheets = [Vec::new(), Vec::new()];
        for (k, label) in [ArmLabel::A, ArmLabel::B].into_iter().enumerate() {
            let arm = arm_model(label);
            let mut tiles = Vec::new();
            for (r, d) in directions.iter().enumerate() {
                let (camera, pose) = framing(&corners, d, a.size);
                for (s, &v) in states.iter().enumerate() {
                    let end = if s == 0 || s + 1 == states.len() {
                        " (end)"
                    } else {
                        ""
                    };
                    tiles.push((
                        format!(
                            "{} view {} {}{suffix}{end}",
                            label.as_str(),
                            r + 1,
                            state_text(v)
                        ),
                        render_tile(arm, &internal(v), &camera, &pose),
                    ));
                }
            }
            let title = format!(
                "mechanism {}: arm {} swept {} to {}{suffix} ({} states, left to right); one row per view, {VIEW_OFF_AXIS_DEG:.0} deg off the joint's axis; other joints at {hold_name}",
                def.name,
                label.as_str(),
                state_text(lo),
                state_text(hi),
                states.len()
            );
            let pages = sheet_pages(&tiles, states.len(), &title);
            sheets[k] = save_pages(
                &dir,
                &format!("mechanism_{stem}_{}", label.as_str()),
                &pages,
            )?;
        }
        // The keyframe that shows the joint's parts furthest from its held state and least
        // covered by hands.
        let mut frame = None;
        if let Some((_, r)) = &resolved {
            let moved = tree.parts_moved_by(j);
            let candidates: Vec<ShownCandidate> = r
                .iter()
                .zip(&in_view)
                .enumerate()
                .map(|(i, (p, seen))| ShownCandidate {
                    frame: i,
                    openness: (p.generalised.states[j] - hold[j]).abs(),
                    part_in_view_share: seen.share(&moved),
                })
                .collect();
            let most_open = candidates
                .iter()
                .max_by(|x, y| x.openness.total_cmp(&y.openness));
            if let Some(shown) = choose_shown(&candidates) {
                let i = shown.frame;
                let img = capture.load_frame(i)?;
                let mask = capture.load_mask(i)?;
                let hand = capture.load_hand(i)?;
                let view = frame_view(
                    &img,
                    &mask,
                    hand.as_ref(),
                    None,
                    &FrameViewOptions::default(),
                );
                let p = dir.join(format!("mechanism_{stem}_frame.png"));
                save_png_rgb(&view.image, &p)?;
                frame = Some(MechanismFrame {
                    frame: capture.frames[i].name.clone(),
                    state: def.to_interface(r[i].generalised.states[j]),
                    image: p,
                    parts: moved.iter().map(|&k| model.parts[k].name.clone()).collect(),
                    part_in_view_share: shown.part_in_view_share,
                    more_open: most_open
                        .filter(|m| m.frame != i && m.openness > shown.openness)
                        .map(|m| MechanismFramePassedOver {
                            frame: capture.frames[m.frame].name.clone(),
                            state: def.to_interface(r[m.frame].generalised.states[j]),
                            part_in_view_share: m.part_in_view_share,
                        }),
                });
            }
        }
        let [sheets_a, sheets_b] = sheets;
        joints_out.push(MechanismJoint {
            joint: def.name.clone(),
            kind: def.kind.as_str().to_string(),
            unit: unit.to_string(),
            axis: [def.axis.x, def.axis.y, def.axis.z],
            range: [lo, hi],
            states,
            sheets_a,
            sheets_b,
            views: directions
                .iter()
                .map(|d| MechanismView {
                    direction: [d.x, d.y, d.z],
                    off_swing_plane_deg: d.dot(&axis).abs().clamp(0.0, 1.0).asin().to_degrees(),
                })
                .collect(),
            frame,
            declared,
        });
    }
    for n in &notes {
        eprintln!("note: {n}");
    }
    let report = MechanismReport {
        out: dir.clone(),
        seed: a.seed,
        hold: hold_name,
        joints: joints_out,
        notes,
    };
    if a.json {
        print_json(&report)?;
    } else {
        println!(
            "mechanism: {} joint(s) swept in {} ({} sheet(s)); which arm is declared is in --json",
            report.joints.len(),
            dir.display(),
            report
                .joints
                .iter()
                .map(|j| j.sheets_a.len() + j.sheets_b.len())
                .sum::<usize>()
        );
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweep_states_keep_the_ends_and_round_the_interior() {
        let s = sweep_states(0.0, 110.0, 7, true);
        assert_eq!(s, [0.0, 18.0, 37.0, 55.0, 73.0, 92.0, 110.0]);
        let p = sweep_states(0.0, 0.3, 5, false);
        assert_eq!(p, [0.0, 0.075, 0.15, 0.225, 0.3]);
        assert_eq!(state_text(37.0), "37");
        assert_eq!(state_text(0.075), "0.075");
    }

    #[test]
    fn viewpoints_are_off_the_swing_plane_and_apart() {
        for axis in [Vector3::x(), Vector3::z(), Vector3::new(1.0, 2.0, -0.5)] {
            let v = viewpoints(&axis);
            assert_eq!(v.len(), 2);
            let a = axis.normalize();
            for d in &v {
                let off_axis = d.dot(&a).abs().acos().to_degrees();
                assert!((off_axis - VIEW_OFF_AXIS_DEG).abs() < 1e-6, "{off_axis}");
            }
            assert!(v[0].dot(&v[1]) <= 1e-9, "{v:?}");
        }
    }

    /// A slab with a lid hinged along its near edge, seen from the front and above.
    fn lidded_box() -> (ObjectModel, PinholeCamera, Similarity) {
        use agentstar_geom::kinematics::JointDef;
        use agentstar_geom::primitives::cuboid;
        use agentstar_geom::Part;
        let body = cuboid(1.0, 1.0, 0.2).expect("box");
        let lid = cuboid(1.0, 1.0, 0.05)
            .expect("box")
            .translated(Vector3::new(0.0, 0.0, 0.125));
        let hinge = JointDef {
            name: "hinge".into(),
            kind: JointKind::Revolute,
            parent: None,
            child: vec!["lid".into()],
            origin: Vector3::new(0.0, -0.5, 0.1),
            axis: Vector3::x(),
            limit: Some((0.0, 120.0)),
        };
        let parts = vec![
            Part::new("body", body, [0.8, 0.2, 0.2]),
            Part::new("lid", lid, [0.2, 0.8, 0.2]),
        ];
        let names: Vec<String> = parts.iter().map(|p| p.name.clone()).collect();
        let model = ObjectModel {
            tree: KinematicTree::new(vec![hinge], &names).expect("tree"),
            parts,
        };
        let camera = PinholeCamera {
            fx: 60.0,
            fy: 60.0,
            cx: 48.0,
            cy: 36.0,
            width: 96,
            height: 72,
        };
        let eye = Point3::new(0.0, -3.0, 2.0);
        let pose = Similarity::from_rigid(&look_at(&eye, &Point3::origin(), &Vector3::z()));
        (model, camera, pose)
    }

    #[test]
    fn a_frame_nearly_as_open_that_shows_the_part_beats_one_whose_hand_hides_it() {
        let (model, camera, pose) = lidded_box();
        let def = &model.tree.joints()[0];
        let lid = model.tree.parts_moved_by(0);
        assert_eq!(lid, [1]);
        // Keyframe 0 opens the lid to 90 deg with a hand over all of it; keyframe 1 opens
        // it to 85 deg and no hand is in the way.
        let states = [vec![def.to_internal(90.0)], vec![def.to_internal(85.0)]];
        let buffers: Vec<RenderBuffers> = states
            .iter()
            .map(|s| render_full(&camera, &PosedModel::new(&model, s, &pose).instances))
            .collect();
        let lid_pixels = |b: &RenderBuffers| {
            BitMask::from_fn(b.width, b.height, |x, y| {
                b.part[(y * b.width + x) as usize] == 1
            })
        };
        let hand = lid_pixels(&buffers[0]);
        assert!(hand.count() > 50, "the lid is in view: {}", hand.count());
        let weigh = |hands: [Option<&BitMask>; 2]| -> Vec<ShownCandidate> {
            (0..2)
                .map(|i| ShownCandidate {
                    frame: i,
                    openness: states[i][0],
                    part_in_view_share: PartsInView::new(&buffers[i], 2, hands[i]).share(&lid),
                })
                .collect()
        };
        let hidden = weigh([Some(&hand), None]);
        assert_eq!(hidden[0].part_in_view_share, 0.0);
        assert_eq!(hidden[1].part_in_view_share, 1.0);
        let shown = choose_shown(&hidden).expect("a frame");
        assert_eq!(shown.frame, 1);
        // Without the hand the most open frame is shown, as before.
        let bare = choose_shown(&weigh([None, None])).expect("a frame");
        assert_eq!(bare.frame, 0);
        // A hand over half the lid weighs the frame by half: 90 × 0.5 < 85.
        let half = BitMask::from_fn(hand.width(), hand.height(), |x, y| x < 48 && hand.get(x, y));
        let partial = weigh([Some(&half), None]);
        assert!(
            (0.3..0.7).contains(&partial[0].part_in_view_share),
            "{}",
            partial[0].part_in_view_share
        );
        assert_eq!(choose_shown(&partial).expect("a frame").frame, 1);
    }

    #[test]
    fn with_no_part_in_view_anywhere_the_most_open_frame_is_shown() {
        let at = |frame, openness| ShownCandidate {
            frame,
            openness,
            part_in_view_share: 0.0,
        };
        assert_eq!(
            choose_shown(&[at(0, 0.5), at(1, 1.2), at(2, 0.0)]).map(|c| c.frame),
            Some(1)
        );
        assert_eq!(choose_shown(&[at(0, 0.0)]), None);
    }

    #[test]
    fn the_coin_is_seeded_and_per_joint() {
        let labels: Vec<ArmLabel> = (0..64).map(|s| declared_label(s, "lid")).collect();
        assert!(labels.contains(&ArmLabel::A) && labels.contains(&ArmLabel::B));
        assert_eq!(declared_label(3, "lid"), declared_label(3, "lid"));
    }
}
