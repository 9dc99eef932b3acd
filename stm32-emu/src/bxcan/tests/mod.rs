//! Unit tests of the bxCAN model, driven by the register sequences bxcan 0.8 and the board crate
//! perform (`Driver` below repeats them access by access), checked against RM0090's register
//! facts.

use super::*;
use crate::periph::{ClockGate, Clocks, Machine, Nanos};

mod errors;
mod filters;
mod modes;
mod receive;
mod transmit;
mod world;

/// A machine with fixed clocks, the CAN1 clock gate open, and a record of the interrupt lines.
pub(super) struct TestMachine {
    pub clocks: Clocks,
    pub gate_open: bool,
    pub irqs: [bool; 128],
    pub now: Nanos,
}

impl TestMachine {
    pub fn at_pclk1(pclk1: u32) -> TestMachine {
        TestMachine { clocks: Clocks { pclk1, ..Clocks::RESET }, gate_open: true, irqs: [false; 128], now: 0 }
    }
}

impl Machine for TestMachine {
    fn clocks(&self) -> Clocks {
        self.clocks
    }
    fn clock_enabled(&self, gate: ClockGate) -> bool {
        gate == CAN1_CLOCK && self.gate_open
    }
    fn set_irq(&mut self, irq: u16, level: bool) {
        self.irqs[usize::from(irq)] = level;
    }
    fn now(&self) -> Nanos {
        self.now
    }
}

/// The board's 125 kbit/s `CAN_BTR` value at 42 MHz (board::bit_timing).
pub(super) const BTR_125K_AT_42MHZ: u32 = 0x011C_0014;
/// The board's APB1 clock.
pub(super) const PCLK1: u32 = 42_000_000;

/// `nb::Result` of bxcan 0.8, as the tests need it.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Nb<T, E> {
    Ok(T),
    WouldBlock,
    Other(E),
}

/// The overrun error of bxcan's `receive`.
#[derive(Debug, PartialEq, Eq)]
pub(super) struct Overrun;

/// A bxcan 0.8 `Mask16`: identifier and mask halves.
#[derive(Clone, Copy)]
pub(super) struct Mask16 {
    pub id: u16,
    pub mask: u16,
}

impl Mask16 {
    /// `Mask16::frames_with_std_id(id, mask)`: `id << 5`, `mask << 5 | F16_IDE`.
    pub fn frames_with_std_id(id: u16, mask: u16) -> Mask16 {
        Mask16 { id: id << 5, mask: mask << 5 | 0b0_1000 }
    }

    /// `Mask16::data_frames_only`: RTR must be 0.
    pub fn data_frames_only(mut self) -> Mask16 {
        self.id &= !0b1_0000;
        self.mask |= 0b1_0000;
        self
    }
}

/// The CPU side: the controller, its machine, and the accesses bxcan 0.8 makes.
pub(super) struct Driver {
    pub can: Bxcan,
    pub m: TestMachine,
}

impl Driver {
    pub fn new(pclk1: u32) -> Driver {
        Driver { can: Bxcan::new(), m: TestMachine::at_pclk1(pclk1) }
    }

    pub fn read(&mut self, offset: u32) -> u32 {
        self.can.read(offset, Width::Word, &mut self.m)
    }

    pub fn write(&mut self, offset: u32, value: u32) {
        self.can.write(offset, Width::Word, value, &mut self.m);
    }

    /// svd2rust `modify`: read, change, write back.
    pub fn modify(&mut self, offset: u32, f: impl FnOnce(u32) -> u32) {
        let value = self.read(offset);
        self.write(offset, f(value));
    }

    /// Polls MSR until `done` holds; a register the hardware never changes would hang the
    /// firmware, so the test fails after 1000 reads.
    pub fn poll_msr(&mut self, done: impl Fn(u32) -> bool) {
        for _ in 0..1000 {
            if done(self.read(offset::MSR)) {
                return;
            }
        }
        panic!("MSR never reached the awaited state: {:#010x}", self.read(offset::MSR));
    }

