//! The general-purpose I/O ports GPIOA–GPIOI (RM0090 §8 "General-purpose I/Os").
//!
//! One [`Gpio`] models one port: the configuration registers (MODER, OTYPER, OSPEEDR, PUPDR,
//! AFRL/AFRH, RM0090 §8.4.1–§8.4.4, §8.4.9–§8.4.10), the data registers (IDR, ODR, BSRR,
//! §8.4.5–§8.4.7) and the lock (LCKR, §8.4.8). The outside world reaches the pins through
//! [`Gpio::drive_pin`] (switches, buttons, a transceiver's receive line), reads them through
//! [`Gpio::pin_level`] and [`Gpio::output_level`] (LEDs, the RS-485 driver enable), and the
//! peripheral models ask [`Gpio::pin_mode`] whether a pin is in its alternate function.
//!
//! A port whose clock gate (RCC_AHB1ENR bit n, RM0090 §7.3.10) is closed reads 0 and ignores
//! writes. RM0090 does not state what an access to an unclocked peripheral does; reads of 0 and
//! ignored writes are what the parts are commonly observed to do (no source confirms it).

use crate::periph::{ClockGate, Machine, Peripheral, ResetKind, Width};

/// A GPIO port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Port {
    /// GPIOA.
    A,
    /// GPIOB.
    B,
    /// GPIOC.
    C,
    /// GPIOD.
    D,
    /// GPIOE.
    E,
    /// GPIOF.
    F,
    /// GPIOG.
    G,
    /// GPIOH.
    H,
    /// GPIOI.
    I,
}

impl Port {
    /// Every port, GPIOA first.
    pub const ALL: [Port; 9] =
        [Port::A, Port::B, Port::C, Port::D, Port::E, Port::F, Port::G, Port::H, Port::I];

    /// The port's index: 0 for GPIOA. It is also its RCC_AHB1ENR bit (RM0090 §7.3.10).
    pub const fn index(self) -> u8 {
        self as u8
    }

    /// The base address of the port's register block: GPIOA at 0x4002_0000, the others 0x400
    /// apart (RM0090 §2.3 table 1).
    pub const fn base(self) -> u32 {
        0x4002_0000 + 0x400 * self as u32
    }

    /// The port's clock gate, RCC_AHB1ENR bit n (RM0090 §7.3.10).
    pub const fn clock_gate(self) -> ClockGate {
        ClockGate::Ahb1(self as u8)
    }
}

/// The alternate function numbers of the peripherals the firmware uses (STM32F405 datasheet
/// DS8626, table "Alternate function mapping"; RM0090 §8.3, figure "Selecting an alternate
/// function").
pub mod af {
    /// USART1, USART2 and USART3 (PA9/PA10, PA2/PA3): AF7.
    pub const USART1_2_3: u8 = 7;
    /// UART4, UART5 and USART6: AF8.
    pub const UART4_5_USART6: u8 = 8;
    /// CAN1 and CAN2 (PB8 RX / PB9 TX): AF9.
    pub const CAN1_2: u8 = 9;
}

/// The mode of one pin (MODER, RM0090 §8.4.1), with its alternate function number (AFRL/AFRH,
/// RM0090 §8.4.9, §8.4.10) in alternate function mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PinMode {
    /// `00`: input.
    Input,
    /// `01`: general-purpose output.
    Output,
    /// `10`: alternate function AFn (0–15).
    Alternate(u8),
    /// `11`: analog.
    Analog,
}

/// Register offsets (RM0090 §8.4.11 "GPIO register map").
mod reg {
    pub const MODER: u32 = 0x00;
    pub const OTYPER: u32 = 0x04;
    pub const OSPEEDR: u32 = 0x08;
    pub const PUPDR: u32 = 0x0C;
    pub const IDR: u32 = 0x10;
    pub const ODR: u32 = 0x14;
    pub const BSRR: u32 = 0x18;
    pub const LCKR: u32 = 0x1C;
    pub const AFRL: u32 = 0x20;
    pub const AFRH: u32 = 0x24;
}

