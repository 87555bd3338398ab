//! The built-in agent loop: the model sees the task document, its notes and the run's state;
//! each tool call is a step recorded in the ledger; images stay in the context for the last
//! few tool results only; budgets on steps, wall time and tokens stop the run cleanly.
//!
//! Pose sub-agents: the orchestrator may call `delegate_pose` with keyframe windows and a
//! brief; each window gets its own agent (own context, tools limited to its keyframes),
//! run in parallel; writing tools are serialised inside the toolbox (shared with the MCP
//! server), so no window's commit overwrites another's.
//! The orchestrator then owns the seams (temporal report, flip checks).

use crate::llm::{complete, LlmError, Message, ModelConfig, Part, ToolCall};
use crate::run::RunDir;
use crate::tools::{
    catalogue, parse_args, schema_of, DelegateArgs, Kind, ToolOutput, ToolSpec, Toolbox,
};
use crate::Result;
use agentstar_data::ledger::LedgerEntry;
use serde_json::{json, Value};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Budgets and context limits.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// Tool calls (steps) in this session, all agents together.
    pub max_steps: u64,
    pub max_wall_s: f64,
    /// Input plus output tokens, all agents together.
    pub max_tokens: u64,
    /// Tool results whose images stay in the context (older ones become a line of text).
    pub keep_images: usize,
    /// Longest tool result text kept in the context, characters.
    pub max_tool_text: usize,
}

impl Default for Budget {
    fn default() -> Self {
        Budget {
            max_steps: 200,
            max_wall_s: 4.0 * 3600.0,
            max_tokens: 4_000_000,
            keep_images: 3,
            max_tool_text: 12_000,
        }
    }
}

/// Why a loop stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum Stop {
    /// `finish` passed (or, for a sub-agent, its window is done).
    Finished,
    /// A budget ran out; the run can be resumed with a larger one.
    Budget(String),
    /// The model could not be reached or kept answering badly; the run can be resumed.
    ModelError(String),
}

/// What a session did.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    pub stop: Stop,
    pub steps: u64,
    pub input_tokens: u64,
    pub output_tokens: u64,
    pub wall_s: f64,
}

/// Shared counters of a session (orchestrator and sub-agents).
pub struct Session {
    pub model: ModelConfig,
    pub budget: Budget,
    /// The last step number this session took (numbers come from `RunDir::next_step`, under
    /// the run's lock, so other processes on the run never take the same).
    step: AtomicU64,
    steps_this_session: AtomicU64,
    tokens: AtomicU64,
    input_tokens: AtomicU64,
    output_tokens: AtomicU64,
    start: Instant,
    /// Seconds of earlier sessions, for the ledger's times.
    offset_s: f64,
    /// Writes progress lines (stderr in the binary).
    pub progress: Box<dyn Fn(&str) + Send + Sync>,
}

impl Session {
    pub fn new(model: ModelConfig, budget: Budget, first_step: u64, offset_s: f64) -> Session {
        Session {
            model,
            budget,
            step: AtomicU64::new(first_step),
            steps_this_session: AtomicU64::new(0),
            tokens: AtomicU64::new(0),
            input_tokens: AtomicU64::new(0),
            output_tokens: AtomicU64::new(0),
            start: Instant::now(),
            offset_s,
            progress: Box::new(|line| eprintln!("{line}")),
        }
    }

    fn time_s(&self) -> f64 {
        self.offset_s + self.start.elapsed().as_secs_f64()
    }

