//! The character formats the instrument UART (USART2) can produce.
//!
//! The serial profile decides the line settings (baud, data bits, parity, stop bits); the board
//! decides how the USART makes them. On the STM32F4 the word length bit `CR1.M` counts the parity
//! bit (RM0090 §30.6.4, "USART_CR1"): 8 data bits without parity and 7 with parity are an 8-bit
//! word, 8 data bits with parity a 9-bit word. 7 data bits without parity (a 7-bit word) is a format
//! this USART cannot make, and is refused. With 7 data bits the parity bit arrives as bit 7 of the
//! data register and is masked off ([`LineFormat::data_mask`]).

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
        f.write_str("the USART makes 8 data bits with or without parity, or 7 data bits with parity")
    }
}

impl LineFormat {
    /// 8 data bits, no parity, one stop bit.
    pub const fn new_8n1(baud: u32) -> LineFormat {
        LineFormat { baud, data_bits: 8, parity: Parity::None, stop_bits: StopBits::One }
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
}
