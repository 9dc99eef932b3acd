//! Reset and clock control, RCC (RM0090 §7 "Reset and clock control for STM32F405xx/07xx and
//! STM32F415xx/17xx", registers §7.3, base 0x4002_3800).
//!
//! The model keeps the oscillators (HSI, HSE with the board's crystal or external clock given at
//! construction, the main PLL), the system clock switch and the bus prescalers, the peripheral
//! clock gates and resets, and the reset flags of RCC_CSR. The machine asks it for the clock
//! frequencies ([`Peripheral::clocks`]) and for the clock gates ([`Peripheral::clock_gate`]).
//!
//! Ready flags rise after a modelled start-up time ([`RccTiming`]), evaluated against the
//! machine's time at every access and [`Peripheral::advance`]. A clock that cannot start never
//! becomes ready, as on the part: the HSE without a crystal, a crystal with HSEBYP set, a PLL
//! whose VCO input or output lies outside the STM32F405 datasheet's range. A switch of the
//! system clock to a source that is not ready waits until it is (RM0090 §7.2.6).
//!
//! Misuses the part tolerates but that break the product (a bus clock above its maximum, a PLL
//! reconfigured while running) are recorded as [`RccNote`]s for the machine to report.

use crate::gpio::{lanes, read_lanes};
pub use crate::periph::ResetCause;
use crate::periph::{ClockGate, Clocks, Machine, Nanos, Peripheral, ResetKind, Width};

/// The RCC's base address (RM0090 §2.3 table 1).
pub const BASE: u32 = 0x4002_3800;
/// The RCC global interrupt's position (RM0090 §12.2 table 61).
pub const IRQ: u16 = 5;
/// The HSI oscillator's frequency (RM0090 §7.2.2).
pub const HSI_HZ: u32 = 16_000_000;

/// Register offsets (RM0090 §7.3.24 "RCC register map").
mod reg {
    pub const CR: u32 = 0x00;
    pub const PLLCFGR: u32 = 0x04;
    pub const CFGR: u32 = 0x08;
    pub const CIR: u32 = 0x0C;
    pub const AHB1RSTR: u32 = 0x10;
    pub const AHB2RSTR: u32 = 0x14;
    pub const AHB3RSTR: u32 = 0x18;
    pub const APB1RSTR: u32 = 0x20;
    pub const APB2RSTR: u32 = 0x24;
    pub const AHB1ENR: u32 = 0x30;
    pub const AHB2ENR: u32 = 0x34;
    pub const AHB3ENR: u32 = 0x38;
    pub const APB1ENR: u32 = 0x40;
    pub const APB2ENR: u32 = 0x44;
    pub const AHB1LPENR: u32 = 0x50;
    pub const AHB2LPENR: u32 = 0x54;
    pub const AHB3LPENR: u32 = 0x58;
    pub const APB1LPENR: u32 = 0x60;
    pub const APB2LPENR: u32 = 0x64;
    pub const BDCR: u32 = 0x70;
    pub const CSR: u32 = 0x74;
    pub const SSCGR: u32 = 0x80;
    pub const PLLI2SCFGR: u32 = 0x84;
}

/// RCC_CR bits (RM0090 §7.3.1).
mod cr {
    pub const HSION: u32 = 1 << 0;
    pub const HSIRDY: u32 = 1 << 1;
    pub const HSITRIM: u32 = 0x1F << 3;
    pub const HSEON: u32 = 1 << 16;
    pub const HSERDY: u32 = 1 << 17;
    pub const HSEBYP: u32 = 1 << 18;
    pub const CSSON: u32 = 1 << 19;
    pub const PLLON: u32 = 1 << 24;
    pub const PLLRDY: u32 = 1 << 25;
    pub const PLLI2SON: u32 = 1 << 26;
    pub const PLLI2SRDY: u32 = 1 << 27;
    /// The bits software writes; the ready flags and HSICAL are read-only.
    pub const WRITABLE: u32 = HSION | HSITRIM | HSEON | HSEBYP | CSSON | PLLON | PLLI2SON;
}

