//! The text trace formats (trc, asc, csv) against python-can, the independent tool: fixtures it
//! wrote from `bring-up.log` read back as the log's frames, foreign lines skipped and named, no
//! panic on any prefix or random text, our writers read back by our readers and by python-can.

use can_io::log::{read_log, LogEntry};
use can_io::trace::write::TraceWriter;
use can_io::trace::{detect, parse_trace, Direction, ReadOptions, Trace, TraceFormat};
use devicenet::{CanFrame, Instant};
use proptest::prelude::*;
use rstest::rstest;
use std::path::PathBuf;
use std::time::UNIX_EPOCH;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

fn log() -> Vec<LogEntry> {
    read_log(&data("bring-up.log")).unwrap()
}

fn read(name: &str, strict: bool) -> Result<Trace, can_io::log::LogError> {
    let bytes = std::fs::read(data(name)).unwrap();
    parse_trace(&bytes, name, ReadOptions { strict, format: None })
}

/// How a fixture keeps the log's times.
#[derive(Clone, Copy, Debug)]
enum Time {
    /// As they are, to the microsecond.
    Exact,
    /// As they are, truncated to this many microseconds.
    Truncated(u64),
    /// Relative to the first frame (python-can's writers start at it), within this many µs.
    Relative(u64),
}

#[rstest]
#[case::asc("text/bring-up.asc", TraceFormat::Asc, Time::Relative(0))]
#[case::trc_v1_0("text/bring-up-v10.trc", TraceFormat::Trc, Time::Relative(500))]
#[case::trc_v1_1("text/bring-up-v11.trc", TraceFormat::Trc, Time::Truncated(100))]
#[case::trc_v1_2("text/bring-up-v12.trc", TraceFormat::Trc, Time::Exact)]
#[case::trc_v1_3("text/bring-up-v13.trc", TraceFormat::Trc, Time::Exact)]
#[case::trc_v2_0("text/bring-up-v20.trc", TraceFormat::Trc, Time::Exact)]
#[case::trc_v2_1("text/bring-up-v21.trc", TraceFormat::Trc, Time::Relative(0))]
#[case::csv("text/bring-up.csv", TraceFormat::Csv, Time::Exact)]
fn fixture_reads_as_the_log(#[case] name: &str, #[case] format: TraceFormat, #[case] time: Time) {
    let bytes = std::fs::read(data(name)).unwrap();
    assert_eq!(detect(&bytes), Some(format), "{name}");
    let trace = read(name, true).unwrap();
    let log = log();
    assert_eq!((trace.skipped_count, trace.entries.len()), (0, log.len()), "{name}: {:?}", trace.skipped);
    let first = (log[0].at.total_micros(), trace.entries[0].at.total_micros());
    for (read, want) in trace.entries.iter().zip(&log) {
        assert_eq!(read.frame, want.frame, "{name}:{}", read.line);
        let (got, want) = (read.at.total_micros(), want.at.total_micros());
        match time {
            Time::Exact => assert_eq!(got, want, "{name}:{}", read.line),
            Time::Truncated(unit) => assert_eq!(got, want / unit * unit, "{name}:{}", read.line),
            Time::Relative(within) => {
                let (got, want) = (got - first.1, want - first.0);
                assert!(got.abs_diff(want) <= within, "{name}:{}: {got} vs {want}", read.line);
            }
        }
    }
}

#[rstest]
#[case::trc_v1_1("text/foreign-v11.trc", 1, &["error warning", "error frame", "remote frame", "extended identifier", "half-written last line"])]
#[case::trc_v2_1("text/foreign-v21.trc", 1, &["CAN FD", "error frame", "event", "hardware status", "error counter", "extended identifier", "remote frame", "half-written last line"])]
#[case::asc("text/foreign.asc", 1, &["error frame", "extended identifier", "remote frame", "CAN FD", "not a CAN frame", "half-written last line"])]
#[case::csv("text/foreign.csv", 1, &["error frame", "extended", "remote frame", "invalid base64", "half-written last line"])]
#[case::zlg("text/zlg.csv", 2, &["extended frame", "remote frame"])]
fn foreign_lines_are_skipped_and_named(#[case] name: &str, #[case] frames: usize, #[case] reasons: &[&str]) {
    let trace = read(name, false).unwrap();
    assert_eq!(trace.entries.len(), frames, "{name}: {:?}", trace.entries);
    assert_eq!(trace.skipped_count, reasons.len(), "{name}: {:?}", trace.skipped);
    for (skipped, reason) in trace.skipped.iter().zip(reasons) {
        assert!(
            skipped.reason.contains(reason),
            "{name}:{}: '{}' lacks '{reason}'",
            skipped.line,
            skipped.reason
        );
        assert!(skipped.line > 1, "{name}: {skipped:?}");
    }
    // Strict: the first skipped line is the error, named file:line.
    let err = read(name, true).unwrap_err();
    let first = &trace.skipped[0];
    assert!(err.to_string().starts_with(&format!("{name}:{}:", first.line)), "{err}");
    assert_eq!(err.reason, first.reason);
}

#[test]
fn zlg_rows_keep_direction_and_time_of_day() {
    let trace = read("text/zlg.csv", true).unwrap_err();
    assert_eq!(trace.line, 4);
    let trace = read("text/zlg.csv", false).unwrap();
    let e = &trace.entries[1];
    assert_eq!((e.frame.id().as_raw(), e.frame.data()), (0x42B, &[0x00, 0xCB, 0x00][..]));
    assert_eq!(e.direction, Some(Direction::Rx));
    assert_eq!(e.at.total_micros(), ((15 * 60 + 7) * 60 + 39) * 1_000_000 + 125_000);
}

