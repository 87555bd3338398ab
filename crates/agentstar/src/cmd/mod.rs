//! One module per subcommand.

pub mod check;
pub mod example;
pub mod export;
pub mod render;
pub mod score;
pub mod turntable;
pub mod validate;
