//! Fragmentation: the acknowledged protocol that carries explicit messages longer than one frame,
//! and the unacknowledged one that carries I/O data on connections larger than 8 bytes
//! (protocol §4.1, §4.2).
//!
//! Both protocols put a *fragmentation byte* ([`FragmentByte`]) in front of every piece: bits 7–6
//! the type ([`FragmentKind`]: first, middle, last, ack), bits 5–0 the count.
//!
//! | protocol | frame data | acknowledged | sender | receiver |
//! |---|---|---|---|---|
//! | explicit (§4.1) | `[header \| 0x80, fragment byte, ≤ 6 body bytes]` | every fragment, `[header \| 0x80, C0 \| count, status]` | [`ExplicitTransmitter`] | [`ExplicitReassembler`] |
//! | I/O (§4.2) | `[fragment byte, ≤ 7 data bytes]` | never; back to back | [`io_fragments`] | [`IoReassembler`] |
//!
//! ## Counts
//!
//! The first fragment has count 0 and each following one counts up by one. After 63 the count
//! wraps to 0: the rollover target is **UNCONFIRMED** (protocol §4.1, §9.4); AN wraps 63 → 0 and this
//! crate does the same. A first fragment with count 0x3F ([`SINGLE_FRAGMENT_COUNT`]) is a
//! one-frame series: that frame holds the whole message.
//!
//! ## Driving the explicit transmitter
//!
//! [`ExplicitTransmitter`] is a sans-IO state machine. After [`start`](ExplicitTransmitter::start),
//! and whenever an ack arrives or [`poll_at`](ExplicitTransmitter::poll_at) is reached:
//!
//! 1. feed received ack frames to [`handle_ack`](ExplicitTransmitter::handle_ack);
//! 2. send what [`poll_transmit`](ExplicitTransmitter::poll_transmit) returns;
//! 3. drain [`poll_event`](ExplicitTransmitter::poll_event);
//! 4. sleep until [`poll_at`](ExplicitTransmitter::poll_at).
//!
//! ## No-panic contract
//!
//! Every parser and both reassemblers accept any byte slice (empty, over-long, any type and count)
//! and answer with a value or a [`FragmentError`]. Memory is fixed by the const generic `N`: a
//! series that would grow past it is refused, never truncated and never allowed to overrun.

use crate::explicit::Header;
use crate::time::{Duration, Instant};
use core::fmt;
use core::iter::FusedIterator;

/// Up to 8 bytes of CAN frame data.
pub type Payload = heapless::Vec<u8, 8>;

/// How long the explicit sender waits for the ack of a fragment before re-sending it once, and
/// then again before giving up (protocol §4.1: JB uses 1 s and one retry; the normative values are
/// UNCONFIRMED, protocol §9.4).
pub const ACK_TIMEOUT: Duration = Duration::from_secs(1);

/// The count of a first fragment that is the whole message (a one-frame series, protocol §4.1, §4.2).
pub const SINGLE_FRAGMENT_COUNT: u8 = 0x3F;

/// Message body bytes carried by one explicit fragment (protocol §4.1).
pub const EXPLICIT_FRAGMENT_BODY: usize = 6;

/// Data bytes carried by one I/O fragment (protocol §4.2).
pub const IO_FRAGMENT_DATA: usize = 7;

/// The fragmentation bit of the explicit header byte (protocol §3.1).
const FRAG_BIT: u8 = 0x80;

/// The count field of the fragmentation byte.
const COUNT_MASK: u8 = 0x3F;

/// Why a fragment was dropped, or a transfer could not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FragmentError {
    /// The frame is too short to hold the header bytes of a fragment.
    FrameTooShort(usize),
    /// The frame data is longer than the 8 bytes of a CAN frame.
    FrameTooLong(usize),
    /// An explicit frame without the fragmentation bit.
    NotFragmented,
    /// An ack-type fragment where a data fragment was expected (always so on I/O connections).
    UnexpectedAck,
    /// A first fragment whose count is neither 0 nor 0x3F; the series was reset.
    FirstCountNotZero(u8),
    /// A middle or last fragment without a first fragment before it.
    NoFirstFragment,
    /// A fragment with the wrong count; the partial series was discarded.
    OutOfSequence {
        /// The count that was expected next.
        expected: u8,
        /// The count received.
        got: u8,
    },
    /// The reassembled data would exceed the receiver's capacity; the series was discarded.
    Overflow {
        /// The receiver's capacity in bytes.
        max: usize,
    },
    /// The message to send is longer than the transmitter's capacity.
    MessageTooLong {
        /// The message length.
        len: usize,
        /// The transmitter's capacity.
        max: usize,
    },
    /// The message to send fits in one unfragmented frame (at most 8 bytes).
    FitsInOneFrame(usize),
    /// A transfer is already in progress.
    Busy,
}

