//! The jobs table printed by `status` and after `gather`'s metric tables: per job its state,
//! attempts, wall times and, for agent runs, steps and tokens.

use crate::state::JobState;
use std::collections::BTreeMap;
use std::fmt::Write;

/// What an agent run spent, read from its ledger.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AgentSpend {
    /// Steps in the ledger (tool calls, all sessions).
    pub steps: u64,
    pub input_tokens: u64,
    pub output_tokens: u64,
    /// The run's own clock across sessions, seconds.
    pub elapsed_s: f64,
}

impl AgentSpend {
    /// From ledger entries as `(step, time_s, tool, scores)`: every session ends with a
    /// `stop` entry whose scores carry that session's `input_tokens` and `output_tokens`.
    pub fn from_ledger<'a>(
        entries: impl IntoIterator<Item = (u64, f64, &'a str, &'a BTreeMap<String, f64>)>,
    ) -> AgentSpend {
        let mut s = AgentSpend::default();
        for (step, time_s, tool, scores) in entries {
            s.steps = s.steps.max(step);
            s.elapsed_s = s.elapsed_s.max(time_s);
            if tool == "stop" {
                let get = |k: &str| scores.get(k).copied().unwrap_or(0.0).max(0.0) as u64;
                s.input_tokens += get("input_tokens");
                s.output_tokens += get("output_tokens");
            }
        }
        s
    }
}

/// The evaluations the tracker reports in `text`: the sum over every line of the form
/// `tracked N frames in S s (K evaluations), …` (what `agentstar track` prints on stdout
/// and the agent's `track` tool in its ledger summary); `None` when no line says so.
pub fn tracked_evaluations(text: &str) -> Option<u64> {
    let mut total = None;
    for line in text.lines() {
        let Some(rest) = line.trim_start().strip_prefix("tracked ") else {
            continue;
        };
        let Some(end) = rest.find(" evaluations)") else {
            continue;
        };
        let Some(open) = rest[..end].rfind('(') else {
            continue;
        };
        if let Ok(n) = rest[open + 1..end].trim().parse::<u64>() {
            total = Some(total.unwrap_or(0) + n);
        }
    }
    total
}

/// The part of a job's log written by its last attempt (after the last `== attempt` line).
pub fn last_attempt_log(log: &str) -> &str {
    match log.rfind("== attempt ") {
        Some(i) => &log[i..],
        None => log,
    }
}

/// One row.
#[derive(Debug, Clone, PartialEq)]
pub struct JobRow {
    pub name: String,
    pub method: String,
    pub state: JobState,
    pub attempts: usize,
    /// The finishing attempt's seconds (track) or the run's own clock (agent).
    pub wall_s: Option<f64>,
    /// Every attempt's seconds together.
    pub total_wall_s: f64,
    pub agent: Option<AgentSpend>,
}

fn opt(v: Option<String>) -> String {
    v.unwrap_or_else(|| "–".into())
}

/// The Markdown table of jobs, in the order given.
pub fn jobs_table(rows: &[JobRow]) -> String {
    let mut out = String::from(
        "### Jobs\n\n| job | method | state | attempts | wall time (s) | all attempts (s) | agent steps | input tokens | output tokens |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1} | {} | {} | {} |",
            r.name,
            r.method,
            r.state,
            r.attempts,
            opt(r.wall_s.map(|s| format!("{s:.1}"))),
            r.total_wall_s,
            opt(r.agent.map(|a| a.steps.to_string())),
            opt(r.agent.map(|a| a.input_tokens.to_string())),
            opt(r.agent.map(|a| a.output_tokens.to_string())),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spend_sums_sessions_and_takes_the_last_step() {
        let a: BTreeMap<String, f64> = [
            ("input_tokens".to_string(), 1200.0),
            ("output_tokens".to_string(), 300.0),
        ]
        .into_iter()
        .collect();
        let b: BTreeMap<String, f64> = [("input_tokens".to_string(), 800.0)].into_iter().collect();
        let none = BTreeMap::new();
        let s = AgentSpend::from_ledger([
            (1, 2.0, "scene_edit", &none),
            (2, 5.0, "stop", &a),
            (3, 9.5, "score", &a),
            (4, 12.0, "stop", &b),
        ]);
        assert_eq!(
            s,
            AgentSpend {
                steps: 4,
                input_tokens: 2000,
                output_tokens: 300,
                elapsed_s: 12.0
            }
        );
    }

    #[test]
    fn evaluations_are_read_from_what_the_tracker_prints() {
        let log = "== attempt 1 of job box on h (Local): agentstar track …\ntracked 4 frames in 2.0 s (999 evaluations), initialised on f0; wrote x\n== attempt 2 of job box on h (Local): agentstar track …\ntrack: phase 1\ntracked 4 frames in 1.5 s (12345 evaluations), initialised on f0001; wrote /b/jobs/box/pose.json (version 1 of its history)\n";
        assert_eq!(tracked_evaluations(last_attempt_log(log)), Some(12345));
        assert_eq!(tracked_evaluations(log), Some(13344));
        assert_eq!(
            tracked_evaluations("tracked 2 frame(s) in 0.3 s (40 evaluations), initialised on a\n"),
            Some(40)
        );
        assert_eq!(tracked_evaluations("== attempt 1\nkilled\n"), None);
        assert_eq!(last_attempt_log("no attempts"), "no attempts");
    }

    #[test]
    fn the_jobs_table_has_a_row_per_job() {
        let t = jobs_table(&[
            JobRow {
                name: "laptop".into(),
                method: "track".into(),
                state: JobState::Finished,
                attempts: 2,
                wall_s: Some(12.34),
                total_wall_s: 20.0,
                agent: None,
            },
            JobRow {
                name: "box".into(),
                method: "ollama:qwen".into(),
                state: JobState::Interrupted,
                attempts: 1,
                wall_s: None,
                total_wall_s: 0.0,
                agent: Some(AgentSpend {
                    steps: 7,
                    input_tokens: 10,
                    output_tokens: 2,
                    elapsed_s: 1.0,
                }),
            },
        ]);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), 6);
        assert_eq!(
            lines[4],
            "| laptop | track | finished | 2 | 12.3 | 20.0 | – | – | – |"
        );
        assert_eq!(
            lines[5],
            "| box | ollama:qwen | interrupted | 1 | – | 0.0 | 7 | 10 | 2 |"
        );
    }
}
