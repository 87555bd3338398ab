//! One module per subcommand.

pub mod agent;
pub mod bake;
pub mod batch;
pub mod bench;
pub mod bench_sfm;
pub mod capture;
pub mod check;
pub mod demo;
pub mod eval;
pub mod example;
pub mod export;
pub mod fit;
pub mod mcp;
pub mod mechanism;
pub mod pose;
pub mod render;
pub mod report;
pub mod scale;
pub mod score;
pub mod search;
pub mod synth;
pub mod temporal;
pub mod track;
pub mod turntable;
pub mod validate;
