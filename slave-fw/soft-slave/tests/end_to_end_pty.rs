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
use can_io::trace::{detect, read_trace, Direction, ReadOptions, TraceFormat};
use common::{require_socat, PtyRig};
use pty_rig::{bin, scratch, Proc, PtyPair};
use rstest::rstest;

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

/// Issue 33: `--log x.asc` without `--format` wrote candump text into the `.asc` file. On the
/// real SLCAN path, `dnet-soft-slave --log slave.EXT` and `dnet-master --log master.EXT` (no
/// `--format`) both write the format the extension names: detected as that format from the
/// content, read back frame for frame, and (trc, asc) each program's own frames marked `Tx`, the
/// other's `Rx`.
#[rstest]
#[case::asc("asc", TraceFormat::Asc)]
#[case::trc("trc", TraceFormat::Trc)]
#[case::csv("csv", TraceFormat::Csv)]
#[ignore = "needs socat: run by scripts/check"]
fn both_logs_are_written_in_the_format_their_extension_names(#[case] ext: &str, #[case] format: TraceFormat) {
    if !require_socat() {
        return;
    }
    let dir = scratch(&format!("log-{ext}"));
    let serial = PtyPair::new();
    let instrument = Proc::spawn(bin("dnet-sim-breaker"), &["--serial", &serial.a, "--period", "0.3"]);
    let can = PtyPair::new();
    let (slave_log, master_log) = (dir.join(format!("slave.{ext}")), dir.join(format!("master.{ext}")));
    let bus = format!("slcan:{}", can.a);
    let mut slave = Proc::spawn(
        bin("dnet-soft-slave"),
        &["--bus", &bus, "--serial", &serial.b, "--log", slave_log.to_str().unwrap()],
    );
    let end = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while !slave.stderr.text().contains("started on") && std::time::Instant::now() < end {
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let master_bus = format!("slcan:{}", can.b);
    let args = [
        "dnet-master",
        "--bus",
        &master_bus,
        "--log",
        master_log.to_str().unwrap(),
        "get",
        "5",
        "1",
        "1",
        "7",
    ];
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = master_harness::cli::run(args, &mut out, &mut err, false);
    assert_eq!(
        code,
        0,
        "{}{}\n{}\n{}",
        String::from_utf8_lossy(&out),
        String::from_utf8_lossy(&err),
        slave.dump(),
        instrument.dump()
    );
    assert_eq!(slave.terminate().and_then(|s| s.code()), Some(0), "{}", slave.dump());

    let mut traces = Vec::new();
    for path in [&slave_log, &master_log] {
        let bytes = std::fs::read(path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        assert_eq!(detect(&bytes), Some(format), "{}:\n{text}", path.display());
        let trace = read_trace(path, ReadOptions { strict: true, format: Some(format) })
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
        // The Get_Attribute_Single exchange at least (allocation, request, response, release).
        assert!(trace.entries.len() >= 4, "{}:\n{text}", path.display());
        traces.push(trace.entries);
    }
    if matches!(format, TraceFormat::Asc | TraceFormat::Trc) {
        // What one program sent the other received: the master's Tx frames are Rx in the soft
        // slave's log and the other way round, and each log has both.
        let frames = |entries: &[can_io::log::LogEntry], d: Direction| -> Vec<devicenet::CanFrame> {
            entries.iter().filter(|e| e.direction == Some(d)).map(|e| e.frame).collect()
        };
        let (slave, master) = (&traces[0], &traces[1]);
        for (sent, received, who) in [
            (frames(master, Direction::Tx), frames(slave, Direction::Rx), "the master"),
            (frames(master, Direction::Rx), frames(slave, Direction::Tx), "the soft slave"),
        ] {
            assert!(!sent.is_empty(), "nothing sent by {who}: {traces:#?}");
            for f in &sent {
                assert!(received.contains(f), "{f:?} of {who} missing on the other side: {traces:#?}");
            }
        }
    }
}