impl fmt::Display for FragmentError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FragmentError::FrameTooShort(n) => write!(f, "{n}-byte frame is too short for a fragment"),
            FragmentError::FrameTooLong(n) => write!(f, "{n} data bytes, a CAN frame holds at most 8"),
            FragmentError::NotFragmented => f.write_str("explicit frame without the fragmentation bit"),
            FragmentError::UnexpectedAck => f.write_str("ack-type fragment where data was expected"),
            FragmentError::FirstCountNotZero(c) => write!(f, "first fragment with count {c}"),
            FragmentError::NoFirstFragment => f.write_str("middle or last fragment without a first"),
            FragmentError::OutOfSequence { expected, got } => {
                write!(f, "fragment count {got} out of sequence, expected {expected}")
            }
            FragmentError::Overflow { max } => write!(f, "fragment series exceeds {max} bytes"),
            FragmentError::MessageTooLong { len, max } => {
                write!(f, "{len}-byte message exceeds the {max}-byte transmit buffer")
            }
            FragmentError::FitsInOneFrame(n) => write!(f, "{n}-byte message fits in one frame"),
            FragmentError::Busy => f.write_str("a fragmented transfer is already in progress"),
        }
    }
}

impl core::error::Error for FragmentError {}

/// The type field of the fragmentation byte, bits 7–6 (protocol §4.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FragmentKind {
    /// 0: first fragment.
    First,
    /// 1: middle fragment.
    Middle,
    /// 2: last fragment.
    Last,
    /// 3: acknowledgement (explicit fragmentation only).
    Ack,
}

impl FragmentKind {
    /// The kind for the two low bits of `bits`.
    pub const fn from_bits(bits: u8) -> FragmentKind {
        match bits & 0b11 {
            0 => FragmentKind::First,
            1 => FragmentKind::Middle,
            2 => FragmentKind::Last,
            _ => FragmentKind::Ack,
        }
    }

    /// The two-bit type code.
    pub const fn bits(self) -> u8 {
        match self {
            FragmentKind::First => 0,
            FragmentKind::Middle => 1,
            FragmentKind::Last => 2,
            FragmentKind::Ack => 3,
        }
    }
}

impl fmt::Display for FragmentKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FragmentKind::First => "first",
            FragmentKind::Middle => "middle",
            FragmentKind::Last => "last",
            FragmentKind::Ack => "ack",
        })
    }
}

/// The fragmentation protocol byte: `type(7–6) | count(5–0)` (protocol §4.1, §4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FragmentByte {
    /// The fragment type.
    pub kind: FragmentKind,
    /// The fragment count, `0..=63`; [`FragmentByte::to_byte`] keeps only its low six bits.
    pub count: u8,
}

impl FragmentByte {
    /// `Some` when `count` fits in six bits.
    pub const fn new(kind: FragmentKind, count: u8) -> Option<FragmentByte> {
        if count <= COUNT_MASK {
            Some(FragmentByte { kind, count })
        } else {
            None
        }
    }

    /// Decodes a fragmentation byte; every byte is valid.
    pub const fn from_byte(b: u8) -> FragmentByte {
        FragmentByte { kind: FragmentKind::from_bits(b >> 6), count: b & COUNT_MASK }
    }

    /// Encodes the fragmentation byte.
    pub const fn to_byte(self) -> u8 {
        self.kind.bits() << 6 | (self.count & COUNT_MASK)
    }

    /// `true` for a first fragment with count 0x3F: a one-frame series.
    pub const fn is_single(self) -> bool {
        matches!(self.kind, FragmentKind::First) && self.count == SINGLE_FRAGMENT_COUNT
    }
}

impl fmt::Display for FragmentByte {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} #{}", self.kind, self.count)
    }
}

/// The count that follows `count`: +1, wrapping 63 → 0 (rollover target UNCONFIRMED, protocol §9.4).
pub const fn next_count(count: u8) -> u8 {
    count.wrapping_add(1) & COUNT_MASK
}