/// LCKR.LCKK, the lock key (RM0090 §8.4.8).
const LCKK: u32 = 1 << 16;

/// The byte lanes an access of `width` at `offset` touches within its 32-bit register: the
/// register's offset, the mask of the lanes, and `value` moved into them. RM0090 §8.4 allows
/// byte, half-word and word accesses to the GPIO registers; the other models use the same rule.
pub(crate) fn lanes(offset: u32, width: Width, value: u32) -> (u32, u32, u32) {
    let shift = (offset & 3) * 8;
    let mask = match width {
        Width::Byte => 0xFF,
        Width::Half => 0xFFFF,
        Width::Word => 0xFFFF_FFFF,
    } << shift;
    (offset & !3, mask, (value << shift) & mask)
}

/// The bytes of a register value an access of `width` at `offset` reads.
pub(crate) fn read_lanes(word: u32, offset: u32, width: Width) -> u32 {
    let (_, mask, _) = lanes(offset, width, 0);
    (word & mask) >> ((offset & 3) * 8)
}

/// One GPIO port.
#[derive(Clone, Debug)]
pub struct Gpio {
    port: Port,
    moder: u32,
    otyper: u32,
    ospeedr: u32,
    pupdr: u32,
    odr: u32,
    afr: [u32; 2],
    /// LCKR.LCK[15:0] as last written, and whether the lock is active (LCKK reads 1).
    lck: u32,
    locked: bool,
    /// Steps of the lock key sequence done so far (RM0090 §8.4.8): 0 none, 1–3 writes done.
    lock_step: u8,
    /// Pins driven from outside, and their levels.
    driven: u16,
    external: u16,
    /// Pins driven by a peripheral in alternate function mode, and their levels.
    af_driven: u16,
    af_level: u16,
    /// The level a floating input reads.
    floating: u16,
}

impl Gpio {
    /// A port at its reset values.
    pub fn new(port: Port) -> Gpio {
        let mut gpio = Gpio {
            port,
            moder: 0,
            otyper: 0,
            ospeedr: 0,
            pupdr: 0,
            odr: 0,
            afr: [0; 2],
            lck: 0,
            locked: false,
            lock_step: 0,
            driven: 0,
            external: 0,
            af_driven: 0,
            af_level: 0,
            floating: 0,
        };
        gpio.reset_registers();
        gpio
    }

    /// The registers to their reset values; the outside world's drive stays.
    fn reset_registers(&mut self) {
        // Reset values with the debug pins PA13/PA14/PA15 and PB3/PB4 in their alternate
        // function (RM0090 §8.4.1 MODER, §8.4.3 OSPEEDR, §8.4.4 PUPDR). OSPEEDR of port A is
        // 0x0C00_0000 in RM0090; ST's SVD file (the `stm32f4` crate) gives 0: the manual is
        // followed.
        let (moder, ospeedr, pupdr) = match self.port {
            Port::A => (0xA800_0000, 0x0C00_0000, 0x6400_0000),
            Port::B => (0x0000_0280, 0x0000_00C0, 0x0000_0100),
            _ => (0, 0, 0),
        };
        self.moder = moder;
        self.ospeedr = ospeedr;
        self.pupdr = pupdr;
        self.otyper = 0;
        self.odr = 0;
        self.afr = [0; 2];
        self.lck = 0;
        self.locked = false;
        self.lock_step = 0;
        self.af_driven = 0;
    }

    /// The port.
    pub fn port(&self) -> Port {
        self.port
    }

    /// The mode of pin `n` (0–15).
    pub fn pin_mode(&self, n: u8) -> PinMode {
        let n = u32::from(n & 15);
        match (self.moder >> (2 * n)) & 3 {
            0 => PinMode::Input,
            1 => PinMode::Output,
            2 => PinMode::Alternate(((self.afr[(n / 8) as usize] >> (4 * (n % 8))) & 0xF) as u8),
            _ => PinMode::Analog,
        }
    }

