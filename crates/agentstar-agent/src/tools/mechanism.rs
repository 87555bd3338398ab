//! The mechanism check: `mechanism` (each joint swept about its declared axis and about the
//! negated axis, as blind arms A and B) and `mechanism_pick` (the agent names, per joint,
//! the arm that moves as the object does, with evidence from at least three interior
//! states), and the gate `finish` reads ([`Toolbox::mechanism_missing`]).
//!
//! Which label is the declared axis is in the command's report only; the harness keeps it
//! in `RUN/.agentstar/mechanism/sheets.json` (with the scene the sheets were made for) and
//! never shows it before a pick. Picks go to `RUN/.agentstar/mechanism/picks.json`, each
//! with the scene (version and content hash) it was made for: a later scene change makes
//! it stale, and `finish` asks again.

use super::*;
use crate::{AgentError, Result};
use agentstar_reports::mechanism::{ArmLabel, MechanismReport};
use agentstar_reports::CheckReport;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Interior states a pick's evidence must name.
pub const MIN_EVIDENCE_STATES: usize = 3;

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MechanismArgs {
    /// Joints to sweep, comma separated (default: every revolute, continuous and prismatic
    /// joint). At most 8 images come back: name joints to see the rest.
    #[schemars(length(min = 1, max = 2000))]
    pub joints: Option<String>,
}

/// A blind arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, JsonSchema)]
pub enum Arm {
    A,
    B,
}

impl Arm {
    fn label(self) -> ArmLabel {
        match self {
            Arm::A => ArmLabel::A,
            Arm::B => ArmLabel::B,
        }
    }
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JointPick {
    /// The arm whose motion matches the object in the frames.
    pub arm: Arm,
    /// What you saw, naming at least three interior states of the sheets by their value,
    /// e.g. "at 37 deg the lid clears the rim; at 55 deg it stands over the back; at 92 deg
    /// it is upright as in 000010".
    #[schemars(length(min = 20, max = 4000))]
    pub evidence: String,
}

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MechanismPickArgs {
    /// Joint name → the arm that matches the frames and your evidence.
    pub picks: BTreeMap<String, JointPick>,
}

/// The scene a sheet or a pick was made for: its version and a hash of its text (a scene
/// edited outside `scene_write` keeps its version but not its hash).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneId {
    pub version: u64,
    pub hash: String,
}

/// A joint as the last `mechanism` swept it (the harness's copy; never shown).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Swept {
    kind: String,
    unit: String,
    axis: [f64; 3],
    range: [f64; 2],
    states: Vec<f64>,
    declared: ArmLabel,
}

/// `sheets.json`: the joints swept for one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SheetsRecord {
    scene: SceneId,
    joints: BTreeMap<String, Swept>,
}

/// One recorded pick.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PickRecord {
    pub arm: ArmLabel,
    /// Whether the arm picked is the one about the declared axis.
    pub declared: bool,
    /// The declared axis when the pick was made.
    pub axis: [f64; 3],
    pub range: [f64; 2],
    pub kind: String,
    pub scene: SceneId,
    pub step: u64,
    pub evidence: String,
}

/// `picks.json`: the latest pick per joint.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PicksRecord {
    pub picks: BTreeMap<String, PickRecord>,
}

tool!(Mechanism, "mechanism", Diagnostic, Nothing, MechanismArgs,
    "The mechanism check of the joints (a mirrored axis sign is invisible in a turntable at one state): each joint is swept through its range twice, about its declared axis and about the negated axis, the other joints at rest, as two arms labelled A and B (which one is declared is not shown), from two views 40° off the joint's axis, the framing fixed per joint; with the keyframe that shows the joint's part most open, openness weighed by the share of the part no hand covers (the reply says that share). Compare the arms with the frames and name the matching arm per joint with `mechanism_pick`; `finish` needs a pick for every revolute joint of the current scene.",
    |tb, a, step| tb.mechanism(&a, step));

