//! `dnet-master ui` on the real SLCAN path: the program against `dnet-soft-slave` on SLCAN over a
//! socat pty pair, with `dnet-sim-breaker` as its instrument, driven through the console's JSON API
//! as the page drives it: node 5 comes into I/O with the breaker's product name, a Close through
//! the output image closes the breaker and the phase currents rise, the history exports its
//! samples as CSV, a recording of the frames decodes, and SIGINT releases the device (exit 130).
//!
//! Needs socat and the soft slave's binaries (`cargo build -p soft-slave`): ignored in the plain
//! host-test run, run by `scripts/check`; skips with a message without socat.

use pty_rig::{console, require_socat, Proc, PtyRig};
use std::time::{Duration, Instant};

/// One request as the console's page sends it; a state-changing one carries the page's CSRF token
/// (pty_rig::console). The status and the body.
fn http(addr: &str, method: &str, path: &str, body: &str) -> (u16, String) {
    if method == "GET" {
        return console::get(addr, path);
    }
    console::http(addr, method, path, Some(&console::csrf_token(addr)), body)
}

fn json(addr: &str, path: &str) -> serde_json::Value {
    let (status, body) = http(addr, "GET", path, "");
    assert_eq!(status, 200, "{path}: {body}");
    serde_json::from_str(&body).unwrap_or_else(|e| panic!("{path}: {e}: {body}"))
}

/// Polls `f` until it gives `Some`, for at most `limit`.
fn until<T>(limit: Duration, what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(start.elapsed() < limit, "{what}: not within {limit:?}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn the_console_drives_the_soft_slave_over_slcan() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("ui", &["--period", "0.3"], None);
    let dir = pty_rig::scratch("ui-pty");
    let bus = rig.master_bus_arg();
    let history = dir.join("history.sqlite");
    let args = [
        "--bus",
        bus.as_str(),
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--record-dir",
        dir.to_str().unwrap(),
    ];
    let mut p = Proc::spawn(env!("CARGO_BIN_EXE_dnet-master"), &args);
    let addr = console::console_addr(&p, Duration::from_secs(30));

    // Node 5 in I/O, identified.
    let node = until(Duration::from_secs(60), "node 5 ok", || {
        let state = json(&addr, "/api/state");
        state["nodes"].as_array()?.iter().find(|n| n["mac"] == 5 && n["status"] == "ok").cloned()
    });
    assert_eq!(node["identity"]["product_name"], "Serial-DeviceNet Bridge", "{node}");
    assert_eq!((node["input_size"].as_u64(), node["output_size"].as_u64()), (Some(18), Some(8)));

    // A recording of the frames while the breaker is closed through the output image.
    let (status, body) = http(&addr, "POST", "/api/record/start", "");
    assert_eq!(status, 200, "{body}");
    let recording: serde_json::Value = serde_json::from_str(&body).unwrap();
    let log = recording["log"].as_str().unwrap_or_else(|| panic!("{recording}")).to_string();
    let (status, body) = http(&addr, "POST", "/api/node/5/breaker/close", "");
    assert_eq!(status, 200, "{body}");
    let closed = until(Duration::from_secs(10), "the switch closed and the currents up", || {
        let n = json(&addr, "/api/node/5");
        let fields = n["fields"].as_array()?.clone();
        let value = |name: &str| fields.iter().find(|f| f["name"] == name).map(|f| f["text"].to_string());
        let switch = value("switch")?;
        let phase_a = fields.iter().find(|f| f["name"] == "phase_a")?["values"][0].as_f64()?;
        (switch.contains("closed") && phase_a > 0.0).then_some(n)
    });
    let (status, body) = http(&addr, "POST", "/api/record/stop", "");
    assert_eq!(status, 200, "{body}");
    assert!(closed["output_hex"].as_str().unwrap_or("").starts_with("02"), "{closed}");
    assert!(rig.breaker_log().to_lowercase().contains("close"), "{}", rig.breaker_log());

    // The history has the samples; the recording decodes.
    let (status, csv) = http(&addr, "GET", "/api/export.csv?mac=5", "");
    assert_eq!(status, 200, "{csv}");
    assert!(csv.starts_with("unix_ms,time,mac,input_hex,phase_a"), "{csv}");
    assert!(csv.lines().count() >= 3, "{csv}");
    // The switch as the page shows it, not its byte (0xF0 = 240).
    assert!(csv.lines().last().unwrap_or("").ends_with(",closed"), "{csv}");
    let decoded = std::process::Command::new(env!("CARGO_BIN_EXE_dnet-master"))
        .args(["decode", &log])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&decoded.stdout);
    assert!(decoded.status.success(), "{text}{}", String::from_utf8_lossy(&decoded.stderr));
    assert!(text.contains("poll command to MAC 5: 8 bytes 02"), "the close is in the recording: {text}");

    // SIGINT: the device released, exit 130, the table printed.
    p.signal("INT");
    let status =
        p.wait(Duration::from_secs(20)).unwrap_or_else(|| panic!("ui hangs after SIGINT\n{}", p.dump()));
    assert_eq!(status.code(), Some(130), "{}", p.dump());
    assert!(p.stderr.text().contains("interrupted by SIGINT: every node released"), "{}", p.dump());
    assert!(p.stdout.text().contains("Serial-DeviceNet Bridge"), "{}", p.dump());
}