    /// `Can::builder`: SLEEP = 0, INRQ = 1, then wait for SLAK = 0 and INAK = 1.
    pub fn builder(&mut self) {
        self.modify(offset::MCR, |r| r & !mcr::SLEEP | mcr::INRQ);
        self.poll_msr(|msr| msr & msr::SLAK == 0 && msr & msr::INAK != 0);
    }

    /// `set_bit_timing`: BTR's mode bits kept, the rest from `btr & 0x037F_03FF`.
    pub fn set_bit_timing(&mut self, btr: u32) {
        self.modify(offset::BTR, |r| r & 0xC000_0000 | btr & 0x037F_03FF);
    }

    /// `set_automatic_retransmit(enabled)`: NART = !enabled.
    pub fn set_automatic_retransmit(&mut self, enabled: bool) {
        self.modify(offset::MCR, |r| if enabled { r & !mcr::NART } else { r | mcr::NART });
    }

    /// `set_loopback` / `set_silent`: LBKM / SILM in BTR.
    pub fn set_btr_mode(&mut self, bit: u32, enabled: bool) {
        self.modify(offset::BTR, |r| if enabled { r | bit } else { r & !bit });
    }

    /// `leave_disabled` (`leave_init_mode`): SLEEP = 1, INRQ = 0, wait for SLAK = 1, INAK = 0.
    pub fn leave_disabled(&mut self) {
        self.modify(offset::MCR, |r| (r | mcr::SLEEP) & !mcr::INRQ);
        self.poll_msr(|msr| msr & msr::SLAK != 0 && msr & msr::INAK == 0);
    }

    /// `enable_non_blocking`: with SLAK set, ABOM = 1 and SLEEP = 0, WouldBlock; else Ok.
    pub fn enable_non_blocking(&mut self) -> Nb<(), ()> {
        if self.read(offset::MSR) & msr::SLAK != 0 {
            self.modify(offset::MCR, |r| (r | mcr::ABOM) & !mcr::SLEEP);
            Nb::WouldBlock
        } else {
            Nb::Ok(())
        }
    }

    /// `CanBuilder::enable`: leave initialisation, then `nb::block!(enable_non_blocking())`.
    pub fn enable(&mut self) {
        self.leave_disabled();
        for _ in 0..1000 {
            if self.enable_non_blocking() == Nb::Ok(()) {
                return;
            }
        }
        panic!("enable never returned");
    }

    /// `Can::modify_filters`: FINIT = 1, CAN2SB read.
    pub fn modify_filters(&mut self) -> u32 {
        self.modify(offset::FMR, |r| r | filter::FINIT);
        (self.read(offset::FMR) >> 8) & 0x3F
    }

    /// `MasterFilters::enable_bank(index, fifo, [a, b])` with two `Mask16`: mask mode, 16-bit
    /// scale, FR1 = a.mask << 16 | a.id, FR2 likewise, the FIFO, then active.
    pub fn enable_bank_mask16(&mut self, index: u32, fifo1: bool, [a, b]: [Mask16; 2]) {
        let bit = 1 << index;
        self.modify(filter::offset::FM1R, |r| r & !bit);
        self.modify(filter::offset::FS1R, |r| r & !bit);
        let fr1 = filter::offset::F0R1 + 8 * index;
        self.write(fr1, u32::from(a.mask) << 16 | u32::from(a.id));
        self.write(fr1 + 4, u32::from(b.mask) << 16 | u32::from(b.id));
        self.modify(filter::offset::FFA1R, |r| if fifo1 { r | bit } else { r & !bit });
        self.modify(filter::offset::FA1R, |r| r | bit);
    }

    /// `MasterFilters` dropped: FINIT = 0.
    pub fn drop_filters(&mut self) {
        self.modify(offset::FMR, |r| r & !filter::FINIT);
    }

