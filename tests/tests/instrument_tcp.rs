//! `dnet-soft-slave --serial tcp:HOST:PORT` the way it is used: the instrument behind a raw TCP
//! serial tunnel. socat plays the device server (`TCP-LISTEN:PORT` to a pty, as a Moxa NPort in
//! TCP server mode joins its TCP port to its serial port), `dnet-sim-breaker` listens on the pty,
//! and `dnet-master monitor` polls the soft slave over SLCAN on a second pty pair. One monitor run
//! sees the data flow, the tunnel killed (the input goes stale after the description's 1.5 s and
//! is cleared, as its policy says, while every poll is still answered), and the tunnel back (the
//! data flows again, the soft slave never restarted).
//!
//! And a Modbus TCP instrument: pymodbus's `ModbusTcpServer` with the soft slave's Modbus profile
//! in `framing = "tcp"` (MBAP), polled the same way: the registers read reach the poll data, the
//! written output reaches the server's datastore (the server prints the write, the scan list reads
//! it back).
//!
//! Needs socat (and for the Modbus test the pymodbus virtual environment, `DNET_PYTHON`) and the built `dnet-soft-slave`, `dnet-sim-breaker` and `dnet-master`: ignored in
//! the plain host-test run, run by `scripts/check` with `-- --ignored`.

use pty_rig::console::free_port;
use pty_rig::pymodbus::{self, Link, GATEWAY_REGISTERS};
use pty_rig::{bin, require_pymodbus, require_socat, scratch, soft_slave, workspace_dir, Proc, PtyPair};
use serde_json::Value;
use slave_fw::serial::StatusByte;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The breaker's currents while closed (dnet-sim-breaker's default load).
const LOAD: [u8; 4] = [120, 118, 121, 3];

/// The description: the breaker with the status assembly (18 data bytes, status, freshness
/// counter), stale after 1500 ms, cleared when stale.
fn description() -> PathBuf {
    workspace_dir().join("slave-fw/soft-slave/tests/descriptions/breaker-with-status.toml")
}

