//! The agent harness: a run directory and its ledger (`run`), the task document (`task`),
//! the tool registry and its execution (`tools`; the typed reports the commands write and
//! the tools read are `agentstar-reports`, pose file versions and keeping `pose.json` in
//! step with the scene are `agentstar_data::{history, poses}`), model clients for OpenAI-compatible servers and Anthropic (`llm`), and
//! the agent loop with pose sub-agents (`agent`). The critic is a model call made through
//! `llm` (`critic`).
//!
//! This crate does I/O (files, child processes, HTTP) on behalf of the binary; it knows
//! nothing of MCP (the binary serves the same catalogue over MCP).

pub mod agent;
pub mod critic;
pub mod llm;
pub mod run;
pub mod task;
pub mod tools;

/// What can go wrong in the harness.
#[derive(Debug, thiserror::Error)]
pub enum AgentError {
    #[error("{0}")]
    Data(#[from] agentstar_data::DataError),
    #[error("{0}")]
    History(#[from] agentstar_data::history::HistoryError),
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    Tool(String),
}

pub type Result<T, E = AgentError> = std::result::Result<T, E>;
