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
//! CSV go to `$UI_ARTIFACTS_DIR/<test>/` (default: cargo's test tmpdir).
//!
//! - `console_in_chromium`: the real program, `dnet-master --bus sim --slave-mac 5,6 ui --listen
//!   127.0.0.1:0 --scanlist DIR/list.toml --history DIR/history.sqlite --record-dir DIR` (the list
//!   names MAC 5 `feeder 1`), found at the URL it prints
//!   (`console at http://127.0.0.1:PORT/`).
//! - `console_in_chromium_on_a_stand_in_scanner`: the same page over the stand-in scanner of
//!   `ui_support` in this process (the page's test while the scanner engine is being written).

mod ui_support;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

fn browser_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/browser")
}

fn artifacts(test: &str) -> PathBuf {
    let base = std::env::var_os("UI_ARTIFACTS_DIR")
        .map_or_else(|| Path::new(env!("CARGO_TARGET_TMPDIR")).join("browser-artifacts"), PathBuf::from);
    let dir = base.join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn chromium() -> PathBuf {
    let path = std::env::var_os("CHROMIUM").map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    assert!(path.exists(), "{} is missing: apt-get install chromium", path.display());
    path
}

/// Fails (never skips) when node or playwright-core is missing.
fn check_tools() {
    let node = Command::new("node").arg("--version").output();
    assert!(
        node.is_ok_and(|o| o.status.success()),
        "node is missing: install Node.js (Debian: apt-get install nodejs)"
    );
    assert!(
        browser_dir().join("node_modules/playwright-core").is_dir(),
        "playwright-core is missing: npm ci --prefix tests/browser"
    );
}

/// Runs the browser script against `url`; panics with its output when a step fails.
fn run_script(url: &str, out: &Path) {
    check_tools();
    let result = Command::new("node")
        .arg("console.test.mjs")
        .current_dir(browser_dir())
        .env("CONSOLE_URL", url)
        .env("ARTIFACTS_DIR", out)
        .env("CHROMIUM", chromium())
        .output()
        .expect("node runs");
    let text =
        format!("{}{}", String::from_utf8_lossy(&result.stdout), String::from_utf8_lossy(&result.stderr));
    println!("{text}");
    assert!(result.status.success(), "the browser test failed:\n{text}");
    for view in ["network", "device", "trace"] {
        assert!(out.join(format!("console-{view}.png")).is_file(), "no screenshot of the {view} view");
    }
}

/// The program, killed when the test ends.
struct Program(Child);

impl Drop for Program {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
#[ignore = "needs chromium: run by scripts/check"]
fn console_in_chromium() {
    let out = artifacts("program");
    let dir = out.join("run");
    std::fs::create_dir_all(&dir).unwrap();
    // The scan list names MAC 5 only (the page shows the name; MAC 6 its product name alone).
    let list = dir.join("list.toml");
    std::fs::write(
        &list,
        "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\nname = \"feeder 1\"\n\n[[node]]\nmac = 6\ninput_size = 18\noutput_size = 8\n",
    )
    .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_dnet-master"))
        .args(["--bus", "sim", "--slave-mac", "5,6", "ui", "--listen", "127.0.0.1:0", "--scanlist"])
        .arg(&list)
        .arg("--history")
        .arg(dir.join("history.sqlite"))
        .arg("--record-dir")
        .arg(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("dnet-master starts");
    let stdout = child.stdout.take().unwrap();
    let program = Program(child);
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            println!("dnet-master: {line}");
            if let Some(url) = line.split("console at ").nth(1) {
                let _ = tx.send(url.trim().to_string());
            }
        }
    });
    let mut program = program;
    let url = match rx.recv_timeout(Duration::from_secs(30)) {
        Ok(url) => url,
        Err(e) => {
            let mut status = None;
            for _ in 0..40 {
                status = program.0.try_wait().ok().flatten();
                if status.is_some() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            panic!("dnet-master did not print `console at http://...` ({e}); it ended with {status:?}")
        }
    };
    run_script(&url, &out);
    drop(program);
}

#[test]
#[ignore = "needs chromium: run by scripts/check"]
fn console_in_chromium_on_a_stand_in_scanner() {
    let out = artifacts("stand-in");
    // The record directory exists, as `ui --record-dir` requires.
    let run = out.join("run");
    std::fs::create_dir_all(&run).unwrap();
    let scanner = ui_support::FakeScanner::start(&run, true);
    let server = dnet_scanner::ui::serve("127.0.0.1:0", scanner.shared.clone()).unwrap();
    run_script(&server.url(), &out);
    server.stop();
}