tool!(MechanismPick, "mechanism_pick", Diagnostic, Picks, MechanismPickArgs,
    "Name, per joint, the arm of the last `mechanism` sheets (A or B) whose motion matches the object in the frames, with evidence naming at least three interior states by their value (e.g. \"at 37 deg the lid clears the rim; at 55 deg …; at 92 deg …\"; the ends of the range do not count). The pick holds for the scene it was made for; a scene change asks for a new one. Picking the arm about the negated axis says which axis to declare.",
    |tb, a, step| tb.mechanism_pick(&a, step));

/// FNV-1a, 64 bits, as 16 hex digits.
fn fnv_hex(bytes: &[u8]) -> String {
    let h = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    format!("{h:016x}")
}

/// A number as the text writes it (as the sheets label the states).
use agentstar_reports::mechanism::state_text as num;

fn vec3(v: &[f64; 3]) -> String {
    format!("({}, {}, {})", num(v[0]), num(v[1]), num(v[2]))
}

/// The numbers written in `text`: a `-` is a sign only after a character that is not
/// alphanumeric (so `18-37` reads 18 and 37).
fn numbers_in(text: &str) -> Vec<f64> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let prev_alnum = i > 0 && chars[i - 1].is_alphanumeric();
        let sign_ok =
            chars[i] == '-' && i + 1 < chars.len() && chars[i + 1].is_ascii_digit() && !prev_alnum;
        if (chars[i].is_ascii_digit() && !prev_alnum) || sign_ok {
            let start = i;
            i += 1;
            while i < chars.len()
                && (chars[i].is_ascii_digit()
                    || (chars[i] == '.' && chars.get(i + 1).is_some_and(char::is_ascii_digit)))
            {
                i += 1;
            }
            let s: String = chars[start..i].iter().collect();
            if let Ok(v) = s.parse::<f64>() {
                out.push(v);
            }
        } else if chars[i].is_ascii_digit() {
            // Digits inside a word (`view2`, `frame000037`): the rest of the word.
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '.') {
                i += 1;
            }
        } else {
            i += 1;
        }
    }
    out
}

/// The interior states (of `states`, the ends first and last) that `evidence` names by
/// value, each once, in the order of `states`.
pub fn evidence_states(evidence: &str, states: &[f64], angular: bool) -> Vec<f64> {
    if states.len() < 3 {
        return vec![];
    }
    let interior = &states[1..states.len() - 1];
    let min_gap = states
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(f64::INFINITY, f64::min);
    let mut tol = 0.25 * min_gap;
    if angular {
        tol = tol.min(0.5);
    }
    let said = numbers_in(evidence);
    interior
        .iter()
        .copied()
        .filter(|s| said.iter().any(|n| (n - s).abs() <= tol))
        .collect()
}

/// Whether `evidence` names at least [`MIN_EVIDENCE_STATES`] interior states: an error
/// naming the interior states otherwise.
pub fn check_evidence(
    joint: &str,
    evidence: &str,
    states: &[f64],
    angular: bool,
) -> std::result::Result<(), String> {
    let named = evidence_states(evidence, states, angular);
    if named.len() >= MIN_EVIDENCE_STATES {
        return Ok(());
    }
    let interior: Vec<String> = states
        .get(1..states.len().saturating_sub(1))
        .unwrap_or(&[])
        .iter()
        .map(|v| num(*v))
        .collect();
    Err(format!(
        "{joint}: the evidence names {} interior state(s) of the sheets ({}); name at least {MIN_EVIDENCE_STATES} of {} by value, saying what the part does there (the ends of the range do not count)",
        named.len(),
        if named.is_empty() {
            "none".to_string()
        } else {
            named.iter().map(|v| num(*v)).collect::<Vec<_>>().join(", ")
        },
        interior.join(", ")
    ))
}

impl Toolbox {
    fn mechanism_dir(&self) -> PathBuf {
        self.run.dir.join(".agentstar").join("mechanism")
    }

