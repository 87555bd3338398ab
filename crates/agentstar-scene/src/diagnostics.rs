//! Turning Rhai's errors into messages a language model can act on.

use std::fmt;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneErrorKind {
    /// The script does not parse.
    Syntax,
    /// A name that is not part of the scene API or not defined.
    UnknownName,
    /// A call with the wrong arguments or invalid values.
    InvalidCall,
    /// The script hit a bound (operations, time, size, depth).
    Limit,
    /// The script ran but the model it declared is inconsistent (joints, parts).
    Model,
}

/// A scene failure with where it happened and what would be valid.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    pub kind: SceneErrorKind,
    pub message: String,
    pub line: Option<usize>,
    pub column: Option<usize>,
    /// Parts defined before the failure, in order.
    pub parts_so_far: Vec<String>,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.line, self.column) {
            (Some(l), Some(c)) => write!(f, "{} at {l}:{c}", self.message)?,
            (Some(l), None) => write!(f, "{} at line {l}", self.message)?,
            _ => write!(f, "{}", self.message)?,
        }
        if self.parts_so_far.is_empty() {
            write!(f, " (no parts defined yet)")
        } else {
            write!(
                f,
                " (parts defined so far: {})",
                self.parts_so_far.join(", ")
            )
        }
    }
}

impl std::error::Error for SceneError {}

/// The closest names to `wanted` among `candidates`, best first (at most three).
pub fn suggestions<'a>(
    wanted: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Vec<&'a str> {
    let mut scored: Vec<(f64, &str)> = candidates
        .into_iter()
        .map(|c| (strsim::jaro_winkler(wanted, c), c))
        .filter(|(s, _)| *s > 0.75)
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(b.1)));
    scored.dedup_by(|a, b| a.1 == b.1);
    scored.into_iter().take(3).map(|(_, c)| c).collect()
}

pub fn did_you_mean(wanted: &str, candidates: &[&str]) -> String {
    match suggestions(wanted, candidates.iter().copied()).as_slice() {
        [] => String::new(),
        [one] => format!("; did you mean `{one}`?"),
        many => format!(
            "; did you mean one of {}?",
            many.iter()
                .map(|m| format!("`{m}`"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}
