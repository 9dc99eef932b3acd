//! The USARTs in asynchronous mode (RM0090 §30 "Universal synchronous asynchronous receiver
//! transmitter", registers §30.6): USART1 (0x4001_1000, APB2, IRQ 37), USART2 (0x4000_4400,
//! APB1, IRQ 38), USART6 (0x4001_1400, APB2, IRQ 71).
//!
//! Registers: SR (§30.6.1) with TXE, TC, RXNE, IDLE, ORE, NF, FE, PE and their clear sequences
//! (read SR then read DR for RXNE's errors and IDLE; read SR then write DR for TC), DR (§30.6.2),
//! BRR (§30.6.3: mantissa and fraction, whose meaning OVER8 changes, §30.3.4), CR1 (§30.6.4:
//! UE, M, PCE, PS, TE, RE, the interrupt enables, OVER8), CR2 (§30.6.5: STOP), CR3 (§30.6.6) and
//! GTPR (§30.6.7) kept as written. The interrupt line is the OR of each enabled flag.
//!
//! RS-485: the STM32F4's USART has no driver-enable output (CR3 has no DEM bit, §30.6.6; the
//! USARTs of later families have one), so the board drives the transceiver's DE from a GPIO
//! (PA1, `board::pins::RS485_DE`), which the GPIO model shows ([`crate::gpio::Gpio`]).
//!
//! The line side ([`mod@line`]): every character written leaves after the time its frame takes at
//! the configured rate (start, word, parity, stop bits), as a [`line::Character`] carrying that
//! rate and format ([`Usart::pop_transmitted`]); setting TE first sends an idle frame (§30.3.2).
//! A character arriving from outside ([`Usart::receive`]) carries its sender's rate and format;
//! the receiver samples it with its own ([`line::Receiver::sample`]: garbled beyond the §30.3.5
//! tolerance, FE when the stop bit reads low, PE on a parity mismatch), and a character
//! completed while RXNE is still set sets ORE and is lost (§30.6.1). Which pins carry the lines
//! (PA9/PA10, PA2/PA3 in AF7) is the machine's concern.

pub mod line;

use crate::gpio::{lanes, read_lanes};
use crate::periph::{ClockGate, Machine, Nanos, Peripheral, ResetKind, Width};
use line::{with_parity, Character, LineSettings, Parity, Receiver, StopBits};
use std::collections::VecDeque;

/// One of the USARTs the firmware may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UsartId {
    /// USART1 (APB2).
    Usart1,
    /// USART2 (APB1).
    Usart2,
    /// USART6 (APB2).
    Usart6,
}

impl UsartId {
    /// The register block's base address (RM0090 §2.3 table 1).
    pub const fn base(self) -> u32 {
        match self {
            UsartId::Usart1 => 0x4001_1000,
            UsartId::Usart2 => 0x4000_4400,
            UsartId::Usart6 => 0x4001_1400,
        }
    }

    /// The interrupt's position (RM0090 §12.2 table 61).
    pub const fn irq(self) -> u16 {
        match self {
            UsartId::Usart1 => 37,
            UsartId::Usart2 => 38,
            UsartId::Usart6 => 71,
        }
    }

    /// The clock gate: RCC_APB2ENR bit 4 / 5, RCC_APB1ENR bit 17 (RM0090 §7.3.13, §7.3.14).
    pub const fn clock_gate(self) -> ClockGate {
        match self {
            UsartId::Usart1 => ClockGate::Apb2(4),
            UsartId::Usart2 => ClockGate::Apb1(17),
            UsartId::Usart6 => ClockGate::Apb2(5),
        }
    }

    const fn name(self) -> &'static str {
        match self {
            UsartId::Usart1 => "USART1",
            UsartId::Usart2 => "USART2",
            UsartId::Usart6 => "USART6",
        }
    }
}