/// RCC_CSR bits (RM0090 §7.3.21).
pub mod csr {
    /// The LSI oscillator on.
    pub const LSION: u32 = 1 << 0;
    /// The LSI oscillator ready.
    pub const LSIRDY: u32 = 1 << 1;
    /// Remove the reset flags (write 1).
    pub const RMVF: u32 = 1 << 24;
    /// Brown-out reset.
    pub const BORRSTF: u32 = 1 << 25;
    /// Reset from the NRST pin.
    pub const PINRSTF: u32 = 1 << 26;
    /// Power-on / power-down reset.
    pub const PORRSTF: u32 = 1 << 27;
    /// Software reset (SYSRESETREQ).
    pub const SFTRSTF: u32 = 1 << 28;
    /// Independent watchdog reset.
    pub const IWDGRSTF: u32 = 1 << 29;
    /// Window watchdog reset.
    pub const WWDGRSTF: u32 = 1 << 30;
    /// Low-power reset.
    pub const LPWRRSTF: u32 = 1 << 31;
    /// Every reset flag.
    pub const FLAGS: u32 = BORRSTF | PINRSTF | PORRSTF | SFTRSTF | IWDGRSTF | WWDGRSTF | LPWRRSTF;
}

/// The HSI calibration RCC_CR.HSICAL reads (bits 15:8). The factory programs a part-specific
/// value (RM0090 §7.3.1, reset value 0x0000 XX83); the model's is arbitrary.
const HSICAL: u32 = 0x6B;

/// The external high-speed clock source on OSC_IN/OSC_OUT (RM0090 §7.2.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hse {
    /// Nothing fitted: HSERDY never rises.
    None,
    /// A crystal or ceramic resonator of this frequency: ready with HSEBYP clear only.
    Crystal(u32),
    /// An external clock of this frequency on OSC_IN: ready with HSEBYP set only.
    External(u32),
}

/// The start-up times of the oscillators, from ON to ready.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RccTiming {
    /// HSI (and LSI) start-up.
    pub hsi: Nanos,
    /// HSE start-up.
    pub hse: Nanos,
    /// PLL lock, counted from both PLLON and its input being ready.
    pub pll: Nanos,
}

impl RccTiming {
    /// A few microseconds each, so that emulated start-up stays quick (the default).
    pub const FAST: RccTiming = RccTiming { hsi: 2_000, hse: 5_000, pll: 5_000 };
    /// The STM32F405 datasheet's typical figures (DS8626: HSI start-up 2.2–4 µs, HSE crystal
    /// start-up 2 ms, PLL lock some 100 µs; quoted from memory, no source here confirms them).
    pub const DATASHEET: RccTiming = RccTiming { hsi: 4_000, hse: 2_000_000, pll: 100_000 };
}

impl Default for RccTiming {
    fn default() -> Self {
        RccTiming::FAST
    }
}

/// The system clock source (RCC_CFGR.SW / SWS, RM0090 §7.3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SysclkSource {
    /// `00`: HSI.
    Hsi,
    /// `01`: HSE.
    Hse,
    /// `10`: the main PLL.
    Pll,
}

impl SysclkSource {
    const fn from_bits(bits: u32) -> Option<SysclkSource> {
        match bits & 3 {
            0 => Some(SysclkSource::Hsi),
            1 => Some(SysclkSource::Hse),
            2 => Some(SysclkSource::Pll),
            _ => None,
        }
    }
}

/// A misuse the part tolerates (or that the manual forbids without saying what happens),
/// recorded for the machine to report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RccNote {
    /// PLLCFGR written while the PLL runs (RM0090 §7.3.2: "should be written only if PLL is
    /// disabled"); the model ignores the write.
    PllConfigWhileOn,
    /// The PLL's configuration is outside the datasheet's range; the PLL never locks.
    PllOutOfRange {
        /// VCO input, Hz.
        vco_in: u32,
        /// VCO output, Hz.
        vco_out: u32,
    },
    /// SW = `11`, not allowed (RM0090 §7.3.3); the switch does not happen.
    SwitchNotAllowed,
    /// A clock above its STM32F405 maximum (DS8626: SYSCLK/HCLK 168 MHz, PCLK1 42 MHz, PCLK2
    /// 84 MHz).
    AboveMaximum {
        /// The clocks in force.
        clocks: Clocks,
    },
    /// An attempt to stop the oscillator that drives the system clock (RM0090 §7.3.1: the ON
    /// bit cannot be cleared); ignored.
    StopRefused,
}

