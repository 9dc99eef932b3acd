//! The instrument port: the board's instrument USART (through its RS-485 or RS-232 transceiver,
//! `board::hw::Rs485`) with its transmit queue, shared by the converter task and the USART's
//! interrupt.
//!
//! Received bytes go from the interrupt to the converter task's input queue; the frames the serial
//! profile returns from `Converter::poll_serial_transmit` are queued here whole and leave from the
//! interrupt, which holds the RS-485 driver on until the last stop bit is out.

use board::hw::{Rs485, SerialEvent};
use heapless::Deque;
use slave_fw::serial::modbus::WIRE_CAPACITY;
use slave_fw::serial::FRAME_CAPACITY;

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
}

impl InstrumentPort {
    /// The port, receive interrupt on.
    pub fn new(mut rs485: Rs485) -> Self {
        rs485.listen(SerialEvent::RxNotEmpty);
        InstrumentPort { rs485, tx: Deque::new(), sending: false, dropped: 0 }
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

    /// The USART's interrupt: received bytes go to `received`; the transmitter is refilled, and
    /// the RS-485 driver released after the last byte.
    pub fn on_interrupt(&mut self, mut received: impl FnMut(u8)) {
        while let Some(b) = self.rs485.read() {
            received(b);
        }
        self.pump();
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
            self.rs485.unlisten(SerialEvent::TransmissionComplete);
            self.sending = false;
        } else {
            self.rs485.listen(SerialEvent::TransmissionComplete);
        }
    }
}