/// Register offsets (RM0090 §30.6.8 "USART register map").
mod reg {
    pub const SR: u32 = 0x00;
    pub const DR: u32 = 0x04;
    pub const BRR: u32 = 0x08;
    pub const CR1: u32 = 0x0C;
    pub const CR2: u32 = 0x10;
    pub const CR3: u32 = 0x14;
    pub const GTPR: u32 = 0x18;
}

/// USART_SR bits (RM0090 §30.6.1).
pub mod sr {
    /// Parity error.
    pub const PE: u32 = 1 << 0;
    /// Framing error.
    pub const FE: u32 = 1 << 1;
    /// Noise detected.
    pub const NF: u32 = 1 << 2;
    /// Overrun.
    pub const ORE: u32 = 1 << 3;
    /// Idle line detected.
    pub const IDLE: u32 = 1 << 4;
    /// Read data register not empty.
    pub const RXNE: u32 = 1 << 5;
    /// Transmission complete.
    pub const TC: u32 = 1 << 6;
    /// Transmit data register empty.
    pub const TXE: u32 = 1 << 7;
    /// The flags the SR-then-DR-read sequence clears.
    pub const READ_CLEARED: u32 = PE | FE | NF | ORE | IDLE;
}

/// USART_CR1 bits (RM0090 §30.6.4).
pub mod cr1 {
    /// Receiver enable.
    pub const RE: u32 = 1 << 2;
    /// Transmitter enable.
    pub const TE: u32 = 1 << 3;
    /// IDLE interrupt enable.
    pub const IDLEIE: u32 = 1 << 4;
    /// RXNE (and ORE) interrupt enable.
    pub const RXNEIE: u32 = 1 << 5;
    /// TC interrupt enable.
    pub const TCIE: u32 = 1 << 6;
    /// TXE interrupt enable.
    pub const TXEIE: u32 = 1 << 7;
    /// PE interrupt enable.
    pub const PEIE: u32 = 1 << 8;
    /// Odd parity.
    pub const PS: u32 = 1 << 9;
    /// Parity control enable.
    pub const PCE: u32 = 1 << 10;
    /// 9-bit words.
    pub const M: u32 = 1 << 12;
    /// USART enable.
    pub const UE: u32 = 1 << 13;
    /// Oversampling by 8.
    pub const OVER8: u32 = 1 << 15;
}

/// CR3.ONEBIT (RM0090 §30.6.6).
const CR3_ONEBIT: u32 = 1 << 11;

/// A character that left the transmitter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transmitted {
    /// When its last stop bit ended.
    pub end: Nanos,
    /// The character.
    pub character: Character,
}

/// A character under way in the transmit shift register.
#[derive(Clone, Copy, Debug)]
struct Shifting {
    end: Nanos,
    character: Character,
}

/// One USART.
#[derive(Clone, Debug)]
pub struct Usart {
    id: UsartId,
    now: Nanos,
    /// The clock the USART runs from (PCLK1 or PCLK2), as last seen.
    fck: u32,
    sr: u32,
    tdr: Option<u16>,
    /// When TDR was written.
    tdr_at: Nanos,
    rdr: u16,
    brr: u32,
    cr1: u32,
    cr2: u32,
    cr3: u32,
    gtpr: u32,
    /// The SR flags seen by the last SR read, for the clear sequences.
    sr_seen: u32,
    /// The transmitter's line is busy until then (the idle frame after TE, a character).
    tx_free_at: Nanos,
    shifting: Option<Shifting>,
    transmitted: VecDeque<Transmitted>,
    /// Characters arriving: when each ends on the line.
    arriving: VecDeque<(Nanos, Character)>,
    rx_free_at: Nanos,
    idle_at: Option<Nanos>,
}

