//! The bus side of the controller: what it puts on the wire, what it makes of what it sees, and
//! the error counting of RM0090 §32.7.6 "Error management" (after ISO 11898-1).
//!
//! ## Driving it (a CAN world, one frame at a time)
//!
//! 1. Ask every node for its frame: [`Bxcan::poll_transmit`] (the frame and the controller's
//!    bit rate). The frame with the lowest [`Frame::arbitration_key`] wins.
//! 2. Ask every other node how it reacts to a frame at the winner's bit rate:
//!    [`Bxcan::response`] (a node at another rate cannot decode it and, error active, flags
//!    it). A world's own nodes (a master, a test node) answer for themselves the same way: an
//!    error-active node at another rate than the winner's flags the frame.
//! 3. [`TxOutcome::from_responses`] settles the frame: one [`Response::ErrorFlag`] destroys it
//!    for everybody; otherwise it is acknowledged if some node answered
//!    [`Response::Acknowledge`]. Deliver it with [`Bxcan::on_wire`] to every other node,
//!    `disturbed` when destroyed; tell the winner the outcome ([`Bxcan::transmit_outcome`]) and
//!    every other sender [`TxOutcome::ArbitrationLost`] (it offers its frame again next time).
//! 4. Between frames, call `advance` with the time (the bus-off recovery runs on it);
//!    [`Bxcan::next_deadline`] says when it is next needed.
//!
//! A frame takes [`Frame::wire_bits`] bit times (plus stuff bits); the world keeps the time, the
//! model takes each frame whole at the `now` it is given.
//!
//! ## Error counting (the model's rules)
//!
//! - A transmit error counts TEC + 8; a successful transmission TEC − 1 (ISO 11898-1 rules 3, 7).
//! - The exception of ISO 11898-1 rule 3a is modelled: an error-passive transmitter that gets
//!   no acknowledgement (and sees no error flag) keeps its TEC. A lone node therefore stops at
//!   TEC = 128, error passive, and retries for ever; it never goes bus-off.
//! - A receive error counts REC + 1; a successful reception REC − 1, or 120 from above 127
//!   (RM0090 §32.9.2 `CAN_ESR`.REC). The counters saturate at 255 in the register.
//! - Error passive at a counter above 127 (EPVF), warning at 96 (EWGF), bus-off at TEC above 255
//!   (BOFF): the controller neither sends nor receives. It recovers (TEC = REC = 0) after 128
//!   occurrences of 11 recessive bits, 128 × 11 bit times of its own rate in the model, counted
//!   in normal mode only: from entering bus-off with ABOM, otherwise from the moment software
//!   leaves initialisation mode (RM0090 §32.7.6). Entering initialisation stops the count.
//! - LEC (RM0090 §32.9.2): 3 (acknowledgement error) for no ACK, 4 (bit recessive error: a
//!   recessive bit sent, a dominant one seen) for a transmission another node's error flag
//!   destroyed, 1 (stuff error) for a frame the controller could not decode or saw destroyed;
//!   0 after every frame sent or received without error.

use super::mailbox::Failure;
use super::{ier, mcr, msr, Bxcan, Mode};
use crate::periph::{Machine, Nanos};

pub use super::frame::Frame;

/// LEC codes (RM0090 §32.9.2).
mod lec {
    pub const NONE: u32 = 0;
    pub const STUFF: u32 = 1;
    pub const ACK: u32 = 3;
    pub const BIT_RECESSIVE: u32 = 4;
}

/// A frame the controller puts on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transmission {
    /// The frame.
    pub frame: Frame,
    /// The controller's nominal bit rate (RM0090 §32.7.7), bit/s.
    pub bit_rate: u32,
}

/// How the controller reacts to a frame another node sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Response {
    /// It receives the frame and sends the dominant ACK bit.
    Acknowledge,
    /// It puts nothing on the bus: asleep, in initialisation, bus-off, silent (RM0090 §32.5.1),
    /// in loop back (§32.5.2: CANRX disregarded), or error passive when it cannot decode the
    /// frame (its passive error flag is recessive).
    Quiet,
    /// It cannot decode the frame (another bit rate) and, error active, sends an active error
    /// flag that destroys the frame for every node.
    ErrorFlag,
}

/// What became of the frame [`Bxcan::poll_transmit`] offered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TxOutcome {
    /// Sent; at least one node acknowledged it.
    Acknowledged,
    /// Sent, but no node acknowledged it (alone on the bus, or no node at its bit rate).
    NoAcknowledge,
    /// Destroyed by another node's error flag.
    ErrorFlagged,
    /// Another node's frame won the arbitration.
    ArbitrationLost,
}