    /// The alternate function of pin `n` when it is in alternate function mode.
    pub fn alternate_function(&self, n: u8) -> Option<u8> {
        match self.pin_mode(n) {
            PinMode::Alternate(af) => Some(af),
            _ => None,
        }
    }

    /// Whether pin `n` is in alternate function mode with function `af` (CAN1 on PB8/PB9 is AF9,
    /// USART1/2 on PA9/PA10 and PA2/PA3 AF7: STM32F405 datasheet DS8626 table 9).
    pub fn has_alternate(&self, n: u8, af: u8) -> bool {
        self.alternate_function(n) == Some(af)
    }

    /// Drives pin `n` from outside (`Some(level)`: a switch, a button, another chip's output) or
    /// releases it (`None`: the pin floats, or its pull resistor sets it).
    pub fn drive_pin(&mut self, n: u8, level: Option<bool>) {
        let bit = 1u16 << (n & 15);
        match level {
            Some(level) => {
                self.driven |= bit;
                self.set_bit_u16(Which::External, bit, level);
            }
            None => self.driven &= !bit,
        }
    }

    /// Drives pin `n` from the peripheral that owns it in alternate function mode (a USART's TX
    /// idles high), or releases it. Only seen on the pin while the pin is in alternate mode.
    pub fn drive_alternate(&mut self, n: u8, level: Option<bool>) {
        let bit = 1u16 << (n & 15);
        match level {
            Some(level) => {
                self.af_driven |= bit;
                self.set_bit_u16(Which::Alternate, bit, level);
            }
            None => self.af_driven &= !bit,
        }
    }

    /// The level a floating input without pull resistor reads (RM0090 §8.3 leaves it
    /// undefined; the model reads `false` unless told otherwise).
    pub fn set_floating_level(&mut self, n: u8, level: bool) {
        self.set_bit_u16(Which::Floating, 1 << (n & 15), level);
    }

    fn set_bit_u16(&mut self, which: Which, bit: u16, level: bool) {
        let field = match which {
            Which::External => &mut self.external,
            Which::Alternate => &mut self.af_level,
            Which::Floating => &mut self.floating,
        };
        if level {
            *field |= bit;
        } else {
            *field &= !bit;
        }
    }

    /// The level the port itself drives on pin `n`, if it drives one: an output in push-pull
    /// drives ODR; in open-drain it drives low for ODR = 0 and lets go for 1 (RM0090 §8.3, "Output configuration");
    /// an alternate-function pin drives what its peripheral drives ([`Gpio::drive_alternate`]),
    /// open-drain letting go of the high level. LEDs and the RS-485 driver enable read this.
    pub fn output_level(&self, n: u8) -> Option<bool> {
        let n = n & 15;
        let open_drain = self.otyper >> n & 1 != 0;
        let level = match self.pin_mode(n) {
            PinMode::Output => self.odr >> n & 1 != 0,
            PinMode::Alternate(_) if self.af_driven >> n & 1 != 0 => self.af_level >> n & 1 != 0,
            _ => return None,
        };
        if open_drain && level {
            None
        } else {
            Some(level)
        }
    }

    /// The level on pin `n`: what the port drives, else what the outside drives, else the pull
    /// resistor (PUPDR `01` up, `10` down, RM0090 §8.4.4; `11` is reserved and taken as none),
    /// else the floating level.
    pub fn pin_level(&self, n: u8) -> bool {
        let n = n & 15;
        if let Some(level) = self.output_level(n) {
            return level;
        }
        if self.driven >> n & 1 != 0 {
            return self.external >> n & 1 != 0;
        }
        match (self.pupdr >> (2 * u32::from(n))) & 3 {
            1 => true,
            2 => false,
            _ => self.floating >> n & 1 != 0,
        }
    }