/// The status byte of an explicit fragment ack (protocol §4.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AckStatus {
    /// 0: fragment received.
    Success,
    /// 1: the message exceeds the receiver's limit.
    TooMuchData,
    /// Any other (reserved) value, kept as received.
    Unknown(u8),
}

impl From<u8> for AckStatus {
    fn from(raw: u8) -> AckStatus {
        match raw {
            0 => AckStatus::Success,
            1 => AckStatus::TooMuchData,
            other => AckStatus::Unknown(other),
        }
    }
}

impl From<AckStatus> for u8 {
    fn from(s: AckStatus) -> u8 {
        match s {
            AckStatus::Success => 0,
            AckStatus::TooMuchData => 1,
            AckStatus::Unknown(raw) => raw,
        }
    }
}

impl fmt::Display for AckStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AckStatus::Success => f.write_str("success (0x00)"),
            AckStatus::TooMuchData => f.write_str("too much data (0x01)"),
            AckStatus::Unknown(raw) => write!(f, "reserved (0x{raw:02X})"),
        }
    }
}

/// Frame data made of `prefix` then `rest`, cut at 8 bytes.
fn payload(prefix: &[u8], rest: &[u8]) -> Payload {
    let mut p = Payload::new();
    for &b in prefix.iter().chain(rest) {
        if p.push(b).is_err() {
            break;
        }
    }
    p
}

/// The ack frame data `[header | 0x80, C0 | count, status]` (protocol §4.1).
pub fn ack_frame(header: Header, count: u8, status: AckStatus) -> Payload {
    let header = Header { fragmented: true, ..header };
    let fragment = FragmentByte { kind: FragmentKind::Ack, count };
    // Three known bytes, not pushed one by one through `payload` (firmware size).
    Payload::from_array([header.to_byte(), fragment.to_byte(), u8::from(status)])
}

/// One explicit fragment frame, parsed: `[header | 0x80, fragment byte, ≤ 6 body bytes]`
/// (protocol §4.1). Acks have the same layout with the status as their only body byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExplicitFragment<'a> {
    /// The header byte (fragmentation bit set).
    pub header: Header,
    /// The fragmentation byte.
    pub fragment: FragmentByte,
    /// The body bytes carried (for an ack: the status byte).
    pub body: &'a [u8],
}

impl<'a> ExplicitFragment<'a> {
    /// Parses the data of one explicit frame; fails when it is shorter than 2 or longer than 8
    /// bytes, or when the header's fragmentation bit is clear.
    // Always inlined: the fragment stays in registers instead of going through a returned
    // `Result` (some 80 bytes of the firmware's flash).
    #[inline(always)]
    pub fn parse(frame: &'a [u8]) -> Result<ExplicitFragment<'a>, FragmentError> {
        if frame.len() > 8 {
            return Err(FragmentError::FrameTooLong(frame.len()));
        }
        match frame {
            [header, fragment, body @ ..] if header & FRAG_BIT != 0 => Ok(ExplicitFragment {
                header: Header::from_byte(*header),
                fragment: FragmentByte::from_byte(*fragment),
                body,
            }),
            [_, _, ..] => Err(FragmentError::NotFragmented),
            _ => Err(FragmentError::FrameTooShort(frame.len())),
        }
    }

    /// The frame data, with the fragmentation bit forced on; bytes beyond 8 are cut.
    pub fn to_payload(&self) -> Payload {
        let header = Header { fragmented: true, ..self.header };
        payload(&[header.to_byte(), self.fragment.to_byte()], self.body)
    }

    /// The status of an ack-type fragment; `None` for other types or an ack without status byte.
    pub fn ack_status(&self) -> Option<AckStatus> {
        match (self.fragment.kind, self.body.first()) {
            (FragmentKind::Ack, Some(&s)) => Some(AckStatus::from(s)),
            _ => None,
        }
    }
}

/// What [`ExplicitReassembler::receive`] asks the caller to do with a fragment.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ExplicitReceive {
    /// Send this ack frame data (`[80|XID|MAC, C0|count, status]`); the series goes on.
    Ack(Payload),
    /// Send this ack; the message is complete, read it with [`ExplicitReassembler::message`].
    Complete(Payload),
    /// Send this ack with status [`AckStatus::TooMuchData`]; the series was dropped (the message
    /// would exceed the reassembler's capacity).
    Rejected(Payload),
    /// A repeated copy of the previously answered fragment: send this ack again (with the status
    /// of the first answer); nothing was appended.
    Duplicate(Payload),
    /// Dropped without an answer, for this reason.
    Ignored(FragmentError),
}

