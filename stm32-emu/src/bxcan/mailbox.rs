//! The three transmit mailboxes with `CAN_TSR` (RM0090 §32.7.1 "Transmission handling", §32.9.2
//! `CAN_TSR`, §32.9.3 `CAN_TIxR`, `CAN_TDTxR`, `CAN_TDLxR`, `CAN_TDHxR`) and the two receive
//! FIFOs of three messages with `CAN_RFxR` (RM0090 §32.7.3 "Reception handling", §32.7.5
//! "Message storage", §32.9.2 `CAN_RF0R`/`CAN_RF1R`, §32.9.3 `CAN_RIxR`, `CAN_RDTxR`,
//! `CAN_RDLxR`, `CAN_RDHxR`).

use super::frame::Frame;

/// TXRQ in `CAN_TIxR`: transmission requested (RM0090 §32.9.3).
pub(crate) const TXRQ: u32 = 1;
/// Per-mailbox `CAN_TSR` bits, shifted by 8 × mailbox (RM0090 §32.9.2).
pub mod tsr {
    /// Request completed.
    pub const RQCP: u32 = 1 << 0;
    /// Transmission OK.
    pub const TXOK: u32 = 1 << 1;
    /// Arbitration lost.
    pub const ALST: u32 = 1 << 2;
    /// Transmission error.
    pub const TERR: u32 = 1 << 3;
    /// Abort request.
    pub const ABRQ: u32 = 1 << 7;
    /// TME0; TME1 and TME2 follow.
    pub const TME0: u32 = 1 << 26;
    /// LOW0; LOW1 and LOW2 follow.
    pub const LOW0: u32 = 1 << 29;
    /// `CODE[1:0]` at bits 25:24.
    pub const CODE_SHIFT: u32 = 24;
}
/// The writable bits of `CAN_TDTxR`: DLC[3:0] and TGT (bit 8). TIME[15:0] is the time stamp of
/// time-triggered mode, which the model does not emulate: it reads 0.
const TDTR_BITS: u32 = 0x0000_010F;

/// Why a transmission attempt failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Failure {
    /// Lost arbitration (ALST).
    ArbitrationLost,
    /// An error (TERR).
    Error,
}

/// One transmit mailbox: its four registers and when its request was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct TxMailbox {
    tir: u32,
    tdtr: u32,
    data: [u32; 2],
    requested: u64,
}

/// The transmit mailboxes and their status (`CAN_TSR`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Transmitter {
    boxes: [TxMailbox; 3],
    /// RQCP, TXOK, ALST, TERR and ABRQ of every mailbox, in `CAN_TSR` positions.
    status: u32,
    /// The mailbox whose frame is on the wire (between `poll_transmit` and its outcome).
    pub(crate) in_flight: Option<usize>,
    requests: u64,
}

impl Transmitter {
    /// Whether mailbox `m` holds a request (TXRQ set, TME clear).
    pub(crate) fn is_pending(&self, m: usize) -> bool {
        self.boxes[m].tir & TXRQ != 0
    }

    /// The frame in mailbox `m`.
    pub(crate) fn frame(&self, m: usize) -> Frame {
        let b = &self.boxes[m];
        Frame::from_registers(b.tir, b.tdtr, b.data[0], b.data[1])
    }

    /// The pending mailbox the controller sends first (RM0090 §32.7.1 "Transmit priority"):
    /// by identifier with TXFP = 0 (the lowest identifier, [`Frame::arbitration_key`]; equal
    /// identifiers go by the lower mailbox number), by request order with TXFP = 1.
    pub(crate) fn highest_priority(&self, by_request_order: bool) -> Option<usize> {
        (0..3).filter(|&m| self.is_pending(m)).min_by_key(|&m| self.priority_key(m, by_request_order))
    }

    fn priority_key(&self, m: usize, by_request_order: bool) -> (u64, usize) {
        if by_request_order {
            (self.boxes[m].requested, m)
        } else {
            (u64::from(self.frame(m).arbitration_key()), m)
        }
    }

