//! The Vector `.asc` (ASCII logging) reader of [`super::read_trace`].
//!
//! Sources: Vector's "CAN, Log & Trigger ASC Logging Format" specification as summarised in public
//! pages (its header grammar, `timestamps absolute|relative`, the CAN, remote, error-frame and
//! CAN FD event lines, the `Length =`/`BitCount =`/`ID =` fields of version 1.2.x), and python-can
//! 4.6.1's `can/io/asc.py` (reader and writer) with its test files. What none of them confirms is
//! marked UNCONFIRMED.
//!
//! ## What is read
//!
//! ```text
//! date Mon Jan 05 14:20:33.123 2026          header, ignored
//! base hex  timestamps absolute              base of IDs, DLCs and data: hex or dec
//! internal events logged                     ignored
//! // version 9.0.0                           comments: ignored
//! Begin Triggerblock Mon Jan 05 ...          ignored
//!    0.000000 Start of measurement           ignored (a marker of the format)
//!    5.001124 1  42B             Rx   d 3 00 CB 00  Length = 111000 BitCount = 57 ID = 1067
//! End TriggerBlock                           ignored
//! ```
//!
//! A CAN event is `time channel ID dir d DLC data...`: the identifier ends in `x` when extended, `dir`
//! is `Rx` or `Tx`, `d` marks a data frame (`r` a remote frame), and fields after the data bytes
//! (`Length = ...`, `BitCount = ...`, `ID = ...`) are accepted. Where the identifier column holds a
//! symbolic message name, the `ID = n` field gives the identifier. With `base dec` the identifier,
//! DLC and data bytes are decimal.
//!
//! ## Time
//!
//! A frame's time is the event's time stamp, in seconds from the start of the measurement, kept to
//! the microsecond (Vector writes 6 decimals; older files 4). With `timestamps relative` each time
//! stamp counts from the previous event, as the specification describes; python-can ignores this
//! and reads them as absolute.
//!
//! ## Channels and direction
//!
//! The channel number is the entry's interface name; the direction is the event's `Rx`/`Tx`.
//!
//! ## Skipped, with the reason
//!
//! Error frames (`ErrorFrame`), remote frames, extended identifiers, every `CANFD` line (CAN FD
//! frames, and also the classic frames a CAN FD channel logs in that form: UNCONFIRMED whether a
//! DeviceNet recorder ever produces these), DLCs above 8, other events (statistics, chip status,
//! log and trigger events, environment and system variables, J1939), lines that follow no known
//! form, and a half-written last line. Header lines, comments and blank lines are not counted.

use super::entry::{LogEntry, LogError};
use super::{for_each_line, parse_scaled, standard_id, tokens, Direction, Sink};
use devicenet::{CanFrame, Instant};

/// The state the header and earlier events leave.
struct State {
    radix: u32,
    relative: bool,
    /// The time of the previous event, in µs (for `timestamps relative`).
    clock: u64,
}

/// Reads an asc trace into `sink`.
pub fn read(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let mut state = State { radix: 16, relative: false, clock: 0 };
    for_each_line(bytes, sink, |sink, line| {
        let trimmed = line.text.trim();
        let lead = line.text.len() - line.text.trim_start().len();
        match parse_line(&mut state, trimmed, line.number) {
            Ok(Some(entry)) => {
                sink.frame(entry);
                Ok(())
            }
            Ok(None) => Ok(()),
            Err((offset, reason)) if line.unterminated => sink.skip(
                line.number,
                lead + offset + 1,
                format!("half-written last line: {reason}"),
                line.text,
            ),
            Err((offset, reason)) => sink.skip(line.number, lead + offset + 1, reason, line.text),
        }
    })
}

/// A frame, nothing (a header line, a comment, a format marker), or (0-based offset, reason).
type Parsed = Result<Option<LogEntry>, (usize, String)>;

