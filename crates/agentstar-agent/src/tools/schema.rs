//! Tool argument schemas: generated from each argument struct, made self-contained and
//! checked (bounds and lengths) before anything runs; the help a bad call is answered with.

use crate::{AgentError, Result};
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde_json::Value;

/// The JSON Schema of `A`, self-contained (no `$schema`, no references), options not
/// nullable.
pub fn schema_of<A: JsonSchema>() -> Value {
    let generator = schemars::generate::SchemaSettings::draft2020_12()
        .with(|s| {
            s.meta_schema = None;
            s.inline_subschemas = true;
        })
        .into_generator();
    let mut v = generator.into_root_schema_for::<A>().to_value();
    if let Some(o) = v.as_object_mut() {
        // The struct's own doc comment is for people reading the code.
        o.remove("title");
        o.remove("description");
        let props = o
            .entry("properties")
            .or_insert_with(|| Value::Object(Default::default()));
        // An optional argument is left out, not sent as null: say so in its schema, at
        // every depth (the fields of `finish`'s reasons too).
        if let Some(props) = props.as_object_mut() {
            for p in props.values_mut() {
                drop_null(p);
                tidy(p);
            }
        }
    }
    v
}

/// Below the top level: nested properties lose their `null` like the top-level ones, and
/// descriptions from multi-line doc comments become one line per paragraph (a model reads
/// the schema as text; line breaks from the source's wrapping are noise there).
pub(super) fn tidy(v: &mut Value) {
    match v {
        Value::Object(o) => {
            if let Some(Value::String(d)) = o.get_mut("description") {
                *d = one_line_paragraphs(d);
            }
            if let Some(Value::Object(props)) = o.get_mut("properties") {
                for p in props.values_mut() {
                    drop_null(p);
                }
            }
            for (k, child) in o.iter_mut() {
                if k != "description" && k != "enum" && k != "const" && k != "default" {
                    tidy(child);
                }
            }
        }
        Value::Array(items) => items.iter_mut().for_each(tidy),
        _ => {}
    }
}

/// `"a\nb\n\nc"` → `"a b\n\nc"`.
pub(super) fn one_line_paragraphs(text: &str) -> String {
    text.split("\n\n")
        .map(|para| para.split_whitespace().collect::<Vec<_>>().join(" "))
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join("\n\n")
}

/// Removes `null` from a property's types (`["string", "null"]` → `"string"`, an
/// `anyOf` with a null branch → the other branch).
pub(super) fn drop_null(p: &mut Value) {
    let Some(o) = p.as_object_mut() else { return };
    if let Some(Value::Array(types)) = o.get_mut("type") {
        types.retain(|t| t != "null");
        if types.len() == 1 {
            let t = types[0].clone();
            o.insert("type".into(), t);
        }
    }
    if let Some(Value::Array(values)) = o.get_mut("enum") {
        values.retain(|v| !v.is_null());
    }
    if let Some(Value::Array(branches)) = o.get("anyOf").cloned().as_ref() {
        let rest: Vec<&Value> = branches.iter().filter(|b| b["type"] != "null").collect();
        if let [only] = rest.as_slice() {
            o.remove("anyOf");
            if let Some(inner) = only.as_object() {
                for (k, v) in inner {
                    o.entry(k.clone()).or_insert_with(|| v.clone());
                }
            }
        }
    }
}

/// Deserialises a tool's arguments (missing = `{}`); the error names the tool.
pub fn parse_args<A: DeserializeOwned + JsonSchema>(tool: &str, args: &Value) -> Result<A> {
    let v = match args {
        Value::Null => Value::Object(Default::default()),
        Value::Object(_) => args.clone(),
        other => {
            return Err(AgentError::Tool(format!(
                "{tool}: the arguments must be an object, not {other}"
            )))
        }
    };
    serde_json::from_value(v).map_err(|e| {
        AgentError::Tool(format!(
            "{tool}: bad arguments: {}",
            unknown_field_named(&e.to_string(), &schema_of::<A>()).unwrap_or_else(|| e.to_string())
        ))
    })
}

/// `serde`'s "unknown field `x`, expected one of …" names only the fields of the outer
/// struct, not those of a flattened one (`osweep`'s `crop` and `zoom`): the same error with
/// every argument the schema has. `None` for any other error.
fn unknown_field_named(error: &str, schema: &Value) -> Option<String> {
    let rest = error.strip_prefix("unknown field `")?;
    let field = &rest[..rest.find('`')?];
    let names: Vec<String> = schema
        .get("properties")
        .and_then(Value::as_object)?
        .keys()
        .map(|k| format!("`{k}`"))
        .collect();
    Some(format!(
        "unknown field `{field}`; the arguments are {}",
        names.join(", ")
    ))
}