    /// The current scene's version and hash.
    pub fn scene_id(&self) -> Result<SceneId> {
        let bytes =
            agentstar_data::read_bounded(&self.run.scene, agentstar_data::limits::TEXT_BYTES)?;
        Ok(SceneId {
            version: self.run.list_scene_versions().last().copied().unwrap_or(0),
            hash: fnv_hex(&bytes),
        })
    }

    fn read_record<T: serde::de::DeserializeOwned>(&self, name: &str) -> Result<Option<T>> {
        let p = self.mechanism_dir().join(name);
        if !p.is_file() {
            return Ok(None);
        }
        let text = agentstar_data::read_text(&p)?;
        serde_json::from_str(&text).map(Some).map_err(|e| {
            AgentError::Tool(format!(
                "{}: not a mechanism record ({e}); run `mechanism` again",
                p.display()
            ))
        })
    }

    fn write_record<T: Serialize>(&self, name: &str, value: &T) -> Result<()> {
        let dir = self.mechanism_dir();
        std::fs::create_dir_all(&dir).map_err(|e| agentstar_data::DataError::io(&dir, e))?;
        let text = serde_json::to_string_pretty(value)
            .map_err(|e| AgentError::Tool(format!("encoding {name}: {e}")))?;
        agentstar_data::atomic::write_atomic(&dir.join(name), text.as_bytes())?;
        Ok(())
    }

    /// The picks recorded so far.
    pub fn mechanism_picks(&self) -> Result<PicksRecord> {
        Ok(self.read_record("picks.json")?.unwrap_or_default())
    }