impl Usart {
    /// The USART at its reset values (SR 0x0000_00C0: TXE and TC set, RM0090 §30.6.1).
    pub fn new(id: UsartId) -> Usart {
        Usart {
            id,
            now: 0,
            fck: 16_000_000,
            sr: sr::TXE | sr::TC,
            tdr: None,
            tdr_at: 0,
            rdr: 0,
            brr: 0,
            cr1: 0,
            cr2: 0,
            cr3: 0,
            gtpr: 0,
            sr_seen: 0,
            tx_free_at: 0,
            shifting: None,
            transmitted: VecDeque::new(),
            arriving: VecDeque::new(),
            rx_free_at: 0,
            idle_at: None,
        }
    }

    /// Which USART this is.
    pub fn id(&self) -> UsartId {
        self.id
    }

    /// The rate BRR gives from the USART's clock (RM0090 §30.3.4): baud = f(CK) / (8 × (2 −
    /// OVER8) × USARTDIV), USARTDIV = mantissa + fraction / 16, or with OVER8 the fraction's
    /// three low bits / 8 (`DIV_Fraction[3]` is not considered). 0 when BRR is 0.
    pub fn baud(&self) -> f64 {
        let mantissa = f64::from(self.brr >> 4 & 0xFFF);
        let (per_bit, fraction) = if self.cr1 & cr1::OVER8 != 0 {
            (8.0, f64::from(self.brr & 7) / 8.0)
        } else {
            (16.0, f64::from(self.brr & 0xF) / 16.0)
        };
        let div = mantissa + fraction;
        if div == 0.0 {
            0.0
        } else {
            f64::from(self.fck) / (per_bit * div)
        }
    }

    /// The line settings the registers select: CR1.M (the word, parity included, §30.6.4),
    /// PCE/PS, CR2.STOP (§30.6.5), and the rate of [`Usart::baud`].
    pub fn settings(&self) -> LineSettings {
        let parity = match (self.cr1 & cr1::PCE != 0, self.cr1 & cr1::PS != 0) {
            (false, _) => Parity::None,
            (true, false) => Parity::Even,
            (true, true) => Parity::Odd,
        };
        let stop_bits = match self.cr2 >> 12 & 3 {
            0 => StopBits::One,
            1 => StopBits::Half,
            2 => StopBits::Two,
            _ => StopBits::OneAndHalf,
        };
        let word_bits = if self.cr1 & cr1::M != 0 { 9 } else { 8 };
        LineSettings { baud: self.baud(), word_bits, parity, stop_bits }
    }

    fn receiver(&self) -> Receiver {
        Receiver {
            settings: self.settings(),
            over8: self.cr1 & cr1::OVER8 != 0,
            one_bit: self.cr3 & CR3_ONEBIT != 0,
        }
    }

    /// The next character that left the transmitter, oldest first.
    pub fn pop_transmitted(&mut self) -> Option<Transmitted> {
        self.transmitted.pop_front()
    }

    /// A character arrives on RX, its start bit now (or when the previous one has ended): it
    /// completes after its sender's frame time and is sampled then.
    pub fn receive(&mut self, character: Character, now: Nanos) {
        let start = now.max(self.rx_free_at);
        let end = start.saturating_add(character.settings.frame_ns());
        self.rx_free_at = end;
        self.arriving.push_back((end, character));
    }

    fn enabled(&self, bit: u32) -> bool {
        self.cr1 & cr1::UE != 0 && self.cr1 & bit != 0
    }

    /// Brings the model to `now`: characters shift out and in, IDLE rises.
    fn update(&mut self, now: Nanos) {
        self.now = self.now.max(now);
        self.update_transmitter();
        while let Some(&(end, character)) = self.arriving.front() {
            if end > self.now {
                break;
            }
            self.arriving.pop_front();
            self.idle_reached(end.saturating_sub(character.settings.frame_ns()));
            self.complete_reception(end, &character);
        }
        let next_start = self.arriving.front().map(|&(end, c)| end.saturating_sub(c.settings.frame_ns()));
        self.idle_reached(next_start.unwrap_or(self.now).min(self.now));
    }

