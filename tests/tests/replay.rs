//! `replay`: the transcript of `connect` replays; one wrong byte, a missing frame or an extra
//! frame is a divergence reported with expected and actual frames, both decoded, and the frames
//! before it; malformed transcripts are refused with their line.

use can_io::bus::Bitrate;
use can_io::log::{format_line, parse_log, LogEntry};
use devicenet::reference::BRING_UP;
use harness_common::error::Divergence;
use harness_common::error::HarnessError;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use master_harness::replay::{replay, ReplayOptions};
use system_tests::{log_text, mac, sim_bus};

fn connect_transcript() -> String {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default()).unwrap();
    log_text(session.records(), "sim")
}

fn run(text: &str) -> (Result<master_harness::replay::ReplaySummary, HarnessError>, usize) {
    let entries = parse_log(text, "t.log").unwrap();
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let r = replay(&mut session, &entries, &ReplayOptions::new(mac(5)));
    let failures = session.failures();
    (r, failures)
}

fn divergence(r: Result<master_harness::replay::ReplaySummary, HarnessError>) -> Divergence {
    match r {
        Err(HarnessError::Divergence(d)) => *d,
        other => panic!("expected a divergence, got {other:?}"),
    }
}

#[test]
fn the_connect_transcript_is_the_reference_and_replays() {
    let text = connect_transcript();
    let entries: Vec<LogEntry> = parse_log(&text, "t").unwrap();
    let frames: Vec<(u16, Vec<u8>)> =
        entries.iter().map(|e| (e.frame.id().as_raw(), e.frame.data().to_vec())).collect();
    let reference: Vec<(u16, Vec<u8>)> = BRING_UP.iter().map(|r| (r.id, r.data.to_vec())).collect();
    assert_eq!(frames, reference);
    let (r, failures) = run(&text);
    let summary = r.unwrap();
    assert_eq!((summary.frames, summary.expected, summary.stimulus), (28, 14, 14));
    assert_eq!(failures, 0);
}

#[test]
fn the_reference_table_itself_replays() {
    // A transcript written by hand from protocol §2, with the capture's timing.
    let times_ms = [0, 1000, 2000, 3000, 4000, 4500];
    let mut text = String::new();
    for (i, r) in BRING_UP.iter().enumerate() {
        let ms = times_ms.get(i).copied().unwrap_or(5000 + 2 * i as u64);
        let f = devicenet::CanFrame::from_raw(r.id, r.data).unwrap();
        text.push_str(&format_line(devicenet::Instant::from_millis(ms), "can0", &f));
        text.push('\n');
    }
    let (r, failures) = run(&text);
    assert!(r.is_ok(), "{r:?}");
    assert_eq!(failures, 0);
}

#[test]
fn one_wrong_byte_is_a_clear_divergence() {
    let text = connect_transcript().replace("42B#008E0C00", "42B#008E0D00");
    let d = divergence(run(&text).0);
    assert_eq!(d.index, 13);
    assert_eq!(d.reason, "the device sent a different frame");
    let expected = d.expected.as_ref().unwrap();
    let actual = d.actual.as_ref().unwrap();
    assert_eq!(expected.line, Some(14));
    assert_eq!((expected.frame.as_str(), actual.frame.as_str()), ("42B#008E0D00", "42B#008E0C00"));
    assert!(expected.meaning.contains("attr 2 (device type) = 0x000D"), "{}", expected.meaning);
    assert!(actual.meaning.contains("attr 2 (device type) = 0x000C"), "{}", actual.meaning);
    assert_eq!(d.before.len(), 8);
    assert_eq!(d.before.last().unwrap().frame, "42C#000E010102");
    let report = d.to_string();
    assert!(report.contains("replay diverged at transcript line 14, frame 14 of 28"), "{report}");
    assert!(report.contains("expected: 42B#008E0D00"), "{report}");
    assert!(report.contains("actual:   42B#008E0C00"), "{report}");
    assert!(report.contains("frames before it:"), "{report}");
}

#[test]
fn a_frame_the_device_does_not_send_is_a_divergence() {
    // The transcript expects an extra response after the vendor ID.
    let text = connect_transcript();
    let mut lines: Vec<&str> = text.lines().collect();
    let extra = lines[11].to_string();
    lines.insert(12, &extra);
    let d = divergence(run(&(lines.join("\n") + "\n")).0);
    assert_eq!(d.index, 12);
    assert!(d.actual.is_none() || d.reason.contains("different"), "{d}");
}

#[test]
fn a_frame_the_transcript_does_not_have_is_a_divergence() {
    // Drop the device's answer to the product code request: the device still sends it.
    let text = connect_transcript();
    let lines: Vec<&str> = text.lines().filter(|l| !l.ends_with("42B#008E0100")).collect();
    let d = divergence(run(&(lines.join("\n") + "\n")).0);
    assert!(d.reason.contains("does not have here"), "{d}");
    assert_eq!(d.actual.unwrap().frame, "42B#008E0100");
    // Truncate after the poll command: the poll response is extra.
    let upto: Vec<&str> = text.lines().take(25).collect();
    let d = divergence(run(&(upto.join("\n") + "\n")).0);
    assert!(d.reason.contains("after the transcript's last one"), "{d}");
}

#[test]
fn a_second_master_in_the_transcript_is_stimulus() {
    // After the bring-up, master 7 tries to allocate: the device refuses with 0x0C / 0x01.
    let mut text = connect_transcript();
    text.push_str("(5.100000) sim 42E#074B03010107\n(5.100300) sim 42B#07940C01\n");
    let (r, failures) = run(&text);
    assert!(r.is_ok(), "{r:?}");
    assert_eq!(failures, 0);
}

#[test]
fn malformed_transcript_lines_are_named() {
    let err = parse_log("(0.000436) sim 407#00010004030201\n(1.0) sim 42F#0G\n", "bench.log").unwrap_err();
    assert_eq!((err.line, err.column), (2, 16));
    assert!(err.to_string().starts_with("bench.log:2:16: invalid hex digit"), "{err}");
}