impl std::fmt::Display for RccNote {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RccNote::PllConfigWhileOn => f.write_str("RCC_PLLCFGR written while the PLL runs: ignored"),
            RccNote::PllOutOfRange { vco_in, vco_out } => write!(
                f,
                "PLL VCO input {vco_in} Hz / output {vco_out} Hz outside 0.95-2.1 MHz / 100-432 MHz: it never locks"
            ),
            RccNote::SwitchNotAllowed => f.write_str("RCC_CFGR.SW = 11 (not allowed): no switch"),
            RccNote::AboveMaximum { clocks } => write!(
                f,
                "clocks above the STM32F405 maximum (HCLK {} Hz <= 168 MHz, PCLK1 {} Hz <= 42 MHz, PCLK2 {} Hz <= 84 MHz)",
                clocks.hclk, clocks.pclk1, clocks.pclk2
            ),
            RccNote::StopRefused => f.write_str("the oscillator that drives SYSCLK cannot be stopped: ON bit kept"),
        }
    }
}

/// The RCC.
#[derive(Clone, Debug)]
pub struct Rcc {
    hse: Hse,
    timing: RccTiming,
    now: Nanos,
    cr: u32,
    /// When each oscillator was last switched on.
    hsi_on_at: Nanos,
    /// The HSI runs from before the reset ended: ready at once (CR reset value HSIRDY = 1).
    hsi_running: bool,
    hse_on_at: Nanos,
    pll_on_at: Nanos,
    plli2s_on_at: Nanos,
    lsi_on_at: Nanos,
    pllcfgr: u32,
    cfgr: u32,
    sws: SysclkSource,
    cir: u32,
    /// Ready states at the last update, to raise the CIR ready flags on a rising edge.
    was_ready: u32,
    rstr: [u32; 6],
    enr: [u32; 6],
    lpenr: [u32; 6],
    bdcr: u32,
    csr: u32,
    sscgr: u32,
    plli2scfgr: u32,
    resets: Vec<ClockGate>,
    notes: Vec<RccNote>,
}

impl Rcc {
    /// The RCC after a power-on reset, with `hse` on the oscillator pins.
    pub fn new(hse: Hse) -> Rcc {
        Rcc::with_timing(hse, RccTiming::default())
    }

    /// The RCC after a power-on reset, with its oscillators starting in `timing`.
    pub fn with_timing(hse: Hse, timing: RccTiming) -> Rcc {
        let mut rcc = Rcc {
            hse,
            timing,
            now: 0,
            cr: 0,
            hsi_on_at: 0,
            hsi_running: true,
            hse_on_at: 0,
            pll_on_at: 0,
            plli2s_on_at: 0,
            lsi_on_at: 0,
            pllcfgr: 0,
            cfgr: 0,
            sws: SysclkSource::Hsi,
            cir: 0,
            was_ready: 0,
            rstr: [0; 6],
            enr: [0; 6],
            lpenr: [0; 6],
            bdcr: 0,
            csr: 0,
            sscgr: 0,
            plli2scfgr: 0,
            resets: Vec::new(),
            notes: Vec::new(),
        };
        rcc.reset(ResetKind::PowerOn);
        rcc
    }

    /// The misuses recorded so far.
    pub fn notes(&self) -> &[RccNote] {
        &self.notes
    }

    /// The peripherals whose reset bit (RCC_AHB1RSTR, APB1RSTR, APB2RSTR, RM0090 §7.3.5–§7.3.9)
    /// was set since the last call: the machine resets their models. A peripheral stays in reset
    /// while its bit is set ([`Rcc::in_reset`]).
    pub fn take_peripheral_resets(&mut self) -> Vec<ClockGate> {
        std::mem::take(&mut self.resets)
    }

    /// Whether `gate` is open (its RCC_AHB1ENR / APB1ENR / APB2ENR bit, RM0090 §7.3.10,
    /// §7.3.13, §7.3.14); [`Peripheral::clock_gate`] answers the same for the machine.
    pub fn clock_enabled(&self, gate: ClockGate) -> bool {
        let (i, bit) = bus_index(gate);
        self.enr[i] >> bit & 1 != 0
    }

    /// Whether `gate`'s peripheral is held in reset by its RSTR bit.
    pub fn in_reset(&self, gate: ClockGate) -> bool {
        let (i, bit) = bus_index(gate);
        self.rstr[i] >> bit & 1 != 0
    }

