//! `dnet-master decode`: a trace of any common format pretty-printed as DeviceNet messages, one
//! line a frame (a million frames a second and more), or as JSON.

use crate::options::{read_input, GlobalOptions, TraceInput};
use can_io::log::LogEntry;
use can_io::trace::Trace;
use clap::Args;
use harness_common::error::HarnessError;
use master_core::decode::{self, Decoder};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;

/// What `decode` was asked.
#[derive(Args, Clone, Debug)]
pub struct DecodeArgs {
    /// The trace (its format is detected from the content; `-`: standard input).
    pub logfile: PathBuf,
    /// How the trace is read.
    #[command(flatten)]
    pub input: TraceInput,
}

/// Runs `decode`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &DecodeArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<u8, HarnessError> {
    let trace = read_input(&args.logfile, &args.input, err)?;
    print(opts, &trace, out)
}

/// The decoded trace on `out`.
fn print(opts: &GlobalOptions, trace: &Trace, out: &mut dyn Write) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let mut decoder = Decoder::new();
    if opts.json {
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
        writeln!(out, "{summary}").map_err(werr)?;
        return Ok(0);
    }
    // A million frames a second and more: one buffer per line, written in 64 KiB blocks (the
    // standard output is line-buffered), nothing allocated per frame but completed messages.
    let mut out = std::io::BufWriter::with_capacity(1 << 16, out);
    let mut line = String::with_capacity(256);
    let mut decoded = decode::Decoded::default();
    for e in &trace.entries {
        decoder.decode_into(&e.frame, &mut decoded);
        line.clear();
        push_trace_line(&mut line, e);
        while line.len() < 40 {
            line.push(' ');
        }
        line.push(' ');
        line.push_str(&decoded.summary);
        line.push('\n');
        if let Some(m) = &decoded.message {
            line.push_str(concat!("                                        ", "   => "));
            line.push_str(m);
            line.push('\n');
        }
        out.write_all(line.as_bytes()).map_err(werr)?;
    }
    out.flush().map_err(werr)?;
    Ok(0)
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
