//! The independent numpy implementations in `scripts/crosscheck_*.py`, run from the tests
//! of this crate and of `agentstar-bench` (`crates/agentstar-bench/tests/bench.rs` includes
//! this file by path).
#![allow(dead_code)]

use agentstar_geom::pose::ObjectPose;
use std::io::Write;

/// Whether `python3` with numpy runs here; where it does not, says that the cross-check is
/// skipped (CI machines need not have numpy).
pub fn has_numpy() -> bool {
    let found = std::process::Command::new("python3")
        .args(["-c", "import numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        eprintln!("python3 with numpy not found: the numpy cross-check did not run");
    }
    found
}

/// Runs `scripts/SCRIPT` with `input` as JSON on its stdin; its stdout as JSON, asserting
/// that it succeeded (the failure shows its stderr).
pub fn crosscheck(script: &str, input: &serde_json::Value) -> serde_json::Value {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scripts")
        .join(script);
    let mut child = std::process::Command::new("python3")
        .arg(path)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("python3");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.to_string().as_bytes())
        .expect("write");
    let out = child.wait_with_output().expect("run");
    assert!(
        out.status.success(),
        "{script}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{script}: {e}"))
}

/// A pose as the scripts read it: `[qw, qx, qy, qz, tx, ty, tz]`.
pub fn pose_row(p: &ObjectPose) -> Vec<f64> {
    let q = p.quaternion_wxyz();
    vec![
        q[0],
        q[1],
        q[2],
        q[3],
        p.translation.x,
        p.translation.y,
        p.translation.z,
    ]
}
