//! Fragment series as the decoder reads them: I/O reassembly per connection direction, and the
//! breaches of the fragmentation protocol (protocol §4.1, §4.2) named as protocol errors.
//!
//! A receiving node drops a broken series without a word (protocol §4: a first fragment whose count
//! is not 0 is dropped, a middle or last without a first is dropped, an out-of-sequence count
//! resets reassembly, a first fragment in the middle of a series restarts it). A decoder must not:
//! each of these is a [`FragmentViolation`] in the frame's text and in
//! [`Decoded::protocol_error`](super::Decoded::protocol_error).

use super::{push_data_text, push_hex, push_u8, Decoded};
use devicenet::fragment::{next_count, FragmentError, FragmentKind, IoReassembler, SINGLE_FRAGMENT_COUNT};
use std::fmt::Write as _;

use super::MAX_IO_MESSAGE;

/// A breach of the fragmentation protocol seen in a trace (protocol §4.1 explicit, §4.2 I/O).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FragmentViolation {
    /// A first fragment whose count is neither 0 nor the one-frame 0x3F: a series begins at 0.
    #[error("first fragment with count {count}, where a series begins with count 0")]
    FirstCountNotZero {
        /// The count it carried.
        count: u8,
    },
    /// A middle or last fragment with no series in progress: its first fragment was never sent or
    /// was lost (or the trace begins in the middle of a series).
    #[error("{kind} fragment #{count} without a first fragment")]
    NoFirst {
        /// Middle or last.
        kind: FragmentKind,
        /// The count it carried.
        count: u8,
    },
    /// A count other than the one due: fragments were missed (ahead of the count due), or one
    /// came again or out of order (behind it).
    #[error("fragment #{got} where #{expected} was due: {}", skipped_text(*.expected, *.got))]
    OutOfSequence {
        /// The count due.
        expected: u8,
        /// The count received.
        got: u8,
    },
    /// A first fragment while an I/O series was still waiting for fragment `expected`: the rest
    /// of that series was missed.
    #[error("a new series began while fragment #{expected} of the one in progress was due: the rest of that series was missed")]
    Unfinished {
        /// The count the unfinished series waited for.
        expected: u8,
    },
    /// An acknowledge-type fragment on an I/O connection (protocol §4.2: I/O fragmentation has no
    /// acknowledgements).
    #[error("acknowledge-type fragment, which I/O fragmentation does not have")]
    AckInIo,
}

fn skipped_text(expected: u8, got: u8) -> String {
    // Counts are 6 bits (protocol §4.1): ahead of the due count by less than half the range means
    // fragments were missed; otherwise the fragment is one already seen, or out of order.
    let ahead = got.wrapping_sub(expected) & 0x3F;
    match ahead {
        1 => format!("fragment #{expected} was missed"),
        2..=31 => format!("fragments #{expected} to #{} were missed", got.wrapping_sub(1) & 0x3F),
        _ => "a fragment repeated or out of order".into(),
    }
}

impl FragmentViolation {
    /// The violation a reassembler's error stands for, for a fragment of `kind` with `count`;
    /// `None` for errors that are no breach of the protocol (a malformed frame, a series longer
    /// than the decoder keeps).
    pub fn of(error: FragmentError, kind: FragmentKind, count: u8) -> Option<FragmentViolation> {
        match error {
            FragmentError::FirstCountNotZero(count) => Some(FragmentViolation::FirstCountNotZero { count }),
            FragmentError::NoFirstFragment => Some(FragmentViolation::NoFirst { kind, count }),
            FragmentError::OutOfSequence { expected, got } => {
                Some(FragmentViolation::OutOfSequence { expected, got })
            }
            FragmentError::UnexpectedAck => Some(FragmentViolation::AckInIo),
            _ => None,
        }
    }

    /// What the receiver does about it, as the text says after the violation.
    pub fn consequence(self) -> &'static str {
        match self {
            FragmentViolation::FirstCountNotZero { .. } | FragmentViolation::NoFirst { .. } => {
                "fragment dropped"
            }
            FragmentViolation::OutOfSequence { .. } | FragmentViolation::AckInIo => "series dropped",
            FragmentViolation::Unfinished { .. } => "unfinished series dropped",
        }
    }

    /// Appends ` (protocol error: ...; consequence)` to `out`.
    pub fn push(self, out: &mut String) {
        let _ = write!(out, " (protocol error: {self}; {})", self.consequence());
    }
}

