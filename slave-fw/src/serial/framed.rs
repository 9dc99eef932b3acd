//! The generic framed-serial wire format: a start byte, a length, data, a checksum, an end byte.
//!
//! The breaker of the source paper frames every message as
//! `0x68, len, data[len], sum8(data), 0x16`; other instruments differ only in the byte values,
//! whether the length is sent, the checksum and the delimiter. [`FramedConfig`] describes all of
//! them, so a new instrument of this kind needs a new description, not new code.
//!
//! * [`FramedConfig::encode`] builds an outgoing frame around the data bytes.
//! * [`FrameParser`] takes received bytes one at a time or in slices and hands every complete,
//!   verified frame to a callback, borrowed from its fixed buffer.
//!
//! ## Resynchronisation
//!
//! Bytes before a start byte are skipped and counted. A candidate frame is rejected as soon as it
//! is known to be bad: a length above `max_len` ([`FrameError::BadLength`]), a wrong end delimiter
//! ([`FrameError::BadEnd`]), a checksum mismatch ([`FrameError::BadChecksum`]), or, for delimited
//! frames, no delimiter within `max_len` ([`FrameError::Overflow`]). The parser then drops only the
//! rejected start byte and re-scans the bytes it had already buffered, so a real frame that began
//! inside the rejected one (after a truncated frame, or a stray start byte in garbage) is still
//! found. The end delimiter is checked before the checksum: a frame with neither right is more
//! likely misaligned than corrupted.
//!
//! ## No-panic contract
//!
//! Any byte sequence may be pushed. The buffer never holds more than one maximal frame (checked
//! against `N` when the parser is built), every rejected byte is counted, and nothing allocates.

use super::checksum::Checksum;
use super::error::{as_u32, ConfigError, Conflict, Field};
use core::fmt;
use heapless::Vec;

/// How the parser knows where a frame's data ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum LengthField {
    /// A byte after the start byte counts the data bytes (`0..=max_len`); the breaker's framing.
    Byte,
    /// Every frame carries exactly this many data bytes; no length byte is sent.
    Fixed(u8),
    /// No length: the frame ends at the first end byte that follows a valid checksum. Meant for
    /// protocols whose data and checksum never contain the end byte (ASCII instruments); an end
    /// byte whose checksum does not verify is taken as data.
    Delimited,
}

/// The framing of a framed-serial instrument.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct FramedConfig {
    /// The byte that starts every frame (`0x68` for the breaker).
    pub start: u8,
    /// How the data length is known.
    pub length: LengthField,
    /// The byte that ends every frame, if any (`0x16` for the breaker).
    pub end: Option<u8>,
    /// The checksum over the data bytes.
    pub checksum: Checksum,
    /// The most data bytes a frame may carry, `1..=255`; longer frames are rejected.
    pub max_len: u8,
}

impl FramedConfig {
    /// Checks `max_len`, a fixed length against it, and that delimited frames have an end byte.
    pub fn validate(&self) -> Result<(), ConfigError> {
        ConfigError::check_range(Field::FramingMaxLen, u32::from(self.max_len), 1, 255)?;
        match self.length {
            LengthField::Byte => Ok(()),
            LengthField::Fixed(n) => {
                ConfigError::check_range(Field::FramingLength, u32::from(n), 0, u32::from(self.max_len))
            }
            LengthField::Delimited => match self.end {
                None => Err(ConfigError::conflict(Field::FramingEnd, Conflict::NoEndDelimiter)),
                Some(end) if end == self.start => {
                    Err(ConfigError::conflict(Field::FramingEnd, Conflict::EndEqualsStart))
                }
                Some(_) => Ok(()),
            },
        }
    }

    /// Bytes before the data: the start byte, and the length byte if there is one.
    pub const fn header_len(&self) -> usize {
        match self.length {
            LengthField::Byte => 2,
            LengthField::Fixed(_) | LengthField::Delimited => 1,
        }
    }

    /// Bytes after the data: the checksum and the end byte if there is one.
    pub const fn trailer_len(&self) -> usize {
        self.checksum.byte_len() + if self.end.is_some() { 1 } else { 0 }
    }

