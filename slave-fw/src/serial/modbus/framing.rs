//! How the master's requests and responses travel: RTU (binary, CRC-16), ASCII (hexadecimal
//! characters, LRC) or Modbus TCP (MBAP header). The master builds and reads the address and PDU
//! the same way for all three; for ASCII and TCP its framer wraps each request for the line and
//! unwraps responses into the address and PDU. RTU frames the master delimits itself.

use super::ascii::{self, AsciiError};
use super::mbap::{self, MbapError};
use super::pdu::ADU_CAPACITY;
use devicenet::Instant;
use heapless::Vec;

/// The framing of the Modbus profile (`[profile.modbus] framing`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Framing {
    /// Modbus RTU: binary, CRC-16, frames delimited by silence (Modbus over Serial Line V1.02
    /// §2.5.1).
    #[default]
    Rtu,
    /// Modbus ASCII: `:`, hexadecimal characters, LRC, CR LF (§2.5.2).
    Ascii,
    /// Modbus TCP: MBAP header and PDU, no checksum (Modbus Messaging on TCP/IP Implementation
    /// Guide V1.0b); only where the serial port is a TCP stream (the soft slave's
    /// `--serial tcp:HOST:PORT`).
    Tcp,
}

/// The longest frame any framing writes: an ASCII frame (513 bytes).
pub const WIRE_CAPACITY: usize = ascii::FRAME_CAPACITY;

// The longest RTU ADU and Modbus TCP ADU fit too.
const _: () = assert!(ADU_CAPACITY <= WIRE_CAPACITY && mbap::FRAME_CAPACITY <= WIRE_CAPACITY);

/// Why a response was dropped by its framing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrameError {
    /// An ASCII frame error.
    Ascii(AsciiError),
    /// A Modbus TCP header error.
    Mbap(MbapError),
}

impl FrameError {
    /// Whether the error is a checksum mismatch (counted with RTU's CRC errors).
    pub fn is_checksum(&self) -> bool {
        matches!(self, FrameError::Ascii(AsciiError::Lrc { .. }))
    }
}

/// What one received byte did, for the ASCII and TCP framings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Received {
    /// Nothing complete yet.
    Pending,
    /// Bytes not part of the awaited response, dropped.
    Skipped(usize),
    /// A response is complete: the receive buffer holds its address (unit) and PDU.
    Frame,
    /// The response being received is dropped.
    Error(FrameError),
}

/// The wire side of the ASCII and TCP framings: the framed request, the decoders, the
/// transaction counter and the ASCII inter-character timeout.
#[derive(Clone, Debug)]
pub(crate) struct Framer {
    framing: Framing,
    wire: [u8; WIRE_CAPACITY],
    wire_len: usize,
    ascii: ascii::Decoder,
    mbap: mbap::Decoder,
    transaction: u16,
    /// The ASCII frame being received is lost if no character arrives before this instant.
    char_deadline: Option<Instant>,
}

impl Framer {
    pub(crate) fn new(framing: Framing) -> Self {
        Framer {
            framing,
            wire: [0; WIRE_CAPACITY],
            wire_len: 0,
            ascii: ascii::Decoder::default(),
            mbap: mbap::Decoder::default(),
            transaction: 0,
            char_deadline: None,
        }
    }

    /// Whether the master delimits frames itself (RTU) rather than through this framer.
    pub(crate) fn is_rtu(&self) -> bool {
        self.framing == Framing::Rtu
    }

    /// Frames `frame` (address and PDU) for the line, starts expecting its response, and returns
    /// the bytes to send; empty when it cannot be framed (not for a frame the master built).
    pub(crate) fn wrap(&mut self, frame: &[u8]) -> &[u8] {
        self.char_deadline = None;
        self.ascii.reset();
        let n = match self.framing {
            Framing::Rtu => None,
            Framing::Ascii => ascii::encode(frame, &mut self.wire),
            Framing::Tcp => {
                self.transaction = self.transaction.wrapping_add(1);
                self.mbap.expect(self.transaction);
                mbap::encode(self.transaction, frame, &mut self.wire)
            }
        };
        self.wire_len = n.unwrap_or(0);
        self.wire.get(..self.wire_len).unwrap_or(&[])
    }

    /// The last framed request.
    pub(crate) fn wire(&self) -> &[u8] {
        self.wire.get(..self.wire_len).unwrap_or(&[])
    }

    /// Takes byte `b` received at `now` into `rx`.
    pub(crate) fn push(&mut self, b: u8, rx: &mut Vec<u8, ADU_CAPACITY>, now: Instant) -> Received {
        match self.framing {
            Framing::Rtu => Received::Skipped(1),
            Framing::Ascii => {
                let step = self.ascii.push(b, rx);
                self.char_deadline = self.ascii.in_frame().then(|| now + ascii::CHAR_TIMEOUT);
                match step {
                    ascii::Step::Pending => Received::Pending,
                    ascii::Step::Skipped => Received::Skipped(1),
                    ascii::Step::Frame => Received::Frame,
                    ascii::Step::Error(e) => Received::Error(FrameError::Ascii(e)),
                }
            }
            Framing::Tcp => match self.mbap.push(b, rx) {
                mbap::Step::Pending => Received::Pending,
                mbap::Step::Skipped(n) => Received::Skipped(n),
                mbap::Step::Frame => Received::Frame,
                mbap::Step::Error(e) => Received::Error(FrameError::Mbap(e)),
            },
        }
    }

    /// The ASCII inter-character timeout: an error once, at or after [`Framer::poll_at`].
    pub(crate) fn poll(&mut self, now: Instant) -> Option<FrameError> {
        if self.char_deadline.is_some_and(|d| now >= d) {
            self.char_deadline = None;
            self.ascii.reset();
            return Some(FrameError::Ascii(AsciiError::CharTimeout));
        }
        None
    }

    /// When the ASCII frame being received times out.
    pub(crate) fn poll_at(&self) -> Option<Instant> {
        self.char_deadline
    }
}
