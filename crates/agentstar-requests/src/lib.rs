//! Requests to the `agentstar` commands as types. The agent's tools run the commands as child
//! processes; what they pass is built here from typed values, never as hand-written flag
//! text:
//!
//! - [`SessionArgs`]: the capture, model and pose file every command on a posed model takes
//!   (the binary flattens it into those commands' arguments);
//! - [`Output`]: where a command writes its files, and `--json`;
//! - the requests the MCP tools take and the commands flatten, one type each (the
//!   object-frame pose verbs: [`OsweepArgs`], [`OapplyArgs`], [`OapplyAllArgs`]; and
//!   [`TurntableArgs`], [`PoseDiffArgs`], [`TemporalArgs`], [`BakeArgs`]);
//! - [`ScaleMethod`] and [`SizeAxis`]: `scale`'s choices, which its report records too;
//! - [`SheetView`]: a search verb's candidate sheet (`crop`, `zoom`), and [`WithSheet`], a
//!   search request with it as one flat set of tool arguments;
//! - the rules a command and its tool share, on the type both read: [`OsweepArgs::region`],
//!   [`WarmStart::check`] (`track`);
//! - [`to_args`]: the one rule that turns any serialisable request into arguments: each
//!   field `name` becomes `--name=VALUE` (snake case to kebab case), `true` a bare `--name`,
//!   `false`, `null` and absent fields nothing, a list one `--name=ITEM` per item.
//!
//! Values are attached with `=`, so a value that starts with `-` (a frame spec of `-1`, a
//! note of `--`) is always the value of its flag, never read as an option.
//!
//! A test in the binary parses every tool's generated arguments with the binary's own
//! parser (`tool_args.rs`), so a field the command does not take fails there.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::PathBuf;

pub mod bake;
pub mod object;
pub mod scale;
pub mod sheet;
pub mod track;
pub mod views;

pub use bake::BakeArgs;
pub use object::{OapplyAllArgs, OapplyArgs, OsweepArgs, Region, RowOrder};
pub use scale::{ScaleMethod, SizeAxis};
pub use sheet::{RankRange, SheetView, WithSheet};
pub use track::WarmStart;
pub use views::{Crop, PoseDiffArgs, TemporalArgs, TurntableArgs};

/// What a `frames` argument takes (the one frame grammar, `Capture::select`).
pub const FRAMES: &str = "Keyframes: `all`, names (`000010.png`), stems (`000010`), keyframe numbers, or ranges `a..b`, comma separated. An in-between frame is refused, with the keyframes it lies between named.";

/// A request that cannot be turned into arguments.
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    #[error("a request must be a struct of named fields, not {0}")]
    NotAStruct(String),
    #[error("field `{field}`: {what} cannot be a command-line value")]
    Unsupported { field: String, what: &'static str },
    #[error("cannot encode a request: {0}")]
    Encode(#[from] serde_json::Error),
}

/// The three inputs of every command that works on a posed model.
#[derive(clap::Args, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionArgs {
    /// The capture directory (holding capture.json).
    #[arg(long)]
    pub capture: PathBuf,
    /// The model: scene script (.rhai), URDF or mesh.
    #[arg(long)]
    pub model: PathBuf,
    /// The pose file.
    #[arg(long)]
    pub poses: PathBuf,
}

/// Where a command writes its files, and whether it prints JSON (`--out DIR --json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Output {
    pub out: PathBuf,
    pub json: bool,
}

/// `request` as command-line arguments (see the crate's docs for the rule).
pub fn to_args<T: Serialize>(request: &T) -> Result<Vec<String>, RequestError> {
    let value = serde_json::to_value(request)?;
    if value.is_null() {
        // `()`: a request with nothing to add.
        return Ok(Vec::new());
    }
    let Value::Object(fields) = value else {
        return Err(RequestError::NotAStruct(kind_of(&value).into()));
    };
    let mut args = Vec::new();
    for (name, value) in &fields {
        let flag = format!("--{}", name.replace('_', "-"));
        match value {
            Value::Null | Value::Bool(false) => {}
            Value::Bool(true) => args.push(flag),
            Value::Array(items) => {
                for item in items {
                    args.push(format!("{flag}={}", scalar(name, item)?));
                }
            }
            other => args.push(format!("{flag}={}", scalar(name, other)?)),
        }
    }
    Ok(args)
}

/// The text of one value.
fn scalar(field: &str, value: &Value) -> Result<String, RequestError> {
    match value {
        Value::String(s) => Ok(s.clone()),
        Value::Number(n) => Ok(n.to_string()),
        Value::Bool(b) => Ok(b.to_string()),
        other => Err(RequestError::Unsupported {
            field: field.to_string(),
            what: kind_of(other),
        }),
    }
}

fn kind_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "a list",
        Value::Object(_) => "an object",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Request {
        frames: Option<String>,
        sort_by: Option<String>,
        evals: Option<u64>,
        no_refine: bool,
        apply: bool,
        params: Vec<String>,
        weight: f64,
    }

    #[test]
    fn fields_become_flags_with_their_values_attached() {
        let r = Request {
            frames: Some("-1".into()),
            sort_by: None,
            evals: Some(400),
            no_refine: true,
            apply: false,
            params: vec!["width".into(), "--".into()],
            weight: 0.5,
        };
        let mut args = to_args(&r).expect("args");
        args.sort();
        assert_eq!(
            args,
            [
                "--evals=400",
                "--frames=-1",
                "--no-refine",
                "--params=--",
                "--params=width",
                "--weight=0.5"
            ]
        );
    }

    #[test]
    fn a_session_is_three_flags() {
        let s = SessionArgs {
            capture: "cap".into(),
            model: "run/scene.rhai".into(),
            poses: "run/pose.json".into(),
        };
        let mut args = to_args(&s).expect("args");
        args.sort();
        assert_eq!(
            args,
            [
                "--capture=cap",
                "--model=run/scene.rhai",
                "--poses=run/pose.json"
            ]
        );
    }

    #[test]
    fn what_is_not_a_struct_of_values_is_refused_by_name() {
        assert!(matches!(to_args(&3), Err(RequestError::NotAStruct(_))));
        #[derive(Serialize)]
        struct Nested {
            inner: std::collections::BTreeMap<String, u8>,
        }
        let e = to_args(&Nested {
            inner: [("a".to_string(), 1)].into(),
        })
        .expect_err("nested");
        assert!(e.to_string().contains("`inner`"), "{e}");
    }
}
