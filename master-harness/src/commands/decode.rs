//! `dnet-master decode`: DeviceNet messages from a trace of any common format (one line a frame, a
//! million frames a second and more, or JSON), from standard input as its lines arrive
//! (`candump -L can0 | dnet-master decode -`), or from a live bus that it never transmits on
//! (`decode --bus slcan:/dev/ttyACM0`, [`live`]).
//!
//! `--mac`, `--group` and `--kind` select the frames shown (every frame is still decoded, so
//! fragments and connections are followed); `--trigger PATTERN` stops at the first frame that
//! matches ([`master_core::decode::filter::Pattern`]: `mac=5,kind=explicit-error`,
//! `id=0x42B/0x7F8,data=0094/00FF`), after printing it: exit 0 when a trigger matched, 1 when the
//! input ended (or the bus was stopped) without one.

pub mod live;

use crate::options::{read_input, report_skipped, GlobalOptions, TraceInput};
use can_io::bus::BusSpec;
use can_io::log::LogEntry;
use can_io::trace::{parse_trace, ReadOptions, Skipped, Trace, TraceFormat};
use clap::Args;
use devicenet::{Duration, Instant};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::decode::filter::{classify, Filter, KindMatch, Pattern};
use master_core::decode::{self, Decoder};
use serde_json::json;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::sync::Arc;

/// What `decode` was asked.
#[derive(Args, Clone, Debug)]
pub struct DecodeArgs {
    /// The trace (its format is detected from the content; `-`: standard input, decoded line by
    /// line as it arrives when it is candump -L). Without it, the live bus --bus names is decoded
    /// (listen-only: nothing is sent).
    pub logfile: Option<PathBuf>,
    /// How the trace is read.
    #[command(flatten)]
    pub input: TraceInput,
    /// Show only frames of these MAC IDs (comma-separated).
    #[arg(long = "mac", value_delimiter = ',', value_parser = crate::options::parse_u8, value_name = "MAC")]
    pub macs: Vec<u8>,
    /// Show only frames of these message groups, 1-4 (comma-separated).
    #[arg(long = "group", value_delimiter = ',', value_parser = clap::value_parser!(u8).range(1..=4), value_name = "N")]
    pub groups: Vec<u8>,
    /// Show only these kinds (comma-separated): explicit, explicit-request, explicit-response,
    /// explicit-error, io, dup-mac, ucmm, other.
    #[arg(long = "kind", value_delimiter = ',', value_name = "KIND")]
    pub kinds: Vec<KindMatch>,
    /// Stop at the first frame matching PATTERN (comma-separated terms, all must hold: mac=N,
    /// group=N, kind=K, id=ID[/MASK], data=HEX[/MASK]); repeat for alternatives. Exit 0 when one
    /// matched, 1 when the input ended without.
    #[arg(long = "trigger", value_name = "PATTERN")]
    pub triggers: Vec<Pattern>,
    /// A live bus: stop after this many seconds [default: until SIGINT / SIGTERM].
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
}

impl DecodeArgs {
    /// The filter of `--mac`, `--group` and `--kind`.
    #[must_use]
    pub fn filter(&self) -> Filter {
        Filter { macs: self.macs.clone(), groups: self.groups.clone(), kinds: self.kinds.clone() }
    }
}

/// Runs `decode`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &DecodeArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    if let Some(mac) = args.macs.iter().find(|&&m| m > 63) {
        return Err(HarnessError::InvalidValue {
            option: "--mac",
            value: mac.to_string(),
            expected: "0..=63",
        });
    }
    let mut printer = Printer::new(opts.json, args.filter(), args.triggers.clone());
    match &args.logfile {
        Some(path) if path.as_os_str() == "-" && streamable(args.input.input_format) => {
            stream_stdin(&mut std::io::stdin().lock(), args, &mut printer, out, err, console)
        }
        Some(path) => {
            let trace = read_input(path, &args.input, err)?;
            if opts.json && printer.plain() {
                return print_json(&trace, out);
            }
            let werr = write_error;
            let mut buffered = std::io::BufWriter::with_capacity(1 << 16, out);
            for e in &trace.entries {
                if printer.frame(e, &mut buffered).map_err(werr)? {
                    break;
                }
            }
            buffered.flush().map_err(werr)?;
            Ok(printer.end(err))
        }
        None => decode_bus(opts, args, &mut printer, out, err, console),
    }
}

/// Whether standard input is read line by line: candump -L, named or to be detected.
fn streamable(format: Option<TraceFormat>) -> bool {
    matches!(format, None | Some(TraceFormat::Candump))
}

fn write_error(source: std::io::Error) -> HarnessError {
    HarnessError::Write { path: "standard output".into(), source }
}

