//! Modbus ASCII framing (Modbus over Serial Line V1.02 §2.5.2): a frame is `:`, the address and
//! the PDU as two upper-case hexadecimal characters per byte, the LRC the same way, then CR LF.
//!
//! * [`lrc`]: the Longitudinal Redundancy Check, the two's complement of the 8-bit sum of the
//!   address and PDU bytes (§2.5.2.2, §6.2.1).
//! * [`encode`]: writes the frame for an address and PDU.
//! * [`Decoder`]: takes received characters one at a time and writes the address and PDU of a
//!   complete frame whose LRC checks into the caller's buffer.
//!
//! ## Rules kept, and where the decoder is lenient
//!
//! * A `:` always starts a new frame; one received inside a frame discards that frame (§2.5.2.1,
//!   the state diagram's "reception of `:` character" in every state), reported as
//!   [`AsciiError::Interrupted`].
//! * Characters outside a frame are skipped ([`Step::Skipped`]).
//! * Hexadecimal digits are accepted in either case (the spec sends upper case; a lenient
//!   receiver loses nothing).
//! * The end is CR then LF. The spec allows the LF to be changed by function 8 sub-function 3;
//!   this master never sends that, so the end is always LF.
//! * The inter-character timeout (1 s unless configured longer, §2.5.2.1) needs a clock, which
//!   the decoder does not read: [`CHAR_TIMEOUT`] is applied by the master.
//!
//! ## No-panic contract
//!
//! [`Decoder::push`] accepts any byte in any state: it never panics and never writes more than
//! [`MAX_DECODED`] bytes into its buffer.

use super::pdu::ADU_CAPACITY;
use core::fmt;
use devicenet::Duration;
use heapless::Vec;

/// The most bytes a frame carries between `:` and CR LF, decoded: the address, a PDU of up to
/// 253 bytes and the LRC.
pub const MAX_DECODED: usize = 1 + 253 + 1;
/// The longest frame on the line: `:`, two characters per decoded byte, CR LF (513, §2.5.2.1).
pub const FRAME_CAPACITY: usize = 1 + 2 * MAX_DECODED + 2;
/// The longest silence allowed between two characters of one frame (§2.5.2.1: "intervals of up
/// to one second may elapse between characters within the message").
pub const CHAR_TIMEOUT: Duration = Duration::from_millis(1000);

// The decoder writes the address, PDU and LRC into an ADU-sized buffer.
const _: () = assert!(MAX_DECODED <= ADU_CAPACITY);

/// The LRC of `bytes` (address and PDU): the two's complement of their 8-bit sum (§6.2.1).
pub fn lrc(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |sum, &b| sum.wrapping_add(b)).wrapping_neg()
}

/// Writes the ASCII frame of `frame` (address and PDU, no checksum) into `out` and returns its
/// length; `None` when `frame` is shorter than an address and a function code, longer than an
/// address and a 253-byte PDU, or `out` is too short.
pub fn encode(frame: &[u8], out: &mut [u8]) -> Option<usize> {
    if frame.len() < 2 || frame.len() >= MAX_DECODED {
        return None;
    }
    let len = 1 + 2 * (frame.len() + 1) + 2;
    let (start, rest) = out.get_mut(..len)?.split_first_mut()?;
    *start = b':';
    let (body, end) = rest.split_at_mut_checked(len - 3)?;
    let check = lrc(frame);
    for (pair, &b) in body.chunks_exact_mut(2).zip(frame.iter().chain([&check])) {
        if let [high, low] = pair {
            *high = hex_digit(b >> 4);
            *low = hex_digit(b & 0x0F);
        }
    }
    if let [cr, lf] = end {
        (*cr, *lf) = (b'\r', b'\n');
    }
    Some(len)
}

/// Why a received ASCII frame was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AsciiError {
    /// A character other than a hexadecimal digit, CR or `:` inside a frame (the character).
    BadHex(u8),
    /// CR not followed by LF (the character that followed).
    MissingLf(u8),
    /// An odd number of hexadecimal characters before CR.
    OddLength,
    /// Fewer than three bytes (address, function, LRC).
    TooShort,
    /// More than [`MAX_DECODED`] bytes before CR.
    TooLong,
    /// The LRC does not match.
    Lrc {
        /// The LRC of the received address and PDU.
        expected: u8,
        /// The LRC received.
        found: u8,
    },
    /// A `:` inside a frame: the frame so far is dropped and a new one starts.
    Interrupted,
    /// More than the inter-character timeout between two characters of a frame.
    CharTimeout,
}

