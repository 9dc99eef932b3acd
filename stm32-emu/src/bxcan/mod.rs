//! The bxCAN controller CAN1 (RM0090 §32 "Controller area network (bxCAN)"), with the filter
//! banks it shares with CAN2.
//!
//! | file | what it models |
//! |---|---|
//! | `mod.rs` | the register block, the operating modes and their handshakes (RM0090 §32.4), the interrupt lines (§32.8) |
//! | [`frame`] | frames and their mailbox register images (§32.9.3) |
//! | [`timing`] | the bit rate from `CAN_BTR` and PCLK1 (§32.7.7), and the rule for a bus at another rate |
//! | [`filter`] | the 28 filter banks, every scale and mode, the filter match index (§32.7.4) |
//! | `mailbox.rs` | three transmit mailboxes (§32.7.1), two receive FIFOs of three (§32.7.3, §32.7.5) |
//! | `bus.rs` | the bus side: what the controller sends and sees, error counting and bus-off (§32.7.6) |
//!
//! ## Modes
//!
//! `CAN_MCR.INRQ` and `SLEEP` request a mode; `CAN_MSR.INAK` and `SLAK` acknowledge it, following
//! the operating-mode diagram of RM0090 §32.4: INRQ = 1, SLEEP = 0 requests initialisation;
//! INRQ = 0, SLEEP = 1 sleep; both clear normal mode; both set leave the mode as it is (§32.4.3:
//! software that requests initialisation from sleep must also clear SLEEP). The hardware enters
//! initialisation or sleep once the current frame is over, and normal mode once it has seen 11
//! consecutive recessive bits (§32.4.1, §32.4.2). The model moves frames whole, so the bus is
//! idle at every register access: each acknowledgement follows its request at once. After a
//! reset the controller sleeps (MCR = 0x0001_0002, MSR = 0x0000_0C02).
//!
//! ## Refusals
//!
//! `CAN_BTR` is written only in initialisation mode (§32.9.2; RM0090 §32.7.7: "only possible
//! while the device is in Standby mode"); a transmit mailbox only while empty (§32.9.1); the
//! filter scale, mode and FIFO assignment only in FINIT mode, a filter bank's registers only in
//! FINIT mode or while the bank is inactive (§32.9.1, §32.9.4; [`filter`]). Other writes to
//! these are ignored, as the hardware ignores them. The registers are word registers (§32.9: "accessed by words"): the
//! model answers a narrower read with the bytes of the word and ignores a narrower write (no
//! source says what the hardware does with one). With the CAN1 clock gate
//! (`RCC_APB1ENR.CAN1EN`, bit 25) closed, reads return 0 and writes are ignored.
//!
//! ## Fault injection
//!
//! [`Bxcan::set_loopback_broken`] breaks the path from the transmitter back to the receiver
//! that loop back mode uses (RM0090 §32.5.2, §32.5.3), a defect of the chip a power-up self-test
//! in silent loop back mode is meant to catch: a frame sent in loop back mode completes (TXOK) but
//! is never received. Normal mode is unaffected. The fault survives every reset: it is the
//! chip's, not a register's.
//!
//! ## Not modelled
//!
//! Time-triggered communication (TTCM, time stamps, TGT: the time fields read 0), debug freeze
//! (DBF is kept but has no effect), the TXM/RXM status bits (always 0: no frame is ever half
//! sent), and CAN2's own register block.

pub mod filter;
pub mod frame;
pub mod timing;

mod bus;
mod mailbox;
#[cfg(test)]
mod tests;

pub use bus::{Response, Transmission, TxOutcome};
pub use frame::{Frame, FrameId};
pub use mailbox::{rfr, tsr};
pub use timing::BitTiming;

use crate::periph::{ClockGate, Clocks, Machine, Nanos, Peripheral, ResetKind, Width};
use filter::FilterModule;
use mailbox::{RxFifo, Transmitter};

/// The base address of CAN1 (RM0090 §2.3 "Memory map").
pub const CAN1_BASE: u32 = 0x4000_6400;
/// The size of a bxCAN register block.
pub const BLOCK_SIZE: u32 = 0x400;
/// The RCC clock gate of CAN1 (`RCC_APB1ENR` bit 25, RM0090 §7.3.13).
pub const CAN1_CLOCK: ClockGate = ClockGate::Apb1(25);

