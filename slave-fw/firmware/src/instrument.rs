//! The instrument port: the board's instrument USART (through its RS-485 or RS-232 transceiver,
//! `board::hw::Rs485`) with its transmit queue, shared by the converter task and the USART's
//! interrupt.
//!
//! Received bytes go from the interrupt to the converter task's input queue; the frames the serial
//! profile returns from `Converter::poll_serial_transmit` are queued here whole and leave from the
//! interrupt, which holds the RS-485 driver on until the last stop bit is out.
//!
//! Line events for the serial-line analyzer (`slave_fw::serial::trace`): a character the USART
//! dropped for a framing, parity or overrun error goes to the interrupt's callback in its place
//! among the received bytes ([`Received::Event`]); the RS-485 driver's edges, which happen both
//! in `send` (the converter task) and in the interrupt, wait in a queue of [`LINE_EVENTS`] that
//! the interrupt hands over ([`InstrumentPort::take_event`]). What does not fit is counted
//! ([`InstrumentPort::events_lost`]). A character with noise only (NF) is dropped as before and
//! not reported: the analyzer has no kind for it.

use board::hw::{Rs485, SerialEvent, UartError};
use heapless::Deque;
use slave_fw::serial::modbus::WIRE_CAPACITY;
use slave_fw::serial::trace::TraceKind;
use slave_fw::serial::FRAME_CAPACITY;

/// Driver edges that may wait for the interrupt to hand them to the converter task: a frame
/// makes two, and a new frame is only sent after the last one's answer.
pub const LINE_EVENTS: usize = 8;

/// What the USART's interrupt passes on from the receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Received {
    /// A byte from the instrument.
    Byte(u8),
    /// A line event: a dropped character's error, or a driver edge.
    Event(TraceKind),
}

/// Bytes that may wait for the transmitter: the longest frame either profile sends (for Modbus,
/// an ASCII frame). A profile has one frame in flight at a time (a command awaiting its
/// acknowledgement, a Modbus request awaiting its response), so one frame's room is enough.
pub const SERIAL_TX_LEN: usize = if FRAME_CAPACITY > WIRE_CAPACITY { FRAME_CAPACITY } else { WIRE_CAPACITY };

/// The instrument's USART and its transmit queue.
pub struct InstrumentPort {
    rs485: Rs485,
    tx: Deque<u8, SERIAL_TX_LEN>,
    sending: bool,
    dropped: u32,
    /// Whether the RS-485 driver is enabled (always false on RS-232: no edges to report).
    driving: bool,
    events: Deque<TraceKind, LINE_EVENTS>,
    events_lost: u32,
}

impl InstrumentPort {
    /// The port, receive interrupt on.
    pub fn new(mut rs485: Rs485) -> Self {
        rs485.listen(SerialEvent::RxNotEmpty);
        InstrumentPort {
            rs485,
            tx: Deque::new(),
            sending: false,
            dropped: 0,
            driving: false,
            events: Deque::new(),
            events_lost: 0,
        }
    }

    /// Queues a frame and starts sending at once. A frame that does not fit behind the bytes
    /// still queued is dropped whole (counted in [`InstrumentPort::dropped`]): half a frame would
    /// only confuse the instrument, and the profile retries a frame that gets no answer.
    pub fn send(&mut self, frame: &[u8]) {
        if self.tx.capacity() - self.tx.len() < frame.len() {
            self.dropped = self.dropped.wrapping_add(1);
            return;
        }
        for &b in frame {
            // Room was checked above.
            let _ = self.tx.push_back(b);
        }
        self.sending = !self.tx.is_empty();
        self.pump();
    }

    /// Frames dropped because the queue was full.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }

    /// Line events lost because a queue was full (this port's, or the converter task's input
    /// queue, counted through [`InstrumentPort::count_lost_event`]).
    pub fn events_lost(&self) -> u32 {
        self.events_lost
    }

    /// Counts a line event the caller could not queue.
    pub fn count_lost_event(&mut self) {
        self.events_lost = self.events_lost.wrapping_add(1);
    }

    /// The oldest driver edge waiting to be handed over.
    pub fn take_event(&mut self) -> Option<TraceKind> {
        self.events.pop_front()
    }

    /// The USART's interrupt: received bytes and the errors of dropped characters go to
    /// `received` in the order they came; the transmitter is refilled, and the RS-485 driver
    /// released after the last byte (its edges queued for [`InstrumentPort::take_event`]).
    pub fn on_interrupt(&mut self, mut received: impl FnMut(Received)) {
        while let Some(r) = self.rs485.read() {
            received(match r {
                Ok(b) => Received::Byte(b),
                Err(UartError::Framing) => Received::Event(TraceKind::UartFraming),
                Err(UartError::Parity) => Received::Event(TraceKind::UartParity),
                Err(UartError::Overrun) => Received::Event(TraceKind::UartOverrun),
                Err(UartError::Noise) => continue,
            });
        }
        self.pump();
    }

    /// Queues a driver edge, or counts it when the queue is full.
    fn edge(&mut self, kind: TraceKind) {
        if self.events.push_back(kind).is_err() {
            self.count_lost_event();
        }
    }

    /// Moves queued bytes into the transmitter while it takes them, then waits for room (TXE
    /// interrupt) or for the last stop bit (TC interrupt) and releases the RS-485 driver.
    ///
    /// Called from `send` too rather than left to the TXE interrupt: the first bytes leave
    /// without an interrupt's delay, and QEMU's USART model raises no interrupt when TXEIE is set
    /// while the transmitter is empty (it does on the chip), so the emulated board would
    /// otherwise send only when a byte is received.
    fn pump(&mut self) {
        if !self.sending {
            return;
        }
        if !self.driving && self.rs485.has_driver_enable() {
            // try_write enables the driver.
            self.driving = true;
            self.edge(TraceKind::DriverOn);
        }
        while let Some(&b) = self.tx.front() {
            if !self.rs485.try_write(b) {
                self.rs485.listen(SerialEvent::TxEmpty);
                return;
            }
            self.tx.pop_front();
        }
        self.rs485.unlisten(SerialEvent::TxEmpty);
        if self.rs485.is_transmission_complete() {
            self.rs485.release_driver();
            if self.driving {
                self.driving = false;
                self.edge(TraceKind::DriverOff);
            }
            self.rs485.unlisten(SerialEvent::TransmissionComplete);
            self.sending = false;
        } else {
            self.rs485.listen(SerialEvent::TransmissionComplete);
        }
    }
}