    /// Records the cause of a reset in RCC_CSR. The machine calls it (through
    /// [`Peripheral::record_reset_cause`]) after the [`Peripheral::reset`] of a system reset. Every internal reset source drives the NRST pin
    /// low through the pulse generator (RM0090 §7.1.2, figure "Simplified diagram of the reset
    /// circuit"), so PINRSTF is set with SFTRSTF, IWDGRSTF and WWDGRSTF.
    pub fn record_reset_cause(&mut self, cause: ResetCause) {
        self.csr |= csr::PINRSTF
            | match cause {
                ResetCause::Software => csr::SFTRSTF,
                ResetCause::IndependentWatchdog => csr::IWDGRSTF,
                ResetCause::WindowWatchdog => csr::WWDGRSTF,
                ResetCause::Pin => 0,
            };
    }

    /// The system clock source now in force (RCC_CFGR.SWS).
    pub fn sysclk_source(&self) -> SysclkSource {
        self.sws
    }

    fn hse_starts(&self) -> bool {
        let bypass = self.cr & cr::HSEBYP != 0;
        matches!((self.hse, bypass), (Hse::Crystal(_), false) | (Hse::External(_), true))
    }

    fn hse_hz(&self) -> u32 {
        match self.hse {
            Hse::Crystal(hz) | Hse::External(hz) => hz,
            Hse::None => 0,
        }
    }

    /// When the HSI is (or will be) ready, if on.
    fn hsi_ready_at(&self) -> Option<Nanos> {
        let at = if self.hsi_running { 0 } else { self.hsi_on_at + self.timing.hsi };
        (self.cr & cr::HSION != 0).then_some(at)
    }

    fn hse_ready_at(&self) -> Option<Nanos> {
        (self.cr & cr::HSEON != 0 && self.hse_starts()).then_some(self.hse_on_at + self.timing.hse)
    }

    /// The PLL's input: PLLSRC (RM0090 §7.3.2) selects HSE (1) or HSI (0).
    fn pll_source(&self) -> (u32, Option<Nanos>) {
        if self.pllcfgr & (1 << 22) != 0 {
            (self.hse_hz(), self.hse_ready_at())
        } else {
            (HSI_HZ, self.hsi_ready_at())
        }
    }

    /// The PLL's VCO input and output and its P output (RM0090 §7.3.2: f(VCO) = f(in) × N / M,
    /// f(PLL) = f(VCO) / P with P = 2, 4, 6, 8).
    fn pll_frequencies(&self) -> (u32, u32, u32) {
        let m = self.pllcfgr & 0x3F;
        let n = (self.pllcfgr >> 6) & 0x1FF;
        let p = 2 * (((self.pllcfgr >> 16) & 3) + 1);
        let (input, _) = self.pll_source();
        let vco_in = input.checked_div(m).unwrap_or(0);
        let vco_out = (u64::from(vco_in) * u64::from(n)).min(u64::from(u32::MAX)) as u32;
        (vco_in, vco_out, vco_out / p)
    }

    /// Whether the PLL configuration lies in the STM32F405 range: PLLM 2–63 and PLLN 50–432
    /// (RM0090 §7.3.2), VCO input 0.95–2.1 MHz and VCO output 100–432 MHz (datasheet DS8626,
    /// "Main PLL characteristics"; quoted from memory: older datasheet revisions give 192 MHz
    /// as the VCO output minimum, no source here confirms which holds for the F405).
    fn pll_in_range(&self) -> bool {
        let m = self.pllcfgr & 0x3F;
        let n = (self.pllcfgr >> 6) & 0x1FF;
        let (vco_in, vco_out, _) = self.pll_frequencies();
        (2..=63).contains(&m)
            && (50..=432).contains(&n)
            && (950_000..=2_100_000).contains(&vco_in)
            && (100_000_000..=432_000_000).contains(&vco_out)
    }

    fn pll_ready_at(&self) -> Option<Nanos> {
        if self.cr & cr::PLLON == 0 || !self.pll_in_range() {
            return None;
        }
        let (_, input_ready) = self.pll_source();
        input_ready.map(|at| at.max(self.pll_on_at) + self.timing.pll)
    }

    fn ready_at(&self, source: SysclkSource) -> Option<Nanos> {
        match source {
            SysclkSource::Hsi => self.hsi_ready_at(),
            SysclkSource::Hse => self.hse_ready_at(),
            SysclkSource::Pll => self.pll_ready_at(),
        }
    }

    fn is_ready(&self, at: Option<Nanos>) -> bool {
        at.is_some_and(|at| at <= self.now)
    }

