//! Shape tools: `fit_shape` (named parameters against the masks) and `scale`.

use super::*;
use crate::{AgentError, Result};
use agentstar_data::history::PoseHistory;
use agentstar_data::posefile::PoseFile;
use agentstar_render::GATE_IOU;
use agentstar_requests::{ScaleMethod, SizeAxis};
use schemars::JsonSchema;
use serde::Deserialize;
use std::collections::BTreeMap;

/// Whether a fitted parameter moved by more than a thousandth of its range.
pub(super) fn param_moved(p: &agentstar_reports::fit::FitParam) -> bool {
    (p.after - p.before).abs() > 1e-3 * (p.max - p.min)
}

/// The line a fit adds when some parameters moved and others did not (play-test 7: 9 of
/// 10 stayed at their values, and one restarted elsewhere by hand gained 0.05 IoU); `None`
/// when all moved or none did (then [`fit_saves_nothing`] says why).
pub(super) fn unmoved_line(report: &agentstar_reports::fit::FitReport) -> Option<String> {
    let unmoved: Vec<&str> = report
        .params
        .iter()
        .filter(|p| !param_moved(p))
        .map(|p| p.name.as_str())
        .collect();
    (!unmoved.is_empty() && unmoved.len() < report.params.len()).then(|| {
        format!(
            "did not move: {}. Along these the IoU is flat or at a local optimum at these poses; where the silhouettes still disagree there, set another value in the script (scene_write) and fit them again, alone.\n",
            unmoved.join(", ")
        )
    })
}

/// Why a shape fit's result is not saved, if it is not: no parameter moved by more than a
/// thousandth of its range (the gain, if any, came from refining the poses alone: play-test,
/// 2026-12-02, a fit from wrong poses saved an unchanged scene as a new version), or the
/// mean IoU did not rise.
pub(super) fn fit_saves_nothing(
    report: &agentstar_reports::fit::FitReport,
) -> Option<&'static str> {
    let moved = report.params.iter().any(param_moved);
    if !moved {
        Some("No parameter moved: at these poses (held, refined only locally) no change of the parameters raises the IoU. That does not make the shape right: poses fitted to a wrong shape hold it where it is, and any rise of the mean above came from refining the poses alone. The scene and pose.json are unchanged (no version saved). If the silhouettes still disagree, change the shape by hand (scene_write), track from pose.json, then fit again.\n")
    } else if report.iou_mean_after <= report.iou_mean_before + 1e-4 {
        Some("The fit did not raise the mean IoU: the scene and pose.json are unchanged.\n")
    } else {
        None
    }
}

