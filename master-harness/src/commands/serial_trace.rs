//! `dnet-master serial-trace`: the converter's serial-line analyzer (vendor class 0x68, Read_Trace,
//! `slave_fw::converter::analyzer_object`) read over the explicit connection and printed decoded
//! by the device's profile: Modbus RTU requests and responses, breaker frames; `--follow` keeps
//! reading until `--duration` or a signal ends it.
//!
//! The profile is read from the settings object (class 0x65 attribute 11: 0 framed serial, 1
//! Modbus); a framed instrument is decoded with the breaker's framing. Bytes that do not make a
//! frame are printed as hex with the decoder's reason.

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
use slave_fw::serial::breaker::{self, BreakerCommand, Message};
use slave_fw::serial::modbus::pdu::{self, Request as MbRequest, Response as MbResponse};
use slave_fw::serial::trace::{TraceEntry, TraceKind, TraceParseError};
use slave_fw::serial::{FrameParser, FRAME_CAPACITY};
use std::io::Write;

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

/// Why a Read_Trace reply could not be read.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum TraceReplyError {
    /// Shorter than its two sequence numbers.
    #[error("reply of {0} bytes, shorter than its two sequence numbers (8 bytes)")]
    Short(usize),
    /// An entry did not parse.
    #[error("entry at byte {offset}: {error}")]
    Entry {
        /// Where in the reply.
        offset: usize,
        /// Why.
        error: TraceParseError,
    },
    /// No entry although the reader is behind the device's next sequence number.
    #[error("no entry from sequence number {from} although the next is {next}")]
    Empty {
        /// Asked from.
        from: u32,
        /// The device's next sequence number.
        next: u32,
    },
}

/// One Read_Trace reply: the first sequence number, the next, the entries.
#[derive(Debug, PartialEq, Eq)]
pub struct TraceReply {
    /// The sequence number of the first entry.
    pub first: u32,
    /// The sequence number the device's next entry will get.
    pub next: u32,
    /// The entries, sequence numbers `first..`.
    pub entries: Vec<TraceEntry>,
}

/// Parses a Read_Trace reply (`slave_fw::converter::analyzer_object`).
pub fn parse_reply(bytes: &[u8]) -> Result<TraceReply, TraceReplyError> {
    let (Some(first), Some(next)) = (bytes.get(..4), bytes.get(4..8)) else {
        return Err(TraceReplyError::Short(bytes.len()));
    };
    let u32_of = |b: &[u8]| b.try_into().map(u32::from_le_bytes).unwrap_or(0);
    let mut entries = Vec::new();
    let mut offset = 8;
    while let Some(rest) = bytes.get(offset..).filter(|r| !r.is_empty()) {
        let (entry, n) = TraceEntry::parse(rest).map_err(|error| TraceReplyError::Entry { offset, error })?;
        entries.push(entry);
        offset += n;
    }
    Ok(TraceReply { first: u32_of(first), next: u32_of(next), entries })
}

/// How the line bytes are cut into frames and named.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineProfile {
    /// Framed serial, decoded with the breaker's framing.
    Breaker,
    /// Modbus RTU.
    ModbusRtu,
    /// Not known: hex only.
    Raw,
}

impl LineProfile {
    /// The name printed and in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            LineProfile::Breaker => "breaker (framed serial)",
            LineProfile::ModbusRtu => "Modbus RTU",
            LineProfile::Raw => "raw",
        }
    }
}

/// One printed line: a frame, bytes that made none, or an event.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct TraceLine {
    /// The sequence number of the entry that completed it.
    pub seq: u32,
    /// The converter's clock at that entry, ms.
    pub time_ms: u32,
    /// `tx`, `rx` or the event's name.
    pub kind: &'static str,
    /// The bytes, hex.
    pub hex: String,
    /// What they are.
    pub decoded: String,
}

impl std::fmt::Display for TraceLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "#{:<6} {:>10} ms  {:<13}", self.seq, self.time_ms, self.kind)?;
        if !self.hex.is_empty() {
            write!(f, " {}", self.hex)?;
        }
        if !self.decoded.is_empty() {
            write!(f, "  {}", self.decoded)?;
        }
        Ok(())
    }
}