    /// Takes one step of the step budget, atomically (sub-agents share it): `Err` names the
    /// spent budget when no step is left.
    fn take_step(&self) -> std::result::Result<(), String> {
        let max = self.budget.max_steps;
        self.steps_this_session
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |s| {
                (s < max).then_some(s + 1)
            })
            .map(|_| ())
            .map_err(|s| format!("step budget spent ({s} of {max})"))
    }

    fn over_token_budget(&self) -> Option<String> {
        let tokens = self.tokens.load(Ordering::SeqCst);
        (tokens > self.budget.max_tokens).then(|| {
            format!(
                "token budget spent ({tokens} of {})",
                self.budget.max_tokens
            )
        })
    }

    fn over_budget(&self) -> Option<String> {
        let b = &self.budget;
        let steps = self.steps_this_session.load(Ordering::SeqCst);
        let tokens = self.tokens.load(Ordering::SeqCst);
        let wall = self.start.elapsed().as_secs_f64();
        if steps >= b.max_steps {
            Some(format!("step budget spent ({steps} of {})", b.max_steps))
        } else if tokens >= b.max_tokens {
            Some(format!("token budget spent ({tokens} of {})", b.max_tokens))
        } else if wall >= b.max_wall_s {
            Some(format!(
                "wall-time budget spent ({wall:.0} s of {:.0} s)",
                b.max_wall_s
            ))
        } else {
            None
        }
    }

    pub fn spend(&self) -> String {
        format!(
            "{} steps, {} input + {} output tokens, {:.0} s",
            self.steps_this_session.load(Ordering::SeqCst),
            self.input_tokens.load(Ordering::SeqCst),
            self.output_tokens.load(Ordering::SeqCst),
            self.start.elapsed().as_secs_f64()
        )
    }

    fn outcome(&self, stop: Stop) -> Outcome {
        Outcome {
            stop,
            steps: self.steps_this_session.load(Ordering::SeqCst),
            input_tokens: self.input_tokens.load(Ordering::SeqCst),
            output_tokens: self.output_tokens.load(Ordering::SeqCst),
            wall_s: self.start.elapsed().as_secs_f64(),
        }
    }
}

fn first_line(s: &str, n: usize) -> String {
    let l = s
        .lines()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("")
        .trim();
    if l.chars().count() > n {
        format!("{}…", l.chars().take(n).collect::<String>())
    } else {
        l.to_string()
    }
}

/// One tool call to record.
#[derive(Debug, Clone, Copy)]
pub struct StepRecord<'a> {
    pub step: u64,
    /// Seconds since the run started (all sessions).
    pub time_s: f64,
    pub kind: Kind,
    pub tool: &'a str,
    pub args: &'a Value,
    /// A sub-agent's label.
    pub agent: Option<&'a str>,
}

/// Records one tool call and what it returned in the ledger; returns the entry.
pub fn record_step(run: &RunDir, r: StepRecord<'_>, out: &ToolOutput) -> Result<LedgerEntry> {
    let StepRecord {
        step,
        time_s,
        kind: spec_kind,
        tool,
        args,
        agent,
    } = r;
    let mut args = args.clone();
    if let (Some(a), Some(o)) = (agent, args.as_object_mut()) {
        o.insert("agent".into(), json!(a));
    }
    let mut scores = out.scores.clone();
    if out.is_error {
        scores.insert("error".into(), 1.0);
    }
    let e = LedgerEntry {
        step,
        time_s,
        kind: spec_kind.as_str().into(),
        tool: tool.into(),
        args,
        summary: if out.is_error {
            format!("error: {}", first_line(&out.text, 240))
        } else {
            first_line(&out.text, 240)
        },
        scores,
        images: out
            .images
            .iter()
            .filter_map(|p| {
                p.strip_prefix(&run.dir)
                    .ok()
                    .map(|r| r.display().to_string())
            })
            .collect(),
        scene_version: out.scene_version,
        pose_version: out
            .pose_version
            .or_else(|| out.pose_changed.then_some(step)),
    };
    run.record(&e)?;
    Ok(e)
}

fn system_prompt(run: &RunDir, brief: Option<&str>) -> String {
    let task = agentstar_data::read_text(&run.task_path())
        .unwrap_or_else(|_| crate::task::task_document());
    let notes = agentstar_data::read_text(&run.notes_path()).unwrap_or_default();
    let mut s = task;
    if let Some(b) = brief {
        s.push_str("\n\n# Your brief (you are a pose sub-agent)\n\n");
        s.push_str(b);
    }
    s.push_str("\n\n# Your notes so far (NOTES.md)\n\n");
    s.push_str(&notes);
    s
}

/// Keeps images only in the last `keep` messages that hold any; older ones become text.
fn drop_old_images(messages: &mut [Message], keep: usize) {
    let mut seen = 0;
    for m in messages.iter_mut().rev() {
        let parts = match m {
            Message::User(p) => p,
            Message::ToolResult { parts, .. } => parts,
            Message::Assistant { .. } => continue,
        };
        if !parts.iter().any(|p| matches!(p, Part::Image { .. })) {
            continue;
        }
        seen += 1;
        if seen > keep {
            for p in parts.iter_mut() {
                if let Part::Image { path, .. } = p {
                    *p = Part::Text(format!("[image no longer shown: {}]", path.display()));
                }
            }
        }
    }
}

