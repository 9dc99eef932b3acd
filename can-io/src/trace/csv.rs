//! CSV traces: the layout `dnet-master --log FILE --format csv` writes, and the reader of
//! [`super::read_trace`], which also reads python-can's CSV and ZLG CANTest-style exports.
//!
//! ## The layout written (python-can's)
//!
//! What this project writes is exactly python-can's `CSVWriter` layout (python-can 4.6.1,
//! `can/io/csv.py`), so that `can.CSVReader` reads it back: a header line, then one line per frame,
//! lines ending in `\n`, no quoting.
//!
//! ```text
//! timestamp,arbitration_id,extended,remote,error,dlc,data
//! 5.001124,0x42b,0,0,0,3,AMsA
//! ```
//!
//! | column | content | example |
//! |---|---|---|
//! | `timestamp` | seconds from the start of the recording (the bus clock's origin), 6 decimals | `5.001124` |
//! | `arbitration_id` | the identifier, hex with `0x` (lower case, no padding) | `0x42b` |
//! | `extended` | `1` for a 29-bit identifier, else `0` (always `0` written) | `0` |
//! | `remote` | `1` for a remote frame (always `0` written) | `0` |
//! | `error` | `1` for an error frame (always `0` written) | `0` |
//! | `dlc` | the number of data bytes, 0 to 8 | `3` |
//! | `data` | the data bytes, base64 (RFC 4648, with padding); empty for no data | `AMsA` |
//!
//! The layout has no channel and no direction (python-can's has none); both are lost when writing
//! CSV, and read back as channel `1` and no direction.
//!
//! ## What is read
//!
//! The first line must be a header. Columns are found by their names, case-insensitively, ignoring
//! a parenthesised suffix (`帧ID(靠右对齐)`, `数据(HEX)`) and spaces or `_`:
//!
//! | meaning | header names |
//! |---|---|
//! | time | `timestamp`, `time`, `time stamp`, `时间标识`, `系统时间`, `时间` (the first present in this order) |
//! | identifier | `arbitration_id`, `id`, `can id`, `frame id`, `identifier`, `帧ID` |
//! | data | `data`, `data bytes`, `payload`, `数据` |
//! | data length | `dlc`, `length`, `len`, `data length`, `数据长度` (optional) |
//! | extended / remote / error flags | `extended`, `remote`, `error` (`1`/`true` set), optional |
//! | frame format and type | `format`, `type`, `frame format`, `frame type`, `帧格式`, `帧类型`: a value naming extended (`扩展帧`, `ext...`), remote (`远程帧`, `remote`, `rtr`), error (`错误`, `error`) or FD (`fd`) marks the row, optional |
//! | direction | `direction`, `dir`, `传输方向` (`Rx`/`接收`/`receive`, `Tx`/`发送`/`send`/`transmit`), optional |
//! | channel | `channel`, `ch`, `bus`, `通道`, optional (default `1`) |
//!
//! Other columns (`序号`/`index`, `名称`/`name`, ...) are ignored. The data is base64 when the
//! identifier column is named `arbitration_id` (python-can's layout), else hex bytes: `00 CB 00`,
//! `00CB00`, or ZLG's `x| 00 CB 00`. The identifier is hex, with or without `0x`. Times:
//!
//! | form | read as | source |
//! |---|---|---|
//! | `5.001124`, `1e-06` | seconds | python-can (`repr(float)`) |
//! | `14:20:33.123`, `15:07:39:123` | time of day, to the millisecond (or finer) | ZLG-style exports, e.g. `HH:mm:ss:fff` |
//! | `0x0012ab34` | the adapter's time stamp in units of 0.1 ms | UNCONFIRMED (ZLG's `VCI_CAN_OBJ.TimeStamp` "时间标识"; its unit is not in the sources found) |
//!
//! A time of day does not wrap at midnight (UNCONFIRMED how ZLG tools write one). ZLG tools on
//! Chinese Windows may write GBK text: such a file must be converted to UTF-8 first (e.g. `iconv -f
//! GBK -t UTF-8`); a header that is not UTF-8 is reported as such.
//!
//! Sources for the ZLG layout: a public tool that writes ZLG CANTest-style files with the header
//! `序号,传输方向,时间标识,名称,帧ID(靠右对齐),帧格式,帧类型,数据长度,数据(HEX)` and rows such as
//! `0,发送,15:07:39:123,,0x18DB33F1,数据帧,扩展帧,8,02 06 01 00 00 00 00 00`, and ZLG's `VCI_CAN_OBJ`
//! (fields `TimeStamp` 时间标识, `RemoteFlag` 是否是远程帧, `ExternFlag` 是否是扩展帧). Which of
//! 帧格式/帧类型 holds data/remote and which standard/extended differs between sources, so both are
//! read by their values. The English header `Index,Direction,Time,ID,Format,Type,DLC,Data` is read
//! by the same rules (UNCONFIRMED as an actual ZLG export).
//!
//! ## Skipped, with the line number and the reason
//!
//! Extended, remote, error and FD rows, identifiers above 0x7FF, bad data (not hex or base64, more
//! than 8 bytes, a DLC that disagrees with the bytes), bad times, and a half-written last line.

