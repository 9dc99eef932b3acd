use super::*;
use rstest::rstest;
use slave_fw::serial::trace::CHUNK;

fn entry(time_ms: u32, kind: TraceKind, bytes: &[u8]) -> TraceEntry {
    TraceEntry::new(time_ms, kind, bytes).unwrap()
}

/// Pushes `bytes` as entries of at most [`CHUNK`] bytes from sequence number `seq` on; returns
/// the lines they completed.
fn push_all(d: &mut Decoder, seq: u32, kind: TraceKind, bytes: &[u8]) -> Vec<TraceLine> {
    let mut out = Vec::new();
    for (k, chunk) in bytes.chunks(CHUNK).enumerate() {
        out.extend(d.push(seq + k as u32, &entry(seq + k as u32, kind, chunk)));
    }
    out
}

fn texts(lines: &[TraceLine]) -> Vec<(&str, &str)> {
    lines.iter().map(|l| (l.kind, l.decoded.as_str())).collect()
}

#[test]
fn reply_parses_and_malformed_replies_are_errors() {
    let mut wire = vec![5, 0, 0, 0, 7, 0, 0, 0];
    let mut e = [0u8; 32];
    let n = entry(9, TraceKind::Receive, &[1, 2]).encode(&mut e).unwrap();
    wire.extend_from_slice(&e[..n]);
    let r = parse_reply(&wire).unwrap();
    assert_eq!((r.first, r.next, r.entries.len()), (5, 7, 1));
    assert_eq!(r.entries[0].bytes(), [1, 2]);
    assert_eq!(parse_reply(&wire[..7]), Err(TraceReplyError::Short(7)));
    assert_eq!(
        parse_reply(&wire[..wire.len() - 1]),
        Err(TraceReplyError::Entry { offset: 8, error: TraceParseError::Truncated })
    );
}

#[rstest]
#[case::none(10, 10, Gap::None)]
#[case::missed(10, 14, Gap::Missed(4))]
#[case::missed_across_the_wrap(u32::MAX - 1, 2, Gap::Missed(4))]
#[case::restarted(500, 3, Gap::Restarted)]
fn gaps_between_asked_and_first(#[case] from: u32, #[case] first: u32, #[case] gap: Gap) {
    assert_eq!(Gap::between(from, first), gap);
}

#[rstest]
#[case::framed(Some(&[0][..]), None, LineProfile::Breaker)]
#[case::framed_ignores_framing(Some(&[0][..]), Some(&[2][..]), LineProfile::Breaker)]
#[case::modbus_before_attribute_12(Some(&[1][..]), None, LineProfile::ModbusRtu)]
#[case::rtu(Some(&[1][..]), Some(&[0][..]), LineProfile::ModbusRtu)]
#[case::ascii(Some(&[1][..]), Some(&[1][..]), LineProfile::ModbusAscii)]
#[case::tcp(Some(&[1][..]), Some(&[2][..]), LineProfile::ModbusTcp)]
#[case::unknown_framing(Some(&[1][..]), Some(&[3][..]), LineProfile::Raw)]
#[case::no_profile(None, None, LineProfile::Raw)]
#[case::long_value(Some(&[1, 0][..]), None, LineProfile::Raw)]
fn profile_from_the_settings_object(
    #[case] profile: Option<&[u8]>,
    #[case] framing: Option<&[u8]>,
    #[case] want: LineProfile,
) {
    assert_eq!(LineProfile::from_settings(profile, framing), want);
}

#[test]
fn breaker_frames_are_decoded_across_entries() {
    let mut d = Decoder::new(LineProfile::Breaker);
    let mut wire = [0u8; 32];
    let data = breaker::StatusData::new([1, 2, 3, 4], breaker::SwitchState::Closed);
    let n = breaker::FRAMING.encode(data.as_bytes(), &mut wire).unwrap();
    assert!(d.push(0, &entry(10, TraceKind::Receive, &wire[..16])).is_empty());
    let lines = d.push(1, &entry(26, TraceKind::Receive, &wire[16..n]));
    assert_eq!(lines.len(), 1);
    assert_eq!(lines[0].decoded, "status: currents 1 2 3 4, switch Closed");
    assert_eq!((lines[0].seq, lines[0].kind), (1, "rx"));
    let lines = d.push(2, &entry(30, TraceKind::Transmit, &[0x68, 0x01, 0x02, 0x02, 0x16]));
    assert_eq!(lines[0].decoded, "command Close");
    assert_eq!(lines[0].hex, "68 01 02 02 16");
    let lines = d.push(3, &entry(31, TraceKind::Checksum, &[]));
    assert_eq!(lines[0].kind, "checksum err");
    assert_eq!(lines[0].to_string(), "#3              31 ms  checksum err ");
}

