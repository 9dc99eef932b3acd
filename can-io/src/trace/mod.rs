//! Trace files of every format test engineers record DeviceNet traffic in, read by `decode` and
//! `replay`, and the text formats written by `--log FILE` (`dnet-master`, `dnet-soft-slave`): the
//! format given with `--format`, else the one the file's extension names, else candump
//! ([`write::log_format`]).
//!
//! | format | [`TraceFormat`] | read | write | detected by |
//! |---|---|---|---|---|
//! | can-utils `candump -L` | `Candump` | yes | yes (`--log`) | `(seconds.micros) iface ID#DATA` lines |
//! | pcap (link type 227, SocketCAN) | `Pcap` | yes | yes (`--pcap`) | magic `A1B2C3D4`/`A1B23C4D` either byte order |
//! | pcapng (SocketCAN interfaces) | `Pcapng` | yes | no | section header block `0A0D0D0A` |
//! | PCAN-View `.trc` 1.x and 2.x | `Trc` | yes | yes (2.1) | `;$FILEVERSION=` header, else `;` comment header with message columns |
//! | Vector `.asc` | `Asc` | yes | yes | `date ...` / `base hex` header lines |
//! | Vector `.blf` | `Blf` | yes | no | magic `LOGG` |
//! | CSV (documented in `trace::csv`) | `Csv` | yes | yes | a header line naming a time, an ID and a data column |
//!
//! Every reader feeds a [`Sink`]: frames go in as [`LogEntry`]s; what is not DeviceNet traffic (an
//! error frame, an extended, remote or FD frame, a comment the format does not define, a
//! half-written last line) is [`Sink::skip`]ped with its location and reason. With
//! [`ReadOptions::strict`] the first skip is an error instead. A reader never panics on any input,
//! and keeps at most [`NAMED_SKIPS`] skipped lines' details (all are counted).

use entry::{LogEntry, LogError};
use std::fmt;
use std::path::Path;

pub mod asc;
pub mod blf;
pub mod candump;
pub mod csv;
pub mod entry;
pub mod pcapfile;
pub mod trc;
pub mod write;

/// How many skipped lines a [`Trace`] names (the rest are only counted).
pub const NAMED_SKIPS: usize = 10;

/// A trace file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TraceFormat {
    /// can-utils `candump -L` log lines.
    Candump,
    /// Classic pcap, link type 227 (SocketCAN).
    Pcap,
    /// pcapng with SocketCAN interfaces.
    Pcapng,
    /// PCAN-View `.trc`, file versions 1.0-1.3 and 2.0-2.1.
    Trc,
    /// Vector `.asc` (ASCII logging).
    Asc,
    /// Vector `.blf` (binary logging).
    Blf,
    /// Comma-separated values (see [`csv`]).
    Csv,
}

impl TraceFormat {
    /// Every format, in the order of the table above.
    pub const ALL: [TraceFormat; 7] = [
        TraceFormat::Candump,
        TraceFormat::Pcap,
        TraceFormat::Pcapng,
        TraceFormat::Trc,
        TraceFormat::Asc,
        TraceFormat::Blf,
        TraceFormat::Csv,
    ];

    /// The name used on the command line (`--format`, `--input-format`).
    pub fn name(self) -> &'static str {
        match self {
            TraceFormat::Candump => "candump",
            TraceFormat::Pcap => "pcap",
            TraceFormat::Pcapng => "pcapng",
            TraceFormat::Trc => "trc",
            TraceFormat::Asc => "asc",
            TraceFormat::Blf => "blf",
            TraceFormat::Csv => "csv",
        }
    }

    /// The format with this command-line name.
    pub fn from_name(name: &str) -> Option<TraceFormat> {
        TraceFormat::ALL.into_iter().find(|f| f.name().eq_ignore_ascii_case(name))
    }

    /// The text formats `--format` writes (see [`write`](mod@write)).
    pub fn writable(self) -> bool {
        matches!(self, TraceFormat::Candump | TraceFormat::Trc | TraceFormat::Asc | TraceFormat::Csv)
    }

    /// The format a file name's extension suggests (used only when the content does not tell).
    pub fn from_extension(path: &Path) -> Option<TraceFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "log" | "candump" => TraceFormat::Candump,
            "pcap" | "cap" => TraceFormat::Pcap,
            "pcapng" => TraceFormat::Pcapng,
            "trc" => TraceFormat::Trc,
            "asc" => TraceFormat::Asc,
            "blf" => TraceFormat::Blf,
            "csv" => TraceFormat::Csv,
            _ => return None,
        })
    }
}

impl fmt::Display for TraceFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The direction a frame travelled, where the format records it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Received by the recording adapter.
    Rx,
    /// Sent by the recording adapter.
    Tx,
}

impl Direction {
    /// `Rx` or `Tx`.
    pub fn name(self) -> &'static str {
        match self {
            Direction::Rx => "Rx",
            Direction::Tx => "Tx",
        }
    }
}