use super::entry::{LogEntry, LogError};
use super::{parse_scaled, standard_id, Direction, Sink};
use base64::Engine as _;
use devicenet::{CanFrame, Instant};

/// Where each meaning is in a row.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Columns {
    time: usize,
    id: usize,
    data: usize,
    base64: bool,
    dlc: Option<usize>,
    extended: Option<usize>,
    remote: Option<usize>,
    error: Option<usize>,
    kinds: Vec<usize>,
    direction: Option<usize>,
    channel: Option<usize>,
}

/// A header name reduced to compare: lower case, without a parenthesised suffix, spaces or `_`.
fn normalize(name: &str) -> String {
    let name = name.trim().trim_start_matches('\u{feff}');
    let name = name.split(['(', '（']).next().unwrap_or(name);
    name.chars().filter(|c| !c.is_whitespace() && *c != '_').flat_map(char::to_lowercase).collect()
}

fn map_header(names: &[String]) -> Option<Columns> {
    let find = |synonyms: &[&str]| synonyms.iter().find_map(|s| names.iter().position(|n| n == s));
    let time = find(&["timestamp", "time", "时间标识", "系统时间", "时间"])?;
    let id = find(&["arbitrationid", "id", "canid", "frameid", "identifier", "帧id"])?;
    let data = find(&["data", "databytes", "payload", "数据"])?;
    let kinds = names
        .iter()
        .enumerate()
        .filter(|(_, n)| {
            ["format", "type", "frameformat", "frametype", "帧格式", "帧类型"].contains(&n.as_str())
        })
        .map(|(i, _)| i)
        .collect();
    Some(Columns {
        time,
        id,
        data,
        base64: names.get(id).is_some_and(|n| n == "arbitrationid"),
        dlc: find(&["dlc", "length", "len", "datalength", "数据长度"]),
        extended: find(&["extended", "isextendedid"]),
        remote: find(&["remote", "isremoteframe"]),
        error: find(&["error", "iserrorframe"]),
        kinds,
        direction: find(&["direction", "dir", "传输方向"]),
        channel: find(&["channel", "ch", "bus", "通道"]),
    })
}

fn csv_reader(bytes: &[u8]) -> ::csv::Reader<&[u8]> {
    ::csv::ReaderBuilder::new().has_headers(false).flexible(true).from_reader(bytes)
}

fn header_of(record: &::csv::ByteRecord) -> Option<Columns> {
    let names: Vec<String> = record.iter().take(64).map(|f| normalize(&String::from_utf8_lossy(f))).collect();
    map_header(&names)
}

/// Whether a line is a CSV header this reader understands (it names a time, an identifier and a
/// data column).
pub fn is_header(line: &str) -> bool {
    let mut reader = csv_reader(line.as_bytes());
    let mut record = ::csv::ByteRecord::new();
    matches!(reader.read_byte_record(&mut record), Ok(true)) && header_of(&record).is_some()
}

