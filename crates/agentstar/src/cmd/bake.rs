//! `agentstar bake`: the model's colours gathered from the keyframes at the committed poses
//! (`agentstar_track::bake`), stored beside the model file (`agentstar_data::bakefile`), which
//! every command then loads with the model. Refused, writing nothing, when frames disagree.

use crate::common::{open_capture, print_json, select_frames};
use agentstar_data::bakefile::{write_bake, BakeFile, BAKE_FORMAT};
use agentstar_data::history::{command_line, PoseHistory};
use agentstar_data::posefile::PoseFile;
use agentstar_data::scenefile::load_model_unbaked;
use agentstar_geom::ObjectModel;
use agentstar_reports::{BakeFrameRow, BakeReport};
use agentstar_requests::{BakeArgs, SessionArgs};
use agentstar_track::bake::{bake, Bake, BakeConfig, BakeFrame};
use anyhow::{anyhow, bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  agentstar bake --capture cap --model run/scene.rhai --poses run/pose.json\n  agentstar bake --capture cap --model run/scene.rhai --poses run/pose.json --frames 000000..000040 --json"
)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    #[command(flatten)]
    request: BakeArgs,
    /// Texels per model unit of length (default: the keyframes' resolution on the object,
    /// so a texel is about a pixel where the object is typically seen; lowered to fit an
    /// atlas of 2048×2048).
    #[arg(long)]
    texels_per_unit: Option<f64>,
    /// Bake and report, write nothing.
    #[arg(long)]
    dry_run: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

fn rows(b: &Bake) -> Vec<BakeFrameRow> {
    b.frames
        .iter()
        .map(|f| BakeFrameRow {
            frame: f.name.clone(),
            texels: f.texels,
            shared_texels: f.shared_texels,
            partners: f.partners,
            residual: f.residual,
            disagrees: f.disagrees,
        })
        .collect()
}