    /// `CAN_TSR` (RM0090 §32.9.2): the status bits, CODE (the lowest empty mailbox, or with all
    /// three pending the one of lowest priority), TME0..2 and LOW0..2 (set for the mailbox of
    /// lowest priority when more than one is pending).
    pub(crate) fn tsr(&self, by_request_order: bool) -> u32 {
        let mut pending = 0;
        let mut lowest: Option<usize> = None;
        for m in (0..3).filter(|&m| self.is_pending(m)) {
            pending += 1;
            let key = self.priority_key(m, by_request_order);
            if lowest.is_none_or(|l| key > self.priority_key(l, by_request_order)) {
                lowest = Some(m);
            }
        }
        let empty = (0..3).find(|&m| !self.is_pending(m));
        let code = empty.or(lowest).unwrap_or(0) as u32;
        let mut value = self.status | (code << tsr::CODE_SHIFT);
        for m in (0..3).filter(|&m| !self.is_pending(m)) {
            value |= tsr::TME0 << m;
        }
        if let (true, Some(m)) = (pending > 1, lowest) {
            value |= tsr::LOW0 << m;
        }
        value
    }

    /// A write to `CAN_TSR`: RQCPx is cleared by writing 1, which also clears TXOKx, ALSTx and
    /// TERRx; ABRQx set by software aborts a pending request (no effect on an empty mailbox).
    /// A mailbox on the wire is aborted only if its attempt fails (RM0090 §32.7.1 "Abort").
    pub(crate) fn write_tsr(&mut self, value: u32) {
        for m in 0..3 {
            let shift = 8 * m as u32;
            if value & (tsr::RQCP << shift) != 0 {
                self.status &= !((tsr::RQCP | tsr::TXOK | tsr::ALST | tsr::TERR) << shift);
            }
            if value & (tsr::ABRQ << shift) != 0 && self.is_pending(m) {
                if self.in_flight == Some(m) {
                    self.status |= tsr::ABRQ << shift;
                } else {
                    self.complete(m, false);
                }
            }
        }
    }

    /// Reads mailbox register `reg` (0 `TIxR`, 1 `TDTxR`, 2 `TDLxR`, 3 `TDHxR`) of mailbox `m`.
    pub(crate) fn read(&self, m: usize, reg: usize) -> u32 {
        let b = &self.boxes[m];
        match reg {
            0 => b.tir,
            1 => b.tdtr,
            2 => b.data[0],
            _ => b.data[1],
        }
    }

    /// Writes mailbox register `reg` of mailbox `m`. A mailbox is written only while empty
    /// (RM0090 §32.9.1 "Register access protection"); setting TXRQ makes it pending and clears
    /// its RQCP, TXOK, ALST and TERR (RM0090 §32.9.2).
    pub(crate) fn write(&mut self, m: usize, reg: usize, value: u32) {
        if self.is_pending(m) {
            return;
        }
        let b = &mut self.boxes[m];
        match reg {
            0 => {
                b.tir = value;
                if value & TXRQ != 0 {
                    self.requests += 1;
                    b.requested = self.requests;
                    self.status &= !((tsr::RQCP | tsr::TXOK | tsr::ALST | tsr::TERR) << (8 * m));
                }
            }
            1 => b.tdtr = value & TDTR_BITS,
            2 => b.data[0] = value,
            _ => b.data[1] = value,
        }
    }

    /// Ends mailbox `m`'s request: empty, RQCP set, TXOK as given, ABRQ cleared.
    pub(crate) fn complete(&mut self, m: usize, ok: bool) {
        let shift = 8 * m as u32;
        self.boxes[m].tir &= !TXRQ;
        self.status &= !((tsr::TXOK | tsr::ABRQ) << shift);
        self.status |= tsr::RQCP << shift;
        if ok {
            self.status &= !((tsr::ALST | tsr::TERR) << shift);
            self.status |= tsr::TXOK << shift;
        }
        if self.in_flight == Some(m) {
            self.in_flight = None;
        }
    }