/// Reads a csv trace into `sink`.
pub fn read(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let complete = bytes.last().is_none_or(|&b| b == b'\n');
    let mut reader = csv_reader(bytes);
    let mut records = reader.byte_records().peekable();
    let header = match records.next() {
        None => return Ok(()),
        Some(Err(e)) => return Err(sink.error(1, 1, format!("unreadable CSV header: {e}"), "")),
        Some(Ok(record)) => record,
    };
    let header_text = String::from_utf8_lossy(header.as_slice()).into_owned();
    let Some(columns) = header_of(&header) else {
        let reason = if header.iter().any(|f| std::str::from_utf8(f).is_err()) {
            "the CSV header is not UTF-8 text (convert a GBK export with iconv -f GBK -t UTF-8)"
        } else {
            "the CSV header names no time, identifier and data columns (see the csv format in the guide, docs/src/reference/trace-formats.md)"
        };
        return Err(sink.error(1, 1, reason, &header_text));
    };
    while let Some(record) = records.next() {
        let last = records.peek().is_none();
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                let line = e.position().map_or(0, |p| p.line() as usize);
                sink.skip(line, 1, format!("unreadable CSV row: {e}"), "")?;
                continue;
            }
        };
        let line = record.position().map_or(0, |p| p.line() as usize);
        let fields: Vec<&str> = match record.iter().take(64).map(std::str::from_utf8).collect() {
            Ok(fields) => fields,
            Err(_) => {
                let text = String::from_utf8_lossy(record.as_slice()).into_owned();
                sink.skip(line, 1, "the row is not UTF-8 text", &text)?;
                continue;
            }
        };
        if fields.iter().all(|f| f.trim().is_empty()) {
            continue;
        }
        let text = fields.join(",");
        match parse_row(&columns, &fields, line) {
            Ok(entry) => sink.frame(entry),
            Err((field, reason)) => {
                // The column of the field, exact for unquoted fields.
                let column = fields.iter().take(field).map(|f| f.len() + 1).sum::<usize>() + 1;
                if last && !complete {
                    sink.skip(line, column, format!("half-written last line: {reason}"), &text)?;
                } else {
                    sink.skip(line, column, reason, &text)?;
                }
            }
        }
    }
    Ok(())
}

fn flag(fields: &[&str], column: Option<usize>) -> bool {
    column
        .and_then(|c| fields.get(c))
        .is_some_and(|v| matches!(v.trim().to_ascii_lowercase().as_str(), "1" | "true" | "yes"))
}

/// A row as an entry, or (0-based field index, reason).
fn parse_row(columns: &Columns, fields: &[&str], line: usize) -> Result<LogEntry, (usize, String)> {
    let get =
        |i: usize| fields.get(i).map(|f| f.trim()).ok_or((fields.len(), format!("missing column {}", i + 1)));
    for &k in &columns.kinds {
        let value = fields.get(k).map(|f| f.trim().to_lowercase()).unwrap_or_default();
        if value.contains("错误") || value.contains("error") {
            return Err((k, format!("error frame ('{value}') is not DeviceNet traffic")));
        }
        if value.contains("远程") || value.contains("remote") || value.contains("rtr") {
            return Err((k, format!("remote frame ('{value}') is not DeviceNet traffic")));
        }
        if value.contains("扩展") || value.starts_with("ext") {
            return Err((
                k,
                format!("extended frame ('{value}') is not DeviceNet traffic (11-bit identifiers only)"),
            ));
        }
        if value.contains("fd") {
            return Err((k, format!("CAN FD frame ('{value}') is not DeviceNet traffic")));
        }
    }
    if flag(fields, columns.error) {
        return Err((columns.error.unwrap_or(0), "error frame (error = 1) is not DeviceNet traffic".into()));
    }
    if flag(fields, columns.remote) {
        return Err((
            columns.remote.unwrap_or(0),
            "remote frame (remote = 1) is not DeviceNet traffic".into(),
        ));
    }
    let at = parse_time(get(columns.time)?).map_err(|r| (columns.time, r))?;
    let id_text = get(columns.id)?;
    let digits = id_text.strip_prefix("0x").or_else(|| id_text.strip_prefix("0X")).unwrap_or(id_text);
    if digits.is_empty() || digits.len() > 8 || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err((columns.id, format!("invalid identifier '{id_text}': expected hex")));
    }
    let raw = u32::from_str_radix(digits, 16)
        .map_err(|_| (columns.id, format!("invalid identifier '{id_text}'")))?;
    let id = standard_id(raw, flag(fields, columns.extended)).map_err(|r| (columns.id, r))?;
    let data_text = get(columns.data)?;
    let data = if columns.base64 { parse_base64(data_text) } else { parse_hex(data_text) }
        .map_err(|r| (columns.data, r))?;
    if let Some(c) = columns.dlc {
        let text = get(c)?;
        let dlc: usize = text.parse().map_err(|_| (c, format!("invalid data length '{text}'")))?;
        if dlc != data.len() {
            return Err((c, format!("data length {dlc} but {} data bytes", data.len())));
        }
    }
    let frame = CanFrame::from_raw(id, &data).map_err(|e| (columns.data, e.to_string()))?;
    let direction = match columns.direction {
        None => None,
        Some(c) => parse_direction(get(c)?).map_err(|r| (c, r))?,
    };
    let iface = match columns.channel.map(get).transpose()? {
        Some(ch) if !ch.is_empty() => ch.chars().take(32).collect(),
        _ => "1".to_string(),
    };
    Ok(LogEntry { line, at: Instant::from_micros(at), iface: iface.into(), frame, direction })
}