/// Where the receiver is in a series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RxState {
    /// No series.
    Idle,
    /// A series is being reassembled; `next` is the count expected next.
    InProgress { next: u8 },
    /// The last fragment arrived; the message is readable.
    Complete,
}

/// Receiver side of explicit (acknowledged) fragmentation (protocol §4.1).
///
/// `N` is the largest reassembled message in bytes, header included. The receiver follows the
/// rules of JB: a first fragment with a count other than 0 is dropped and reassembly reset; a
/// repeated copy of the previously acked fragment is re-acked but not re-appended; any other count
/// mismatch resets reassembly without an ack; a middle or last fragment without a first is
/// dropped; a first fragment in the middle of a series restarts it (so a re-sent first fragment,
/// whose ack was lost, is simply taken again). A first fragment with count 0x3F is a whole message.
///
/// The caller resets the reassembler when an unfragmented request arrives (protocol §4.1) and
/// filters the header MAC (protocol §8); the header of each ack copies that of the fragment acked.
#[derive(Clone, Debug)]
pub struct ExplicitReassembler<const N: usize> {
    buf: [u8; N],
    len: usize,
    state: RxState,
    /// The last fragment answered and the status it was answered with, to re-ack a repeat.
    last_answer: Option<(FragmentByte, AckStatus)>,
}

impl<const N: usize> Default for ExplicitReassembler<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> ExplicitReassembler<N> {
    /// An idle reassembler.
    pub const fn new() -> Self {
        ExplicitReassembler { buf: [0; N], len: 0, state: RxState::Idle, last_answer: None }
    }

    /// Takes the whole CAN data of one explicit frame whose header has the fragmentation bit set,
    /// `[header, fragment byte, ≤ 6 body bytes]`, and says what to answer.
    ///
    /// After [`ExplicitReceive::Complete`], read [`message`](Self::message) before feeding the
    /// next frame: a new first fragment replaces it.
    pub fn receive(&mut self, frame: &[u8]) -> ExplicitReceive {
        match ExplicitFragment::parse(frame) {
            Ok(frag) => match frag.fragment.kind {
                FragmentKind::Ack => ExplicitReceive::Ignored(FragmentError::UnexpectedAck),
                FragmentKind::First => self.first(&frag),
                FragmentKind::Middle | FragmentKind::Last => self.continuation(&frag),
            },
            Err(e) => ExplicitReceive::Ignored(e),
        }
    }

    fn first(&mut self, frag: &ExplicitFragment<'_>) -> ExplicitReceive {
        self.reset();
        let count = frag.fragment.count;
        if count != 0 && count != SINGLE_FRAGMENT_COUNT {
            return ExplicitReceive::Ignored(FragmentError::FirstCountNotZero(count));
        }
        let header = Header { fragmented: false, ..frag.header };
        if !self.append(&[header.to_byte()]) {
            return self.reject(frag);
        }
        self.accept(frag, frag.fragment.is_single())
    }

    fn continuation(&mut self, frag: &ExplicitFragment<'_>) -> ExplicitReceive {
        let fragment = frag.fragment;
        let expected = match self.state {
            RxState::InProgress { next } => Some(next),
            RxState::Idle | RxState::Complete => None,
        };
        if expected == Some(fragment.count) {
            return self.accept(frag, fragment.kind == FragmentKind::Last);
        }
        match (self.last_answer, expected) {
            (Some((last, status)), _) if last == fragment => {
                ExplicitReceive::Duplicate(ack_frame(frag.header, fragment.count, status))
            }
            (_, Some(expected)) => {
                self.reset();
                ExplicitReceive::Ignored(FragmentError::OutOfSequence { expected, got: fragment.count })
            }
            (_, None) => ExplicitReceive::Ignored(FragmentError::NoFirstFragment),
        }
    }

