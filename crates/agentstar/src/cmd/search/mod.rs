//! The pose verbs: `sweep` and `apply` (camera-frame increments about the pivot, in
//! `camera.rs`), `osweep` and `oapply` (object-frame rotations per frame) and `oapply-all`
//! (one shared object-frame rotation for every frame, in `object.rs`). Each writes a typed
//! report ([`SearchReport`]), a text table that says how to keep a candidate (never pose
//! numbers to paste), and a candidate sheet (render over the frame and silhouette
//! comparison per finalist, cropped around the object, labelled with rank, score and the
//! order, paged within the image limits); this module holds what they share.

use crate::common::{
    out_dir, print_json, progress, select_frames, FrameInputs, Session, SessionArgs,
};
use agentstar_data::images::save_png_rgb;
use agentstar_data::posefile::pose_json;
use agentstar_geom::{KinematicTree, Point3, UnitQuaternion};
use agentstar_render::frames::{crop_box, crop_zoomed, widened};
use agentstar_render::sheet::{sheet_layout, sheet_pages};
use agentstar_render::views::{overlay, shade_model, silhouette_comparison, ShadeOptions};
use agentstar_render::{render_full, BitMask, PosedModel};
use agentstar_reports::{Candidate, SearchFrame, SearchReport, SearchVerb, SheetPage};
use agentstar_track::hypotheses::{hinge_swaps, refine_each, refine_ranked, LocalWindow};
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

mod camera;
mod object;

pub use camera::{run_apply, run_sweep, ApplyArgs, SweepArgs};
pub use object::{run_oapply, run_oapply_all, run_osweep, OapplyAllArgs, OapplyArgs, OsweepArgs};

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
    /// The candidate sheet's `--crop` and `--zoom` (the search tools' `crop` and `zoom`).
    #[command(flatten)]
    view: agentstar_requests::SheetView,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// A grid search's options, shared by `sweep --strategy grid` and `osweep`.
#[derive(clap::Args, Clone, Copy)]
pub struct GridArgs {
    /// Grid steps for the searched values whose range gives none.
    #[arg(long, default_value_t = 5)]
    steps: usize,
    /// Grid refinement passes (each re-centres the windows on the best point).
    #[arg(long, default_value_t = 1)]
    refine: usize,
    /// Factor applied to each window's half-span per refinement pass.
    #[arg(long, default_value_t = 0.5)]
    shrink: f64,
}

impl GridArgs {
    fn strategy(self) -> Strategy {
        Strategy::Grid {
            default_steps: self.steps,
            refine: self.refine,
            shrink: self.shrink,
        }
    }
}

/// One ranked candidate for the report.
struct Row {
    rank: usize,
    label: String,
    pose: GenPose,
    score: CandidateScore,
    extra: Value,
    /// The frame's colours against the model's own part colours at this pose
    /// ([`with_model_agreement`]); `None` for a model of one colour.
    model_ncc: Option<f64>,
    /// The turns from the neighbouring keyframes' committed poses ([`annotate`]).
    neighbour_steps: Vec<agentstar_reports::NeighbourStep>,
    /// Where a kept start lies outside the region ([`outside_region`]).
    outside_region: Vec<String>,
}

/// Fills each row of frame `i` with what tells twins apart where their outlines tie: the
/// turns from the neighbouring keyframes' committed poses ([`neighbour_steps`]) and the
/// agreement of the frame's colours with the model's own ([`with_model_agreement`]).
fn annotate(s: &Session, i: usize, rows: &mut [Row]) -> Result<()> {
    for r in rows.iter_mut() {
        r.neighbour_steps = neighbour_steps(s, i, &r.pose);
    }
    with_model_agreement(s, i, rows)
}

