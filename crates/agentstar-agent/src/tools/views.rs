//! View tools: `render`, `frames`, `score` and `turntable`.

use super::*;
use crate::{AgentError, Result};
use agentstar_render::GATE_IOU;
use agentstar_reports::view::{RenderReport, TurntableReport};
use agentstar_requests::{Crop, TurntableArgs};
use schemars::JsonSchema;
use serde::Deserialize;

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RenderArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Comma separated: overlay, compare, ids, shaded, side (the keyframe cropped around its
    /// mask beside the model rendered opaque over the same crop, with a sheet: to compare a
    /// print without one showing through the other; the hand mask hatched in cyan on both
    /// halves, so the model's parts a hand hides show). Default overlay,compare.
    pub views: Option<String>,
    /// Output pixels per frame pixel of every view's crop (1 to 8; default 1): to look at a
    /// detail of a few pixels (a hole, a letter). Above 1 the overlay and ids are cropped
    /// too; reduced where an image would pass the size limits.
    #[schemars(range(min = 1.0, max = 8.0))]
    pub zoom: Option<f64>,
    /// What the views show: `mask` (around the mask and the model; default) or
    /// `x0,y0,x1,y1`, a box in frame pixels (the crops' positions are in the reply).
    pub crop: Option<Crop>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FramesArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
}

/// What the keyframe view draws over the raw pixels.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Outline {
    /// The raw pixels only.
    None,
    /// The object mask's boundary (magenta) and the hand mask's (cyan).
    Mask,
    /// The posed model's silhouette boundary (yellow).
    Model,
    /// Both.
    Both,
}

impl Outline {
    fn as_str(self) -> &'static str {
        match self {
            Outline::None => "none",
            Outline::Mask => "mask",
            Outline::Model => "model",
            Outline::Both => "both",
        }
    }
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct KeyframesArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Margin around the mask's box, a fraction of its longer side (default 0.25).
    #[schemars(range(min = 0.0, max = 4.0))]
    pub margin: Option<f64>,
    /// Scale of the crop: 1 = the frame's own pixels (default), up to 8 to look at thin
    /// parts; reduced where an image would pass the size limits.
    #[schemars(range(min = 0.1, max = 8.0))]
    pub zoom: Option<f64>,
    /// Boundaries drawn over the raw pixels (default none).
    pub outline: Option<Outline>,
    /// What the crops show: `mask` (around the mask; default) or `x0,y0,x1,y1`, a box in
    /// frame pixels, e.g. around a 10-pixel detail, with `zoom` up to 8.
    pub crop: Option<Crop>,
    /// Also the posed model with its own colours, opaque, beside each crop at the same
    /// crop and zoom (to compare a print, a hole, letters), with a sheet of them.
    pub model: Option<bool>,
}

tool!(Render, "render", Diagnostic, Nothing, RenderArgs,
    "Render the posed model into keyframes (each frame's text says which side of the model and of each part faces the camera, with angles): `overlay` (shaded model over the frame) and `compare` (silhouette comparison: green model and mask agree, magenta mask not covered by the model, yellow model outside the mask, grey hand (ignored), blue model under the hand, on a near-black background; the legend is on each image), `ids` (parts in flat colours, visible pixels each). With `overlay`, also a contact sheet of the overlays; with `compare`, a sheet of every frame's comparison cropped around mask and model. `zoom` (up to 8) and `crop` (`mask`, or a box `x0,y0,x1,y1` in frame pixels) apply to every view, to judge a detail of a few pixels; a sheet draws each crop at one size, so a crop of a small box zooms its tiles and `zoom` the per-frame images. For the raw keyframes without the model, use `frames`.",
    |tb, a, step| {
        let request = RenderRequest {
            frames: nonblank(&a.frames),
            views: nonblank(&a.views).unwrap_or("overlay,compare"),
            zoom: a.zoom,
            crop: a.crop,
            ..Default::default()
        };
        let (mut o, out, report) = match request.run(tb, Render::NAME, step)? {
            Ok(done) => done,
            Err(failed) => return Ok(failed),
        };
        let written = o.images.len();
        o.images.truncate(MAX_IMAGES_RETURNED);
        let mut text = format!(
            "render: wrote {written} image(s) in {}; {} returned (sheets first){}",
            out.display(),
            o.images.len(),
            if written > o.images.len() { "; the rest are files there" } else { "" }
        );
        text.push_str(&crop_lines(&report));
        let facing: Vec<_> = report.frames.iter().filter_map(|f| f.facing.clone()).collect();
        text.push('\n');
        text.push_str(&agentstar_reports::view::facing_lines(&facing));
        for n in &report.notes {
            text.push_str(&format!("note: {n}\n"));
        }
        o.text = text;
        Ok(o)
    });