    /// Appends the body of `frag`, the fragment expected, and acks it; `last` completes the
    /// message. A body that does not fit drops the series ([`reject`](Self::reject)).
    fn accept(&mut self, frag: &ExplicitFragment<'_>, last: bool) -> ExplicitReceive {
        if !self.append(frag.body) {
            return self.reject(frag);
        }
        let fragment = frag.fragment;
        self.last_answer = Some((fragment, AckStatus::Success));
        let ack = ack_frame(frag.header, fragment.count, AckStatus::Success);
        if last {
            self.state = RxState::Complete;
            ExplicitReceive::Complete(ack)
        } else {
            self.state = RxState::InProgress { next: next_count(fragment.count) };
            ExplicitReceive::Ack(ack)
        }
    }

    /// Drops the series and answers `frag` with status "too much data".
    fn reject(&mut self, frag: &ExplicitFragment<'_>) -> ExplicitReceive {
        self.reset();
        self.last_answer = Some((frag.fragment, AckStatus::TooMuchData));
        ExplicitReceive::Rejected(ack_frame(frag.header, frag.fragment.count, AckStatus::TooMuchData))
    }

    // Always inlined: at each call site the length is known or checked already (some 80 bytes of
    // the firmware's flash).
    #[inline(always)]
    fn append(&mut self, bytes: &[u8]) -> bool {
        let end = self.len.saturating_add(bytes.len());
        match self.buf.get_mut(self.len..end) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                self.len = end;
                true
            }
            None => false,
        }
    }

    /// The reassembled message after [`ExplicitReceive::Complete`]: the header byte with the
    /// fragmentation bit cleared, then the whole body (service byte onward). Empty while no
    /// message is complete.
    pub fn message(&self) -> &[u8] {
        match self.state {
            RxState::Complete => self.buf.get(..self.len).unwrap_or(&[]),
            RxState::Idle | RxState::InProgress { .. } => &[],
        }
    }

    /// Drops any series in progress or completed message, and forgets the last answer.
    pub fn reset(&mut self) {
        self.len = 0;
        self.state = RxState::Idle;
        self.last_answer = None;
    }

    /// `true` while a series has begun and its last fragment has not arrived.
    pub fn in_progress(&self) -> bool {
        matches!(self.state, RxState::InProgress { .. })
    }
}

/// What [`ExplicitTransmitter::handle_ack`] made of an ack frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AckOutcome {
    /// The fragment was acked; the next one is due.
    Progress,
    /// The last fragment was acked; the transfer is complete.
    Done,
    /// The ack carried this non-zero status; the transfer is aborted.
    Aborted(AckStatus),
    /// Not an ack for the fragment awaited (wrong count, not an ack, no status, or idle).
    Ignored,
}

/// The end of a transfer, reported by [`ExplicitTransmitter::poll_event`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TransmitEvent {
    /// The last fragment was acked.
    Completed,
    /// The transfer was given up.
    Aborted(AbortReason),
}

/// Why a transfer was given up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AbortReason {
    /// No ack within [`ACK_TIMEOUT`], twice for the same fragment.
    AckTimeout,
    /// The receiver answered with this non-zero status.
    Rejected(AckStatus),
}

/// Where the transmitter is in a transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum TxState {
    /// No transfer.
    Idle,
    /// The current fragment is due since `at` and not sent yet.
    Due { at: Instant },
    /// The current fragment was sent; its ack is awaited until `deadline`.
    AwaitingAck { deadline: Instant, retried: bool },
    /// The transfer ended at `at`; `event` waits for [`ExplicitTransmitter::poll_event`].
    Finished { event: TransmitEvent, at: Instant },
}

/// Sender side of explicit (acknowledged) fragmentation, one transfer at a time (protocol §4.1).
///
/// `N` is the largest message in bytes, header included. Each fragment goes out once its
/// predecessor is acked; a fragment whose ack does not come within [`ACK_TIMEOUT`] is re-sent
/// once, and a second timeout aborts the transfer (JB). See the module docs for the calling order.
#[derive(Clone, Debug)]
pub struct ExplicitTransmitter<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// Offset of the current fragment in the body (`buf[1..len]`).
    offset: usize,
    /// Count of the current fragment.
    count: u8,
    state: TxState,
}

impl<const N: usize> Default for ExplicitTransmitter<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> ExplicitTransmitter<N> {
    /// An idle transmitter.
    pub const fn new() -> Self {
        ExplicitTransmitter { buf: [0; N], len: 0, offset: 0, count: 0, state: TxState::Idle }
    }

