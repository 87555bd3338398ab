//! Ending a run: `critic`, `notes` and `finish` with its gates (IoU with reasons, the
//! turntable and temporal checks, the large steps looked at, the mechanism picks).

use super::*;
use crate::Result;
use agentstar_render::GATE_IOU;
use schemars::JsonSchema;
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CriticArgs {
    /// One keyframe.
    #[schemars(length(min = 1))]
    pub frame: String,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NotesArgs {
    #[schemars(length(min = 1, max = 4000))]
    pub text: String,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FinishArgs {
    /// Keyframes (a name, stem, number or `a..b` range) → why they cannot reach the gate,
    /// one of the categories.
    pub unreachable: Option<BTreeMap<String, Unreachable>>,
    /// Each large step of the `temporal` report (over 90°) you checked: `A->B` (the step as
    /// `temporal` prints it; names or stems) → what you found, e.g. `oapply on B: no twin
    /// within 0.01`. One of the step's frames must have been looked at (`oapply`, `osweep`,
    /// `render` or `frames`) since either frame's pose last changed. A step that is no longer
    /// large is ignored.
    pub steps_checked: Option<BTreeMap<String, String>>,
    #[schemars(length(max = 4000))]
    pub summary: Option<String>,
}

/// Why a keyframe cannot reach the gate: the categories `finish` accepts, each checked.
#[derive(Debug, Clone, PartialEq, Deserialize, JsonSchema)]
#[serde(tag = "category", rename_all = "snake_case", deny_unknown_fields)]
pub enum Unreachable {
    /// Hands or other occluders hide much of the object: accepted when the hidden share
    /// of the rendered model is over the run's threshold (`finish.min_occlusion_percent`
    /// in run.json, default 30).
    Occlusion {
        /// The share of the object you judge hidden, percent.
        percent: f64,
    },
    /// The mask is wrong here: name an image of this run that shows it (a render or a
    /// frames view).
    MaskError {
        /// Path of the image (inside the run directory or the capture).
        image: String,
        note: Option<String>,
    },
    /// The object is cut by the frame border (accepted when its mask touches the border).
    Truncated { note: Option<String> },
    /// The model cannot reach it (a deforming part, a part the model lacks): say what.
    OutOfReach {
        /// What the model cannot do here (at least 20 characters).
        note: String,
    },
}

impl Unreachable {
    fn label(&self) -> &'static str {
        match self {
            Unreachable::Occlusion { .. } => "occlusion",
            Unreachable::MaskError { .. } => "mask error",
            Unreachable::Truncated { .. } => "truncated",
            Unreachable::OutOfReach { .. } => "out of reach",
        }
    }
}

tool!(Critic, "critic", Diagnostic, Nothing, CriticArgs,
    "Ask a separate model to criticise one keyframe: it sees the frame, the overlay and the turntable and returns realism and identity scores and discrepancies tagged shape, pose, joint state or joint definition, with a severity and a direction of change. Skipped with a note when no critic model is configured.",
    |tb, a, step| tb.critic(&a.frame, step));

tool!(Notes, "notes", Note, Notes, NotesArgs,
    "Append to NOTES.md, your memory across contexts (what the object is, which parts move, what you ruled out).",
    |tb, a, step| {
        let p = tb.run.notes_path();
        let mut all = agentstar_data::read_text(&p).unwrap_or_default();
        let line = format!("\n- (step {step}) {}\n", a.text.trim());
        if all.len() + line.len() > MAX_NOTES_BYTES {
            return Ok(ToolOutput::error(format!(
                "NOTES.md is full ({} of {MAX_NOTES_BYTES} bytes): it is in every request, so keep notes short; nothing was added",
                all.len()
            )));
        }
        all.push_str(&line);
        agentstar_data::atomic::write_atomic(&p, all.as_bytes())?;
        Ok(ToolOutput::text("noted"))
    });

tool!(Finish, "finish", Diagnostic, Nothing, FinishArgs,
    "Check the gates and end the run when they hold: every keyframe's band IoU (the gate `score` reports) ≥ 0.98 or a checked reason for it in `unreachable` (categories: occlusion over the run's threshold, a mask error shown on an image, truncated by the frame border, out of the model's reach with a note); at most a quarter of the keyframes (the run's `finish.max_share_under_gate`) under the gate even with reasons; a turntable after the last shape change; a temporal report after the last change of the poses (a commit, track, restore, fit or rescale; searches that were not committed do not count); every large step of the current poses (over 90°, as `temporal` warns) named in `steps_checked` with what you found, after looking at one of its frames (`oapply`, `osweep`, `render` or `frames`); for every revolute joint, a `mechanism_pick` made for the current scene that names the arm about the declared axis (run.json `finish.mechanism_check`, on by default). Returns what is missing otherwise.",
    |tb, a, _step| tb.finish(&a));

impl Toolbox {
    pub(super) fn critic(&self, frame: &str, step: u64) -> Result<ToolOutput> {
        let Some(critic) = &self.critic else {
            return Ok(ToolOutput::text(
                "critic skipped: no critic model is configured (agentstar run --critic PROVIDER:MODEL, or AGENTSTAR_CRITIC for the MCP server)",
            ));
        };
        let names = self.frame_names(Some(frame))?;
        let [name] = names.as_slice() else {
            return Ok(ToolOutput::error(format!(
                "critic: `{frame}` names {} frames; name one",
                names.len()
            )));
        };
        let request = RenderRequest {
            frames: Some(name),
            views: "overlay,compare,frame",
            ..Default::default()
        };
        let (r, _, _) = self.cli(&["render"], step, Critic::NAME, &request)?;
        if r.is_error {
            return Ok(r);
        }
        let tt = self.call(Turntable::NAME, &Value::Null, step);
        // The keyframe first (cropped around its mask, within the image limits), then the
        // overlay and the comparison, then one turntable sheet.
        let mut images: Vec<PathBuf> = r
            .images
            .into_iter()
            .filter(|p| !p.to_string_lossy().contains("sheet"))
            .collect();
        images.sort_by_key(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("frame_"))
        });
        images.extend(tt.images.into_iter().take(1));
        match critic(name, &images) {
            Ok(text) => Ok(ToolOutput {
                text,
                images,
                ..Default::default()
            }),
            Err(e) => Ok(ToolOutput::error(format!("the critic failed: {e}"))),
        }
    }

    /// Checks a reason given for keyframe `i` (score `f`) being under the gate.
    pub(super) fn check_reason(
        &self,
        i: usize,
        f: &agentstar_reports::FrameScore,
        why: &Unreachable,
    ) -> std::result::Result<(), String> {
        match why {
            Unreachable::Occlusion { percent } => {
                if !(percent.is_finite() && *percent > 0.0 && *percent <= 100.0) {
                    return Err(format!("`percent` is {percent}; a share in (0, 100]"));
                }
                // The hidden share of the rendered model: what the mask (hands excluded)
                // does not show of it.
                if f.render_px == 0 {
                    return Err("the model is not in view here, so nothing is hidden".into());
                }
                let hidden = 100.0 * (1.0 - f.mask_px as f64 / f.render_px as f64).max(0.0);
                let min = self.run.finish.min_occlusion_percent;
                if hidden < min {
                    return Err(format!(
                        "about {hidden:.0}% of the rendered model is hidden (1 − mask/render pixels), under the run's {min:.0}% threshold"
                    ));
                }
                Ok(())
            }
            Unreachable::MaskError { image, .. } => {
                let p = self.confine(image)?;
                let is_image = p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg")
                });
                if !p.is_file() || !is_image {
                    return Err(format!("`{image}` is not an image file (PNG or JPEG)"));
                }
                Ok(())
            }
            Unreachable::Truncated { .. } => {
                let cap = self.capture().map_err(|e| e.to_string())?;
                let m = cap.load_mask(i).map_err(|e| e.to_string())?;
                let (w, h) = (m.width(), m.height());
                let touches = (0..w).any(|x| m.get(x, 0) || m.get(x, h - 1))
                    || (0..h).any(|y| m.get(0, y) || m.get(w - 1, y));
                if touches {
                    Ok(())
                } else {
                    Err("its mask does not touch the frame border".into())
                }
            }
            Unreachable::OutOfReach { note } => {
                if note.trim().chars().count() < 20 {
                    Err(
                        "say in `note` (at least 20 characters) what the model cannot do here"
                            .into(),
                    )
                } else {
                    Ok(())
                }
            }
        }
    }

    /// What `finish` still needs about the large steps of the current poses: each one named
    /// in `checked` with a note, and one of its two frames looked at with a tool that shows
    /// or scores its twins (`entries`: the ledger) since either frame's pose last changed.
    /// A key that does not read as a step of two keyframes is reported; one naming a step
    /// that is not large (fixed since) is ignored.
    pub(super) fn unchecked_steps(
        &self,
        checked: Option<&BTreeMap<String, String>>,
        entries: &[agentstar_data::ledger::LedgerEntry],
    ) -> Vec<String> {
        let report = match self.temporal_report() {
            Ok(r) => r,
            Err(e) => return vec![format!("the temporal report could not be made: {e}")],
        };
        let large: Vec<(String, String, f64)> = report
            .large_steps
            .iter()
            .map(|s| (s.from.clone(), s.to.clone(), s.rotation_deg))
            .collect();
        let mut missing = Vec::new();
        // The large steps named with a note, resolved to frame names.
        let mut named: Vec<(String, String)> = Vec::new();
        for (key, note) in checked.into_iter().flatten() {
            let Some((a, b)) = key.split_once("->") else {
                missing.push(format!(
                    "`steps_checked` key `{key}` is not a step: write it `A->B`, as `temporal` prints it"
                ));
                continue;
            };
            let one = |spec: &str| -> std::result::Result<String, String> {
                match self.frame_names(Some(spec.trim())) {
                    Ok(v) if v.len() == 1 => Ok(v[0].clone()),
                    Ok(v) => Err(format!(
                        "`{}` names {} keyframes, not one",
                        spec.trim(),
                        v.len()
                    )),
                    Err(e) => Err(e.to_string()),
                }
            };
            match (one(a), one(b)) {
                (Ok(a), Ok(b)) => {
                    // A step that is no longer large (fixed since) is no gate: nothing to
                    // check there.
                    if !large
                        .iter()
                        .any(|(f, t, _)| (f, t) == (&a, &b) || (f, t) == (&b, &a))
                    {
                        continue;
                    }
                    if note.trim().is_empty() {
                        missing.push(format!(
                            "`steps_checked` {a}->{b} has no note: say what you checked and found"
                        ));
                    } else {
                        named.push((a, b));
                    }
                }
                (Err(e), _) | (_, Err(e)) => {
                    missing.push(format!("`steps_checked` key `{key}`: {e}"));
                }
            }
        }
        // Whether a ledger entry's `frames` (all when absent) name `name`; `unknown` when its
        // arguments do not read.
        let names = |e: &agentstar_data::ledger::LedgerEntry, name: &str, unknown: bool| {
            match serde_json::from_value::<FramesOf>(e.args.clone()) {
                Ok(FramesOf { frames: None }) => true,
                Ok(FramesOf { frames: Some(spec) }) => self
                    .frame_names(Some(&spec))
                    .is_ok_and(|v| v.iter().any(|n| n == name)),
                Err(_) => unknown,
            }
        };
        let ok = |e: &agentstar_data::ledger::LedgerEntry| !e.scores.contains_key("error");
        // A step is checked by a call that scores or shows the twins of one of its frames,
        // or shows the frame, when no pose change of either frame came after it (a look at
        // poses since replaced is no check of these; play-test 8: a change elsewhere did
        // not need new looks here). A rescale (`scale` with `apply`) is no such change: it
        // keeps every rotation and joint state and scales the translations, so every view
        // stays what it was (play-test 17: a rescale before `finish` asked for three looks
        // again).
        let looks = [Oapply::NAME, Osweep::NAME, Render::NAME, Keyframes::NAME];
        let checked_since = |from: &str, to: &str| {
            entries.iter().any(|look| {
                looks.contains(&look.tool.as_str())
                    && ok(look)
                    && (names(look, from, false) || names(look, to, false))
                    && !entries.iter().any(|change| {
                        change.step > look.step
                            && change.pose_version.is_some()
                            && change.tool != Scale::NAME
                            && ok(change)
                            && (names(change, from, true) || names(change, to, true))
                    })
            })
        };
        for (from, to, deg) in &large {
            let done = named
                .iter()
                .any(|(a, b)| (a, b) == (from, to) || (a, b) == (to, from));
            if !done {
                missing.push(format!(
                    "step {from} -> {to} turns the object by {deg:.0}° (over {:.0}°): check it (`oapply` on {to} scores its flips and swaps, each refined; a twin within about 0.01 IoU means look by eye) and name it in `steps_checked`, e.g. {{\"steps_checked\": {{\"{from}->{to}\": \"oapply on {to}: no twin within 0.01\"}}}}",
                    report.large_step_deg
                ));
            } else if !checked_since(from, to) {
                missing.push(format!(
                    "step {from} -> {to} is named in `steps_checked`, but neither frame was looked at since their poses last changed: run `oapply` (or `osweep`, `render`, `frames`) on {to}"
                ));
            }
        }
        missing
    }

    /// The gates: IoU (or reasons), a turntable after the last shape change, a temporal
    /// report after the last pose change (both read from the ledger), and each large step
    /// of the poses checked ([`Toolbox::unchecked_steps`]).
    pub(super) fn finish(&self, args: &FinishArgs) -> Result<ToolOutput> {
        let summary = args.summary.as_deref().unwrap_or("");
        if let Some(window) = &self.window {
            // A pose sub-agent ends its window; the orchestrator owns the gates.
            let score = self.call(
                Score::NAME,
                &serde_json::json!({"frames": window.join(",")}),
                0,
            );
            let mut o = ToolOutput {
                text: format!("window done. {}\n{summary}", first_line_of(&score.text)),
                finished: true,
                scores: score.scores,
                ..Default::default()
            };
            o.scores.insert("window".into(), 1.0);
            return Ok(o);
        }
        let policy = self.run.finish;
        let mut missing = vec![];
        let mut scores = BTreeMap::new();
        // The reasons, by frame name (a key may name several frames).
        let mut reasons: BTreeMap<String, &Unreachable> = BTreeMap::new();
        for (spec, why) in args.unreachable.iter().flatten() {
            match self.frame_names(Some(spec)) {
                Ok(names) => {
                    for n in names {
                        reasons.insert(n, why);
                    }
                }
                Err(e) => missing.push(format!("`unreachable` names `{spec}`: {e}")),
            }
        }
        let mut accepted: Vec<String> = vec![];
        let mut colours = None;
        match self.score_report(None) {
            Ok(report) => {
                colours = colour_line(&report.appearance);
                let n = report.frames.len();
                let under: Vec<(usize, &agentstar_reports::FrameScore)> = report
                    .frames
                    .iter()
                    .enumerate()
                    .filter(|(_, f)| f.gate() < GATE_IOU)
                    .collect();
                let min = report.frames.iter().map(|f| f.gate()).fold(1.0, f64::min);
                scores.insert("iou_min".to_string(), min);
                scores.insert("under_gate".to_string(), under.len() as f64);
                let mut without = vec![];
                for (i, f) in &under {
                    match reasons.get(&f.frame) {
                        None => without.push(format!("{} ({:.4})", f.frame, f.gate())),
                        Some(why) => match self.check_reason(*i, f, why) {
                            Ok(()) => accepted.push(format!("{} ({})", f.frame, why.label())),
                            Err(e) => missing.push(format!(
                                "{} ({:.4}): the {} reason is not accepted: {e}",
                                f.frame,
                                f.gate(),
                                why.label()
                            )),
                        },
                    }
                }
                if !without.is_empty() {
                    missing.push(format!(
                        "keyframes under the {GATE_IOU} gate without a reason: {}",
                        without.join(", ")
                    ));
                }
                let share = under.len() as f64 / n.max(1) as f64;
                if share > policy.max_share_under_gate {
                    missing.push(format!(
                        "{} of {n} keyframes ({:.0}%) are under the gate; at most {:.0}% may finish with reasons (run.json `finish.max_share_under_gate`): fix the poses or the shape",
                        under.len(),
                        100.0 * share,
                        100.0 * policy.max_share_under_gate
                    ));
                }
            }
            Err(e) => missing.push(format!("the poses could not be scored: {e}")),
        }
        let (entries, _) = if self.run.ledger_path().is_file() {
            agentstar_data::ledger::read(&self.run.ledger_path())?
        } else {
            (vec![], vec![])
        };
        let last = |pred: &dyn Fn(&agentstar_data::ledger::LedgerEntry) -> bool| {
            entries.iter().filter(|e| pred(e)).map(|e| e.step).max()
        };
        let ok = |e: &agentstar_data::ledger::LedgerEntry| !e.scores.contains_key("error");
        let shape = last(&|e| e.kind == "shape" && ok(e)).unwrap_or(0);
        // The last step that wrote the poses (a search that was not committed changes
        // nothing; play-test 2026-12-02: `finish` asked for `temporal` again after uncommitted
        // `osweep`s); in a run without any, the last pose step, as before.
        let pose = last(&|e| e.pose_version.is_some() && ok(e))
            .or_else(|| last(&|e| e.kind == "pose" && ok(e)))
            .unwrap_or(0);
        let turntable = last(&|e| e.tool == "turntable" && ok(e));
        let temporal = last(&|e| e.tool == "temporal" && ok(e));
        if turntable.is_none_or(|t| t < shape) {
            missing.push("look at a `turntable` after the last shape change".into());
        }
        if temporal.is_none_or(|t| t < pose) {
            missing.push("review the `temporal` report after the last pose change".into());
        }
        missing.extend(self.unchecked_steps(args.steps_checked.as_ref(), &entries));
        missing.extend(self.mechanism_missing());
        let passed = missing.is_empty();
        let mut o = ToolOutput {
            text: if passed {
                format!(
                    "All gates hold. The run is finished.{}{}",
                    if accepted.is_empty() {
                        String::new()
                    } else {
                        format!(" Keyframes with accepted reasons: {}.", accepted.join(", "))
                    },
                    colours.map(|l| format!("\n{l}")).unwrap_or_default()
                )
            } else {
                format!("Not finished:\n- {}", missing.join("\n- "))
            },
            finished: passed,
            scores,
            ..Default::default()
        };
        o.scores
            .insert("passed".into(), if passed { 1.0 } else { 0.0 });
        Ok(o)
    }
}

