//! The `candump -L` reader of [`super::read_trace`]: the line grammar is [`super::entry`]'s.
//!
//! Skipped (counted, named): error frames (identifier with `CAN_ERR_FLAG`, 8 hex digits `2xxxxxxx`),
//! extended, remote and FD frames, lines that are not log lines, and a half-written last line (a last
//! line with no newline that does not parse). Comments (`#`) and blank lines are not frames and not
//! counted.
//!
//! Speed: `decode` reads millions of lines, so the canonical form candump writes
//! (`(digits.digits) iface HHH#HEX`) is read by `fast_line` straight from the bytes, and entries
//! of one interface share its name; every other line goes through [`super::entry`]'s parser, which
//! gives the precise reason when a line is not a frame.

use super::entry::{parse_line, LogEntry, LogError};
use super::Sink;
use devicenet::{CanFrame, Instant};
use std::sync::Arc;

/// Reads `candump -L` lines into `sink`.
pub fn read(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let complete = bytes.last().is_none_or(|&b| b == b'\n');
    let mut lines = bytes.split(|&b| b == b'\n').peekable();
    let mut number = 0;
    let mut iface: Arc<str> = Arc::from("");
    while let Some(raw) = lines.next() {
        number += 1;
        let last = lines.peek().is_none();
        if last && raw.is_empty() {
            break;
        }
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        if let Some((at, name, frame)) = fast_line(raw) {
            if name != iface.as_bytes() {
                // `fast_line` took the name from ASCII graphic bytes only.
                iface = Arc::from(String::from_utf8_lossy(name).as_ref());
            }
            sink.frame(LogEntry { line: number, at, iface: Arc::clone(&iface), frame, direction: None });
            continue;
        }
        let line = match std::str::from_utf8(raw) {
            Ok(line) => line,
            Err(_) => {
                let text = String::from_utf8_lossy(raw);
                sink.skip(number, 1, "the line is not UTF-8 text", &text)?;
                continue;
            }
        };
        let trimmed = line.trim_start();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        match parse_line(line, number) {
            Ok(entry) => sink.frame(entry),
            // A last line cut off by an interrupted recording: it has no newline.
            Err((column, reason)) if last && !complete => {
                sink.skip(number, column, format!("half-written last line: {reason}"), line)?
            }
            Err((column, reason)) => sink.skip(number, column, reason, line)?,
        }
    }
    Ok(())
}

fn hex_value(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'a'..=b'f' => Some(b - b'a' + 10),
        b'A'..=b'F' => Some(b - b'A' + 10),
        _ => None,
    }
}

/// The canonical line `(seconds.fraction) iface HHH#HEX` (1-9 fraction digits, an 11-bit
/// identifier, 0-8 data bytes, nothing after), read without allocating; `None` for anything else
/// (which [`parse_line`] then reads or explains). Agrees with [`parse_line`] on every line it
/// accepts (a test in this module checks).
pub(crate) fn fast_line(line: &[u8]) -> Option<(Instant, &[u8], CanFrame)> {
    let rest = line.strip_prefix(b"(")?;
    let close = rest.iter().position(|&b| b == b')')?;
    let (stamp, rest) = (&rest[..close], &rest[close + 1..]);
    let dot = stamp.iter().position(|&b| b == b'.')?;
    let (secs, frac) = (&stamp[..dot], &stamp[dot + 1..]);
    if secs.is_empty() || secs.len() > 12 || frac.is_empty() || frac.len() > 9 {
        return None;
    }
    let mut seconds = 0u64;
    for &b in secs {
        seconds = seconds * 10 + u64::from(b.checked_sub(b'0').filter(|d| *d <= 9)?);
    }
    let mut micros = 0u64;
    for i in 0..6 {
        let digit = match frac.get(i) {
            Some(&b) => u64::from(b.checked_sub(b'0').filter(|d| *d <= 9)?),
            None => 0,
        };
        micros = micros * 10 + digit;
    }
    if !frac.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let rest = rest.strip_prefix(b" ")?;
    let space = rest.iter().position(|&b| b == b' ')?;
    let (name, frame) = (&rest[..space], &rest[space + 1..]);
    if name.is_empty() || !name.iter().all(u8::is_ascii_graphic) {
        return None;
    }
    let [a, b, c, b'#', data @ ..] = frame else { return None };
    let raw = u16::from(hex_value(*a)?) << 8 | u16::from(hex_value(*b)?) << 4 | u16::from(hex_value(*c)?);
    if raw > 0x7FF || data.len() % 2 != 0 || data.len() > 16 {
        return None;
    }
    let mut bytes = [0u8; 8];
    for (i, pair) in data.chunks_exact(2).enumerate() {
        bytes[i] = hex_value(pair[0])? << 4 | hex_value(pair[1])?;
    }
    let frame = CanFrame::from_raw(raw, &bytes[..data.len() / 2]).ok()?;
    Some((Instant::from_micros(seconds * 1_000_000 + micros), name, frame))
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        #[test]
        fn the_fast_path_agrees_with_the_line_parser(line in "\\(([0-9]{1,3}|x)\\.[0-9]{0,10}\\) [a-z0-9]{0,3} [0-9A-Fa-f]{2,4}#[0-9A-F.R#]{0,18}") {
            if let Some((at, name, frame)) = fast_line(line.as_bytes()) {
                let entry = parse_line(&line, 1).expect("what the fast path reads, the parser reads");
                proptest::prop_assert_eq!((at, name, frame), (entry.at, entry.iface.as_bytes(), entry.frame));
            }
        }
    }

    #[test]
    fn the_fast_path_reads_canonical_lines_and_leaves_the_rest() {
        let (at, name, frame) = fast_line(b"(1436509052.249713) can0 42B#00CB00").unwrap();
        assert_eq!(
            (at.total_micros(), name, frame.to_string()),
            (1_436_509_052_249_713, &b"can0"[..], "42B#00CB00".into())
        );
        assert_eq!(
            fast_line(b"(0.5) sim 7FF#").map(|(at, _, f)| (at.total_micros(), f.dlc())),
            Some((500_000, 0))
        );
        for other in [
            "(0.1) can0 42B#0",
            "(0.1) can0 12345678#00",
            "(0.1) can0 42B#R",
            "(0.1) can0 42B#00 x",
            "(0.1)  can0 42B#00",
            "(.1) can0 42B#00",
            "(0.1) can0 800#00",
        ] {
            assert!(fast_line(other.as_bytes()).is_none(), "{other}");
        }
    }
}
