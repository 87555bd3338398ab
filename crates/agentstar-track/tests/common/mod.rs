//! Shared test fixtures.

pub mod case;