/// The tools a loop offers: the catalogue as `toolbox` can serve it ([`Toolbox::offers`]:
/// no `critic` without a critic model), minus `task` (in the system prompt), plus
/// `delegate_pose` for the orchestrator.
fn offered(toolbox: &Toolbox, orchestrator: bool) -> Vec<ToolSpec> {
    let mut v: Vec<ToolSpec> = catalogue()
        .into_iter()
        .filter(|t| t.name != "task" && toolbox.offers(t.name))
        .collect();
    if orchestrator {
        v.push(ToolSpec {
            name: "delegate_pose",
            kind: Kind::Pose,
            description: "Once the shape is settled, split the keyframes into windows and give each to a pose sub-agent that works in parallel with its own context (sweeps, flips and commits on its keyframes only). The brief says which basin the poses are in and which flips to check. Returns each window's final scores and summary; you then own the seams (temporal report, flip checks).",
            schema: schema_of::<DelegateArgs>(),
        });
    }
    v
}

fn opening(run: &RunDir) -> Result<Vec<Part>> {
    let st = run.state()?;
    let mut text = if st.steps == 0 {
        "Begin: look at the keyframes (render), build the model (scene_write), then the poses. Call finish when the gates hold.".to_string()
    } else {
        let mut t = format!(
            "You are resuming this run after {} step(s) ({:.0} s). The last steps from the ledger:\n",
            st.steps, st.elapsed_s
        );
        for e in &st.recent {
            t.push_str(&format!(
                "- #{} {} {}: {}\n",
                e.step, e.kind, e.tool, e.summary
            ));
        }
        t.push_str(
            "Your notes are in the system prompt. Continue; call finish when the gates hold.",
        );
        t
    };
    for n in st.notes {
        text.push_str(&format!("\n(note: {n})"));
    }
    Ok(vec![Part::Text(text)])
}

