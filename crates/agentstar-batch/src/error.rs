//! The errors of batch planning and of parsing scheduler output.

/// What went wrong, with what and where.
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// A plan or a flag that cannot be carried out.
    #[error("{0}")]
    Invalid(String),
    /// Scheduler output we could not read.
    #[error("cannot read the output of `{command}`: {message} (line: `{line}`)")]
    Parse {
        command: &'static str,
        message: String,
        line: String,
    },
}
