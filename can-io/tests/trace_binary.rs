//! The binary trace readers (pcap, pcapng, BLF) on fixtures written by independent tools
//! (`tests/data/make-binary-fixtures.py`: python-can's BLFWriter, Wireshark's editcap, records
//! packed with Python's struct module) from one simulated bring-up run (`tests/data/bring-up.log`).

use can_io::log::{read_log, LogEntry};
use can_io::trace::{parse_trace, Direction, ReadOptions, Trace, TraceFormat};
use devicenet::Instant;
use proptest::prelude::*;
use rstest::rstest;
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(data("binary").join(name)).unwrap()
}

fn read(name: &str, strict: bool) -> Result<Trace, can_io::log::LogError> {
    parse_trace(&fixture(name), name, ReadOptions { strict, format: None })
}

fn bring_up() -> Vec<LogEntry> {
    let log = read_log(&data("bring-up.log")).unwrap();
    assert_eq!(log.len(), 30, "bring-up.log holds the 30 frames of one connect");
    log
}

#[rstest]
#[case::pcap_by_dnet_master("bring-up.pcap", TraceFormat::Pcap, "pcap", None)]
#[case::pcap_nanoseconds("bring-up-ns.pcap", TraceFormat::Pcap, "pcap", None)]
#[case::pcap_big_endian("bring-up-be.pcap", TraceFormat::Pcap, "pcap", None)]
#[case::pcapng_by_editcap("bring-up.pcapng", TraceFormat::Pcapng, "if0", None)]
#[case::blf_by_python_can("bring-up.blf", TraceFormat::Blf, "1", Some(Direction::Rx))]
fn bring_up_reads_as_the_log(
    #[case] name: &str,
    #[case] format: TraceFormat,
    #[case] iface: &str,
    #[case] direction: Option<Direction>,
) {
    let trace = read(name, true).unwrap();
    assert_eq!(trace.format, format);
    assert_eq!(trace.skipped_count, 0, "{:?}", trace.skipped);
    let log = bring_up();
    assert_eq!(trace.entries.len(), log.len());
    for (i, (got, want)) in trace.entries.iter().zip(&log).enumerate() {
        assert_eq!(got.line, i + 1, "{name}: record numbers are 1-based");
        assert_eq!((got.frame, got.at), (want.frame, want.at), "{name}: record {}", i + 1);
        assert_eq!((got.iface.as_ref(), got.direction), (iface, direction), "{name}: record {}", i + 1);
    }
}

/// (record, reason part) of every skipped record, in order.
fn skips(trace: &Trace) -> Vec<(usize, String)> {
    trace.skipped.iter().map(|s| (s.line, s.reason.clone())).collect()
}

fn assert_skips(trace: &Trace, expected: &[(usize, &str)]) {
    let got = skips(trace);
    assert_eq!(trace.skipped_count, expected.len(), "{got:?}");
    for ((line, reason), (want_line, part)) in got.iter().zip(expected) {
        assert_eq!(line, want_line, "{got:?}");
        assert!(reason.contains(part), "record {line}: '{reason}' should name '{part}'");
    }
}

#[test]
fn foreign_pcap_records_are_skipped_by_name() {
    let trace = read("foreign.pcap", false).unwrap();
    let frames: Vec<_> = trace.entries.iter().map(|e| (e.line, e.frame.to_string(), e.at)).collect();
    assert_eq!(
        frames,
        [
            (1, "407#00010004030201".to_string(), Instant::from_micros(1_000_000)),
            (8, "7FF#".to_string(), Instant::from_micros(2_500_000)),
        ]
    );
    assert_skips(
        &trace,
        &[
            (2, "error frame (CAN_ERR_FLAG"),
            (3, "extended frame (CAN_EFF_FLAG"),
            (4, "remote frame (CAN_RTR_FLAG"),
            (5, "CAN FD frame"),
            (6, "DLC 9 > 8"),
            (7, "truncated record: 6 captured bytes"),
            (9, "half-written last record"),
        ],
    );
}

#[test]
fn foreign_pcapng_reads_names_directions_and_resolution() {
    let trace = read("foreign.pcapng", false).unwrap();
    assert_eq!(trace.format, TraceFormat::Pcapng);
    let frames: Vec<_> = trace
        .entries
        .iter()
        .map(|e| (e.line, e.iface.as_ref(), e.direction, e.frame.to_string(), e.at))
        .collect();
    assert_eq!(
        frames,
        [
            (1, "can0", Some(Direction::Rx), "407#00010004030201".into(), Instant::from_micros(5_000_002)),
            (2, "can0", Some(Direction::Tx), "42B#00CB00".into(), Instant::from_micros(5_000_002)),
            (5, "can0", None, "3C5#8200".into(), Instant::from_micros(6_000_000)),
        ]
    );
    assert_skips(&trace, &[(3, "link type 1 is not SocketCAN (227), interface if1"), (4, "CAN FD frame")]);
}

