//! The serial line between a USART and the outside: characters with the baud rate and format
//! they were sent with, and what a receiver with its own baud rate and format samples from them.
//!
//! # The receiving rule
//!
//! RM0090 §30.3.5 ("USART receiver tolerance to clock deviation") guarantees a correct reception
//! while the deviation between the sender's and the receiver's rates stays below 3.75 % (16×
//! oversampling, M = 0, three samples per bit), 3.41 % (M = 1), 2.50 % / 2.27 % (8× oversampling),
//! 4.375 % / 3.97 % and 3.75 % / 3.41 % with ONEBIT. Each figure is a drift margin over the frame:
//! 6/16 of a bit (16×), 2/8 (8×), 7/16 and 3/8 with ONEBIT, divided by the frame's bits up to
//! its stop bit (10 for M = 0, 11 for M = 1).
//!
//! The model applies that margin bit by bit: bit k of the frame (0 the start bit) is read right
//! while (k + 1) × |r − 1| stays within the margin, r being the sender's rate over the
//! receiver's. Beyond it the sample falls as far from the bit's centre as the excess drift puts
//! it (a faster sender's later bits, a slower sender's earlier ones), and the receiver reads
//! whatever the sender's line holds there: a neighbouring bit, the stop level, the idle level
//! after the frame. The stop bit sampled low is a framing error (FE); the receiver checks the
//! first stop bit only (§30.3.3). A word whose parity is wrong for the receiver's setting is a
//! parity error (PE). The line is noiseless: the noise flag (NF) is never set. Each character
//! is sampled on its own, the line idle after it (a following character's start bit, which a
//! slow receiver might sample, is not modelled).

/// Parity of a line (CR1.PCE / PS, RM0090 §30.6.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Parity {
    /// No parity bit.
    None,
    /// Even: the word, parity bit included, has an even number of ones.
    Even,
    /// Odd.
    Odd,
}

/// Stop bits (CR2.STOP, RM0090 §30.6.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopBits {
    /// `01`: 0.5.
    Half,
    /// `00`: 1.
    One,
    /// `11`: 1.5.
    OneAndHalf,
    /// `10`: 2.
    Two,
}

impl StopBits {
    /// The stop bits' length in bit times.
    pub const fn bits(self) -> f64 {
        match self {
            StopBits::Half => 0.5,
            StopBits::One => 1.0,
            StopBits::OneAndHalf => 1.5,
            StopBits::Two => 2.0,
        }
    }
}

/// A line's rate and character format.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineSettings {
    /// Bits per second (a USART's exact rate: its clock over USARTDIV).
    pub baud: f64,
    /// Bits of the word after the start bit, parity included: 8 or 9 on the STM32 (CR1.M), and
    /// anything from 5 to 9 for another sender.
    pub word_bits: u8,
    /// Parity (the word's last bit when not `None`).
    pub parity: Parity,
    /// Stop bits.
    pub stop_bits: StopBits,
}

impl LineSettings {
    /// 8 data bits, no parity, one stop bit.
    pub const fn new_8n1(baud: f64) -> LineSettings {
        LineSettings { baud, word_bits: 8, parity: Parity::None, stop_bits: StopBits::One }
    }

    /// The character's length in nanoseconds: start bit, word, stop bits.
    pub fn frame_ns(&self) -> u64 {
        let bits = 1.0 + f64::from(self.word_bits) + self.stop_bits.bits();
        if self.baud > 0.0 {
            (bits * 1e9 / self.baud).round() as u64
        } else {
            u64::MAX
        }
    }

    /// The word's bits that carry data.
    pub const fn data_bits(&self) -> u8 {
        match self.parity {
            Parity::None => self.word_bits,
            _ => self.word_bits - 1,
        }
    }
}

/// One character on the line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Character {
    /// The word after the start bit, least significant bit first, parity bit included.
    pub word: u16,
    /// The sender's rate and format.
    pub settings: LineSettings,
}