    /// `Can::enable_interrupts(bits)`: IER |= bits.
    pub fn enable_interrupts(&mut self, bits: u32) {
        self.modify(offset::IER, |r| r | bits);
    }

    /// The firmware's set-up (slave-fw/firmware/src/can_bxcan.rs `Bxcan::new` with MAC 5,
    /// board::filters): builder, 125k timing, automatic retransmission, leave_disabled, the two
    /// filter banks, the interrupts, `enable_can_error_interrupts`, `enable_non_blocking`.
    pub fn firmware_setup(&mut self) {
        self.builder();
        self.set_bit_timing(BTR_125K_AT_42MHZ);
        self.set_automatic_retransmit(true);
        self.leave_disabled();
        self.modify_filters();
        let own = Mask16::frames_with_std_id(0x428, 0x7F8);
        let strobe = Mask16::frames_with_std_id(0x400, 0x607);
        let offline = Mask16::frames_with_std_id(0x7ED, 0x7FD).data_frames_only();
        self.enable_bank_mask16(0, false, [own, strobe]);
        self.enable_bank_mask16(1, false, [offline, offline]);
        self.drop_filters();
        self.enable_interrupts(ier::TMEIE | ier::FMPIE0 | ier::FMPIE0 << 3 | ier::ERRIE);
        self.modify(offset::IER, |r| r | ier::ERRIE | ier::BOFIE | ier::EPVIE);
        let _ = self.enable_non_blocking();
    }

    /// `Tx::transmit`: the mailbox CODE names, after checking that no pending mailbox holds a
    /// frame of higher or equal priority (WouldBlock then); with all three pending, the lowest
    /// one is aborted and its frame returned. Returns the mailbox used and the dequeued frame.
    pub fn transmit(&mut self, frame: &Frame) -> Nb<(usize, Option<Frame>), ()> {
        let tsr = self.read(offset::TSR);
        let idx = ((tsr >> 24) & 3) as usize;
        let tme = (tsr >> 26) & 0b111;
        let mut dequeued = None;
        if tme != 0b111 {
            for m in 0..3u32 {
                let tir = self.read(offset::TI0R + 0x10 * m);
                if tir & 1 != 0 && !id_reg_gt(frame.id_register(), tir & !1) {
                    return Nb::WouldBlock;
                }
            }
            if tme == 0 {
                dequeued = self.abort_and_read(idx);
            }
        }
        let base = offset::TI0R + 0x10 * idx as u32;
        let [low, high] = frame.data_registers();
        self.write(base + 4, u32::from(frame.dlc()));
        self.write(base + 8, low);
        self.write(base + 12, high);
        self.write(base, frame.id_register() | 1);
        Nb::Ok((idx, dequeued))
    }

    /// `read_pending_mailbox`: ABRQ written, wait for it to clear, then the frame if TXOK = 0.
    fn abort_and_read(&mut self, idx: usize) -> Option<Frame> {
        let abrq = 0x80 << (8 * idx);
        self.write(offset::TSR, abrq);
        let mut tsr = self.read(offset::TSR);
        for _ in 0..1000 {
            if tsr & abrq == 0 {
                break;
            }
            tsr = self.read(offset::TSR);
        }
        assert_eq!(tsr & abrq, 0, "ABRQ never cleared");
        if tsr & (0x02 << (8 * idx)) != 0 {
            return None;
        }
        let base = offset::TI0R + 0x10 * idx as u32;
        let (tir, tdtr) = (self.read(base), self.read(base + 4));
        let (low, high) = (self.read(base + 8), self.read(base + 12));
        Some(Frame::from_registers(tir, tdtr, low, high))
    }

    /// `is_transmitter_idle`: TME0, TME1 and TME2 all set.
    pub fn is_transmitter_idle(&mut self) -> bool {
        self.read(offset::TSR) >> 26 & 0b111 == 0b111
    }