#[test]
fn every_prefix_of_every_fixture_reads_without_panic() {
    let dir = data("text");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let bytes = std::fs::read(&path).unwrap();
        for end in 0..=bytes.len() {
            for format in [None, Some(TraceFormat::Trc), Some(TraceFormat::Asc), Some(TraceFormat::Csv)] {
                let _ = parse_trace(&bytes[..end], "prefix", ReadOptions { strict: false, format });
            }
        }
    }
}

/// Writes `entries` in `format` with a start time at the Unix epoch (python-can then reads the
/// offsets as they are).
fn written(format: TraceFormat, entries: &[(Instant, Option<Direction>, CanFrame)]) -> Vec<u8> {
    #[derive(Clone, Default)]
    struct Shared(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);
    impl std::io::Write for Shared {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().map_err(|_| std::io::Error::other("poisoned"))?.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let shared = Shared::default();
    let mut w = TraceWriter::with_start_time(Box::new(shared.clone()), format, UNIX_EPOCH).unwrap();
    for (at, dir, frame) in entries {
        w.write(*at, "1", *dir, frame).unwrap();
    }
    w.finish().unwrap();
    drop(w);
    let bytes = shared.0.lock().unwrap().clone();
    bytes
}

const WRITABLE: [TraceFormat; 4] =
    [TraceFormat::Candump, TraceFormat::Trc, TraceFormat::Asc, TraceFormat::Csv];

proptest! {
    #[test]
    fn random_text_never_panics(text in "\\PC{0,200}", which in 0usize..4) {
        let format = [None, Some(TraceFormat::Trc), Some(TraceFormat::Asc), Some(TraceFormat::Csv)][which];
        let _ = parse_trace(text.as_bytes(), "fuzz", ReadOptions { strict: false, format });
    }

    #[test]
    fn random_lines_after_a_header_never_panic(
        lines in proptest::collection::vec("[ 0-9A-Fa-fxXRTDdrt.:;,|=-]{0,60}", 0..8),
        which in 0usize..4,
    ) {
        let header = [";$FILEVERSION=2.1\n;$COLUMNS=N,O,T,B,I,d,R,L,D\n", ";$FILEVERSION=1.3\n", "base hex  timestamps relative\n",
                      "timestamp,arbitration_id,extended,remote,error,dlc,data\n"][which];
        let text = format!("{header}{}", lines.join("\n"));
        let _ = parse_trace(text.as_bytes(), "fuzz", ReadOptions::default());
    }

    #[test]
    fn what_we_write_we_read(
        frames in proptest::collection::vec((0u16..=0x7FF, proptest::collection::vec(any::<u8>(), 0..=8), 0u64..10_000_000, any::<bool>()), 1..20),
        which in 0usize..4,
    ) {
        let format = WRITABLE[which];
        let mut at = 0;
        let entries: Vec<_> = frames.into_iter().map(|(id, data, step, tx)| {
            at += step;
            let dir = if tx { Direction::Tx } else { Direction::Rx };
            (Instant::from_micros(at), Some(dir), CanFrame::from_raw(id, &data).unwrap())
        }).collect();
        let bytes = written(format, &entries);
        prop_assert_eq!(detect(&bytes), Some(format));
        let trace = parse_trace(&bytes, "ours", ReadOptions { strict: true, format: None }).unwrap();
        prop_assert_eq!(trace.entries.len(), entries.len());
        for (read, (at, dir, frame)) in trace.entries.iter().zip(&entries) {
            prop_assert_eq!(read.frame, *frame);
            prop_assert_eq!(read.at, *at);
            if matches!(format, TraceFormat::Trc | TraceFormat::Asc) {
                prop_assert_eq!(read.direction, *dir);
            }
        }
    }
}

/// The script that reads a trace with python-can's reader and prints one JSON object per frame.
const READ_BACK: &str = r#"
import json, sys, can
readers = {"asc": can.ASCReader, "trc": can.TRCReader, "csv": can.CSVReader, "candump": can.CanutilsLogReader}
for msg in readers[sys.argv[1]](sys.argv[2]):
    print(json.dumps({"id": msg.arbitration_id, "dlc": msg.dlc, "data": msg.data.hex().upper(), "us": round(msg.timestamp * 1e6)}))
"#;

#[test]
#[ignore = "needs python-can: DNET_PYTHON"]
fn python_can_reads_what_we_write() {
    let python = std::env::var("DNET_PYTHON").expect("DNET_PYTHON names a python with python-can");
    let entries: Vec<_> = log().into_iter().map(|e| (e.at, Some(Direction::Rx), e.frame)).collect();
    let dir = std::env::temp_dir().join(format!("dnet-trace-text-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for format in WRITABLE {
        let path = dir
            .join(format!("bring-up.{}", if format == TraceFormat::Candump { "log" } else { format.name() }));
        std::fs::write(&path, written(format, &entries)).unwrap();
        let out = std::process::Command::new(&python)
            .arg("-c")
            .arg(READ_BACK)
            .arg(format.name())
            .arg(&path)
            .output()
            .unwrap();
        assert!(out.status.success(), "{format}: {}", String::from_utf8_lossy(&out.stderr));
        let got: Vec<String> = String::from_utf8(out.stdout).unwrap().lines().map(str::to_string).collect();
        let want: Vec<String> = entries
            .iter()
            .map(|(at, _, f)| {
                let hex: String = f.data().iter().map(|b| format!("{b:02X}")).collect();
                format!(
                    r#"{{"id": {}, "dlc": {}, "data": "{hex}", "us": {}}}"#,
                    f.id().as_raw(),
                    f.dlc(),
                    at.total_micros()
                )
            })
            .collect();
        assert_eq!(got, want, "{format}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
