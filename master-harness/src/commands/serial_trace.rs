//! `dnet-master serial-trace`: the converter's serial-line analyzer (vendor class 0x68, Read_Trace,
//! `slave_fw::converter::analyzer_object`) read over the explicit connection and printed decoded
//! by the device's profile: Modbus RTU requests and responses, breaker frames; `--follow` keeps
//! reading until `--duration` or a signal ends it.
//!
//! The profile is read from the settings object (class 0x65 attribute 11: 0 framed serial, 1
//! Modbus; attribute 12: the Modbus framing, RTU, ASCII or TCP); a framed instrument is decoded
//! with the breaker's framing. Bytes that do not make a frame are printed as hex with the
//! decoder's reason. The decoding is `dnet_scanner::serial_trace`'s, which the console's Serial
//! line panel uses too.

use crate::options::{parse_mac, GlobalOptions};
use crate::run::{DeviceRun, Outcome, Ran};
use clap::Args;
use devicenet::explicit::{Request, ServiceCode};
use devicenet::{Duration, MacId};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::client::{Port, ReplyBody};
use master_core::decode;
use master_core::error::MasterError;
use master_core::master::Master;
use serde_json::json;
use slave_fw::converter::analyzer_object::{ANALYZER_CLASS, READ_TRACE};
use slave_fw::converter::objects::{SettingsAttribute, SETTINGS_CLASS};
use std::io::Write;

pub use dnet_scanner::serial_trace::{
    parse_reply, Decoder, Gap, LineProfile, TraceLine, TraceReply, TraceReplyError,
};

/// What `serial-trace` was asked.
#[derive(Args, Clone, Debug)]
pub struct SerialTraceArgs {
    /// The converter's MAC ID.
    #[arg(long, value_parser = parse_mac)]
    pub mac: MacId,
    /// Keep reading new entries until --duration or Ctrl-C.
    #[arg(long)]
    pub follow: bool,
    /// With --follow: ms between reads once the trace is read to its end.
    #[arg(long, default_value_t = 200, value_name = "MS")]
    pub interval: u16,
    /// With --follow: stop after this many seconds (bus time).
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
}

/// Runs `serial-trace`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &SerialTraceArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let duration = crate::options::duration_secs(args.duration)?;
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    run.run(out, err, console, |master, _, out| {
        let mut sink = std::io::sink();
        let screen: &mut dyn Write = if opts.json { &mut sink } else { out };
        let mut state = Traced::default();
        let result = follow(master, args, duration, screen, opts.json, &mut state);
        let outcome = state.outcome();
        match result {
            Ok(()) => Ran { result: Ok(outcome), partial: None, cleanup: Vec::new() },
            Err(e) => Ran { result: Err(e), partial: Some(outcome), cleanup: Vec::new() },
        }
    })
}

/// The most lines `--json` keeps (the newest): a long `--follow` holds bounded memory.
pub const JSON_LINES: usize = 10_000;

/// What was read so far.
#[derive(Default)]
struct Traced {
    profile: Option<LineProfile>,
    /// The newest lines, for `--json` only.
    lines: std::collections::VecDeque<TraceLine>,
    /// Lines dropped from `lines` to keep it within [`JSON_LINES`].
    lines_dropped: u64,
    entries: u64,
    missed: u64,
}

impl Traced {
    fn outcome(&self) -> Outcome {
        let profile = self.profile.map_or("unknown", LineProfile::name);
        Outcome {
            text: format!(
                "{} entries read ({profile}), {} overwritten before they were read",
                self.entries, self.missed
            ),
            json: json!({
                "profile": profile,
                "entries": self.entries,
                "missed": self.missed,
                "lines": self.lines,
                "lines_dropped": self.lines_dropped,
            }),
            code: 0,
        }
    }
}