/// The bounds of a schema that `serde` does not check: `minimum`, `maximum`,
/// `exclusiveMinimum`, `minLength`, `maxLength` of each property given.
pub fn check_bounds(tool: &str, schema: &Value, args: &Value) -> std::result::Result<(), String> {
    let (Some(props), Some(given)) = (
        schema.get("properties").and_then(Value::as_object),
        args.as_object(),
    ) else {
        return Ok(());
    };
    let num = |s: &Value, k: &str| s.get(k).and_then(Value::as_f64);
    for (key, value) in given {
        let Some(s) = props.get(key) else { continue };
        if let Some(x) = value.as_f64() {
            if let Some(min) = num(s, "minimum").filter(|m| x < *m) {
                return Err(format!(
                    "{tool}: `{key}` is {value}, under its minimum {min}"
                ));
            }
            if let Some(max) = num(s, "maximum").filter(|m| x > *m) {
                return Err(format!(
                    "{tool}: `{key}` is {value}, over its maximum {max}"
                ));
            }
            if let Some(min) = num(s, "exclusiveMinimum").filter(|m| x <= *m) {
                return Err(format!("{tool}: `{key}` is {value}; it must be over {min}"));
            }
            if !x.is_finite() {
                return Err(format!("{tool}: `{key}` must be finite"));
            }
        }
        if let Some(text) = value.as_str() {
            let n = text.chars().count();
            if let Some(min) = num(s, "minLength").filter(|m| (n as f64) < *m) {
                return Err(format!(
                    "{tool}: `{key}` must have at least {min} character(s)"
                ));
            }
            if let Some(max) = num(s, "maxLength").filter(|m| (n as f64) > *m) {
                return Err(format!(
                    "{tool}: `{key}` has {n} characters, over its limit of {max}"
                ));
            }
        }
    }
    Ok(())
}

/// A JSON schema's type as an agent reads it: `list of string`, `integer 1–10`,
/// `{category: "out_of_reach", note: string}`, `map of key → …`, alternatives with `|`.
pub(super) fn schema_type(s: &Value) -> String {
    if let Some(c) = s.get("const") {
        return c.to_string();
    }
    if let Some(Value::Array(values)) = s.get("enum") {
        return values
            .iter()
            .map(Value::to_string)
            .collect::<Vec<_>>()
            .join(" | ");
    }
    for key in ["oneOf", "anyOf"] {
        if let Some(Value::Array(branches)) = s.get(key) {
            return branches
                .iter()
                .filter(|b| b["type"] != "null")
                .map(schema_type)
                .collect::<Vec<_>>()
                .join(" | ");
        }
    }
    let kind = match s.get("type") {
        Some(Value::String(t)) => t.as_str(),
        Some(Value::Array(ts)) => ts
            .iter()
            .filter_map(Value::as_str)
            .find(|t| *t != "null")
            .unwrap_or("any"),
        _ => "any",
    };
    let bound = |k: &str| s.get(k).and_then(Value::as_f64);
    match kind {
        "array" => format!(
            "list of {}",
            s.get("items").map_or("any".to_string(), schema_type)
        ),
        "integer" | "number" => match (bound("minimum"), bound("maximum")) {
            (Some(lo), Some(hi)) => format!("{kind} {lo}–{hi}"),
            (Some(lo), None) => format!("{kind} ≥ {lo}"),
            (None, Some(hi)) => format!("{kind} ≤ {hi}"),
            (None, None) => kind.to_string(),
        },
        "object" => {
            if let Some(props) = s.get("properties").and_then(Value::as_object) {
                let required = required_of(s);
                let fields: Vec<String> = props
                    .iter()
                    .map(|(k, v)| {
                        let mark = if required.contains(&k.as_str()) {
                            ""
                        } else {
                            "?"
                        };
                        format!("{k}{mark}: {}", schema_type(v))
                    })
                    .collect();
                format!("{{{}}}", fields.join(", "))
            } else if let Some(values) = s.get("additionalProperties").filter(|v| v.is_object()) {
                format!("map of key → {}", schema_type(values))
            } else {
                "object".to_string()
            }
        }
        other => other.to_string(),
    }
}

pub(super) fn required_of(s: &Value) -> Vec<&str> {
    s.get("required")
        .and_then(Value::as_array)
        .map(|r| r.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default()
}

/// What a tool takes, one line per argument (name, required or not, type, the first
/// sentence of its description): appended to a bad call's error, for agents that do not
/// read the schema.
pub fn arguments_help(tool: &str, schema: &Value) -> String {
    let Some(props) = schema.get("properties").and_then(Value::as_object) else {
        return String::new();
    };
    if props.is_empty() {
        return format!("{tool} takes no arguments: call it with {{}}");
    }
    let required = required_of(schema);
    let mut out = format!("{tool} takes:");
    for (name, s) in props {
        let first = s
            .get("description")
            .and_then(Value::as_str)
            .map(|d| {
                let sentence = d.split(". ").next().unwrap_or(d).trim_end_matches('.');
                let short: String = sentence.chars().take(140).collect();
                if short.len() < sentence.len() {
                    format!(": {short}…")
                } else {
                    format!(": {short}")
                }
            })
            .unwrap_or_default();
        out.push_str(&format!(
            "\n- `{name}` ({}{}){first}",
            if required.contains(&name.as_str()) {
                "required, "
            } else {
                ""
            },
            schema_type(s)
        ));
    }
    out
}
