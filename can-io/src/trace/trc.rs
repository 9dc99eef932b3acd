//! The PCAN-View / PCAN-Explorer `.trc` reader of [`super::read_trace`], file versions 1.0 to 2.1.
//!
//! Sources: PEAK-System's "PEAK CAN TRC File Format" (the examples of every version, 2016 and 2020
//! editions), PEAK's forum note on the header (`;$STARTTIME` is days since 30 December 1899 with the
//! fraction of the day), and python-can 4.6.1's `can/io/trc.py` (reader and writer) with its test
//! files. What none of them confirms is marked UNCONFIRMED.
//!
//! ## Layouts
//!
//! | version | how it is told | columns of a message line |
//! |---|---|---|
//! | 1.0 | no `;$FILEVERSION` line | `N)` offset(ms, integer) ID DLC data |
//! | 1.1 | `;$FILEVERSION=1.1` | `N)` offset(ms, 0.1 ms) type ID DLC data |
//! | 1.2 | `;$FILEVERSION=1.2` | `N)` offset(ms, 1 µs) bus type ID DLC data |
//! | 1.3 | `;$FILEVERSION=1.3` | `N)` offset bus type ID reserved(`-`) DLC data |
//! | 2.0, 2.1 | `;$FILEVERSION=2.x` | as named by `;$COLUMNS=` (`N,O,T,B,I,d,R,L,l,D`) |
//!
//! A file with no `;$FILEVERSION` line is read by its `;` column description: a description naming
//! a `Type` column is 1.1, with a `Bus` column too 1.2, with a `Reserved` column too 1.3; none of
//! them (or no description at all, as python-can's 1.0 writer and PEAK's 1.0 example) is 1.0. A 2.x
//! file without `;$COLUMNS` is read with the columns of PEAK's examples (2.0: `N,O,T,I,d,l,D`, 2.1:
//! `N,O,T,B,I,d,R,L,D`) (a decision: PEAK requires the line).
//!
//! ## Time
//!
//! A frame's time is its time offset, in milliseconds from the start of the trace, kept exactly to
//! the microsecond (1.0: 1 ms, 1.1: 0.1 ms, 1.2 and later: 1 µs; more digits are truncated).
//! `;$STARTTIME` is not added (a decision): it is a floating-point day count whose ten decimals
//! resolve some 9 µs, so adding it would blur the exact offsets, and `decode`/`replay` need only the
//! relative times.
//!
//! ## Channels and direction
//!
//! The bus number (1.2, 1.3, 2.x with a `B` column) is the entry's interface name; without one it is
//! `1`. The direction is the type (1.1 to 1.3: `Rx`/`Tx`) or the `d` column (2.x); 1.0 has none.
//!
//! ## Skipped, with the reason
//!
//! Error frames (1.0 `ERROR` data, 1.x type `Error`, 2.x type `ER`), error warnings and hardware
//! status (ID `FFFFFFFF`, type `Warng`, 2.x `ST`), error counter changes (`EC`), events (`EV`),
//! remote frames (`RTR` data, 2.x `RR`), CAN FD frames (`FD`, `FB`, `FE`, `BI`), extended
//! identifiers (more than 4 hex digits, as python-can decides; PEAK writes 8), lines that do not
//! follow the layout, and a half-written last line. Comment lines (`;`) and blank lines are neither
//! frames nor skipped.

use super::entry::{LogEntry, LogError};
use super::{for_each_line, parse_scaled, standard_id, tokens, Direction, Sink, TextLine};
use devicenet::{CanFrame, Instant};

/// The column layout of a file version.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Layout {
    V1_0,
    V1_1,
    V1_2,
    V1_3,
    /// Version 2.x with its `;$COLUMNS` letters.
    V2(Vec<char>),
}