tool!(Keyframes, "frames", Diagnostic, Nothing, KeyframesArgs,
    "Look at the raw keyframes (the input itself, no model): each keyframe cropped around its object mask with a margin, optionally zoomed (to judge thin parts: an edge, a handle) or cropped to a box of frame pixels (`crop`: a 10-pixel hole, 15-pixel letters), with the posed model in its own colours beside each crop at the same zoom (`model: true`: prints, holes and letters compared without one showing through the other), and outlined (`mask`: the mask's boundary in magenta and the hand's in cyan; `model`: the posed model's boundary in yellow). Returns sheets of the crops (each labelled with the frame and the crop's position in the frame) and, for a few frames, the crops themselves.",
    |tb, a, step| {
        let request = RenderRequest {
            frames: nonblank(&a.frames),
            views: if a.model.unwrap_or(false) { "frame,side" } else { "frame" },
            margin: a.margin,
            zoom: a.zoom,
            outline: a.outline.map(Outline::as_str),
            crop: a.crop,
        };
        let (mut o, out, report) = match request.run(tb, Keyframes::NAME, step)? {
            Ok(done) => done,
            Err(failed) => return Ok(failed),
        };
        let crops = report.frames.len();
        let sheets = report.sheets.len();
        o.images.truncate(MAX_IMAGES_RETURNED);
        let mut text = format!(
            "frames: {crops} keyframe crop(s) and {sheets} sheet(s) in {}; {} image(s) returned (sheets first){}",
            out.display(),
            o.images.len(),
            if crops + sheets > o.images.len() {
                "; the rest are files there"
            } else {
                ""
            }
        );
        text.push_str(&crop_lines(&report));
        for n in &report.notes {
            text.push_str(&format!("\nnote: {n}"));
        }
        o.text = text;
        Ok(o)
    });

tool!(Score, "score", Diagnostic, Nothing, FramesArgs,
    "Per keyframe: band IoU (the visible IoU without ±2 px around the mask's outline, where segmenters err: the gate is 0.98 on it), visible IoU (hands excluded), raw IoU, pixel counts, depth error when the capture has depth, and the appearance figure (colour agreement with the neighbouring keyframes and, where the model's parts differ in colour, with the model's own colours, pooled), with the agreement with the model's own colours alone beside it (`model_ncc`: does the pose put the model's print where the frame shows it) and with its colour boundaries alone (`model_regions`); where the model's colours as painted explain under half of what their boundaries do over the keyframes showing its print, it says they are no likeness of the frames (the parts painted otherwise than the frames show them, or poses in twins). Lists the keyframes under the gate, and per keyframe which side of the model (+X … −Z, with each axis's angle to the camera ray: face-on or edge-on) and of each part (at its joint states) faces the camera. Names a part that lies off the object mask in some keyframes and on it in others (a part modelled rigid that moves against the body, or a joint wrong there).",
    |tb, a, _step| {
        let report = tb.score_report(a.frames.as_deref())?;
        let mut o = ToolOutput::default();
        let mut head = format!("score: {} keyframe(s)", report.frames.len());
        if !report.frames.is_empty() {
            let gates: Vec<f64> = report.frames.iter().map(|f| f.gate()).collect();
            let min = gates.iter().copied().fold(1.0, f64::min);
            let mean = gates.iter().sum::<f64>() / gates.len() as f64;
            let below: Vec<&str> = report
                .frames
                .iter()
                .filter(|f| f.gate() < GATE_IOU)
                .map(|f| f.frame.as_str())
                .collect();
            o.scores.insert("iou_min".into(), min);
            o.scores.insert("iou_mean".into(), mean);
            head.push_str(&format!(
                ", gate IoU (visible, boundary band excluded) mean {mean:.4}, min {min:.4}; under the gate: {}",
                if below.is_empty() { "none".to_string() } else { below.join(", ") }
            ));
        }
        // The table a person reads; the report's numbers are the structured content.
        o.text = format!(
            "{head}\n{}{}{}",
            agentstar_reports::score_table(
                &report.frames,
                &report.sequence,
                &report.appearance,
                report.model_colours.as_ref(),
            ),
            agentstar_reports::view::facing_lines(&report.facing),
            agentstar_reports::parts::parts_off_mask_text(&report.parts_off_mask)
        );
        o.structured = serde_json::to_value(&report).ok();
        Ok(o)
    });