#[test]
fn foreign_blf_objects_are_skipped_by_name() {
    let trace = read("foreign.blf", false).unwrap();
    let log = bring_up();
    let frames: Vec<_> = trace.entries.iter().map(|e| (e.line, e.frame, e.at, e.direction)).collect();
    let mut expected: Vec<_> =
        log[..4].iter().enumerate().map(|(i, e)| (i + 1, e.frame, e.at, Some(Direction::Rx))).collect();
    // Object 9 is a global marker (not a frame, not counted); 10 a frame the recorder sent.
    let sent = devicenet::CanFrame::from_raw(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]).unwrap();
    expected.push((10, sent, Instant::from_micros(log[3].at.total_micros() + 6_000), Some(Direction::Tx)));
    assert_eq!(frames, expected);
    assert_skips(
        &trace,
        &[
            (5, "error frame (CAN_ERROR_EXT"),
            (6, "extended frame"),
            (7, "remote frame"),
            (8, "CAN FD frame (CAN_FD_MESSAGE"),
        ],
    );
}

#[rstest]
#[case::pcap("foreign.pcap", 2, "error frame")]
#[case::pcapng("foreign.pcapng", 3, "link type 1")]
#[case::blf("foreign.blf", 5, "error frame")]
fn strict_names_the_first_foreign_record(#[case] name: &str, #[case] line: usize, #[case] reason: &str) {
    let err = read(name, true).unwrap_err();
    assert_eq!((err.file.as_str(), err.line), (name, line), "{err}");
    assert!(err.reason.contains(reason), "{err}");
    assert!(err.to_string().starts_with(&format!("{name}:{line}:")), "{err}");
}

const ALL: [(&str, TraceFormat); 8] = [
    ("bring-up.pcap", TraceFormat::Pcap),
    ("bring-up-ns.pcap", TraceFormat::Pcap),
    ("bring-up-be.pcap", TraceFormat::Pcap),
    ("bring-up.pcapng", TraceFormat::Pcapng),
    ("bring-up.blf", TraceFormat::Blf),
    ("foreign.pcap", TraceFormat::Pcap),
    ("foreign.pcapng", TraceFormat::Pcapng),
    ("foreign.blf", TraceFormat::Blf),
];

/// A file cut at any byte reads without a panic, and what it reads is the whole file's frames up
/// to some point (never a frame the whole file does not have), with the same records skipped up
/// to there and perhaps a half-written last one.
#[test]
fn every_cut_point_reads_a_prefix_of_the_frames() {
    for (name, format) in ALL {
        let bytes = fixture(name);
        let whole = parse_trace(&bytes, name, ReadOptions::default()).unwrap();
        for len in 0..=bytes.len() {
            let cut = &bytes[..len];
            let options = ReadOptions { strict: false, format: Some(format) };
            let _ = parse_trace(cut, name, ReadOptions::default());
            if let Ok(trace) = parse_trace(cut, name, options) {
                let n = trace.entries.len();
                assert_eq!(trace.entries[..], whole.entries[..n], "{name} cut at {len}");
                let mut skipped = trace.skipped.clone();
                if skipped.last().is_some_and(|s| s.reason.starts_with("half-written last record")) {
                    skipped.pop();
                }
                assert_eq!(skipped[..], whole.skipped[..skipped.len()], "{name} cut at {len}");
            }
        }
    }
}

/// The smallest valid start of each format: a file header (and for pcapng an interface).
fn headers() -> Vec<(TraceFormat, Vec<u8>)> {
    let pcap = fixture("bring-up.pcap")[..24].to_vec();
    let pcapng = fixture("foreign.pcapng")[..28 + 40 + 20].to_vec();
    let blf = fixture("bring-up.blf")[..144].to_vec();
    vec![(TraceFormat::Pcap, pcap), (TraceFormat::Pcapng, pcapng), (TraceFormat::Blf, blf)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_bytes_after_a_valid_header_never_panic(
        which in 0usize..3,
        tail in proptest::collection::vec(any::<u8>(), 0..600),
    ) {
        let (format, mut bytes) = headers().swap_remove(which);
        bytes.extend(tail);
        let _ = parse_trace(&bytes, "fuzz", ReadOptions { strict: false, format: Some(format) });
        let _ = parse_trace(&bytes, "fuzz", ReadOptions { strict: true, format: None });
    }

    #[test]
    fn corrupted_fixtures_never_panic(
        which in 0usize..ALL.len(),
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
    ) {
        let (name, format) = ALL[which];
        let mut bytes = fixture(name);
        for (at, value) in flips {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        let _ = parse_trace(&bytes, name, ReadOptions { strict: false, format: Some(format) });
    }
}
