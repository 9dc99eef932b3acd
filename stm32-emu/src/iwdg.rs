//! The independent watchdog, IWDG (RM0090 rev 18 §21 "Independent watchdog", registers §21.4,
//! base 0x4000_3000).
//!
//! A 12-bit down-counter clocked by the LSI through a prescaler of 4 × 2^PR (PR 6 and 7: 256),
//! started by writing 0xCCCC to IWDG_KR and reloaded from IWDG_RLR by 0xAAAA (§21.3: "whenever"
//! it is written; started without a reload, it counts from its reset value 0xFFF). The model
//! reloads the counter on 0xAAAA before the start too, which stm32f4xx-hal 0.23's
//! `IndependentWatchdog::start` relies on (0x5555, PR, RLR, 0xAAAA, 0xCCCC) for its first period;
//! no source here says what the chip does then. When the count passes 0 it resets the system (RM0090 table 107 gives the timeout
//! as (RL + 1) × prescaler / f_LSI: 0.125 ms at RL 0 and 512 ms at RL 0xFFF with /4 at 32 kHz),
//! which the model asks of the machine ([`Machine::system_reset`] with
//! [`ResetCause::IndependentWatchdog`]: the RCC model sets RCC_CSR.IWDGRSTF). PR and RLR are
//! writable only after 0x5555, until any other key (§21.3.2); PVU and RVU in IWDG_SR are set for
//! 5 LSI cycles after a write of PR or RLR (§21.4.4: the update "takes up to 5" cycles of the
//! RC oscillator), and a write while the flag is set is ignored (§21.4.2, §21.4.3: the bit "must
//! be reset in order to be able to change" the value; the model keeps the old one).
//!
//! Once started the watchdog cannot be stopped: no key stops it; only a reset does (ST's IWDG
//! training slides: "Once enabled, it can only be disabled by a reset"). After a reset it is
//! stopped, unless the hardware watchdog option is selected (FLASH_OPTCR.WDG_SW = 0, RM0090
//! §3.7.1), which starts it "automatically at power-on" (§21.3.1); the model
//! ([`Iwdg::with_hardware_watchdog`]) starts it after every reset, system resets included (no
//! source here says so for a system reset).
//!
//! Simplifications, each small against the LSI's own spread (the datasheet's 17–47 kHz): a new
//! prescaler takes effect on the count at once (on the chip, once PVU clears); a reload loads
//! the RLR just written even while RVU is set; the LSI runs at [`Iwdg::with_lsi_hz`] (32 kHz
//! nominal, [`LSI_HZ`]) exactly, and starting the watchdog does not show LSIRDY in the RCC model
//! (on the chip it forces the LSI on). The debug freeze (DBG_IWDG_STOP) is not modelled.

use crate::gpio::{lanes, read_lanes};
use crate::periph::{Machine, Nanos, Peripheral, ResetCause, ResetKind, Width};

/// The register block's base address (RM0090 §2.3 table 1).
pub const BASE: u32 = 0x4000_3000;
/// The LSI's nominal frequency (RM0090 §7.2.5, table 107's 32 kHz).
pub const LSI_HZ: u32 = 32_000;

/// IWDG_KR keys (RM0090 §21.4.1).
pub mod key {
    /// Starts the watchdog.
    pub const START: u32 = 0xCCCC;
    /// Reloads the counter from RLR.
    pub const RELOAD: u32 = 0xAAAA;
    /// Enables write access to PR and RLR.
    pub const ACCESS: u32 = 0x5555;
}

/// IWDG_SR bits (RM0090 §21.4.4).
pub mod sr {
    /// A prescaler update is under way.
    pub const PVU: u32 = 1 << 0;
    /// A reload value update is under way.
    pub const RVU: u32 = 1 << 1;
}

/// Register offsets (RM0090 §21.4.5 "IWDG register map").
mod reg {
    pub const KR: u32 = 0x0;
    pub const PR: u32 = 0x4;
    pub const RLR: u32 = 0x8;
    pub const SR: u32 = 0xC;
}

/// The counter's value at start (RM0090 §21.3) and RLR's reset value (§21.4.3).
const FULL: u32 = 0xFFF;
/// LSI cycles a PR or RLR update keeps PVU or RVU set (RM0090 §21.4.4: "up to 5").
const UPDATE_CYCLES: u64 = 5;

/// The independent watchdog.
#[derive(Clone, Debug)]
pub struct Iwdg {
    lsi_hz: u32,
    hardware: bool,
    now: Nanos,
    /// 0x5555 was the last key: PR and RLR writable.
    access: bool,
    pr: u32,
    rlr: u32,
    pvu_until: Nanos,
    rvu_until: Nanos,
    running: bool,
    /// The counter's value at `counted_from`.
    count: u32,
    counted_from: Nanos,
    /// The reset was asked for; the machine has not performed it yet.
    expired: bool,
    watchdog_resets: u32,
}

impl Iwdg {
    /// A stopped watchdog (the software watchdog option, FLASH_OPTCR.WDG_SW = 1, the factory
    /// setting), its registers at reset, the LSI at 32 kHz.
    pub fn new() -> Iwdg {
        let mut iwdg = Iwdg {
            lsi_hz: LSI_HZ,
            hardware: false,
            now: 0,
            access: false,
            pr: 0,
            rlr: FULL,
            pvu_until: 0,
            rvu_until: 0,
            running: false,
            count: FULL,
            counted_from: 0,
            expired: false,
            watchdog_resets: 0,
        };
        iwdg.reset(ResetKind::PowerOn);
        iwdg
    }

