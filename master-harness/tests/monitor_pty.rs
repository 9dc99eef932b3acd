//! `dnet-master monitor` as a process on the real SLCAN path: `dnet-sim-breaker` on one socat pty
//! pair, `dnet-soft-slave` between it and a second pair that carries SLCAN, the master at the far
//! end (`pty_rig::PtyRig`). Ctrl-C and SIGTERM keep what was recorded (CSV rows, the candump log,
//! the JSON summary with the samples) and give the device back; a breaker gone silent is shown
//! stale through the status assembly.
//!
//! Needs socat: ignored in the plain host-test run, run by `scripts/check`; skips with a message
//! without socat, fails in CI. Build the instrument and the soft slave first:
//! `cargo build -p soft-slave && cargo test -p master-harness --test monitor_pty -- --ignored`.

use pty_rig::{require_socat, workspace_dir, Proc, PtyRig};
use std::path::{Path, PathBuf};
use std::time::Duration;

fn dnet_master(args: &[&str]) -> Proc {
    Proc::spawn(env!("CARGO_BIN_EXE_dnet-master"), args)
}

/// Waits up to `timeout` until `csv` holds a header and `rows` rows.
fn await_rows(csv: &Path, rows: usize, timeout: Duration) -> bool {
    let end = std::time::Instant::now() + timeout;
    while std::time::Instant::now() < end {
        let lines = std::fs::read_to_string(csv).map(|t| t.lines().count()).unwrap_or(0);
        if lines > rows {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

/// `monitor --json --csv --log --epr EPR` on the rig, stopped by `signal` once three rows are on
/// disk: exit 128 + the signal, one JSON document with the samples and the interruption, the CSV
/// and the log kept, the connections released, no frame check failed; the JSON document.
fn interrupted_monitor(rig: &PtyRig, signal: &str, name: &str, epr: &str) -> serde_json::Value {
    let csv = rig.dir.join(format!("{name}.csv"));
    let log = rig.dir.join(format!("{name}.log"));
    let bus = rig.master_bus_arg();
    let (csv_arg, log_arg) = (csv.to_str().unwrap(), log.to_str().unwrap());
    let mut master = dnet_master(&[
        "--bus", &bus, "--json", "--log", log_arg, "monitor", "--mac", "5", "--epr", epr, "--csv", csv_arg,
    ]);
    // The rows are flushed as they are taken: a reader tailing the file sees them during the run.
    assert!(await_rows(&csv, 3, Duration::from_secs(30)), "no CSV rows\n{}\n{}", master.dump(), rig.dump());
    master.signal(signal);
    let status = master.wait(Duration::from_secs(10)).expect("monitor ends on the signal");
    let expected = if signal == "INT" { 130 } else { 143 };
    assert_eq!(status.code(), Some(expected), "{}\n{}", master.dump(), rig.dump());

    let out = master.stdout.text();
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: one JSON document\n{out}"));
    assert_eq!(v["interrupted"], format!("SIG{signal}"), "{v}");
    assert_eq!(v["ok"], false);
    let samples = v["samples"].as_array().unwrap();
    assert!(samples.len() >= 3, "{v}");
    // No description on a real bus: raw bytes, the reference breaker's 18.
    assert!(samples.iter().all(|s| s["raw"].as_array().unwrap().len() == 18 && s["link"].is_null()), "{v}");

    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows[0], "time_s,status,freshness,stale,raw");
    assert_eq!(rows.len(), samples.len() + 1, "a row for every sample\n{text}");
    assert!(rows[1..].iter().all(|r| r.ends_with(",,,,0000000000000000000F0000000000000000")), "{text}");

    let logged = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<&str> = logged.lines().collect();
    assert!(lines.len() > 20, "{logged}");
    assert!(lines.iter().all(|l| l.starts_with('(') && l.contains('#')), "candump -L lines:\n{logged}");
    // The connections were given back through the explicit connection before the exit.
    assert!(logged.contains("#004C03"), "no Release in the log:\n{logged}");
    assert_eq!(v["error"], format!("interrupted by SIG{signal}"), "{v}");
    // The data was fine: the answer to the poll the signal cut short, arriving during the Release,
    // is recorded as not judged, not as the device's fault (issue 33, item 1).
    let frames = v["frames"].as_array().unwrap();
    let failed: Vec<&serde_json::Value> = frames.iter().filter(|f| f["verdict"] == "fail").collect();
    assert!(failed.is_empty(), "no frame check fails after SIG{signal}: {failed:#?}");
    assert_eq!(v["failures"], 0, "{v}");
    let released = v["frames"].as_array().unwrap().iter().any(|f| {
        f["meaning"].as_str().unwrap().contains("Release_Master/Slave_Connection_Set response: success")
    });
    assert!(released, "{v}");
    v
}

/// The frames recorded as not judged in a JSON summary.
fn not_judged(v: &serde_json::Value) -> Vec<&serde_json::Value> {
    let frames = v["frames"].as_array().unwrap();
    frames.iter().filter(|f| f["note"].as_str().is_some_and(|n| n.starts_with("not judged: "))).collect()
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn ctrl_c_and_sigterm_keep_the_csv_the_log_and_the_samples_and_release_the_device() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("monitor-signal", &["--period", "0.3"], None);
    interrupted_monitor(&rig, "INT", "int", "300");
    interrupted_monitor(&rig, "TERM", "term", "300");
    // An EPR shorter than the session's stop check (50 ms): the wait for the next poll is one
    // slice, so the stop is seen once the poll is out, and its answer comes during the Release.
    // Recorded as not judged, not as an unexpected frame (issue 33, item 1).
    let v = interrupted_monitor(&rig, "INT", "in-flight", "20");
    let unjudged = not_judged(&v);
    assert!(!unjudged.is_empty() && unjudged.iter().all(|f| f["id"] == "3C5"), "{unjudged:#?}");
    assert!(unjudged.iter().all(|f| f["note"].as_str().unwrap().contains("wound down (stopped by SIGINT)")));
    // The device was released: another master run brings it up again.
    let bus = rig.master_bus_arg();
    let mut connect = dnet_master(&["--bus", &bus, "connect", "--mac", "5", "--epr", "300"]);
    let status = connect.wait(Duration::from_secs(30)).expect("connect ends");
    assert_eq!(status.code(), Some(0), "{}\n{}", connect.dump(), rig.dump());
    assert!(connect.stdout.text().contains("every check holds"), "{}", connect.dump());
}

/// A monitor stopped during its bring-up, before its first sample, still leaves its CSV file with
/// the header (issue 33, item 7), and exits 130.
#[test]
#[ignore = "needs socat: run by scripts/check"]
fn a_monitor_stopped_before_its_first_sample_leaves_the_csv_header() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("monitor-early-stop", &["--period", "0.3"], None);
    let csv = rig.dir.join("early.csv");
    let bus = rig.master_bus_arg();
    let mut master = dnet_master(&["--bus", &bus, "monitor", "--mac", "5", "--csv", csv.to_str().unwrap()]);
    // The CSV file is created once the bus is open, before the bring-up (the master's network
    // access alone takes 2 s): stopped now, the run has no sample.
    let end = std::time::Instant::now() + Duration::from_secs(20);
    while !csv.exists() {
        assert!(std::time::Instant::now() < end, "no CSV file\n{}", master.dump());
        std::thread::sleep(Duration::from_millis(5));
    }
    master.signal("INT");
    let status = master.wait(Duration::from_secs(10)).expect("monitor ends on the signal");
    assert_eq!(status.code(), Some(130), "{}\n{}", master.dump(), rig.dump());
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "time_s,status,freshness,stale,raw\n");
}

