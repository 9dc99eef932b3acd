//! The console's health panel in a real browser: Debian's `chromium` driven by `playwright-core`
//! (`tests/browser/health.test.mjs`) against `dnet-master --bus sim --slave-mac 5,6 --realtime ui`:
//! the controller's state and counters, a row per node with response times, the same score and
//! findings as `GET /api/health`, the CSV download, Clear.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check`'s health stage after `cargo build -p
//! master-harness` and `npm ci --prefix tests/browser`. A missing chromium, node or
//! `node_modules` is a failure, never a skip. The screenshot and the CSV go to
//! `$UI_ARTIFACTS_DIR/health/` (default: a scratch folder).

use pty_rig::browser::{artifacts, Browser};
use pty_rig::console::spawn_ui;
use std::time::Duration;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check's health stage"]
fn health_panel_in_chromium() {
    let browser = Browser::require();
    let out = artifacts("health", "health-browser");
    let history = out.join("h.sqlite");
    let (mut ui, addr) = spawn_ui(
        &["--bus", "sim", "--slave-mac", "5,6", "--realtime"],
        &["--history", history.to_str().unwrap()],
        Duration::from_secs(20),
        String::new,
    );
    let run = browser.run("health.test.mjs", &format!("http://{addr}/"), &out);
    ui.terminate();
    assert!(run.success, "the browser test failed:\n{}\n{}", run.text, ui.dump());
    assert_eq!(run.steps_passed(), 4, "four steps passed:\n{}", run.text);
    assert!(out.join("console-health.png").is_file(), "no screenshot");
}