    /// The ready flags of RCC_CR and LSIRDY as CIR's flag layout (bit 0 LSI, 2 HSI, 3 HSE,
    /// 4 PLL, 5 PLLI2S).
    fn ready_mask(&self) -> u32 {
        let lsi = (self.csr & csr::LSION != 0).then_some(self.lsi_on_at + self.timing.hsi);
        let plli2s = (self.cr & cr::PLLI2SON != 0).then_some(self.plli2s_on_at + self.timing.pll);
        [(0, lsi), (2, self.hsi_ready_at()), (3, self.hse_ready_at()), (4, self.pll_ready_at()), (5, plli2s)]
            .into_iter()
            .filter(|&(_, at)| self.is_ready(at))
            .fold(0, |mask, (bit, _)| mask | 1 << bit)
    }

    /// Brings the model to `now`: the system clock switch completes once its target is ready
    /// (RM0090 §7.2.6), and rising ready flags set their CIR flags where enabled (§7.3.4).
    fn update(&mut self, now: Nanos) {
        self.now = self.now.max(now);
        if let Some(target) = SysclkSource::from_bits(self.cfgr) {
            if target != self.sws && self.is_ready(self.ready_at(target)) {
                self.sws = target;
                self.check_maximum();
            }
        }
        let ready = self.ready_mask();
        let rising = ready & !self.was_ready;
        self.cir |= rising & (self.cir >> 8) & 0x3F;
        self.was_ready = ready;
    }

    fn check_maximum(&mut self) {
        let clocks = self.current_clocks();
        if clocks.hclk > 168_000_000 || clocks.pclk1 > 42_000_000 || clocks.pclk2 > 84_000_000 {
            self.notes.push(RccNote::AboveMaximum { clocks });
        }
    }

    fn sysclk(&self) -> u32 {
        match self.sws {
            SysclkSource::Hsi => HSI_HZ,
            SysclkSource::Hse => self.hse_hz(),
            SysclkSource::Pll => self.pll_frequencies().2,
        }
    }

    /// The clocks the registers select (RM0090 §7.3.3: HPRE divides SYSCLK by 1, 2, 4 … 512,
    /// PPRE1/PPRE2 divide HCLK by 1, 2, 4, 8, 16).
    pub fn current_clocks(&self) -> Clocks {
        let hpre = (self.cfgr >> 4) & 0xF;
        let ahb_shift = match hpre {
            0..=7 => 0,
            8..=11 => hpre - 7,
            _ => hpre - 6,
        };
        let hclk = self.sysclk() >> ahb_shift;
        let apb = |ppre: u32| if ppre & 4 == 0 { hclk } else { hclk >> ((ppre & 3) + 1) };
        Clocks {
            sysclk: self.sysclk(),
            hclk,
            pclk1: apb((self.cfgr >> 10) & 7),
            pclk2: apb((self.cfgr >> 13) & 7),
        }
    }

    /// Whether the HSI drives SYSCLK, directly or through the PLL; likewise the HSE.
    fn in_use(&self) -> (bool, bool) {
        let pll_hse = self.pllcfgr & (1 << 22) != 0;
        let pll = self.sws == SysclkSource::Pll;
        (self.sws == SysclkSource::Hsi || pll && !pll_hse, self.sws == SysclkSource::Hse || pll && pll_hse)
    }

    /// RCC_CR (RM0090 §7.3.1): an oscillator that drives the system clock cannot be stopped,
    /// HSEBYP is written only while HSEON was clear.
    fn write_cr(&mut self, value: u32) {
        let old = self.cr;
        let mut new = value & cr::WRITABLE;
        let (hsi_used, hse_used) = self.in_use();
        let keep = [(cr::HSION, hsi_used), (cr::HSEON, hse_used), (cr::PLLON, self.sws == SysclkSource::Pll)];
        for (bit, used) in keep {
            if used && old & bit != 0 && new & bit == 0 {
                new |= bit;
                self.notes.push(RccNote::StopRefused);
            }
        }
        if old & cr::HSEON != 0 {
            new = new & !cr::HSEBYP | old & cr::HSEBYP;
        }
        let rising = new & !old;
        let now = self.now;
        for (bit, at) in [
            (cr::HSION, &mut self.hsi_on_at),
            (cr::HSEON, &mut self.hse_on_at),
            (cr::PLLON, &mut self.pll_on_at),
            (cr::PLLI2SON, &mut self.plli2s_on_at),
        ] {
            if rising & bit != 0 {
                *at = now;
            }
        }
        if rising & cr::HSION != 0 {
            self.hsi_running = false;
        }
        self.cr = new;
        if rising & cr::PLLON != 0 && !self.pll_in_range() {
            let (vco_in, vco_out, _) = self.pll_frequencies();
            self.notes.push(RccNote::PllOutOfRange { vco_in, vco_out });
        }
    }