fn description(name: &str) -> PathBuf {
    workspace_dir().join("slave-fw/soft-slave/tests/descriptions").join(name)
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn a_silent_breaker_is_shown_stale_with_the_status_assembly() {
    if !require_socat() {
        return;
    }
    // Assembly 101, stale after 1.5 s, policy clear; the breaker stops sending 6 s after its start.
    let config = description("breaker-with-status.toml");
    let rig = PtyRig::breaker(
        "monitor-stale",
        &["--closed", "--period", "0.2", "--silent-after", "6"],
        Some(&config),
    );
    let csv = rig.dir.join("stale.csv");
    let bus = rig.master_bus_arg();
    let mut master = dnet_master(&[
        "--bus",
        &bus,
        "monitor",
        "--mac",
        "5",
        "--epr",
        "300",
        "--duration",
        "10",
        "--csv",
        csv.to_str().unwrap(),
        "--description",
        config.to_str().unwrap(),
    ]);
    let status = master.wait(Duration::from_secs(40)).expect("monitor ends after its duration");
    assert_eq!(status.code(), Some(0), "{}\n{}", master.dump(), rig.dump());
    let out = master.stdout.text();
    let samples: Vec<&str> = out.lines().filter(|l| l.contains("switch")).collect();
    assert!(samples.len() > 20, "{out}");
    let first_stale = samples.iter().position(|l| l.contains("| STALE: LINK TIMEOUT")).unwrap_or_else(|| {
        panic!("never shown stale:\n{out}\n{}", rig.dump());
    });
    assert!(first_stale > 0, "{out}");
    assert!(
        samples[..first_stale]
            .iter()
            .all(|l| l.contains("A 120 A  B 118 A  C 121 A  N   3 A  switch closed  | link ok,")),
        "{out}"
    );
    assert!(samples[first_stale..].iter().all(|l| l.contains("| STALE: LINK TIMEOUT")), "{out}");
    // Policy clear: the stale image is zeros.
    assert!(samples.last().unwrap().contains("A   0 A  B   0 A  C   0 A  N   0 A"), "{out}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows[0], "time_s,phase_a,phase_b,phase_c,neutral,switch,status,freshness,stale,raw");
    assert_eq!(rows.len(), samples.len() + 1, "{text}");
    assert!(rows[1].contains(",120,118,121,3,closed,0x01,") && rows[1].contains(",0,"), "{text}");
    let last: Vec<&str> = rows.last().unwrap().split(',').collect();
    assert_eq!((last[6], last[8]), ("0x02", "1"), "{text}");
}