/// CAN1's interrupt lines (RM0090 §12.2, table 61).
pub mod irq {
    /// CAN1 TX: a request completed (RQCPx) with TMEIE.
    pub const TX: u16 = 19;
    /// CAN1 RX0: FIFO 0 message pending, full or overrun.
    pub const RX0: u16 = 20;
    /// CAN1 RX1: FIFO 1 likewise.
    pub const RX1: u16 = 21;
    /// CAN1 SCE: status change and error (ERRI, WKUI, SLAKI).
    pub const SCE: u16 = 22;
}

/// Register offsets within the block (RM0090 §32.9.5 "bxCAN register map").
pub mod offset {
    /// `CAN_MCR`.
    pub const MCR: u32 = 0x000;
    /// `CAN_MSR`.
    pub const MSR: u32 = 0x004;
    /// `CAN_TSR`.
    pub const TSR: u32 = 0x008;
    /// `CAN_RF0R`.
    pub const RF0R: u32 = 0x00C;
    /// `CAN_RF1R`.
    pub const RF1R: u32 = 0x010;
    /// `CAN_IER`.
    pub const IER: u32 = 0x014;
    /// `CAN_ESR`.
    pub const ESR: u32 = 0x018;
    /// `CAN_BTR`.
    pub const BTR: u32 = 0x01C;
    /// `CAN_TI0R`; mailbox m's registers start at `TI0R + 0x10 m`: TIxR, TDTxR, TDLxR, TDHxR.
    pub const TI0R: u32 = 0x180;
    /// `CAN_RI0R`; FIFO f's output mailbox starts at `RI0R + 0x10 f`: RIxR, RDTxR, RDLxR, RDHxR.
    pub const RI0R: u32 = 0x1B0;
    /// `CAN_FMR`, the first filter register ([`super::filter`]).
    pub const FMR: u32 = 0x200;
}

/// `CAN_MCR` bits (RM0090 §32.9.2).
pub mod mcr {
    /// Initialisation request.
    pub const INRQ: u32 = 1 << 0;
    /// Sleep request.
    pub const SLEEP: u32 = 1 << 1;
    /// Transmit FIFO priority: by request order (1) or identifier (0).
    pub const TXFP: u32 = 1 << 2;
    /// Receive FIFO locked against overrun.
    pub const RFLM: u32 = 1 << 3;
    /// No automatic retransmission.
    pub const NART: u32 = 1 << 4;
    /// Automatic wakeup.
    pub const AWUM: u32 = 1 << 5;
    /// Automatic bus-off management.
    pub const ABOM: u32 = 1 << 6;
    /// Time-triggered communication mode (kept, not modelled).
    pub const TTCM: u32 = 1 << 7;
    /// Master reset (set by software, cleared by hardware).
    pub const RESET: u32 = 1 << 15;
    /// Debug freeze (kept, not modelled).
    pub const DBF: u32 = 1 << 16;
    /// The value after reset.
    pub const RESET_VALUE: u32 = DBF | SLEEP;
    /// The bits software writes and reads back.
    pub(crate) const WRITABLE: u32 = 0x0001_00FF;
}

/// `CAN_MSR` bits (RM0090 §32.9.2).
pub mod msr {
    /// Initialisation acknowledge.
    pub const INAK: u32 = 1 << 0;
    /// Sleep acknowledge.
    pub const SLAK: u32 = 1 << 1;
    /// Error interrupt (rc_w1).
    pub const ERRI: u32 = 1 << 2;
    /// Wakeup interrupt (rc_w1).
    pub const WKUI: u32 = 1 << 3;
    /// Sleep acknowledge interrupt (rc_w1).
    pub const SLAKI: u32 = 1 << 4;
    /// SAMP and RX: the last sample and the CANRX level, recessive (1) on an idle bus.
    pub const SAMP_RX: u32 = 0b11 << 10;
}