/// The frames a ledger entry's arguments name (`frames`; all when absent): what `finish`
/// reads back of the calls that looked at a large step's frames.
#[derive(Debug, Deserialize)]
struct FramesOf {
    #[serde(default)]
    frames: Option<String>,
}

/// What the colours say of the finished poses, not a gate: the keyframes' colours against
/// their neighbours' and against the model's own print, mean and lowest. The gates read
/// outlines only, and a turn about a round body's axis keeps the outline (play-test 16
/// finished a labelled tin 40° off in that turn; its neighbours' colours agreed at NCC 0.55
/// mean; the hard suite's labelled can at its true poses: 0.83 mean over keyframes 65–85,
/// seed 300). `None` without evidence.
fn colour_line(appearance: &[agentstar_reports::FrameAppearance]) -> Option<String> {
    let figure = |get: &dyn Fn(&agentstar_reports::FrameAppearance) -> Option<f64>| {
        let v: Vec<(&str, f64)> = appearance
            .iter()
            .filter_map(|a| get(a).map(|x| (a.frame.as_str(), x)))
            .collect();
        let lowest = v.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
        Some(format!(
            "mean {:.2}, lowest {:.2} ({})",
            v.iter().map(|x| x.1).sum::<f64>() / v.len() as f64,
            lowest.1,
            lowest.0
        ))
    };
    let neighbours = figure(&|a| a.ncc)?;
    let model = figure(&|a| a.model_ncc)
        .map(|m| format!("; against the model's own colours (the share its print explains beyond shading; 0 with no print in view), {m}"))
        .unwrap_or_default();
    Some(format!(
        "Colours (not a gate): the keyframes' colours against their neighbours' at these poses, NCC {neighbours}{model}. The gates read outlines only: where the object has a print and these are low, a pose may put it on the wrong side (a turn about a round body's axis keeps the outline); look at the lowest frames with `frames` and `model: true`."
    ))
}
