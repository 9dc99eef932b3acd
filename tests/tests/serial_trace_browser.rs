//! The console's Serial line panel in a real browser, on the real SLCAN path: `dnet-sim-breaker`
//! and the soft slave on socat pty pairs (`pty_rig`), `dnet-master --bus slcan:PTY ui` at the far
//! end, and Debian's `chromium` driven by `playwright-core` (`tests/browser/serial-trace.test.mjs`):
//! the panel opened for the converter shows the breaker's status frames decoded, a Close given in
//! the page shows up as the command frame, its acknowledgement and the closed switch, and the
//! panel agrees with `GET /api/node/5/serial-trace`.
//!
//! Ignored by a plain `cargo test`; run by `scripts/check`'s browser stage after the programs are
//! built and `npm ci --prefix tests/browser`. A missing socat, chromium, node or `node_modules` is a
//! failure, never a skip. The screenshot goes to `$UI_ARTIFACTS_DIR/serial-trace/` (default: a
//! scratch folder).

use pty_rig::browser::{artifacts, Browser};
use pty_rig::console::{spawn_ui, stop_ui};
use pty_rig::{require_socat, PtyRig};
use std::time::Duration;

#[test]
#[ignore = "needs socat, chromium, node and playwright-core: run by scripts/check's browser stage"]
fn serial_line_panel_in_chromium() {
    assert!(require_socat(), "socat is needed");
    let browser = Browser::require();
    let out = artifacts("serial-trace", "serial-trace-browser");
    // A status frame every 0.3 s, the switch open.
    let mut rig = PtyRig::breaker("serial-trace-browser", &["--period", "0.3"], None);
    let list = rig.dir.join("list.toml");
    std::fs::write(&list, "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n").unwrap();
    let bus = rig.master_bus_arg();
    let (mut ui, addr) = spawn_ui(
        &["--bus", &bus],
        &["--no-history", "--scanlist", list.to_str().unwrap()],
        Duration::from_secs(20),
        || rig.dump(),
    );
    let run = browser.run("serial-trace.test.mjs", &format!("http://{addr}/#/node/5"), &out);
    stop_ui(&mut ui, Duration::from_secs(10), &rig.dump());
    assert!(run.success, "the browser test failed:\n{}\n{}\n{}", run.text, ui.dump(), rig.dump());
    assert_eq!(run.steps_passed(), 3, "three steps passed:\n{}", run.text);
    assert!(out.join("console-serial-line.png").is_file(), "no screenshot");
    // The breaker itself saw the Close the page gave.
    assert!(rig.wait_breaker_log("command close", Duration::from_secs(2)), "{}", rig.dump());
    rig.stop_slave();
}