impl TxOutcome {
    /// The outcome of a frame from the responses of every other node (step 3 of the module
    /// docs), and whether the frame was destroyed (`disturbed` for [`Bxcan::on_wire`]).
    pub fn from_responses(responses: impl IntoIterator<Item = Response>) -> (TxOutcome, bool) {
        let mut acknowledged = false;
        for response in responses {
            match response {
                Response::ErrorFlag => return (TxOutcome::ErrorFlagged, true),
                Response::Acknowledge => acknowledged = true,
                Response::Quiet => {}
            }
        }
        let outcome = if acknowledged { TxOutcome::Acknowledged } else { TxOutcome::NoAcknowledge };
        (outcome, false)
    }
}

impl Bxcan {
    /// The nominal bit rate at the machine's PCLK1.
    fn bit_rate(&self, machine: &dyn Machine) -> u32 {
        self.bit_timing().bit_rate(machine.clocks().pclk1)
    }

    /// Whether the controller takes part in bus traffic now (normal mode, not bus-off).
    fn on_bus(&self) -> bool {
        self.mode == Mode::Normal && !self.bus_off
    }

    /// The frame the controller sends now, if any: the pending mailbox of highest priority, in
    /// normal mode, not bus-off, not silent. Until [`Bxcan::transmit_outcome`] the same frame
    /// is offered again, and an abort request for its mailbox waits (ABRQ stays set, as while a
    /// frame is on the wire): every frame offered must get its outcome. In silent loop back
    /// mode nothing reaches the wire (RM0090 §32.5.3).
    pub fn poll_transmit(&mut self, now: Nanos, machine: &mut dyn Machine) -> Option<Transmission> {
        self.sync(now, machine);
        self.run_internal();
        if !self.on_bus() || self.silent() {
            return None;
        }
        let by_order = self.mcr & mcr::TXFP != 0;
        let m = self.tx.in_flight.or_else(|| self.tx.highest_priority(by_order))?;
        self.tx.in_flight = Some(m);
        Some(Transmission { frame: self.tx.frame(m), bit_rate: self.bit_rate(machine) })
    }

    /// The outcome of the frame last offered by [`Bxcan::poll_transmit`]. In loop back mode
    /// an acknowledgement error is ignored (RM0090 §32.5.2) and the frame is received back.
    pub fn transmit_outcome(&mut self, outcome: TxOutcome, now: Nanos, machine: &mut dyn Machine) {
        self.sync(now, machine);
        let Some(m) = self.tx.in_flight else { return };
        let one_shot = self.mcr & mcr::NART != 0;
        let before = self.esr();
        let outcome = match outcome {
            TxOutcome::NoAcknowledge if self.loopback() => TxOutcome::Acknowledged,
            other => other,
        };
        match outcome {
            TxOutcome::Acknowledged => {
                let frame = self.tx.frame(m);
                self.tx.complete(m, true);
                self.tec = self.tec.saturating_sub(1);
                self.lec = lec::NONE;
                if self.loopback() && !self.loopback_broken {
                    self.receive(&frame);
                }
            }
            TxOutcome::NoAcknowledge => {
                self.set_lec(lec::ACK);
                if !self.error_passive() {
                    self.add_tec(8);
                }
                self.tx.fail(m, Failure::Error, one_shot);
            }
            TxOutcome::ErrorFlagged => {
                self.set_lec(lec::BIT_RECESSIVE);
                self.add_tec(8);
                self.tx.fail(m, Failure::Error, one_shot);
            }
            TxOutcome::ArbitrationLost => self.tx.fail(m, Failure::ArbitrationLost, one_shot),
        }
        self.note_error_flags(before);
        self.update_irqs(machine);
    }

    /// How the controller would react to a frame at `bus_bit_rate` now (no state changes).
    pub fn response(&self, bus_bit_rate: u32, machine: &dyn Machine) -> Response {
        if !self.on_bus() || self.loopback() {
            return Response::Quiet;
        }
        let follows = self.bit_timing().follows(machine.clocks().pclk1, bus_bit_rate);
        match (follows, self.silent()) {
            (_, true) => Response::Quiet,
            (true, false) => Response::Acknowledge,
            (false, false) if self.error_passive() => Response::Quiet,
            (false, false) => Response::ErrorFlag,
        }
    }