/// Tracks an I/O fragment series on one connection direction.
#[derive(Clone)]
pub(super) struct IoSeries {
    rx: IoReassembler<MAX_IO_MESSAGE>,
    /// The count expected next while a series is in progress.
    next: Option<u8>,
    /// The connection's size is unknown, but a whole series of several fragments was seen on it:
    /// it is fragmented (a connection has one size), so every later frame is a fragment.
    proven: bool,
}

impl IoSeries {
    pub(super) fn new() -> IoSeries {
        IoSeries { rx: IoReassembler::new(), next: None, proven: false }
    }

    /// Whether `data` is a fragment when the connection size is not known. An 8-byte frame
    /// starting with `00` opens a series. While one is in progress, the fragment due (a middle or
    /// last byte with the count due) continues it, and so does any middle, last or ack byte in a
    /// frame shorter than 8 bytes: a connection has one size, so after 8 bytes a shorter frame
    /// cannot be plain data, and a count other than the one due is then a missed fragment. An
    /// 8-byte frame with another count is taken as plain data (the `00` frame was data too).
    /// Once a whole series of several fragments was seen on the connection, it is fragmented:
    /// every frame shaped like a fragment is one (a first or middle fragment fills its frame, a
    /// first with the one-frame count 0x3F and a last may be shorter).
    fn looks_fragmented(&self, data: &[u8]) -> bool {
        let Some(&b) = data.first() else { return false };
        let kind = FragmentKind::from_bits(b >> 6);
        if self.proven {
            return match kind {
                FragmentKind::First => data.len() == 8 || b & 0x3F == SINGLE_FRAGMENT_COUNT,
                FragmentKind::Middle => data.len() == 8,
                FragmentKind::Last | FragmentKind::Ack => true,
            };
        }
        match self.next {
            None => b == 0x00 && data.len() == 8,
            Some(_) if kind == FragmentKind::First => false,
            Some(next) => (b & 0x3F == next && kind != FragmentKind::Ack) || data.len() < 8,
        }
    }
}

/// Who sent I/O data: `name` ends with "MAC ", the MAC follows.
#[derive(Clone, Copy)]
pub(super) struct Who {
    pub(super) name: &'static str,
    pub(super) mac: u8,
}

impl Who {
    pub(super) fn push(self, out: &mut String) {
        out.push_str(self.name);
        push_u8(out, self.mac);
    }
}

/// I/O data on a connection of `size` bytes (unknown: inferred from the fragment bytes).
pub(super) fn io_data(series: &mut IoSeries, size: Option<u16>, who: Who, data: &[u8]) -> Decoded {
    let mut out = Decoded::default();
    io_data_into(series, size, who, data, &mut out);
    out
}

/// [`io_data`] into `out` (cleared by the caller).
pub(super) fn io_data_into(
    series: &mut IoSeries,
    size: Option<u16>,
    who: Who,
    data: &[u8],
    out: &mut Decoded,
) {
    let fragmented = match size {
        Some(size) => size > 8,
        None => series.looks_fragmented(data),
    };
    let summary = &mut out.summary;
    who.push(summary);
    summary.push_str(": ");
    if !fragmented {
        series.next = None;
        series.rx.reset();
        if data.is_empty() {
            summary.push_str("no data (idle)");
        } else {
            push_data_text(summary, data);
        }
        return;
    }
    let (kind, count) = match data.first() {
        Some(&b) => (FragmentKind::from_bits(b >> 6), b & 0x3F),
        None => (FragmentKind::First, 0),
    };
    summary.push_str("I/O fragment ");
    summary.push_str(fragment_name(kind));
    summary.push_str(" #");
    push_u8(summary, count);
    if kind == FragmentKind::First && count == SINGLE_FRAGMENT_COUNT {
        summary.push_str(" (a one-frame series: the whole message)");
    }
    if size.is_none() {
        summary.push_str(", size inferred from fragment bytes");
    }
    summary.push_str(": ");
    push_hex(summary, data.get(1..).unwrap_or(&[]));
    // A first fragment restarts the series (protocol §4.2): one still in progress lost its end.
    let unfinished = match (kind, series.next) {
        (FragmentKind::First, Some(expected)) => Some(FragmentViolation::Unfinished { expected }),
        _ => None,
    };
    if let Some(v) = unfinished {
        v.push(summary);
        out.protocol_error = Some(v);
    }
    match series.rx.receive(data) {
        Ok(Some(whole)) => {
            series.next = None;
            series.proven |= size.is_none() && kind == FragmentKind::Last;
            let mut message = String::with_capacity(40 + whole.len() * 3);
            who.push(&mut message);
            let _ = write!(message, ", {} bytes: ", whole.len());
            push_hex(&mut message, whole);
            out.message = Some(message);
        }
        Ok(None) => series.next = Some(next_count(count)),
        Err(e) => {
            series.next = None;
            match FragmentViolation::of(e, kind, count) {
                Some(v) => {
                    v.push(&mut out.summary);
                    out.protocol_error = Some(v);
                }
                None => {
                    let _ = write!(out.summary, " (dropped: {e})");
                }
            }
        }
    }
}