/// Whether `token` is a version 1.x message number, `123)`.
pub(crate) fn is_message_number(token: &str) -> bool {
    token.strip_suffix(')').is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// Reads a trc trace into `sink`.
pub fn read(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let layout = header_layout(bytes, sink)?;
    for_each_line(bytes, sink, |sink, line| {
        let trimmed = line.text.trim();
        if trimmed.is_empty() || trimmed.starts_with(';') {
            return Ok(());
        }
        match parse_message(&layout, trimmed, line.number) {
            Ok(entry) => {
                sink.frame(entry);
                Ok(())
            }
            Err(Problem { column, reason }) => {
                let column = column_in(&line, trimmed, column);
                if line.unterminated {
                    sink.skip(line.number, column, format!("half-written last line: {reason}"), line.text)
                } else {
                    sink.skip(line.number, column, reason, line.text)
                }
            }
        }
    })
}

/// The 1-based column in the whole line of a 0-based byte offset in its trimmed part.
fn column_in(line: &TextLine<'_>, trimmed: &str, offset: usize) -> usize {
    let lead = line.text.len() - line.text.trim_start().len();
    debug_assert!(trimmed.len() <= line.text.len());
    lead + offset + 1
}

/// The layout from the leading `;` lines (the header).
fn header_layout(bytes: &[u8], sink: &mut Sink<'_>) -> Result<Layout, LogError> {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(64 * 1024)]);
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut version: Option<(usize, String)> = None;
    let mut columns: Option<Vec<char>> = None;
    let (mut has_type, mut has_bus, mut has_reserved) = (false, false, false);
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        let Some(comment) = line.strip_prefix(';') else { break };
        if let Some(v) = comment.strip_prefix("$FILEVERSION=") {
            version = Some((i + 1, v.trim().to_string()));
        } else if let Some(c) = comment.strip_prefix("$COLUMNS=") {
            columns = Some(c.split(',').filter_map(|c| c.trim().chars().next()).take(32).collect());
        } else {
            // A column description line: `;   |    |   +Type` or `;   |    |    Bus`.
            let body = comment.trim_start();
            if body.starts_with('|') || body.starts_with('+') {
                let words = body.trim_start_matches(['|', '+', '-', ' ']).to_ascii_lowercase();
                has_type |= words.starts_with("type");
                has_bus |= words.starts_with("bus");
                has_reserved |= words.starts_with("reserved");
            }
        }
    }
    let Some((line, version)) = version else {
        return Ok(match (has_type, has_bus, has_reserved) {
            (true, true, true) => Layout::V1_3,
            (true, true, false) => Layout::V1_2,
            (true, false, _) => Layout::V1_1,
            _ => Layout::V1_0,
        });
    };
    Ok(match version.as_str() {
        "1.0" => Layout::V1_0,
        "1.1" => Layout::V1_1,
        "1.2" => Layout::V1_2,
        "1.3" => Layout::V1_3,
        "2.0" => Layout::V2(columns.unwrap_or_else(|| "NOTIdlD".chars().collect())),
        "2.1" => Layout::V2(columns.unwrap_or_else(|| "NOTBIdRLD".chars().collect())),
        other => {
            return Err(sink.error(
                line,
                15,
                format!("trc file version '{other}' is not known (1.0, 1.1, 1.2, 1.3, 2.0, 2.1)"),
                &format!(";$FILEVERSION={other}"),
            ))
        }
    })
}

/// Why a message line is not a frame: 0-based byte offset in the trimmed line, and the reason.
#[derive(Debug)]
struct Problem {
    column: usize,
    reason: String,
}

fn problem(column: usize, reason: impl Into<String>) -> Problem {
    Problem { column, reason: reason.into() }
}

