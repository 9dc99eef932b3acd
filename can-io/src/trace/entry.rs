//! One frame of a trace ([`LogEntry`]), the errors that name its file, line and column
//! ([`LogError`]), and the `candump -L` line grammar every reader and writer shares:
//! `(seconds.micros) iface ID#DATA`.
//!
//! Only what DeviceNet uses is accepted: classic data frames with a 3-digit (11-bit) identifier and
//! 0–8 data bytes. Blank lines and lines starting with `#` are skipped. Every other line is an
//! error naming the file, the line and the column, never a panic.

use super::Direction;
use devicenet::{CanFrame, Instant};
use std::path::Path;
use std::sync::Arc;

/// One frame of a log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogEntry {
    /// 1-based line number in the file.
    pub line: usize,
    /// The timestamp.
    pub at: Instant,
    /// The interface (candump, pcapng) or channel (trc, asc, blf, csv) name; shared by the
    /// entries of one interface (a trace has millions of entries and a few interfaces).
    pub iface: Arc<str>,
    /// The frame.
    pub frame: CanFrame,
    /// The direction, where the format records it (trc, asc, blf, csv).
    pub direction: Option<Direction>,
}

/// What is wrong with a log line.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}:{column}: {reason}\n    {text}")]
pub struct LogError {
    /// The file (or `<input>`).
    pub file: String,
    /// 1-based line number.
    pub line: usize,
    /// 1-based column where the problem starts.
    pub column: usize,
    /// What is wrong.
    pub reason: String,
    /// The line itself.
    pub text: String,
}

/// Formats one log line (without the newline): `(0.000423) sim 407#00010004030201`.
pub fn format_line(at: Instant, iface: &str, frame: &CanFrame) -> String {
    let us = at.total_micros();
    format!("({}.{:06}) {iface} {frame}", us / 1_000_000, us % 1_000_000)
}

/// Parses a whole log. `file` names the source in errors.
pub fn parse_log(text: &str, file: &str) -> Result<Vec<LogEntry>, LogError> {
    let mut entries = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim_end_matches('\r');
        let trimmed = line.trim_start();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        entries.push(parse_line(line, i + 1).map_err(|(column, reason)| LogError {
            file: file.to_string(),
            line: i + 1,
            column,
            reason,
            text: line.to_string(),
        })?);
    }
    Ok(entries)
}

/// Reads and parses a log file; `-` reads standard input (as the candump tools do; a file named
/// `-` is `./-`). An unreadable file is reported as line 0.
pub fn read_log(path: &Path) -> Result<Vec<LogEntry>, LogError> {
    let (bytes, file) = read_source(path)?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..valid].iter().filter(|&&b| b == b'\n').count() + 1;
        LogError {
            file: file.clone(),
            line,
            column: 0,
            reason: "the file is not UTF-8 text".to_string(),
            text: String::new(),
        }
    })?;
    parse_log(&text, &file)
}

/// The bytes of a log or trace file and its name for messages; `-` is standard input (read to its
/// end, named `standard input`). A file that cannot be read is an error at line 0.
pub(crate) fn read_source(path: &Path) -> Result<(Vec<u8>, String), LogError> {
    let stdin = path.as_os_str() == "-";
    let file = if stdin { "standard input".to_string() } else { path.display().to_string() };
    let read = if stdin {
        let mut bytes = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin().lock(), &mut bytes).map(|_| bytes)
    } else {
        std::fs::read(path)
    };
    let bytes = read.map_err(|e| LogError {
        file: file.clone(),
        line: 0,
        column: 0,
        reason: format!("cannot read the file: {e}"),
        text: String::new(),
    })?;
    Ok((bytes, file))
}

fn is_hex(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit())
}