    pub(super) fn mechanism(&self, a: &MechanismArgs, step: u64) -> Result<ToolOutput> {
        #[derive(Serialize)]
        struct MechanismRequest<'a> {
            joints: Option<&'a str>,
            seed: u64,
        }
        let before = self.scene_id()?;
        // A new coin for every call (the step number: seeded, in the ledger), so the labels
        // of one run say nothing of the next (play-test 11 found A the negated arm in both of
        // its runs and, once told which arm was declared, picked without looking).
        let request = MechanismRequest {
            joints: nonblank(&a.joints),
            seed: step,
        };
        let (o, out, stdout) = self.cli(&["mechanism"], step, Mechanism::NAME, &request)?;
        if o.is_error {
            return Ok(o);
        }
        let report: MechanismReport = serde_json::from_str(&stdout).map_err(|e| {
            AgentError::Tool(format!("mechanism printed no mechanism report ({e})"))
        })?;
        if self.scene_id()? != before {
            return Ok(ToolOutput::error(
                "the scene changed while the mechanism sheets were made; run `mechanism` again",
            ));
        }
        // The harness's copy, with the declared labels; merged with the joints swept
        // earlier for the same scene.
        let mut record = match self.read_record::<SheetsRecord>("sheets.json") {
            Ok(Some(r)) if r.scene == before => r,
            _ => SheetsRecord {
                scene: before.clone(),
                joints: BTreeMap::new(),
            },
        };
        let mut images = Vec::new();
        let mut text = format!(
            "mechanism: {} joint(s) swept for scene version {} in {}.",
            report.joints.len(),
            before.version,
            out.display()
        );
        if report.joints.is_empty() {
            text.push_str(" The model has no joint to sweep: nothing to check.");
        } else {
            text.push_str(
                " Each joint is swept through its range twice, about its declared axis and about the negated axis: arms A and B (which is which is not shown). Compare each arm with the frames (the keyframe that shows the joint's part most open and least hidden by hands comes with its sheets): which arm moves the part the way the object does?",
            );
        }
        for j in &report.joints {
            let angular = j.unit == "deg";
            let unit = if angular { " deg" } else { "" };
            let states: Vec<String> = j.states.iter().map(|v| num(*v)).collect();
            let interior: Vec<String> = j.interior().iter().map(|v| num(*v)).collect();
            text.push_str(&format!(
                "\n- {} ({}, {} to {}{unit}): states {} (interior {})\n  arm A: {}\n  arm B: {}",
                j.joint,
                j.kind,
                num(j.range[0]),
                num(j.range[1]),
                states.join(", "),
                interior.join(", "),
                j.sheets_a
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                j.sheets_b
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
            ));
            if let Some(f) = &j.frame {
                let parts = f.parts.join(", ");
                text.push_str(&format!(
                    "\n  shown open in {} ({}{unit}; {:.0}% of {parts} in view, the rest under a hand or hidden): {}",
                    f.frame,
                    num(f.state),
                    f.part_in_view_share * 100.0,
                    f.image.display()
                ));
                if let Some(m) = &f.more_open {
                    text.push_str(&format!(
                        "\n  ({} is more open, {}{unit}, but only {:.0}% of {parts} is in view there)",
                        m.frame,
                        num(m.state),
                        m.part_in_view_share * 100.0
                    ));
                }
            }
            images.extend(j.sheets_a.iter().take(1).cloned());
            images.extend(j.sheets_b.iter().take(1).cloned());
            images.extend(j.frame.as_ref().map(|f| f.image.clone()));
            record.joints.insert(
                j.joint.clone(),
                Swept {
                    kind: j.kind.clone(),
                    unit: j.unit.clone(),
                    axis: j.axis,
                    range: j.range,
                    states: j.states.clone(),
                    declared: j.declared,
                },
            );
        }
        for n in &report.notes {
            text.push_str(&format!("\nnote: {n}"));
        }
        if let Some(j) = report.joints.first() {
            let s: Vec<String> = j.interior().iter().take(3).map(|v| num(*v)).collect();
            let unit = if j.unit == "deg" { " deg" } else { "" };
            text.push_str(&format!(
                "\nThen name the matching arm of each joint with `mechanism_pick`, with evidence naming at least {MIN_EVIDENCE_STATES} interior states by value, e.g. {{\"picks\": {{\"{}\": {{\"arm\": \"A\", \"evidence\": \"at {}{unit} …; at {}{unit} …; at {}{unit} …\"}}}}}}",
                j.joint,
                s.first().map_or("", String::as_str),
                s.get(1).map_or("", String::as_str),
                s.get(2).map_or("", String::as_str),
            ));
        }
        self.write_record("sheets.json", &record)?;
        let written = images.len();
        images.truncate(MAX_IMAGES_RETURNED);
        if written > images.len() {
            text.push_str(&format!(
                "\n{} of {written} images returned; name fewer joints (`joints`) to see the rest",
                images.len()
            ));
        }
        Ok(ToolOutput {
            text,
            images,
            ..Default::default()
        })
    }

    pub(super) fn mechanism_pick(&self, a: &MechanismPickArgs, step: u64) -> Result<ToolOutput> {
        if a.picks.is_empty() {
            return Ok(ToolOutput::error(
                "name at least one joint in `picks`, e.g. {\"picks\": {\"lid_hinge\": {\"arm\": \"A\", \"evidence\": \"at 37 deg …; at 55 deg …; at 92 deg …\"}}}",
            ));
        }
        let now = self.scene_id()?;
        let Some(sheets) = self.read_record::<SheetsRecord>("sheets.json")? else {
            return Ok(ToolOutput::error(
                "no mechanism sheets yet: run `mechanism` and look at them first",
            ));
        };
        if sheets.scene != now {
            return Ok(ToolOutput::error(format!(
                "the mechanism sheets were made for scene version {}, and the scene has changed since (version {} now): run `mechanism` again and look at the new sheets",
                sheets.scene.version, now.version
            )));
        }
        // Every pick checked before any is recorded.
        let mut problems = Vec::new();
        for (joint, pick) in &a.picks {
            match sheets.joints.get(joint) {
                None => problems.push(format!(
                    "{joint}: not swept by `mechanism` for this scene (swept: {})",
                    sheets.joints.keys().cloned().collect::<Vec<_>>().join(", ")
                )),
                Some(s) => {
                    if let Err(e) =
                        check_evidence(joint, &pick.evidence, &s.states, s.unit == "deg")
                    {
                        problems.push(e);
                    }
                }
            }
        }
        if !problems.is_empty() {
            return Ok(ToolOutput::error(format!(
                "no pick recorded:\n- {}",
                problems.join("\n- ")
            )));
        }
        let mut record = self.mechanism_picks()?;
        let mut lines = Vec::new();
        let mut wrong = 0.0;
        for (joint, pick) in &a.picks {
            let Some(s) = sheets.joints.get(joint) else {
                continue;
            };
            let arm = pick.arm.label();
            let declared = arm == s.declared;
            record.picks.insert(
                joint.clone(),
                PickRecord {
                    arm,
                    declared,
                    axis: s.axis,
                    range: s.range,
                    kind: s.kind.clone(),
                    scene: now.clone(),
                    step,
                    evidence: pick.evidence.trim().to_string(),
                },
            );
            if declared {
                lines.push(format!(
                    "{joint}: arm {} recorded; it is the arm about the declared axis {}: this joint holds the gate while the scene stays as it is",
                    arm.as_str(),
                    vec3(&s.axis)
                ));
            } else {
                wrong += 1.0;
                lines.push(format!(
                    "{joint}: arm {} recorded; it is the arm about the NEGATED axis: {}",
                    arm.as_str(),
                    sign_advice(joint, &s.axis, &s.range, &s.kind)
                ));
            }
        }
        self.write_record("picks.json", &record)?;
        let mut o = ToolOutput::text(format!(
            "mechanism_pick (scene version {}):\n- {}",
            now.version,
            lines.join("\n- ")
        ));
        o.scores.insert("negated_picks".into(), wrong);
        Ok(o)
    }

    /// What `finish` still needs of the mechanism check: a fresh pick (made for the current
    /// scene) for every revolute joint, and no fresh pick of a negated arm. Nothing when
    /// the run's policy turns the check off.
    /// After a shape change: what the mechanism gate now wants, when the agent has picked
    /// before and the picks no longer hold (play-test 11 learnt it only from TASK.md).
    pub(super) fn mechanism_reminder(&self) -> Option<String> {
        if !self.run.finish.mechanism_check
            || self.mechanism_picks().map_or(true, |p| p.picks.is_empty())
        {
            return None;
        }
        let missing = self.mechanism_missing();
        (!missing.is_empty()).then(|| {
            format!(
                "The mechanism picks were for the earlier scene: run `mechanism` and `mechanism_pick` again before `finish` ({}).",
                missing.join("; ")
            )
        })
    }

    pub(super) fn mechanism_missing(&self) -> Vec<String> {
        if !self.run.finish.mechanism_check {
            return vec![];
        }
        let (ok, stdout, stderr) = match super::scene::check_call(&self.run.scene)
            .and_then(|call| self.exec(call.args()))
        {
            Ok(r) => r,
            Err(e) => return vec![format!("the mechanism check could not read the scene: {e}")],
        };
        let report: CheckReport = match serde_json::from_str(&stdout) {
            Ok(r) if ok => r,
            _ => {
                return vec![format!(
                    "the mechanism check could not read the scene: {}",
                    failure_text(&stderr)
                )]
            }
        };
        let (now, picks) = match (self.scene_id(), self.mechanism_picks()) {
            (Ok(n), Ok(p)) => (n, p),
            (Err(e), _) | (_, Err(e)) => {
                return vec![format!("the mechanism picks could not be read: {e}")]
            }
        };
        let mut missing = Vec::new();
        for j in &report.joints {
            let pick = picks.picks.get(&j.name);
            let fresh = pick.filter(|p| p.scene == now);
            match fresh {
                Some(p) if !p.declared => missing.push(format!(
                    "joint {}: the frames match the arm about the negated axis; {}",
                    j.name,
                    sign_advice(&j.name, &p.axis, &p.range, &p.kind)
                )),
                Some(_) => {}
                None if j.kind == "revolute" => missing.push(match pick {
                    Some(p) => format!(
                        "joint {}: its mechanism pick was made for scene version {}, and the scene has changed since: run `mechanism` and pick again with `mechanism_pick` (or set run.json `finish.mechanism_check` to false)",
                        j.name, p.scene.version
                    ),
                    None => format!(
                        "joint {}: no mechanism pick for the current scene (version {}): run `mechanism`, compare arms A and B with the frames, and name the matching arm with `mechanism_pick` (or set run.json `finish.mechanism_check` to false)",
                        j.name, now.version
                    ),
                }),
                None => {}
            }
        }
        missing
    }
}