    /// IDLE (RM0090 §30.6.1): the line stayed idle for a frame after a reception, up to `until`.
    /// It rises once per burst: the next reception re-arms it.
    fn idle_reached(&mut self, until: Nanos) {
        if self.idle_at.is_some_and(|at| at <= until) {
            self.sr |= sr::IDLE;
            self.idle_at = None;
        }
    }

    /// The transmitter (RM0090 §30.3.2): TDR moves to the shift register when it is free,
    /// setting TXE; TC rises when the last frame ended with TDR empty.
    fn update_transmitter(&mut self) {
        loop {
            if let Some(s) = self.shifting {
                if s.end > self.now {
                    return;
                }
                self.transmitted.push_back(Transmitted { end: s.end, character: s.character });
                self.shifting = None;
                if self.tdr.is_none() {
                    self.sr |= sr::TC;
                }
            }
            if !self.enabled(cr1::TE) || self.tx_free_at > self.now {
                return;
            }
            let Some(word) = self.tdr.take() else { return };
            let settings = self.settings();
            let start = self.tx_free_at.max(self.tdr_at);
            let frame = settings.frame_ns();
            // A rate of 0 (BRR = 0 or no clock) never finishes a frame.
            let end = start.saturating_add(frame);
            self.tx_free_at = end;
            self.shifting = Some(Shifting { end, character: self.frame(word, settings) });
            self.sr |= sr::TXE;
        }
    }

    /// The character for a written word: with parity on, the word's most significant bit is
    /// replaced by the parity bit (RM0090 §30.3.2, "Parity control").
    fn frame(&self, word: u16, settings: LineSettings) -> Character {
        let bits = settings.word_bits;
        let word = word & ((1 << bits) - 1);
        let word = match settings.parity {
            Parity::None => word,
            parity => with_parity(word, bits - 1, parity),
        };
        Character { word, settings }
    }

    /// A character completed at `end`: into RDR with its errors, or lost to an overrun
    /// (RM0090 §30.6.1: ORE, "the RDR content is not lost, the shift register is overwritten").
    fn complete_reception(&mut self, end: Nanos, character: &Character) {
        if !self.enabled(cr1::RE) {
            return;
        }
        let receiver = self.receiver();
        self.idle_at = Some(end.saturating_add(receiver.settings.frame_ns()));
        if self.sr & sr::RXNE != 0 {
            self.sr |= sr::ORE;
            return;
        }
        let got = receiver.sample(character);
        self.rdr = got.word;
        // The error flags stay until their clear sequence (RM0090 §30.6.1), whatever follows.
        self.sr |= sr::RXNE;
        if got.framing_error {
            self.sr |= sr::FE;
        }
        if got.parity_error && self.cr1 & cr1::PCE != 0 {
            self.sr |= sr::PE;
        }
    }

    /// USART_DR read: RDR; clears RXNE, and after an SR read the error flags and IDLE that read
    /// saw (RM0090 §30.6.1).
    fn read_dr(&mut self) -> u32 {
        self.sr &= !(sr::RXNE | (self.sr_seen & sr::READ_CLEARED));
        self.sr_seen = 0;
        let mask = if self.cr1 & cr1::M != 0 { 0x1FF } else { 0xFF };
        u32::from(self.rdr) & mask
    }

    /// USART_DR write: into TDR (TXE clears); after an SR read, clears TC and PE (§30.6.1).
    fn write_dr(&mut self, value: u32) {
        self.sr &= !(self.sr_seen & (sr::TC | sr::PE));
        self.sr_seen = 0;
        self.tdr = Some(value as u16 & 0x1FF);
        self.tdr_at = self.now;
        self.sr &= !sr::TXE;
        self.update_transmitter();
    }

    /// USART_CR1: TE rising sends an idle frame first (RM0090 §30.3.2).
    fn write_cr1(&mut self, value: u32) {
        let rising = value & !self.cr1;
        self.cr1 = value & 0xBFFF;
        if rising & (cr1::TE | cr1::UE) != 0 && self.enabled(cr1::TE) {
            let idle = self.settings().frame_ns();
            self.tx_free_at = self.now.max(self.tx_free_at).saturating_add(idle);
        }
        self.update_transmitter();
    }