/// Whether `word` (of `bits` bits) has the parity `parity` asks for.
pub(crate) fn parity_ok(word: u16, bits: u8, parity: Parity) -> bool {
    let ones = (u32::from(word) & ((1 << bits) - 1)).count_ones();
    match parity {
        Parity::None => true,
        Parity::Even => ones % 2 == 0,
        Parity::Odd => ones % 2 == 1,
    }
}

/// `data` with its parity bit added above its data bits.
pub(crate) fn with_parity(data: u16, data_bits: u8, parity: Parity) -> u16 {
    let data = data & ((1 << data_bits) - 1);
    let odd_ones = data.count_ones() % 2 == 1;
    let bit = match parity {
        Parity::None => return data,
        Parity::Even => odd_ones,
        Parity::Odd => !odd_ones,
    };
    data | u16::from(bit) << data_bits
}

impl Character {
    /// The character a sender with `settings` makes of `data` (its parity bit computed).
    pub fn encode(data: u16, settings: LineSettings) -> Character {
        Character { word: with_parity(data, settings.data_bits(), settings.parity), settings }
    }

    /// The data bits of the word.
    pub fn data(&self) -> u16 {
        self.word & ((1 << self.settings.data_bits()) - 1)
    }

    /// The line level at `x` sender bit times after the start bit's falling edge: low in the
    /// start bit, the word's bits, high after them (stop bits and idle).
    fn level_at(&self, x: f64) -> bool {
        if x < 0.0 {
            return true;
        }
        let bit = x.floor() as i64;
        match bit {
            0 => false,
            b if b <= i64::from(self.settings.word_bits) => self.word >> (b - 1) & 1 != 0,
            _ => true,
        }
    }
}

/// How a receiver samples (RM0090 §30.3.3, §30.3.5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Receiver {
    /// Its rate and format.
    pub settings: LineSettings,
    /// CR1.OVER8: 8× oversampling.
    pub over8: bool,
    /// CR3.ONEBIT: one sample per bit.
    pub one_bit: bool,
}

/// What the receiver got from one character.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Received {
    /// The word as the data register holds it (parity bit included, RM0090 §30.6.2).
    pub word: u16,
    /// The stop bit was sampled low.
    pub framing_error: bool,
    /// The word's parity is wrong for the receiver.
    pub parity_error: bool,
}

impl Receiver {
    /// The drift the receiver tolerates over a frame, in bit times (see the module docs).
    fn margin(&self) -> f64 {
        match (self.over8, self.one_bit) {
            (false, false) => 6.0 / 16.0,
            (false, true) => 7.0 / 16.0,
            (true, false) => 2.0 / 8.0,
            (true, true) => 3.0 / 8.0,
        }
    }

    /// The receiver's tolerance as a fraction (RM0090 §30.3.5 tables: 0.0375 for 16×, M = 0).
    pub fn tolerance(&self) -> f64 {
        self.margin() / (f64::from(self.settings.word_bits) + 2.0)
    }

    /// Samples `character` (see the module docs for the rule).
    pub fn sample(&self, character: &Character) -> Received {
        let r = character.settings.baud / self.settings.baud;
        let deviation = (r - 1.0).abs();
        let direction = if r >= 1.0 { 1.0 } else { -1.0 };
        let margin = self.margin();
        let read = |k: u8| {
            let centre = f64::from(k) + 0.5;
            let excess = f64::from(k + 1) * deviation - margin;
            let at = if excess > 0.0 { centre + direction * (excess + 0.5) } else { centre };
            character.level_at(at)
        };
        let bits = self.settings.word_bits;
        let word = (1..=bits).filter(|&k| read(k)).fold(0u16, |w, k| w | 1 << (k - 1));
        Received {
            word,
            framing_error: !read(bits + 1),
            parity_error: !parity_ok(word, bits, self.settings.parity),
        }
    }
}