/// How to read a trace.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// The first line that is not DeviceNet traffic is an error (default: skipped and counted).
    pub strict: bool,
    /// The format, when the caller knows it (default: detected from the content).
    pub format: Option<TraceFormat>,
}

/// A line (or record) that was not read as a frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Skipped {
    /// 1-based line number (text formats) or record number (binary formats).
    pub line: usize,
    /// Why it was skipped.
    pub reason: String,
}

/// A whole trace read from a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Trace {
    /// The format it was read as.
    pub format: TraceFormat,
    /// The DeviceNet frames, in file order.
    pub entries: Vec<LogEntry>,
    /// The first [`NAMED_SKIPS`] skipped lines or records.
    pub skipped: Vec<Skipped>,
    /// How many lines or records were skipped in all.
    pub skipped_count: usize,
}

/// Where a reader puts what it reads: frames, and the lines it skips.
#[derive(Debug)]
pub struct Sink<'a> {
    file: &'a str,
    strict: bool,
    entries: Vec<LogEntry>,
    skipped: Vec<Skipped>,
    skipped_count: usize,
}

impl<'a> Sink<'a> {
    /// A sink for the file named `file` (in messages).
    pub fn new(file: &'a str, strict: bool) -> Sink<'a> {
        Sink { file, strict, entries: Vec::new(), skipped: Vec::new(), skipped_count: 0 }
    }

    /// The file name given to [`Sink::new`].
    pub fn file(&self) -> &str {
        self.file
    }

    /// One frame.
    pub fn frame(&mut self, entry: LogEntry) {
        self.entries.push(entry);
    }

    /// How many frames so far.
    pub fn frames(&self) -> usize {
        self.entries.len()
    }

    /// A line or record that is not DeviceNet traffic: counted (its details kept for the first
    /// [`NAMED_SKIPS`]), or with `strict` the error this returns (the reader returns it at once).
    pub fn skip(
        &mut self,
        line: usize,
        column: usize,
        reason: impl Into<String>,
        text: &str,
    ) -> Result<(), LogError> {
        let reason = reason.into();
        if self.strict {
            return Err(self.error(line, column, reason, text));
        }
        self.skipped_count += 1;
        if self.skipped.len() < NAMED_SKIPS {
            self.skipped.push(Skipped { line, reason });
        }
        Ok(())
    }

    /// An error that stops the reading whatever `strict` says (an unreadable header, a file of
    /// another format).
    pub fn error(&self, line: usize, column: usize, reason: impl Into<String>, text: &str) -> LogError {
        LogError {
            file: self.file.to_string(),
            line,
            column,
            reason: reason.into(),
            text: text.chars().take(120).collect(),
        }
    }

    /// The trace read.
    pub fn finish(self, format: TraceFormat) -> Trace {
        Trace { format, entries: self.entries, skipped: self.skipped, skipped_count: self.skipped_count }
    }
}

/// The format of a trace, from its first bytes; `None` when nothing known matches.
pub fn detect(bytes: &[u8]) -> Option<TraceFormat> {
    if bytes.len() >= 4 {
        let magic = [bytes[0], bytes[1], bytes[2], bytes[3]];
        match magic {
            [0xD4, 0xC3, 0xB2, 0xA1]
            | [0xA1, 0xB2, 0xC3, 0xD4]
            | [0x4D, 0x3C, 0xB2, 0xA1]
            | [0xA1, 0xB2, 0x3C, 0x4D] => return Some(TraceFormat::Pcap),
            [0x0A, 0x0D, 0x0D, 0x0A] => return Some(TraceFormat::Pcapng),
            [b'L', b'O', b'G', b'G'] => return Some(TraceFormat::Blf),
            _ => {}
        }
    }
    let head = &bytes[..bytes.len().min(4096)];
    let text = String::from_utf8_lossy(head);
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    for line in text.lines().map(str::trim).filter(|l| !l.is_empty()).take(40) {
        if line.starts_with(";$FILEVERSION")
            || line.starts_with(";   Start time:")
            || line.starts_with(";    Start time:")
            || line.starts_with(";$STARTTIME")
        {
            return Some(TraceFormat::Trc);
        }
        let lower = line.to_ascii_lowercase();
        if lower.starts_with("date ") || lower.starts_with("base hex") || lower.starts_with("base dec") {
            return Some(TraceFormat::Asc);
        }
        if line.starts_with('(') && line.contains('#') {
            return Some(TraceFormat::Candump);
        }
        // A trc 1.0 file has no `;$FILEVERSION` line: its column description names the time
        // offset, and its messages are numbered `1)`.
        if line.starts_with(';') && lower.contains("time offset") {
            return Some(TraceFormat::Trc);
        }
        if trc::is_message_number(line.split_whitespace().next().unwrap_or("")) {
            return Some(TraceFormat::Trc);
        }
        if line.starts_with(';') || line.starts_with('#') || line.starts_with("//") {
            continue;
        }
        if csv::is_header(line) {
            return Some(TraceFormat::Csv);
        }
    }
    None
}

/// Reads a trace from bytes. `file` names the source in messages.
pub fn parse_trace(bytes: &[u8], file: &str, options: ReadOptions) -> Result<Trace, LogError> {
    let format = match options.format.or_else(|| detect(bytes)) {
        Some(f) => f,
        None => {
            return Err(LogError {
                file: file.to_string(),
                line: 0,
                column: 0,
                reason: "cannot tell the trace format from the content (candump -L, pcap, pcapng, trc, \
                         asc, blf or csv expected); name it with --input-format"
                    .into(),
                text: String::new(),
            })
        }
    };
    let mut sink = Sink::new(file, options.strict);
    match format {
        TraceFormat::Candump => candump::read(bytes, &mut sink)?,
        TraceFormat::Pcap | TraceFormat::Pcapng => pcapfile::read(bytes, &mut sink)?,
        TraceFormat::Trc => trc::read(bytes, &mut sink)?,
        TraceFormat::Asc => asc::read(bytes, &mut sink)?,
        TraceFormat::Blf => blf::read(bytes, &mut sink)?,
        TraceFormat::Csv => csv::read(bytes, &mut sink)?,
    }
    Ok(sink.finish(format))
}

/// Reads a trace file; `-` reads standard input to its end (its name in messages is
/// `standard input`). An unreadable file is reported as line 0.
pub fn read_trace(path: &Path, options: ReadOptions) -> Result<Trace, LogError> {
    let (bytes, file) = entry::read_source(path)?;
    let stdin = path.as_os_str() == "-";
    let options = ReadOptions {
        format: options.format.or_else(|| detect(&bytes)).or_else(|| {
            if stdin {
                None
            } else {
                TraceFormat::from_extension(path)
            }
        }),
        ..options
    };
    parse_trace(&bytes, &file, options)
}

/// One line of a text trace, as the text readers see it.
pub(crate) struct TextLine<'a> {
    /// 1-based line number.
    pub number: usize,
    /// The line without its line ending (and without a byte-order mark on line 1).
    pub text: &'a str,
    /// The last line of the file, with no newline after it: perhaps cut off by an interrupted
    /// recording.
    pub unterminated: bool,
}