/// The decoder: one byte stream per direction, cut into frames by the profile.
pub struct Decoder {
    profile: LineProfile,
    tx: Vec<u8>,
    rx: Vec<u8>,
    tx_frames: FrameParser<FRAME_CAPACITY>,
    rx_frames: FrameParser<FRAME_CAPACITY>,
}

/// The name of an event kind.
fn kind_name(kind: TraceKind) -> &'static str {
    match kind {
        TraceKind::Transmit => "tx",
        TraceKind::Receive => "rx",
        TraceKind::DriverOn => "driver on",
        TraceKind::DriverOff => "driver off",
        TraceKind::UartFraming => "uart framing",
        TraceKind::UartParity => "uart parity",
        TraceKind::UartOverrun => "uart overrun",
        TraceKind::Checksum => "checksum err",
        TraceKind::Framing => "framing err",
    }
}

impl Decoder {
    /// A decoder for `profile`.
    pub fn new(profile: LineProfile) -> Decoder {
        // The breaker's framing is valid (a slave_fw test holds it); `expect` cannot fire.
        let parser = || FrameParser::new(breaker::FRAMING).expect("the breaker framing is valid");
        Decoder { profile, tx: Vec::new(), rx: Vec::new(), tx_frames: parser(), rx_frames: parser() }
    }

    /// Takes entry `seq`; returns the lines it completes.
    pub fn push(&mut self, seq: u32, entry: &TraceEntry) -> Vec<TraceLine> {
        let line = |kind, bytes: &[u8], decoded: String| TraceLine {
            seq,
            time_ms: entry.time_ms,
            kind,
            hex: decode::hex(bytes),
            decoded,
        };
        let tx = match entry.kind {
            TraceKind::Transmit => true,
            TraceKind::Receive => false,
            other => return vec![line(kind_name(other), &[], String::new())],
        };
        let name = kind_name(entry.kind);
        match self.profile {
            LineProfile::Raw => vec![line(name, entry.bytes(), String::new())],
            LineProfile::Breaker => {
                let parser = if tx { &mut self.tx_frames } else { &mut self.rx_frames };
                let mut out = Vec::new();
                parser.push_slice(entry.bytes(), |event| {
                    out.push(match event {
                        Ok(frame) => line(name, frame.raw(), breaker_text(tx, frame.data())),
                        Err(e) => line(name, &[], format!("not a frame: {e}")),
                    })
                });
                out
            }
            LineProfile::ModbusRtu => {
                let mut out = Vec::new();
                // A request ends the response before it, and a response the request: what is
                // left of the other direction was cut short.
                let other = if tx { &mut self.rx } else { &mut self.tx };
                if !other.is_empty() {
                    let other_name = if tx { "rx" } else { "tx" };
                    out.push(line(other_name, &std::mem::take(other), "incomplete frame".into()));
                }
                let buf = if tx { &mut self.tx } else { &mut self.rx };
                buf.extend_from_slice(entry.bytes());
                loop {
                    let len = if tx { pdu::request_len(buf) } else { pdu::response_len(buf) };
                    match len {
                        Ok(Some(n)) if n <= buf.len() => {
                            let adu: Vec<u8> = buf.drain(..n).collect();
                            out.push(line(name, &adu, modbus_text(tx, &adu)));
                        }
                        Ok(_) => break,
                        Err(e) => {
                            let bytes = std::mem::take(buf);
                            out.push(line(name, &bytes, format!("not a Modbus RTU frame: {e}")));
                            break;
                        }
                    }
                }
                out
            }
        }
    }
}