    /// A frame another node sent at `bus_bit_rate`, `disturbed` when some node's error flag
    /// destroyed it. Received when the controller is on the bus at a rate that follows the
    /// bus's and the frame is whole: it goes through the filters into a FIFO (nothing is stored
    /// while the filters are in FINIT mode). Otherwise, on the bus, it is a receive error. In
    /// sleep the start of frame sets WKUI and, with AWUM, wakes the controller (RM0090
    /// §32.4.3); that frame itself is lost. Returns the controller's [`Response`].
    pub fn on_wire(
        &mut self,
        frame: &Frame,
        bus_bit_rate: u32,
        disturbed: bool,
        now: Nanos,
        machine: &mut dyn Machine,
    ) -> Response {
        self.sync(now, machine);
        self.run_internal();
        let response = self.response(bus_bit_rate, machine);
        if self.mode == Mode::Sleep {
            self.msr_flags |= msr::WKUI;
            if self.mcr & mcr::AWUM != 0 {
                self.mcr &= !mcr::SLEEP;
                self.update_mode();
            }
        } else if self.on_bus() && !self.loopback() {
            let before = self.esr();
            if disturbed || !self.bit_timing().follows(machine.clocks().pclk1, bus_bit_rate) {
                self.set_lec(lec::STUFF);
                self.rec = (self.rec + 1).min(255);
            } else {
                self.rec = if self.rec > 127 { 120 } else { self.rec.saturating_sub(1) };
                self.lec = lec::NONE;
                self.receive(frame);
            }
            self.note_error_flags(before);
        }
        self.update_irqs(machine);
        response
    }

    /// When the model next needs `advance`: the end of the bus-off recovery, if one runs.
    pub fn next_deadline(&self) -> Option<Nanos> {
        let from = self.recovery_from?;
        Some(from.saturating_add(self.bit_timing().bits_to_nanos(128 * 11, self.pclk1)))
    }

    /// What happens inside the controller without the wire: the end of a bus-off recovery, and
    /// the transmissions of silent loop back mode (RM0090 §32.5.3), which complete at once (and
    /// are not received back when the loop back path is broken, [`Bxcan::set_loopback_broken`]).
    pub(super) fn run_internal(&mut self) {
        if let Some(deadline) = self.next_deadline() {
            if self.mode == Mode::Normal && self.now >= deadline {
                let before = self.esr();
                self.bus_off = false;
                self.tec = 0;
                self.rec = 0;
                self.recovery_from = None;
                self.recovery_requested = false;
                self.note_error_flags(before);
            }
        }
        if self.on_bus() && self.loopback() && self.silent() {
            let by_order = self.mcr & mcr::TXFP != 0;
            while let Some(m) = self.tx.highest_priority(by_order) {
                let frame = self.tx.frame(m);
                self.tx.complete(m, true);
                if !self.loopback_broken {
                    self.receive(&frame);
                }
            }
        }
    }

    /// A frame received whole: through the filters (unless in FINIT mode) into its FIFO.
    fn receive(&mut self, frame: &Frame) {
        if self.filters.in_init() {
            return;
        }
        let end = self.filters.can2_start_bank();
        if let Some(found) = self.filters.route(frame.id_register(), frame.filter16(), 0, end) {
            let locked = self.mcr & mcr::RFLM != 0;
            self.rx[found.fifo].store(frame, found.fmi, locked);
        }
    }

    /// Error passive: a counter above 127.
    fn error_passive(&self) -> bool {
        self.tec > 127 || self.rec > 127
    }

    fn add_tec(&mut self, n: u32) {
        self.tec += n;
        if self.tec > 255 && !self.bus_off {
            self.bus_off = true;
            self.recovery_requested = false;
            self.recovery_from = (self.mcr & mcr::ABOM != 0).then_some(self.now);
        }
    }

    /// LEC set by hardware on an error; with LECIE this raises ERRI (RM0090 §32.9.2).
    fn set_lec(&mut self, code: u32) {
        self.lec = code;
        if self.ier & ier::LECIE != 0 {
            self.msr_flags |= msr::ERRI;
        }
    }

    /// ERRI is set when an error flag of `CAN_ESR` is set and its interrupt enabled (EWGIE,
    /// EPVIE, BOFIE; RM0090 §32.9.2 `CAN_MSR`.ERRI). `before` is `CAN_ESR` before the event.
    fn note_error_flags(&mut self, before: u32) {
        let raised = self.esr() & !before & 0b111;
        let enabled = (self.ier >> 8) & 0b111;
        if raised & enabled != 0 {
            self.msr_flags |= msr::ERRI;
        }
    }
}
