//! The numerical half of the agentic loop: pose updates in the reference harness's
//! conventions (camera-frame orders about the pivot, object-frame rotations, flips),
//! search spaces with their grammar and presets, scoring of candidates, searches
//! (differential evolution with restarts, grids, explicit candidates), temporal
//! diagnostics, and an automatic tracker for a known model. No file I/O.

pub mod appearance;
pub mod axis;
pub mod bake;
pub mod hypotheses;
pub mod objective;
pub mod proportion;
pub mod scale;
pub mod search;
pub mod sequence;
pub mod shape;
pub mod space;
pub mod standin;
pub mod symmetry;
pub mod temporal;
pub mod tracker;
pub mod tracks;
pub mod update;

pub use objective::{CandidateScore, FrameProblem};
pub use search::{sweep, Candidate, Strategy, SweepConfig, SweepResult};
pub use space::{Dof, DofRange, SearchSpace, SpaceKind};
pub use update::{CameraOrder, GenPose};

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackError {
    #[error("{0}")]
    Spec(String),
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Optim(#[from] agentstar_optim::OptimError),
}
