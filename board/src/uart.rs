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
//!
//! [`LineFormat::registers`] gives the values the board writes into `USART_BRR`, `USART_CR1` and
//! `USART_CR2` (RM0090 §30.6): computed here, where host tests check them bit by bit (and
//! stm32-emu's USART tests drive its model with the same values), and written by `hw`. The
//! rule that refuses a line the USART cannot make (the converter's platform check) and the values
//! written are thereby one computation.

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

/// Bits of `USART_SR`, `USART_CR1` and `USART_CR2` (RM0090 §30.6.1, §30.6.4, §30.6.5).
pub mod bits {
    /// SR: parity error.
    pub const SR_PE: u16 = 1 << 0;
    /// SR: framing error.
    pub const SR_FE: u16 = 1 << 1;
    /// SR: noise detected.
    pub const SR_NF: u16 = 1 << 2;
    /// SR: overrun.
    pub const SR_ORE: u16 = 1 << 3;
    /// SR: a received character waits in the data register.
    pub const SR_RXNE: u16 = 1 << 5;
    /// SR: transmission complete (the last stop bit is out).
    pub const SR_TC: u16 = 1 << 6;
    /// SR: the transmit data register is empty.
    pub const SR_TXE: u16 = 1 << 7;
    /// SR: the error flags, cleared by reading SR then DR.
    pub const SR_ERRORS: u16 = SR_PE | SR_FE | SR_NF | SR_ORE;
    /// CR1: receiver enable.
    pub const CR1_RE: u16 = 1 << 2;
    /// CR1: transmitter enable.
    pub const CR1_TE: u16 = 1 << 3;
    /// CR1: interrupt on RXNE (and overrun).
    pub const CR1_RXNEIE: u16 = 1 << 5;
    /// CR1: interrupt on TC.
    pub const CR1_TCIE: u16 = 1 << 6;
    /// CR1: interrupt on TXE.
    pub const CR1_TXEIE: u16 = 1 << 7;
    /// CR1: odd parity (even when clear).
    pub const CR1_PS: u16 = 1 << 9;
    /// CR1: parity control enable.
    pub const CR1_PCE: u16 = 1 << 10;
    /// CR1: 9-bit words (`M`).
    pub const CR1_M: u16 = 1 << 12;
    /// CR1: USART enable.
    pub const CR1_UE: u16 = 1 << 13;
    /// CR1: oversampling by 8 (by 16 when clear).
    pub const CR1_OVER8: u16 = 1 << 15;
    /// CR2: `STOP = 10`, two stop bits (`00`: one).
    pub const CR2_STOP_2: u16 = 0b10 << 12;
}

/// The register values that make a [`LineFormat`] ([`LineFormat::registers`]); the interrupt
/// enable bits of CR1 are left clear.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UsartRegisters {
    /// `USART_BRR`: mantissa and fraction of the divider.
    pub brr: u16,
    /// `USART_CR1`: enabled, transmitter and receiver on, word length, parity, oversampling.
    pub cr1: u16,
    /// `USART_CR2`: the stop bits.
    pub cr2: u16,
}