/// Standard input line by line: each candump -L line decoded and printed (and flushed) as it
/// arrives. A first line of another format (a trc or asc header, csv) makes the whole input read
/// first, as a file is.
pub fn stream_stdin(
    input: &mut dyn BufRead,
    args: &DecodeArgs,
    printer: &mut Printer,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let name = "standard input";
    let options = ReadOptions { strict: args.input.strict, format: Some(TraceFormat::Candump) };
    let mut number = 0usize;
    let mut raw = Vec::with_capacity(256);
    let mut decided = args.input.input_format.is_some();
    let (mut frames, mut skipped, mut skipped_count) = (0usize, Vec::new(), 0usize);
    loop {
        if console.stop.requested().is_some() {
            break;
        }
        raw.clear();
        let n = std::io::Read::take(&mut *input, 64 * 1024)
            .read_until(b'\n', &mut raw)
            .map_err(|source| HarnessError::Read { path: name.into(), what: "trace", error: source })?;
        if n == 0 {
            break;
        }
        number += 1;
        let text = String::from_utf8_lossy(&raw);
        let trimmed = text.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        if !decided {
            decided = true;
            if !trimmed.starts_with('(') {
                // Not candump -L: the rest is read as a file is.
                let mut all = raw.clone();
                input.read_to_end(&mut all).map_err(|source| HarnessError::Read {
                    path: name.into(),
                    what: "trace",
                    error: source,
                })?;
                let trace = parse_trace(&all, name, args.input.options())?;
                report_skipped(err, name, trace.format, trace.skipped_count, &trace.skipped);
                let mut count = 0;
                for e in &trace.entries {
                    count += 1;
                    if printer.frame(e, out).map_err(write_error)? {
                        break;
                    }
                }
                if count == 0 {
                    return Err(HarnessError::NothingCompared(format!("{name}: no DeviceNet frames")));
                }
                return Ok(printer.end(err));
            }
        }
        let mut line = raw.clone();
        if line.last() != Some(&b'\n') {
            line.push(b'\n');
        }
        let trace = parse_trace(&line, name, options).map_err(|mut e| {
            e.line = number;
            HarnessError::from(e)
        })?;
        for s in &trace.skipped {
            skipped_count += 1;
            if skipped.len() < can_io::trace::NAMED_SKIPS {
                skipped.push(Skipped { line: number, reason: s.reason.clone() });
            }
        }
        for mut e in trace.entries {
            e.line = number;
            frames += 1;
            let stop = printer.frame(&e, out).map_err(write_error)?;
            out.flush().map_err(write_error)?;
            if stop {
                return Ok(printer.end(err));
            }
        }
    }
    report_skipped(err, name, TraceFormat::Candump, skipped_count, &skipped);
    if frames == 0 {
        return Err(HarnessError::NothingCompared(format!("{name}: no DeviceNet frames")));
    }
    Ok(printer.end(err))
}

/// A live bus, listen-only ([`live`]), until a trigger, `--duration` or a signal.
fn decode_bus(
    opts: &GlobalOptions,
    args: &DecodeArgs,
    printer: &mut Printer,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    if matches!(opts.bus, BusSpec::Sim) {
        return Err(HarnessError::BusSetup {
            detail: "decode without a trace decodes a live bus: give --bus socketcan:IFACE or \
                     slcan:PATH (nothing is sent), or a trace FILE (- for standard input)"
                .into(),
        });
    }
    let mut bus = live::open_listening(&opts.bus, opts.bitrate).map_err(HarnessError::from)?;
    let iface: Arc<str> = Arc::from(bus.name());
    let started = bus.now();
    let end = args.duration.map(|s| started + Duration::from_micros((s.max(0.0) * 1e6) as u64));
    let _ = writeln!(err, "dnet-master: decoding {} (listen-only; Ctrl-C stops)", opts.bus);
    let mut number = 0usize;
    loop {
        if let Some(signal) = console.stop.requested() {
            let code = printer.end(err);
            return Ok(if printer.triggered { code } else { master_core::stop::exit_status(signal) });
        }
        let now = bus.now();
        if end.is_some_and(|e| now >= e) {
            break;
        }
        // Wake every 100 ms to see a signal.
        let step = now + Duration::from_millis(100);
        let deadline = end.map_or(step, |e| e.min(step));
        let Some(ev) = bus.recv(deadline).map_err(HarnessError::from)? else { continue };
        number += 1;
        let entry = LogEntry {
            line: number,
            at: Instant::ZERO + (ev.at - started),
            iface: Arc::clone(&iface),
            frame: ev.frame,
            direction: None,
        };
        let stop = printer.frame(&entry, out).map_err(write_error)?;
        out.flush().map_err(write_error)?;
        if stop {
            break;
        }
    }
    Ok(printer.end(err))
}

/// The whole trace as one JSON object (no filter, no trigger).
fn print_json(trace: &Trace, out: &mut dyn Write) -> Result<u8, HarnessError> {
    let mut decoder = Decoder::new();
    let mut items = Vec::with_capacity(trace.entries.len());
    for e in &trace.entries {
        let d = decoder.decode(&e.frame);
        items.push(json!({
            "line": e.line,
            "time_us": e.at.total_micros(),
            "iface": &*e.iface,
            "direction": e.direction.map(|d| d.name()),
            "frame": e.frame.to_string(),
            "meaning": d.summary,
            "message": d.message,
        }));
    }
    let skipped: Vec<_> =
        trace.skipped.iter().map(|s| json!({ "line": s.line, "reason": s.reason })).collect();
    let summary = json!({
        "ok": true,
        "format": trace.format.name(),
        "frames": items,
        "skipped": trace.skipped_count,
        "skipped_first": skipped,
    });
    writeln!(out, "{summary}").map_err(write_error)?;
    Ok(0)
}