/// The turns from the committed poses of frame `i`'s neighbouring keyframes (the one before
/// and the one after, where `pose.json` states a pose, not one seeded through the cameras),
/// each carried into frame `i` through the cameras (the object held still), to `pose`.
fn neighbour_steps(s: &Session, i: usize, pose: &GenPose) -> Vec<agentstar_reports::NeighbourStep> {
    [i.checked_sub(1), Some(i + 1)]
        .into_iter()
        .flatten()
        .filter_map(|k| {
            let neighbour = s.poses.get(k).filter(|p| !p.seeded)?;
            let frames = &s.capture.frames;
            let carried = agentstar_geom::pose::seed_from_reference(
                &frames[i].world_from_camera,
                &frames[k].world_from_camera,
                &neighbour.generalised.pose,
            );
            Some(agentstar_reports::NeighbourStep {
                frame: frames[k].name.clone(),
                angle_deg: carried.rotation.angle_to(&pose.pose.rotation).to_degrees(),
            })
        })
        .collect()
}

/// Fills each row's agreement of frame `i`'s colours with the model's own part colours
/// (`model_agreement`): where the outlines tie (a lid and base swapped, a can turned half
/// way), the figure that tells them apart, shown beside the IoU. Nothing for a model of one
/// colour or a frame whose image does not match its camera.
fn with_model_agreement(s: &Session, i: usize, rows: &mut [Row]) -> Result<()> {
    use agentstar_track::appearance::{
        model_agreement, model_has_appearance, AppearanceConfig, AppearanceFrame,
    };
    let model = &s.model.model;
    if !model_has_appearance(model) {
        return Ok(());
    }
    let Some((image, mask)) = crate::common::appearance_inputs(&s.capture, i)? else {
        return Ok(());
    };
    let frame = AppearanceFrame {
        camera: &s.capture.frames[i].camera,
        rgb: image.as_raw(),
        mask: &mask,
    };
    let cfg = AppearanceConfig::default();
    for r in rows {
        r.model_ncc = model_agreement(model, s.scale(), &frame, &r.pose, &cfg).ncc;
    }
    Ok(())
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

fn candidate(r: &Row, scale: f64, tree: &KinematicTree) -> Candidate {
    let p = pose_json(&r.pose.pose, Some(scale));
    Candidate {
        rank: r.rank,
        label: r.label.clone(),
        pose: p,
        joints: tree.states_to_interface(&r.pose.states),
        iou_visible: r.score.iou_visible,
        iou_raw: r.score.iou_raw,
        iou_band: r.score.iou_band,
        gate: r.score.gate,
        depth_canon: r.score.depth_canon,
        combined: r.score.combined,
        model_ncc: r.model_ncc,
        neighbour_steps: r.neighbour_steps.clone(),
        outside_region: r.outside_region.clone(),
        extra: r.extra.clone(),
    }
}

fn space_json(space: &SearchSpace, tree: &KinematicTree) -> Value {
    json!(space
        .ranges
        .iter()
        .map(|r| json!({"dof": r.dof.name(tree), "lower": r.lo, "upper": r.hi, "steps": r.steps}))
        .collect::<Vec<_>>())
}

/// Margin around the mask and the finalists' silhouettes on a candidate sheet, a fraction
/// of the box's longer side.
const SHEET_MARGIN: f64 = 0.15;

/// The candidate sheet of one frame, as pages within the image limits, each with the ranks
/// it draws: per finalist, the render over the frame, the render opaque on the frame and the
/// silhouette comparison (one finalist a row), cropped to the mask and every finalist's
/// silhouette with a margin (the same crop for all, so they compare), labelled with rank,
/// score and order; `zoom` is the sheet's zoom, checked ([`SheetView::zoom`]).
///
/// [`SheetView::zoom`]: agentstar_requests::SheetView::zoom
fn candidate_sheet(
    s: &Session,
    i: usize,
    rows: &[Row],
    limit: usize,
    title: &str,
    (view, zoom): (&agentstar_requests::SheetView, f64),
) -> Result<CandidateSheet> {
    let frame = s.capture.load_frame(i)?;
    let (target, _) = s.target(i)?;
    let cam = s.capture.frames[i].camera;
    let hand = target.keep().map(|k| k.not());
    if let Some(d) = view.draw {
        if !rows.iter().any(|r| d.contains(r.rank)) {
            let ranks: Vec<usize> = rows.iter().map(|r| r.rank).collect();
            bail!(
                "--draw {d}: frame {} has no candidate of those ranks (it ranked {})",
                s.capture.frames[i].name,
                rank_list(&ranks)
            );
        }
    }
    // The ranks asked for (`--draw`), else the first `limit`.
    let shown: Vec<(&Row, agentstar_render::RenderBuffers, image::RgbaImage)> = rows
        .iter()
        .filter(|r| view.draw.is_none_or(|d| d.contains(r.rank)))
        .take(if view.draw.is_some() {
            usize::MAX
        } else {
            limit.max(1)
        })
        .map(|r| {
            let posed = PosedModel::new(
                &s.model.model,
                &r.pose.states,
                &r.pose.pose.with_scale(s.scale()),
            );
            let buffers = render_full(&cam, &posed.instances);
            let shaded = shade_model(
                &s.model.model,
                &posed.instances,
                &cam,
                &buffers,
                ShadeOptions::default(),
            );
            (r, buffers, shaded)
        })
        .collect();
    let silhouettes: Vec<BitMask> = shown.iter().map(|(_, b, _)| b.silhouette()).collect();
    let union = silhouettes
        .iter()
        .skip(1)
        .fold(silhouettes.first().cloned(), |acc, m| acc.map(|a| a.or(m)));
    let [x0, y0, w, h] = crop_box(target.mask(), union.as_ref(), SHEET_MARGIN).unwrap_or([
        0,
        0,
        frame.width(),
        frame.height(),
    ]);
    // A box asked for replaces the crop around the mask and the silhouettes.
    let around = (view.crop.unwrap_or_default())
        .window(frame.width(), frame.height(), Some([x0, y0, w, h]))
        .map_err(|e| anyhow!("--crop: {e} (frame {})", s.capture.frames[i].name))?;
    // At least 4:3 and 320 px on its long side, so that each tile's label (the order) has
    // room under it; zoomed, at most 960 px.
    let crop = widened(around, TILE_ASPECT, frame.width());
    let long = crop[2].max(crop[3]);
    let side = tile_side(long, zoom);
    let cut = |img: &RgbImage| crop_zoomed(img, crop, side);
    let mut tiles = Vec::new();
    // Per candidate: the model over the frame (its outline against the frame's), the model
    // opaque (its print against the frame's, as `render side` shows it: play-tests 8 and 10
    // could not tell the model's print from the frame's under the translucent overlay), and
    // the silhouette comparison.
    for ((r, _, shaded), sil) in shown.iter().zip(&silhouettes) {
        let (cmp, _) = silhouette_comparison(sil, target.mask(), hand.as_ref());
        tiles.push((
            format!("#{} IoU {:.4} {}", r.rank, r.score.gate, r.label),
            cut(&overlay(&frame, shaded, 0.6)),
        ));
        tiles.push((
            format!("#{} model (opaque)", r.rank),
            cut(&overlay(&frame, shaded, 1.0)),
        ));
        tiles.push((format!("#{} compare", r.rank), cut(&cmp)));
    }
    // One finalist a row of three tiles: a page holds whole rows, so whole finalists.
    let layout = sheet_layout(&tiles, TILES_PER_CANDIDATE, title);
    let drawn_zoom = side as f64 * layout.tile_factor / long.max(1) as f64;
    let per_page = (layout.columns * layout.rows_per_page / TILES_PER_CANDIDATE).max(1);
    let ranks: Vec<usize> = shown.iter().map(|(r, _, _)| r.rank).collect();
    let pages = sheet_pages(&tiles, TILES_PER_CANDIDATE, title);
    let groups: Vec<Vec<usize>> = ranks.chunks(per_page).map(<[usize]>::to_vec).collect();
    // The frame alone, as the tiles cut it, at the size they are drawn.
    let frame_alone = agentstar_render::sheet::scaled(&cut(&frame), layout.tile_factor);
    Ok(CandidateSheet {
        pages: pages
            .into_iter()
            .zip(groups.into_iter().chain(std::iter::repeat(vec![])))
            .collect(),
        crop,
        zoom: drawn_zoom,
        frame_alone,
    })
}

/// A frame's candidate sheet: its pages with the ranks each draws, the crop its tiles show
/// (`x0, y0, w, h`, frame pixels) and the zoom they are drawn at (output pixels per frame
/// pixel, after the tile cap and the image limits).
struct CandidateSheet {
    pages: Vec<(RgbImage, Vec<usize>)>,
    crop: [u32; 4],
    zoom: f64,
    /// The frame alone, cut and drawn as the tiles are.
    frame_alone: RgbImage,
}

/// A tile's long side for a crop `long` frame pixels long at `zoom`: at least
/// [`TILE_LONG_SIDE_PX`], zoomed at most to [`MAX_TILE_LONG_SIDE_PX`], never shrunk.
fn tile_side(long: u32, zoom: f64) -> u32 {
    let zoomed = ((long as f64 * zoom).round() as u32).min(MAX_TILE_LONG_SIDE_PX);
    long.max(zoomed).max(TILE_LONG_SIDE_PX)
}

/// The note that says at what zoom a sheet's tiles came out when a crop or zoom was asked:
/// the tile cap and the image limits (three tiles a row) can undo a zoom (play-test 15:
/// `zoom: 2` about the mask's box gave tiles no larger than without).
fn zoom_note(
    view: &agentstar_requests::SheetView,
    asked: f64,
    sheet: &CandidateSheet,
) -> Option<String> {
    if view.crop.is_none() && view.zoom.is_none() {
        return None;
    }
    let [x0, y0, w, h] = sheet.crop;
    let mut line = format!(
        "sheet tiles: crop at ({x0}, {y0}), {w}×{h} frame pixels, drawn at zoom {:.2}",
        sheet.zoom
    );
    if sheet.zoom < asked * 0.95 {
        line.push_str(&format!(
            " (zoom {asked:.2} asked: tiles are at most {MAX_TILE_LONG_SIDE_PX} px on their long side and a sheet of three tiles a row keeps the image limits, {} px and {:.2} megapixels; a smaller crop zooms further)",
            agentstar_render::sheet::MAX_LONG_SIDE_PX,
            agentstar_render::sheet::MAX_PIXELS as f64 / 1e6
        ));
    }
    Some(line)
}

/// Tiles per finalist on a candidate sheet (and its columns): over the frame, opaque,
/// compared.
const TILES_PER_CANDIDATE: usize = 3;

/// The first run of consecutive ranks in `ranks` as `draw` takes it: `6-17` (one rank
/// alone: `7`), at most [`agentstar_requests::sheet::MAX_DRAWN_RANKS`] long.
fn rank_span(ranks: &[usize]) -> String {
    let runs = rank_runs(ranks);
    let (lo, hi) = runs.first().copied().unwrap_or((0, 0));
    let hi = hi.min(lo + agentstar_requests::sheet::MAX_DRAWN_RANKS - 1);
    agentstar_requests::RankRange { from: lo, to: hi }.to_string()
}

/// `ranks` (ascending, or in any order) as runs of consecutive ranks, in order.
fn rank_runs(ranks: &[usize]) -> Vec<(usize, usize)> {
    let mut sorted = ranks.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for r in sorted {
        match runs.last_mut() {
            Some((_, hi)) if *hi + 1 == r => *hi = r,
            _ => runs.push((r, r)),
        }
    }
    runs
}

/// The ranks `ranks` as people read them: `#0–#5`, `#0–#19, #23, #24`, or `#0, #2, #7`
/// (runs of three or more joined).
fn rank_list(ranks: &[usize]) -> String {
    if ranks.is_empty() {
        return "none".to_string();
    }
    rank_runs(ranks)
        .into_iter()
        .map(|(lo, hi)| match hi - lo {
            0 => format!("#{lo}"),
            1 => format!("#{lo}, #{hi}"),
            _ => format!("#{lo}–#{hi}"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The least width over height of a sweep sheet's tile, and the long side its crop is
/// enlarged to (never shrunk).
const TILE_ASPECT: f64 = 4.0 / 3.0;
const TILE_LONG_SIDE_PX: u32 = 320;
/// The longest a zoomed tile's long side is drawn before the sheet's own limits.
const MAX_TILE_LONG_SIDE_PX: u32 = 3 * TILE_LONG_SIDE_PX;

/// The text a person reads at a shell: the ranked table, notes, and how to keep a
/// candidate (the numbers are in the JSON report, never to be typed into pose.json).
fn text_report(
    verb: &str,
    frame: &str,
    ranked: &[Candidate],
    notes: &[String],
    report_path: &Path,
    poses: &Path,
) -> String {
    let twins = agentstar_reports::twin_columns(ranked);
    let mut t = format!(
        "{verb} {frame}\n{:<5} {:>8} {:>8} {:>8} {:>8} {:>9}{}  order\n",
        "rank", "combined", "iou_band", "iou_vis", "iou_raw", "dp_canon", twins.header
    );
    let or_na = |v: Option<f64>| v.map_or("n/a".into(), |v| format!("{v:.4}"));
    for (c, cells) in ranked.iter().zip(&twins.cells) {
        t.push_str(&format!(
            "{:<5} {:>8.4} {:>8} {:>8} {:>8.4} {:>9}{cells}  {}\n",
            c.rank,
            c.combined,
            or_na(c.iou_band),
            or_na(c.iou_visible),
            c.iou_raw,
            c.depth_canon.map_or("-".into(), |v| format!("{v:.4}")),
            c.label
        ));
    }
    for n in &twins.notes {
        t.push_str(n);
        t.push('\n');
    }
    for n in notes {
        t.push_str(&format!("note: {n}\n"));
    }
    if !ranked.is_empty() {
        t.push_str(&format!(
            "keep a candidate after looking at the sheet: agentstar pose commit --poses {} --report {} --rank N --frames {frame}\n",
            poses.display(),
            report_path.display()
        ));
    }
    t
}

struct FrameOutput {
    frame: String,
    rows: Vec<Row>,
    extra: Value,
    notes: Vec<String>,
    /// The sheet's pages, once drawn.
    pages: Vec<SheetPage>,
    /// Draw every row on the sheet (a preset's or a set's candidates), paged as needed;
    /// else the first `--sheet` rows.
    draw_all: bool,
}

fn write_outputs(
    verb: SearchVerb,
    s: &Session,
    c: &Common,
    frames: &[usize],
    mut outputs: Vec<FrameOutput>,
    details: Value,
) -> Result<ExitCode> {
    let zoom = c.view.zoom().map_err(|e| anyhow!("--{e}"))?;
    let dir = out_dir(&c.out)?;
    let tree = &s.model.model.tree;
    let report_path = verb.report_path(&dir);
    let mut text = String::new();
    let mut report_frames = Vec::new();
    for (o, &i) in outputs.iter_mut().zip(frames) {
        let sheet = verb.sheet_path(&dir, &s.capture.frames[i].stem);
        let limit = if o.draw_all { o.rows.len() } else { c.sheet };
        let drawn = candidate_sheet(
            s,
            i,
            &o.rows,
            limit,
            &format!("{} {}", verb.stem(), o.frame),
            (&c.view, zoom),
        )?;
        if let Some(line) = zoom_note(&c.view, zoom, &drawn) {
            o.notes.push(line);
        }
        // With a crop or a zoom over 1 (a detail to judge), the frame alone as the tiles show it: one
        // image more a frame, only where it is asked for.
        let frame_alone = (c.view.crop.is_some() || zoom > 1.0)
            .then(|| verb.frame_alone_path(&dir, &s.capture.frames[i].stem));
        if let Some(path) = &frame_alone {
            save_png_rgb(&drawn.frame_alone, path)?;
            o.notes.push(format!(
                "the frame alone at the tiles' crop and scale: {}",
                path.display()
            ));
        }
        let mut sheet_pages = Vec::new();
        for (k, (page, ranks)) in drawn.pages.iter().enumerate() {
            // The first page is the report's sheet; further pages beside it.
            let p = if k == 0 {
                sheet.clone()
            } else {
                sheet.with_file_name(format!(
                    "{}_sheet_{}_p{}.png",
                    verb.stem(),
                    s.capture.frames[i].stem,
                    k + 1
                ))
            };
            save_png_rgb(page, &p)?;
            sheet_pages.push(SheetPage {
                path: p,
                ranks: ranks.clone(),
            });
        }
        // Which page draws which candidates, and which are not drawn.
        let drawn: usize = sheet_pages.iter().map(|p| p.ranks.len()).sum();
        if sheet_pages.len() > 1 || drawn < o.rows.len() {
            let mut line = format!("sheet: {} of {} candidates drawn", drawn, o.rows.len());
            for (k, p) in sheet_pages.iter().enumerate() {
                let name = p
                    .path
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                line.push_str(&format!(
                    "; page {}/{} ({name}): {}",
                    k + 1,
                    sheet_pages.len(),
                    rank_list(&p.ranks)
                ));
            }
            if drawn < o.rows.len() {
                let on_pages: Vec<usize> =
                    sheet_pages.iter().flat_map(|p| p.ranks.clone()).collect();
                let rest: Vec<usize> = o
                    .rows
                    .iter()
                    .map(|r| r.rank)
                    .filter(|k| !on_pages.contains(k))
                    .collect();
                line.push_str(&format!(
                    "; not drawn: {} (`draw: \"{}\"` draws them)",
                    rank_list(&rest),
                    rank_span(&rest)
                ));
            }
            o.notes.push(line);
        }
        o.pages = sheet_pages;
        let ranked: Vec<Candidate> = o
            .rows
            .iter()
            .map(|r| candidate(r, s.scale(), tree))
            .collect();
        text.push_str(&text_report(
            verb.stem(),
            &o.frame,
            &ranked,
            &o.notes,
            &report_path,
            &c.session.poses,
        ));
        text.push('\n');
        report_frames.push(SearchFrame {
            frame: o.frame.clone(),
            sheet,
            notes: o.notes.clone(),
            search: o.extra.clone(),
            pages: o.pages.clone(),
            ranked,
            frame_alone,
        });
    }
    let gates: Vec<f64> = outputs
        .iter()
        .filter_map(|o| o.rows.first().map(|r| r.score.gate))
        .collect();
    let report = SearchReport {
        verb,
        capture: c.session.capture.clone(),
        model: c.session.model.clone(),
        poses: c.session.poses.clone(),
        scale: s.scale(),
        depth_weight: c.depth_weight,
        frames: report_frames,
        mean_gate_iou: gates.iter().sum::<f64>() / gates.len().max(1) as f64,
        min_gate_iou: gates.iter().copied().reduce(f64::min),
        details,
        command: std::env::args().collect::<Vec<_>>().join(" "),
    };
    agentstar_data::atomic::write_json(&report_path, &report)?;
    agentstar_data::atomic::write_atomic(&verb.text_path(&dir), text.as_bytes())?;
    if c.json {
        print_json(&report)?;
    } else {
        print!("{text}");
        println!(
            "report: {} (and {}.txt, {}_sheet_*.png)",
            report_path.display(),
            verb.stem(),
            verb.stem()
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
        .map(|c| {
            let outside = if c.kept_start {
                outside_region(space, &c.pose, tree)
            } else {
                vec![]
            };
            Row {
            rank: c.rank,
            label: if c.kept_start {
                if outside.is_empty() {
                    agentstar_reports::KEPT_START.into()
                } else {
                    format!(
                        "{}, outside the region: {}",
                        agentstar_reports::KEPT_START,
                        outside.join(", ")
                    )
                }
            } else if c.runner_up {
                format!("seen {}", order_string(space, &c.x, tree))
            } else {
                order_string(space, &c.x, tree)
            },
            extra: json!({"restart": c.restart, "seed": c.seed, "pass": c.pass, "x": c.x, "kept_start": c.kept_start, "runner_up": c.runner_up, "unrefined": c.unrefined.map(|u| u.combined)}),
            pose: c.pose,
            score: c.score,
            model_ncc: None,
            neighbour_steps: vec![],
            outside_region: outside,
        }
        })
        .collect()
}

/// Where the start `pose` lies outside the region `space` names (an increment of 0, or its
/// joint state, not within a range): `lid_hinge 67 not in 100..125`, one per coordinate;
/// empty inside. A kept start outside the region is rank 0 only because nothing in the
/// region beat it (play-test 6 read it as the region's best).
fn outside_region(space: &SearchSpace, pose: &GenPose, tree: &KinematicTree) -> Vec<String> {
    space
        .ranges
        .iter()
        .filter_map(|r| {
            let v = match r.dof {
                Dof::Joint(j) => tree.joints()[j].to_interface(*pose.states.get(j)?),
                _ => 0.0,
            };
            (v < r.lo - 1e-9 || v > r.hi + 1e-9).then(|| {
                format!(
                    "{} {} not in {}..{}",
                    r.dof.name(tree),
                    fmt6(v),
                    fmt6(r.lo),
                    fmt6(r.hi)
                )
            })
        })
        .collect()
}

fn default_frame(s: &Session, spec: Option<&str>) -> Result<Vec<usize>> {
    match spec {
        None => Ok(vec![s.capture.ref_index]),
        Some(sp) => select_frames(&s.capture, Some(sp)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The zoom a sheet of `finalists` draws a crop `long` frame pixels long at, asked `zoom`.
    fn drawn(long: u32, zoom: f64, finalists: usize) -> CandidateSheet {
        let side = tile_side(long, zoom);
        let tile = RgbImage::new(side, side * 3 / 4);
        let tiles: Vec<(String, RgbImage)> = (0..finalists * TILES_PER_CANDIDATE)
            .map(|k| (format!("#{k}"), tile.clone()))
            .collect();
        let layout = sheet_layout(&tiles, TILES_PER_CANDIDATE, "osweep 000010.png");
        CandidateSheet {
            pages: vec![],
            crop: [10, 20, long, long * 3 / 4],
            zoom: side as f64 * layout.tile_factor / long as f64,
            frame_alone: RgbImage::new(1, 1),
        }
    }

    #[test]
    fn the_reply_says_the_zoom_the_tiles_came_out_at() {
        let view = |zoom: Option<f64>| agentstar_requests::SheetView {
            crop: None,
            zoom,
            draw: None,
        };
        // Play-test 15: a crop about the mask's box (480 px), zoom 2: the three tiles a row
        // keep the image limits, so the tiles come out near the size of an unzoomed sheet's.
        let plain = drawn(480, 1.0, 2);
        let zoomed = drawn(480, 2.0, 2);
        assert!(
            zoomed.zoom < 1.2 * plain.zoom,
            "{} vs {}",
            zoomed.zoom,
            plain.zoom
        );
        let note = zoom_note(&view(Some(2.0)), 2.0, &zoomed).expect("a note");
        assert!(
            note.starts_with(&format!(
                "sheet tiles: crop at (10, 20), 480×360 frame pixels, drawn at zoom {:.2} (zoom 2.00 asked",
                zoomed.zoom
            )),
            "{note}"
        );
        // A small crop takes the zoom asked (and more: tiles are at least 320 px long).
        let small = drawn(100, 2.0, 2);
        assert!(small.zoom >= 2.0, "{}", small.zoom);
        let note = zoom_note(&view(Some(2.0)), 2.0, &small).expect("a note");
        assert!(!note.contains("asked"), "{note}");
        // Neither asked: no note.
        assert_eq!(zoom_note(&view(None), 1.0, &plain), None);
    }
}
