//! `agentstar render`: views of the posed model in chosen frames.

use crate::common::{out_dir, print_json, select_frames, SessionArgs};
use agentstar_data::images::{save_png_rgb, save_png_rgba};
use agentstar_render::views::{
    comparison_legend, contact_sheet, id_color, overlay, part_id_view, shade,
    silhouette_comparison, with_legend, ShadeOptions,
};
use anyhow::{bail, Result};
use rayon::prelude::*;
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;

pub const VIEWS: [&str; 5] = ["overlay", "compare", "ids", "shaded", "depth"];

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar render --capture cap --model run/scene.rhai --poses run/pose.json --out views --views overlay,compare --frames 000000..000020"
)]
pub struct Args {
    #[command(flatten)]
    session: SessionArgs,
    /// Frames: `all` (default), names, stems, indices or `a..b` ranges, comma separated.
    #[arg(long)]
    frames: Option<String>,
    /// Views, comma separated: overlay, compare, ids, shaded, depth.
    #[arg(long, default_value = "overlay,compare")]
    views: String,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Draw no outlines on the shaded render.
    #[arg(long)]
    no_outlines: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// What one frame's rendering produced: its name, files, visible IoU and overlay tile.
type FrameViews = (String, Vec<PathBuf>, Option<f64>, image::RgbImage);

pub fn run(a: Args) -> Result<ExitCode> {
    let views: Vec<&str> = a
        .views
        .split(',')
        .map(str::trim)
        .filter(|v| !v.is_empty())
        .collect();
    for v in &views {
        if !VIEWS.contains(v) {
            bail!("unknown view `{v}`; views are {}", VIEWS.join(", "));
        }
    }
    let s = a.session.open()?;
    let frames = select_frames(&s.capture, a.frames.as_deref())?;
    let dir = out_dir(&a.out)?;
    let colors: Vec<[f32; 3]> = s.model.model.parts.iter().map(|p| p.color).collect();
    let names = s.model.model.part_names();
    let opts = ShadeOptions {
        outlines: !a.no_outlines,
    };
    let bar = crate::common::progress(frames.len(), "render");
    let results: Vec<Result<FrameViews>> = frames
        .par_iter()
        .map(|&i| {
            bar.inc(1);
            let f = &s.capture.frames[i];
            let buffers = s.render_buffers(i);
            let shaded = shade(&buffers, &colors, opts);
            let mut written = Vec::new();
            let mut iou = None;
            let frame_img = s.capture.load_frame(i)?;
            let over = overlay(&frame_img, &shaded, 0.6);
            if views.contains(&"overlay") {
                let p = dir.join(format!("overlay_{}.png", f.stem));
                save_png_rgb(&over, &p)?;
                written.push(p);
            }
            if views.contains(&"compare") {
                let mask = s.capture.load_mask(i)?;
                let hand = s.capture.load_hand(i)?;
                let sil = buffers.silhouette();
                let score =
                    agentstar_render::ScoreTarget::new(mask.clone(), hand.clone())?.score(&sil);
                iou = score.iou_visible;
                let (img, _) = silhouette_comparison(&sil, &mask, hand.as_ref());
                let title = format!(
                    "{}  IoU visible {}  raw {:.4}",
                    f.name,
                    score
                        .iou_visible
                        .map_or("n/a".into(), |v| format!("{v:.4}")),
                    score.iou_raw
                );
                let p = dir.join(format!("compare_{}.png", f.stem));
                save_png_rgb(
                    &with_legend(&img, &title, &comparison_legend(hand.is_some())),
                    &p,
                )?;
                written.push(p);
            }
            if views.contains(&"ids") {
                let (img, vis) = part_id_view(&buffers, &names);
                let legend: Vec<_> = vis
                    .iter()
                    .enumerate()
                    .map(|(k, v)| (id_color(k), format!("{} {}px", v.name, v.pixels)))
                    .collect();
                let p = dir.join(format!("ids_{}.png", f.stem));
                save_png_rgb(&with_legend(&img, &f.name, &legend), &p)?;
                written.push(p);
            }
            if views.contains(&"shaded") {
                let p = dir.join(format!("shaded_{}.png", f.stem));
                save_png_rgba(&shaded, &p)?;
                written.push(p);
            }
            if views.contains(&"depth") {
                let p = dir.join(format!("depth_{}.npy", f.stem));
                write_depth_npy(&p, &buffers)?;
                written.push(p);
            }
            Ok((f.name.clone(), written, iou, over))
        })
        .collect();
    let mut rows = Vec::new();
    let mut tiles = Vec::new();
    for r in results {
        let (name, written, iou, over) = r?;
        tiles.push((
            match iou {
                Some(v) => format!("{name} {v:.3}"),
                None => name.clone(),
            },
            over,
        ));
        rows.push(json!({"frame": name, "files": written, "iou_visible": iou}));
    }
    let sheet = dir.join("sheet_overlay.png");
    if views.contains(&"overlay") && !tiles.is_empty() {
        let cols = (tiles.len() as f64).sqrt().ceil() as usize;
        save_png_rgb(&contact_sheet(&tiles, cols, "render over frame"), &sheet)?;
    }
    if a.json {
        print_json(&json!({"out": dir, "frames": rows, "sheet": sheet}))?;
    } else {
        println!(
            "rendered {} frame(s) into {} ({})",
            rows.len(),
            dir.display(),
            views.join(", ")
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Planar depth as float32 `.npy`, `+inf` where no geometry is seen (as the reference writes).
fn write_depth_npy(path: &std::path::Path, b: &agentstar_render::RenderBuffers) -> Result<()> {
    use npyz::WriterBuilder;
    let mut buf = Vec::new();
    {
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&[b.height as u64, b.width as u64])
            .writer(&mut buf)
            .begin_nd()?;
        w.extend(b.depth.iter().copied())?;
        w.finish()?;
    }
    agentstar_data::atomic::write_atomic(path, &buf)?;
    Ok(())
}
