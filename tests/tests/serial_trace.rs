//! `dnet-master serial-trace` the way it is used: the soft slave between `dnet-sim-breaker` (or
//! pymodbus, `tests/modbus/server.py`) on one socat pty pair and SLCAN on a second, the master at
//! the far end. The trace read over the bus shows the instrument's frames decoded by the profile;
//! `--follow` sees frames sent after it started, and Ctrl-C (SIGINT) keeps what was printed.
//!
//! Needs socat, the built `dnet-soft-slave`, `dnet-sim-breaker` and `dnet-master` (and pymodbus
//! for the Modbus test): ignored in the plain host-test run, run by `scripts/check` with
//! `-- --ignored`.

use pty_rig::{bin, require_pymodbus, require_socat, workspace_dir, Proc, PtyRig};
use serde_json::Value;
use std::time::Duration;

/// `dnet-master --bus BUS --json serial-trace --mac 5 ARGS`, run to its end: its JSON.
fn trace_json(rig: &PtyRig, args: &[&str]) -> Value {
    let bus = rig.master_bus_arg();
    let mut all = vec!["--bus", bus.as_str(), "--json", "serial-trace", "--mac", "5"];
    all.extend_from_slice(args);
    let mut master = Proc::spawn(bin("dnet-master"), &all);
    let status = master.wait(Duration::from_secs(60));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "serial-trace\n{}\n{}", master.dump(), rig.dump());
    serde_json::from_str(master.stdout.text().trim())
        .unwrap_or_else(|e| panic!("serial-trace's JSON: {e}\n{}", master.dump()))
}

/// The printed lines of a JSON result: (sequence number, kind, hex, decoded).
fn lines(json: &Value) -> Vec<(u64, String, String, String)> {
    let list = json["lines"].as_array().unwrap_or_else(|| panic!("no lines in {json}"));
    list.iter()
        .map(|l| {
            let s = |k: &str| l[k].as_str().unwrap_or_else(|| panic!("{k} in {l}")).to_string();
            (l["seq"].as_u64().unwrap(), s("kind"), s("hex"), s("decoded"))
        })
        .collect()
}

/// The status frame dnet-sim-breaker sends while closed with its default load (120, 118, 121, 3).
const CLOSED_STATUS: &str = "status: currents 120 118 121 3, switch Closed";

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn breaker_frames_are_read_decoded_and_followed() {
    if !require_socat() {
        return;
    }
    let mut rig = PtyRig::breaker("serial-trace-breaker", &["--closed", "--period", "0.2"], None);
    std::thread::sleep(Duration::from_secs(2));

    // One read: the status frames the breaker sent, decoded, each its 22 bytes on the wire.
    let json = trace_json(&rig, &[]);
    assert_eq!(json["profile"], "breaker (framed serial)", "{json}");
    let read = lines(&json);
    let statuses: Vec<_> =
        read.iter().filter(|(_, kind, _, decoded)| kind == "rx" && decoded == CLOSED_STATUS).collect();
    assert!(statuses.len() >= 3, "status frames read: {read:?}\n{}", rig.dump());
    for (_, _, hex, _) in &statuses {
        assert!(
            hex.starts_with("68 12 78 76 79 03") && hex.ends_with(" 16") && hex.len() == 22 * 3 - 1,
            "{hex}"
        );
    }
    let last_seq = read.iter().map(|l| l.0).max().unwrap();

    // --follow for 3 s: frames recorded after the first read, in order.
    let json = trace_json(&rig, &["--follow", "--duration", "3", "--interval", "100"]);
    let followed = lines(&json);
    let new: Vec<_> = followed.iter().filter(|l| l.0 > last_seq && l.3 == CLOSED_STATUS).collect();
    // 5 frames a second: at least 10 new ones in 3 s (of which some may have been overwritten
    // before the follow started reading: those are counted as missed, not shown).
    assert!(new.len() >= 10, "{} new status frames while following: {followed:?}", new.len());
    assert!(followed.windows(2).all(|w| w[0].0 < w[1].0), "sequence numbers in order: {followed:?}");

    // --follow in text until SIGINT: what was printed stays, the exit status is 130.
    let bus = rig.master_bus_arg();
    let mut master =
        Proc::spawn(bin("dnet-master"), &["--bus", &bus, "serial-trace", "--mac", "5", "--follow"]);
    let seen = master.wait_stdout(CLOSED_STATUS, Duration::from_secs(20));
    assert!(seen.is_some(), "no status frame printed\n{}", master.dump());
    std::thread::sleep(Duration::from_secs(1));
    master.signal("INT");
    let status = master.wait(Duration::from_secs(20));
    assert_eq!(status.and_then(|s| s.code()), Some(130), "{}", master.dump());
    let printed = master.stdout.text();
    assert!(printed.matches(CLOSED_STATUS).count() >= 3, "{printed}");
    assert!(master.stderr.text().contains("interrupted by SIGINT"), "{}", master.dump());
    rig.stop_slave();
}

#[test]
#[ignore = "needs socat and pymodbus: run by scripts/check"]
fn modbus_requests_and_responses_are_decoded() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let config = workspace_dir().join("slave-fw/soft-slave/tests/descriptions/modbus-gateway.toml");
    let mut rig = PtyRig::modbus("serial-trace-modbus", &python, &config);
    std::thread::sleep(Duration::from_secs(2));
    let json = trace_json(&rig, &[]);
    assert_eq!(json["profile"], "Modbus RTU", "{json}");
    let read = lines(&json);
    let has = |kind: &str, decoded: &str| read.iter().any(|l| l.1 == kind && l.3 == decoded);
    // The scan list of modbus-gateway.toml and the server's registers (tests/modbus/server.py).
    assert!(has("tx", "request unit 1: 0x04 read input registers 0 count 4"), "{read:?}\n{}", rig.dump());
    assert!(has("rx", "response unit 1: 0x04 registers 0102 0304 0506 0708"), "{read:?}");
    assert!(has("tx", "request unit 1: 0x03 read holding registers 100 count 2"), "{read:?}");
    assert!(has("rx", "response unit 1: 0x03 registers ABCD 1234"), "{read:?}");
    assert!(read.iter().all(|l| !l.3.starts_with("not a")), "every frame decoded: {read:?}");
    rig.stop_slave();
}
