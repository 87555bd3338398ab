//! `ARCHITECTURE.md` against the workspace as cargo sees it: the Boundaries table of our
//! crates' dependencies is the rule, so a new dependency between our crates (or a removed
//! one) fails here until the document says so; and the code map names every crate.

use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::process::Command;

fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// Our crates and their normal (not dev, not build) dependencies on our crates.
fn cargo_graph() -> BTreeMap<String, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(workspace_root())
        .output()
        .expect("run cargo metadata");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: Value = serde_json::from_slice(&out.stdout).expect("metadata JSON");
    let packages = meta["packages"].as_array().expect("packages");
    let ours: BTreeSet<String> = packages
        .iter()
        .map(|p| p["name"].as_str().expect("name").to_string())
        .collect();
    packages
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .expect("dependencies")
                .iter()
                .filter(|d| d["kind"].is_null())
                .filter_map(|d| d["name"].as_str())
                .filter(|n| ours.contains(*n))
                .map(str::to_string)
                .collect();
            (p["name"].as_str().expect("name").to_string(), deps)
        })
        .collect()
}

fn architecture() -> String {
    std::fs::read_to_string(workspace_root().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md")
}

/// The text of `## title` up to the next `## ` heading.
fn section<'a>(doc: &'a str, title: &str) -> &'a str {
    let start = doc
        .find(&format!("\n## {title}\n"))
        .unwrap_or_else(|| panic!("ARCHITECTURE.md has no `## {title}` section"));
    let body = &doc[start + title.len() + 5..];
    &body[..body.find("\n## ").unwrap_or(body.len())]
}

/// The crate names in backticks in a table cell (`—` for none).
fn crates_in(cell: &str) -> BTreeSet<String> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .filter(|n| n.starts_with("agentstar"))
        .map(str::to_string)
        .collect()
}

/// The Boundaries table: `| `crate` | deps |` rows.
fn documented_graph(doc: &str) -> BTreeMap<String, BTreeSet<String>> {
    let mut graph = BTreeMap::new();
    for line in section(doc, "Boundaries").lines() {
        let cells: Vec<&str> = line.trim().split('|').map(str::trim).collect();
        // "", crate, deps, ""
        if cells.len() != 4 || !cells[1].starts_with("`agentstar") {
            continue;
        }
        let name = cells[1].trim_matches('`').to_string();
        let previous = graph.insert(name.clone(), crates_in(cells[2]));
        assert!(previous.is_none(), "`{name}` is listed twice in Boundaries");
    }
    graph
}

#[test]
fn the_boundaries_table_is_the_dependency_graph() {
    let real = cargo_graph();
    let documented = documented_graph(&architecture());
    assert!(
        real.len() >= 15,
        "cargo metadata lists {} crates",
        real.len()
    );
    let mut problems = Vec::new();
    for (name, deps) in &real {
        match documented.get(name) {
            None => problems.push(format!("`{name}` is not in the Boundaries table")),
            Some(doc) if doc != deps => {
                let extra: Vec<_> = deps.difference(doc).collect();
                let missing: Vec<_> = doc.difference(deps).collect();
                problems.push(format!(
                    "`{name}`: depends on {extra:?} not in the table; the table lists {missing:?} it does not depend on"
                ));
            }
            Some(_) => {}
        }
    }
    for name in documented.keys() {
        if !real.contains_key(name) {
            problems.push(format!(
                "the Boundaries table lists `{name}`, which is not a workspace crate"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "ARCHITECTURE.md vs cargo metadata:\n{}",
        problems.join("\n")
    );
}

#[test]
fn the_code_map_names_every_crate_once() {
    let doc = architecture();
    let map = section(&doc, "Code map");
    let mut named = BTreeMap::<String, usize>::new();
    for line in map.lines() {
        if let Some(rest) = line.strip_prefix("| `") {
            if let Some(end) = rest.find('`') {
                *named.entry(rest[..end].to_string()).or_default() += 1;
            }
        }
    }
    for name in cargo_graph().keys() {
        assert_eq!(
            named.get(name).copied(),
            Some(1),
            "the code map should have one row for `{name}`"
        );
    }
}

#[test]
fn the_document_parser_reads_what_it_is_given() {
    let doc = "x\n## Boundaries\n| crate | deps |\n|---|---|\n| `agentstar-a` | `agentstar-b`, `agentstar-c` |\n| `agentstar-b` | — |\n## Next\n| `agentstar-z` | `agentstar-a` |\n";
    let g = documented_graph(doc);
    assert_eq!(g.len(), 2);
    assert_eq!(
        g["agentstar-a"],
        BTreeSet::from(["agentstar-b".to_string(), "agentstar-c".to_string()])
    );
    assert!(g["agentstar-b"].is_empty());
}

/// The binary's source files under `src/cmd/` that name `agentstar_agent`, as paths relative
/// to `src/` (`cmd/agent.rs`).
fn command_files_using_the_agent() -> BTreeSet<String> {
    let src = workspace_root().join("crates/agentstar/src");
    let mut found = BTreeSet::new();
    let mut stack = vec![src.join("cmd")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("read cmd dir") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs")
                && std::fs::read_to_string(&path)
                    .expect("read source")
                    .contains("agentstar_agent")
            {
                let rel = path.strip_prefix(&src).expect("under src");
                found.insert(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    found
}

/// The command files the Boundaries section says may use the agent crate: the backticked
/// `cmd/…` paths on its line that starts "Command files that use `agentstar-agent`".
fn documented_agent_commands(doc: &str) -> BTreeSet<String> {
    let line = section(doc, "Boundaries")
        .lines()
        .find(|l| {
            l.trim_start()
                .starts_with("- Command files that use `agentstar-agent`")
        })
        .expect("Boundaries names the command files that use `agentstar-agent`");
    line.split('`')
        .skip(1)
        .step_by(2)
        .filter(|n| n.starts_with("cmd/"))
        .map(str::to_string)
        .collect()
}

/// Only the commands that drive a model link the agent harness: a command that reads a
/// report, a run directory or a ledger takes it from `agentstar-reports` or `agentstar-data`.
#[test]
fn only_the_documented_commands_use_the_agent_crate() {
    let documented = documented_agent_commands(&architecture());
    assert!(
        documented.len() <= 3,
        "at most three command files may use the agent crate; the document lists {documented:?}"
    );
    let real = command_files_using_the_agent();
    assert!(!real.is_empty(), "no command file names agentstar_agent");
    assert_eq!(
        real, documented,
        "command files naming `agentstar_agent` (left) vs ARCHITECTURE.md's Boundaries (right)"
    );
}