/// Reads the trace to its end, and with `--follow` on until `duration`.
fn follow(
    master: &mut Master<'_, '_>,
    args: &SerialTraceArgs,
    duration: Option<Duration>,
    screen: &mut dyn Write,
    keep_lines: bool,
    state: &mut Traced,
) -> Result<(), HarnessError> {
    let mac = args.mac;
    master.open_explicit(mac)?;
    let serial_profile = get(master, mac, SETTINGS_CLASS, &[SettingsAttribute::SerialProfile.id()])?;
    let framing = match serial_profile.as_deref() {
        Some([1]) => get(master, mac, SETTINGS_CLASS, &[SettingsAttribute::ModbusFraming.id()])?,
        _ => None,
    };
    let profile = LineProfile::from_settings(serial_profile.as_deref(), framing.as_deref());
    state.profile = Some(profile);
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    writeln!(screen, "MAC {mac} serial trace, decoded as {}", profile.name()).map_err(werr)?;
    let mut decoder = Decoder::new(profile);
    let start = master.session.now();
    let end = duration.map(|d| start.saturating_add(d));
    let mut from = 0u32;
    loop {
        let what = format!("Read_Trace of class 0x{ANALYZER_CLASS:02X} at MAC {mac}");
        let bytes = read_trace(master, mac, from)?;
        let reply = parse_reply(&bytes)
            .map_err(|e| MasterError::Protocol { what: what.clone(), reason: e.to_string() })?;
        match Gap::between(from, reply.first) {
            Gap::None => {}
            Gap::Missed(missed) => {
                state.missed += u64::from(missed);
                writeln!(screen, "({missed} entries overwritten before they were read)").map_err(werr)?;
            }
            Gap::Restarted => {
                writeln!(screen, "(the converter restarted: its trace starts again at #{})", reply.first)
                    .map_err(werr)?;
            }
        }
        if reply.entries.is_empty() && reply.first != reply.next {
            let e = TraceReplyError::Empty { from: reply.first, next: reply.next };
            return Err(MasterError::Protocol { what, reason: e.to_string() }.into());
        }
        for (k, entry) in reply.entries.iter().enumerate() {
            let seq = reply.first.wrapping_add(k as u32);
            for line in decoder.push(seq, entry) {
                writeln!(screen, "{line}").map_err(werr)?;
                if keep_lines {
                    if state.lines.len() == JSON_LINES {
                        state.lines.pop_front();
                        state.lines_dropped += 1;
                    }
                    state.lines.push_back(line);
                }
            }
        }
        state.entries += reply.entries.len() as u64;
        from = reply.first.wrapping_add(reply.entries.len() as u32);
        if from == reply.next {
            if !args.follow {
                return Ok(());
            }
            let now = master.session.now();
            if end.is_some_and(|end| now >= end) {
                return Ok(());
            }
            let wake = now.saturating_add(Duration::from_millis(args.interval.into()));
            master.idle_until(end.map_or(wake, |end| wake.min(end)))?;
        }
    }
}

/// A Get_Attribute_Single; `None` for an error response (the attribute is not served).
fn get(
    master: &mut Master<'_, '_>,
    mac: MacId,
    class: u16,
    data: &[u8],
) -> Result<Option<Vec<u8>>, HarnessError> {
    let req = Request { service: ServiceCode::GetAttributeSingle, class, instance: 1, data };
    let answer = master.request(mac, Port::Explicit, &req)?;
    Ok(match answer.reply.body {
        ReplyBody::Success(bytes) => Some(bytes),
        ReplyBody::Error { .. } => None,
    })
}

/// Read_Trace from `from`; an error response is an error naming it.
fn read_trace(master: &mut Master<'_, '_>, mac: MacId, from: u32) -> Result<Vec<u8>, HarnessError> {
    let data = from.to_le_bytes();
    let req =
        Request { service: ServiceCode::from(READ_TRACE), class: ANALYZER_CLASS, instance: 1, data: &data };
    let what = decode::request_text(&req);
    let answer = master.request(mac, Port::Explicit, &req)?;
    match answer.reply.body {
        ReplyBody::Success(bytes) => Ok(bytes),
        ReplyBody::Error { general, additional } => {
            let text = decode::error_text(general, additional);
            Err(MasterError::ErrorResponse { what, mac: mac.as_raw(), general, additional, text }.into())
        }
    }
}