/// What to write when the frames match the arm about the negated axis.
fn sign_advice(joint: &str, axis: &[f64; 3], range: &[f64; 2], kind: &str) -> String {
    let neg = [-axis[0], -axis[1], -axis[2]];
    let limit = if kind == "continuous" {
        String::new()
    } else {
        format!(
            ", or keep the axis and swap the limits to [{}, {}] with every state negated",
            num(-range[1]),
            num(-range[0])
        )
    };
    format!(
        "declare axis {} for {joint} instead of {}{limit}; then run `mechanism` and pick again",
        vec3(&neg),
        vec3(axis)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const STATES: [f64; 7] = [0.0, 18.0, 37.0, 55.0, 73.0, 92.0, 110.0];

    #[test]
    fn evidence_must_name_three_interior_states_by_value() {
        let ok = "at 18° the lid lifts off the rim; at 55 deg it stands over the back; at 92 it is upright as in 000010";
        assert_eq!(evidence_states(ok, &STATES, true), [18.0, 55.0, 92.0]);
        assert!(check_evidence("lid", ok, &STATES, true).is_ok());
        // The ends do not count, nor does a number repeated.
        let ends = "at 0 closed, at 110 open, at 55 half way, at 55 again";
        assert_eq!(evidence_states(ends, &STATES, true), [55.0]);
        let e = check_evidence("lid", ends, &STATES, true).expect_err("one interior state");
        assert!(
            e.contains("names 1 interior state(s) of the sheets (55)"),
            "{e}"
        );
        assert!(e.contains("18, 37, 55, 73, 92"), "{e}");
        // Numbers inside words (frame names, view labels) and off the states do not count.
        let words = "view2 frame000037 v18 at 36 and 56 the lid moves";
        assert!(evidence_states(words, &STATES, true).is_empty());
        // A range `18-37` names both; a negative state is read with its sign.
        assert_eq!(
            evidence_states("18-37 and 73", &STATES, true),
            [18.0, 37.0, 73.0]
        );
        let neg = [-90.0, -68.0, -45.0, -23.0, 0.0];
        assert_eq!(
            evidence_states("at -68, at -45 and (-23)", &neg, true),
            [-68.0, -45.0, -23.0]
        );
        assert_eq!(
            evidence_states("at 68, 45, 23", &neg, true),
            Vec::<f64>::new()
        );
        // Model units: the states as the sheets write them.
        let slide = [0.0, 0.075, 0.15, 0.225, 0.3];
        assert_eq!(
            evidence_states("0.075 out, 0.15 half, 0.225 nearly", &slide, false),
            [0.075, 0.15, 0.225]
        );
    }

    #[test]
    fn the_sign_advice_names_the_negated_axis_and_the_swapped_limits() {
        let s = sign_advice("lid_hinge", &[1.0, 0.0, 0.0], &[0.0, 110.0], "revolute");
        assert!(
            s.contains("declare axis (-1, 0, 0) for lid_hinge instead of (1, 0, 0)"),
            "{s}"
        );
        assert!(s.contains("[-110, 0]"), "{s}");
    }
}