/// The pieces of a message line, whatever the version.
struct Fields<'a> {
    offset: (usize, &'a str),
    bus: Option<(usize, &'a str)>,
    direction: Option<(usize, &'a str)>,
    id: (usize, &'a str),
    dlc: (usize, &'a str),
    data: &'a [(usize, &'a str)],
}

fn parse_message(layout: &Layout, line: &str, number: usize) -> Result<LogEntry, Problem> {
    let tokens = tokens(line);
    let at = |i: usize| tokens.get(i).copied();
    let missing = |what: &str| problem(line.len(), format!("missing {what}"));
    let fields = match layout {
        Layout::V2(columns) => return parse_v2(columns, &tokens, line, number),
        v1 => {
            let (first_col, first) = at(0).ok_or_else(|| missing("message number"))?;
            if !is_message_number(first) {
                return Err(problem(first_col, format!("expected a message number 'N)', found '{first}'")));
            }
            let offset = at(1).ok_or_else(|| missing("time offset"))?;
            let mut next = 2;
            let mut take = |what: &str| {
                let t = at(next).ok_or_else(|| missing(what));
                next += 1;
                t
            };
            let bus = if matches!(v1, Layout::V1_2 | Layout::V1_3) { Some(take("bus")?) } else { None };
            let kind = if matches!(v1, Layout::V1_0) { None } else { Some(take("message type")?) };
            let id = take("identifier")?;
            if matches!(v1, Layout::V1_3) {
                take("reserved column")?;
            }
            let dlc = take("data length code")?;
            let data = tokens.get(next..).unwrap_or_default();
            if let Some((col, kind)) = kind {
                match kind {
                    "Rx" | "Tx" => {}
                    "Error" => return Err(problem(col, "error frame (type Error) is not DeviceNet traffic")),
                    "Warng" => {
                        return Err(problem(col, "error warning (type Warng): a bus status, not a frame"))
                    }
                    other => return Err(problem(col, format!("message type '{other}' is not a CAN frame"))),
                }
            }
            if id.1.eq_ignore_ascii_case("FFFFFFFF") {
                return Err(problem(id.0, "error warning (ID FFFFFFFF): a bus status, not a frame"));
            }
            if let Some(&(col, first)) = data.first() {
                if first == "ERROR" {
                    return Err(problem(col, "error frame (ERROR) is not DeviceNet traffic"));
                }
                if first == "RTR" {
                    return Err(problem(col, "remote frame (RTR) is not DeviceNet traffic"));
                }
            }
            Fields { offset, bus, direction: kind, id, dlc, data }
        }
    };
    let digits = if matches!(layout, Layout::V1_0) { 0 } else { 3 };
    build(fields, digits, number)
}

/// Builds the entry from the fields of a data frame.
fn build(f: Fields<'_>, digits: u32, number: usize) -> Result<LogEntry, Problem> {
    let micros =
        parse_scaled(f.offset.1, digits).and_then(|ms| ms.checked_mul(10u64.pow(3 - digits))).ok_or_else(
            || problem(f.offset.0, format!("invalid time offset '{}': expected milliseconds", f.offset.1)),
        )?;
    let (id_col, id) = f.id;
    if id.is_empty() || id.len() > 8 || !id.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(problem(id_col, format!("invalid identifier '{id}': expected 4 (or 8) hex digits")));
    }
    let raw =
        u32::from_str_radix(id, 16).map_err(|_| problem(id_col, format!("invalid identifier '{id}'")))?;
    let id = standard_id(raw, id.len() > 4).map_err(|reason| problem(id_col, reason))?;
    let (dlc_col, dlc_text) = f.dlc;
    let dlc: usize =
        dlc_text.parse().map_err(|_| problem(dlc_col, format!("invalid data length code '{dlc_text}'")))?;
    if dlc > 8 {
        return Err(problem(
            dlc_col,
            format!("data length {dlc}: more than 8 bytes is not a classic CAN frame"),
        ));
    }
    if f.data.len() < dlc {
        let col = f.data.last().map_or(dlc_col + dlc_text.len(), |&(c, t)| c + t.len());
        return Err(problem(col, format!("data length code {dlc} but {} data bytes", f.data.len())));
    }
    if let Some(&(col, extra)) = f.data.get(dlc) {
        return Err(problem(col, format!("unexpected text '{extra}' after {dlc} data bytes")));
    }
    let mut data = [0u8; 8];
    for (slot, &(col, byte)) in data.iter_mut().zip(f.data) {
        if byte.len() != 2 {
            return Err(problem(col, format!("invalid data byte '{byte}': expected 2 hex digits")));
        }
        *slot = u8::from_str_radix(byte, 16)
            .map_err(|_| problem(col, format!("invalid data byte '{byte}': expected 2 hex digits")))?;
    }
    let frame = CanFrame::from_raw(id, &data[..dlc]).map_err(|e| problem(id_col, e.to_string()))?;
    let direction = match f.direction {
        None => None,
        Some((_, "Rx")) => Some(Direction::Rx),
        Some((_, "Tx")) => Some(Direction::Tx),
        Some((col, other)) => {
            return Err(problem(col, format!("invalid direction '{other}': expected Rx or Tx")))
        }
    };
    let iface = match f.bus {
        None => "1".to_string(),
        Some((_, bus)) if !bus.is_empty() && bus.len() <= 3 && bus.bytes().all(|b| b.is_ascii_digit()) => {
            bus.to_string()
        }
        Some((col, bus)) => return Err(problem(col, format!("invalid bus '{bus}': expected a number"))),
    };
    Ok(LogEntry { line: number, at: Instant::from_micros(micros), iface: iface.into(), frame, direction })
}

fn parse_v2(
    columns: &[char],
    tokens: &[(usize, &str)],
    line: &str,
    number: usize,
) -> Result<LogEntry, Problem> {
    let index = |c: char| columns.iter().position(|&x| x == c);
    let missing = |what: &str| problem(line.len(), format!("missing {what}"));
    let Some(t) = index('T') else {
        return Err(problem(0, "the ;$COLUMNS line names no type column (T)"));
    };
    let (type_col, kind) = tokens.get(t).copied().ok_or_else(|| missing("message type"))?;
    match kind {
        "DT" => {}
        "RR" => return Err(problem(type_col, "remote frame (type RR) is not DeviceNet traffic")),
        "FD" | "FB" | "FE" | "BI" => {
            return Err(problem(type_col, format!("CAN FD frame (type {kind}) is not DeviceNet traffic")))
        }
        "ER" => return Err(problem(type_col, "error frame (type ER) is not DeviceNet traffic")),
        "ST" => return Err(problem(type_col, "hardware status (type ST), not a frame")),
        "EC" => return Err(problem(type_col, "error counter change (type EC), not a frame")),
        "EV" => return Err(problem(type_col, "event (type EV), not a frame")),
        other => return Err(problem(type_col, format!("message type '{other}' is not a CAN frame"))),
    }
    let field = |c: char, what: &str| -> Result<Option<(usize, &str)>, Problem> {
        match index(c) {
            None => Ok(None),
            Some(i) => tokens.get(i).copied().map(Some).ok_or_else(|| missing(what)),
        }
    };
    let offset = field('O', "time offset")?
        .ok_or_else(|| problem(0, "the ;$COLUMNS line names no time offset column (O)"))?;
    let id = field('I', "identifier")?
        .ok_or_else(|| problem(0, "the ;$COLUMNS line names no identifier column (I)"))?;
    let dlc = match field('L', "data length code")? {
        Some(l) => l,
        None => field('l', "data length")?
            .ok_or_else(|| problem(0, "the ;$COLUMNS line names no length column (L or l)"))?,
    };
    let data = match index('D') {
        Some(i) if i + 1 == columns.len() => tokens.get(i..).unwrap_or_default(),
        Some(_) => return Err(problem(0, "the data column (D) is not the last of ;$COLUMNS")),
        None => &[],
    };
    let fields =
        Fields { offset, bus: field('B', "bus")?, direction: field('d', "direction")?, id, dlc, data };
    build(fields, 3, number)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::{parse_trace, ReadOptions, TraceFormat};
    use rstest::rstest;

    fn read(text: &str) -> crate::trace::Trace {
        let options = ReadOptions { strict: false, format: Some(TraceFormat::Trc) };
        parse_trace(text.as_bytes(), "t.trc", options).unwrap()
    }

    #[rstest]
    #[case::v1_0("     1)      1841      0001  8  00 00 00 00 00 00 00 00\n", 1_841_000, None, "1")]
    #[case::v1_1(
        ";$FILEVERSION=1.1\n     1)      1059.9  Rx         0300  7  00 00 00 00 04 00 00\n",
        1_059_900,
        Some(Direction::Rx),
        "1"
    )]
    #[case::v1_2(
        ";$FILEVERSION=1.2\n     2)      1283.231  2  Tx         0300  7  00 00 00 00 04 00 00\n",
        1_283_231,
        Some(Direction::Tx),
        "2"
    )]
    #[case::v1_3(
        ";$FILEVERSION=1.3\n     1)      1059.900 1  Rx        0300 -  7    00 00 00 00 04 00 00\n",
        1_059_900,
        Some(Direction::Rx),
        "1"
    )]
    #[case::v2_0(";$FILEVERSION=2.0\n;$COLUMNS=N,O,T,I,d,l,D\n      1      1059.900 DT     0300 Rx 7  00 00 00 00 04 00 00\n", 1_059_900, Some(Direction::Rx), "1")]
    #[case::v2_1(";$FILEVERSION=2.1\n;$COLUMNS=N,O,T,B,I,d,R,L,D\n      1      1059.900 DT 3      0300 Rx -  7    00 00 00 00 04 00 00\n", 1_059_900, Some(Direction::Rx), "3")]
    fn every_version(#[case] text: &str, #[case] us: u64, #[case] dir: Option<Direction>, #[case] bus: &str) {
        let t = read(text);
        assert_eq!(t.skipped, vec![]);
        assert_eq!(t.entries.len(), 1);
        let e = &t.entries[0];
        assert_eq!((e.at.total_micros(), e.direction, e.iface.as_ref()), (us, dir, bus));
        assert_eq!(e.frame.id().as_raw(), if text.contains("0001") { 1 } else { 0x300 });
    }

    #[rstest]
    #[case::v1_error("     2)      1842      0008  4  ERROR 00 19 08 08", "error frame")]
    #[case::v1_warning("     3)      1843  FFFFFFFF  4  00 00 00 04 -- -- -- --  BUSLIGHT", "error warning")]
    #[case::v1_rtr("     4)      1844      0100  3  RTR", "remote frame")]
    #[case::v1_extended("     5)      1845  18EFC034  1  00", "extended identifier")]
    #[case::v1_short("     6)      1846      0100  3  00 01", "data length code 3 but 2")]
    fn v1_0_skips(#[case] line: &str, #[case] reason: &str) {
        let t = read(&format!("{line}\n"));
        assert_eq!(t.skipped_count, 1);
        assert!(t.skipped[0].reason.contains(reason), "{:?}", t.skipped);
    }

    #[rstest]
    #[case::fd("      5      1334.416 FD     0500 Tx 12 01 02 03 04 05 06 07 08 09 0A 0B 0C", "CAN FD")]
    #[case::er("      6      1334.522 ER          Rx    04 00 02 00 00", "error frame")]
    #[case::st("      7      1334.531 ST          Rx    00 00 00 08", "hardware status")]
    #[case::ec("      8      1334.643 EC          Rx    02 02", "error counter")]
    #[case::ext("      9      1335.156 DT 18EFC034 Tx 8  01 02 03 04 05 06 07 08", "extended identifier")]
    #[case::rr("     10      1336.543 RR     0100 Rx 3", "remote frame")]
    fn v2_0_skips(#[case] line: &str, #[case] reason: &str) {
        let t = read(&format!(";$FILEVERSION=2.0\n;$COLUMNS=N,O,T,I,d,l,D\n{line}\n"));
        assert_eq!(t.skipped_count, 1);
        assert!(t.skipped[0].reason.contains(reason), "{:?}", t.skipped);
    }

    #[test]
    fn layout_from_the_column_description() {
        let text = ";   Message Number\n;   |         Time Offset (ms)\n;   |         |        Type\n\
                    ;   |         |        |        ID (hex)\n     1)      1059.9  Rx         0300  0\n";
        assert_eq!(read(text).entries.len(), 1);
    }

    #[test]
    fn unknown_version_is_an_error() {
        let options = ReadOptions { strict: false, format: Some(TraceFormat::Trc) };
        let err = parse_trace(b";$FILEVERSION=9.9\n", "t.trc", options).unwrap_err();
        assert!(err.reason.contains("9.9"), "{err}");
    }
}