#[test]
fn modbus_requests_and_responses_are_decoded() {
    let mut d = Decoder::new(LineProfile::ModbusRtu);
    let adu = rtu_adu(&[0x01, 0x04, 0x00, 0x07, 0x00, 0x01]);
    let lines = d.push(0, &entry(0, TraceKind::Transmit, &adu));
    assert_eq!(lines[0].decoded, "request unit 1: 0x04 read input registers 7 count 1");
    let lines = d.push(1, &entry(5, TraceKind::Receive, &[0x01, 0x04, 0x02, 0xFF]));
    assert!(lines.is_empty());
    let lines = d.push(2, &entry(6, TraceKind::Receive, &[0xFF, 0xB8, 0x80]));
    assert_eq!(lines[0].decoded, "response unit 1: 0x04 registers FFFF");
    let lines = d.push(3, &entry(9, TraceKind::Receive, &[0x01, 0x63]));
    assert!(lines[0].decoded.starts_with("not a Modbus RTU frame"), "{lines:?}");
    // A response cut short, then the next request: the rest is named incomplete.
    assert!(d.push(4, &entry(20, TraceKind::Receive, &[0x01, 0x04, 0x02])).is_empty());
    let lines = d.push(5, &entry(30, TraceKind::Transmit, &adu));
    assert_eq!(
        (lines[0].kind, lines[0].hex.as_str(), lines[0].decoded.as_str()),
        ("rx", "01 04 02", "incomplete frame")
    );
    assert_eq!(lines[1].decoded, "request unit 1: 0x04 read input registers 7 count 1");
}

/// Read input registers 7 count 1 at unit 1 (LRC 0xF3), and its answer FFFF (LRC 0xFB), as
/// Modbus over Serial Line §2.5.2 writes them.
const ASCII_REQUEST: &[u8] = b":010400070001F3\r\n";
const ASCII_RESPONSE: &[u8] = b":010402FFFFFB\r\n";

#[test]
fn modbus_ascii_requests_and_responses_are_decoded_across_entries() {
    let mut d = Decoder::new(LineProfile::ModbusAscii);
    // 17 characters: two entries, the line made by the second.
    let lines = push_all(&mut d, 0, TraceKind::Transmit, ASCII_REQUEST);
    assert_eq!(texts(&lines), [("tx", "request unit 1: 0x04 read input registers 7 count 1")]);
    assert_eq!(lines[0].seq, 1);
    assert_eq!(lines[0].hex, decode::hex(ASCII_REQUEST));
    let lines = push_all(&mut d, 2, TraceKind::Receive, ASCII_RESPONSE);
    assert_eq!(texts(&lines), [("rx", "response unit 1: 0x04 registers FFFF")]);
    // The same frame a character at a time.
    let mut lines = Vec::new();
    for (k, c) in ASCII_RESPONSE.iter().enumerate() {
        lines.extend(d.push(10 + k as u32, &entry(0, TraceKind::Receive, &[*c])));
    }
    assert_eq!(texts(&lines), [("rx", "response unit 1: 0x04 registers FFFF")]);
}

/// `taken`: the characters up to the one that ended the frame (the rest is outside any frame).
#[rstest]
#[case::bad_lrc(b":010402FFFF00\r\n", 15, "not a Modbus ASCII frame: LRC 0x00 received, 0xFB computed")]
#[case::short(
    b":0104\r\n",
    7,
    "not a Modbus ASCII frame: ASCII frame shorter than address, function and LRC"
)]
#[case::bad_character(b":0104G2\r\n", 6, "not a Modbus ASCII frame: character 0x47 inside an ASCII frame")]
#[case::odd_length(b":010\r\n", 5, "not a Modbus ASCII frame: odd number of hexadecimal characters")]
#[case::no_lf(b":010402FFFFFB\rX", 15, "not a Modbus ASCII frame: CR followed by 0x58, not LF")]
#[case::unknown_function(b":0163FF9D\r\n", 11, "not a Modbus ASCII frame: ")]
fn malformed_ascii_frames_are_hex_with_the_reason(
    #[case] wire: &[u8],
    #[case] taken: usize,
    #[case] reason: &str,
) {
    let mut d = Decoder::new(LineProfile::ModbusAscii);
    let lines = push_all(&mut d, 0, TraceKind::Receive, wire);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].decoded.starts_with(reason), "{lines:?}");
    assert_eq!(lines[0].hex, decode::hex(&wire[..taken]));
    // What follows the error is outside any frame, named when the next frame starts.
    let lines = push_all(&mut d, 2, TraceKind::Receive, ASCII_RESPONSE);
    let mut want = vec![("rx", "response unit 1: 0x04 registers FFFF")];
    if taken < wire.len() {
        want.insert(0, ("rx", "bytes outside any ASCII frame"));
    }
    assert_eq!(texts(&lines), want);
}