/// Calls `each` for every line of `bytes`; a line that is not UTF-8 is skipped (named) here.
pub(crate) fn for_each_line(
    bytes: &[u8],
    sink: &mut Sink<'_>,
    mut each: impl FnMut(&mut Sink<'_>, TextLine<'_>) -> Result<(), LogError>,
) -> Result<(), LogError> {
    let complete = bytes.last().is_none_or(|&b| b == b'\n');
    let mut lines = bytes.split(|&b| b == b'\n').peekable();
    let mut number = 0;
    while let Some(raw) = lines.next() {
        number += 1;
        let last = lines.peek().is_none();
        if last && raw.is_empty() {
            break;
        }
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let raw = if number == 1 { raw.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(raw) } else { raw };
        let Ok(text) = std::str::from_utf8(raw) else {
            sink.skip(number, 1, "the line is not UTF-8 text", &String::from_utf8_lossy(raw))?;
            continue;
        };
        each(sink, TextLine { number, text, unterminated: last && !complete })?;
    }
    Ok(())
}

/// A decimal number `int[.frac]` scaled by `10^digits` (`"12.5"`, 3 → 12500); digits past
/// `digits` are dropped (truncated). `None` for anything else, a sign included, or an overflow.
pub(crate) fn parse_scaled(text: &str, digits: u32) -> Option<u64> {
    let (int, frac) = text.split_once('.').unwrap_or((text, ""));
    if int.is_empty() || int.len() > 19 || !int.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    if !frac.bytes().all(|b| b.is_ascii_digit()) || frac.len() > 18 {
        return None;
    }
    let mut value: u64 = int.parse().ok()?;
    let mut taken = 0;
    for b in frac.bytes().take(digits as usize) {
        value = value.checked_mul(10)?.checked_add(u64::from(b - b'0'))?;
        taken += 1;
    }
    for _ in taken..digits {
        value = value.checked_mul(10)?;
    }
    Some(value)
}

/// The 11-bit identifier `raw`, or why a frame with it is not DeviceNet traffic.
pub(crate) fn standard_id(raw: u32, extended: bool) -> Result<u16, String> {
    if extended {
        return Err(format!(
            "extended identifier 0x{raw:08X} is not DeviceNet traffic (11-bit identifiers only)"
        ));
    }
    u16::try_from(raw)
        .ok()
        .filter(|&id| id <= 0x7FF)
        .ok_or_else(|| format!("identifier 0x{raw:X} does not fit in 11 bits"))
}

/// The whitespace-separated tokens of a line with their byte offsets.
pub(crate) fn tokens(line: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, c) in line.char_indices() {
        match (c.is_whitespace(), start) {
            (true, Some(s)) => {
                out.push((s, &line[s..i]));
                start = None;
            }
            (false, None) => start = Some(i),
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, &line[s..]));
    }
    out
}