tool!(Turntable, "turntable", Diagnostic, Nothing, TurntableArgs,
    "Eight views around the upright model (canonical +Z up) on a light background, one sheet per joint state: by default each joint's min, median and max over the keyframes (`states`: `all` or keyframes for others). The 3-D shape check after every shape step: parts floating, intersecting or missing from the back, and joints that move the wrong part or the wrong way. A joint piled at a limit is warned of; once checked, `acknowledge_limits: true` turns that warning into one line in later replies.",
    |tb, a, step| {
        let request = TurntableArgs { acknowledge_limits: false, ..a.clone() };
        let (mut o, out, stdout) = tb.cli(&["turntable"], step, Turntable::NAME, &request)?;
        if o.is_error {
            return Ok(o);
        }
        let report: TurntableReport = serde_json::from_str(&stdout)
            .map_err(|e| AgentError::Tool(format!("turntable printed no turntable report ({e})")))?;
        o.images = report.sheets.clone();
        o.images.truncate(MAX_IMAGES_RETURNED);
        let mut text = format!(
            "turntable: {} sheet(s) for {} joint state(s) in {}; {} returned",
            report.sheets.len(),
            report.states.len(),
            out.display(),
            o.images.len()
        );
        for st in &report.states {
            let joints: Vec<String> = st.joints.iter().map(|(k, v)| format!("{k} = {v:.2}")).collect();
            text.push_str(&format!(
                "\n- {} ({}): {}",
                st.label,
                st.source,
                if joints.is_empty() { "no joints".to_string() } else { joints.join(", ") }
            ));
        }
        let acknowledged = tb.acknowledged_limits()?;
        for w in report.warnings.iter().chain(&acknowledged.lines(&report.at_limit)) {
            text.push_str(&format!("\nwarning: {w}"));
        }
        if a.acknowledge_limits {
            text.push('\n');
            text.push_str(&tb.acknowledge_limits(&report.at_limit)?);
        }
        o.text = text;
        Ok(o)
    });

/// What `render` is asked for by `render`, `frames` and `critic` (its flags of the same names).
#[derive(Debug, Default, serde::Serialize)]
pub(super) struct RenderRequest<'a> {
    pub(super) frames: Option<&'a str>,
    pub(super) views: &'a str,
    pub(super) margin: Option<f64>,
    pub(super) zoom: Option<f64>,
    pub(super) outline: Option<&'static str>,
    pub(super) crop: Option<Crop>,
}

impl RenderRequest<'_> {
    /// Runs `render` for the tool `tool` and reads its report: the output (with the images
    /// it wrote), the step's folder and the report; `Err` with the tool's answer where the
    /// command failed.
    pub(super) fn run(
        &self,
        tb: &Toolbox,
        tool: &str,
        step: u64,
    ) -> Result<std::result::Result<(ToolOutput, PathBuf, RenderReport), ToolOutput>> {
        let (o, out, stdout) = tb.cli(&["render"], step, tool, self)?;
        if o.is_error {
            return Ok(Err(o));
        }
        let report: RenderReport = serde_json::from_str(&stdout)
            .map_err(|e| AgentError::Tool(format!("render printed no render report ({e})")))?;
        Ok(Ok((o, out, report)))
    }
}

/// One line per frame of a render report that was cropped or zoomed: where its crop lies in
/// the frame and at what zoom (each line starts with a line break).
fn crop_lines(report: &RenderReport) -> String {
    let mut text = String::new();
    for f in &report.frames {
        if let (Some([x, y, w, h]), Some(z)) = (f.crop, f.zoom) {
            text.push_str(&format!(
                "\n- {}: crop at ({x}, {y}), {w}×{h} frame pixels, zoom {z:.2}",
                f.frame
            ));
        }
    }
    if !text.is_empty() {
        // Play-test 14 read positions off a crop and gave them to `crop` as frame pixels.
        text.push_str(
            "\n(in a crop image, pixel (u, v) is frame pixel (x + u / zoom, y + v / zoom), with the crop's (x, y) above; `crop` takes frame pixels. A sheet's tiles are scaled to fit it: read positions off the crop images)",
        );
    }
    text
}