#[test]
fn ascii_bytes_outside_frames_and_cut_frames_are_named() {
    let mut d = Decoder::new(LineProfile::ModbusAscii);
    // Noise, then a frame: the noise is its own line when the frame starts.
    let mut wire = b"xy".to_vec();
    wire.extend_from_slice(ASCII_RESPONSE);
    let lines = push_all(&mut d, 0, TraceKind::Receive, &wire);
    assert_eq!(
        texts(&lines),
        [("rx", "bytes outside any ASCII frame"), ("rx", "response unit 1: 0x04 registers FFFF")]
    );
    assert_eq!(lines[0].hex, "78 79");
    // A ':' inside a frame: the frame so far is dropped, the new one decoded.
    let mut wire = b":0104".to_vec();
    wire.extend_from_slice(ASCII_RESPONSE);
    let lines = push_all(&mut d, 5, TraceKind::Receive, &wire);
    assert_eq!(
        texts(&lines),
        [
            ("rx", "not a Modbus ASCII frame: ':' inside an ASCII frame"),
            ("rx", "response unit 1: 0x04 registers FFFF")
        ]
    );
    assert_eq!(lines[0].hex, "3A 30 31 30 34");
    // A response cut short by the next request.
    assert!(push_all(&mut d, 9, TraceKind::Receive, b":0104").is_empty());
    let lines = push_all(&mut d, 10, TraceKind::Transmit, ASCII_REQUEST);
    assert_eq!(
        texts(&lines),
        [("rx", "incomplete frame"), ("tx", "request unit 1: 0x04 read input registers 7 count 1")]
    );
    // Noise without end is printed once it fills a frame's room, not kept.
    let lines = push_all(&mut d, 20, TraceKind::Receive, &[b'z'; MAX_LOOSE + 3]);
    assert_eq!(texts(&lines), [("rx", "bytes outside any ASCII frame")]);
    assert_eq!(lines[0].hex.len(), MAX_LOOSE * 3 - 1);
}

/// Transaction 5: read input registers 7 count 1 at unit 1, and its answer FFFF (Modbus
/// Messaging on TCP/IP Implementation Guide V1.0b §3.1.3).
const TCP_REQUEST: &[u8] = &[0x00, 0x05, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04, 0x00, 0x07, 0x00, 0x01];
const TCP_RESPONSE: &[u8] = &[0x00, 0x05, 0x00, 0x00, 0x00, 0x05, 0x01, 0x04, 0x02, 0xFF, 0xFF];

#[test]
fn modbus_tcp_requests_and_responses_are_decoded() {
    let mut d = Decoder::new(LineProfile::ModbusTcp);
    let lines = push_all(&mut d, 0, TraceKind::Transmit, TCP_REQUEST);
    assert_eq!(
        texts(&lines),
        [("tx", "request unit 1: 0x04 read input registers 7 count 1 (transaction 5)")]
    );
    assert_eq!(lines[0].hex, decode::hex(TCP_REQUEST));
    // The response in two entries, then two responses in one stream of entries.
    assert!(d.push(1, &entry(1, TraceKind::Receive, &TCP_RESPONSE[..4])).is_empty());
    let lines = d.push(2, &entry(2, TraceKind::Receive, &TCP_RESPONSE[4..]));
    assert_eq!(texts(&lines), [("rx", "response unit 1: 0x04 registers FFFF (transaction 5)")]);
    let mut two = TCP_RESPONSE.to_vec();
    two.extend_from_slice(&[0x01, 0x00, 0x00, 0x00, 0x00, 0x05, 0x02, 0x03, 0x02, 0x12, 0x34]);
    let lines = push_all(&mut d, 3, TraceKind::Receive, &two);
    assert_eq!(
        texts(&lines),
        [
            ("rx", "response unit 1: 0x04 registers FFFF (transaction 5)"),
            ("rx", "response unit 2: 0x03 registers 1234 (transaction 256)")
        ]
    );
}