    /// The length on the wire of a frame carrying `data_len` data bytes.
    pub const fn frame_len(&self, data_len: usize) -> usize {
        self.header_len() + data_len + self.trailer_len()
    }

    /// The length on the wire of the longest frame this framing allows.
    pub const fn max_frame_len(&self) -> usize {
        match self.length {
            LengthField::Fixed(n) => self.frame_len(n as usize),
            LengthField::Byte | LengthField::Delimited => self.frame_len(self.max_len as usize),
        }
    }

    /// Whether `data_len` data bytes can be framed: at most `max_len`, exactly `n` for
    /// [`LengthField::Fixed`].
    pub const fn accepts_data_len(&self, data_len: usize) -> bool {
        match self.length {
            LengthField::Fixed(n) => data_len == n as usize,
            LengthField::Byte | LengthField::Delimited => data_len <= self.max_len as usize,
        }
    }

    /// Writes the frame carrying `data` to the start of `out` and returns its length.
    #[allow(clippy::manual_contains)] // No `memchr` in the firmware (size budget).
    pub fn encode(&self, data: &[u8], out: &mut [u8]) -> Result<usize, EncodeError> {
        if !self.accepts_data_len(data.len()) {
            return Err(EncodeError::DataLength(data.len()));
        }
        if let (LengthField::Delimited, Some(end)) = (self.length, self.end) {
            // A plain loop: `contains` on bytes would pull in `memchr` (flash).
            if data.iter().any(|&b| b == end) {
                return Err(EncodeError::DelimiterInData);
            }
        }
        let total = self.frame_len(data.len());
        let Some(out) = out.get_mut(..total) else {
            return Err(EncodeError::BufferTooSmall { needed: total });
        };
        let mut w = Writer { out, pos: 0 };
        w.put(self.start);
        if self.length == LengthField::Byte {
            // `accepts_data_len` bounded the length by `max_len: u8`.
            w.put(data.len() as u8);
        }
        w.put_slice(data);
        let sum = self.checksum.wire_bytes(data);
        w.put_slice(sum.get(..self.checksum.byte_len()).unwrap_or(&[]));
        if let Some(end) = self.end {
            w.put(end);
        }
        Ok(total)
    }

    /// Replaces the contents of `out` with the frame carrying `data`.
    pub fn encode_to_vec<const M: usize>(
        &self,
        data: &[u8],
        out: &mut Vec<u8, M>,
    ) -> Result<(), EncodeError> {
        let total = self.frame_len(data.len());
        out.clear();
        out.resize(total, 0).map_err(|_| EncodeError::BufferTooSmall { needed: total })?;
        match self.encode(data, out) {
            Ok(_) => Ok(()),
            Err(e) => {
                out.clear();
                Err(e)
            }
        }
    }
}

/// A bounds-checked byte writer: a write past the end is dropped (callers size `out` first).
struct Writer<'a> {
    out: &'a mut [u8],
    pos: usize,
}

impl Writer<'_> {
    fn put(&mut self, b: u8) {
        if let Some(slot) = self.out.get_mut(self.pos) {
            *slot = b;
        }
        self.pos += 1;
    }

    fn put_slice(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.put(b);
        }
    }
}

/// Why a frame could not be encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EncodeError {
    /// This many data bytes do not fit the framing (above `max_len`, or not the fixed length).
    DataLength(usize),
    /// The output buffer is shorter than the frame.
    BufferTooSmall {
        /// The frame's length.
        needed: usize,
    },
    /// The data of a delimited frame contains the end byte.
    DelimiterInData,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::DataLength(n) => write!(f, "{n} data bytes do not fit the framing"),
            EncodeError::BufferTooSmall { needed } => write!(f, "the frame needs {needed} bytes"),
            EncodeError::DelimiterInData => f.write_str("the data contains the end delimiter"),
        }
    }
}

impl core::error::Error for EncodeError {}