    /// The hardware watchdog option (FLASH_OPTCR.WDG_SW = 0): running from every reset.
    pub fn with_hardware_watchdog(mut self) -> Iwdg {
        self.hardware = true;
        self.reset(ResetKind::PowerOn);
        self
    }

    /// Counts on an LSI of `hz` (at least 1 Hz) instead of the nominal 32 kHz.
    pub fn with_lsi_hz(mut self, hz: u32) -> Iwdg {
        self.lsi_hz = hz.max(1);
        self
    }

    /// Whether the watchdog runs.
    pub fn running(&self) -> bool {
        self.running
    }

    /// The system resets the watchdog asked for since the model was built.
    pub fn watchdog_resets(&self) -> u32 {
        self.watchdog_resets
    }

    /// The prescaler's divider: 4 × 2^PR, 256 for PR 6 and 7 (RM0090 §21.4.2).
    fn divider(&self) -> u64 {
        4 << self.pr.min(6)
    }

    /// Nanoseconds of `ticks` counter decrements.
    fn ticks_to_nanos(&self, ticks: u64) -> Nanos {
        let nanos = u128::from(ticks) * u128::from(self.divider()) * 1_000_000_000;
        nanos.div_ceil(u128::from(self.lsi_hz)) as Nanos
    }

    /// The counter's value now (RLR's or 0xFFF while stopped, where it starts from).
    pub fn counter(&self) -> u32 {
        if !self.running {
            return self.count;
        }
        let elapsed = u128::from(self.now - self.counted_from) * u128::from(self.lsi_hz);
        let ticks = elapsed / (u128::from(self.divider()) * 1_000_000_000);
        self.count.saturating_sub(ticks.min(u128::from(FULL)) as u32)
    }

    /// When the count passes 0 and the watchdog resets the chip, if it runs.
    pub fn reset_at(&self) -> Option<Nanos> {
        self.running.then(|| self.counted_from + self.ticks_to_nanos(u64::from(self.count) + 1))
    }

    /// Restarts the count from `count` now.
    fn count_from(&mut self, count: u32) {
        self.count = count;
        self.counted_from = self.now;
    }

    fn update(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.now = self.now.max(now);
        if self.expired {
            return;
        }
        if self.reset_at().is_some_and(|at| self.now >= at) {
            self.expired = true;
            self.watchdog_resets += 1;
            machine.system_reset(ResetCause::IndependentWatchdog);
        }
    }

    fn lsi_cycles(&self, cycles: u64) -> Nanos {
        (u128::from(cycles) * 1_000_000_000).div_ceil(u128::from(self.lsi_hz)) as Nanos
    }

    /// IWDG_KR (RM0090 §21.4.1): the keys; any value but 0x5555 protects PR and RLR again
    /// (§21.3.2).
    fn write_kr(&mut self, value: u32) {
        let value = value & 0xFFFF;
        self.access = value == key::ACCESS;
        match value {
            key::START if !self.running => {
                self.running = true;
                self.counted_from = self.now;
            }
            key::RELOAD => {
                let rlr = self.rlr;
                self.count_from(rlr);
            }
            _ => {}
        }
    }

    fn write_pr(&mut self, value: u32) {
        if !self.access || self.pvu_until > self.now {
            return;
        }
        // The count so far at the old prescaler, the rest at the new one.
        let count = self.counter();
        self.pr = value & 7;
        if self.running {
            self.count_from(count);
        }
        self.pvu_until = self.now + self.lsi_cycles(UPDATE_CYCLES);
    }

    fn write_rlr(&mut self, value: u32) {
        if !self.access || self.rvu_until > self.now {
            return;
        }
        self.rlr = value & FULL;
        self.rvu_until = self.now + self.lsi_cycles(UPDATE_CYCLES);
    }

    fn read_register(&self, offset: u32) -> u32 {
        match offset {
            reg::PR => self.pr,
            reg::RLR => self.rlr,
            reg::SR => {
                let pvu = if self.pvu_until > self.now { sr::PVU } else { 0 };
                pvu | if self.rvu_until > self.now { sr::RVU } else { 0 }
            }
            // KR is write-only (reads 0).
            _ => 0,
        }
    }
}

impl Default for Iwdg {
    fn default() -> Self {
        Iwdg::new()
    }
}

impl Peripheral for Iwdg {
    fn name(&self) -> &'static str {
        "IWDG"
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        self.update(machine.now(), machine);
        read_lanes(self.read_register(offset & !3), offset, width)
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.update(machine.now(), machine);
        let (offset, mask, value) = lanes(offset, width, value);
        match offset {
            reg::KR => self.write_kr(value & mask),
            reg::PR => self.write_pr(self.pr & !mask | value),
            reg::RLR => self.write_rlr(self.rlr & !mask | value),
            _ => {}
        }
    }

    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.update(now, machine);
    }

    /// Every reset stops the watchdog and puts PR 0 and RLR 0xFFF back (RM0090 §21.4); with
    /// the hardware watchdog option it starts again at once, from 0xFFF.
    fn reset(&mut self, kind: ResetKind) {
        let _ = kind;
        self.access = false;
        self.pr = 0;
        self.rlr = FULL;
        self.pvu_until = self.now;
        self.rvu_until = self.now;
        self.expired = false;
        self.running = self.hardware;
        self.count_from(FULL);
    }

    fn next_event(&self) -> Option<Nanos> {
        let flags = [self.pvu_until, self.rvu_until].into_iter().filter(|&at| at > self.now);
        let reset = if self.expired { None } else { self.reset_at() };
        flags.chain(reset).min()
    }
}

#[cfg(test)]
mod tests;
