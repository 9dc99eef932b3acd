//! The serial-line analyzer's record: a fixed ring of [`TraceEntry`]s, the last bytes each way on
//! the instrument's line and the line events between them, read over DeviceNet through the
//! analyzer object (`converter::analyzer_object`, vendor class 0x68) and printed by
//! `dnet-master serial-trace`.
//!
//! ## What is recorded
//!
//! | [`TraceKind`] | recorded by |
//! |---|---|
//! | [`Transmit`](TraceKind::Transmit), [`Receive`](TraceKind::Receive) | the converter, for every frame handed to the UART and every chunk read from it |
//! | [`Checksum`](TraceKind::Checksum), [`Framing`](TraceKind::Framing) | the converter, when the profile's checksum or framing error counter moves while it takes received bytes |
//! | [`DriverOn`](TraceKind::DriverOn), [`DriverOff`](TraceKind::DriverOff), [`UartFraming`](TraceKind::UartFraming), [`UartParity`](TraceKind::UartParity), [`UartOverrun`](TraceKind::UartOverrun) | whoever owns the UART, through `Converter::record_line_event` |
//!
//! Bytes of one direction that follow each other within [`CONTINUE_MS`] continue the newest entry
//! while it has room ([`CHUNK`] bytes), so a frame read a byte at a time still takes one or two
//! entries; a longer frame takes several. Reading the trace ([`Trace::seal`]) closes the newest
//! entry, so bytes arriving after a read go to a new entry that the next read gets.
//!
//! ## Sequence numbers
//!
//! Every entry gets the next sequence number (a `u32`, wrapping); the ring keeps the newest
//! [`ENTRIES`], overwriting the oldest. A reader asks for the entries from a sequence number on
//! ([`Trace::start_from`]): when that entry was already overwritten it gets the oldest kept one
//! and knows from the difference how many it missed.
//!
//! ## Wire form of one entry
//!
//! `time_ms` (UDINT, little-endian, the milliseconds of the converter's clock, wrapping), `kind`
//! (USINT, [`TraceKind`]), `len` (USINT, `0..=CHUNK`), then `len` bytes: [`TraceEntry::encode`],
//! [`TraceEntry::parse`].
//!
//! ## Memory
//!
//! [`ENTRIES`] × 24 bytes (a `u32`, two bytes and [`CHUNK`] data bytes, aligned) = 768 bytes of
//! static RAM in the firmware, whose budget is 16 KiB (the reference board used 5.3 KiB before).
//! At 9600 baud it holds about 20 breaker status frames (22 bytes, two entries each) or 16 Modbus
//! request/response pairs reading a few registers.
//!
//! No input can make it panic or allocate: every index is checked.

use devicenet::Instant;

/// Entries kept.
pub const ENTRIES: usize = 32;

// The slot of sequence number `s` is `s % ENTRIES`: a power of two keeps it right across the
// wrap of `s` at 2^32.
const _: () = assert!(ENTRIES.is_power_of_two() && ENTRIES <= 255);

/// Bytes one entry holds.
pub const CHUNK: usize = 16;

/// Bytes of one direction at most this many milliseconds after the previous ones continue the
/// newest entry (one character takes about 1 ms at 9600 baud; the Modbus RTU inter-frame gap
/// there is 4 ms).
pub const CONTINUE_MS: u32 = 2;

/// The largest encoded entry: the 6-byte head and [`CHUNK`] bytes.
pub const MAX_ENCODED_LEN: usize = 6 + CHUNK;

/// What an entry records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum TraceKind {
    /// Bytes written to the instrument.
    Transmit = 0,
    /// Bytes read from the instrument.
    Receive = 1,
    /// The RS-485 driver was enabled (transmit-enable rising edge).
    DriverOn = 2,
    /// The RS-485 driver was released (transmit-enable falling edge).
    DriverOff = 3,
    /// The UART saw a character without its stop bit (framing error).
    UartFraming = 4,
    /// The UART saw a character with the wrong parity.
    UartParity = 5,
    /// The UART lost a character (overrun).
    UartOverrun = 6,
    /// The profile discarded a frame for its checksum (CRC, LRC, sum).
    Checksum = 7,
    /// The profile discarded bytes for bad framing.
    Framing = 8,
}