/// Why a candidate frame was discarded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrameError {
    /// The checksum did not match the data.
    BadChecksum,
    /// The byte where the end delimiter belongs is something else.
    BadEnd,
    /// The length byte exceeds `max_len`.
    BadLength,
    /// A delimited frame ran past `max_len` without a delimiter.
    Overflow,
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FrameError::BadChecksum => "bad checksum",
            FrameError::BadEnd => "bad end delimiter",
            FrameError::BadLength => "bad length",
            FrameError::Overflow => "frame too long",
        })
    }
}

impl core::error::Error for FrameError {}

/// What the parser has seen, by kind. Counters wrap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameCounters {
    /// Complete, verified frames.
    pub frames: u32,
    /// Frames rejected for [`FrameError::BadChecksum`].
    pub bad_checksum: u32,
    /// Frames rejected for [`FrameError::BadEnd`].
    pub bad_end: u32,
    /// Frames rejected for [`FrameError::BadLength`].
    pub bad_length: u32,
    /// Frames rejected for [`FrameError::Overflow`].
    pub overflow: u32,
    /// Bytes skipped while looking for a start byte.
    pub skipped_bytes: u32,
}

impl FrameCounters {
    /// All rejected frames.
    pub fn rejected(&self) -> u32 {
        self.bad_checksum.wrapping_add(self.bad_end).wrapping_add(self.bad_length).wrapping_add(self.overflow)
    }

    fn count(&mut self, e: FrameError) {
        let c = match e {
            FrameError::BadChecksum => &mut self.bad_checksum,
            FrameError::BadEnd => &mut self.bad_end,
            FrameError::BadLength => &mut self.bad_length,
            FrameError::Overflow => &mut self.overflow,
        };
        *c = c.wrapping_add(1);
    }
}

/// A complete, verified frame, borrowed from the parser's buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    raw: &'a [u8],
    data_start: usize,
    data_len: usize,
}

impl<'a> Frame<'a> {
    /// The whole frame as received, start byte to end byte.
    pub fn raw(&self) -> &'a [u8] {
        self.raw
    }

    /// The data bytes (between the header and the checksum).
    pub fn data(&self) -> &'a [u8] {
        self.raw.get(self.data_start..self.data_start + self.data_len).unwrap_or(&[])
    }
}

/// The verdict on the buffered candidate frame.
enum Check {
    NeedMore,
    Complete { total: usize, data_start: usize, data_len: usize },
    Reject(FrameError),
}

/// A streaming, resynchronising parser for one [`FramedConfig`], with an `N`-byte buffer.
///
/// `N` must hold the longest frame ([`FramedConfig::max_frame_len`]); [`FrameParser::new`]
/// checks it. Frames and rejections are reported through a callback as they are found:
///
/// ```
/// use slave_fw::serial::{breaker, FrameParser};
/// let mut parser = FrameParser::<32>::new(breaker::FRAMING).unwrap();
/// let mut acks = 0;
/// parser.push_slice(&[0x00, 0x68, 0x02, 0x81, 0x00, 0x81, 0x16], |event| {
///     if let Ok(frame) = event {
///         assert_eq!(frame.data(), &[0x81, 0x00]);
///         acks += 1;
///     }
/// });
/// assert_eq!(acks, 1);
/// assert_eq!(parser.counters().skipped_bytes, 1);
/// ```
#[derive(Clone, Debug)]
pub struct FrameParser<const N: usize> {
    config: FramedConfig,
    buf: Vec<u8, N>,
    counters: FrameCounters,
}

impl<const N: usize> FrameParser<N> {
    /// A parser for `config`; fails when the configuration is invalid or its longest frame does
    /// not fit in `N` bytes.
    pub fn new(config: FramedConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Self::check_capacity(&config)?;
        Ok(Self::build(config))
    }

    /// `Ok` when the longest frame of `config` fits in `N` bytes.
    pub(crate) fn check_capacity(config: &FramedConfig) -> Result<(), ConfigError> {
        if config.max_frame_len() > N {
            let overhead = config.header_len() + config.trailer_len();
            let max = N.saturating_sub(overhead).min(255);
            let (field, value) = match config.length {
                LengthField::Fixed(n) => (Field::FramingLength, n),
                LengthField::Byte | LengthField::Delimited => (Field::FramingMaxLen, config.max_len),
            };
            return Err(ConfigError::out_of_range(field, u32::from(value), 0, as_u32(max)));
        }
        Ok(())
    }

