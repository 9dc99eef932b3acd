//! The character formats the instrument UART (USART2) can produce.
//!
//! The serial profile decides the line settings (baud, data bits, parity, stop bits); the board
//! decides how the USART makes them. On the STM32F4 the word length bit `CR1.M` counts the parity
//! bit (RM0090 §30.6.4, "USART_CR1"): 8 data bits without parity and 7 with parity are an 8-bit
//! word, 8 data bits with parity a 9-bit word. 7 data bits without parity (a 7-bit word) is a format
//! this USART cannot make, and is refused. With 7 data bits the parity bit arrives as bit 7 of the
//! data register and is masked off ([`LineFormat::data_mask`]).
//!
//! The baud rate divider (`USART_BRR`, 16 bits) bounds the rates the USART makes from its clock
//! ([`LineFormat::baud_range`]): at most an eighth of the clock (8× oversampling), at least the
//! clock over 65535; a rate outside is refused, not approximated.

use core::fmt;

/// Parity of the instrument line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Parity {
    /// No parity bit.
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

/// Stop bits of the instrument line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopBits {
    /// One stop bit.
    One,
    /// Two stop bits.
    Two,
}

/// The USART word length (`CR1.M`), parity bit included.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WordLength {
    /// `M = 0`: 8-bit words.
    Eight,
    /// `M = 1`: 9-bit words.
    Nine,
}

/// The instrument line's settings as the board takes them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LineFormat {
    /// Bits per second.
    pub baud: u32,
    /// Data bits per character: 7 or 8.
    pub data_bits: u8,
    /// Parity.
    pub parity: Parity,
    /// Stop bits.
    pub stop_bits: StopBits,
}

/// A line format the USART cannot make.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UnsupportedFormat;

impl fmt::Display for UnsupportedFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(
            "the USART makes 8 data bits with or without parity, or 7 data bits with parity, at a \
             baud rate its divider reaches",
        )
    }
}

impl LineFormat {
    /// 8 data bits, no parity, one stop bit.
    pub const fn new_8n1(baud: u32) -> LineFormat {
        LineFormat { baud, data_bits: 8, parity: Parity::None, stop_bits: StopBits::One }
    }

    /// The baud rates the USART makes from a `clock_hz` clock
    /// ([`crate::clocks::INSTRUMENT_UART_HZ`] for the instrument port).
    pub const fn baud_range(clock_hz: u32) -> core::ops::RangeInclusive<u32> {
        clock_hz.div_ceil(u16::MAX as u32)..=clock_hz / 8
    }

    /// The word length, when the USART running from `clock_hz` makes this format (character
    /// format and baud rate, [`LineFormat::baud_range`]).
    pub fn check(&self, clock_hz: u32) -> Result<WordLength, UnsupportedFormat> {
        let word = self.word_length()?;
        if Self::baud_range(clock_hz).contains(&self.baud) {
            Ok(word)
        } else {
            Err(UnsupportedFormat)
        }
    }

    /// The word length for this format, or why the USART cannot make it.
    pub const fn word_length(&self) -> Result<WordLength, UnsupportedFormat> {
        match (self.data_bits, self.parity) {
            (8, Parity::None) | (7, Parity::Even | Parity::Odd) => Ok(WordLength::Eight),
            (8, Parity::Even | Parity::Odd) => Ok(WordLength::Nine),
            _ => Err(UnsupportedFormat),
        }
    }

    /// The data bits of a received word (the parity bit, when inside the byte, removed).
    pub const fn data_mask(&self) -> u8 {
        if self.data_bits == 7 {
            0x7F
        } else {
            0xFF
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn format(data_bits: u8, parity: Parity) -> LineFormat {
        LineFormat { baud: 9600, data_bits, parity, stop_bits: StopBits::One }
    }

    #[rstest]
    #[case::eight_none(8, Parity::None, Ok(WordLength::Eight), 0xFF)]
    #[case::eight_even(8, Parity::Even, Ok(WordLength::Nine), 0xFF)]
    #[case::eight_odd(8, Parity::Odd, Ok(WordLength::Nine), 0xFF)]
    #[case::seven_even(7, Parity::Even, Ok(WordLength::Eight), 0x7F)]
    #[case::seven_odd(7, Parity::Odd, Ok(WordLength::Eight), 0x7F)]
    #[case::seven_none(7, Parity::None, Err(UnsupportedFormat), 0x7F)]
    #[case::nine_none(9, Parity::None, Err(UnsupportedFormat), 0xFF)]
    fn word_lengths(
        #[case] data_bits: u8,
        #[case] parity: Parity,
        #[case] word: Result<WordLength, UnsupportedFormat>,
        #[case] mask: u8,
    ) {
        assert_eq!(format(data_bits, parity).word_length(), word);
        assert_eq!(format(data_bits, parity).data_mask(), mask);
    }

    #[test]
    fn breaker_line() {
        assert_eq!(LineFormat::new_8n1(9600), format(8, Parity::None));
    }

    #[rstest]
    #[case::board_9600(42_000_000, 9600, true)]
    #[case::board_lowest(42_000_000, 641, true)]
    #[case::board_too_slow(42_000_000, 640, false)]
    #[case::board_fastest(42_000_000, 5_250_000, true)]
    #[case::board_too_fast(42_000_000, 5_250_001, false)]
    #[case::emulated_300(16_000_000, 300, true)]
    #[case::emulated_too_fast(16_000_000, 4_000_000, false)]
    fn baud_rates(#[case] clock_hz: u32, #[case] baud: u32, #[case] made: bool) {
        let line = LineFormat::new_8n1(baud);
        assert_eq!(line.check(clock_hz).is_ok(), made);
    }
}