/// Parses `(seconds.micros) iface ID#DATA`; errors are (1-based column, reason).
pub(crate) fn parse_line(line: &str, number: usize) -> Result<LogEntry, (usize, String)> {
    let col = |part: &str| part.as_ptr() as usize - line.as_ptr() as usize + 1;
    let start = line.len() - line.trim_start().len();
    let rest = &line[start..];
    let Some(after_paren) = rest.strip_prefix('(') else {
        return Err((start + 1, "expected '(' starting the timestamp '(seconds.micros)'".into()));
    };
    let Some(close) = after_paren.find(')') else {
        return Err((col(after_paren), "the timestamp has no closing ')'".into()));
    };
    let stamp = &after_paren[..close];
    let at = parse_timestamp(stamp).map_err(|reason| (col(after_paren), reason))?;
    let after = &after_paren[close + 1..];
    let mut fields = after.split_whitespace();
    let Some(iface) = fields.next() else {
        return Err((line.len() + 1, "missing interface name and frame after the timestamp".into()));
    };
    let Some(frame_text) = fields.next() else {
        return Err((line.len() + 1, "missing frame 'ID#DATA' after the interface name".into()));
    };
    if let Some(extra) = fields.next() {
        // candump -L writes nothing after the frame; a trailing comment is allowed with '#'.
        if !extra.starts_with('#') {
            return Err((col(extra), format!("unexpected text '{extra}' after the frame")));
        }
    }
    let frame = parse_frame(frame_text).map_err(|(offset, reason)| (col(frame_text) + offset, reason))?;
    Ok(LogEntry { line: number, at, iface: iface.into(), frame, direction: None })
}

fn parse_timestamp(stamp: &str) -> Result<Instant, String> {
    let bad = || format!("invalid timestamp '({stamp})': expected (seconds.micros), e.g. (12.000345)");
    let (secs, frac) = stamp.split_once('.').ok_or_else(bad)?;
    if !secs.bytes().all(|b| b.is_ascii_digit()) || secs.is_empty() {
        return Err(bad());
    }
    if frac.is_empty() || frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let secs: u64 = secs.parse().map_err(|_| bad())?;
    // Up to nanoseconds accepted; kept to the microsecond.
    let mut digits = frac.to_string();
    while digits.len() < 6 {
        digits.push('0');
    }
    let micros: u64 = digits[..6].parse().map_err(|_| bad())?;
    let total = secs.checked_mul(1_000_000).and_then(|s| s.checked_add(micros)).ok_or_else(bad)?;
    Ok(Instant::from_micros(total))
}