    fn irq_level(&self) -> bool {
        let on = |enable: u32, flags: u32| self.cr1 & enable != 0 && self.sr & flags != 0;
        on(cr1::TXEIE, sr::TXE)
            || on(cr1::TCIE, sr::TC)
            || on(cr1::RXNEIE, sr::RXNE | sr::ORE)
            || on(cr1::IDLEIE, sr::IDLE)
            || on(cr1::PEIE, sr::PE)
    }

    fn read_register(&mut self, offset: u32) -> u32 {
        match offset {
            reg::SR => {
                self.sr_seen = self.sr;
                self.sr
            }
            reg::DR => self.read_dr(),
            reg::BRR => self.brr,
            reg::CR1 => self.cr1,
            reg::CR2 => self.cr2,
            reg::CR3 => self.cr3,
            reg::GTPR => self.gtpr,
            _ => 0,
        }
    }

    fn write_register(&mut self, offset: u32, mask: u32, value: u32) {
        let merge = |old: u32| old & !mask | value & mask;
        match offset {
            // RXNE and TC clear by writing 0 (rc_w0); the other flags ignore writes (§30.6.1).
            reg::SR => self.sr &= !(sr::RXNE | sr::TC) | (value | !mask),
            reg::DR => self.write_dr(value),
            reg::BRR => self.brr = merge(self.brr) & 0xFFFF,
            reg::CR1 => self.write_cr1(merge(self.cr1)),
            reg::CR2 => self.cr2 = merge(self.cr2) & 0x7F6F,
            // CR3 bits 31:12 are reserved on the STM32F4 (no DEM, §30.6.6).
            reg::CR3 => self.cr3 = merge(self.cr3) & 0x0FFF,
            reg::GTPR => self.gtpr = merge(self.gtpr) & 0xFFFF,
            _ => {}
        }
    }

    fn bus_clock(&self, machine: &dyn Machine) -> u32 {
        let clocks = machine.clocks();
        match self.id {
            UsartId::Usart2 => clocks.pclk1,
            UsartId::Usart1 | UsartId::Usart6 => clocks.pclk2,
        }
    }
}

impl Peripheral for Usart {
    fn name(&self) -> &'static str {
        self.id.name()
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        if !machine.clock_enabled(self.id.clock_gate()) {
            machine.unclocked_access(self.id.clock_gate());
            return 0;
        }
        self.fck = self.bus_clock(machine);
        self.update(machine.now());
        let value = read_lanes(self.read_register(offset & !3), offset, width);
        machine.set_irq(self.id.irq(), self.irq_level());
        value
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        if !machine.clock_enabled(self.id.clock_gate()) {
            machine.unclocked_access(self.id.clock_gate());
            return;
        }
        self.fck = self.bus_clock(machine);
        self.update(machine.now());
        let (offset, mask, value) = lanes(offset, width, value);
        self.write_register(offset, mask, value);
        machine.set_irq(self.id.irq(), self.irq_level());
    }

    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.fck = self.bus_clock(machine);
        self.update(now);
        machine.set_irq(self.id.irq(), self.irq_level());
    }

    fn reset(&mut self, kind: ResetKind) {
        let _ = kind;
        let (now, transmitted) = (self.now, std::mem::take(&mut self.transmitted));
        *self = Usart::new(self.id);
        self.now = now;
        self.transmitted = transmitted;
    }

    fn next_event(&self) -> Option<Nanos> {
        [
            self.shifting.map(|s| s.end),
            (self.tdr.is_some() && self.tx_free_at > self.now).then_some(self.tx_free_at),
            self.arriving.front().map(|&(end, _)| end),
            self.idle_at,
        ]
        .into_iter()
        .flatten()
        .filter(|&at| at > self.now && at != Nanos::MAX)
        .min()
    }
}

#[cfg(test)]
mod tests;
