//! `dnet-master serial-trace` on a Modbus ASCII and a Modbus TCP line, the way it is used:
//! pymodbus (the independent implementation, `pty_rig::pymodbus`) serves unit 1 with its ASCII
//! framer on a socat pty pair, or as a Modbus TCP server on loopback; `dnet-soft-slave` is the
//! gateway in `framing = "ascii"` / `"tcp"`; the master reads the trace over SLCAN on a second pty
//! pair. The framing is read from the settings object (class 0x65 attribute 12), and every frame
//! the gateway exchanged is decoded: the requests of its scan list and pymodbus's answers.
//!
//! Needs socat, pymodbus (`DNET_PYTHON`) and the built `dnet-soft-slave` and `dnet-master`:
//! ignored in the plain host-test run, run by `scripts/check` with `-- --ignored`.

use pty_rig::console::free_port;
use pty_rig::pymodbus::{self, Link, GATEWAY_REGISTERS};
use pty_rig::{bin, require_pymodbus, require_socat, scratch, soft_slave, Proc, PtyPair};
use serde_json::Value;
use std::time::Duration;

/// `dnet-master --bus BUS --json serial-trace --mac 5`: the profile and the lines (kind,
/// decoded).
fn trace(bus: &str, others: &[&Proc]) -> (String, Vec<(String, String)>) {
    let mut master = Proc::spawn(bin("dnet-master"), &["--bus", bus, "--json", "serial-trace", "--mac", "5"]);
    let status = master.wait(Duration::from_secs(30));
    let context = || others.iter().map(|p| p.dump()).collect::<Vec<_>>().join("\n");
    assert_eq!(status.and_then(|s| s.code()), Some(0), "serial-trace\n{}\n{}", master.dump(), context());
    let json: Value = serde_json::from_str(master.stdout.text().trim())
        .unwrap_or_else(|e| panic!("serial-trace's JSON: {e}\n{}", master.dump()));
    let lines = json["lines"].as_array().unwrap_or_else(|| panic!("no lines in {json}"));
    let s = |l: &Value, k: &str| l[k].as_str().unwrap_or_else(|| panic!("{k} in {l}")).to_string();
    (s(&json, "profile"), lines.iter().map(|l| (s(l, "kind"), s(l, "decoded"))).collect())
}

/// The scan list's first entry and pymodbus's answer (GATEWAY_REGISTERS), each at least once,
/// every line decoded; `suffix` is what the framing adds to a decoded frame.
fn assert_decoded(lines: &[(String, String)], suffix: &str) {
    let has = |kind: &str, text: &str| {
        lines
            .iter()
            .any(|(k, d)| k == kind && d.strip_prefix(text).is_some_and(|rest| rest.starts_with(suffix)))
    };
    assert!(has("tx", "request unit 1: 0x04 read input registers 0 count 4"), "{lines:?}");
    assert!(has("rx", "response unit 1: 0x04 registers 0102 0304 0506 0708"), "{lines:?}");
    assert!(has("tx", "request unit 1: 0x03 read holding registers 100 count 2"), "{lines:?}");
    assert!(has("rx", "response unit 1: 0x03 registers ABCD 1234"), "{lines:?}");
    let undecoded: Vec<_> =
        lines.iter().filter(|(k, d)| (k == "tx" || k == "rx") && !d.contains(" unit 1: ")).collect();
    assert!(undecoded.is_empty(), "every frame decoded: {undecoded:?}");
}

#[test]
#[ignore = "needs socat, pymodbus and the built programs: run by scripts/check"]
fn modbus_ascii_frames_are_decoded() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("serial-trace-ascii");
    let serial = PtyPair::new();
    let server = pymodbus::server(&python, Link::Ascii(&serial.a), &GATEWAY_REGISTERS);
    let config = dir.join("gateway.toml");
    let modbus = "framing = \"ascii\"\nresponse_timeout_ms = 300\nretries = 1\npoll_period_ms = 50\n\n\
                  [profile.modbus.serial]\nbaud = 19200\ndata_bits = \"eight\"\nparity = \"none\"\nstop_bits = \"one\"\n";
    std::fs::write(&config, pymodbus::gateway_description(modbus)).unwrap();
    let can = PtyPair::new();
    let mut slave = soft_slave(&can, &serial.b, &config);
    std::thread::sleep(Duration::from_secs(2));
    let (profile, lines) = trace(&format!("slcan:{}", can.b), &[&slave, &server]);
    assert_eq!(profile, "Modbus ASCII");
    assert_decoded(&lines, "");
    pymodbus::stop(&mut slave);
}

#[test]
#[ignore = "needs socat, pymodbus and the built programs: run by scripts/check"]
fn modbus_tcp_frames_are_decoded() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("serial-trace-tcp");
    let port = free_port();
    let server = pymodbus::server(&python, Link::Tcp(port), &GATEWAY_REGISTERS);
    let config = dir.join("gateway.toml");
    let modbus = "framing = \"tcp\"\nresponse_timeout_ms = 200\nretries = 1\npoll_period_ms = 50\n";
    std::fs::write(&config, pymodbus::gateway_description(modbus)).unwrap();
    let can = PtyPair::new();
    let mut slave = soft_slave(&can, &format!("tcp:127.0.0.1:{port}"), &config);
    assert!(server.wait_stdout("connected", Duration::from_secs(10)).is_some(), "{}", slave.dump());
    std::thread::sleep(Duration::from_secs(1));
    let (profile, lines) = trace(&format!("slcan:{}", can.b), &[&slave, &server]);
    assert_eq!(profile, "Modbus TCP");
    assert_decoded(&lines, " (transaction ");
    pymodbus::stop(&mut slave);
}