    /// Starts sending `message`: the header byte (fragmentation bit clear) followed by the body.
    ///
    /// Fails with [`FragmentError::MessageTooLong`] beyond `N` bytes, with
    /// [`FragmentError::FitsInOneFrame`] at 8 bytes or fewer (those go out unfragmented), and with
    /// [`FragmentError::Busy`] while a transfer is active. An unread [`TransmitEvent`] of the
    /// previous transfer is discarded.
    pub fn start(&mut self, message: &[u8], now: Instant) -> Result<(), FragmentError> {
        if self.is_active() {
            return Err(FragmentError::Busy);
        }
        if message.len() <= 8 {
            return Err(FragmentError::FitsInOneFrame(message.len()));
        }
        let dst = self
            .buf
            .get_mut(..message.len())
            .ok_or(FragmentError::MessageTooLong { len: message.len(), max: N })?;
        dst.copy_from_slice(message);
        self.len = message.len();
        self.offset = 0;
        self.count = 0;
        self.state = TxState::Due { at: now };
        Ok(())
    }

    /// The message body being sent.
    fn body(&self) -> &[u8] {
        self.buf.get(1..self.len).unwrap_or(&[])
    }

    /// The end of the current fragment in the body.
    // Always inlined: it shares its loads with the caller's (some 10 bytes of flash).
    #[inline(always)]
    fn fragment_end(&self) -> usize {
        self.offset.saturating_add(EXPLICIT_FRAGMENT_BODY).min(self.body().len())
    }

    /// Whether the current fragment (the one due, awaiting its ack, or the one a transfer ended
    /// on) is the message's last.
    pub fn is_last_fragment(&self) -> bool {
        self.fragment_end() >= self.body().len()
    }

    /// The current fragment's count (protocol §4.1: 0 for the first, then one more each, modulo
    /// 64).
    pub fn fragment_count(&self) -> u8 {
        self.count
    }

    /// The frame data of the current fragment.
    fn fragment_frame(&self) -> Payload {
        let kind = if self.offset == 0 {
            FragmentKind::First
        } else if self.is_last_fragment() {
            FragmentKind::Last
        } else {
            FragmentKind::Middle
        };
        let header = self.buf.first().copied().unwrap_or(0) | FRAG_BIT;
        let fragment = FragmentByte { kind, count: self.count };
        let chunk = self.body().get(self.offset..self.fragment_end()).unwrap_or(&[]);
        // The two known bytes, then the chunk (at most 6 bytes, so it fits) in one copy, not
        // pushed byte by byte through `payload` (firmware size).
        let mut frame = Payload::from_array([header, fragment.to_byte()]);
        let _ = frame.extend_from_slice(chunk);
        frame
    }

    /// Aborts the transfer when the re-sent fragment's ack is overdue.
    fn expire(&mut self, now: Instant) {
        if let TxState::AwaitingAck { deadline, retried: true } = self.state {
            if now >= deadline {
                self.state =
                    TxState::Finished { event: TransmitEvent::Aborted(AbortReason::AckTimeout), at: now };
            }
        }
    }

    /// The next frame to put on the bus, if one is due at `now`: the first fragment right after
    /// [`start`](Self::start), each following one once its predecessor is acked, and one re-send
    /// of an unacked fragment when [`ACK_TIMEOUT`] has passed. Each frame is
    /// `[header | 0x80, fragment byte, ≤ 6 body bytes]`.
    #[must_use = "the payload is handed out once: a dropped one is never sent"]
    pub fn poll_transmit(&mut self, now: Instant) -> Option<Payload> {
        self.expire(now);
        let retried = match self.state {
            TxState::Due { .. } => false,
            TxState::AwaitingAck { deadline, retried: false } if now >= deadline => true,
            _ => return None,
        };
        self.state = TxState::AwaitingAck { deadline: now + ACK_TIMEOUT, retried };
        Some(self.fragment_frame())
    }

