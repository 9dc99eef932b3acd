//! The instrument line on a pty: the USART's characters sampled at the line the instrument side
//! uses, and the instrument's bytes sent to the USART as characters at that line.
//!
//! A pty carries bytes, not bit times: whatever the far program sets with `tcsetattr` does not
//! reach this end (socat joins two ptys byte for byte). So the line's rate and format are given
//! ([`LineSpec`], `--instrument-line`), the ones the instrument on the far end is set to, as on
//! a real wire where both ends must agree. What is checked: the USART's BRR, oversampling,
//! word length, parity and stop bits against that line, character by character, by the
//! receiving rule of stm32-emu (`usart::line`); a character with a framing or parity error is
//! not passed on (counted in [`LineCounts::garbled`]), a character sampled wrong but without
//! error is passed on wrong, as a real receiver would. What is not: that the far program set
//! its own port to the same line (a pty cannot tell).

use std::fmt;
use std::str::FromStr;
use stm32_emu::periph::Nanos;
use stm32_emu::usart::line::{Character, LineSettings, Parity, Receiver, StopBits};
use stm32_emu::usart::Usart;

/// The line the instrument side runs: `BAUD,8N1`, `19200,8E1`, `9600,7O2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineSpec(pub LineSettings);

/// Why a `--instrument-line` value is not a line.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("instrument line '{text}': {why} (BAUD,FORMAT such as 9600,8N1 or 19200,8E1: data bits 5-8, parity N/E/O, stop bits 1 or 2)")]
pub struct BadLine {
    /// The value given.
    pub text: String,
    /// What is wrong with it.
    pub why: &'static str,
}

impl FromStr for LineSpec {
    type Err = BadLine;

    fn from_str(text: &str) -> Result<LineSpec, BadLine> {
        let bad = |why| BadLine { text: text.to_string(), why };
        let (baud, format) = text.split_once(',').ok_or_else(|| bad("no comma"))?;
        let baud: u32 = baud.trim().parse().map_err(|_| bad("the baud rate is not a number"))?;
        if !(300..=4_000_000).contains(&baud) {
            return Err(bad("the baud rate is outside 300..=4000000"));
        }
        let &[data, parity, stop] = format.trim().as_bytes() else {
            return Err(bad("the format is not three characters"));
        };
        let data = match data {
            b'5'..=b'8' => data - b'0',
            _ => return Err(bad("data bits are not 5 to 8")),
        };
        let parity = match parity.to_ascii_uppercase() {
            b'N' => Parity::None,
            b'E' => Parity::Even,
            b'O' => Parity::Odd,
            _ => return Err(bad("parity is not N, E or O")),
        };
        let stop_bits = match stop {
            b'1' => StopBits::One,
            b'2' => StopBits::Two,
            _ => return Err(bad("stop bits are not 1 or 2")),
        };
        let word_bits = data + u8::from(parity != Parity::None);
        Ok(LineSpec(LineSettings { baud: f64::from(baud), word_bits, parity, stop_bits }))
    }
}

impl fmt::Display for LineSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.0;
        let parity = match s.parity {
            Parity::None => 'N',
            Parity::Even => 'E',
            Parity::Odd => 'O',
        };
        let stop = if s.stop_bits == StopBits::Two { 2 } else { 1 };
        write!(f, "{},{}{parity}{stop}", s.baud.round(), s.data_bits())
    }
}

/// What went over the instrument line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineCounts {
    /// Bytes from the USART passed to the pty.
    pub to_instrument: u64,
    /// Bytes from the pty sent to the USART.
    pub from_instrument: u64,
    /// Characters of the USART with a framing or parity error at the instrument's line: dropped.
    pub garbled: u64,
}

/// The line between the USART model and the pty.
#[derive(Clone, Debug)]
pub struct InstrumentLine {
    spec: LineSpec,
    /// When the characters already sent to the USART end on the line.
    busy_until: Nanos,
    counts: LineCounts,
}