/// Waits up to `timeout` for `what` to hold.
fn wait_for(timeout: Duration, mut what: impl FnMut() -> bool) -> bool {
    let end = Instant::now() + timeout;
    while Instant::now() < end {
        if what() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    what()
}

/// The device server: socat accepting one TCP connection on `port` and joining it to a new pty
/// at `link` (made once the connection is accepted).
fn tunnel(port: u16, link: &Path) -> Proc {
    let listen = format!("TCP-LISTEN:{port},reuseaddr,bind=127.0.0.1");
    let pty = format!("PTY,link={},raw,echo=0", link.display());
    let socat = Proc::spawn("socat", &["-d", "-d", &listen, &pty]);
    assert!(
        wait_for(Duration::from_secs(10), || socat.stderr.text().contains("listening on")),
        "socat does not listen\n{}",
        socat.dump()
    );
    socat
}

/// The simulated breaker on the tunnel's pty, once socat has made it.
fn breaker(link: &Path, log: &Path) -> Proc {
    assert!(wait_for(Duration::from_secs(10), || link.exists()), "socat made no pty at {}", link.display());
    let args =
        ["--serial", link.to_str().unwrap(), "--closed", "--period", "0.2", "--log", log.to_str().unwrap()];
    Proc::spawn(bin("dnet-sim-breaker"), &args)
}

/// Lines of the soft slave's report that contain `needle`.
fn count(slave: &Proc, needle: &str) -> usize {
    slave.stderr.lines().iter().filter(|l| l.contains(needle)).count()
}

/// One monitor sample: bus time (µs) and the 20 input bytes.
fn samples(json: &Value) -> Vec<(u64, Vec<u8>)> {
    let list = json["samples"].as_array().unwrap_or_else(|| panic!("no samples in {json}"));
    list.iter()
        .map(|s| {
            let raw: Vec<u8> = s["raw"]
                .as_array()
                .unwrap()
                .iter()
                .map(|b| u8::try_from(b.as_u64().unwrap()).unwrap())
                .collect();
            assert_eq!(raw.len(), 20, "{s}");
            (s["time_us"].as_u64().unwrap(), raw)
        })
        .collect()
}

fn fresh(raw: &[u8]) -> bool {
    raw[18] & 0x03 == StatusByte::LINK_OK && raw[..4] == LOAD
}

fn stale(raw: &[u8]) -> bool {
    raw[18] & 0x03 == StatusByte::LINK_TIMEOUT
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn the_breaker_through_a_tcp_tunnel_goes_stale_while_it_is_down_and_flows_again() {
    if !require_socat() {
        return;
    }
    let dir = scratch("instrument-tcp-breaker");
    let port = free_port();
    let link = dir.join("instrument");
    let mut socat = tunnel(port, &link);
    let can = PtyPair::new();
    let spec = format!("tcp:127.0.0.1:{port}");
    let mut slave = soft_slave(&can, &spec, &description());
    let connected = format!("instrument {spec}: connected to 127.0.0.1:{port}");
    assert!(wait_for(Duration::from_secs(10), || count(&slave, &connected) == 1), "{}", slave.dump());
    let mut instrument = breaker(&link, &dir.join("breaker-1.log"));

    // One monitor run over the whole story: 10 polls a second for 24 s.
    let master_bus = format!("slcan:{}", can.b);
    let mut monitor = Proc::spawn(
        bin("dnet-master"),
        &["--bus", &master_bus, "--json", "monitor", "--mac", "5", "--epr", "100", "--duration", "24"],
    );
    let started = Instant::now();
    std::thread::sleep(Duration::from_secs(6));

    // The device server goes away (its process killed: the connection and the pty with it).
    socat.terminate();
    instrument.terminate();
    let lost = format!("instrument {spec}: connection lost (");
    assert!(wait_for(Duration::from_secs(5), || count(&slave, &lost) == 1), "{}", slave.dump());
    // Attempts after 0.5 s, 1 s, 2 s are refused: the next waits 4 s; the tunnel is back before it.
    let refused = format!("instrument {spec}: cannot connect (");
    assert!(wait_for(Duration::from_secs(10), || count(&slave, &refused) >= 3), "{}", slave.dump());
    let socat = tunnel(port, &link);
    assert!(wait_for(Duration::from_secs(10), || count(&slave, &connected) == 2), "{}", slave.dump());
    let instrument = breaker(&link, &dir.join("breaker-2.log"));
    let back_at = started.elapsed();
    assert!(
        back_at < Duration::from_secs(20),
        "the tunnel was back only after {back_at:?}: too late to see data"
    );

    let status = monitor.wait(Duration::from_secs(40));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "monitor\n{}", monitor.dump());
    let json: Value = serde_json::from_str(monitor.stdout.text().trim())
        .unwrap_or_else(|e| panic!("monitor's JSON: {e}\n{}", monitor.dump()));
    let samples = samples(&json);

    // Every poll was answered (no gap of a second in the samples), through the whole run.
    for pair in samples.windows(2) {
        let gap = pair[1].0 - pair[0].0;
        assert!(gap < 1_000_000, "{gap} µs without a poll answer at {} µs", pair[0].0);
    }
    // Fresh data, then stale and cleared, then fresh again.
    let first_stale = samples
        .iter()
        .position(|(_, raw)| stale(raw))
        .unwrap_or_else(|| panic!("never stale: {samples:02X?}"));
    let fresh_again = first_stale
        + samples[first_stale..]
            .iter()
            .position(|(_, raw)| fresh(raw))
            .unwrap_or_else(|| panic!("never fresh again after the tunnel came back\n{}", slave.dump()));
    let before = &samples[..first_stale];
    assert!(before.iter().filter(|(_, raw)| fresh(raw)).count() >= 10, "data before the cut: {before:02X?}");
    let down = &samples[first_stale..fresh_again];
    assert!(down.len() >= 20, "stale for {} polls only", down.len());
    for (t, raw) in down {
        assert!(stale(raw), "at {t} µs: {raw:02X?}");
        assert_eq!(&raw[..18], &[0; 18], "the clear policy, at {t} µs");
    }
    let after = &samples[fresh_again..];
    assert!(
        after.iter().filter(|(_, raw)| fresh(raw)).count() >= 10,
        "data after the tunnel came back: {after:02X?}"
    );
    assert!(after.iter().all(|(_, raw)| !stale(raw)), "stale again after the tunnel came back");
    // Stale 1.5 s (the description's stale timeout) after the freshness counter last moved.
    let (mut moved_at, mut counter, mut moves) = (before[0].0, before[0].1[19], 0);
    for (t, raw) in before {
        if raw[19] != counter {
            (moved_at, counter, moves) = (*t, raw[19], moves + 1);
        }
    }
    assert!(moves >= 5, "the freshness counter moved {moves} times only: {before:02X?}");
    let took = down[0].0 - moved_at;
    eprintln!(
        "stale {} ms after the last fresh frame; data again {:?} after the start",
        took / 1000,
        back_at
    );
    assert!(
        (1_400_000..=2_100_000).contains(&took),
        "stale {took} µs after the last fresh frame; configured 1500 ms"
    );

    // The same soft slave throughout: still running, and it stops cleanly.
    assert!(slave.running(), "{}", slave.dump());
    let status = slave.terminate();
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{}", slave.dump());
    let report = slave.stderr.text();
    for line in report.lines().filter(|l| l.contains("instrument")) {
        eprintln!("{line}");
    }
    assert!(report.contains("instrument silent: input image stale"), "{report}");
    assert!(report.contains("instrument link ok"), "{report}");
    drop((socat, instrument));
}

/// The gateway's `[profile.modbus]` table: Modbus TCP (MBAP).
const MODBUS_TCP: &str = r#"framing = "tcp"
response_timeout_ms = 200
retries = 1
poll_period_ms = 50
"#;

#[test]
#[ignore = "needs socat, pymodbus and the built programs: run by scripts/check"]
fn a_modbus_tcp_instrument_fills_the_poll_data_and_takes_the_written_output() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("instrument-tcp-modbus");
    let port = free_port();
    let server = pymodbus::server(&python, Link::Tcp(port), &GATEWAY_REGISTERS);
    let config = dir.join("modbus-tcp-gateway.toml");
    std::fs::write(&config, pymodbus::gateway_description(MODBUS_TCP)).unwrap();
    let can = PtyPair::new();
    let spec = format!("tcp:127.0.0.1:{port}");
    let mut slave = soft_slave(&can, &spec, &config);
    assert!(server.wait_stdout("connected", Duration::from_secs(10)).is_some(), "{}", slave.dump());

    // Output bytes 11 22 33 44: holding registers 16..17 = 0x2211, 0x4433 (little-endian image).
    let last = pymodbus::last_poll(&format!("slcan:{}", can.b), "11223344", &[&slave, &server]);
    assert_eq!(last.len(), 18, "{last:02X?}");
    assert_eq!(&last[..8], &[0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07], "input registers 0..3");
    assert_eq!(&last[8..12], &[0xCD, 0xAB, 0x34, 0x12], "holding registers 100..101");
    assert_eq!(
        &last[12..16],
        &[0x11, 0x22, 0x33, 0x44],
        "holding registers 16..17 read back after the write"
    );
    assert_eq!(last[16] & 0x0F, StatusByte::LINK_OK, "link ok, no errors: {:#04X}", last[16]);
    let write = "write unit=1 function=16 address=16 values=0x2211,0x4433";
    assert!(
        server.wait_stdout(write, Duration::from_secs(2)).is_some(),
        "the server saw {write}\n{}",
        server.dump()
    );

    let report = pymodbus::stop(&mut slave);
    assert!(report.contains(&format!("Modbus TCP profile on {spec}")), "{report}");
    assert!(report.contains(&format!("instrument {spec}: connected to 127.0.0.1:{port}")), "{report}");
    assert!(report.contains("0 checksum and 0 framing errors, 0 timeouts"), "{report}");
}