    /// A parser for `config`, which [`FramedConfig::validate`] and
    /// [`check_capacity`](Self::check_capacity) have accepted.
    pub(crate) fn build(config: FramedConfig) -> Self {
        FrameParser { config, buf: Vec::new(), counters: FrameCounters::default() }
    }

    /// The framing this parser follows.
    pub fn config(&self) -> &FramedConfig {
        &self.config
    }

    /// What the parser has seen so far.
    pub fn counters(&self) -> &FrameCounters {
        &self.counters
    }

    /// Bytes of an incomplete candidate frame currently buffered.
    pub fn buffered(&self) -> usize {
        self.buf.len()
    }

    /// Drops any partial frame (for example after a long gap on the line). Counters are kept.
    pub fn reset(&mut self) {
        self.buf.clear();
    }

    /// Feeds one received byte; `on_event` is called for every frame completed or rejected by it
    /// (more than one when a rejection uncovers buffered frames).
    pub fn push(&mut self, byte: u8, mut on_event: impl FnMut(Result<Frame<'_>, FrameError>)) {
        self.push_inner(byte, &mut on_event);
    }

    /// Feeds received bytes in order; `on_event` is called as for [`push`](Self::push).
    pub fn push_slice(&mut self, bytes: &[u8], mut on_event: impl FnMut(Result<Frame<'_>, FrameError>)) {
        for &b in bytes {
            self.push_inner(b, &mut on_event);
        }
    }

    fn push_inner(&mut self, byte: u8, on_event: &mut impl FnMut(Result<Frame<'_>, FrameError>)) {
        if self.buf.is_empty() && byte != self.config.start {
            self.counters.skipped_bytes = self.counters.skipped_bytes.wrapping_add(1);
            return;
        }
        if self.buf.push(byte).is_err() {
            // Unreachable: `process` never leaves a maximal frame buffered and `new` checked that
            // one fits. Should it happen, drop the buffer rather than the invariant.
            self.counters.count(FrameError::Overflow);
            on_event(Err(FrameError::Overflow));
            self.buf.clear();
            return;
        }
        self.process(on_event);
    }

    /// Decides on the buffered candidate until more bytes are needed.
    fn process(&mut self, on_event: &mut impl FnMut(Result<Frame<'_>, FrameError>)) {
        loop {
            // One call of `on_event` for both verdicts: each call site builds the event (flash).
            let (event, used) = match self.check() {
                Check::NeedMore => return,
                Check::Complete { total, data_start, data_len } => {
                    self.counters.frames = self.counters.frames.wrapping_add(1);
                    let raw = self.buf.get(..total).unwrap_or(&[]);
                    (Ok(Frame { raw, data_start, data_len }), total)
                }
                Check::Reject(e) => {
                    self.counters.count(e);
                    // Drop only the start byte: a frame may begin inside the rejected one.
                    (Err(e), 1)
                }
            };
            on_event(event);
            self.discard(used);
            self.skip_to_start();
            if self.buf.is_empty() {
                return;
            }
        }
    }

    fn discard(&mut self, n: usize) {
        super::buffer::drop_front(&mut self.buf, n);
    }

    /// Drops buffered bytes up to the next start byte, counting them as skipped.
    fn skip_to_start(&mut self) {
        let skip = self.buf.iter().position(|&b| b == self.config.start).unwrap_or(self.buf.len());
        if skip > 0 {
            self.counters.skipped_bytes = self.counters.skipped_bytes.wrapping_add(as_u32(skip));
            self.discard(skip);
        }
    }

    /// The verdict on the buffer, which starts with a start byte.
    fn check(&self) -> Check {
        let buf = self.buf.as_slice();
        match self.config.length {
            LengthField::Byte => match buf.get(1) {
                None => Check::NeedMore,
                Some(&n) if n > self.config.max_len => Check::Reject(FrameError::BadLength),
                Some(&n) => self.check_sized(2, usize::from(n)),
            },
            LengthField::Fixed(n) => self.check_sized(1, usize::from(n)),
            LengthField::Delimited => self.check_delimited(),
        }
    }

    /// A frame whose data length is known: `data_len` bytes from `data_start`.
    fn check_sized(&self, data_start: usize, data_len: usize) -> Check {
        let cs = self.config.checksum.byte_len();
        let total = data_start + data_len + self.config.trailer_len();
        let Some(frame) = self.buf.get(..total) else {
            return Check::NeedMore;
        };
        if let Some(end) = self.config.end {
            if frame.last() != Some(&end) {
                return Check::Reject(FrameError::BadEnd);
            }
        }
        let data_end = data_start + data_len;
        let data = frame.get(data_start..data_end).unwrap_or(&[]);
        let trailer = frame.get(data_end..data_end + cs).unwrap_or(&[]);
        if !self.config.checksum.verify(data, trailer) {
            return Check::Reject(FrameError::BadChecksum);
        }
        Check::Complete { total, data_start, data_len }
    }

    /// A delimited frame: the first end byte preceded by a verifying checksum ends it.
    fn check_delimited(&self) -> Check {
        let buf = self.buf.as_slice();
        let cs = self.config.checksum.byte_len();
        let Some(end) = self.config.end else {
            // `validate` requires an end byte for delimited frames.
            return Check::Reject(FrameError::Overflow);
        };
        let mut seen_end = false;
        for (p, _) in buf.iter().enumerate().skip(1 + cs).filter(|&(_, &b)| b == end) {
            seen_end = true;
            let data = buf.get(1..p - cs).unwrap_or(&[]);
            let trailer = buf.get(p - cs..p).unwrap_or(&[]);
            if self.config.checksum.verify(data, trailer) {
                return Check::Complete { total: p + 1, data_start: 1, data_len: p - cs - 1 };
            }
        }
        if buf.len() >= self.config.max_frame_len() {
            Check::Reject(if seen_end { FrameError::BadChecksum } else { FrameError::Overflow })
        } else {
            Check::NeedMore
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::breaker::FRAMING as BREAKER;
    use proptest::prelude::*;
    use rstest::rstest;
    use std::vec::Vec as StdVec;

    const XOR_FIXED: FramedConfig = FramedConfig {
        start: 0x02,
        length: LengthField::Fixed(3),
        end: Some(0x03),
        checksum: Checksum::Xor8,
        max_len: 8,
    };
    const CRC_NO_END: FramedConfig = FramedConfig {
        start: 0xAA,
        length: LengthField::Byte,
        end: None,
        checksum: Checksum::Crc16Modbus,
        max_len: 16,
    };
    const ASCII_LINE: FramedConfig = FramedConfig {
        start: b':',
        length: LengthField::Delimited,
        end: Some(b'\n'),
        checksum: Checksum::None,
        max_len: 8,
    };
    const DELIMITED_SUM: FramedConfig = FramedConfig {
        start: 0x7E,
        length: LengthField::Delimited,
        end: Some(0x7F),
        checksum: Checksum::Sum8,
        max_len: 8,
    };

    #[derive(Debug, Default, PartialEq)]
    struct Seen {
        frames: StdVec<StdVec<u8>>,
        errors: StdVec<FrameError>,
    }

    fn feed<const N: usize>(parser: &mut FrameParser<N>, bytes: &[u8]) -> Seen {
        let mut seen = Seen::default();
        parser.push_slice(bytes, |e| match e {
            Ok(f) => seen.frames.push(f.data().to_vec()),
            Err(e) => seen.errors.push(e),
        });
        seen
    }

    fn parser(config: FramedConfig) -> FrameParser<64> {
        FrameParser::new(config).unwrap()
    }

    fn status_open() -> StdVec<u8> {
        let mut f = std::vec![0x68, 0x12];
        f.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 0, 0, 0x0F, 0, 0, 0, 0, 0, 0, 0, 0]);
        f.extend_from_slice(&[0x0F, 0x16]);
        f
    }

    // Encode and parse agree on each wire vector, both ways.
    #[rstest]
    #[case::breaker_open_cmd(BREAKER, &[0x01], &[0x68, 0x01, 0x01, 0x01, 0x16])]
    #[case::breaker_close_cmd(BREAKER, &[0x02], &[0x68, 0x01, 0x02, 0x02, 0x16])]
    #[case::breaker_set_param(BREAKER, &[0x03, 0x02, 0x34, 0x12], &[0x68, 0x04, 0x03, 0x02, 0x34, 0x12, 0x4B, 0x16])]
    #[case::breaker_ack(BREAKER, &[0x81, 0x00], &[0x68, 0x02, 0x81, 0x00, 0x81, 0x16])]
    #[case::breaker_nak(BREAKER, &[0x83, 0x02], &[0x68, 0x02, 0x83, 0x02, 0x85, 0x16])]
    #[case::empty_data(BREAKER, &[], &[0x68, 0x00, 0x00, 0x16])]
    #[case::xor_fixed(XOR_FIXED, &[0x10, 0x20, 0x31], &[0x02, 0x10, 0x20, 0x31, 0x01, 0x03])]
    #[case::crc_no_end(CRC_NO_END, &[0x01, 0x03, 0x00, 0x00, 0x00, 0x0A], &[0xAA, 0x06, 0x01, 0x03, 0x00, 0x00, 0x00, 0x0A, 0xC5, 0xCD])]
    #[case::ascii_line(ASCII_LINE, b"T=21", b":T=21\n")]
    #[case::delimited_sum(DELIMITED_SUM, &[0x01, 0x02], &[0x7E, 0x01, 0x02, 0x03, 0x7F])]
    fn codec(#[case] config: FramedConfig, #[case] data: &[u8], #[case] wire: &[u8]) {
        let mut out = [0u8; 64];
        let n = config.encode(data, &mut out).unwrap();
        assert_eq!(&out[..n], wire);
        assert_eq!(config.frame_len(data.len()), wire.len());

        let mut p = parser(config);
        let seen = feed(&mut p, wire);
        assert_eq!(seen, Seen { frames: std::vec![data.to_vec()], errors: std::vec![] });
        assert_eq!(p.buffered(), 0);
    }

    #[test]
    fn breaker_status_frame_parses() {
        let mut p = parser(BREAKER);
        let seen = feed(&mut p, &status_open());
        assert_eq!(seen.frames.len(), 1);
        assert_eq!(seen.frames[0][9], 0x0F);
        let mut raw = StdVec::new();
        p.push_slice(&status_open(), |e| raw = e.unwrap().raw().to_vec());
        assert_eq!(raw, status_open());
    }

    #[rstest]
    #[case::too_long_for_byte(BREAKER, &[0u8; 19][..], EncodeError::DataLength(19))]
    #[case::wrong_fixed_len(XOR_FIXED, &[1, 2][..], EncodeError::DataLength(2))]
    #[case::delimiter_in_data(ASCII_LINE, &b"a\nb"[..], EncodeError::DelimiterInData)]
    fn encode_rejects(#[case] config: FramedConfig, #[case] data: &[u8], #[case] e: EncodeError) {
        assert_eq!(config.encode(data, &mut [0u8; 64]), Err(e));
    }

    #[test]
    fn encode_needs_room() {
        assert_eq!(BREAKER.encode(&[1], &mut [0u8; 4]), Err(EncodeError::BufferTooSmall { needed: 5 }));
        let mut v: Vec<u8, 4> = Vec::new();
        assert_eq!(BREAKER.encode_to_vec(&[1], &mut v), Err(EncodeError::BufferTooSmall { needed: 5 }));
        let mut v: Vec<u8, 8> = Vec::new();
        BREAKER.encode_to_vec(&[1], &mut v).unwrap();
        assert_eq!(v.as_slice(), &[0x68, 0x01, 0x01, 0x01, 0x16]);
    }

    #[rstest]
    #[case::leading_garbage(&[0x00, 0xFF, 0x12], 0, 3)]
    #[case::garbage_is_end_bytes(&[0x16, 0x16], 0, 2)]
    #[case::stray_start_bad_length(&[0x68, 0xFF], 1, 1)]
    #[case::stray_start_then_start(&[0x68], 1, 0)]
    fn resync_on_garbage_before_frame(#[case] garbage: &[u8], #[case] rejected: u32, #[case] skipped: u32) {
        let mut p = parser(BREAKER);
        let mut bytes = garbage.to_vec();
        bytes.extend_from_slice(&status_open());
        bytes.extend_from_slice(&[0x68, 0x02, 0x81, 0x00, 0x81, 0x16]);
        let seen = feed(&mut p, &bytes);
        assert_eq!(seen.frames.len(), 2, "{seen:?}");
        assert_eq!(p.counters().rejected(), rejected);
        assert_eq!(p.counters().skipped_bytes, skipped);
    }

    // A start byte inside garbage claims a length that swallows a real frame; the rejected
    // candidate is re-scanned and the real frame found.
    #[test]
    fn start_byte_inside_garbage_is_not_lost() {
        let mut p = parser(BREAKER);
        let seen = feed(&mut p, &[0x68, 0x05, 0x68, 0x02, 0x81, 0x00, 0x81, 0x16]);
        assert!(seen.frames.is_empty(), "the candidate still needs a byte");
        let seen = feed(&mut p, &[0xAA]);
        assert_eq!(seen.errors, std::vec![FrameError::BadEnd]);
        assert_eq!(seen.frames, std::vec![std::vec![0x81, 0x00]]);
        assert_eq!(p.buffered(), 0);
        assert_eq!(p.counters().skipped_bytes, 2, "0x05 and 0xAA");
    }

    // A truncated status frame followed by a whole one: the second is recovered.
    #[test]
    fn truncated_frame_then_whole_frame() {
        let mut p = parser(BREAKER);
        let mut bytes = std::vec![0x68, 0x12, 0x01, 0x02, 0x03];
        bytes.extend_from_slice(&status_open());
        let seen = feed(&mut p, &bytes);
        assert_eq!(seen.frames.len(), 1);
        assert_eq!(seen.errors.len(), 1);
        assert_eq!(p.counters().frames, 1);
    }

    #[rstest]
    #[case::bad_checksum(&[0x68, 0x02, 0x81, 0x00, 0x80, 0x16], FrameError::BadChecksum)]
    #[case::bad_end(&[0x68, 0x02, 0x81, 0x00, 0x81, 0x17], FrameError::BadEnd)]
    #[case::bad_length(&[0x68, 0x13], FrameError::BadLength)]
    fn bad_frame_counted_and_survived(#[case] bad: &[u8], #[case] error: FrameError) {
        let mut p = parser(BREAKER);
        let mut bytes = bad.to_vec();
        bytes.extend_from_slice(&status_open());
        let seen = feed(&mut p, &bytes);
        assert_eq!(seen.errors, std::vec![error]);
        assert_eq!(seen.frames.len(), 1);
        assert_eq!(p.counters().rejected(), 1);
        assert_eq!(p.counters().frames, 1);
    }

    #[test]
    fn counters_by_kind() {
        let mut p = parser(BREAKER);
        feed(&mut p, &[0x68, 0x02, 0x81, 0x00, 0x80, 0x16]);
        feed(&mut p, &[0x68, 0x02, 0x81, 0x00, 0x81, 0x00]);
        feed(&mut p, &[0x68, 0xFE]);
        let mut d = parser(ASCII_LINE);
        feed(&mut d, b":123456789");
        assert_eq!(
            (p.counters().bad_checksum, p.counters().bad_end, p.counters().bad_length, d.counters().overflow),
            (1, 1, 1, 1)
        );
    }

    #[test]
    fn delimited_overflow_then_recovers() {
        let mut p = parser(ASCII_LINE);
        let seen = feed(&mut p, b":012345678:ok\n");
        assert_eq!(seen.errors, std::vec![FrameError::Overflow]);
        assert_eq!(seen.frames, std::vec![b"ok".to_vec()]);
    }

    // An end byte whose checksum fails is data: here the checksum byte itself equals 0x7F.
    #[test]
    fn delimited_checksum_equal_to_end_byte() {
        let data = [0x70, 0x0F]; // sum 0x7F
        let mut p = parser(DELIMITED_SUM);
        let seen = feed(&mut p, &[0x7E, 0x70, 0x0F, 0x7F, 0x7F]);
        assert_eq!(seen.frames, std::vec![data.to_vec()]);
        let seen = feed(&mut p, &[0x7E, 0x01, 0x05, 0x7F, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]);
        assert_eq!(seen.errors, std::vec![FrameError::BadChecksum]);
    }

    #[test]
    fn reset_drops_partial_frame() {
        let mut p = parser(BREAKER);
        feed(&mut p, &[0x68, 0x02, 0x81]);
        assert_eq!(p.buffered(), 3);
        p.reset();
        let seen = feed(&mut p, &[0x68, 0x02, 0x81, 0x00, 0x81, 0x16]);
        assert_eq!(seen.frames.len(), 1);
    }

    #[rstest]
    #[case::max_len_zero(FramedConfig { max_len: 0, ..BREAKER }, "framing.max_len")]
    #[case::fixed_above_max(FramedConfig { length: LengthField::Fixed(9), ..XOR_FIXED }, "framing.length")]
    #[case::delimited_without_end(FramedConfig { end: None, ..ASCII_LINE }, "framing.end")]
    #[case::delimited_end_is_start(FramedConfig { end: Some(b':'), ..ASCII_LINE }, "framing.end")]
    fn validate_rejects(#[case] config: FramedConfig, #[case] field: &str) {
        assert_eq!(config.validate().unwrap_err().field.key(), field);
    }

    #[test]
    fn parser_checks_capacity() {
        let e = FrameParser::<16>::new(FramedConfig { max_len: 255, ..BREAKER }).unwrap_err();
        assert_eq!(e.problem, crate::serial::Problem::OutOfRange { value: 255, min: 0, max: 12 });
        assert!(FrameParser::<22>::new(BREAKER).is_ok());
        assert!(FrameParser::<21>::new(BREAKER).is_err());
    }

    fn any_config() -> impl Strategy<Value = FramedConfig> {
        prop_oneof![Just(BREAKER), Just(XOR_FIXED), Just(CRC_NO_END), Just(ASCII_LINE), Just(DELIMITED_SUM)]
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(config in any_config(), bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let mut p = parser(config);
            let mut frames = 0u32;
            p.push_slice(&bytes, |e| {
                if let Ok(f) = e {
                    // Every frame handed out re-encodes to exactly its raw bytes.
                    let mut out = [0u8; 64];
                    let n = config.encode(f.data(), &mut out);
                    if config.length != LengthField::Delimited {
                        assert_eq!(&out[..n.unwrap()], f.raw());
                    }
                    frames += 1;
                }
            });
            prop_assert!(p.buffered() < config.max_frame_len());
            prop_assert_eq!(p.counters().frames, frames);
        }

        #[test]
        fn chunking_does_not_matter(bytes in proptest::collection::vec(prop_oneof![Just(0x68u8), Just(0x16), Just(0x02), any::<u8>()], 0..300), split in 0usize..300) {
            let split = split.min(bytes.len());
            let mut whole = parser(BREAKER);
            let all = feed(&mut whole, &bytes);
            let mut parts = parser(BREAKER);
            let mut seen = feed(&mut parts, &bytes[..split]);
            let rest = feed(&mut parts, &bytes[split..]);
            seen.frames.extend(rest.frames);
            seen.errors.extend(rest.errors);
            prop_assert_eq!(all, seen);
            prop_assert_eq!(whole.counters(), parts.counters());
        }

        #[test]
        fn frame_after_garbage_without_start_byte_is_found(
            garbage in proptest::collection::vec(any::<u8>().prop_filter("no start byte", |b| *b != 0x68), 0..100),
            data in proptest::collection::vec(any::<u8>(), 0..=18),
        ) {
            let mut wire = [0u8; 64];
            let n = BREAKER.encode(&data, &mut wire).unwrap();
            let mut bytes = garbage.clone();
            bytes.extend_from_slice(&wire[..n]);
            let mut p = parser(BREAKER);
            let seen = feed(&mut p, &bytes);
            prop_assert_eq!(seen.frames, std::vec![data]);
            prop_assert_eq!(p.counters().skipped_bytes as usize, garbage.len());
        }
    }
}
