//! Headless Chromium for the report's browser checks, shared by this crate's tests and the
//! binary's (`crates/agentstar/tests/report.rs` includes this file by path): finding it,
//! running it on a page with a time limit, and reading what the viewer wrote on `<body>`.
#![allow(dead_code)]

use std::path::Path;

/// A headless Chromium, where one is installed (`.ci/run` installs Debian's `chromium` and
/// sets `AGENTSTAR_REQUIRE_CHROMIUM=1`, which turns its absence into a failure).
pub fn chromium() -> Option<String> {
    let found = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            std::process::Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .map(str::to_string);
    if found.is_none() {
        assert!(
            std::env::var_os("AGENTSTAR_REQUIRE_CHROMIUM").is_none(),
            "AGENTSTAR_REQUIRE_CHROMIUM is set but no chromium is installed"
        );
        eprintln!("chromium not installed (apt install chromium): the browser check is skipped");
    }
    found
}

/// Runs headless Chromium on a page with a time limit; returns stdout (through a file: the
/// DOM dump is larger than a pipe holds).
pub fn run_chromium(bin: &str, extra: &[&str], page: &Path) -> String {
    let stdout_path = page.with_extension("stdout");
    let stdout = std::fs::File::create(&stdout_path).expect("stdout file");
    let mut child = std::process::Command::new(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-extensions",
            "--no-first-run",
            "--virtual-time-budget=15000",
            "--window-size=1300,1400",
        ])
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .stdout(stdout)
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start chromium");
    let start = std::time::Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed().as_secs() > 120 {
            let _ = child.kill();
            panic!("chromium did not finish in 120 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    String::from_utf8_lossy(&std::fs::read(&stdout_path).expect("stdout")).into_owned()
}

/// The value of attribute `name` on the DOM's `<body>`.
pub fn body_attr(dom: &str, name: &str) -> Option<String> {
    let body = &dom[dom.find("<body")?..];
    let body = &body[..body.find('>')?];
    let key = format!("{name}=\"");
    let at = body.find(&key)? + key.len();
    Some(body[at..at + body[at..].find('"')?].to_string())
}

/// The page's DOM after Chromium ran its scripts, asserting that the viewer started
/// (`data-viewer="ready"`) with no script error (`data-errors="0"`); a failure shows the
/// viewer's error text.
pub fn viewer_dom(bin: &str, page: &Path) -> String {
    let dom = run_chromium(bin, &["--dump-dom"], page);
    assert_eq!(
        body_attr(&dom, "data-viewer").as_deref(),
        Some("ready"),
        "{:?}",
        body_attr(&dom, "data-error-text")
    );
    assert_eq!(
        body_attr(&dom, "data-errors").as_deref(),
        Some("0"),
        "{:?}",
        body_attr(&dom, "data-error-text")
    );
    dom
}

/// The pixel count the viewer wrote in `<body>`'s attribute `view` (`data-cam-pixels`,
/// `data-orbit-pixels`).
pub fn view_pixels(dom: &str, view: &str) -> u64 {
    body_attr(dom, view)
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {view} on <body>"))
}
