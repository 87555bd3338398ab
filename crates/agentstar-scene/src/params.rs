//! Writing parameter values back into a script: the `value` argument of each named
//! `param("name", value, min, max)` call is replaced in the source text, everything else
//! (comments, layout, other calls) is left as it was.

use std::collections::BTreeMap;

/// A value as written into a script: at most six decimals, trailing zeros dropped, always
/// with a decimal point (`0.595`, `1.0`, `-0.25`).
pub fn format_param_value(v: f64) -> String {
    let mut s = format!("{:.6}", v);
    while s.ends_with('0') && !s.ends_with(".0") {
        s.pop();
    }
    if s == "-0.0" {
        s = "0.0".into();
    }
    s
}

/// `source` with the value of every `param` named in `values` replaced (formatted by
/// [`format_param_value`]). The value must be a number literal in the script; a name that
/// no `param("name", <number>, …)` call carries is an error naming it.
pub fn set_param_values(source: &str, values: &BTreeMap<String, f64>) -> Result<String, String> {
    let calls = param_calls(source);
    let mut edits: Vec<(usize, usize, String)> = vec![];
    for (name, v) in values {
        let found: Vec<&ParamCall> = calls.iter().filter(|c| &c.name == name).collect();
        match found.as_slice() {
            [] => {
                return Err(format!(
                    "no `param(\"{name}\", <number>, min, max)` call in the script; its value must be a number literal to be written back"
                ))
            }
            [one] => match one.value {
                Some((a, b)) => edits.push((a, b, format_param_value(*v))),
                None => {
                    return Err(format!(
                        "the value of `param(\"{name}\", …)` is not a number literal; write it as one (e.g. param(\"{name}\", 0.5, 0.4, 0.6)) so it can be written back"
                    ))
                }
            },
            _ => return Err(format!("`param(\"{name}\", …)` appears more than once in the script")),
        }
    }
    edits.sort_by_key(|e| std::cmp::Reverse(e.0));
    let mut out = source.to_string();
    for (a, b, text) in edits {
        out.replace_range(a..b, &text);
    }
    Ok(out)
}

/// One `param(` call found in the source: its name and the byte span of its value literal.
#[derive(Debug, PartialEq)]
struct ParamCall {
    name: String,
    value: Option<(usize, usize)>,
}

/// Every `param("name", …)` call outside comments and strings.
fn param_calls(src: &str) -> Vec<ParamCall> {
    let b = src.as_bytes();
    let mut calls = vec![];
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'/' if b.get(i + 1) == Some(&b'/') => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                let mut depth = 0usize;
                while i < b.len() {
                    if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                        depth += 1;
                        i += 2;
                    } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                        depth -= 1;
                        i += 2;
                        if depth == 0 {
                            break;
                        }
                    } else {
                        i += 1;
                    }
                }
            }
            b'"' | b'`' | b'\'' => i = skip_string(b, i).unwrap_or(b.len()),
            c if is_ident(c) => {
                let start = i;
                while i < b.len() && is_ident(b[i]) {
                    i += 1;
                }
                let before = src[..start].trim_end().as_bytes().last().copied();
                if &src[start..i] == "param" && before != Some(b'.') {
                    if let Some(call) = parse_call(src, i) {
                        calls.push(call);
                    }
                }
            }
            _ => i += 1,
        }
    }
    calls
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// The index after the string literal starting at `i`.
fn skip_string(b: &[u8], i: usize) -> Option<usize> {
    let quote = b[i];
    let mut j = i + 1;
    while j < b.len() {
        if b[j] == b'\\' && quote != b'`' {
            j += 2;
            continue;
        }
        if b[j] == quote {
            return Some(j + 1);
        }
        j += 1;
    }
    None
}

fn skip_ws(b: &[u8], mut i: usize) -> usize {
    while i < b.len() && b[i].is_ascii_whitespace() {
        i += 1;
    }
    i
}

/// After `param`: `( "name" , <number>` with the number's span when it is a literal.
fn parse_call(src: &str, after: usize) -> Option<ParamCall> {
    let b = src.as_bytes();
    let mut i = skip_ws(b, after);
    if b.get(i) != Some(&b'(') {
        return None;
    }
    i = skip_ws(b, i + 1);
    if b.get(i) != Some(&b'"') {
        return None;
    }
    let end = skip_string(b, i)?;
    let name = src[i + 1..end - 1].to_string();
    i = skip_ws(b, end);
    if b.get(i) != Some(&b',') {
        return None;
    }
    i = skip_ws(b, i + 1);
    let start = i;
    if b.get(i) == Some(&b'-') {
        i += 1;
    }
    let digits = |i: &mut usize| {
        let s = *i;
        while *i < b.len() && (b[*i].is_ascii_digit() || b[*i] == b'_') {
            *i += 1;
        }
        *i > s
    };
    let mut any = digits(&mut i);
    if b.get(i) == Some(&b'.') {
        i += 1;
        any |= digits(&mut i);
    }
    if any && matches!(b.get(i), Some(b'e' | b'E')) {
        let mut j = i + 1;
        if matches!(b.get(j), Some(b'+' | b'-')) {
            j += 1;
        }
        if digits(&mut j) {
            i = j;
        }
    }
    // The literal must end the argument: `0.5 * k` is an expression, not a literal.
    let next = skip_ws(b, i);
    let literal = any && matches!(b.get(next), Some(b',') | Some(b')'));
    Some(ParamCall {
        name,
        value: literal.then_some((start, i)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_written_into_their_literals_only() {
        let src = "// param(\"depth\", 9.0, 0, 10) in a comment\nlet d = param(\"depth\", 0.595, 0.4, 0.9);\nlet s = \"param(\\\"depth\\\", 1, 0, 2)\";\nlet h = param( \"height\" ,-1e-1, -1, 1 );\nlet k = param(\"k\", 2 * 0.5, 0, 2);\n";
        let mut v = BTreeMap::new();
        v.insert("depth".to_string(), 0.7);
        v.insert("height".to_string(), 0.25);
        let out = set_param_values(src, &v).expect("write");
        assert!(
            out.contains("let d = param(\"depth\", 0.7, 0.4, 0.9);"),
            "{out}"
        );
        assert!(out.contains("param( \"height\" ,0.25, -1, 1 )"), "{out}");
        assert!(out.starts_with("// param(\"depth\", 9.0, 0, 10)"), "{out}");
        assert!(out.contains("\"param(\\\"depth\\\", 1, 0, 2)\""), "{out}");
        let mut k = BTreeMap::new();
        k.insert("k".to_string(), 1.0);
        let e = set_param_values(src, &k).expect_err("expression");
        assert!(e.contains("not a number literal"), "{e}");
        let mut none = BTreeMap::new();
        none.insert("width".to_string(), 1.0);
        assert!(set_param_values(src, &none)
            .expect_err("missing")
            .contains("width"));
    }

    #[test]
    fn formatted_values_stay_float_literals() {
        assert_eq!(format_param_value(1.0), "1.0");
        assert_eq!(format_param_value(0.5950004), "0.595");
        assert_eq!(format_param_value(-0.25), "-0.25");
        assert_eq!(format_param_value(-0.0000001), "0.0");
        assert_eq!(format_param_value(0.123456789), "0.123457");
    }
}
