//! The power controller's registers (PWR, 0x4000_7000 on APB1, clock gate RCC_APB1ENR bit 28):
//! PWR_CR and PWR_CSR as the firmware's clock set-up uses them, the regulator's voltage scale and,
//! on the STM32F446, the over-drive that 180 MHz needs (RM0390 §5.1.4 "Voltage regulator",
//! §5.4.1 `PWR_CR`, §5.4.2 `PWR_CSR`; RM0090 §5.4.1, §5.4.2 for the F405, which has no
//! over-drive).
//!
//! The regulator is always ready: VOSRDY reads 1, and ODRDY / ODSWRDY follow ODEN / ODSWEN at
//! once (on silicon they rise some microseconds later, RM0390 §5.1.4 "Entering Over-drive
//! mode"; the firmware waits for them, which takes no time here). What the other bits do (low-power
//! modes, the backup domain's write protection DBP, the voltage detector) is kept as written and
//! not acted on.

use crate::gpio::{lanes, read_lanes};
use crate::machine::Chip;
use crate::periph::{ClockGate, Machine, Peripheral, ResetKind, Width};

/// The register block's base address (RM0090 §2.3 table 1, RM0390 §2.2.2 table 1).
pub const BASE: u32 = 0x4000_7000;
/// The clock gate: RCC_APB1ENR bit 28, PWREN.
pub const CLOCK: ClockGate = ClockGate::Apb1(28);

/// PWR_CR bits.
pub mod cr {
    /// Over-drive enable (F446 only, RM0390 §5.4.1).
    pub const ODEN: u32 = 1 << 16;
    /// Over-drive switching enable (F446 only).
    pub const ODSWEN: u32 = 1 << 17;
}

/// PWR_CSR bits.
pub mod csr {
    /// Regulator voltage scaling output selection ready.
    pub const VOSRDY: u32 = 1 << 14;
    /// Over-drive ready (F446 only).
    pub const ODRDY: u32 = 1 << 16;
    /// Over-drive switching ready (F446 only).
    pub const ODSWRDY: u32 = 1 << 17;
}

/// The PWR registers of one chip.
#[derive(Clone, Debug)]
pub struct Pwr {
    chip: Chip,
    cr: u32,
    csr: u32,
}

impl Pwr {
    /// At the reset values of `chip`.
    pub fn new(chip: Chip) -> Pwr {
        let mut pwr = Pwr { chip, cr: 0, csr: 0 };
        pwr.reset(ResetKind::PowerOn);
        pwr
    }

    /// PWR_CR's reset value: VOS scale 1 (F405: bit 14 set, RM0090 §5.4.1; F446: VOS = 11,
    /// RM0390 §5.4.1).
    fn cr_reset(&self) -> u32 {
        match self.chip {
            Chip::Stm32F405 => 0x0000_4000,
            Chip::Stm32F446 => 0x0000_C000,
        }
    }

    /// The bits of PWR_CR the chip has (the over-drive bits on the F446 only).
    fn cr_writable(&self) -> u32 {
        match self.chip {
            Chip::Stm32F405 => 0x0000_43FF,
            Chip::Stm32F446 => 0x003F_EFFF,
        }
    }

    fn csr_value(&self) -> u32 {
        let mut v = self.csr | csr::VOSRDY;
        if self.chip == Chip::Stm32F446 {
            if self.cr & cr::ODEN != 0 {
                v |= csr::ODRDY;
            }
            if self.cr & cr::ODSWEN != 0 {
                v |= csr::ODSWRDY;
            }
        }
        v
    }
}

impl Peripheral for Pwr {
    fn name(&self) -> &'static str {
        "PWR"
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        if !machine.clock_enabled(CLOCK) {
            machine.unclocked_access(CLOCK);
            return 0;
        }
        let word = match offset & !3 {
            0x00 => self.cr,
            0x04 => self.csr_value(),
            _ => 0,
        };
        read_lanes(word, offset, width)
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        if !machine.clock_enabled(CLOCK) {
            machine.unclocked_access(CLOCK);
            return;
        }
        let (offset, mask, value) = lanes(offset, width, value);
        match offset {
            0x00 => {
                let writable = mask & self.cr_writable();
                self.cr = (self.cr & !writable) | (value & writable);
            }
            // EWUP (bit 8) and BRE (bit 9) are the CSR's read/write bits.
            0x04 => {
                let writable = mask & 0x0000_0300;
                self.csr = (self.csr & !writable) | (value & writable);
            }
            _ => {}
        }
    }

    fn reset(&mut self, kind: ResetKind) {
        let _ = kind;
        self.cr = self.cr_reset();
        self.csr = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::periph::{Clocks, Nanos};

    struct Bench;

    impl Machine for Bench {
        fn clocks(&self) -> Clocks {
            Clocks::RESET
        }
        fn clock_enabled(&self, _: ClockGate) -> bool {
            true
        }
        fn set_irq(&mut self, _: u16, _: bool) {}
        fn now(&self) -> Nanos {
            0
        }
    }

    #[test]
    fn the_f446_over_drive_is_ready_once_enabled() {
        let mut pwr = Pwr::new(Chip::Stm32F446);
        let m = &mut Bench;
        assert_eq!(pwr.read(0, Width::Word, m), 0x0000_C000);
        assert_eq!(pwr.read(4, Width::Word, m) & (csr::ODRDY | csr::ODSWRDY), 0);
        pwr.write(0, Width::Word, 0x0000_C000 | cr::ODEN, m);
        assert_eq!(pwr.read(4, Width::Word, m) & (csr::ODRDY | csr::ODSWRDY), csr::ODRDY);
        pwr.write(0, Width::Word, 0x0000_C000 | cr::ODEN | cr::ODSWEN, m);
        assert_eq!(pwr.read(4, Width::Word, m) & (csr::ODRDY | csr::ODSWRDY), csr::ODRDY | csr::ODSWRDY);
        pwr.reset(ResetKind::System);
        assert_eq!(pwr.read(0, Width::Word, m), 0x0000_C000);
    }

    #[test]
    fn the_f405_has_no_over_drive() {
        let mut pwr = Pwr::new(Chip::Stm32F405);
        let m = &mut Bench;
        assert_eq!(pwr.read(0, Width::Word, m), 0x0000_4000);
        pwr.write(0, Width::Word, cr::ODEN | cr::ODSWEN | 0x4000, m);
        assert_eq!(pwr.read(0, Width::Word, m), 0x0000_4000);
        assert_eq!(pwr.read(4, Width::Word, m), csr::VOSRDY);
    }
}
