//! Every part real: `dnet-master monitor` (its command line, run in-process through
//! `master_harness::cli::run`) over SLCAN on a pty pair, `dnet-soft-slave` as a process, and
//! `dnet-sim-breaker` as a process on a second pty pair. A close command, then (after the soft
//! slave is stopped with SIGTERM and started again, as on a bench) an open command through the
//! poll output: the monitored switch state follows each, and the breaker hears each once.
//!
//! Needs socat: ignored in the plain host-test run, run by the `scripts/check` stage "serial
//! bridge on ptys (socat, pymodbus)"; skips with a message without socat, fails in CI.

mod common;

use can_io::log::read_log;
use common::{require_socat, PtyRig};

/// `dnet-master --bus slcan:PTY monitor --output HEX --epr 300 --count 10 --csv FILE --description
/// breaker.toml`; returns the CSV rows. (EPR 300 ms: the poll response timeout is the EPR, and a
/// loaded CI machine can take longer than 100 ms to pass a frame through two ptys and a process.)
fn monitor(rig: &PtyRig, output: &str, name: &str) -> Vec<String> {
    let csv = rig.dir.join(format!("{name}.csv"));
    let bus = format!("slcan:{}", rig.can.b);
    let args = ["dnet-master", "--bus", &bus, "monitor", "--output", output, "--epr", "300", "--count", "10"];
    let mut args: Vec<&str> = args.to_vec();
    // On a real bus monitor decodes only what a description tells it: the built-in device's.
    args.extend_from_slice(&[
        "--description",
        concat!(env!("CARGO_MANIFEST_DIR"), "/../descriptions/breaker.toml"),
    ]);
    args.extend_from_slice(&["--csv", csv.to_str().unwrap()]);
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = master_harness::cli::run(args, &mut out, &mut err, false);
    let out = String::from_utf8_lossy(&out);
    assert_eq!(
        code,
        0,
        "dnet-master monitor --output {output}\n{out}\n{}\n{}",
        String::from_utf8_lossy(&err),
        rig.dump()
    );
    assert!(out.contains("10 samples"), "{out}");
    std::fs::read_to_string(&csv).unwrap().lines().skip(1).map(str::to_string).collect()
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn dnet_master_monitor_shows_the_breaker_follow_close_then_open() {
    if !require_socat() {
        return;
    }
    let mut rig = PtyRig::breaker("monitor", &["--period", "0.3"], None);
    // Close (command 2, sequence 1): the breaker starts open and closes with its load.
    let rows = monitor(&rig, "0201", "close");
    assert!(rows[0].contains(",0,0,0,0,open,"), "{rows:#?}");
    assert!(rows[9].contains(",120,118,121,3,closed,"), "{rows:#?}");
    let report = rig.stop_slave();
    assert!(report.contains("commands 1 sent"), "{report}");
    let log = read_log(&rig.dir.join("can.log")).unwrap();
    assert!(log.iter().any(|e| e.frame.id().as_raw() == 0x42D && e.frame.data().starts_with(&[2, 1])));

    // The breaker keeps its state while the soft slave restarts; open (command 1, sequence 2).
    rig.start_slave(None);
    let rows = monitor(&rig, "0102", "open");
    assert!(rows[0].contains(",closed,"), "{rows:#?}");
    assert!(rows[9].contains(",0,0,0,0,open,"), "{rows:#?}");
    rig.stop_slave();

    let breaker_log = rig.breaker_log();
    let commands: Vec<&str> =
        breaker_log.lines().filter_map(|l| l.split_once(" command ").map(|(_, c)| c)).collect();
    assert_eq!(commands, ["close", "open"], "{breaker_log}");
}
