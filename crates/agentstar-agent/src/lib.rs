//! The agent harness: a run directory and its ledger (`run`), the task document (`task`),
//! the tool registry and its execution (`tools`), the typed reports commands write and
//! tools read (`reports`, and `view_reports` for the image commands), pose file versions under one lock (`history`), keeping `pose.json` in step with the
//! scene (`poses`), model clients for OpenAI-compatible servers and Anthropic (`llm`), and
//! the agent loop with pose sub-agents (`agent`). The critic is a model call made through
//! `llm` (`critic`).
//!
//! This crate does I/O (files, child processes, HTTP) on behalf of the binary; it knows
//! nothing of MCP (the binary serves the same catalogue over MCP).

pub mod agent;
pub mod critic;
pub mod fit;
pub mod history;
pub mod llm;
pub mod poses;
pub mod reports;
pub mod run;
pub mod task;
pub mod tools;
pub mod view_reports;

/// What can go wrong in the harness.
#[derive(Debug, thiserror::Error)]
pub enum AgentError {
    #[error("{0}")]
    Data(#[from] agentstar_data::DataError),
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    Tool(String),
}

pub type Result<T, E = AgentError> = std::result::Result<T, E>;