pub fn run(a: Args) -> Result<ExitCode> {
    if let Some(d) = a.texels_per_unit {
        if !(d.is_finite() && d > 0.0) {
            bail!("--texels-per-unit {d}: give a positive number of texels per model unit");
        }
    }
    let model_path = &a.session.model;
    let capture = open_capture(&a.session.capture)?;
    // Baked on the model as its file gives it, not on an earlier bake's colours.
    let loaded = load_model_unbaked(model_path)?;
    for w in &loaded.warnings {
        eprintln!("warning: {}: {w}", model_path.display());
    }
    let model = &loaded.model;
    let pose_file = PoseFile::read(&a.session.poses)?;
    let poses = pose_file
        .resolve(&capture, &model.tree)
        .map_err(|e| anyhow!("{}: {e}", a.session.poses.display()))?;
    let selected = select_frames(&capture, a.request.frames.as_deref())?;
    // A frame whose pose was never written is only the reference's pose carried through
    // the cameras: not a pose to bake from.
    let (posed, unposed): (Vec<usize>, Vec<usize>) =
        selected.into_iter().partition(|&i| !poses[i].seeded);
    let unposed: Vec<String> = unposed
        .iter()
        .map(|&i| capture.frames[i].name.clone())
        .collect();
    if !unposed.is_empty() {
        eprintln!(
            "bake: {} keyframe(s) have no written pose and are left out: {}",
            unposed.len(),
            unposed.join(", ")
        );
    }
    if posed.is_empty() {
        bail!(
            "{}: no selected keyframe has a written pose; track or commit poses first",
            a.session.poses.display()
        );
    }
    let mut images = Vec::with_capacity(posed.len());
    let mut masks = Vec::with_capacity(posed.len());
    let mut hands = Vec::with_capacity(posed.len());
    for &i in &posed {
        images.push(capture.load_frame(i)?);
        masks.push(capture.load_mask(i)?);
        hands.push(capture.load_hand(i)?);
    }
    let frames: Vec<BakeFrame> = posed
        .iter()
        .enumerate()
        .map(|(k, &i)| BakeFrame {
            name: &capture.frames[i].name,
            camera: &capture.frames[i].camera,
            rgb: images[k].as_raw(),
            mask: &masks[k],
            hand: hands[k].as_ref(),
            pose: &poses[i].generalised,
        })
        .collect();
    let cfg = BakeConfig {
        texels_per_unit: a.texels_per_unit,
        ..BakeConfig::default()
    };
    let b = bake(model, pose_file.scale, &frames, &cfg)
        .with_context(|| format!("baking {}", model_path.display()))?;
    let disagreeing: Vec<String> = b.disagreeing().iter().map(|f| f.name.clone()).collect();
    let pose_version = PoseHistory::new(&a.session.poses).version_of(&pose_file)?;
    let mut report = BakeReport {
        model: model_path.clone(),
        bake_file: None,
        atlas: None,
        atlas_width: b.layout.width,
        atlas_height: b.layout.height,
        texels_per_unit: b.layout.texels_per_unit,
        surface_texels: b.surface_texels,
        seen_texels: b.seen_texels,
        seen_fraction: b.seen_fraction(),
        multi_view_texels: b.multi_view_texels,
        spread: b.spread,
        pose_version,
        frames: rows(&b),
        disagreeing: disagreeing.clone(),
        unposed,
        forced: a.request.force && !disagreeing.is_empty(),
    };
    let refused = !disagreeing.is_empty() && !a.request.force;
    if !refused && !a.dry_run {
        let provenance = Provenance {
            capture: &a.session.capture,
            poses: &a.session.poses,
            pose_version,
            frames: frames.iter().map(|f| f.name.to_string()).collect(),
            forced: report.forced,
        };
        let (json, atlas) = store_bake(model_path, model, &b, provenance)?;
        report.atlas = Some(atlas);
        report.bake_file = Some(json);
    }
    if a.json {
        print_json(&report)?;
    } else {
        print_summary(&report, refused, a.dry_run);
    }
    if refused {
        let worst: Vec<String> = b
            .disagreeing()
            .iter()
            .map(|f| format!("{} ({:.0})", f.name, f.residual.unwrap_or(0.0)))
            .collect();
        let agreeing: Vec<&str> = b
            .agreeing()
            .iter()
            .map(|&k| b.frames[k].name.as_str())
            .collect();
        let keep = if agreeing.len() >= 2 {
            format!(
                " The largest set that agrees: --frames {}.",
                agreeing.join(",")
            )
        } else {
            " No two of them agree.".to_string()
        };
        eprintln!(
            "bake refused: frame(s) {} disagree with the others (median colour difference in 8-bit units, the worst first): their poses put the colours on other parts of the model than the rest do — a pose in a twin of the true one, or wrong. Baked from them, the error is locked into the model's colours. Check those poses, or leave them out with --frames; --force stores the bake anyway. Nothing was written.{keep}",
            worst.join(", ")
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// Where a bake's colours came from, as its bake file records it.
pub(crate) struct Provenance<'a> {
    pub capture: &'a Path,
    pub poses: &'a Path,
    /// The pose file's history version the poses came from.
    pub pose_version: Option<u64>,
    pub frames: Vec<String>,
    /// Stored although frames disagree.
    pub forced: bool,
}

/// Stores `b`, baked on `model` (the model as `model_path` gives it), beside the model file
/// through the bake file (atomically) with its provenance; returns the bake file's path and
/// its atlas image's. `bake` and `track --store-bake` both store through it.
pub(crate) fn store_bake(
    model_path: &Path,
    model: &ObjectModel,
    b: &Bake,
    p: Provenance<'_>,
) -> Result<(PathBuf, PathBuf)> {
    let disagreeing: Vec<String> = b.disagreeing().iter().map(|f| f.name.clone()).collect();
    let mut file = BakeFile {
        format: BAKE_FORMAT.into(),
        model: model_path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        tessellation: agentstar_geom::tessellation_fingerprint(model),
        atlas: String::new(),
        triangles: String::new(),
        atlas_width: b.layout.width,
        atlas_height: b.layout.height,
        texels_per_unit: b.layout.texels_per_unit,
        capture: p.capture.to_path_buf(),
        poses: p.poses.to_path_buf(),
        pose_version: p.pose_version,
        frames: p.frames,
        seen_fraction: b.seen_fraction(),
        spread: b.spread,
        disagreeing,
        forced: p.forced,
        command: command_line(),
        time_unix_s: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0),
    };
    let atlas = image::RgbaImage::from_raw(b.layout.width, b.layout.height, b.rgba.clone())
        .ok_or_else(|| anyhow!("the baked atlas is not its layout's size"))?;
    let json = write_bake(model_path, model, &mut file, &atlas)?;
    let atlas_path = json.with_file_name(&file.atlas);
    Ok((json, atlas_path))
}

fn print_summary(r: &BakeReport, refused: bool, dry_run: bool) {
    println!(
        "baked {} from {} frame(s): {} of {} texels seen ({:.1}%), atlas {}×{} at {:.1} texels per unit; colour spread over {} texels seen twice or more: {}; pose version {}",
        r.model.display(),
        r.frames.len(),
        r.seen_texels,
        r.surface_texels,
        100.0 * r.seen_fraction,
        r.atlas_width,
        r.atlas_height,
        r.texels_per_unit,
        r.multi_view_texels,
        r.spread.map_or("none".into(), |s| format!("{s:.1} (8-bit units)")),
        r.pose_version.map_or("none (the file is not its history's newest version)".into(), |v| v.to_string()),
    );
    for f in &r.frames {
        println!(
            "  {:<14} {:>8} texels  residual {:>6}  {}",
            f.frame,
            f.texels,
            f.residual.map_or("-".into(), |v| format!("{v:.1}")),
            if f.disagrees { "DISAGREES" } else { "" }
        );
    }
    match (&r.bake_file, refused, dry_run) {
        (Some(p), _, _) => println!(
            "wrote {} ({}); every command loading {} now draws and tracks with these colours",
            p.display(),
            r.atlas
                .as_ref()
                .map_or(String::new(), |a| a.display().to_string()),
            r.model.display()
        ),
        (None, true, _) => println!("refused: nothing written"),
        (None, _, true) => println!("dry run: nothing written"),
        _ => {}
    }
}
