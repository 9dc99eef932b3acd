//! The console's health panel in a real browser: Debian's `chromium` driven by `playwright-core`
//! (`tests/browser/health.test.mjs`) against `dnet-master --bus sim --slave-mac 5,6 --realtime ui`:
//! the controller's state and counters, a row per node with response times, the same score and
//! findings as `GET /api/health`, the CSV download, Clear.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check`'s health stage after `cargo build -p
//! master-harness` and `npm ci --prefix tests/browser`. A missing chromium, node or
//! `node_modules` is a failure, never a skip. The screenshot and the CSV go to
//! `$UI_ARTIFACTS_DIR/health/` (default: a scratch folder).

use std::path::Path;
use std::process::Command;

#[test]
#[ignore = "needs chromium, node and playwright-core: run by scripts/check's health stage"]
fn health_panel_in_chromium() {
    let browser = Path::new(env!("CARGO_MANIFEST_DIR")).join("browser");
    assert!(browser.join("node_modules/playwright-core").is_dir(), "npm ci --prefix tests/browser");
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    assert!(Path::new(&chromium).exists(), "{chromium} is missing: apt-get install chromium");
    let out = std::env::var_os("UI_ARTIFACTS_DIR")
        .map_or_else(|| pty_rig::scratch("health-browser"), |d| Path::new(&d).join("health"));
    std::fs::create_dir_all(&out).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let addr = format!("127.0.0.1:{port}");
    let history = out.join("h.sqlite");
    let mut ui = pty_rig::Proc::spawn(
        pty_rig::bin("dnet-master"),
        &[
            "--bus",
            "sim",
            "--slave-mac",
            "5,6",
            "--realtime",
            "ui",
            "--listen",
            &addr,
            "--history",
            history.to_str().unwrap(),
        ],
    );
    let end = std::time::Instant::now() + std::time::Duration::from_secs(20);
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(std::time::Instant::now() < end, "the console did not start\n{}", ui.dump());
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let result = Command::new("node")
        .arg("health.test.mjs")
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
    assert!(
        text.matches("\nok   ").count() + usize::from(text.starts_with("ok   ")) == 4,
        "four steps passed:\n{text}"
    );
    assert!(out.join("console-health.png").is_file(), "no screenshot");
}