    fn read_cr(&self) -> u32 {
        let ready = self.ready_mask();
        let flag = |bit: u32, flag: u32| if ready & (1 << bit) != 0 { flag } else { 0 };
        self.cr
            | HSICAL << 8
            | flag(2, cr::HSIRDY)
            | flag(3, cr::HSERDY)
            | flag(4, cr::PLLRDY)
            | flag(5, cr::PLLI2SRDY)
    }

    /// RCC_PLLCFGR (RM0090 §7.3.2): PLLM/N/P/Q while the PLL is off, PLLSRC while both PLLs
    /// are off ("can be written only when PLL and PLLI2S are disabled").
    fn write_pllcfgr(&mut self, value: u32) {
        const DIVIDERS: u32 = 0x3F | 0x1FF << 6 | 3 << 16 | 0xF << 24;
        const PLLSRC: u32 = 1 << 22;
        let mut writable = 0;
        if self.cr & cr::PLLON == 0 {
            writable |= DIVIDERS;
        } else {
            self.notes.push(RccNote::PllConfigWhileOn);
        }
        if self.cr & (cr::PLLON | cr::PLLI2SON) == 0 {
            writable |= PLLSRC;
        }
        self.pllcfgr = self.pllcfgr & !writable | value & writable;
    }

    fn write_cfgr(&mut self, value: u32) {
        // SWS (bits 3:2) is read-only.
        self.cfgr = value & !0xC;
        if SysclkSource::from_bits(value).is_none() {
            self.notes.push(RccNote::SwitchNotAllowed);
        }
        self.check_maximum();
    }

    /// RCC_CIR (RM0090 §7.3.4): flags read-only, enables read-write, clear bits write-only.
    fn write_cir(&mut self, value: u32) {
        let clear = (value >> 16) & 0xBF;
        self.cir = (self.cir & 0xBF & !clear) | (value & 0x3F00);
    }

    fn write_rstr(&mut self, index: usize, value: u32) {
        let rising = value & !self.rstr[index];
        self.rstr[index] = value;
        let gate: fn(u8) -> ClockGate = match index {
            0 => ClockGate::Ahb1,
            4 => ClockGate::Apb1,
            5 => ClockGate::Apb2,
            _ => return,
        };
        self.resets.extend((0..32u8).filter(|b| rising >> b & 1 != 0).map(gate));
    }

    /// RCC_CSR (RM0090 §7.3.21): LSION read-write, RMVF clears the reset flags.
    fn write_csr(&mut self, value: u32) {
        if value & csr::LSION != 0 && self.csr & csr::LSION == 0 {
            self.lsi_on_at = self.now;
        }
        self.csr = self.csr & !csr::LSION | value & csr::LSION;
        if value & csr::RMVF != 0 {
            self.csr &= !csr::FLAGS;
        }
    }

    fn read_register(&self, offset: u32) -> u32 {
        let bank = |base: u32| ((offset - base) / 4) as usize;
        match offset {
            reg::CR => self.read_cr(),
            reg::PLLCFGR => self.pllcfgr,
            reg::CFGR => self.cfgr | (self.sws as u32) << 2,
            reg::CIR => self.cir,
            reg::AHB1RSTR..=reg::APB2RSTR => self.rstr[bank(reg::AHB1RSTR)],
            reg::AHB1ENR..=reg::APB2ENR => self.enr[bank(reg::AHB1ENR)],
            reg::AHB1LPENR..=reg::APB2LPENR => self.lpenr[bank(reg::AHB1LPENR)],
            reg::BDCR => self.bdcr,
            reg::CSR => {
                let lsi = self.ready_mask() & 1 != 0;
                self.csr | if lsi { csr::LSIRDY } else { 0 }
            }
            reg::SSCGR => self.sscgr,
            reg::PLLI2SCFGR => self.plli2scfgr,
            _ => 0,
        }
    }