impl TraceKind {
    /// Every kind, in code order.
    pub const ALL: [TraceKind; 9] = [
        TraceKind::Transmit,
        TraceKind::Receive,
        TraceKind::DriverOn,
        TraceKind::DriverOff,
        TraceKind::UartFraming,
        TraceKind::UartParity,
        TraceKind::UartOverrun,
        TraceKind::Checksum,
        TraceKind::Framing,
    ];

    /// The kind with code `code`, if any.
    pub fn from_code(code: u8) -> Option<TraceKind> {
        TraceKind::ALL.get(usize::from(code)).copied()
    }

    /// The code on the wire.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// Whether the entry holds line bytes (the other kinds are events without bytes).
    pub const fn is_bytes(self) -> bool {
        matches!(self, TraceKind::Transmit | TraceKind::Receive)
    }
}

/// One entry: when, what, and up to [`CHUNK`] bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceEntry {
    /// The converter's clock when the first byte or the event was recorded, ms (wrapping).
    pub time_ms: u32,
    /// What it records.
    pub kind: TraceKind,
    len: u8,
    data: [u8; CHUNK],
}

/// Why an encoded entry could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceParseError {
    /// Fewer bytes than the head or than its length byte says.
    Truncated,
    /// A kind code no [`TraceKind`] has.
    UnknownKind(u8),
    /// A length over [`CHUNK`].
    TooLong(u8),
}