/// Runs an agent on `toolbox` until it finishes, a budget runs out or the model fails.
/// `brief` makes it a pose sub-agent for the toolbox's window.
pub fn run_agent(
    session: &Session,
    toolbox: &Toolbox,
    brief: Option<&str>,
    label: &str,
) -> Result<Outcome> {
    let orchestrator = brief.is_none();
    let tools = offered(toolbox, orchestrator);
    let mut messages: Vec<Message> = vec![Message::User(match brief {
        None => opening(&toolbox.run)?,
        Some(_) => vec![Part::Text(format!(
            "Work on your keyframes ({}). Call finish when each is at the gate or you have a reason why not.",
            toolbox.window.as_deref().unwrap_or(&[]).join(", ")
        ))],
    })];
    let mut nudges = 0;
    loop {
        if let Some(why) = session.over_budget() {
            return Ok(session.outcome(Stop::Budget(why)));
        }
        drop_old_images(&mut messages, session.budget.keep_images);
        let system = system_prompt(&toolbox.run, brief);
        let reply = complete(&session.model, &system, &messages, &tools, &|n, e| {
            (session.progress)(&format!("{label}: model request failed ({e}); retry {n}"))
        });
        let reply = match reply {
            Ok(r) => r,
            Err(e) => {
                let msg = match &e {
                    LlmError::GaveUp { failures, last, .. }
                        if failures.len() == 1 && matches!(**last, LlmError::Malformed(_)) =>
                    {
                        format!("the model kept sending malformed tool calls ({last})")
                    }
                    LlmError::GaveUp { .. } => format!("the model request failed: {e}"),
                    LlmError::Malformed(m) => {
                        format!("the model sent a malformed tool call ({m})")
                    }
                    other => format!("the model could not be reached: {other}"),
                };
                return Ok(session.outcome(Stop::ModelError(msg)));
            }
        };
        session
            .input_tokens
            .fetch_add(reply.input_tokens, Ordering::SeqCst);
        session
            .output_tokens
            .fetch_add(reply.output_tokens, Ordering::SeqCst);
        session
            .tokens
            .fetch_add(reply.input_tokens + reply.output_tokens, Ordering::SeqCst);
        if !reply.text.trim().is_empty() {
            (session.progress)(&format!("{label}: {}", first_line(&reply.text, 160)));
        }
        messages.push(Message::Assistant {
            text: reply.text.clone(),
            calls: reply.calls.clone(),
        });
        // A reply that took the session past its token budget runs none of its calls: they
        // are recorded as refused, and the run stops.
        if let Some(why) = session.over_token_budget() {
            for call in &reply.calls {
                refuse_call(session, toolbox, call, &why, orchestrator, label)?;
            }
            return Ok(session.outcome(Stop::Budget(why)));
        }
        if reply.calls.is_empty() {
            nudges += 1;
            if nudges > 3 {
                return Ok(session.outcome(Stop::ModelError(
                    "the model stopped calling tools without finishing".into(),
                )));
            }
            messages.push(Message::User(vec![Part::Text(
                "Use the tools to work; call `finish` when the gates hold (it tells you what is missing).".into(),
            )]));
            continue;
        }
        nudges = 0;
        let mut finished = false;
        let mut refused: Option<String> = None;
        for call in &reply.calls {
            // Each call takes one step of the budget before it runs; the calls of a reply
            // past the budget are refused and recorded, not run.
            let delegating = call.name == "delegate_pose" && orchestrator;
            if let Err(why) = if delegating {
                // A delegation is not a step itself; its sub-agent's calls are.
                Ok(())
            } else {
                session.take_step()
            } {
                refuse_call(session, toolbox, call, &why, orchestrator, label)?;
                messages.push(Message::ToolResult {
                    call_id: call.id.clone(),
                    name: call.name.clone(),
                    parts: vec![Part::Text(format!("refused: {why}; the call was not run"))],
                    is_error: true,
                });
                refused = Some(why);
                continue;
            }
            let out = if delegating {
                delegate(session, toolbox, call)
            } else {
                let kind = tools
                    .iter()
                    .find(|t| t.name == call.name)
                    .map_or(Kind::Diagnostic, |t| t.kind);
                let step = toolbox.run.next_step()?;
                session.step.store(step, Ordering::SeqCst);
                (session.progress)(&format!(
                    "{label}: #{step} {} {}",
                    call.name,
                    brief_args(&call.arguments)
                ));
                // The toolbox serialises the writers; searches run in parallel.
                let out = toolbox.call(&call.name, &call.arguments, step);
                record_step(
                    &toolbox.run,
                    StepRecord {
                        step,
                        time_s: session.time_s(),
                        kind,
                        tool: &call.name,
                        args: &call.arguments,
                        agent: (!orchestrator).then_some(label),
                    },
                    &out,
                )?;
                out
            };
            finished |= out.finished;
            messages.push(tool_message(call, &out, session.budget.max_tool_text));
        }
        if finished {
            return Ok(session.outcome(Stop::Finished));
        }
        if let Some(why) = refused {
            return Ok(session.outcome(Stop::Budget(why)));
        }
    }
}

/// Records a call that a budget refused: a ledger step marked as an error, so that the
/// ledger shows every call the model asked for and that none of them ran.
fn refuse_call(
    session: &Session,
    toolbox: &Toolbox,
    call: &ToolCall,
    why: &str,
    orchestrator: bool,
    label: &str,
) -> Result<()> {
    let step = toolbox.run.next_step()?;
    session.step.store(step, Ordering::SeqCst);
    (session.progress)(&format!("{label}: #{step} {} refused ({why})", call.name));
    let out = ToolOutput {
        text: format!("refused: {why}; the call was not run"),
        is_error: true,
        ..ToolOutput::default()
    };
    let mut args = call.arguments.clone();
    if let Some(o) = args.as_object_mut() {
        o.insert("refused".into(), json!(why));
    }
    record_step(
        &toolbox.run,
        StepRecord {
            step,
            time_s: session.time_s(),
            kind: Kind::Diagnostic,
            tool: &call.name,
            args: &args,
            agent: (!orchestrator).then_some(label),
        },
        &out,
    )?;
    Ok(())
}

fn brief_args(v: &Value) -> String {
    let s = v.to_string();
    if s.len() > 120 {
        format!(
            "{}…",
            &s[..s.char_indices().nth(117).map_or(s.len(), |(i, _)| i)]
        )
    } else {
        s
    }
}

