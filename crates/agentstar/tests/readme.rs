//! The README tells the truth: the table it shows for `agentstar demo` is the table the
//! command prints (the same rows, to the digits shown). The demo is seeded, so its table is
//! the same on every run and every machine.

mod support;

use std::path::PathBuf;
use support::{agentstar, text};

/// The rows of the first markdown table that starts with `| metric | value |` in `s`.
fn metric_table(s: &str) -> Vec<String> {
    let mut rows = Vec::new();
    let mut inside = false;
    for line in s.lines() {
        let line = line.trim();
        if !inside {
            inside = line == "| metric | value |";
            if inside {
                rows.push(line.to_string());
            }
            continue;
        }
        if !line.starts_with('|') {
            break;
        }
        rows.push(line.to_string());
    }
    rows
}

#[test]
fn the_readmes_demo_table_is_what_the_demo_prints() {
    let readme =
        std::fs::read_to_string(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../README.md"))
            .expect("README.md");
    let shown = metric_table(&readme);
    assert!(
        shown.len() > 5,
        "the README shows no demo table (a `| metric | value |` table): {shown:?}"
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("demo");
    let o = agentstar(&["demo", out.to_str().expect("utf8")]);
    assert!(o.status.success(), "{}", text(&o));
    let printed = metric_table(&String::from_utf8_lossy(&o.stdout));
    assert_eq!(
        shown,
        printed,
        "the README's demo table differs from what `agentstar demo` prints; README:\n{}\nprinted:\n{}",
        shown.join("\n"),
        printed.join("\n")
    );
}

#[test]
fn the_table_reader_takes_the_rows_up_to_the_first_line_that_is_not_a_row() {
    let s = "text\n| metric | value |\n|---|---|\n| frames | 10 |\n\n| other | 1 |\n";
    assert_eq!(
        metric_table(s),
        ["| metric | value |", "|---|---|", "| frames | 10 |"]
    );
}