/// A list of names, or one string of names separated by commas (play-test 18 wrote
/// `"radius,lid_h"` as every other list of the tools is written).
fn names_or_comma_list<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Names {
        List(Vec<String>),
        Text(String),
    }
    Ok(match Names::deserialize(d)? {
        Names::List(v) => v,
        Names::Text(t) => t
            .split(',')
            .map(str::trim)
            .filter(|n| !n.is_empty())
            .map(str::to_string)
            .collect(),
    })
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FitShapeArgs {
    /// The parameters to fit: names of the scene's `param("name", value, min, max)` calls (a list; `"a,b"` is read as the list of a and b, as `frames` is). Only these move, and only within their bounds; every other parameter keeps its value.
    #[schemars(length(min = 1, max = 12))]
    #[serde(deserialize_with = "names_or_comma_list")]
    pub params: Vec<String>,
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Rounds of (parameters with the poses held, then every pose refined locally); default 3.
    #[schemars(range(min = 1, max = 10))]
    pub rounds: Option<u64>,
    /// Model builds per round (default 60).
    #[schemars(range(min = 5, max = 500))]
    pub evals: Option<u64>,
    /// The part kept in place when the poses are carried to each new shape (a part of the
    /// scene). Default: the part with the most visible pixels in the keyframes.
    #[schemars(length(min = 1))]
    pub hold: Option<String>,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ScaleArgs {
    /// `depth` (the capture's depth against the render), `parallax` (metric cameras moving around an object that stays put), `size` (give `axis` and `metres`) or `hand` (the hands' palm breadth in their masks against an adult hand, the hand at the object's depth: without depth or a known size only; its uncertainty, often ±10–20%, is stated).
    pub method: ScaleMethod,
    /// With `size`: the model axis the size is along (default the longest side).
    pub axis: Option<SizeAxis>,
    /// With `size`: the object's size along `axis`, metres ("the laptop is 30 cm wide": axis x, metres 0.3).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub metres: Option<f64>,
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Rescale pose.json to the estimate (a pose version); default false: estimate only.
    pub apply: Option<bool>,
}

tool!(FitShape, "fit_shape", Shape, Scene, FitShapeArgs,
    "Fit shape parameters the scene declares with `let d = param(\"depth\", 0.6, 0.4, 0.9);` (value, min, max) against the committed poses over the keyframes (default all): only the parameters you name move, within their bounds, while every keyframe's pose is refined locally. Returns the values, the IoU change per keyframe and before/after silhouette comparisons; when the mean IoU rises, the fitted values become the script's `param` values (a new scene version) and the refined poses a pose version. Fit proportions you judged wrong by eye on poses that are right otherwise; then look at a turntable (a shape that games IoU from these views can still be wrong in 3-D). Also returns the residuals grouped by viewing direction (frames face-on to each model axis, and what size change along X, Y, Z they want) and, where the axes disagree, the fixed proportion they point at.",
    |tb, a, step| tb.fit_shape(&a, step));

tool!(Scale, "scale", Pose, Poses, ScaleArgs,
    "Estimate the scale (metres per model unit) from the capture's depth, from the parallax of metric cameras moving around an object that stays put, from a size you state along a model axis, or from the hands holding it (their palm breadth in the hand masks against an adult hand's, about 7.9 cm: the weakest route, its uncertainty stated; use it when there is no depth, the object moves and you know no size); with `apply: true` rescale pose.json to it (rotations kept, translations scaled, so every silhouette and IoU stays the same; a pose version). Silhouettes never say the scale: use this before reporting metric results.",
    |tb, a, step| tb.scale(&a, step));

impl Toolbox {
    /// `scale`: `agentstar scale`, its rescaled poses committed as a pose version when asked.
    pub(super) fn scale(&self, a: &ScaleArgs, step: u64) -> Result<ToolOutput> {
        let apply = a.apply.unwrap_or(false);
        if apply && self.window.is_some() {
            return Ok(ToolOutput::error(
                "a pose sub-agent cannot rescale every keyframe",
            ));
        }
        let out = self.run.step_dir(step, Scale::NAME);
        std::fs::create_dir_all(&out).map_err(|e| agentstar_data::DataError::io(&out, e))?;
        let scaled = out.join("scaled_pose.json");
        #[derive(serde::Serialize)]
        struct ScaleRequest<'a> {
            from: ScaleMethod,
            out: &'a Path,
            json: bool,
            axis: Option<SizeAxis>,
            metres: Option<f64>,
            frames: Option<&'a str>,
        }
        let request = ScaleRequest {
            from: a.method,
            out: &scaled,
            json: true,
            axis: a.axis,
            metres: a.metres,
            frames: nonblank(&a.frames),
        };
        let call = Invocation::new(&["scale"])
            .with(&self.session())?
            .with(&request)?;
        let method = a.method.as_str();
        let (ok, stdout, stderr) = self.exec(call.args())?;
        if !ok {
            return Ok(ToolOutput::error(failure_text(&stderr)));
        }
        let report: agentstar_reports::fit::ScaleReport =
            serde_json::from_str(&stdout).map_err(|e| {
                AgentError::Tool(format!("scale printed no scale report ({e}): {stdout}"))
            })?;
        let mut text = format!(
            "scale from {method}: {} → {:.6} m per model unit (translations × {:.4}; spread {:.2}%, {} sample(s){})\n",
            report.scale_before,
            report.scale_after,
            report.ratio,
            100.0 * report.spread,
            report.samples,
            match report.uncertainty {
                Some(u) => format!(
                    "; ± {:.0}% one standard deviation: {:.6} to {:.6} m per unit",
                    100.0 * u,
                    report.scale_after * (1.0 - u),
                    report.scale_after * (1.0 + u)
                ),
                None => String::new(),
            }
        );
        for n in &report.notes {
            text.push_str(&format!("note: {n}\n"));
        }
        let mut scores = BTreeMap::new();
        scores.insert("scale".to_string(), report.scale_after);
        let structured = serde_json::to_value(&report).ok();
        if !apply {
            text.push_str(if !report.weak {
                "pose.json is unchanged; call scale again with `apply: true` to rescale it.\n"
            } else {
                // A play-test agent was offered a parallax estimate of an object moving in
                // the world (spread 61%) with the same line as a sound one.
                "pose.json is unchanged. The notes above say this estimate is weak: apply it only if you can rule them out. Otherwise state a size you can judge in the frames (method `size` with `axis` and `metres`), or use depth where the capture has it.\n"
            });
            return Ok(ToolOutput {
                text,
                scores,
                structured,
                ..Default::default()
            });
        }
        let pf = PoseFile::read(&scaled)?;
        let version = PoseHistory::new(&self.run.poses).replace(
            pf,
            &format!(
                "scale from {method} (step {step}): {} -> {:.6} m per unit",
                report.scale_before, report.scale_after
            ),
        )?;
        text.push_str(&format!(
            "pose.json rescaled (version {version}); every IoU is as it was.\n"
        ));
        Ok(ToolOutput {
            text,
            scores,
            structured,
            pose_changed: true,
            pose_version: Some(version),
            ..Default::default()
        })
    }

    /// `fit_shape`: `agentstar fit-shape` in the step's directory; when the mean IoU rose,
    /// its script becomes the scene (a new version) and its poses a pose version. Runs
    /// under the writer lock.
    pub(super) fn fit_shape(&self, a: &FitShapeArgs, step: u64) -> Result<ToolOutput> {
        if self.window.is_some() {
            return Ok(ToolOutput::error(
                "a pose sub-agent cannot change the shape",
            ));
        }
        let names: Vec<String> = a.params.iter().map(|p| p.trim().to_string()).collect();
        if let Some(bad) = names.iter().find(|n| n.is_empty() || n.contains(',')) {
            return Ok(ToolOutput::error(format!(
                "fit_shape: `{bad}` is not a parameter name (one name per list entry)"
            )));
        }
        #[derive(serde::Serialize)]
        struct FitRequest<'a> {
            params: String,
            frames: Option<&'a str>,
            rounds: Option<u64>,
            evals: Option<u64>,
            hold: Option<&'a str>,
        }
        let request = FitRequest {
            params: names.join(","),
            frames: nonblank(&a.frames),
            rounds: a.rounds,
            evals: a.evals,
            hold: nonblank(&a.hold),
        };
        let (o, _, stdout) = self.cli(&["fit-shape"], step, FitShape::NAME, &request)?;
        if o.is_error {
            return Ok(o);
        }
        let report: agentstar_reports::fit::FitReport =
            serde_json::from_str(&stdout).map_err(|e| {
                AgentError::Tool(format!("fit-shape printed no fit report ({e}): {stdout}"))
            })?;
        let values: Vec<String> = report
            .params
            .iter()
            .map(|p| {
                format!(
                    "{} {} → {} (bounds [{}, {}]{})",
                    p.name,
                    agentstar_scene::format_param_value(p.before),
                    agentstar_scene::format_param_value(p.after),
                    p.min,
                    p.max,
                    if p.at_bound { ", AT A BOUND" } else { "" }
                )
            })
            .collect();
        let mut text = format!(
            "fit_shape: {}\nvisible IoU over {} keyframe(s): mean {:.4} → {:.4}, min {:.4} → {:.4}\n",
            values.join("; "),
            report.frames.len(),
            report.iou_mean_before,
            report.iou_mean_after,
            report.iou_min_before,
            report.iou_min_after
        );
        if let Some(line) = unmoved_line(&report) {
            text.push_str(&line);
        }
        if let Some(part) = &report.held_part {
            text.push_str(&format!(
                "poses carried to each shape holding part {part} in place\n"
            ));
        }
        if !report.held.is_empty() {
            text.push_str(&format!(
                "held as they are: {}\n",
                report
                    .held
                    .iter()
                    .map(|h| format!(
                        "{} {}",
                        h.name,
                        agentstar_scene::format_param_value(h.value)
                    ))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        for f in &report.frames {
            let band = f
                .iou_band_after
                .map(|b| format!("  (band {b:.4})"))
                .unwrap_or_default();
            text.push_str(&format!(
                "  {}  {:.4} → {:.4}{band}\n",
                f.frame, f.iou_before, f.iou_after
            ));
        }
        if let Some(line) = agentstar_reports::fit::unmet_line(&report.unmet) {
            text.push_str(&line);
        }
        if let Some(line) = agentstar_reports::fit::unseen_line(&report.unseen) {
            text.push_str(&line);
        }
        if let Some(v) = &report.views {
            text.push_str(&agentstar_reports::fit::views_text(v));
            if !v.verdict.is_empty() && fit_saves_nothing(&report).is_some() {
                // Play-test: a fit came back to its start with no hint that the error was
                // one fixed proportion the fitted parameters do not set.
                text.push_str("The fit came back near its start while the frames point at a fixed proportion: the parameters fitted do not set it, or the poses hold the wrong shape where it is. Change that proportion in the script (scene_write, or declare a `param` for it and fit that), then `track` from pose.json and fit again.\n");
            }
        }
        let mut scores = BTreeMap::new();
        scores.insert("iou_mean_before".to_string(), report.iou_mean_before);
        scores.insert("iou_mean_after".to_string(), report.iou_mean_after);
        let images = report.sheets.clone();
        let structured = serde_json::to_value(&report).ok();
        let under_gate = report
            .frames
            .iter()
            .filter(|f| f.gate_after() < GATE_IOU)
            .count();
        if let Some(why) = fit_saves_nothing(&report) {
            text.push_str(why);
            if under_gate > 0 {
                text.push_str(&format!(
                    "{under_gate} keyframe(s) stay under the {GATE_IOU} gate (band IoU, as `score` reads it): a shape fit cannot repair a pose in a wrong basin (a flip or a twin). Check `temporal` for large steps and try the flips (`osweep`) or `track` with trusted anchors before fitting again.\n"
                ));
            }
            return Ok(ToolOutput {
                text,
                images,
                scores,
                structured,
                ..Default::default()
            });
        }
        let script = agentstar_data::read_text(&report.scene)?;
        let written = self.scene_write(&script, nonblank(&a.hold), step)?;
        if written.is_error {
            return Ok(written);
        }
        let fitted = PoseFile::read(&report.poses)?;
        let pose_version = PoseHistory::new(&self.run.poses).replace(
            fitted,
            &format!(
                "fit_shape (step {step}): poses refined for scene version {}",
                written.scene_version.unwrap_or(0)
            ),
        )?;
        text.push_str(&format!(
            "scene version {} saved with the fitted values; pose.json version {pose_version} holds the refined poses. Look at a `turntable` before finishing.\n",
            written.scene_version.unwrap_or(0)
        ));
        if let Some(r) = self.mechanism_reminder() {
            text.push_str(&r);
            text.push('\n');
        }
        Ok(ToolOutput {
            text,
            images,
            scores,
            scene_version: written.scene_version,
            pose_changed: true,
            pose_version: Some(pose_version),
            structured,
            ..Default::default()
        })
    }
}