    /// Takes a received ack frame, `[header, C0 | count, status]`.
    ///
    /// The header's XID and MAC are not checked: the caller routes by identifier and owner.
    pub fn handle_ack(&mut self, frame: &[u8], now: Instant) -> AckOutcome {
        self.expire(now);
        if !matches!(self.state, TxState::AwaitingAck { .. }) {
            return AckOutcome::Ignored;
        }
        let Ok(frag) = ExplicitFragment::parse(frame) else {
            return AckOutcome::Ignored;
        };
        let Some(status) = frag.ack_status() else {
            return AckOutcome::Ignored;
        };
        if frag.fragment.count != self.count {
            return AckOutcome::Ignored;
        }
        match status {
            AckStatus::Success if self.is_last_fragment() => {
                self.state = TxState::Finished { event: TransmitEvent::Completed, at: now };
                AckOutcome::Done
            }
            AckStatus::Success => {
                self.offset = self.fragment_end();
                self.count = next_count(self.count);
                self.state = TxState::Due { at: now };
                AckOutcome::Progress
            }
            rejected => {
                let event = TransmitEvent::Aborted(AbortReason::Rejected(rejected));
                self.state = TxState::Finished { event, at: now };
                AckOutcome::Aborted(rejected)
            }
        }
    }

    /// The end of the transfer, once: [`TransmitEvent::Completed`] when the last fragment was
    /// acked, [`TransmitEvent::Aborted`] when an ack had a non-zero status or the re-sent
    /// fragment's ack also timed out.
    #[must_use = "an event is handed out once: a dropped one is lost"]
    pub fn poll_event(&mut self, now: Instant) -> Option<TransmitEvent> {
        self.expire(now);
        match self.state {
            TxState::Finished { event, .. } => {
                self.state = TxState::Idle;
                Some(event)
            }
            _ => None,
        }
    }

    /// When to call [`poll_transmit`](Self::poll_transmit) and [`poll_event`](Self::poll_event)
    /// again: the moment a fragment or an event became due, else the ack deadline; `None` when idle.
    pub fn poll_at(&self) -> Option<Instant> {
        match self.state {
            TxState::Idle => None,
            TxState::Due { at } | TxState::Finished { at, .. } => Some(at),
            TxState::AwaitingAck { deadline, .. } => Some(deadline),
        }
    }

    /// `true` from [`start`](Self::start) until the transfer completes or aborts.
    pub fn is_active(&self) -> bool {
        matches!(self.state, TxState::Due { .. } | TxState::AwaitingAck { .. })
    }

    /// Drops the transfer and any unread event.
    pub fn reset(&mut self) {
        self.len = 0;
        self.offset = 0;
        self.count = 0;
        self.state = TxState::Idle;
    }
}

/// One I/O fragment frame, parsed: `[fragment byte, ≤ 7 data bytes]` (protocol §4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IoFragment<'a> {
    /// The fragmentation byte.
    pub fragment: FragmentByte,
    /// The data bytes carried.
    pub data: &'a [u8],
}

impl<'a> IoFragment<'a> {
    /// Parses the data of one I/O frame; fails when it is empty or longer than 8 bytes.
    pub fn parse(frame: &'a [u8]) -> Result<IoFragment<'a>, FragmentError> {
        if frame.len() > 8 {
            return Err(FragmentError::FrameTooLong(frame.len()));
        }
        match frame.split_first() {
            Some((&b, data)) => Ok(IoFragment { fragment: FragmentByte::from_byte(b), data }),
            None => Err(FragmentError::FrameTooShort(0)),
        }
    }
}

/// The frames of one I/O message on a fragmented connection (produced size > 8, protocol §4.2): the
/// fragment byte and up to 7 data bytes each, back to back.
///
/// 18 bytes give `[00 + 7]`, `[41 + 7]`, `[82 + 4]` (protocol §2, frames 25–27). Data of 7 bytes or
/// fewer is a one-frame series, `[3F + data]`; empty data gives the single frame `[3F]`, so that a
/// zero-length production (whose meaning is UNCONFIRMED, protocol §9.12) still reaches the consumer.
pub fn io_fragments(data: &[u8]) -> IoFragments<'_> {
    IoFragments { data, offset: 0, count: 0, done: false }
}

/// The number of frames [`io_fragments`] yields for `len` data bytes.
pub const fn io_fragment_count(len: usize) -> usize {
    if len <= IO_FRAGMENT_DATA {
        1
    } else {
        len.div_ceil(IO_FRAGMENT_DATA)
    }
}

/// Iterator over the frames of an I/O message, made by [`io_fragments`].
#[derive(Clone, Debug)]
pub struct IoFragments<'a> {
    data: &'a [u8],
    /// Data bytes already yielded.
    offset: usize,
    /// Count of the next fragment.
    count: u8,
    done: bool,
}