impl LineFormat {
    /// The register values for this format on a USART clocked at `clock_hz`, or why it cannot
    /// make it: everything [`LineFormat::check`] accepts is made. The divider rounds to the
    /// nearest step and oversamples by 16 where the clock allows it, by 8 above a sixteenth of the
    /// clock (RM0090 §30.3.4): the values the HAL's serial driver computes.
    pub const fn registers(&self, clock_hz: u32) -> Result<UsartRegisters, UnsupportedFormat> {
        use bits::*;
        let m = match self.check(clock_hz) {
            Ok(WordLength::Eight) => 0,
            Ok(WordLength::Nine) => CR1_M,
            Err(e) => return Err(e),
        };
        let parity = match self.parity {
            Parity::None => 0,
            Parity::Even => CR1_PCE,
            Parity::Odd => CR1_PCE | CR1_PS,
        };
        let cr2 = if matches!(self.stop_bits, StopBits::Two) { CR2_STOP_2 } else { 0 };
        // Within the checked range the rounded divider fits 16 bits: baud ≥ clock / 65535, so
        // (clock + baud / 2) / baud ≤ 65535.5.
        let over8 = self.baud > clock_hz / 16;
        let div = ((clock_hz << over8 as u32) + self.baud / 2) / self.baud;
        // 8× oversampling: the fraction has three bits, right-aligned.
        let brr = if over8 { div & !0xF | (div & 0xF) >> 1 } else { div };
        let over8 = if over8 { CR1_OVER8 } else { 0 };
        Ok(UsartRegisters { brr: brr as u16, cr1: CR1_UE | CR1_TE | CR1_RE | over8 | m | parity, cr2 })
    }

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
    pub const fn check(&self, clock_hz: u32) -> Result<WordLength, UnsupportedFormat> {
        let range = Self::baud_range(clock_hz);
        if self.baud < *range.start() || self.baud > *range.end() {
            return Err(UnsupportedFormat);
        }
        self.word_length()
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

    /// Register values worked out by hand from RM0090 §30.3.4 (USARTDIV = f / (16 × baud), or
    /// f / (8 × baud) with OVER8, as mantissa and fraction) and §30.6.4-30.6.5.
    #[rstest]
    // 42 MHz / 9600 = 4375 = 0x1117: mantissa 273, fraction 7/16 (USARTDIV 273.4375).
    #[case::breaker_9600_8n1(LineFormat::new_8n1(9600), 42_000_000, 0x1117, 0x200C, 0)]
    // 42 MHz / 19200 = 2187.5, rounded to 2188 = 0x88C; 8E1: M (9-bit word) and PCE.
    #[case::modbus_19200_8e1(
        LineFormat { baud: 19_200, data_bits: 8, parity: Parity::Even, stop_bits: StopBits::One },
        42_000_000, 0x88C, 0x340C, 0
    )]
    // 7O2: an 8-bit word with PCE and PS; CR2 STOP = 10.
    #[case::seven_odd_two_stop(
        LineFormat { baud: 9600, data_bits: 7, parity: Parity::Odd, stop_bits: StopBits::Two },
        42_000_000, 0x1117, 0x260C, 0x2000
    )]
    // 16 MHz / 115200 = 138.9, rounded to 139 = 0x8B (the emulated service port).
    #[case::service_port(LineFormat::new_8n1(115_200), 16_000_000, 0x8B, 0x200C, 0)]
    // 42 MHz / 4 Mbit/s: above a sixteenth of the clock, so OVER8: 2 × 42 / 4 = 21 = 0x15,
    // fraction 5 shifted right to 2 (USARTDIV 2.625 × 8 = 21).
    #[case::over8(LineFormat::new_8n1(4_000_000), 42_000_000, 0x12, 0xA00C, 0)]
    // The slowest rate: 42 MHz / 641 = 65522.6, rounded to 65523, fits 16 bits.
    #[case::slowest(LineFormat::new_8n1(641), 42_000_000, 65_523, 0x200C, 0)]
    fn register_values(
        #[case] line: LineFormat,
        #[case] clock_hz: u32,
        #[case] brr: u16,
        #[case] cr1: u16,
        #[case] cr2: u16,
    ) {
        assert_eq!(line.registers(clock_hz), Ok(UsartRegisters { brr, cr1, cr2 }));
    }

    /// Every rate [`LineFormat::check`] accepts gets registers, and no other: the firmware's
    /// platform check and the port's set-up agree (at the edges and every 97th rate between).
    #[rstest]
    #[case::board(42_000_000)]
    #[case::emulated(16_000_000)]
    fn registers_exist_exactly_for_the_checked_rates(#[case] clock_hz: u32) {
        let range = LineFormat::baud_range(clock_hz);
        let edges = [0, 1, *range.start() - 1, *range.start(), *range.end(), *range.end() + 1, u32::MAX];
        for baud in edges.into_iter().chain((1..clock_hz / 7).step_by(97)) {
            let line = LineFormat::new_8n1(baud);
            assert_eq!(line.registers(clock_hz).is_ok(), line.check(clock_hz).is_ok(), "{baud} bit/s");
        }
    }

    #[rstest]
    #[case::seven_none(LineFormat { baud: 9600, data_bits: 7, parity: Parity::None, stop_bits: StopBits::One })]
    #[case::too_slow(LineFormat::new_8n1(640))]
    #[case::too_fast(LineFormat::new_8n1(5_250_001))]
    fn registers_refuse_what_the_usart_cannot_make(#[case] line: LineFormat) {
        assert_eq!(line.registers(42_000_000), Err(UnsupportedFormat));
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