fn parse_line(state: &mut State, line: &str, number: usize) -> Parsed {
    if line.is_empty() || line.starts_with("//") {
        return Ok(None);
    }
    let tokens = tokens(line);
    let lower = |i: usize| tokens.get(i).map(|t| t.1.to_ascii_lowercase()).unwrap_or_default();
    match lower(0).as_str() {
        "date" => return Ok(None),
        "base" => {
            state.radix = match lower(1).as_str() {
                "hex" => 16,
                "dec" => 10,
                other => {
                    return Err((
                        tokens.get(1).map_or(0, |t| t.0),
                        format!("unknown base '{other}': hex or dec"),
                    ))
                }
            };
            state.relative = lower(3) == "relative";
            return Ok(None);
        }
        "begin" | "end" if lower(1) == "triggerblock" => return Ok(None),
        "internal" | "no" if line.to_ascii_lowercase().ends_with("events logged") => return Ok(None),
        _ => {}
    }
    let Some(&(_, stamp)) = tokens.first() else { return Ok(None) };
    let Some(micros) = parse_scaled(stamp, 6) else {
        return Err((0, format!("not an event line: expected a time stamp in seconds, found '{stamp}'")));
    };
    let at = if state.relative { state.clock.saturating_add(micros) } else { micros };
    state.clock = at;
    let at = Instant::from_micros(at);
    let Some(&(ch_col, channel)) = tokens.get(1) else {
        return Err((line.len(), "an event with nothing after its time stamp".into()));
    };
    if channel.eq_ignore_ascii_case("CANFD") {
        let error = tokens.get(4).is_some_and(|t| t.1.eq_ignore_ascii_case("ErrorFrame"));
        return Err(if error {
            (ch_col, "error frame (CAN FD ErrorFrame) is not DeviceNet traffic".into())
        } else {
            (ch_col, "CAN FD event (CANFD line) is not DeviceNet traffic".into())
        });
    }
    if line.get(ch_col..).is_some_and(|rest| rest.eq_ignore_ascii_case("Start of measurement")) {
        return Ok(None);
    }
    if channel.is_empty() || channel.len() > 3 || !channel.bytes().all(|b| b.is_ascii_digit()) {
        return Err((ch_col, format!("not a CAN frame: event '{}'", line.get(ch_col..).unwrap_or(channel))));
    }
    let Some(&(id_col, id_text)) = tokens.get(2) else {
        return Err((line.len(), "missing identifier after the channel".into()));
    };
    if id_text.eq_ignore_ascii_case("ErrorFrame") {
        return Err((id_col, "error frame (ErrorFrame) is not DeviceNet traffic".into()));
    }
    let Some(&(_, dir)) = tokens.get(3) else {
        return Err((line.len(), "missing direction (Rx or Tx)".into()));
    };
    let direction = if dir.eq_ignore_ascii_case("Rx") {
        Direction::Rx
    } else if dir.eq_ignore_ascii_case("Tx") {
        Direction::Tx
    } else {
        return Err((id_col, format!("not a CAN frame: event '{}'", line.get(ch_col..).unwrap_or(channel))));
    };
    let Some(&(kind_col, kind)) = tokens.get(4) else {
        return Err((line.len(), "missing frame kind ('d' data or 'r' remote)".into()));
    };
    match kind {
        "d" | "D" => {}
        "r" | "R" => return Err((kind_col, "remote frame is not DeviceNet traffic".into())),
        other => {
            return Err((
                kind_col,
                format!("unknown frame kind '{other}': expected 'd' (data) or 'r' (remote)"),
            ))
        }
    }
    let Some(&(dlc_col, dlc_text)) = tokens.get(5) else {
        return Err((line.len(), "missing data length code".into()));
    };
    let dlc = u32::from_str_radix(dlc_text, state.radix)
        .map_err(|_| (dlc_col, format!("invalid data length code '{dlc_text}'")))?;
    if dlc > 8 {
        return Err((dlc_col, format!("data length code {dlc}: more than 8 bytes is not DeviceNet traffic")));
    }
    let dlc = dlc as usize;
    let mut data = [0u8; 8];
    let mut rest = tokens.get(6..).unwrap_or_default();
    for slot in data.iter_mut().take(dlc) {
        let Some((&(col, byte), tail)) = rest.split_first() else {
            return Err((line.len(), format!("data length code {dlc} but fewer data bytes")));
        };
        *slot = u8::from_str_radix(byte, state.radix)
            .ok()
            .filter(|_| byte.len() <= if state.radix == 16 { 2 } else { 3 })
            .ok_or_else(|| (col, format!("invalid data byte '{byte}'")))?;
        rest = tail;
    }
    let id_field = extra_fields(rest, state.radix)?;
    let id = match (parse_id(id_text, id_col, state.radix), id_field) {
        (Err(_), Some(id)) => id,
        (column, _) => column?,
    };
    let frame = CanFrame::from_raw(id, &data[..dlc]).map_err(|e| (id_col, e.to_string()))?;
    Ok(Some(LogEntry {
        line: number,
        at,
        iface: channel.to_string().into(),
        frame,
        direction: Some(direction),
    }))
}

/// The identifier of the ID column (`42B`, `18EFC034x`).
fn parse_id(text: &str, col: usize, radix: u32) -> Result<u16, (usize, String)> {
    let (digits, extended) = match text.strip_suffix(['x', 'X']) {
        Some(d) => (d, true),
        None => (text, false),
    };
    let raw = u32::from_str_radix(digits, radix).map_err(|_| {
        (col, format!("invalid identifier '{text}' (a symbolic name without an 'ID =' field?)"))
    })?;
    standard_id(raw, extended).map_err(|reason| (col, reason))
}

