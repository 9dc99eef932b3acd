//! The console in a real browser: Debian's `chromium` driven by `playwright-core`
//! (`tests/browser/console.test.mjs`): MAC 5 and MAC 6 with their product names (MAC 5 with its
//! scan-list name), distinct y-axis labels on the plot, Close on MAC 5's
//! breaker and the switch closed with the currents rising within two seconds, the CSV export with
//! the samples, a recording; a screenshot of each view.
//!
//! Both tests are ignored by a plain `cargo test` and run by `scripts/check`
//! (`cargo test -p master-harness --test ui_browser -- --ignored`), after
//! Debian's `chromium`, a Node.js with npm (from any source), and `npm ci --prefix tests/browser`:
//! `./scripts/check` installs each that is missing.
//! A missing chromium, node or `node_modules` is a failure, never a skip. Screenshots and the
//! CSV go to `$UI_ARTIFACTS_DIR/<test>/` (`program`, `stand-in`; default: a scratch folder,
//! `pty_rig::browser::artifacts`).
//!
//! - `console_in_chromium`: the real program, `dnet-master --bus sim --slave-mac 5,6 ui --listen
//!   127.0.0.1:0 --scanlist DIR/list.toml --history DIR/history.sqlite --record-dir DIR` (the list
//!   names MAC 5 `feeder 1`), found at the URL it prints
//!   (`console at http://127.0.0.1:PORT/`).
//! - `console_in_chromium_on_a_stand_in_scanner`: the same page over the stand-in scanner of
//!   `ui_support` in this process (the page's test while the scanner engine is being written).

mod ui_support;

use pty_rig::browser::{artifacts, Browser};
use pty_rig::console::console_url;
use pty_rig::Proc;
use std::path::Path;
use std::time::Duration;

/// Runs `console.test.mjs` against `url` (pty_rig::browser); panics with its output when a step
/// fails or a view has no screenshot.
fn run_script(url: &str, out: &Path) {
    let run = Browser::require().run("console.test.mjs", url, out);
    assert!(run.success, "the browser test failed:\n{}", run.text);
    for view in ["network", "device", "trace"] {
        assert!(out.join(format!("console-{view}.png")).is_file(), "no screenshot of the {view} view");
    }
}

#[test]
#[ignore = "needs chromium: run by scripts/check"]
fn console_in_chromium() {
    let out = artifacts("program", "ui-browser-program");
    let dir = out.join("run");
    std::fs::create_dir_all(&dir).unwrap();
    // The scan list names MAC 5 only (the page shows the name; MAC 6 its product name alone).
    let list = dir.join("list.toml");
    std::fs::write(
        &list,
        "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\nname = \"feeder 1\"\n\n[[node]]\nmac = 6\ninput_size = 18\noutput_size = 8\n",
    )
    .unwrap();
    let history = dir.join("history.sqlite");
    let args = [
        "--bus",
        "sim",
        "--slave-mac",
        "5,6",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--scanlist",
        list.to_str().unwrap(),
        "--history",
        history.to_str().unwrap(),
        "--record-dir",
        dir.to_str().unwrap(),
    ];
    let program = Proc::spawn(env!("CARGO_BIN_EXE_dnet-master"), &args);
    let url = console_url(&program, Duration::from_secs(30));
    run_script(&url, &out);
    drop(program);
}

#[test]
#[ignore = "needs chromium: run by scripts/check"]
fn console_in_chromium_on_a_stand_in_scanner() {
    let out = artifacts("stand-in", "ui-browser-stand-in");
    // The record directory exists, as `ui --record-dir` requires.
    let run = out.join("run");
    std::fs::create_dir_all(&run).unwrap();
    let scanner = ui_support::FakeScanner::start(&run, true);
    let server = dnet_scanner::ui::serve("127.0.0.1:0", scanner.shared.clone()).unwrap();
    run_script(&server.url(), &out);
    server.stop();
}