    /// `clear_tx_interrupt`: while an RQCPx is set, `tsr.modify(|_, w| w.rqcpx().set_bit())`
    /// (svd2rust's modify writes back what it read, with RQCPx set).
    pub fn clear_tx_interrupt(&mut self) {
        for _ in 0..10 {
            let tsr = self.read(offset::TSR);
            let Some(m) = (0..3).find(|m| tsr & (1 << (8 * m)) != 0) else { return };
            self.write(offset::TSR, tsr | 1 << (8 * m));
        }
        panic!("RQCP never cleared");
    }

    /// `Can::receive`: FIFO 0, then FIFO 1 (`receive_fifo`).
    pub fn receive(&mut self) -> Nb<Frame, Overrun> {
        match self.receive_fifo(0) {
            Nb::WouldBlock => self.receive_fifo(1),
            other => other,
        }
    }

    /// `receive_fifo`: FMP = 0 WouldBlock; FOVR set: FOVR written (cleared), Overrun; else the
    /// output mailbox read and released (`rfr.write(|w| w.rfom().set_bit())`).
    pub fn receive_fifo(&mut self, fifo: u32) -> Nb<Frame, Overrun> {
        let rfr_offset = offset::RF0R + 4 * fifo;
        let rfr = self.read(rfr_offset);
        if rfr & 0b11 == 0 {
            return Nb::WouldBlock;
        }
        if rfr & mailbox::rfr::FOVR != 0 {
            self.write(rfr_offset, mailbox::rfr::FOVR);
            return Nb::Other(Overrun);
        }
        let base = offset::RI0R + 0x10 * fifo;
        let rir = self.read(base);
        let low = self.read(base + 8);
        let high = self.read(base + 12);
        let rdtr = self.read(base + 4);
        self.write(rfr_offset, mailbox::rfr::RFOM);
        Nb::Ok(Frame::from_registers(rir, rdtr, low, high))
    }

    /// board::hw::can_bus_state: ESR read, ERRI cleared by `msr.write(|w| w.erri().set_bit())`
    /// (the PAC's MSR reset value 0x0000_0C02 with ERRI).
    pub fn can_bus_state(&mut self) -> u32 {
        let esr = self.read(offset::ESR);
        self.write(offset::MSR, 0x0000_0C02 | msr::ERRI);
        esr
    }

    /// A frame from another node at `rate`, delivered whole; the controller's response.
    pub fn hear(&mut self, frame: &Frame, rate: u32) -> Response {
        self.can.on_wire(frame, rate, false, self.m.now, &mut self.m)
    }

    /// The controller's next frame, sent with `outcome`.
    pub fn send(&mut self, outcome: TxOutcome) -> Option<Transmission> {
        let tx = self.can.poll_transmit(self.m.now, &mut self.m)?;
        self.can.transmit_outcome(outcome, self.m.now, &mut self.m);
        Some(tx)
    }

    /// Moves time on by `nanos` and advances the model.
    pub fn wait(&mut self, nanos: Nanos) {
        self.m.now += nanos;
        let now = self.m.now;
        self.can.advance(now, &mut self.m);
    }

    /// CAN_ESR's TEC and REC.
    pub fn counters(&mut self) -> (u32, u32) {
        let esr = self.read(offset::ESR);
        ((esr >> 16) & 0xFF, esr >> 24)
    }
}

/// bxcan 0.8's `IdReg` order (`Ord for IdReg`): `a > b` when `a` has the higher priority
/// (lower identifier; data before remote; standard before extended of the same base).
fn id_reg_gt(a: u32, b: u32) -> bool {
    let fa = Frame::from_registers(a, 0, 0, 0);
    let fb = Frame::from_registers(b, 0, 0, 0);
    fa.arbitration_key() < fb.arbitration_key()
}

/// A standard data frame.
pub(super) fn data(id: u16, bytes: &[u8]) -> Frame {
    Frame::new_data(FrameId::standard(id).unwrap(), bytes).unwrap()
}