fn tool_message(call: &ToolCall, out: &ToolOutput, max_text: usize) -> Message {
    let mut text = out.text.clone();
    if text.chars().count() > max_text {
        text = format!(
            "{}… [cut at {max_text} characters]",
            text.chars().take(max_text).collect::<String>()
        );
    }
    let mut parts = vec![Part::Text(text)];
    for p in &out.images {
        match Part::image(p) {
            Ok(img) => {
                parts.push(Part::Text(format!("image: {}", p.display())));
                parts.push(img);
            }
            Err(e) => parts.push(Part::Text(format!(
                "image {} could not be read: {e}",
                p.display()
            ))),
        }
    }
    Message::ToolResult {
        call_id: call.id.clone(),
        name: call.name.clone(),
        parts,
        is_error: out.is_error,
    }
}

/// A window's index, how its agent ended, and its keyframes' final visible IoU.
type WindowResult = (usize, Result<Outcome>, Vec<(String, f64)>);

/// `delegate_pose`: one sub-agent per window, in parallel; returns their outcomes.
fn delegate(session: &Session, toolbox: &Toolbox, call: &ToolCall) -> ToolOutput {
    let refuse = |text: String| ToolOutput {
        text,
        is_error: true,
        ..Default::default()
    };
    let args: DelegateArgs = match parse_args("delegate_pose", &call.arguments) {
        Ok(a) => a,
        Err(e) => {
            return refuse(format!(
                "{e} (e.g. {{\"windows\": [\"000000..000020\", \"000025..000045\"], \"brief\": \"…\"}})"
            ))
        }
    };
    if let Err(e) = crate::tools::check_bounds(
        "delegate_pose",
        &schema_of::<DelegateArgs>(),
        &call.arguments,
    ) {
        return refuse(e);
    }
    let (windows, brief) = (args.windows, args.brief);
    // The one frame grammar: names, stems, numbers and `a..b` ranges.
    let mut resolved = vec![];
    for w in &windows {
        match toolbox.frame_names(Some(w)) {
            Ok(f) => resolved.push(f),
            Err(e) => return refuse(format!("window `{w}`: {e}")),
        }
    }
    let results: Vec<WindowResult> = std::thread::scope(|scope| {
        let handles: Vec<_> = resolved
            .iter()
            .enumerate()
            .map(|(k, frames)| {
                let brief = brief.clone();
                let name = windows[k].clone();
                scope.spawn(move || {
                    let tb = toolbox.for_window(frames.clone());
                    let label = format!("window {} ({name})", k + 1);
                    let r = run_agent(session, &tb, Some(&brief), &label);
                    // The window's final scores.
                    let ious = tb.ious(Some(&frames.join(","))).unwrap_or_default();
                    (k, r, ious)
                })
            })
            .collect();
        handles.into_iter().filter_map(|h| h.join().ok()).collect()
    });
    let mut text = String::new();
    for (k, r, score) in results {
        let how = match r {
            Ok(o) => format!("{:?} after {} step(s)", o.stop, o.steps),
            Err(e) => format!("failed: {e}"),
        };
        let ious: Vec<String> = score
            .iter()
            .map(|(frame, iou)| format!("{frame} {iou:.4}"))
            .collect();
        text.push_str(&format!(
            "window {} ({}): {how}; IoU: {}\n",
            k + 1,
            windows[k],
            ious.join(", ")
        ));
    }
    text.push_str("Now check the seams between windows with `temporal` and fix any flips there.");
    ToolOutput {
        text,
        pose_changed: true,
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn old_images_leave_the_context_but_say_where_they_are() {
        let img = |n: &str| Part::Image {
            mime: "image/png".into(),
            data_b64: "AA".into(),
            path: n.into(),
        };
        let mut m = vec![
            Message::User(vec![img("a.png")]),
            Message::Assistant {
                text: String::new(),
                calls: vec![],
            },
            Message::ToolResult {
                call_id: "1".into(),
                name: "render".into(),
                parts: vec![img("b.png")],
                is_error: false,
            },
            Message::ToolResult {
                call_id: "2".into(),
                name: "render".into(),
                parts: vec![img("c.png")],
                is_error: false,
            },
        ];
        drop_old_images(&mut m, 2);
        assert_eq!(
            m[0],
            Message::User(vec![Part::Text("[image no longer shown: a.png]".into())])
        );
        assert!(
            matches!(&m[2], Message::ToolResult { parts, .. } if matches!(parts[0], Part::Image { .. }))
        );
    }
}