#[rstest]
#[case::protocol(&[0x00, 0x06, 0x00, 0x01, 0x00, 0x06, 0x01], "not a Modbus TCP frame: MBAP protocol identifier 1, not 0")]
#[case::length(&[0x00, 0x07, 0x00, 0x00, 0x00, 0x01, 0x01], "not a Modbus TCP frame: MBAP length 1 outside 2..=254")]
#[case::short_pdu(&[0x00, 0x08, 0x00, 0x00, 0x00, 0x02, 0x01, 0x04], "not a Modbus TCP frame: ")]
fn malformed_tcp_frames_are_hex_with_the_reason(#[case] wire: &[u8], #[case] reason: &str) {
    let mut d = Decoder::new(LineProfile::ModbusTcp);
    let lines = d.push(0, &entry(0, TraceKind::Transmit, wire));
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].decoded.starts_with(reason), "{lines:?}");
    assert_eq!(lines[0].hex, decode::hex(wire));
    // The stream goes on with the next frame.
    let lines = d.push(1, &entry(1, TraceKind::Transmit, TCP_REQUEST));
    assert_eq!(
        texts(&lines),
        [("tx", "request unit 1: 0x04 read input registers 7 count 1 (transaction 5)")]
    );
}

#[test]
fn a_tcp_frame_cut_short_is_named_incomplete() {
    let mut d = Decoder::new(LineProfile::ModbusTcp);
    assert!(d.push(0, &entry(0, TraceKind::Receive, &TCP_RESPONSE[..8])).is_empty());
    let lines = d.push(1, &entry(1, TraceKind::Transmit, TCP_REQUEST));
    assert_eq!(
        texts(&lines),
        [
            ("rx", "incomplete frame"),
            ("tx", "request unit 1: 0x04 read input registers 7 count 1 (transaction 5)")
        ]
    );
    assert_eq!(lines[0].hex, decode::hex(&TCP_RESPONSE[..8]));
    // The receiver starts again: the next response is whole.
    let lines = d.push(2, &entry(2, TraceKind::Receive, TCP_RESPONSE));
    assert_eq!(texts(&lines), [("rx", "response unit 1: 0x04 registers FFFF (transaction 5)")]);
}

#[test]
fn events_are_lines_of_their_own_in_every_profile() {
    for profile in [LineProfile::ModbusAscii, LineProfile::ModbusTcp, LineProfile::Raw] {
        let mut d = Decoder::new(profile);
        let lines = d.push(7, &entry(40, TraceKind::DriverOn, &[]));
        assert_eq!(texts(&lines), [("driver on", "")], "{profile:?}");
    }
}

/// Bytes held by a decoder between lines, at most: an ASCII frame's characters (or the loose
/// bytes before one is printed) per direction.
fn held(d: &Decoder) -> usize {
    let ascii = d.ascii.iter().map(|s| s.raw.len()).max().unwrap_or(0);
    let mbap = d.mbap.iter().map(|s| s.raw.len()).max().unwrap_or(0);
    d.tx.len().max(d.rx.len()).max(ascii).max(mbap)
}

proptest::proptest! {
    /// Any entries, in any profile: no panic, and what the decoder holds stays within one longest
    /// frame (an ASCII frame, 513 characters) per direction.
    #[test]
    fn any_entries_decode_without_panic_in_bounded_memory(
        entries in proptest::collection::vec(
            (0u8..9, proptest::collection::vec(proptest::prelude::any::<u8>(), 0..=CHUNK)),
            0..200,
        ),
        profile in 0usize..5,
    ) {
        let profile = [
            LineProfile::Breaker,
            LineProfile::ModbusRtu,
            LineProfile::ModbusAscii,
            LineProfile::ModbusTcp,
            LineProfile::Raw,
        ][profile];
        let mut d = Decoder::new(profile);
        for (k, (kind, bytes)) in entries.iter().enumerate() {
            let kind = TraceKind::from_code(*kind).unwrap();
            let _ = d.push(k as u32, &entry(k as u32, kind, bytes));
            proptest::prop_assert!(held(&d) <= ascii::FRAME_CAPACITY, "{} bytes held", held(&d));
        }
    }

    /// Noise and colons on an ASCII line: every byte given reaches a line or is still held.
    #[test]
    fn ascii_bytes_are_printed_or_held(bytes in proptest::collection::vec(
        proptest::sample::select(b":0123456789ABCDEFG\r\nx".to_vec()), 0..400)
    ) {
        let mut d = Decoder::new(LineProfile::ModbusAscii);
        let lines = push_all(&mut d, 0, TraceKind::Receive, &bytes);
        let printed: usize = lines.iter().map(|l| if l.hex.is_empty() { 0 } else { l.hex.len().div_ceil(3) }).sum();
        proptest::prop_assert_eq!(printed + d.ascii[1].raw.len(), bytes.len());
    }
}