impl fmt::Display for AsciiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AsciiError::BadHex(c) => write!(f, "character 0x{c:02X} inside an ASCII frame"),
            AsciiError::MissingLf(c) => write!(f, "CR followed by 0x{c:02X}, not LF"),
            AsciiError::OddLength => f.write_str("odd number of hexadecimal characters"),
            AsciiError::TooShort => f.write_str("ASCII frame shorter than address, function and LRC"),
            AsciiError::TooLong => write!(f, "ASCII frame longer than {MAX_DECODED} bytes"),
            AsciiError::Lrc { expected, found } => {
                write!(f, "LRC 0x{found:02X} received, 0x{expected:02X} computed")
            }
            AsciiError::Interrupted => f.write_str("':' inside an ASCII frame"),
            AsciiError::CharTimeout => f.write_str("inter-character timeout inside an ASCII frame"),
        }
    }
}

impl core::error::Error for AsciiError {}

/// What one received character did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Taken into the frame being received (or its start or end so far).
    Pending,
    /// Outside any frame: not part of a frame, dropped.
    Skipped,
    /// A frame is complete and its LRC checks: the buffer holds its address and PDU.
    Frame,
    /// The frame being received is dropped.
    Error(AsciiError),
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum State {
    /// Waiting for `:`.
    #[default]
    Idle,
    /// Inside a frame; the high nibble of a byte whose low nibble is due.
    Frame(Option<u8>),
    /// CR received, LF due.
    Cr,
}

/// A receiver of ASCII frames, one character at a time (see the [module docs](self)).
#[derive(Clone, Copy, Debug, Default)]
pub struct Decoder {
    state: State,
}

impl Decoder {
    /// Whether a frame has started and not yet ended (the inter-character timeout runs).
    pub fn in_frame(&self) -> bool {
        self.state != State::Idle
    }

    /// Drops any frame being received.
    pub fn reset(&mut self) {
        self.state = State::Idle;
    }

    /// Takes character `c`; the decoded bytes of the frame go into `out`, which holds the address
    /// and PDU (the LRC removed) when [`Step::Frame`] is returned.
    pub fn push(&mut self, c: u8, out: &mut Vec<u8, ADU_CAPACITY>) -> Step {
        if c == b':' {
            let interrupted = self.in_frame();
            out.clear();
            self.state = State::Frame(None);
            return if interrupted { Step::Error(AsciiError::Interrupted) } else { Step::Pending };
        }
        match self.state {
            State::Idle => Step::Skipped,
            State::Frame(high) if c == b'\r' => {
                if high.is_some() {
                    return self.fail(AsciiError::OddLength);
                }
                self.state = State::Cr;
                Step::Pending
            }
            State::Frame(high) => {
                let Some(nibble) = hex_value(c) else {
                    return self.fail(AsciiError::BadHex(c));
                };
                match high {
                    None => self.state = State::Frame(Some(nibble)),
                    Some(h) => {
                        if out.len() >= MAX_DECODED || out.push(h << 4 | nibble).is_err() {
                            return self.fail(AsciiError::TooLong);
                        }
                        self.state = State::Frame(None);
                    }
                }
                Step::Pending
            }
            State::Cr if c != b'\n' => self.fail(AsciiError::MissingLf(c)),
            State::Cr => {
                self.state = State::Idle;
                if out.len() < 3 {
                    return Step::Error(AsciiError::TooShort);
                }
                let found = out.pop().unwrap_or(0);
                let expected = lrc(out);
                if found == expected {
                    Step::Frame
                } else {
                    Step::Error(AsciiError::Lrc { expected, found })
                }
            }
        }
    }

    fn fail(&mut self, e: AsciiError) -> Step {
        self.state = State::Idle;
        Step::Error(e)
    }
}

/// The upper-case hexadecimal digit of `nibble` (`0..=15`).
fn hex_digit(nibble: u8) -> u8 {
    if nibble < 10 {
        b'0' + nibble
    } else {
        b'A' + (nibble - 10)
    }
}

fn hex_value(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'A'..=b'F' => Some(c - b'A' + 10),
        b'a'..=b'f' => Some(c - b'a' + 10),
        _ => None,
    }
}

#[cfg(test)]
mod tests;
