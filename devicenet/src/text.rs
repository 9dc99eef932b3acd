//! Messages written piece by piece, without `core::fmt`.
//!
//! A message a device may write (the key of the converter's refusal record, written straight
//! into the reply) goes into a [`TextSink`]: static pieces and decimal or hexadecimal numbers.
//! The firmware's sinks are its own buffers, so none of `core::fmt`'s formatting machinery (some
//! 3 KiB of flash on a Cortex-M) is linked; a host's `Display` is the same writer driving a
//! [`core::fmt::Formatter`] ([`FmtSink`]), so both give the same words.

use core::fmt;

/// Where a message goes, piece by piece. Only [`TextSink::text`] is required.
pub trait TextSink {
    /// Appends `s`.
    fn text(&mut self, s: &str);

    /// Appends `v` in decimal.
    fn decimal(&mut self, v: u32) {
        // The leading digits first, by recursion (at most ten deep): smaller code than collecting
        // the digits in a buffer (firmware size budget).
        if v >= 10 {
            self.decimal(v / 10);
        }
        self.text(digit(v % 10));
    }

    /// Appends `v` as eight upper-case hexadecimal digits (`{v:08X}`).
    // Always inlined into the one sink that uses it (some 30 bytes of the firmware's flash).
    #[inline(always)]
    fn hex8(&mut self, v: u32) {
        for i in (0..8).rev() {
            self.text(digit((v >> (4 * i)) & 0xF));
        }
    }
}

/// The one-character text of the digit `d` (0..=15, upper-case), without `str::from_utf8`'s
/// validation linked in.
fn digit(d: u32) -> &'static str {
    let d = d as usize;
    "0123456789ABCDEF".get(d..d + 1).unwrap_or("0")
}

/// A [`TextSink`] writing into a formatter: `Display` for the types that write their text. The
/// first error of the formatter is kept; later pieces are dropped.
pub struct FmtSink<'a, 'b> {
    f: &'a mut fmt::Formatter<'b>,
    result: fmt::Result,
}

impl<'a, 'b> FmtSink<'a, 'b> {
    /// A sink writing to `f`.
    pub fn new(f: &'a mut fmt::Formatter<'b>) -> Self {
        FmtSink { f, result: Ok(()) }
    }

    /// What the formatter said: the result for `Display::fmt`.
    pub fn finish(self) -> fmt::Result {
        self.result
    }
}

impl TextSink for FmtSink<'_, '_> {
    fn text(&mut self, s: &str) {
        if self.result.is_ok() {
            self.result = self.f.write_str(s);
        }
    }
}

/// Writes `write`'s text to `f`: the body of a `Display::fmt` that uses a text writer.
pub fn display(f: &mut fmt::Formatter<'_>, write: impl FnOnce(&mut FmtSink<'_, '_>)) -> fmt::Result {
    let mut sink = FmtSink::new(f);
    write(&mut sink);
    sink.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;
    use std::string::String;

    /// The sink of a test: everything, in a string.
    struct All(String);

    impl TextSink for All {
        fn text(&mut self, s: &str) {
            self.0.push_str(s);
        }
    }

    #[rstest]
    #[case::zero(0, "0")]
    #[case::one_digit(7, "7")]
    #[case::ten(10, "10")]
    #[case::max(u32::MAX, "4294967295")]
    fn decimal(#[case] v: u32, #[case] text: &str) {
        let mut s = All(String::new());
        s.decimal(v);
        assert_eq!(s.0, text);
    }

    #[rstest]
    #[case::zero(0, "00000000")]
    #[case::crc(0xCBF4_3926, "CBF43926")]
    fn hex8(#[case] v: u32, #[case] text: &str) {
        let mut s = All(String::new());
        s.hex8(v);
        assert_eq!(s.0, text);
    }
}