    /// A failed attempt of mailbox `m`: TXOK cleared, ALST or TERR set. The request ends
    /// (RQCP) with `one_shot` (NART, RM0090 §32.7.1 "Non automatic retransmission mode") or
    /// when an abort was requested meanwhile; otherwise it stays pending for a retry.
    pub(crate) fn fail(&mut self, m: usize, failure: Failure, one_shot: bool) {
        let shift = 8 * m as u32;
        let flag = match failure {
            Failure::ArbitrationLost => tsr::ALST,
            Failure::Error => tsr::TERR,
        };
        self.status &= !((tsr::TXOK | tsr::ALST | tsr::TERR) << shift);
        self.status |= flag << shift;
        let aborted = self.status & (tsr::ABRQ << shift) != 0;
        if one_shot || aborted {
            self.complete(m, false);
            self.status |= flag << shift;
        }
        if self.in_flight == Some(m) {
            self.in_flight = None;
        }
    }

    /// Whether any RQCP is set: the transmit interrupt's source (RM0090 §32.8).
    pub(crate) fn request_completed(&self) -> bool {
        self.status & (tsr::RQCP * 0x0001_0101) != 0
    }
}

/// One received message as its FIFO's output mailbox shows it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct RxMessage {
    rir: u32,
    rdtr: u32,
    data: [u32; 2],
}

/// `CAN_RFxR` bits (RM0090 §32.9.2).
pub mod rfr {
    /// FULL: three messages stored (rc_w1).
    pub const FULL: u32 = 1 << 3;
    /// FOVR: a message passed the filter while the FIFO was full (rc_w1).
    pub const FOVR: u32 = 1 << 4;
    /// RFOM: release the output mailbox (set by software).
    pub const RFOM: u32 = 1 << 5;
}

/// One receive FIFO of three messages.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct RxFifo {
    messages: [RxMessage; 3],
    len: usize,
    full: bool,
    overrun: bool,
    /// What the output mailbox shows when the FIFO is empty: the last message released (the
    /// registers keep their contents; no source says what an empty FIFO's mailbox reads).
    last: RxMessage,
}

impl RxFifo {
    /// The number of messages pending (FMP).
    pub(crate) fn pending(&self) -> usize {
        self.len
    }

    /// FULL.
    pub(crate) fn full(&self) -> bool {
        self.full
    }

    /// FOVR.
    pub(crate) fn overrun(&self) -> bool {
        self.overrun
    }

    /// Stores a frame that passed filter `fmi`. A full FIFO sets FOVR and, with the FIFO not
    /// locked (RFLM = 0), the new message replaces the last one stored; locked (RFLM = 1), the
    /// new message is discarded (RM0090 §32.7.5 "Overrun").
    pub(crate) fn store(&mut self, frame: &Frame, fmi: u8, locked: bool) {
        let [low, high] = frame.data_registers();
        let message = RxMessage {
            rir: frame.id_register(),
            rdtr: u32::from(frame.dlc()) | (u32::from(fmi) << 8),
            data: [low, high],
        };
        if self.len < 3 {
            self.messages[self.len] = message;
            self.len += 1;
            self.full |= self.len == 3;
        } else {
            self.overrun = true;
            if !locked {
                self.messages[2] = message;
            }
        }
    }

    /// `CAN_RFxR`: FMP[1:0], FULL, FOVR; RFOM reads 0 (the release is immediate).
    pub(crate) fn rfr(&self) -> u32 {
        let mut value = self.len as u32;
        if self.full {
            value |= rfr::FULL;
        }
        if self.overrun {
            value |= rfr::FOVR;
        }
        value
    }

    /// A write to `CAN_RFxR`: FULL and FOVR cleared by writing 1; RFOM releases the output
    /// mailbox when a message is pending (no effect on an empty FIFO).
    pub(crate) fn write_rfr(&mut self, value: u32) {
        if value & rfr::FULL != 0 {
            self.full = false;
        }
        if value & rfr::FOVR != 0 {
            self.overrun = false;
        }
        if value & rfr::RFOM != 0 && self.len > 0 {
            self.last = self.messages[0];
            self.messages.rotate_left(1);
            self.len -= 1;
        }
    }

    /// Output mailbox register `reg` (0 `RIxR`, 1 `RDTxR`, 2 `RDLxR`, 3 `RDHxR`).
    pub(crate) fn read(&self, reg: usize) -> u32 {
        let m = if self.len > 0 { &self.messages[0] } else { &self.last };
        match reg {
            0 => m.rir,
            1 => m.rdtr,
            2 => m.data[0],
            _ => m.data[1],
        }
    }
}