/// How far ahead of the machine's time the characters sent to the USART may reach: the pty
/// keeps the rest, so a far end that writes faster than the line runs costs no memory here.
pub const RX_AHEAD: Nanos = 50_000_000;

impl InstrumentLine {
    /// The line `spec`, idle.
    pub fn new(spec: LineSpec) -> InstrumentLine {
        InstrumentLine { spec, busy_until: 0, counts: LineCounts::default() }
    }

    /// What went over it.
    pub fn counts(&self) -> LineCounts {
        self.counts
    }

    /// The bytes the USART sent since the last call, sampled at the instrument's line.
    pub fn from_usart(&mut self, usart: &mut Usart) -> Vec<u8> {
        let receiver = Receiver { settings: self.spec.0, over8: false, one_bit: false };
        let mask = (1u16 << self.spec.0.data_bits()) - 1;
        let mut bytes = Vec::new();
        while let Some(t) = usart.pop_transmitted() {
            let got = receiver.sample(&t.character);
            if got.framing_error || got.parity_error {
                self.counts.garbled += 1;
            } else {
                bytes.push((got.word & mask) as u8);
            }
        }
        self.counts.to_instrument += bytes.len() as u64;
        bytes
    }

    /// How many bytes the USART may be given at machine time `now` ([`RX_AHEAD`]).
    pub fn room(&self, now: Nanos) -> usize {
        let ahead = self.busy_until.saturating_sub(now);
        let left = RX_AHEAD.saturating_sub(ahead);
        usize::try_from(left / self.spec.0.frame_ns().max(1)).unwrap_or(usize::MAX)
    }

    /// Sends `bytes` from the instrument to the USART, one character after the other from `now`.
    pub fn to_usart(&mut self, usart: &mut Usart, bytes: &[u8], now: Nanos) {
        for &b in bytes {
            usart.receive(Character::encode(u16::from(b), self.spec.0), now);
            self.busy_until = self.busy_until.max(now) + self.spec.0.frame_ns();
        }
        self.counts.from_instrument += bytes.len() as u64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use stm32_emu::usart::UsartId;

    #[test]
    fn line_specs_parse_and_print_back() {
        for text in ["9600,8N1", "19200,8E1", "115200,7O2"] {
            assert_eq!(text.parse::<LineSpec>().expect(text).to_string(), text);
        }
        let meter: LineSpec = "19200,8E1".parse().unwrap();
        assert_eq!((meter.0.word_bits, meter.0.parity, meter.0.data_bits()), (9, Parity::Even, 8));
    }

    #[test]
    fn bad_line_specs_say_what_is_wrong() {
        for (text, why) in [
            ("9600", "no comma"),
            ("fast,8N1", "the baud rate is not a number"),
            ("100,8N1", "the baud rate is outside 300..=4000000"),
            ("9600,8N", "the format is not three characters"),
            ("9600,9N1", "data bits are not 5 to 8"),
            ("9600,8X1", "parity is not N, E or O"),
            ("9600,8N3", "stop bits are not 1 or 2"),
        ] {
            assert_eq!(text.parse::<LineSpec>().unwrap_err().why, why, "{text}");
        }
    }

    #[test]
    fn room_shrinks_as_characters_are_queued_and_grows_as_time_passes() {
        let spec: LineSpec = "9600,8N1".parse().unwrap();
        let mut line = InstrumentLine::new(spec);
        let mut usart = Usart::new(UsartId::Usart2);
        let frame = spec.0.frame_ns();
        let empty = line.room(0);
        assert_eq!(empty as u64, RX_AHEAD / frame);
        line.to_usart(&mut usart, &[0x55; 10], 0);
        assert_eq!(line.room(0), empty - 10);
        assert_eq!(line.room(10 * frame), empty);
        assert_eq!(line.counts().from_instrument, 10);
    }
}