    /// IDR: the pins' levels, sampled every AHB1 clock (RM0090 §8.3, "Input configuration" and
    /// "Output configuration": the input buffer stays on); an analog pin reads 0
    /// (RM0090 §8.3, "Analog configuration": its Schmitt trigger is off).
    pub fn idr(&self) -> u16 {
        (0..16u8)
            .filter(|&n| self.pin_mode(n) != PinMode::Analog && self.pin_level(n))
            .fold(0, |idr, n| idr | 1 << n)
    }

    /// ODR.
    pub fn odr(&self) -> u16 {
        self.odr as u16
    }

    /// Whether the configuration lock is active (LCKR.LCKK, RM0090 §8.4.8).
    pub fn is_locked(&self) -> bool {
        self.locked
    }

    /// The mask of the configuration bits of the locked pins in a register of `bits_per_pin`
    /// bits per pin (RM0090 §8.4.8: MODER, OTYPER, OSPEEDR, PUPDR, AFRL and AFRH freeze).
    fn locked_mask(&self, bits_per_pin: u32, first_pin: u32) -> u32 {
        if !self.locked {
            return 0;
        }
        let pins = 32 / bits_per_pin;
        (0..pins)
            .filter(|p| self.lck >> (first_pin + p) & 1 != 0)
            .fold(0, |m, p| m | ((1u32 << bits_per_pin) - 1) << (p * bits_per_pin))
    }

    /// The LCKR key sequence (RM0090 §8.4.8): write LCKK = 1 with LCK, LCKK = 0 with the same
    /// LCK, LCKK = 1 with the same LCK, then read LCKR. Any other write aborts the sequence.
    /// The manual asks for word accesses; a narrower write aborts it too (no source says what a
    /// half-word write does; the model's choice).
    fn write_lckr(&mut self, width: Width, value: u32) {
        if self.locked {
            return; // Frozen until the next reset (RM0090 §8.4.8).
        }
        let lck = value & 0xFFFF;
        let key = value & LCKK != 0;
        let same = lck == self.lck;
        self.lock_step = match (self.lock_step, key, width) {
            (_, _, Width::Byte | Width::Half) => 0,
            (0, true, _) => 1,
            (1, false, _) if same => 2,
            (2, true, _) if same => 3,
            _ => 0,
        };
        self.lck = lck;
    }

    fn read_register(&mut self, offset: u32) -> u32 {
        match offset {
            reg::MODER => self.moder,
            reg::OTYPER => self.otyper,
            reg::OSPEEDR => self.ospeedr,
            reg::PUPDR => self.pupdr,
            reg::IDR => u32::from(self.idr()),
            reg::ODR => self.odr,
            reg::LCKR => {
                // The read that ends the key sequence activates the lock.
                if self.lock_step == 3 {
                    self.locked = true;
                    self.lock_step = 0;
                }
                self.lck | if self.locked { LCKK } else { 0 }
            }
            reg::AFRL => self.afr[0],
            reg::AFRH => self.afr[1],
            // BSRR reads 0 (RM0090 §8.4.7); reserved addresses read 0.
            _ => 0,
        }
    }

    fn write_register(&mut self, offset: u32, mask: u32, value: u32) {
        let merge = |old: u32, frozen: u32| {
            let writable = mask & !frozen;
            old & !writable | value & writable
        };
        match offset {
            reg::MODER => self.moder = merge(self.moder, self.locked_mask(2, 0)),
            // OTYPER and ODR: bits 31:16 reserved, kept at 0 (RM0090 §8.4.2, §8.4.6).
            reg::OTYPER => self.otyper = merge(self.otyper, self.locked_mask(1, 0)) & 0xFFFF,
            reg::OSPEEDR => self.ospeedr = merge(self.ospeedr, self.locked_mask(2, 0)),
            reg::PUPDR => self.pupdr = merge(self.pupdr, self.locked_mask(2, 0)),
            reg::ODR => self.odr = merge(self.odr, 0) & 0xFFFF,
            reg::BSRR => {
                // BRy resets, BSy sets; with both set, BSy has priority (RM0090 §8.4.7).
                let bsrr = value & mask;
                self.odr = (self.odr & !(bsrr >> 16) | bsrr) & 0xFFFF;
            }
            reg::AFRL => self.afr[0] = merge(self.afr[0], self.locked_mask(4, 0)),
            reg::AFRH => self.afr[1] = merge(self.afr[1], self.locked_mask(4, 8)),
            _ => {}
        }
    }
}