impl Iterator for IoFragments<'_> {
    type Item = Payload;

    fn next(&mut self) -> Option<Payload> {
        if self.done {
            return None;
        }
        let len = self.data.len();
        if len <= IO_FRAGMENT_DATA {
            self.done = true;
            let single = FragmentByte { kind: FragmentKind::First, count: SINGLE_FRAGMENT_COUNT };
            return Some(payload(&[single.to_byte()], self.data));
        }
        let end = self.offset.saturating_add(IO_FRAGMENT_DATA).min(len);
        let kind = if self.offset == 0 {
            FragmentKind::First
        } else if end == len {
            FragmentKind::Last
        } else {
            FragmentKind::Middle
        };
        let fragment = FragmentByte { kind, count: self.count };
        let chunk = self.data.get(self.offset..end).unwrap_or(&[]);
        self.offset = end;
        self.count = next_count(self.count);
        self.done = end >= len;
        Some(payload(&[fragment.to_byte()], chunk))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = if self.done {
            0
        } else if self.offset == 0 {
            io_fragment_count(self.data.len())
        } else {
            (self.data.len() - self.offset.min(self.data.len())).div_ceil(IO_FRAGMENT_DATA)
        };
        (n, Some(n))
    }
}

impl ExactSizeIterator for IoFragments<'_> {}

impl FusedIterator for IoFragments<'_> {}

/// Receiver side of I/O (unacknowledged) fragmentation (protocol §4.2).
///
/// `N` is the largest reassembled message in bytes. Any error discards the partial series; a
/// first fragment always starts a new series, also in the middle of one (AN). Duplicated or
/// missing fragments therefore lose the series, and the next first fragment recovers.
#[derive(Clone, Debug)]
pub struct IoReassembler<const N: usize> {
    buf: [u8; N],
    len: usize,
    /// The count expected next while a series is in progress.
    next: Option<u8>,
}

impl<const N: usize> Default for IoReassembler<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> IoReassembler<N> {
    /// An idle reassembler.
    pub const fn new() -> Self {
        IoReassembler { buf: [0; N], len: 0, next: None }
    }

    /// Takes one frame's data: `Ok(Some(data))` when a series completes, `Ok(None)` while one is
    /// in progress, `Err` for an out-of-sequence, ack-type, malformed or overflowing fragment (the
    /// partial series is discarded).
    pub fn receive(&mut self, frame: &[u8]) -> Result<Option<&[u8]>, FragmentError> {
        match self.step(frame) {
            Ok(true) => Ok(Some(self.buf.get(..self.len).unwrap_or(&[]))),
            Ok(false) => Ok(None),
            Err(e) => {
                self.reset();
                Err(e)
            }
        }
    }

    /// Applies one frame; `Ok(true)` when the series is complete.
    fn step(&mut self, frame: &[u8]) -> Result<bool, FragmentError> {
        let IoFragment { fragment, data } = IoFragment::parse(frame)?;
        let complete = match fragment.kind {
            FragmentKind::Ack => return Err(FragmentError::UnexpectedAck),
            FragmentKind::First => {
                self.reset();
                if fragment.count != 0 && !fragment.is_single() {
                    return Err(FragmentError::FirstCountNotZero(fragment.count));
                }
                fragment.is_single()
            }
            FragmentKind::Middle | FragmentKind::Last => {
                let expected = self.next.ok_or(FragmentError::NoFirstFragment)?;
                if fragment.count != expected {
                    return Err(FragmentError::OutOfSequence { expected, got: fragment.count });
                }
                fragment.kind == FragmentKind::Last
            }
        };
        self.append(data)?;
        self.next = if complete { None } else { Some(next_count(fragment.count)) };
        Ok(complete)
    }

    fn append(&mut self, bytes: &[u8]) -> Result<(), FragmentError> {
        let end = self.len.saturating_add(bytes.len());
        let dst = self.buf.get_mut(self.len..end).ok_or(FragmentError::Overflow { max: N })?;
        dst.copy_from_slice(bytes);
        self.len = end;
        Ok(())
    }

    /// Drops any series in progress.
    pub fn reset(&mut self) {
        self.len = 0;
        self.next = None;
    }

    /// `true` while a series has begun and its last fragment has not arrived.
    pub fn in_progress(&self) -> bool {
        self.next.is_some()
    }
}

#[cfg(test)]
mod tests;