/// `CAN_IER` bits (RM0090 §32.9.2).
pub mod ier {
    /// Transmit mailbox empty.
    pub const TMEIE: u32 = 1 << 0;
    /// FIFO 0 message pending.
    pub const FMPIE0: u32 = 1 << 1;
    /// FIFO 0 full.
    pub const FFIE0: u32 = 1 << 2;
    /// FIFO 0 overrun.
    pub const FOVIE0: u32 = 1 << 3;
    /// Error warning.
    pub const EWGIE: u32 = 1 << 8;
    /// Error passive.
    pub const EPVIE: u32 = 1 << 9;
    /// Bus-off.
    pub const BOFIE: u32 = 1 << 10;
    /// Last error code.
    pub const LECIE: u32 = 1 << 11;
    /// Error interrupt (ERRI to the SCE line).
    pub const ERRIE: u32 = 1 << 15;
    /// Wakeup.
    pub const WKUIE: u32 = 1 << 16;
    /// Sleep.
    pub const SLKIE: u32 = 1 << 17;
    /// The implemented bits.
    pub(crate) const WRITABLE: u32 = 0x0003_8F7F;
}

/// The reset value of `CAN_BTR` (RM0090 §32.9.2).
pub const BTR_RESET_VALUE: u32 = 0x0123_0000;
/// The implemented bits of `CAN_BTR`: SILM, LBKM, SJW, TS2, TS1, BRP.
const BTR_BITS: u32 = 0xC37F_03FF;
/// LBKM in `CAN_BTR`: loop back mode (RM0090 §32.5.2).
pub const LBKM: u32 = 1 << 30;
/// SILM in `CAN_BTR`: silent mode (RM0090 §32.5.1).
pub const SILM: u32 = 1 << 31;

/// The operating mode the controller is in (RM0090 §32.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Sleep (SLAK = 1), the mode after reset.
    Sleep,
    /// Initialisation (INAK = 1).
    Init,
    /// Normal: on the bus (INAK = SLAK = 0), bus-off included.
    Normal,
}

/// The bxCAN1 model: registers, mailboxes, FIFOs, filters and error state.
///
/// The CPU side is [`Peripheral`]; the bus side ([`Bxcan::poll_transmit`],
/// [`Bxcan::transmit_outcome`], [`Bxcan::response`], [`Bxcan::on_wire`],
/// [`Bxcan::next_deadline`]) is described in `bus.rs` and on each method.
#[derive(Clone, Debug)]
pub struct Bxcan {
    mcr: u32,
    mode: Mode,
    /// ERRI, WKUI and SLAKI.
    msr_flags: u32,
    ier: u32,
    btr: u32,
    lec: u32,
    tec: u32,
    rec: u32,
    bus_off: bool,
    /// Since when the bus-off recovery sequence runs (RM0090 §32.7.6).
    recovery_from: Option<Nanos>,
    /// Software left initialisation mode while bus-off: recovery starts in normal mode.
    recovery_requested: bool,
    tx: Transmitter,
    rx: [RxFifo; 2],
    filters: FilterModule,
    now: Nanos,
    /// PCLK1 as last seen from the machine, for [`Peripheral::next_event`].
    pclk1: u32,
    /// The injected fault of [`Bxcan::set_loopback_broken`].
    loopback_broken: bool,
}

impl Default for Bxcan {
    fn default() -> Self {
        Bxcan::new()
    }
}

impl Bxcan {
    /// CAN1 after a reset: asleep, every mailbox empty, the filters in FINIT mode.
    pub fn new() -> Bxcan {
        Bxcan {
            mcr: mcr::RESET_VALUE,
            mode: Mode::Sleep,
            msr_flags: 0,
            ier: 0,
            btr: BTR_RESET_VALUE,
            lec: 0,
            tec: 0,
            rec: 0,
            bus_off: false,
            recovery_from: None,
            recovery_requested: false,
            tx: Transmitter::default(),
            rx: [RxFifo::default(), RxFifo::default()],
            filters: FilterModule::new(),
            now: 0,
            pclk1: Clocks::RESET.pclk1,
            loopback_broken: false,
        }
    }

    /// The reset of CAN1 through `RCC_APB1RSTR` (bit 25) or a system reset: everything,
    /// filters included, to its reset value.
    pub fn reset(&mut self) {
        *self =
            Bxcan { now: self.now, pclk1: self.pclk1, loopback_broken: self.loopback_broken, ..Bxcan::new() };
    }

    /// Injects (or removes) the fault of a broken loop back path (module docs, "Fault
    /// injection"): from now on a frame sent in loop back mode completes but never reaches the
    /// receive FIFOs.
    pub fn set_loopback_broken(&mut self, broken: bool) {
        self.loopback_broken = broken;
    }

    /// Whether the loop back path is broken ([`Bxcan::set_loopback_broken`]).
    pub const fn loopback_broken(&self) -> bool {
        self.loopback_broken
    }