fn parse_direction(text: &str) -> Result<Option<Direction>, String> {
    Ok(match text.to_lowercase().as_str() {
        "" => None,
        "rx" | "r" | "receive" | "received" | "接收" => Some(Direction::Rx),
        "tx" | "t" | "send" | "sent" | "transmit" | "发送" => Some(Direction::Tx),
        other => return Err(format!("unknown direction '{other}': expected Rx or Tx (接收 or 发送)")),
    })
}

/// Microseconds from a time column (see the module docs for the forms).
fn parse_time(text: &str) -> Result<u64, String> {
    let bad = || {
        format!("invalid time '{text}': expected seconds (5.001124), a time of day (14:20:33.123) or 0x hex")
    };
    if let Some(hex) = text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        if hex.is_empty() || hex.len() > 16 {
            return Err(bad());
        }
        let ticks = u64::from_str_radix(hex, 16).map_err(|_| bad())?;
        return ticks.checked_mul(100).ok_or_else(bad);
    }
    if text.contains(':') {
        let parts: Vec<&str> = text.splitn(4, ':').collect();
        let (h, m, s) = match parts.as_slice() {
            [h, m, s] => (*h, *m, parse_scaled(s, 6)),
            // HH:mm:ss:fff, milliseconds after a colon.
            [h, m, s, ms] if ms.len() == 3 => (
                *h,
                *m,
                parse_scaled(s, 0)
                    .zip(parse_scaled(ms, 0))
                    .and_then(|(s, ms)| s.checked_mul(1_000_000)?.checked_add(ms * 1000)),
            ),
            _ => return Err(bad()),
        };
        let h = parse_scaled(h, 0).filter(|&h| h < 24).ok_or_else(bad)?;
        let m = parse_scaled(m, 0).filter(|&m| m < 60).ok_or_else(bad)?;
        let s = s.filter(|&s| s < 61_000_000).ok_or_else(bad)?;
        return Ok((h * 60 + m) * 60_000_000 + s);
    }
    if let Some(us) = parse_scaled(text, 6) {
        return Ok(us);
    }
    // python-can writes repr(float): small values in exponent form (`5e-05`).
    let seconds: f64 = text.parse().map_err(|_| bad())?;
    if !seconds.is_finite() || !(0.0..1.0e12).contains(&seconds) {
        return Err(bad());
    }
    Ok((seconds * 1e6).round() as u64)
}

fn parse_hex(text: &str) -> Result<Vec<u8>, String> {
    let text = text.strip_prefix("x|").unwrap_or(text).trim();
    let mut bytes = Vec::new();
    for token in text.split_whitespace() {
        let token = token.strip_prefix("0x").unwrap_or(token);
        if token.len() % 2 != 0 || !token.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(format!("invalid data '{text}': expected hex bytes (00 CB 00)"));
        }
        for i in (0..token.len()).step_by(2) {
            if bytes.len() == 8 {
                return Err(format!("more than 8 data bytes in '{text}': not a classic CAN frame"));
            }
            let byte = token.get(i..i + 2).and_then(|b| u8::from_str_radix(b, 16).ok());
            bytes.push(byte.ok_or_else(|| format!("invalid data '{text}'"))?);
        }
    }
    Ok(bytes)
}

