//! The console's events panel in a real browser: Debian's `chromium` driven by `playwright-core`
//! (`tests/browser/scanner_adr.test.mjs`) against `dnet-master --bus sim --slave-mac 5,6
//! --sim-replace 5@10000 --realtime ui --adr`: the replacement of MAC 5 step by step, as
//! `GET /api/events` gives it.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check`'s scanner-adr stage after `cargo build -p
//! master-harness` and `npm ci --prefix tests/browser`. A missing chromium, node or
//! `node_modules` is a failure, never a skip. The screenshot goes to `$UI_ARTIFACTS_DIR/scanner-adr/`
//! (default: a scratch folder).

use pty_rig::browser::{artifacts, Browser};
use pty_rig::console::spawn_ui;
use std::time::Duration;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check's scanner-adr stage"]
fn events_panel_in_chromium() {
    let browser = Browser::require();
    let out = artifacts("scanner-adr", "scanner-adr-browser");
    let (mut ui, addr) = spawn_ui(
        &["--bus", "sim", "--slave-mac", "5,6", "--sim-replace", "5@10000", "--realtime"],
        &["--no-history", "--adr"],
        Duration::from_secs(30),
        String::new,
    );
    let run = browser.run("scanner_adr.test.mjs", &format!("http://{addr}/"), &out);
    ui.terminate();
    assert!(run.success, "the browser test failed:\n{}\n{}", run.text, ui.dump());
    assert_eq!(run.steps_passed(), 2, "two steps passed:\n{}", run.text);
    assert!(out.join("console-events.png").is_file(), "no screenshot");
}
