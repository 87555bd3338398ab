//! Shared test fixtures (each test file uses some of them).
#![allow(dead_code)]

pub mod case;
pub mod view;