fn parse_base64(text: &str) -> Result<Vec<u8>, String> {
    // 8 bytes are 12 base64 characters; anything longer cannot be a classic frame.
    if text.len() > 12 {
        return Err(format!("more than 8 data bytes in '{text}': not a classic CAN frame"));
    }
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(text)
        .map_err(|e| format!("invalid base64 data '{text}': {e}"))?;
    if bytes.len() > 8 {
        return Err(format!("{} data bytes, a CAN frame holds at most 8", bytes.len()));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::{parse_trace, ReadOptions, TraceFormat};
    use rstest::rstest;

    fn read(text: &str) -> crate::trace::Trace {
        let options = ReadOptions { strict: false, format: Some(TraceFormat::Csv) };
        parse_trace(text.as_bytes(), "t.csv", options).unwrap()
    }

    #[rstest]
    #[case::python_can("timestamp,arbitration_id,extended,remote,error,dlc,data", true)]
    #[case::zlg("序号,传输方向,时间标识,名称,帧ID(靠右对齐),帧格式,帧类型,数据长度,数据(HEX)", true)]
    #[case::zlg_short("序号,传输方向,时间标识,帧ID,帧格式,帧类型,数据长度,数据", true)]
    #[case::english("Index,Direction,Time,ID,Format,Type,DLC,Data", true)]
    #[case::no_data("timestamp,arbitration_id", false)]
    #[case::prose("time flies, data sleeps", false)]
    fn headers(#[case] line: &str, #[case] header: bool) {
        assert_eq!(is_header(line), header);
    }

    #[test]
    fn python_can_rows() {
        let t = read("timestamp,arbitration_id,extended,remote,error,dlc,data\n5.001124,0x42b,0,0,0,3,AMsA\n5e-05,0x407,0,0,0,0,\n");
        assert_eq!(t.skipped, vec![]);
        assert_eq!(t.entries[0].at.total_micros(), 5_001_124);
        assert_eq!(t.entries[0].frame.data(), &[0x00, 0xCB, 0x00]);
        assert_eq!(t.entries[1].at.total_micros(), 50);
    }

    #[test]
    fn zlg_rows() {
        let t = read(
            "序号,传输方向,时间标识,名称,帧ID(靠右对齐),帧格式,帧类型,数据长度,数据(HEX)\n\
             0,接收,15:07:39:123,,0x0000042B,数据帧,标准帧,3,x| 00 CB 00\n\
             1,发送,0x0012ab34,,0x42C,数据帧,标准帧,2,00 0E\n\
             2,发送,15:07:39:125,,0x18DB33F1,数据帧,扩展帧,8,02 06 01 00 00 00 00 00\n",
        );
        assert_eq!(t.entries.len(), 2);
        assert_eq!(t.entries[0].at.total_micros(), ((15 * 60 + 7) * 60 + 39) * 1_000_000 + 123_000);
        assert_eq!(t.entries[0].direction, Some(Direction::Rx));
        assert_eq!(t.entries[1].at.total_micros(), 0x0012_ab34 * 100);
        assert!(t.skipped[0].reason.contains("extended"), "{:?}", t.skipped);
        assert_eq!(t.skipped[0].line, 4);
    }

    #[rstest]
    #[case::remote("1.0,0x42b,0,1,0,3,", "remote")]
    #[case::error("1.0,0x20000080,0,0,1,8,AAAAAAAAAAA=", "error frame")]
    #[case::extended("1.0,0x18db33f1,1,0,0,1,AA==", "extended")]
    #[case::bad_data("1.0,0x42b,0,0,0,1,!!", "invalid base64")]
    #[case::dlc("1.0,0x42b,0,0,0,2,AA==", "data length 2 but 1")]
    #[case::time("soon,0x42b,0,0,0,1,AA==", "invalid time")]
    fn python_can_skips(#[case] row: &str, #[case] reason: &str) {
        let t = read(&format!("timestamp,arbitration_id,extended,remote,error,dlc,data\n{row}\n"));
        assert_eq!(t.skipped_count, 1);
        assert!(t.skipped[0].reason.contains(reason), "{:?}", t.skipped);
        assert_eq!(t.skipped[0].line, 2);
    }
}
