//! The SysTick timer of the Cortex-M4 (PM0214 §4.5 "SysTick timer (STK)"): a 24-bit down
//! counter that reloads from RVR, sets COUNTFLAG and raises the SysTick exception when it
//! reaches 0.
//!
//! The counter runs on the processor clock (CLKSOURCE = 1) or on the external reference,
//! which the STM32F4's RCC makes HCLK/8 (RM0090 §7.2 "Clocks", figure 21: "to Cortex System
//! timer: HCLK/8"). The machine feeds the model processor clock cycles; the model keeps the
//! remainder of the division by 8.

/// Offsets of the SysTick registers within the System Control Space (0xE000_E000).
pub mod offset {
    /// SYST_CSR, control and status (PM0214 §4.5.1).
    pub const CSR: u32 = 0x010;
    /// SYST_RVR, reload value (PM0214 §4.5.2).
    pub const RVR: u32 = 0x014;
    /// SYST_CVR, current value (PM0214 §4.5.3).
    pub const CVR: u32 = 0x018;
    /// SYST_CALIB, calibration value (PM0214 §4.5.4).
    pub const CALIB: u32 = 0x01C;
}

const CSR_ENABLE: u32 = 1 << 0;
const CSR_TICKINT: u32 = 1 << 1;
const CSR_CLKSOURCE: u32 = 1 << 2;
const CSR_COUNTFLAG: u32 = 1 << 16;
const COUNTER_MASK: u32 = 0x00FF_FFFF;

/// SYST_CALIB of the STM32F4: TENMS = 21000, a 1 ms reference with the SysTick clock at
/// 21 MHz (HCLK/8 with HCLK at 168 MHz); NOREF and SKEW clear. RM0090 gives no register
/// description of its own for SysTick; this value is the one of PM0214 §4.5.4 for STM32F4
/// devices and could not be confirmed in a second source.
pub const CALIB: u32 = 21_000;

/// The SysTick timer.
#[derive(Clone, Debug, Default)]
pub struct SysTick {
    csr: u32,
    rvr: u32,
    cvr: u32,
    /// Processor cycles not yet counted at HCLK/8.
    prescaler_remainder: u64,
}

impl SysTick {
    /// The timer at reset: disabled, RVR and CVR unknown at reset (PM0214 table 52), modelled as 0.
    pub const fn new() -> SysTick {
        SysTick { csr: 0, rvr: 0, cvr: 0, prescaler_remainder: 0 }
    }

    /// Reads a SysTick register. Reading CSR clears COUNTFLAG (PM0214 §4.5.1).
    pub fn read(&mut self, offset: u32) -> u32 {
        match offset {
            offset::CSR => {
                let value = self.csr;
                self.csr &= !CSR_COUNTFLAG;
                value
            }
            offset::RVR => self.rvr,
            offset::CVR => self.cvr,
            offset::CALIB => CALIB,
            _ => 0,
        }
    }

    /// Writes a SysTick register. Any write to CVR clears it and COUNTFLAG (PM0214 §4.5.3).
    pub fn write(&mut self, offset: u32, value: u32) {
        match offset {
            offset::CSR => {
                let writable = CSR_ENABLE | CSR_TICKINT | CSR_CLKSOURCE;
                self.csr = (self.csr & CSR_COUNTFLAG) | (value & writable);
            }
            offset::RVR => self.rvr = value & COUNTER_MASK,
            offset::CVR => {
                self.cvr = 0;
                self.csr &= !CSR_COUNTFLAG;
            }
            _ => {}
        }
    }

    /// SYST_RVR, the reload value.
    pub const fn reload(&self) -> u32 {
        self.rvr
    }

    /// Whether the counter runs on the processor clock (CLKSOURCE = 1) rather than HCLK/8.
    pub const fn on_processor_clock(&self) -> bool {
        self.csr & CSR_CLKSOURCE != 0
    }

    /// Whether the counter runs.
    pub const fn enabled(&self) -> bool {
        self.csr & CSR_ENABLE != 0
    }

    /// Whether reaching 0 pends the SysTick exception (TICKINT).
    pub const fn interrupt_enabled(&self) -> bool {
        self.csr & CSR_TICKINT != 0
    }

    /// Processor cycles per counter tick: 1 (CLKSOURCE = processor clock) or 8 (HCLK/8).
    const fn divider(&self) -> u64 {
        if self.csr & CSR_CLKSOURCE != 0 {
            1
        } else {
            8
        }
    }

    /// Counts `cycles` processor cycles. Returns whether the counter reached 0 with TICKINT set
    /// (the SysTick exception is to be pended).
    pub fn advance(&mut self, cycles: u64) -> bool {
        if !self.enabled() {
            return false;
        }
        let total = self.prescaler_remainder + cycles;
        let divider = self.divider();
        self.prescaler_remainder = total % divider;
        let ticks = total / divider;
        self.count(ticks)
    }

