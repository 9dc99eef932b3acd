//! `configure` and `params` on the real SLCAN path: the `dnet-master` program against
//! `dnet-soft-slave --state FILE` (with `dnet-sim-breaker` on a second pty pair), as an integrator
//! configures an adapter in the field: download a description, see the device come back running
//! it, restart the soft slave (the board's power cycle) and find the configuration still in force,
//! read it back as an equivalent description, read and set parameters, and get the spec's errors
//! for bad values without any change.
//!
//! Needs socat and the soft slave's binaries: ignored in the plain host-test run, run by the
//! `scripts/check` stage "dnet-master on the real SLCAN path".

use pty_rig::{require_socat, workspace_dir, Proc, PtyRig};
use slave_fw::description::DeviceDescription;
use std::path::PathBuf;
use std::time::Duration;

fn dnet(rig: &PtyRig, args: &[&str]) -> (i32, String, String) {
    let bus = rig.master_bus_arg();
    let mut all = vec!["--bus", bus.as_str()];
    all.extend_from_slice(args);
    let mut p = Proc::spawn(env!("CARGO_BIN_EXE_dnet-master"), &all);
    let status =
        p.wait(Duration::from_secs(90)).unwrap_or_else(|| panic!("dnet-master {args:?} hangs\n{}", p.dump()));
    (status.code().unwrap_or(-1), p.stdout.text(), p.stderr.text())
}

fn ok(rig: &PtyRig, args: &[&str]) -> String {
    let (code, out, err) = dnet(rig, args);
    assert_eq!(code, 0, "dnet-master {args:?}\n{out}\n{err}\n{}", rig.dump());
    out
}