/// Decodes frames one by one and prints those the filter shows (text lines, or with `--json` one
/// JSON object a line), watching for the triggers.
pub struct Printer {
    json: bool,
    filter: Filter,
    triggers: Vec<Pattern>,
    decoder: Decoder,
    decoded: decode::Decoded,
    line: String,
    /// A trigger matched.
    pub triggered: bool,
    /// Frames decoded, frames shown.
    pub counts: (usize, usize),
}

impl Printer {
    /// A printer with `filter` and `triggers`.
    #[must_use]
    pub fn new(json: bool, filter: Filter, triggers: Vec<Pattern>) -> Printer {
        Printer {
            json,
            filter,
            triggers,
            decoder: Decoder::new(),
            decoded: decode::Decoded::default(),
            line: String::with_capacity(256),
            triggered: false,
            counts: (0, 0),
        }
    }

    /// No filter and no trigger.
    fn plain(&self) -> bool {
        self.filter.is_empty() && self.triggers.is_empty()
    }

    /// Decodes `e`, prints it when the filter shows it (a trigger's frame always); `true` when a
    /// trigger matched (the caller stops).
    pub fn frame(&mut self, e: &LogEntry, out: &mut dyn Write) -> std::io::Result<bool> {
        self.decoder.decode_into(&e.frame, &mut self.decoded);
        self.counts.0 += 1;
        let class = classify(&e.frame);
        let hit = self.triggers.iter().find(|t| t.matches(&e.frame, class));
        if !self.filter.passes(class) && hit.is_none() {
            return Ok(false);
        }
        self.counts.1 += 1;
        let d = &self.decoded;
        if self.json {
            let item = json!({
                "line": e.line,
                "time_us": e.at.total_micros(),
                "iface": &*e.iface,
                "frame": e.frame.to_string(),
                "kind": class.kind.name(),
                "mac": class.mac,
                "group": class.group,
                "meaning": d.summary,
                "message": d.message,
                "trigger": hit.map(ToString::to_string),
            });
            writeln!(out, "{item}")?;
        } else {
            let line = &mut self.line;
            line.clear();
            push_trace_line(line, e);
            while line.len() < 40 {
                line.push(' ');
            }
            line.push(' ');
            line.push_str(&d.summary);
            line.push('\n');
            if let Some(m) = &d.message {
                line.push_str(concat!("                                        ", "   => "));
                line.push_str(m);
                line.push('\n');
            }
            if let Some(t) = hit {
                line.push_str(&format!("trigger {t} matched at line {}: stopped\n", e.line));
            }
            out.write_all(line.as_bytes())?;
        }
        self.triggered = hit.is_some();
        Ok(self.triggered)
    }

    /// The exit status: 1 when triggers were given and none matched (said on `err`), else 0.
    pub fn end(&self, err: &mut dyn Write) -> u8 {
        if self.triggers.is_empty() || self.triggered {
            return 0;
        }
        let names: Vec<String> = self.triggers.iter().map(ToString::to_string).collect();
        let _ = writeln!(
            err,
            "dnet-master: no frame matched the trigger ({}) in {} frame(s)",
            names.join(" | "),
            self.counts.0
        );
        1
    }
}

/// `(seconds.micros) iface [Rx|Tx] ID#DATA`: a `candump -L` line, with the direction where the
/// trace recorded one.
fn push_trace_line(line: &mut String, e: &LogEntry) {
    let us = e.at.total_micros();
    let mut digits = [0u8; 26];
    let mut at = digits.len();
    let mut rest = us;
    // Digits from the right: six of microseconds, the point, then the seconds (at least one).
    for i in 0.. {
        if i == 6 {
            at -= 1;
            digits[at] = b'.';
        }
        at -= 1;
        digits[at] = b'0' + (rest % 10) as u8;
        rest /= 10;
        if rest == 0 && i >= 6 {
            break;
        }
    }
    line.push('(');
    line.push_str(std::str::from_utf8(&digits[at..]).unwrap_or("?"));
    line.push_str(") ");
    line.push_str(&e.iface);
    if let Some(d) = e.direction {
        line.push(' ');
        line.push_str(d.name());
    }
    line.push(' ');
    let raw = e.frame.id().as_raw();
    for shift in [8, 4, 0] {
        line.push(char::from(b"0123456789ABCDEF"[usize::from(raw >> shift & 0xF)]));
    }
    line.push('#');
    for b in e.frame.data() {
        line.push(char::from(b"0123456789ABCDEF"[usize::from(b >> 4)]));
        line.push(char::from(b"0123456789ABCDEF"[usize::from(b & 0xF)]));
    }
}