impl core::fmt::Display for TraceParseError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TraceParseError::Truncated => f.write_str("trace entry truncated"),
            TraceParseError::UnknownKind(k) => write!(f, "unknown trace entry kind {k}"),
            TraceParseError::TooLong(n) => write!(f, "trace entry of {n} bytes (at most {CHUNK})"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for TraceParseError {}

impl TraceEntry {
    const EMPTY: TraceEntry = TraceEntry { time_ms: 0, kind: TraceKind::Transmit, len: 0, data: [0; CHUNK] };

    /// An entry; `None` when `bytes` is longer than [`CHUNK`].
    pub fn new(time_ms: u32, kind: TraceKind, bytes: &[u8]) -> Option<TraceEntry> {
        let mut e = TraceEntry { time_ms, kind, ..TraceEntry::EMPTY };
        e.data.get_mut(..bytes.len())?.copy_from_slice(bytes);
        e.len = bytes.len() as u8; // ≤ CHUNK, checked above
        Some(e)
    }

    /// The bytes it holds.
    pub fn bytes(&self) -> &[u8] {
        self.data.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// Bytes of [`encode`](Self::encode)'s output.
    pub fn encoded_len(&self) -> usize {
        6 + usize::from(self.len)
    }

    /// Writes the wire form into the start of `out`; `None` when it does not fit.
    pub fn encode(&self, out: &mut [u8]) -> Option<usize> {
        let n = self.encoded_len();
        let out = out.get_mut(..n)?;
        let (head, rest) = out.split_at_mut(6);
        head.copy_from_slice(&[0, 0, 0, 0, self.kind.code(), self.len]);
        head.get_mut(..4)?.copy_from_slice(&self.time_ms.to_le_bytes());
        rest.copy_from_slice(self.bytes());
        Some(n)
    }

    /// Reads one entry from the start of `wire`; returns it and the bytes it took.
    pub fn parse(wire: &[u8]) -> Result<(TraceEntry, usize), TraceParseError> {
        let [t0, t1, t2, t3, kind, len, rest @ ..] = wire else {
            return Err(TraceParseError::Truncated);
        };
        let kind = TraceKind::from_code(*kind).ok_or(TraceParseError::UnknownKind(*kind))?;
        if usize::from(*len) > CHUNK {
            return Err(TraceParseError::TooLong(*len));
        }
        let bytes = rest.get(..usize::from(*len)).ok_or(TraceParseError::Truncated)?;
        let entry = TraceEntry::new(u32::from_le_bytes([*t0, *t1, *t2, *t3]), kind, bytes)
            .ok_or(TraceParseError::TooLong(*len))?;
        Ok((entry, entry.encoded_len()))
    }
}

/// The ring of the newest [`ENTRIES`] entries (module docs).
#[derive(Clone, Debug)]
pub struct Trace {
    entries: [TraceEntry; ENTRIES],
    /// The sequence number the next entry gets; also the count of entries ever recorded.
    next_seq: u32,
    /// Entries held, `0..=ENTRIES` (not derived from `next_seq`, which wraps).
    held: usize,
    /// Whether the newest entry may still take bytes.
    open: bool,
    /// When bytes last went into the newest entry, ms.
    last_ms: u32,
}

impl Default for Trace {
    fn default() -> Self {
        Trace::new()
    }
}

impl Trace {
    /// An empty trace.
    pub const fn new() -> Trace {
        Trace { entries: [TraceEntry::EMPTY; ENTRIES], next_seq: 0, held: 0, open: false, last_ms: 0 }
    }

    /// `now` in the trace's milliseconds (wrapping at 2^32 ms, 49.7 days).
    fn millis(now: Instant) -> u32 {
        now.total_millis() as u32
    }

    /// Records bytes written to ([`TraceKind::Transmit`]) or read from ([`TraceKind::Receive`])
    /// the instrument at `now`. An event kind records the event and ignores `bytes`.
    pub fn record_bytes(&mut self, kind: TraceKind, bytes: &[u8], now: Instant) {
        if !kind.is_bytes() {
            self.record_event(kind, now);
            return;
        }
        let ms = Trace::millis(now);
        let mut rest = bytes;
        // Continue the newest entry: same direction, still open, recent, with room.
        if self.open && ms.wrapping_sub(self.last_ms) <= CONTINUE_MS {
            if let Some(e) = self.newest_mut().filter(|e| e.kind == kind) {
                let used = usize::from(e.len);
                let take = rest.len().min(CHUNK - used);
                let (now_part, later) = rest.split_at(take);
                if let Some(dst) = e.data.get_mut(used..used + take) {
                    dst.copy_from_slice(now_part);
                    e.len = (used + take) as u8; // ≤ CHUNK
                    rest = later;
                }
            }
        }
        for chunk in rest.chunks(CHUNK) {
            self.push(TraceEntry::new(ms, kind, chunk).unwrap_or(TraceEntry::EMPTY));
        }
        self.open = true;
        self.last_ms = ms;
    }

    /// Records an event without bytes at `now`; it closes the newest entry.
    pub fn record_event(&mut self, kind: TraceKind, now: Instant) {
        self.push(TraceEntry { time_ms: Trace::millis(now), kind, ..TraceEntry::EMPTY });
        self.open = false;
    }

    fn push(&mut self, entry: TraceEntry) {
        if let Some(slot) = self.entries.get_mut(self.next_seq as usize % ENTRIES) {
            *slot = entry;
        }
        self.next_seq = self.next_seq.wrapping_add(1);
        self.held = (self.held + 1).min(ENTRIES);
    }

    fn newest_mut(&mut self) -> Option<&mut TraceEntry> {
        (self.held != 0).then_some(())?;
        self.entries.get_mut(self.next_seq.wrapping_sub(1) as usize % ENTRIES)
    }

    /// Closes the newest entry: later bytes start a new one. Called before a reader reads, so an
    /// entry it has seen does not grow.
    pub fn seal(&mut self) {
        self.open = false;
    }

    /// The sequence number the next entry will get.
    pub fn next_seq(&self) -> u32 {
        self.next_seq
    }

    /// Entries held: those recorded, at most [`ENTRIES`].
    pub fn len(&self) -> usize {
        self.held
    }

    /// Whether nothing was recorded yet.
    pub fn is_empty(&self) -> bool {
        self.held == 0
    }

    /// The sequence number of the oldest entry held.
    pub fn oldest_seq(&self) -> u32 {
        self.next_seq.wrapping_sub(self.len() as u32)
    }

    /// The entry with sequence number `seq`, if it is still held.
    pub fn get(&self, seq: u32) -> Option<&TraceEntry> {
        let age = self.next_seq.wrapping_sub(seq);
        if age == 0 || age as usize > self.len() {
            return None;
        }
        self.entries.get(seq as usize % ENTRIES)
    }

    /// Where a reader that wants the entries from `seq` on starts: `seq` itself when that entry
    /// is held or is the next one, else (overwritten, or a number from before a restart) the
    /// oldest entry held.
    pub fn start_from(&self, seq: u32) -> u32 {
        if self.next_seq.wrapping_sub(seq) as usize <= self.len() {
            seq
        } else {
            self.oldest_seq()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn held(t: &Trace) -> std::vec::Vec<(u32, TraceKind, std::vec::Vec<u8>)> {
        (t.oldest_seq()..t.next_seq())
            .map(|s| t.get(s).unwrap())
            .map(|e| (e.time_ms, e.kind, e.bytes().to_vec()))
            .collect()
    }

    #[test]
    fn empty_trace_holds_nothing() {
        let t = Trace::new();
        assert!(t.is_empty());
        assert_eq!((t.len(), t.next_seq(), t.oldest_seq()), (0, 0, 0));
        assert_eq!(t.get(0), None);
        assert_eq!(t.start_from(0), 0);
        assert_eq!(t.start_from(5), 0);
    }

    #[test]
    fn bytes_close_in_time_continue_one_entry_and_split_at_chunk() {
        let mut t = Trace::new();
        for (i, b) in (0u8..20).enumerate() {
            t.record_bytes(TraceKind::Receive, &[b], ms(100 + i as u64 / 4));
        }
        let first: std::vec::Vec<u8> = (0..16).collect();
        assert_eq!(
            held(&t),
            [(100, TraceKind::Receive, first), (104, TraceKind::Receive, (16..20).collect())]
        );
    }

    #[rstest]
    #[case::gap(TraceKind::Receive, 103, 2)]
    #[case::within_gap(TraceKind::Receive, 102, 1)]
    #[case::other_direction(TraceKind::Transmit, 100, 2)]
    fn new_entry_after_a_gap_or_a_turn(#[case] kind: TraceKind, #[case] at: u64, #[case] entries: usize) {
        let mut t = Trace::new();
        t.record_bytes(TraceKind::Receive, &[1, 2], ms(100));
        t.record_bytes(kind, &[3], ms(at));
        assert_eq!(t.len(), entries);
    }

    #[test]
    fn an_event_or_a_read_closes_the_entry() {
        let mut t = Trace::new();
        t.record_bytes(TraceKind::Receive, &[1], ms(10));
        t.record_event(TraceKind::Checksum, ms(10));
        t.record_bytes(TraceKind::Receive, &[2], ms(10));
        t.seal();
        t.record_bytes(TraceKind::Receive, &[3], ms(10));
        assert_eq!(
            held(&t),
            [
                (10, TraceKind::Receive, std::vec![1]),
                (10, TraceKind::Checksum, std::vec![]),
                (10, TraceKind::Receive, std::vec![2]),
                (10, TraceKind::Receive, std::vec![3]),
            ]
        );
    }

    #[test]
    fn event_kinds_passed_as_bytes_record_the_event_only() {
        let mut t = Trace::new();
        t.record_bytes(TraceKind::UartParity, &[9, 9], ms(1));
        assert_eq!(held(&t), [(1, TraceKind::UartParity, std::vec![])]);
    }

    #[test]
    fn wraps_keeping_the_newest_and_counting_sequence_numbers() {
        let mut t = Trace::new();
        let total = ENTRIES as u32 * 2 + 5;
        for i in 0..total {
            t.record_bytes(TraceKind::Transmit, &[i as u8], ms(u64::from(i) * 10));
        }
        assert_eq!(t.next_seq(), total);
        assert_eq!(t.len(), ENTRIES);
        assert_eq!(t.oldest_seq(), total - ENTRIES as u32);
        assert_eq!(t.get(t.oldest_seq() - 1), None);
        assert_eq!(t.get(total), None);
        for s in t.oldest_seq()..total {
            assert_eq!(t.get(s).unwrap().bytes(), [s as u8], "seq {s}");
        }
    }

    #[rstest]
    #[case::held(40, 40)]
    #[case::next(69, 69)]
    #[case::missed(3, 69 - ENTRIES as u32)]
    #[case::ahead_after_a_restart(500, 69 - ENTRIES as u32)]
    fn start_from(#[case] asked: u32, #[case] start: u32) {
        let mut t = Trace::new();
        for i in 0..69u64 {
            t.record_event(TraceKind::DriverOn, ms(i));
        }
        assert_eq!(t.start_from(asked), start);
    }

    #[test]
    fn sequence_numbers_wrap_at_2_pow_32() {
        let mut t = Trace::new();
        t.next_seq = u32::MAX - 1;
        t.record_event(TraceKind::DriverOn, ms(0));
        assert_eq!((t.len(), t.oldest_seq()), (1, u32::MAX - 1));
        t.next_seq = u32::MAX - 1;
        t.held = ENTRIES;
        for i in 0..4u64 {
            t.record_event(TraceKind::DriverOff, ms(i));
        }
        assert_eq!(t.next_seq(), 2);
        assert_eq!(t.len(), ENTRIES);
        assert_eq!(t.get(u32::MAX).unwrap().time_ms, 1);
        assert_eq!(t.get(1).unwrap().time_ms, 3);
        assert_eq!(t.start_from(u32::MAX), u32::MAX);
    }

    #[test]
    fn time_wraps_in_milliseconds() {
        let mut t = Trace::new();
        t.record_event(TraceKind::Framing, Instant::from_millis((1 << 32) + 7));
        assert_eq!(t.get(0).unwrap().time_ms, 7);
    }

    #[test]
    fn entry_encodes_and_parses_back() {
        for kind in TraceKind::ALL {
            assert_eq!(TraceKind::from_code(kind.code()), Some(kind));
            let e = TraceEntry::new(0x0102_0304, kind, &[0xAA, 0xBB]).unwrap();
            let mut out = [0u8; MAX_ENCODED_LEN + 1];
            assert_eq!(e.encode(&mut out), Some(8));
            assert_eq!(out[..8], [4, 3, 2, 1, kind.code(), 2, 0xAA, 0xBB]);
            assert_eq!(TraceEntry::parse(&out[..8]), Ok((e, 8)));
        }
        let full = TraceEntry::new(1, TraceKind::Receive, &[7; CHUNK]).unwrap();
        assert_eq!(full.encode(&mut [0; MAX_ENCODED_LEN - 1]), None);
        assert_eq!(TraceEntry::new(1, TraceKind::Receive, &[7; CHUNK + 1]), None);
    }

    #[rstest]
    #[case::empty(&[], TraceParseError::Truncated)]
    #[case::short_head(&[1, 2, 3, 4, 0], TraceParseError::Truncated)]
    #[case::short_bytes(&[1, 2, 3, 4, 0, 3, 9, 9], TraceParseError::Truncated)]
    #[case::unknown_kind(&[1, 2, 3, 4, 9, 0], TraceParseError::UnknownKind(9))]
    #[case::too_long(&[1, 2, 3, 4, 1, 17], TraceParseError::TooLong(17))]
    fn malformed_entries_are_errors(#[case] wire: &[u8], #[case] error: TraceParseError) {
        assert_eq!(TraceEntry::parse(wire), Err(error));
    }

    proptest::proptest! {
        #[test]
        fn parse_never_panics(wire in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..40)) {
            let _ = TraceEntry::parse(&wire);
        }
    }
}