    fn write_register(&mut self, offset: u32, value: u32) {
        let bank = |base: u32| ((offset - base) / 4) as usize;
        match offset {
            reg::CR => self.write_cr(value),
            reg::PLLCFGR => self.write_pllcfgr(value),
            reg::CFGR => self.write_cfgr(value),
            reg::CIR => self.write_cir(value),
            reg::AHB1RSTR | reg::AHB2RSTR | reg::AHB3RSTR | reg::APB1RSTR | reg::APB2RSTR => {
                self.write_rstr(bank(reg::AHB1RSTR), value)
            }
            reg::AHB1ENR | reg::AHB2ENR | reg::AHB3ENR | reg::APB1ENR | reg::APB2ENR => {
                self.enr[bank(reg::AHB1ENR)] = value
            }
            reg::AHB1LPENR | reg::AHB2LPENR | reg::AHB3LPENR | reg::APB1LPENR | reg::APB2LPENR => {
                self.lpenr[bank(reg::AHB1LPENR)] = value
            }
            reg::BDCR => self.bdcr = value,
            reg::CSR => self.write_csr(value),
            reg::SSCGR => self.sscgr = value,
            reg::PLLI2SCFGR => self.plli2scfgr = value,
            _ => {}
        }
    }

    fn irq_level(&self) -> bool {
        self.cir & (self.cir >> 8) & 0x3F != 0
    }
}

/// The register bank (index into the RSTR/ENR arrays, by offset: AHB1 0, AHB2 1, AHB3 2, a
/// reserved word 3, APB1 4, APB2 5)
/// and bit of a clock gate.
fn bus_index(gate: ClockGate) -> (usize, u8) {
    match gate {
        ClockGate::Ahb1(bit) => (0, bit & 31),
        ClockGate::Apb1(bit) => (4, bit & 31),
        ClockGate::Apb2(bit) => (5, bit & 31),
    }
}

impl Peripheral for Rcc {
    fn name(&self) -> &'static str {
        "RCC"
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        self.update(machine.now());
        machine.set_irq(IRQ, self.irq_level());
        read_lanes(self.read_register(offset & !3), offset, width)
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.update(machine.now());
        let (offset, mask, value) = lanes(offset, width, value);
        let old = self.read_register(offset);
        self.write_register(offset, old & !mask | value);
        self.update(machine.now());
        machine.set_irq(IRQ, self.irq_level());
    }

    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.update(now);
        machine.set_irq(IRQ, self.irq_level());
    }

    /// Reset values (RM0090 §7.3): CR 0x0000_XX83 (HSI on and ready), PLLCFGR 0x2400_3010,
    /// AHB1ENR 0x0010_0000 (CCM data RAM clock), the LPENR registers all-enabled, PLLI2SCFGR
    /// 0x2000_3000. RCC_BDCR and the CSR reset flags survive a system reset (§7.3.20, §7.3.21).
    fn reset(&mut self, kind: ResetKind) {
        self.cr = cr::HSION | 0x10 << 3;
        self.hsi_running = true;
        self.pllcfgr = 0x2400_3010;
        self.cfgr = 0;
        self.sws = SysclkSource::Hsi;
        self.cir = 0;
        self.rstr = [0; 6];
        self.enr = [0x0010_0000, 0, 0, 0, 0, 0];
        self.lpenr = [0x7E67_91FF, 0xF1, 0x1, 0, 0x36FE_C9FF, 0x0007_5F33];
        self.sscgr = 0;
        self.plli2scfgr = 0x2000_3000;
        self.csr &= csr::FLAGS;
        if kind == ResetKind::PowerOn {
            self.bdcr = 0;
            self.csr = csr::PORRSTF | csr::PINRSTF | csr::BORRSTF;
        }
        self.was_ready = self.ready_mask();
    }

    fn next_event(&self) -> Option<Nanos> {
        let lsi = (self.csr & csr::LSION != 0).then_some(self.lsi_on_at + self.timing.hsi);
        [self.hsi_ready_at(), self.hse_ready_at(), self.pll_ready_at(), lsi]
            .into_iter()
            .flatten()
            .filter(|&at| at > self.now)
            .min()
    }

    fn clocks(&self) -> Option<Clocks> {
        Some(self.current_clocks())
    }

    fn record_reset_cause(&mut self, cause: ResetCause) {
        Rcc::record_reset_cause(self, cause);
    }

    fn clock_gate(&self, gate: ClockGate) -> Option<bool> {
        Some(self.clock_enabled(gate))
    }
}

#[cfg(test)]
mod tests;