/// The fragment type as `FragmentKind`'s `Display` writes it.
pub(super) fn fragment_name(kind: FragmentKind) -> &'static str {
    match kind {
        FragmentKind::First => "first",
        FragmentKind::Middle => "middle",
        FragmentKind::Last => "last",
        FragmentKind::Ack => "ack",
    }
}

#[cfg(test)]
mod tests {
    use super::super::Decoder;
    use super::*;
    use devicenet::CanFrame;
    use rstest::rstest;

    fn f(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::from_raw(id, data).unwrap()
    }

    /// The sizes of the poll connection of MAC 5 (18 produced, 8 consumed) read from Connection 2
    /// attributes 7 and 8, as in the bring-up (protocol §2 frames 18-21).
    fn sized() -> Decoder {
        let mut d = Decoder::new();
        d.decode(&f(0x42C, &[0x00, 0x0E, 0x05, 0x02, 0x07]));
        d.decode(&f(0x42B, &[0x00, 0x8E, 0x12, 0x00]));
        d
    }

    /// Each frame's protocol error, decoding `frames` of the poll response of MAC 5 in order.
    fn errors(mut d: Decoder, frames: &[&[u8]]) -> Vec<(Option<FragmentViolation>, String)> {
        frames
            .iter()
            .map(|data| {
                let out = d.decode(&f(0x3C5, data));
                (out.protocol_error, out.text())
            })
            .collect()
    }

    const FIRST: &[u8] = &[0x00, 0, 1, 2, 3, 4, 5, 6];
    const MIDDLE: &[u8] = &[0x41, 7, 8, 9, 10, 11, 12, 13];
    const LAST: &[u8] = &[0x82, 14, 15, 16, 17];

    #[rstest]
    #[case::first_count_not_zero(&[&[0x03, 0, 1, 2, 3, 4, 5, 6][..]], 0, FragmentViolation::FirstCountNotZero { count: 3 })]
    #[case::middle_without_first(&[MIDDLE], 0, FragmentViolation::NoFirst { kind: FragmentKind::Middle, count: 1 })]
    #[case::last_without_first(&[LAST], 0, FragmentViolation::NoFirst { kind: FragmentKind::Last, count: 2 })]
    #[case::missed_middle(&[FIRST, LAST], 1, FragmentViolation::OutOfSequence { expected: 1, got: 2 })]
    #[case::missed_last(&[FIRST, MIDDLE, FIRST], 2, FragmentViolation::Unfinished { expected: 2 })]
    #[case::repeated_middle(&[FIRST, MIDDLE, MIDDLE], 2, FragmentViolation::OutOfSequence { expected: 2, got: 1 })]
    #[case::ack_type(&[FIRST, &[0xC1, 7][..]], 1, FragmentViolation::AckInIo)]
    fn broken_io_series_are_protocol_errors(
        #[case] frames: &[&[u8]],
        #[case] at: usize,
        #[case] violation: FragmentViolation,
    ) {
        let seen = errors(sized(), frames);
        for (i, (error, text)) in seen.iter().enumerate() {
            if i == at {
                assert_eq!(*error, Some(violation), "{text}");
                assert!(text.contains(&format!("(protocol error: {violation}")), "{text}");
            } else {
                assert_eq!(*error, None, "frame {i}: {text}");
            }
        }
        // Nothing was reassembled from the broken series.
        assert!(seen.iter().all(|(_, text)| !text.contains("=>")), "{seen:?}");
    }

    #[test]
    fn the_texts_say_what_was_missed() {
        let missed = FragmentViolation::OutOfSequence { expected: 1, got: 2 };
        assert_eq!(missed.to_string(), "fragment #2 where #1 was due: fragment #1 was missed");
        let two = FragmentViolation::OutOfSequence { expected: 1, got: 3 };
        assert_eq!(two.to_string(), "fragment #3 where #1 was due: fragments #1 to #2 were missed");
        let again = FragmentViolation::OutOfSequence { expected: 2, got: 1 };
        assert_eq!(again.to_string(), "fragment #1 where #2 was due: a fragment repeated or out of order");
    }

