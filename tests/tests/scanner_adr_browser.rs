//! The console's events panel in a real browser: Debian's `chromium` driven by `playwright-core`
//! (`tests/browser/scanner_adr.test.mjs`) against `dnet-master --bus sim --slave-mac 5,6
//! --sim-replace 5@10000 --realtime ui --adr`: the replacement of MAC 5 step by step, as
//! `GET /api/events` gives it.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check`'s scanner-adr stage after `cargo build -p
//! master-harness` and `npm ci --prefix tests/browser`. A missing chromium, node or
//! `node_modules` is a failure, never a skip. The screenshot goes to `$UI_ARTIFACTS_DIR/scanner-adr/`
//! (default: a scratch folder).

use std::path::Path;
use std::process::Command;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check's scanner-adr stage"]
fn events_panel_in_chromium() {
    let browser = Path::new(env!("CARGO_MANIFEST_DIR")).join("browser");
    assert!(browser.join("node_modules/playwright-core").is_dir(), "npm ci --prefix tests/browser");
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    assert!(Path::new(&chromium).exists(), "{chromium} is missing: apt-get install chromium");
    let out = std::env::var_os("UI_ARTIFACTS_DIR")
        .map_or_else(|| pty_rig::scratch("scanner-adr-browser"), |d| Path::new(&d).join("scanner-adr"));
    std::fs::create_dir_all(&out).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let addr = format!("127.0.0.1:{port}");
    let mut ui = pty_rig::Proc::spawn(
        pty_rig::bin("dnet-master"),
        &[
            "--bus",
            "sim",
            "--slave-mac",
            "5,6",
            "--sim-replace",
            "5@10000",
            "--realtime",
            "ui",
            "--no-history",
            "--listen",
            &addr,
            "--adr",
        ],
    );
    let end = std::time::Instant::now() + std::time::Duration::from_secs(30);
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(std::time::Instant::now() < end, "the console did not start\n{}", ui.dump());
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let result = Command::new("node")
        .arg("scanner_adr.test.mjs")
        .current_dir(&browser)
        .env("CONSOLE_URL", format!("http://{addr}/"))
        .env("ARTIFACTS_DIR", &out)
        .env("CHROMIUM", &chromium)
        .output()
        .expect("node runs (install Node.js)");
    let text =
        format!("{}{}", String::from_utf8_lossy(&result.stdout), String::from_utf8_lossy(&result.stderr));
    println!("{text}");
    ui.terminate();
    assert!(result.status.success(), "the browser test failed:\n{text}\n{}", ui.dump());
    assert_eq!(text.matches("ok   ").count(), 2, "two steps passed:\n{text}");
    assert!(out.join("console-events.png").is_file(), "no screenshot");
}