#[derive(Clone, Copy)]
enum Which {
    External,
    Alternate,
    Floating,
}

impl Peripheral for Gpio {
    fn name(&self) -> &'static str {
        ["GPIOA", "GPIOB", "GPIOC", "GPIOD", "GPIOE", "GPIOF", "GPIOG", "GPIOH", "GPIOI"][self.port as usize]
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        if !machine.clock_enabled(self.port.clock_gate()) {
            machine.unclocked_access(self.port.clock_gate());
            return 0;
        }
        let word = self.read_register(offset & !3);
        read_lanes(word, offset, width)
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        if !machine.clock_enabled(self.port.clock_gate()) {
            machine.unclocked_access(self.port.clock_gate());
            return;
        }
        let (offset, mask, value) = lanes(offset, width, value);
        if offset == reg::LCKR {
            self.write_lckr(width, value);
        } else {
            self.write_register(offset, mask, value);
        }
    }

    fn reset(&mut self, kind: ResetKind) {
        let _ = kind;
        self.reset_registers();
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::periph::{Clocks, Nanos};
    use rstest::rstest;

    /// A machine with every clock gate open, no interrupt wired, and a settable time.
    #[derive(Default)]
    pub(crate) struct TestMachine {
        pub now: Nanos,
        pub closed: Vec<ClockGate>,
        pub clocks: Option<Clocks>,
        pub irqs: std::collections::BTreeMap<u16, bool>,
    }

    impl Machine for TestMachine {
        fn clocks(&self) -> Clocks {
            self.clocks.unwrap_or(Clocks::RESET)
        }
        fn clock_enabled(&self, gate: ClockGate) -> bool {
            !self.closed.contains(&gate)
        }
        fn set_irq(&mut self, irq: u16, level: bool) {
            self.irqs.insert(irq, level);
        }
        fn now(&self) -> Nanos {
            self.now
        }
    }

    fn rmw(gpio: &mut Gpio, m: &mut TestMachine, offset: u32, clear: u32, set: u32) {
        let v = gpio.read(offset, Width::Word, m);
        gpio.write(offset, Width::Word, v & !clear | set, m);
    }

    #[rstest]
    #[case::port_a(Port::A, 0xA800_0000, 0x0C00_0000, 0x6400_0000)]
    #[case::port_b(Port::B, 0x0000_0280, 0x0000_00C0, 0x0000_0100)]
    #[case::port_c(Port::C, 0, 0, 0)]
    fn reset_values(#[case] port: Port, #[case] moder: u32, #[case] ospeedr: u32, #[case] pupdr: u32) {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(port);
        assert_eq!(g.read(reg::MODER, Width::Word, &mut m), moder);
        assert_eq!(g.read(reg::OSPEEDR, Width::Word, &mut m), ospeedr);
        assert_eq!(g.read(reg::PUPDR, Width::Word, &mut m), pupdr);
        assert_eq!(g.read(reg::ODR, Width::Word, &mut m), 0);
    }

    #[rstest]
    #[case::gpioa(Port::A, 0x4002_0000)]
    #[case::gpioc(Port::C, 0x4002_0800)]
    #[case::gpioi(Port::I, 0x4002_2000)]
    fn base_addresses(#[case] port: Port, #[case] base: u32) {
        assert_eq!(port.base(), base);
    }

    /// The HAL's `into_alternate::<7>()` on PA2/PA3 (stm32f4xx-hal 0.23 gpio/convert.rs:
    /// AFRL modify, then MODER modify) and `into_alternate::<9>()` on PB8/PB9 (AFRH).
    #[rstest]
    #[case::usart2_tx(Port::A, 2, 7)]
    #[case::usart2_rx(Port::A, 3, 7)]
    #[case::usart1_tx(Port::A, 9, 7)]
    #[case::usart1_rx(Port::A, 10, 7)]
    #[case::can1_rx(Port::B, 8, 9)]
    #[case::can1_tx(Port::B, 9, 9)]
    fn alternate_function_as_the_hal_sets_it(#[case] port: Port, #[case] n: u8, #[case] af: u8) {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(port);
        let (afr, shift) = if n < 8 { (reg::AFRL, 4 * n) } else { (reg::AFRH, 4 * (n - 8)) };
        assert_eq!(g.pin_mode(n), PinMode::Input);
        rmw(&mut g, &mut m, afr, 0xF << shift, u32::from(af) << shift);
        assert_eq!(g.pin_mode(n), PinMode::Input, "AFR alone does not switch the mode");
        rmw(&mut g, &mut m, reg::MODER, 3 << (2 * n), 2 << (2 * n));
        assert_eq!(g.pin_mode(n), PinMode::Alternate(af));
        assert!(g.has_alternate(n, af));
        assert!(!g.has_alternate(n, af + 1));
    }

    /// `board::hw::read_switches`: PB0–PB7 inputs with pull-ups; a closed switch pulls to ground.
    #[rstest]
    #[case::all_open(0x00, 0xFF)]
    #[case::switch_1_closed(0x01, 0xFE)]
    #[case::switches_2_and_8_closed(0x82, 0x7D)]
    fn switches_read_through_pull_ups(#[case] closed: u8, #[case] idr: u8) {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::B);
        for n in 0..8 {
            g.drive_pin(n, (closed >> n & 1 != 0).then_some(false));
        }
        rmw(&mut g, &mut m, reg::MODER, 0xFFFF, 0);
        rmw(&mut g, &mut m, reg::PUPDR, 0xFFFF, 0x5555);
        assert_eq!(g.read(reg::IDR, Width::Word, &mut m) as u8, idr);
    }

    #[rstest]
    #[case::pull_up(1, false, true)]
    #[case::pull_down(2, true, false)]
    #[case::floating_reads_its_level(0, true, true)]
    fn released_input_follows_its_pull(#[case] pupd: u32, #[case] floating: bool, #[case] level: bool) {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::C);
        g.set_floating_level(5, floating);
        rmw(&mut g, &mut m, reg::PUPDR, 3 << 10, pupd << 10);
        assert_eq!(g.pin_level(5), level);
        assert_eq!(g.read(reg::IDR, Width::Word, &mut m) >> 5 & 1 != 0, level);
    }

    /// LEDs on PC0–PC3 (`board::hw::LedPins`): MODER outputs, BSRR writes, levels seen outside.
    #[rstest]
    #[case::set_two(0x0000_0005, 0x5)]
    #[case::set_has_priority(0x0001_0001, 0x1)]
    #[case::reset_one(0x0001_0000, 0x0)]
    fn bsrr_sets_and_resets(#[case] bsrr: u32, #[case] odr: u32) {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::C);
        rmw(&mut g, &mut m, reg::MODER, 0xFF, 0x55);
        g.write(reg::ODR, Width::Word, 0x1, &mut m);
        g.write(reg::BSRR, Width::Word, bsrr, &mut m);
        assert_eq!(g.read(reg::ODR, Width::Word, &mut m), odr, "BSy has priority over BRy (§8.4.7)");
        for n in 0..4 {
            assert_eq!(g.output_level(n), Some(odr >> n & 1 != 0));
        }
        assert_eq!(g.read(reg::BSRR, Width::Word, &mut m), 0, "BSRR reads 0");
        assert_eq!(g.read(reg::IDR, Width::Word, &mut m) & 0xF, odr, "IDR follows the outputs");
    }

    #[test]
    fn bsrr_half_word_write_resets() {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::A);
        rmw(&mut g, &mut m, reg::MODER, 3 << 2, 1 << 2);
        g.write(reg::BSRR, Width::Half, 1 << 1, &mut m);
        assert_eq!(g.output_level(1), Some(true), "RS-485 DE high");
        g.write(reg::BSRR + 2, Width::Half, 1 << 1, &mut m);
        assert_eq!(g.output_level(1), Some(false), "RS-485 DE low");
    }

    #[test]
    fn open_drain_lets_go_of_high() {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::C);
        rmw(&mut g, &mut m, reg::MODER, 3, 1);
        rmw(&mut g, &mut m, reg::OTYPER, 0, 1);
        rmw(&mut g, &mut m, reg::PUPDR, 3, 1);
        g.write(reg::ODR, Width::Word, 1, &mut m);
        assert_eq!(g.output_level(0), None);
        assert!(g.pin_level(0), "pull-up");
        g.drive_pin(0, Some(false));
        assert!(!g.pin_level(0), "another driver pulls the line low");
        g.write(reg::ODR, Width::Word, 0, &mut m);
        assert_eq!(g.output_level(0), Some(false));
    }

    #[test]
    fn analog_pin_reads_zero() {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::C);
        g.drive_pin(4, Some(true));
        assert_eq!(g.read(reg::IDR, Width::Word, &mut m), 1 << 4);
        rmw(&mut g, &mut m, reg::MODER, 0, 3 << 8);
        assert_eq!(g.pin_mode(4), PinMode::Analog);
        assert_eq!(g.read(reg::IDR, Width::Word, &mut m), 0);
    }

    #[test]
    fn lock_sequence_freezes_the_configuration_of_locked_pins() {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::C);
        for value in [LCKK | 1, 1, LCKK | 1] {
            g.write(reg::LCKR, Width::Word, value, &mut m);
        }
        assert!(!g.is_locked(), "active only after the read");
        assert_eq!(g.read(reg::LCKR, Width::Word, &mut m), LCKK | 1);
        assert!(g.is_locked());
        g.write(reg::MODER, Width::Word, 0x5, &mut m);
        assert_eq!(g.read(reg::MODER, Width::Word, &mut m), 0x4, "PC0 frozen, PC1 free");
        g.write(reg::LCKR, Width::Word, 0, &mut m);
        assert_eq!(g.read(reg::LCKR, Width::Word, &mut m), LCKK | 1, "LCKR frozen");
        g.reset(ResetKind::System);
        assert!(!g.is_locked());
    }

    #[rstest]
    #[case::lck_changed(&[LCKK | 1, 3, LCKK | 3])]
    #[case::key_order_wrong(&[LCKK | 1, LCKK | 1, LCKK | 1])]
    #[case::no_first_write(&[1, LCKK | 1])]
    fn broken_lock_sequence_does_not_lock(#[case] writes: &[u32]) {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::C);
        for &value in writes {
            g.write(reg::LCKR, Width::Word, value, &mut m);
        }
        let _ = g.read(reg::LCKR, Width::Word, &mut m);
        assert!(!g.is_locked());
        assert_eq!(g.read(reg::LCKR, Width::Word, &mut m) & LCKK, 0);
    }

    #[test]
    fn unclocked_port_ignores_writes_and_reads_zero() {
        let mut m = TestMachine { closed: vec![ClockGate::Ahb1(2)], ..Default::default() };
        let mut g = Gpio::new(Port::C);
        g.write(reg::MODER, Width::Word, 0x55, &mut m);
        m.closed.clear();
        assert_eq!(g.read(reg::MODER, Width::Word, &mut m), 0);
        m.closed.push(ClockGate::Ahb1(2));
        assert_eq!(g.read(reg::MODER, Width::Word, &mut m), 0);
    }

    #[test]
    fn byte_access_reaches_its_lane() {
        let mut m = TestMachine::default();
        let mut g = Gpio::new(Port::C);
        g.write(reg::AFRH + 1, Width::Byte, 0x99, &mut m);
        assert_eq!(g.read(reg::AFRH, Width::Word, &mut m), 0x9900);
        assert_eq!(g.read(reg::AFRH + 1, Width::Byte, &mut m), 0x99);
    }
}