    /// The master reset of `CAN_MCR.RESET`: the controller to its reset state (asleep). The
    /// filter module is kept: RM0090 describes RESET as a reset of the bxCAN, and the model
    /// takes the filter banks (shared with CAN2) to be outside it (no source confirms this).
    fn master_reset(&mut self) {
        let filters = self.filters.clone();
        self.reset();
        self.filters = filters;
    }

    /// The operating mode.
    pub const fn mode(&self) -> Mode {
        self.mode
    }

    /// The bit timing `CAN_BTR` holds.
    pub const fn bit_timing(&self) -> BitTiming {
        BitTiming::from_btr(self.btr)
    }

    /// The transmit and receive error counters (TEC, REC) as `CAN_ESR` shows them.
    pub fn error_counters(&self) -> (u8, u8) {
        (self.tec.min(255) as u8, self.rec.min(255) as u8)
    }

    /// Whether the controller is bus-off.
    pub const fn is_bus_off(&self) -> bool {
        self.bus_off
    }

    /// The filter module (read-only view, e.g. for CAN2 or a test).
    pub const fn filters(&self) -> &FilterModule {
        &self.filters
    }

    /// Takes the time and PCLK1 from the machine.
    fn sync(&mut self, now: Nanos, machine: &dyn Machine) {
        self.now = self.now.max(now);
        self.pclk1 = machine.clocks().pclk1;
    }

    fn loopback(&self) -> bool {
        self.btr & LBKM != 0
    }

    fn silent(&self) -> bool {
        self.btr & SILM != 0
    }

    /// `CAN_MSR`.
    fn msr(&self) -> u32 {
        let ack = match self.mode {
            Mode::Init => msr::INAK,
            Mode::Sleep => msr::SLAK,
            Mode::Normal => 0,
        };
        ack | self.msr_flags | msr::SAMP_RX
    }

    /// `CAN_ESR` (RM0090 §32.9.2): EWGF (a counter ≥ 96), EPVF (a counter > 127), BOFF, LEC,
    /// TEC and REC.
    fn esr(&self) -> u32 {
        let (tec, rec) = self.error_counters();
        let ewgf = self.tec >= 96 || self.rec >= 96;
        let epvf = self.tec > 127 || self.rec > 127;
        u32::from(ewgf)
            | u32::from(epvf) << 1
            | u32::from(self.bus_off) << 2
            | self.lec << 4
            | u32::from(tec) << 16
            | u32::from(rec) << 24
    }

    fn read_word(&self, offset: u32) -> u32 {
        let by_order = self.mcr & mcr::TXFP != 0;
        match offset {
            offset::MCR => self.mcr,
            offset::MSR => self.msr(),
            offset::TSR => self.tx.tsr(by_order),
            offset::RF0R => self.rx[0].rfr(),
            offset::RF1R => self.rx[1].rfr(),
            offset::IER => self.ier,
            offset::ESR => self.esr(),
            offset::BTR => self.btr,
            0x180..=0x1AF => self.tx.read(((offset - 0x180) / 0x10) as usize, ((offset % 0x10) / 4) as usize),
            0x1B0..=0x1CF => self.rx[((offset - 0x1B0) / 0x10) as usize].read(((offset % 0x10) / 4) as usize),
            o if o >= offset::FMR => self.filters.read(o),
            _ => 0,
        }
    }

    fn write_word(&mut self, offset: u32, value: u32) {
        match offset {
            offset::MCR => self.write_mcr(value),
            offset::MSR => self.msr_flags &= !(value & (msr::ERRI | msr::WKUI | msr::SLAKI)),
            offset::TSR => self.tx.write_tsr(value),
            offset::RF0R => self.rx[0].write_rfr(value),
            offset::RF1R => self.rx[1].write_rfr(value),
            offset::IER => self.ier = value & ier::WRITABLE,
            // LEC is the only field software writes (RM0090 §32.9.2: it may set it to 7).
            offset::ESR => self.lec = (value >> 4) & 0x7,
            offset::BTR if self.mode == Mode::Init => self.btr = value & BTR_BITS,
            0x180..=0x1AF => {
                self.tx.write(((offset - 0x180) / 0x10) as usize, ((offset % 0x10) / 4) as usize, value)
            }
            o if o >= offset::FMR => self.filters.write(o, value),
            _ => {}
        }
    }

