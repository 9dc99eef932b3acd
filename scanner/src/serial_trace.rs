//! The converter's serial-line analyzer decoded: a Read_Trace reply (vendor class 0x68,
//! `slave_fw::converter::analyzer_object`) parsed into [`TraceEntry`]s ([`parse_reply`]), and the
//! entries turned into printed lines by the device's profile ([`Decoder`]): breaker frames, Modbus
//! RTU, Modbus ASCII (`:` … LRC CR LF) and Modbus TCP (MBAP) requests and responses. Bytes that do
//! not make a frame become a line of hex with the decoder's reason.
//!
//! `dnet-master serial-trace` prints these lines; the console's Serial line panel
//! (`GET /api/node/MAC/serial-trace`) shows them. The profile comes from the settings object
//! (class 0x65): attribute 11 (0 framed serial, 1 Modbus) and attribute 12 (the Modbus framing: 0
//! RTU, 1 ASCII, 2 TCP), [`LineProfile::from_settings`].
//!
//! The frames are cut and checked by the converter's own codecs (`slave_fw::serial::FrameParser`
//! for the breaker, `slave_fw::serial::modbus::{pdu, ascii, mbap}`); a Modbus ASCII or TCP frame's
//! address and PDU are named by the RTU request and response parsers after a CRC is appended
//! ([`rtu_adu`]), so every framing names function codes and addresses alike.
//!
//! ## Memory
//!
//! A decoder holds at most one unfinished frame per direction: an RTU or Modbus TCP frame (at most
//! 260 bytes), an ASCII frame (at most 513 characters) or [`MAX_LOOSE`] bytes outside any frame;
//! more is printed and dropped. No input makes it panic.

use master_core::decode;
use slave_fw::serial::breaker::{self, BreakerCommand, Message};
use slave_fw::serial::modbus::pdu::{self, Request as MbRequest, Response as MbResponse, ADU_CAPACITY};
use slave_fw::serial::modbus::{ascii, mbap};
use slave_fw::serial::trace::{TraceEntry, TraceKind, TraceParseError};
use slave_fw::serial::{FrameParser, FRAME_CAPACITY};

/// The most bytes outside any ASCII frame held before they are printed: one longest ASCII frame.
pub const MAX_LOOSE: usize = ascii::FRAME_CAPACITY;

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

/// What a reply says about the entries before it, for a reader that asked from `from`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gap {
    /// The reply starts where the reader asked.
    None,
    /// This many entries were overwritten before they were read.
    Missed(u32),
    /// The converter restarted: its sequence numbers start again.
    Restarted,
}

impl Gap {
    /// The gap between `from` (asked) and `first` (the reply's first sequence number).
    pub fn between(from: u32, first: u32) -> Gap {
        match first.wrapping_sub(from) {
            0 => Gap::None,
            n if n < u32::MAX / 2 => Gap::Missed(n),
            _ => Gap::Restarted,
        }
    }
}

/// How the line bytes are cut into frames and named.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineProfile {
    /// Framed serial, decoded with the breaker's framing.
    Breaker,
    /// Modbus RTU.
    ModbusRtu,
    /// Modbus ASCII.
    ModbusAscii,
    /// Modbus TCP (MBAP).
    ModbusTcp,
    /// Not known: hex only.
    Raw,
}