/// A breaker of another make: its own product code and name, the status assembly (20 bytes
/// produced), a 5 s stale timeout, a serial number of its own (which no device takes: each keeps
/// its own); 9600 8N1 like the simulated breaker on the pty.
fn other_breaker(dir: &std::path::Path) -> PathBuf {
    let text = std::fs::read_to_string(workspace_dir().join("slave-fw/descriptions/breaker.toml"))
        .unwrap()
        .replace("product_code = 1", "product_code = 42")
        .replace("product_name = \"Serial-DeviceNet Bridge\"", "product_name = \"Breaker Gateway B\"")
        .replace("input_assembly = \"plain\"", "input_assembly = \"with_status\"")
        .replace("produced_size = 18", "produced_size = 20")
        .replace("stale_timeout_ms = 3000", "stale_timeout_ms = 5000")
        .replace("serial_number = 0x12345678", "serial_number = 0x00C0FFEE");
    for needle in [
        "serial_number = 0x00C0FFEE",
        "product_code = 42",
        "Breaker Gateway B",
        "with_status",
        "produced_size = 20",
        "stale_timeout_ms = 5000",
    ] {
        assert!(text.contains(needle), "the reference description changed: {needle}");
    }
    let path = dir.join("breaker-b.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn configure_survives_a_restart_reads_back_and_parameters_are_checked() {
    if !require_socat() {
        return;
    }
    let mut rig = PtyRig::breaker("configure", &["--period", "0.3"], None);
    rig.stop_slave();
    let state = rig.dir.join("state.json");
    let state_arg = state.to_str().unwrap().to_string();
    rig.start_slave_with(None, &["--state", &state_arg]);
    let description = other_breaker(&rig.dir);

    // Download: checked, verified, reset, back on-line, identity and sizes as described.
    let out = ok(&rig, &["configure", "--mac", "5", description.to_str().unwrap()]);
    assert!(out.contains("read back and verified"), "{out}");
    assert!(out.contains("the device runs the description"), "{out}");
    assert!(line_of(&out, "poll produced size").ends_with(" 20 bytes"), "{out}");
    // The soft slave's serial number (its start-up description's), not the downloaded one's;
    // values as `decode` writes them, no byte lists.
    assert!(line_of(&out, "Identity serial number").ends_with(" 0x12345678"), "{out}");
    assert!(line_of(&out, "configuration CRC-32").contains(" 0x"), "{out}");
    assert!(!out.contains('['), "{out}");
    assert!(std::fs::read_to_string(&state).unwrap().contains("\"configuration\""), "the image is kept");

    // The board's power cycle: the soft slave restarts with the same state file.
    rig.stop_slave();
    rig.start_slave_with(None, &["--state", &state_arg]);
    let read_back = rig.dir.join("read.toml");
    let out = ok(&rig, &["configure", "--mac", "5", "--read", read_back.to_str().unwrap()]);
    assert!(out.contains("written to"), "{out}");
    let got = DeviceDescription::load(&read_back).unwrap();
    let want = DeviceDescription::load(&description).unwrap();
    assert_eq!(got.converter, want.converter, "configure --read gives back the description");
    let out = ok(&rig, &["get", "5", "1", "1", "6"]);
    assert!(out.contains("0x12345678"), "the device's own serial number after the restart: {out}");
    let text = std::fs::read_to_string(&read_back).unwrap();
    assert!(
        text.contains("# identity.serial_number is the image's: the device keeps its own, 0x12345678."),
        "{text}"
    );

    // Parameters: read, set in range (stored, applies at reset), refused out of range, no change.
    let out = ok(&rig, &["params", "--mac", "5"]);
    assert!(out.contains("parameter(s)"), "{out}");
    assert!(out.to_lowercase().contains("stale timeout"), "{out}");
    let (code, _, err) = dnet(&rig, &["params", "--mac", "5", "--set", "Stale timeout=0"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("invalid attribute value (0x09)"), "{err}");
    let out = ok(&rig, &["params", "--mac", "5"]);
    assert!(out.contains("5000"), "nothing changed: {out}");
}

/// The line of `out` that reports `what`.
fn line_of<'a>(out: &'a str, what: &str) -> &'a str {
    out.lines().find(|l| l.contains(what)).unwrap_or_else(|| panic!("no {what} line in\n{out}"))
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn a_soft_slave_keeps_the_serial_number_of_its_state_file_and_hears_of_another_data_rate() {
    if !require_socat() {
        return;
    }
    let mut rig = PtyRig::breaker("configure-serial", &["--period", "0.3"], None);
    rig.stop_slave();
    let state = rig.dir.join("state.json");
    std::fs::write(&state, "{ \"serial_number\": 3735928559 }\n").unwrap();
    let state_arg = state.to_str().unwrap().to_string();
    rig.start_slave_with(None, &["--state", &state_arg]);
    // Another breaker at 500 kbit/s: the master says so before the reset (the soft slave keeps
    // the rate it started with until its next start, so it comes back on this bus).
    let text = std::fs::read_to_string(other_breaker(&rig.dir))
        .unwrap()
        .replace("baud_rate = \"250k\"", "baud_rate = \"500k\"");
    assert!(text.contains("baud_rate = \"500k\""), "the reference description changed: baud_rate");
    let description = rig.dir.join("breaker-500k.toml");
    std::fs::write(&description, text).unwrap();
    let out = ok(&rig, &["configure", "--mac", "5", description.to_str().unwrap()]);
    let note = out
        .find("note: the description's data rate is 500 kbit/s, MAC 5 runs at 250 kbit/s")
        .unwrap_or_else(|| panic!("{out}"));
    assert!(note < out.find("; reset;").unwrap(), "said before the reset: {out}");
    assert!(line_of(&out, "Identity serial number").ends_with(" 0xDEADBEEF"), "{out}");
    // Identity attribute 6 answers it too.
    let out = ok(&rig, &["get", "5", "1", "1", "6"]);
    assert!(out.contains("0xDEADBEEF"), "{out}");
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn a_download_while_polled_is_refused_and_the_device_keeps_working() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("configure-polled", &["--period", "0.3"], None);
    let description = other_breaker(&rig.dir);
    // A connect that keeps the poll connection (EPR 10 s: the watchdog leaves room), then the
    // same master downloads: its own poll connection is established, so the device refuses.
    ok(&rig, &["--keep", "connect", "--mac", "5", "--epr", "10000"]);
    let (code, out, err) = dnet(&rig, &["--keep", "configure", "--mac", "5", description.to_str().unwrap()]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(err.contains("device state conflict (0x10)"), "{err}");
    // Still the reference device, still answering.
    let out = ok(&rig, &["get", "5", "1", "1", "3"]);
    assert!(out.contains("(product code): 0x0001 (1)"), "{out}");
}