    /// Without the sizes, a missed fragment inside a series that was inferred is still named.
    #[test]
    fn a_missed_fragment_is_named_without_the_sizes() {
        let seen = errors(Decoder::new(), &[FIRST, LAST]);
        assert_eq!(
            seen[1].0,
            Some(FragmentViolation::OutOfSequence { expected: 1, got: 2 }),
            "{}",
            seen[1].1
        );
    }

    /// Without the sizes, once a whole series was seen the connection is known to be fragmented:
    /// a first fragment with a wrong count and a middle without a first are named.
    #[test]
    fn a_connection_seen_fragmented_stays_fragmented() {
        let seen = errors(
            Decoder::new(),
            &[FIRST, MIDDLE, LAST, &[0x05, 0, 1, 2, 3, 4, 5, 6][..], MIDDLE, FIRST, MIDDLE, LAST],
        );
        assert!(seen[2].1.contains("=> poll response from MAC 5, 18 bytes"), "{}", seen[2].1);
        assert_eq!(seen[3].0, Some(FragmentViolation::FirstCountNotZero { count: 5 }), "{}", seen[3].1);
        assert_eq!(seen[4].0, Some(FragmentViolation::NoFirst { kind: FragmentKind::Middle, count: 1 }));
        assert!(seen[7].1.contains("=> poll response from MAC 5, 18 bytes"), "{}", seen[7].1);
        assert_eq!(seen.iter().filter(|s| s.0.is_some()).count(), 2);
    }

    /// Without the sizes, 8-byte frames of plain data (a bit-strobe response: the breaker's
    /// currents, 0 while open, 120 A = 0x78 once closed) are never taken for a broken series.
    #[test]
    fn plain_8_byte_data_is_no_protocol_error_without_the_sizes() {
        let mut d = Decoder::new();
        let open = [0x00, 0, 0, 0, 0, 0, 0, 0];
        let closed = [0x78, 118, 121, 3, 0, 0, 0, 0];
        for data in [&open, &open, &closed, &open, &closed, &closed] {
            let out = d.decode(&f(0x385, data));
            assert_eq!(out.protocol_error, None, "{}", out.text());
        }
    }

    /// The reference series of protocol §2 (frames 25-27) and a one-frame series are no errors.
    #[test]
    fn whole_series_are_no_errors() {
        let seen = errors(sized(), &[FIRST, MIDDLE, LAST, &[0x3F, 1, 2][..]]);
        assert!(seen.iter().all(|s| s.0.is_none()), "{seen:?}");
    }

    #[rstest]
    #[case::first_count_not_zero(&[0x80, 0x03, 0x8E, 1, 2, 3, 4, 5], FragmentViolation::FirstCountNotZero { count: 3 })]
    #[case::middle_without_first(&[0x80, 0x41, 1, 2, 3, 4, 5, 6], FragmentViolation::NoFirst { kind: FragmentKind::Middle, count: 1 })]
    #[case::last_without_first(&[0x80, 0x82, 1, 2], FragmentViolation::NoFirst { kind: FragmentKind::Last, count: 2 })]
    fn broken_explicit_fragments_are_protocol_errors(
        #[case] data: &[u8],
        #[case] violation: FragmentViolation,
    ) {
        let mut d = Decoder::new();
        d.decode(&f(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]));
        let out = d.decode(&f(0x42B, data));
        assert_eq!(out.protocol_error, Some(violation), "{}", out.text());
        assert!(
            out.summary.contains(&format!("(protocol error: {violation}; fragment dropped)")),
            "{}",
            out.summary
        );
    }

    #[test]
    fn a_missed_explicit_fragment_is_a_protocol_error() {
        let mut d = Decoder::new();
        d.decode(&f(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]));
        assert_eq!(
            d.decode(&f(0x42B, &[0x80, 0x00, 0x8E, 0x17, b'S', b'e', b'r', b'i'])).protocol_error,
            None
        );
        let out = d.decode(&f(0x42B, &[0x80, 0x42, b'i', b'c', b'e', b'N', b'e', b't']));
        assert_eq!(
            out.protocol_error,
            Some(FragmentViolation::OutOfSequence { expected: 1, got: 2 }),
            "{}",
            out.text()
        );
        // A repeated fragment (its ack was lost, protocol §4.1) is a retry, not an error.
        let mut d = Decoder::new();
        d.decode(&f(0x42B, &[0x80, 0x00, 0x8E, 0x17, b'S', b'e', b'r', b'i']));
        let again = d.decode(&f(0x42B, &[0x80, 0x00, 0x8E, 0x17, b'S', b'e', b'r', b'i']));
        assert_eq!(again.protocol_error, None, "{}", again.text());
    }
}