impl LineProfile {
    /// The name printed and in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            LineProfile::Breaker => "breaker (framed serial)",
            LineProfile::ModbusRtu => "Modbus RTU",
            LineProfile::ModbusAscii => "Modbus ASCII",
            LineProfile::ModbusTcp => "Modbus TCP",
            LineProfile::Raw => "raw",
        }
    }

    /// The profile of the settings object's attribute 11 (`profile`, the serial profile) and 12
    /// (`framing`, the Modbus framing), each `None` when the device did not serve it: Modbus
    /// without attribute 12 (a converter from before it) is RTU; anything unknown is
    /// [`LineProfile::Raw`].
    pub fn from_settings(profile: Option<&[u8]>, framing: Option<&[u8]>) -> LineProfile {
        match (profile, framing) {
            (Some([0]), _) => LineProfile::Breaker,
            (Some([1]), None | Some([0])) => LineProfile::ModbusRtu,
            (Some([1]), Some([1])) => LineProfile::ModbusAscii,
            (Some([1]), Some([2])) => LineProfile::ModbusTcp,
            _ => LineProfile::Raw,
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

/// The name of an event kind.
pub fn kind_name(kind: TraceKind) -> &'static str {
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

/// A frame or loose bytes of one direction, before the line is made.
type Piece = (Vec<u8>, String);

/// One direction of a Modbus ASCII line: the converter's ASCII receiver, the characters of the
/// frame (or of the bytes outside any frame) so far and the address and PDU decoded.
#[derive(Default)]
struct AsciiSide {
    decoder: ascii::Decoder,
    raw: Vec<u8>,
    frame: heapless::Vec<u8, ADU_CAPACITY>,
}

impl AsciiSide {
    fn push(&mut self, tx: bool, bytes: &[u8], out: &mut Vec<Piece>) {
        for &c in bytes {
            if c == b':' && !self.decoder.in_frame() && !self.raw.is_empty() {
                out.push((std::mem::take(&mut self.raw), "bytes outside any ASCII frame".into()));
            }
            match self.decoder.push(c, &mut self.frame) {
                ascii::Step::Pending | ascii::Step::Skipped => {
                    self.raw.push(c);
                    if !self.decoder.in_frame() && self.raw.len() >= MAX_LOOSE {
                        out.push((std::mem::take(&mut self.raw), "bytes outside any ASCII frame".into()));
                    }
                }
                ascii::Step::Frame => {
                    self.raw.push(c);
                    let text = modbus_text(tx, &rtu_adu(&self.frame), "Modbus ASCII");
                    out.push((std::mem::take(&mut self.raw), text));
                }
                ascii::Step::Error(ascii::AsciiError::Interrupted) => {
                    let reason = ascii::AsciiError::Interrupted;
                    out.push((std::mem::take(&mut self.raw), format!("not a Modbus ASCII frame: {reason}")));
                    self.raw.push(c);
                }
                ascii::Step::Error(e) => {
                    self.raw.push(c);
                    out.push((std::mem::take(&mut self.raw), format!("not a Modbus ASCII frame: {e}")));
                }
            }
        }
    }

    /// What is left, cut short by the other direction.
    fn cut(&mut self) -> Option<Piece> {
        let why = if self.decoder.in_frame() { "incomplete frame" } else { "bytes outside any ASCII frame" };
        self.decoder.reset();
        (!self.raw.is_empty()).then(|| (std::mem::take(&mut self.raw), why.into()))
    }
}

/// One direction of a Modbus TCP stream: the converter's MBAP receiver, fed once the transaction
/// identifier is known (it drops frames of another transaction), and the frame's bytes so far.
#[derive(Default)]
struct MbapSide {
    decoder: mbap::Decoder,
    raw: Vec<u8>,
    frame: heapless::Vec<u8, ADU_CAPACITY>,
}

impl MbapSide {
    fn push(&mut self, tx: bool, bytes: &[u8], out: &mut Vec<Piece>) {
        for &b in bytes {
            self.raw.push(b);
            // The receiver expects one transaction: it is told the frame's own once its first
            // two bytes are in, and given them then.
            let step = match *self.raw.as_slice() {
                [_] => continue,
                [t0, t1] => {
                    self.decoder.expect(u16::from_be_bytes([t0, t1]));
                    self.decoder.push(t0, &mut self.frame);
                    self.decoder.push(t1, &mut self.frame)
                }
                _ => self.decoder.push(b, &mut self.frame),
            };
            match step {
                mbap::Step::Pending => {}
                mbap::Step::Frame => {
                    let transaction = self.raw.get(..2).map_or(0, |t| u16::from_be_bytes([t[0], t[1]]));
                    let text = modbus_text(tx, &rtu_adu(&self.frame), "Modbus TCP");
                    let text = format!("{text} (transaction {transaction})");
                    out.push((std::mem::take(&mut self.raw), text));
                }
                // Not expected: the receiver was told this frame's transaction.
                mbap::Step::Skipped(_) => {
                    out.push((std::mem::take(&mut self.raw), "not a Modbus TCP frame".into()));
                }
                mbap::Step::Error(e) => {
                    out.push((std::mem::take(&mut self.raw), format!("not a Modbus TCP frame: {e}")));
                }
            }
        }
    }

    /// What is left, cut short by the other direction.
    fn cut(&mut self) -> Option<Piece> {
        self.decoder.expect(0);
        (!self.raw.is_empty()).then(|| (std::mem::take(&mut self.raw), "incomplete frame".into()))
    }
}

/// The decoder: one byte stream per direction, cut into frames by the profile.
pub struct Decoder {
    profile: LineProfile,
    tx: Vec<u8>,
    rx: Vec<u8>,
    tx_frames: FrameParser<FRAME_CAPACITY>,
    rx_frames: FrameParser<FRAME_CAPACITY>,
    ascii: [AsciiSide; 2],
    mbap: [MbapSide; 2],
}

impl Decoder {
    /// A decoder for `profile`.
    pub fn new(profile: LineProfile) -> Decoder {
        // The breaker's framing is valid (a slave_fw test holds it); `expect` cannot fire.
        let parser = || FrameParser::new(breaker::FRAMING).expect("the breaker framing is valid");
        Decoder {
            profile,
            tx: Vec::new(),
            rx: Vec::new(),
            tx_frames: parser(),
            rx_frames: parser(),
            ascii: Default::default(),
            mbap: Default::default(),
        }
    }

    /// The profile it decodes by.
    pub fn profile(&self) -> LineProfile {
        self.profile
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
        let other_name = if tx { "rx" } else { "tx" };
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
            LineProfile::ModbusRtu => self.push_rtu(tx, entry.bytes(), line),
            LineProfile::ModbusAscii | LineProfile::ModbusTcp => {
                let (this, other) = if tx { (0, 1) } else { (1, 0) };
                let mut out = Vec::new();
                // As for RTU: a frame of one direction ends what is left of the other.
                let cut = match self.profile {
                    LineProfile::ModbusAscii => self.ascii[other].cut(),
                    _ => self.mbap[other].cut(),
                };
                out.extend(cut.map(|(bytes, why)| line(other_name, &bytes, why)));
                let mut pieces = Vec::new();
                match self.profile {
                    LineProfile::ModbusAscii => self.ascii[this].push(tx, entry.bytes(), &mut pieces),
                    _ => self.mbap[this].push(tx, entry.bytes(), &mut pieces),
                }
                out.extend(pieces.into_iter().map(|(bytes, text)| line(name, &bytes, text)));
                out
            }
        }
    }

    fn push_rtu(
        &mut self,
        tx: bool,
        bytes: &[u8],
        line: impl Fn(&'static str, &[u8], String) -> TraceLine,
    ) -> Vec<TraceLine> {
        let name = if tx { "tx" } else { "rx" };
        let mut out = Vec::new();
        // A request ends the response before it, and a response the request: what is left of
        // the other direction was cut short.
        let other = if tx { &mut self.rx } else { &mut self.tx };
        if !other.is_empty() {
            let other_name = if tx { "rx" } else { "tx" };
            out.push(line(other_name, &std::mem::take(other), "incomplete frame".into()));
        }
        let buf = if tx { &mut self.tx } else { &mut self.rx };
        buf.extend_from_slice(bytes);
        loop {
            let len = if tx { pdu::request_len(buf) } else { pdu::response_len(buf) };
            match len {
                Ok(Some(n)) if n <= buf.len() => {
                    let adu: Vec<u8> = buf.drain(..n).collect();
                    out.push(line(name, &adu, modbus_text(tx, &adu, "Modbus RTU")));
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

/// The RTU ADU of a Modbus ASCII or TCP frame's address (unit) and PDU: the same bytes with their
/// CRC-16 appended, so the RTU request and response parsers name them. A thin adapter: the
/// converter's ASCII and MBAP receivers give the address and PDU without a checksum, and its PDU
/// parsers take a whole RTU ADU.
pub fn rtu_adu(frame: &[u8]) -> Vec<u8> {
    let mut adu = frame.to_vec();
    adu.extend_from_slice(&slave_fw::serial::checksum::crc16_modbus(frame).to_le_bytes());
    adu
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

/// A Modbus RTU ADU (or the RTU form of an ASCII or TCP frame, [`rtu_adu`]), named; `framing`
/// names the framing in the error.
fn modbus_text(tx: bool, adu: &[u8], framing: &str) -> String {
    let parsed = if tx {
        MbRequest::parse(adu).map(|(unit, r)| format!("request unit {unit}: {}", request_text(&r)))
    } else {
        MbResponse::parse(adu).map(|(unit, r)| format!("response unit {unit}: {}", response_text(&r)))
    };
    parsed.unwrap_or_else(|e| format!("not a {framing} frame: {e}"))
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

#[cfg(test)]
mod tests;
