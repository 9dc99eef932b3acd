//! Modbus TCP framing: the MBAP header (Modbus Messaging on TCP/IP Implementation Guide V1.0b
//! §3.1.3) in front of the PDU.
//!
//! ```text
//! offset  size  field
//! 0       2     transaction identifier (the client's; copied by the server into its response)
//! 2       2     protocol identifier, 0 for Modbus
//! 4       2     length: the bytes that follow (unit identifier and PDU)
//! 6       1     unit identifier (the device behind a gateway; copied into the response)
//! 7       n     PDU (function code and data, up to 253 bytes)
//! ```
//!
//! All fields big-endian. There is no checksum: TCP delivers the bytes intact. [`encode`] writes
//! a request; [`Decoder`] takes response bytes one at a time and writes the unit identifier and
//! PDU of a complete response to the expected transaction into the caller's buffer, the same
//! bytes an RTU frame carries before its CRC.
//!
//! ## No-panic contract
//!
//! [`Decoder::push`] accepts any byte in any state: it never panics and never writes more than
//! the unit identifier and a 253-byte PDU into its buffer.

use super::pdu::ADU_CAPACITY;
use core::fmt;
use heapless::Vec;

/// Bytes of the MBAP header, the unit identifier included.
pub const HEADER_LEN: usize = 7;
/// The most bytes a PDU carries.
pub const MAX_PDU: usize = 253;
/// The longest Modbus TCP ADU: header and PDU (260).
pub const FRAME_CAPACITY: usize = HEADER_LEN + MAX_PDU;

// The decoder writes the unit identifier and PDU into an ADU-sized buffer.
const _: () = assert!(MAX_PDU < ADU_CAPACITY);

/// Writes the Modbus TCP ADU for `frame` (unit identifier and PDU, as an RTU frame without its
/// CRC) with `transaction` into `out` and returns its length; `None` when `frame` has no PDU, a
/// PDU over [`MAX_PDU`] bytes, or `out` is too short.
pub fn encode(transaction: u16, frame: &[u8], out: &mut [u8]) -> Option<usize> {
    let (&unit, pdu) = frame.split_first()?;
    if pdu.is_empty() || pdu.len() > MAX_PDU {
        return None;
    }
    let len = HEADER_LEN + pdu.len();
    let (header, body) = out.get_mut(..len)?.split_first_chunk_mut::<HEADER_LEN>()?;
    let [t_hi, t_lo] = transaction.to_be_bytes();
    let [l_hi, l_lo] = (frame.len() as u16).to_be_bytes();
    *header = [t_hi, t_lo, 0, 0, l_hi, l_lo, unit];
    body.copy_from_slice(pdu);
    Some(len)
}

/// Why a received Modbus TCP frame was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MbapError {
    /// A protocol identifier other than 0 (the value).
    Protocol(u16),
    /// A length field below 2 (unit and function) or above 254 (unit and a 253-byte PDU).
    Length(u16),
}

impl fmt::Display for MbapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MbapError::Protocol(p) => write!(f, "MBAP protocol identifier {p}, not 0"),
            MbapError::Length(n) => write!(f, "MBAP length {n} outside 2..=254"),
        }
    }
}

impl core::error::Error for MbapError {}

/// What one received byte did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Taken into the frame being received.
    Pending,
    /// A whole, well-formed frame answering another transaction (a late answer to a request
    /// given up): dropped, its bytes not part of the expected response.
    Skipped(usize),
    /// A frame of the expected transaction is complete: the buffer holds its unit identifier
    /// and PDU.
    Frame,
    /// The header is malformed: the frame is dropped.
    Error(MbapError),
}

/// A receiver of Modbus TCP responses, one byte at a time (see the [module docs](self)).
#[derive(Clone, Copy, Debug, Default)]
pub struct Decoder {
    header: [u8; HEADER_LEN],
    /// Header bytes received so far (`HEADER_LEN`: the PDU is being received).
    have: usize,
    /// The transaction identifier a response must carry.
    expected: u16,
}

impl Decoder {
    /// Expects the response to `transaction` next, dropping any frame being received.
    pub fn expect(&mut self, transaction: u16) {
        self.expected = transaction;
        self.have = 0;
    }

    fn length(&self) -> usize {
        usize::from(u16::from_be_bytes([self.header[4], self.header[5]]))
    }

    /// Takes byte `b`; the unit identifier and PDU go into `out`, which holds them when
    /// [`Step::Frame`] is returned.
    pub fn push(&mut self, b: u8, out: &mut Vec<u8, ADU_CAPACITY>) -> Step {
        if let Some(slot) = self.header.get_mut(self.have) {
            *slot = b;
            self.have += 1;
            if self.have < HEADER_LEN {
                return Step::Pending;
            }
            let protocol = u16::from_be_bytes([self.header[2], self.header[3]]);
            let length = self.length();
            self.have = if protocol != 0 || !(2..=1 + MAX_PDU).contains(&length) { 0 } else { HEADER_LEN };
            if protocol != 0 {
                return Step::Error(MbapError::Protocol(protocol));
            }
            if self.have == 0 {
                return Step::Error(MbapError::Length(length as u16));
            }
            out.clear();
            // The length checked above fits the buffer.
            let _ = out.push(self.header[6]);
            return Step::Pending;
        }
        if out.push(b).is_err() {
            // Unreachable: the length was bounded when the header was complete.
            self.have = 0;
            return Step::Error(MbapError::Length(self.length() as u16));
        }
        if out.len() < self.length() {
            return Step::Pending;
        }
        self.have = 0;
        if u16::from_be_bytes([self.header[0], self.header[1]]) == self.expected {
            Step::Frame
        } else {
            let n = HEADER_LEN - 1 + out.len();
            out.clear();
            Step::Skipped(n)
        }
    }
}

#[cfg(test)]
mod tests;