/// A breaker frame's data, named.
fn breaker_text(tx: bool, data: &[u8]) -> String {
    if tx {
        return match BreakerCommand::parse(data) {
            Ok(BreakerCommand::Open) => "command Open".into(),
            Ok(BreakerCommand::Close) => "command Close".into(),
            Ok(BreakerCommand::Refresh) => "command Refresh".into(),
            Ok(BreakerCommand::SetParameter { id, value }) => format!("command Set parameter {id} = {value}"),
            Err(_) => format!("command {}", decode::hex(data)),
        };
    }
    match Message::classify(data) {
        Message::Status(s) => {
            let [a, b, c, d] = s.phase_currents();
            format!("status: currents {a} {b} {c} {d}, switch {:?}", s.switch_state())
        }
        Message::Ack(ack) if ack.status == breaker::ACK_OK => {
            format!("ack of command 0x{:02X}: ok", ack.command)
        }
        Message::Ack(ack) => format!("ack of command 0x{:02X}: refused (0x{:02X})", ack.command, ack.status),
        Message::Other => "frame of another kind".into(),
    }
}

/// A Modbus RTU ADU, named.
fn modbus_text(tx: bool, adu: &[u8]) -> String {
    let parsed = if tx {
        MbRequest::parse(adu).map(|(unit, r)| format!("request unit {unit}: {}", request_text(&r)))
    } else {
        MbResponse::parse(adu).map(|(unit, r)| format!("response unit {unit}: {}", response_text(&r)))
    };
    parsed.unwrap_or_else(|e| format!("not a Modbus RTU frame: {e}"))
}

fn request_text(r: &MbRequest<'_>) -> String {
    match *r {
        MbRequest::ReadCoils { address, count } => format!("0x01 read coils {address} count {count}"),
        MbRequest::ReadDiscreteInputs { address, count } => {
            format!("0x02 read discrete inputs {address} count {count}")
        }
        MbRequest::ReadHoldingRegisters { address, count } => {
            format!("0x03 read holding registers {address} count {count}")
        }
        MbRequest::ReadInputRegisters { address, count } => {
            format!("0x04 read input registers {address} count {count}")
        }
        MbRequest::WriteSingleCoil { address, value } => {
            format!("0x05 write coil {address} = {}", u8::from(value))
        }
        MbRequest::WriteSingleRegister { address, value } => {
            format!("0x06 write register {address} = {value}")
        }
        MbRequest::WriteMultipleCoils { address, count, .. } => {
            format!("0x0F write coils {address} count {count}")
        }
        MbRequest::WriteMultipleRegisters { address, values } => {
            format!("0x10 write registers {address} count {}", values.len() / 2)
        }
    }
}

fn response_text(r: &MbResponse<'_>) -> String {
    let words = |b: &[u8]| b.chunks(2).map(|w| decode::hex(w).replace(' ', "")).collect::<Vec<_>>().join(" ");
    match r {
        MbResponse::ReadCoils(b) => format!("0x01 coils {}", decode::hex(b)),
        MbResponse::ReadDiscreteInputs(b) => format!("0x02 inputs {}", decode::hex(b)),
        MbResponse::ReadHoldingRegisters(b) => format!("0x03 registers {}", words(b)),
        MbResponse::ReadInputRegisters(b) => format!("0x04 registers {}", words(b)),
        other => format!("{other:?}"),
    }
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
    let profile = match get(master, mac, SETTINGS_CLASS, &[SettingsAttribute::SerialProfile.id()])? {
        Some(b) if b == [0] => LineProfile::Breaker,
        Some(b) if b == [1] => LineProfile::ModbusRtu,
        _ => LineProfile::Raw,
    };
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
        let missed = reply.first.wrapping_sub(from);
        if missed > 0 && missed < u32::MAX / 2 {
            state.missed += u64::from(missed);
            writeln!(screen, "({missed} entries overwritten before they were read)").map_err(werr)?;
        } else if missed != 0 {
            writeln!(screen, "(the converter restarted: its trace starts again at #{})", reply.first)
                .map_err(werr)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(time_ms: u32, kind: TraceKind, bytes: &[u8]) -> TraceEntry {
        TraceEntry::new(time_ms, kind, bytes).unwrap()
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
    }

    #[test]
    fn modbus_requests_and_responses_are_decoded() {
        let mut d = Decoder::new(LineProfile::ModbusRtu);
        let req = [0x01, 0x04, 0x00, 0x07, 0x00, 0x01];
        let crc = slave_fw::serial::checksum::crc16_modbus(&req);
        let mut adu = req.to_vec();
        adu.extend_from_slice(&crc.to_le_bytes());
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
}
