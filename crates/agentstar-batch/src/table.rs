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
