//! Tool arguments as a model writes them, mutated: every tool's argument parsing and schema
//! check answer every input (an error naming the tool, or the parsed arguments), never
//! panic or hang. The corpus (`fuzz/corpus/tool_args/`) holds values that start with `-`
//! or `--`, out-of-range numbers and nested objects; the command lines built from parsed
//! arguments attach every value with `=` (`agentstar_requests::to_args`), so such values
//! are never read as options (the binary's `tool_args` test parses them).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use agentstar_agent::tools::registry;

#[test]
fn tool_arguments_never_panic_the_parser() {
    harness::fuzz(
        vec![(
            "tool_args",
            Box::new(|b: &[u8]| {
                for args in arguments_from(b) {
                    for tool in registry() {
                        let _ = tool.parse_args(&args);
                    }
                }
            }) as harness::Run,
        )],
        6,
    );
}

/// The text fields the tools take, by name.
const TEXT_FIELDS: &[&str] = &[
    "frames", "ranges", "report", "label", "from", "anchors", "rotation", "order", "frame", "set",
    "opreset", "views", "states", "a", "b", "text", "summary", "sort_by", "script", "path",
    "outline", "strategy", "method", "axis", "joints",
];

/// The argument objects one input stands for: the input itself where it is JSON, else
/// every text field holding the input as its value (most byte mutations break the JSON, so
/// the mutated text still reaches the fields), and every number field its number.
fn arguments_from(b: &[u8]) -> Vec<serde_json::Value> {
    if let Ok(v) = serde_json::from_slice::<serde_json::Value>(b) {
        return vec![v];
    }
    let text = String::from_utf8_lossy(b).into_owned();
    let mut out: Vec<serde_json::Value> = TEXT_FIELDS
        .iter()
        .map(|f| serde_json::json!({ *f: text }))
        .collect();
    if let Ok(x) = text.trim().parse::<f64>() {
        for f in [
            "evals", "rank", "rounds", "scale", "metres", "margin", "zoom", "version", "last",
        ] {
            out.push(serde_json::json!({ f: x }));
        }
    }
    out
}
