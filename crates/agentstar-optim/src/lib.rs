//! Derivative-free optimisers over bounded boxes, generic over the objective: differential
//! evolution with SciPy's `best1bin` behaviour, bounded Nelder–Mead polish, bounded CMA-ES,
//! grids with coarse-to-fine refinement, and a seeded random generator. Nothing here knows about
//! images, poses or renderers; every search is deterministic for its seed.

pub mod cma;
pub mod de;
pub mod grid;
pub mod nelder_mead;
pub mod rng;

pub use cma::{cma_es, CmaConfig, CmaResult};
pub use de::{differential_evolution, DeConfig, DeResult, Termination};
pub use grid::{grid_search, GridConfig, GridPoint};
pub use nelder_mead::{nelder_mead, NelderMeadConfig};
pub use rng::Rng;

/// A bounded search box: `(lower, upper)` per dimension, lower ≤ upper.
pub type Bounds = [(f64, f64)];

/// Errors of the optimisers: bad boxes and bad settings, with what is valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OptimError {
    #[error("dimension {dim}: bounds ({lo}, {hi}) must be finite with lower ≤ upper")]
    Bounds { dim: usize, lo: f64, hi: f64 },
    #[error("{0}")]
    Config(String),
}

pub(crate) fn check_bounds(bounds: &Bounds) -> Result<(), OptimError> {
    for (dim, &(lo, hi)) in bounds.iter().enumerate() {
        if !(lo.is_finite() && hi.is_finite()) || lo > hi {
            return Err(OptimError::Bounds { dim, lo, hi });
        }
    }
    Ok(())
}