    fn write_mcr(&mut self, value: u32) {
        if value & mcr::RESET != 0 {
            self.master_reset();
            return;
        }
        self.mcr = value & mcr::WRITABLE;
        self.update_mode();
    }

    /// Follows the mode requested in `CAN_MCR` (module docs, "Modes").
    fn update_mode(&mut self) {
        let requested = match (self.mcr & mcr::INRQ != 0, self.mcr & mcr::SLEEP != 0) {
            (true, false) => Mode::Init,
            (false, true) => Mode::Sleep,
            (false, false) => Mode::Normal,
            (true, true) => self.mode,
        };
        self.enter(requested);
    }

    fn enter(&mut self, mode: Mode) {
        if mode == self.mode {
            return;
        }
        match self.mode {
            // RM0090 §32.7.6: with ABOM clear, software starts the bus-off recovery by entering
            // and leaving initialisation mode.
            Mode::Init if self.bus_off => self.recovery_requested = true,
            // SLAKI is cleared by hardware when SLAK is (RM0090 §32.9.2).
            Mode::Sleep => self.msr_flags &= !msr::SLAKI,
            _ => {}
        }
        match mode {
            Mode::Init | Mode::Sleep => {
                // RM0090 §32.7.6: out of normal mode the controller does not monitor CANRX and
                // cannot complete the recovery sequence; it starts over on return.
                self.recovery_from = None;
                if mode == Mode::Sleep && self.ier & ier::SLKIE != 0 {
                    self.msr_flags |= msr::SLAKI;
                }
            }
            Mode::Normal => {
                if self.bus_off && (self.recovery_requested || self.mcr & mcr::ABOM != 0) {
                    self.recovery_from = Some(self.now);
                }
            }
        }
        self.mode = mode;
    }

    /// Drives the four interrupt lines (RM0090 §32.8): TX = TMEIE & any RQCPx; RX0/RX1 =
    /// FMPIEx & FMPx ≠ 0 | FFIEx & FULLx | FOVIEx & FOVRx; SCE = ERRIE & ERRI | WKUIE & WKUI |
    /// SLKIE & SLAKI.
    fn update_irqs(&self, machine: &mut dyn Machine) {
        let on = |bit: u32| self.ier & bit != 0;
        machine.set_irq(irq::TX, on(ier::TMEIE) && self.tx.request_completed());
        for (f, line) in [(0, irq::RX0), (1, irq::RX1)] {
            let fifo = &self.rx[f];
            let shift = 3 * f as u32;
            let level = on(ier::FMPIE0 << shift) && fifo.pending() > 0
                || on(ier::FFIE0 << shift) && fifo.full()
                || on(ier::FOVIE0 << shift) && fifo.overrun();
            machine.set_irq(line, level);
        }
        let flags = self.msr_flags;
        let sce = on(ier::ERRIE) && flags & msr::ERRI != 0
            || on(ier::WKUIE) && flags & msr::WKUI != 0
            || on(ier::SLKIE) && flags & msr::SLAKI != 0;
        machine.set_irq(irq::SCE, sce);
    }
}

impl Peripheral for Bxcan {
    fn name(&self) -> &'static str {
        "bxCAN1"
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        if !machine.clock_enabled(CAN1_CLOCK) {
            machine.unclocked_access(CAN1_CLOCK);
            return 0;
        }
        let word = self.read_word(offset & !3);
        let shifted = word >> (8 * (offset & 3));
        match width {
            Width::Byte => shifted & 0xFF,
            Width::Half => shifted & 0xFFFF,
            Width::Word => word,
        }
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        if !machine.clock_enabled(CAN1_CLOCK) {
            machine.unclocked_access(CAN1_CLOCK);
            return;
        }
        if width != Width::Word || offset & 3 != 0 {
            return;
        }
        self.sync(machine.now(), machine);
        self.write_word(offset, value);
        self.run_internal();
        self.update_irqs(machine);
    }

    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.sync(now, machine);
        self.run_internal();
        self.update_irqs(machine);
    }

    /// Power-on and system reset: every register, filters included, to its reset value.
    fn reset(&mut self, kind: ResetKind) {
        let _ = kind;
        Bxcan::reset(self);
    }

    fn next_event(&self) -> Option<Nanos> {
        self.next_deadline()
    }
}