/// Parses `ID#DATA`; errors are (0-based offset in the frame text, reason).
pub fn parse_frame(text: &str) -> Result<CanFrame, (usize, String)> {
    let Some((id, data)) = text.split_once('#') else {
        return Err((0, format!("invalid frame '{text}': expected ID#DATA")));
    };
    if data.starts_with('#') {
        return Err((id.len(), "CAN FD frames (ID##...) are not DeviceNet traffic".into()));
    }
    if data.starts_with('R') || data.starts_with('r') {
        return Err((id.len() + 1, "remote frames are not DeviceNet traffic".into()));
    }
    if !is_hex(id) {
        return Err((0, format!("invalid identifier '{id}': expected 3 hex digits")));
    }
    if id.len() == 8 && u32::from_str_radix(id, 16).is_ok_and(|raw| raw & 0x2000_0000 != 0) {
        return Err((0, format!("error frame '{text}' (CAN_ERR_FLAG set) is not DeviceNet traffic")));
    }
    if id.len() == 8 {
        return Err((
            0,
            format!("extended identifier '{id}' is not DeviceNet traffic (11-bit identifiers only)"),
        ));
    }
    if id.len() != 3 {
        return Err((0, format!("invalid identifier '{id}': expected 3 hex digits")));
    }
    let raw = u16::from_str_radix(id, 16).map_err(|_| (0, format!("invalid identifier '{id}'")))?;
    if raw > 0x7FF {
        return Err((0, format!("identifier 0x{raw:03X} does not fit in 11 bits")));
    }
    // candump may separate bytes with '.'.
    let data: String = data.chars().filter(|&c| c != '.').collect();
    if data.len() % 2 != 0 {
        return Err((id.len() + 1, format!("odd number of hex digits in data '{data}'")));
    }
    if !data.is_empty() && !is_hex(&data) {
        let pos = data.find(|c: char| !c.is_ascii_hexdigit()).unwrap_or(0);
        return Err((id.len() + 1 + pos, format!("invalid hex digit in data '{data}'")));
    }
    if data.len() > 16 {
        return Err((id.len() + 1, format!("{} data bytes, a CAN frame holds at most 8", data.len() / 2)));
    }
    let bytes: Vec<u8> =
        (0..data.len()).step_by(2).filter_map(|i| u8::from_str_radix(&data[i..i + 2], 16).ok()).collect();
    CanFrame::from_raw(raw, &bytes).map_err(|e| (0, e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[test]
    fn round_trip() {
        let f = CanFrame::from_raw(0x42B, &[0x00, 0xCB, 0x00]).unwrap();
        let line = format_line(Instant::from_micros(5_000_423), "sim", &f);
        assert_eq!(line, "(5.000423) sim 42B#00CB00");
        let entries = parse_log(&format!("# comment\n\n{line}\n"), "t.log").unwrap();
        assert_eq!(
            entries,
            vec![LogEntry {
                line: 3,
                at: Instant::from_micros(5_000_423),
                iface: "sim".into(),
                frame: f,
                direction: None
            }]
        );
    }

    #[test]
    fn empty_frame_and_candump_real_timestamps() {
        let e = parse_log("(1436509052.249713) can0 42D#\n", "x").unwrap();
        assert_eq!(e[0].frame.dlc(), 0);
        assert_eq!(e[0].at.total_micros(), 1_436_509_052_249_713);
    }

    #[rstest]
    #[case::no_paren("0.1 sim 42B#00", 1, "expected '('")]
    #[case::no_close("(0.1 sim 42B#00", 2, "no closing ')'")]
    #[case::bad_stamp("(abc) sim 42B#00", 2, "invalid timestamp")]
    #[case::no_frame("(0.100000) sim", 15, "missing frame")]
    #[case::no_hash("(0.100000) sim 42B00", 16, "expected ID#DATA")]
    #[case::extended("(0.100000) sim 0000042B#00", 16, "extended identifier")]
    #[case::too_big("(0.100000) sim 800#00", 16, "does not fit in 11 bits")]
    #[case::odd("(0.100000) sim 42B#0", 20, "odd number of hex digits")]
    #[case::bad_hex("(0.100000) sim 42B#0G", 21, "invalid hex digit")]
    #[case::too_long("(0.100000) sim 42B#000102030405060708", 20, "9 data bytes")]
    #[case::remote("(0.100000) sim 42B#R", 20, "remote frames")]
    #[case::fd("(0.100000) sim 42B##100", 19, "CAN FD")]
    #[case::trailing("(0.100000) sim 42B#00 junk", 23, "unexpected text 'junk'")]
    fn precise_errors(#[case] line: &str, #[case] column: usize, #[case] reason: &str) {
        let err = parse_log(&format!("(0.000000) sim 407#00\n{line}\n"), "bad.log").unwrap_err();
        assert_eq!((err.line, err.column), (2, column), "{err}");
        assert!(err.reason.contains(reason), "{err}");
        assert!(err.to_string().starts_with("bad.log:2:"), "{err}");
    }

    proptest::proptest! {
        #[test]
        fn never_panics(text in "\\PC{0,80}") {
            let _ = parse_log(&text, "fuzz");
        }

        #[test]
        fn formatted_lines_parse_back(id in 0u16..=0x7FF, data in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..=8), us in 0u64..10_000_000_000) {
            let f = CanFrame::from_raw(id, &data).unwrap();
            let line = format_line(Instant::from_micros(us), "can0", &f);
            let e = parse_log(&line, "p").unwrap();
            proptest::prop_assert_eq!(e[0].frame, f);
            proptest::prop_assert_eq!(e[0].at, Instant::from_micros(us));
        }
    }
}
