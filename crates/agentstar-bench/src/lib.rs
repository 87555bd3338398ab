//! The benchmark harness. Ground truth in the evaluator's form ([`gt`]); suites of synthetic
//! sequences ([`suite`]); one sequence synthesised, tracked by a method (the automatic
//! tracker or one of the paper's agent-free ablations) and evaluated ([`run`]); the paper's
//! tables as Markdown ([`table`]); where each miss comes from ([`misses`]); tolerances recorded from a run and checked against
//! later ones ([`tolerance`]).
//!
//! No file I/O: everything runs in memory; the `agentstar bench` command writes results.

pub mod misses;
pub mod run;
pub mod suite;
pub mod table;
pub mod tolerance;

pub use run::{run_sequence, run_sequence_observed, Method, RunConfig, RunInfo, SequenceResult};
pub use suite::{suite, SequenceSpec};

#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("{0}")]
    Synth(#[from] agentstar_synth::SynthError),
    #[error("tracking {id}: {source}")]
    Track {
        id: String,
        source: agentstar_track::TrackError,
    },
    #[error("ground truth: {0}")]
    GroundTruth(String),
    #[error("{0}")]
    Invalid(String),
}