    /// Counts `ticks` counter clocks: a tick at 0 reloads RVR, a tick from 1 reaches 0 and sets
    /// COUNTFLAG (PM0214 §4.5: "When the counter transitions to zero, the COUNTFLAG status bit
    /// is set to 1").
    fn count(&mut self, mut ticks: u64) -> bool {
        let mut reached_zero = false;
        while ticks > 0 {
            if self.cvr == 0 {
                if self.rvr == 0 {
                    // RVR = 0: the counter stays at 0 and never fires (PM0214 §4.5.2).
                    break;
                }
                self.cvr = self.rvr;
                ticks -= 1;
                // Whole periods left: skip them at once.
                let period = u64::from(self.rvr) + 1;
                if ticks >= period {
                    ticks %= period;
                    reached_zero = true;
                    self.csr |= CSR_COUNTFLAG;
                }
                continue;
            }
            if ticks >= u64::from(self.cvr) {
                ticks -= u64::from(self.cvr);
                self.cvr = 0;
                self.csr |= CSR_COUNTFLAG;
                reached_zero = true;
            } else {
                self.cvr -= ticks as u32;
                ticks = 0;
            }
        }
        reached_zero && self.interrupt_enabled()
    }

    /// Processor cycles until the counter next reaches 0 with TICKINT set, if it will.
    pub fn cycles_to_interrupt(&self) -> Option<u64> {
        if !self.enabled() || !self.interrupt_enabled() {
            return None;
        }
        let ticks = match self.cvr {
            0 if self.rvr == 0 => return None,
            0 => u64::from(self.rvr) + 1,
            cvr => u64::from(cvr),
        };
        Some((ticks * self.divider()).saturating_sub(self.prescaler_remainder).max(1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    /// The firmware's set-up (cortex-m 0.7 `SYST`): CLKSOURCE = core, RVR = hz/1000 - 1, CVR
    /// cleared, TICKINT, ENABLE.
    fn firmware_systick(reload: u32) -> SysTick {
        let mut syst = SysTick::new();
        syst.write(offset::CSR, CSR_CLKSOURCE);
        syst.write(offset::RVR, reload);
        syst.write(offset::CVR, 0);
        syst.write(offset::CSR, CSR_CLKSOURCE | CSR_TICKINT);
        syst.write(offset::CSR, CSR_CLKSOURCE | CSR_TICKINT | CSR_ENABLE);
        syst
    }

    #[rstest]
    #[case::first_tick_reloads(1, false, 999)]
    #[case::reaches_zero_after_reload_plus_period(1000, true, 0)]
    #[case::one_short(999, false, 1)]
    #[case::two_periods(2000, true, 0)]
    fn counts_core_cycles(#[case] cycles: u64, #[case] fired: bool, #[case] cvr: u32) {
        let mut syst = firmware_systick(999);
        assert_eq!(syst.advance(cycles), fired);
        assert_eq!(syst.read(offset::CVR), cvr);
    }

    #[test]
    fn countflag_set_at_zero_and_cleared_by_reading_csr() {
        let mut syst = firmware_systick(9);
        syst.advance(10);
        assert_ne!(syst.read(offset::CSR) & CSR_COUNTFLAG, 0);
        assert_eq!(syst.read(offset::CSR) & CSR_COUNTFLAG, 0);
    }

    #[test]
    fn writing_cvr_clears_countflag() {
        let mut syst = firmware_systick(9);
        syst.advance(10);
        syst.write(offset::CVR, 1234);
        assert_eq!(syst.read(offset::CVR), 0);
        assert_eq!(syst.read(offset::CSR) & CSR_COUNTFLAG, 0);
    }

    #[rstest]
    #[case::processor_clock(CSR_CLKSOURCE, 100)]
    #[case::hclk_over_8(0, 800)]
    fn clock_source(#[case] clksource: u32, #[case] cycles_per_period: u64) {
        let mut syst = SysTick::new();
        syst.write(offset::RVR, 99);
        syst.write(offset::CSR, clksource | CSR_TICKINT | CSR_ENABLE);
        // The first tick loads RVR: the first interrupt comes after RVR + 1 ticks.
        assert_eq!(syst.cycles_to_interrupt(), Some(cycles_per_period));
        assert!(!syst.advance(cycles_per_period / 100));
        assert_eq!(syst.cycles_to_interrupt(), Some(cycles_per_period - cycles_per_period / 100));
        assert!(syst.advance(cycles_per_period - cycles_per_period / 100));
        assert_eq!(syst.cycles_to_interrupt(), Some(cycles_per_period));
    }

    #[rstest]
    #[case::disabled(CSR_TICKINT)]
    #[case::no_tickint(CSR_ENABLE)]
    fn no_interrupt(#[case] csr: u32) {
        let mut syst = SysTick::new();
        syst.write(offset::RVR, 9);
        syst.write(offset::CSR, csr | CSR_CLKSOURCE);
        assert!(!syst.advance(100));
        assert_eq!(syst.cycles_to_interrupt(), None);
    }

    #[test]
    fn registers_are_24_bit_and_calib_is_the_stm32f4s() {
        let mut syst = SysTick::new();
        syst.write(offset::RVR, 0xFFFF_FFFF);
        assert_eq!(syst.read(offset::RVR), 0x00FF_FFFF);
        assert_eq!(syst.read(offset::CALIB), 21_000);
    }
}