/// The fields after the data bytes: `Length = n`, `BitCount = n`, `ID = n[x]`; the identifier of
/// an `ID =` field, read in the file's base (UNCONFIRMED: no source shows the field's base), used
/// only when the ID column is not a number (a symbolic name).
fn extra_fields(mut rest: &[(usize, &str)], radix: u32) -> Result<Option<u16>, (usize, String)> {
    let mut id = None;
    while let Some((&(col, name), tail)) = rest.split_first() {
        // `Length = 111000` or `Length=111000`.
        let (name, value, tail) = match name.split_once('=') {
            Some((n, v)) if !v.is_empty() => (n, Some((col + n.len() + 1, v)), tail),
            Some((n, _)) => (n, tail.first().copied(), tail.get(1..).unwrap_or_default()),
            None => match tail.split_first() {
                Some((&(_, "="), after)) => {
                    (name, after.first().copied(), after.get(1..).unwrap_or_default())
                }
                Some((&(c, eq), after)) if eq.starts_with('=') => (name, Some((c + 1, &eq[1..])), after),
                _ => return Err((col, format!("unexpected text '{name}' after the data bytes"))),
            },
        };
        let Some((value_col, value)) = value else {
            return Err((col, format!("field '{name}' has no value")));
        };
        match name {
            "Length" | "BitCount" => {}
            "ID" => id = Some(parse_id(value, value_col, radix)?),
            other => return Err((col, format!("unexpected field '{other}' after the data bytes"))),
        }
        rest = tail;
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::{parse_trace, ReadOptions, TraceFormat};
    use rstest::rstest;

    fn read(text: &str) -> crate::trace::Trace {
        let options = ReadOptions { strict: false, format: Some(TraceFormat::Asc) };
        parse_trace(text.as_bytes(), "t.asc", options).unwrap()
    }

    const HEAD: &str = "date Mon Jan 05 14:20:33.123 2026\nbase hex  timestamps absolute\ninternal events logged\n\
                        // version 9.0.0\nBegin Triggerblock Mon Jan 05 14:20:33.123 2026\n   0.000000 Start of measurement\n";

    #[rstest]
    #[case::plain("   5.001124 1  42B             Rx   d 3 00 CB 00", 0x42B, 5_001_124)]
    #[case::fields(
        "   5.001124 2  42B             Tx   d 3 00 CB 00  Length = 111000 BitCount = 57 ID = 42B",
        0x42B,
        5_001_124
    )]
    #[case::symbolic(
        "   5.001124 1  Response        Rx   d 3 00 CB 00  Length = 111000 BitCount = 57 ID = 42B",
        0x42B,
        5_001_124
    )]
    #[case::four_digits("   5.0011 1  42B Rx d 3 00 CB 00", 0x42B, 5_001_100)]
    fn frames(#[case] line: &str, #[case] id: u16, #[case] us: u64) {
        let t = read(&format!("{HEAD}{line}\nEnd TriggerBlock\n"));
        assert_eq!(t.skipped, vec![]);
        assert_eq!(t.entries.len(), 1);
        assert_eq!((t.entries[0].frame.id().as_raw(), t.entries[0].at.total_micros()), (id, us));
        assert_eq!(t.entries[0].frame.data(), &[0x00, 0xCB, 0x00]);
    }

    #[test]
    fn base_dec_and_relative_timestamps() {
        let t = read("base dec  timestamps relative\n   1.000000 1  1067  Rx   d 3 0 203 0\n   0.500000 1  1067  Tx   d 0\n");
        assert_eq!(t.skipped, vec![]);
        assert_eq!(t.entries[0].frame.data(), &[0x00, 0xCB, 0x00]);
        assert_eq!(t.entries[0].frame.id().as_raw(), 0x42B);
        assert_eq!(t.entries[1].at.total_micros(), 1_500_000);
        assert_eq!(t.entries[1].direction, Some(Direction::Tx));
    }

    #[rstest]
    #[case::error("   1.0 1  ErrorFrame", "error frame")]
    #[case::extended("   1.0 1  18EFC034x  Rx   d 1 00", "extended identifier")]
    #[case::remote("   1.0 1  100  Rx   r 3", "remote frame")]
    #[case::fd(
        "   1.0 CANFD   1 Rx   500  1 0 9 12 01 02 03 04 05 06 07 08 09 0A 0B 0C   0 0   1000 0 0 0 0 0",
        "CAN FD"
    )]
    #[case::statistic("   1.0 1  Statistic: D 0 R 0 XD 0 XR 0 E 0 O 0 B 0.00%", "not a CAN frame")]
    #[case::short("   1.0 1  42B Rx d 3 00 CB", "fewer data bytes")]
    #[case::junk("hello", "not an event line")]
    fn skips(#[case] line: &str, #[case] reason: &str) {
        let t = read(&format!("{HEAD}{line}\n"));
        assert_eq!(t.skipped_count, 1, "{:?}", t.skipped);
        assert!(t.skipped[0].reason.contains(reason), "{:?}", t.skipped);
    }
}
