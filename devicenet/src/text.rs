//! Messages written piece by piece, without `core::fmt`.
//!
//! An error whose text a device must hold (the converter's refusal reason, a SHORT_STRING
//! attribute) writes it into a [`TextSink`]: static pieces and decimal or hexadecimal numbers.
//! The firmware's sink is a fixed buffer, so none of `core::fmt`'s formatting machinery (some
//! 3 KiB of flash on a Cortex-M) is linked; a host's `Display` is the same writer driving a
//! [`core::fmt::Formatter`] ([`FmtSink`]), so both give the same words.

use core::fmt;

/// Where a message goes, piece by piece. Only [`TextSink::text`] is required.
pub trait TextSink {
    /// Appends `s`.
    fn text(&mut self, s: &str);

    /// Appends `v` in decimal.
    fn decimal(&mut self, v: u32) {
        let mut digits = [0u8; 10];
        self.text(decimal_digits(v, &mut digits));
    }

    /// Appends `v` as eight upper-case hexadecimal digits (`{v:08X}`).
    fn hex8(&mut self, v: u32) {
        let mut digits = [0u8; 8];
        for (i, d) in digits.iter_mut().enumerate() {
            let nibble = (v >> (28 - 4 * i)) & 0xF;
            *d = b"0123456789ABCDEF".get(nibble as usize).copied().unwrap_or(b'0');
        }
        self.text(core::str::from_utf8(&digits).unwrap_or_default());
    }
}

/// The decimal digits of `v`, written at the end of `buf`.
fn decimal_digits(mut v: u32, buf: &mut [u8; 10]) -> &str {
    let mut start = buf.len();
    for slot in buf.iter_mut().rev() {
        *slot = b'0' + (v % 10) as u8;
        start -= 1;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    core::str::from_utf8(buf.get(start..).unwrap_or_default()).unwrap_or_default()
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

/// A [`TextSink`] that keeps what fits in a fixed string and drops the rest (a refusal text cut
/// to the attribute's size).
impl<const N: usize> TextSink for heapless::String<N> {
    fn text(&mut self, s: &str) {
        for c in s.chars() {
            if self.push(c).is_err() {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::zero(0, "0")]
    #[case::one_digit(7, "7")]
    #[case::ten(10, "10")]
    #[case::max(u32::MAX, "4294967295")]
    fn decimal(#[case] v: u32, #[case] text: &str) {
        let mut s = heapless::String::<16>::new();
        s.decimal(v);
        assert_eq!(s, text);
    }

    #[rstest]
    #[case::zero(0, "00000000")]
    #[case::crc(0xCBF4_3926, "CBF43926")]
    fn hex8(#[case] v: u32, #[case] text: &str) {
        let mut s = heapless::String::<16>::new();
        s.hex8(v);
        assert_eq!(s, text);
    }

    #[test]
    fn a_full_string_drops_the_rest() {
        let mut s = heapless::String::<4>::new();
        s.text("ab");
        s.decimal(12345);
        assert_eq!(s, "ab12");
    }
}
