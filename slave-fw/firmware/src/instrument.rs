//! The instrument side: what the converter library (`slave-fw`, serial profiles) will plug into.
//!
//! Until it lands, [`ReferenceInstrument`] stands in: it keeps the reference input image
//! (`devicenet::reference::INPUT_IMAGE`), ignores output data and serial bytes, and never sends.
//! The USART2/RS-485 plumbing ([`InstrumentPort`]) is complete: received bytes reach
//! [`Instrument::on_serial_byte`] from the interrupt through the node task's channel, and bytes
//! from [`Instrument::poll_serial`] leave through an interrupt-driven queue that holds the RS-485
//! driver on until the last stop bit is out.

use board::hw::{Rs485, SerialEvent};
use devicenet::slave::ApplicationStatus;
use devicenet::Instant;
use heapless::Deque;

/// Bytes that may wait for the instrument's transmitter.
pub const SERIAL_TX_LEN: usize = 64;

/// The converter's instrument side, as the node task drives it.
pub trait Instrument {
    /// A byte arrived from the instrument.
    fn on_serial_byte(&mut self, byte: u8, now: Instant);
    /// The master sent output data (poll command or Assembly set); `idle` for a zero-length
    /// poll.
    fn on_output(&mut self, data: &[u8], idle: bool, now: Instant);
    /// Bytes to send to the instrument now, appended to `out`.
    fn poll_serial(&mut self, now: Instant, out: &mut Deque<u8, SERIAL_TX_LEN>);
    /// The input image every poll is answered with.
    fn input_image(&self) -> &[u8];
    /// Status flags for the Identity object and the Module Status LED.
    fn status(&self) -> ApplicationStatus;
    /// When the instrument side wants to be called again.
    fn poll_at(&self) -> Option<Instant>;
}

/// The placeholder: the reference device's fixed input image.
pub struct ReferenceInstrument {
    image: [u8; devicenet::reference::INPUT_IMAGE.len()],
}

impl ReferenceInstrument {
    /// The reference image (breaker "open": byte 9 = 0x0F).
    pub const fn new() -> Self {
        ReferenceInstrument { image: devicenet::reference::INPUT_IMAGE }
    }
}

impl Instrument for ReferenceInstrument {
    fn on_serial_byte(&mut self, _byte: u8, _now: Instant) {}

    fn on_output(&mut self, _data: &[u8], _idle: bool, _now: Instant) {}

    fn poll_serial(&mut self, _now: Instant, _out: &mut Deque<u8, SERIAL_TX_LEN>) {}

    fn input_image(&self) -> &[u8] {
        &self.image
    }

    fn status(&self) -> ApplicationStatus {
        ApplicationStatus { configured: true, ..ApplicationStatus::default() }
    }

    fn poll_at(&self) -> Option<Instant> {
        None
    }
}

/// USART2 with its transmit queue, shared by the node task and the USART2 interrupt.
pub struct InstrumentPort {
    rs485: Rs485,
    tx: Deque<u8, SERIAL_TX_LEN>,
    sending: bool,
}

impl InstrumentPort {
    /// The port, receive interrupt on.
    pub fn new(mut rs485: Rs485) -> Self {
        rs485.listen(SerialEvent::RxNotEmpty);
        InstrumentPort { rs485, tx: Deque::new(), sending: false }
    }

    /// Queues bytes (from [`Instrument::poll_serial`]) and starts sending.
    pub fn send(&mut self, bytes: &mut Deque<u8, SERIAL_TX_LEN>) {
        while let Some(b) = bytes.pop_front() {
            if self.tx.push_back(b).is_err() {
                break;
            }
        }
        if !self.tx.is_empty() {
            self.sending = true;
            self.rs485.listen(SerialEvent::TxEmpty);
        }
    }

    /// The USART2 interrupt: received bytes go to `received`; the transmitter is refilled, and
    /// the RS-485 driver released after the last byte.
    pub fn on_interrupt(&mut self, mut received: impl FnMut(u8)) {
        while let Some(b) = self.rs485.read() {
            received(b);
        }
        if !self.sending {
            return;
        }
        while let Some(&b) = self.tx.front() {
            if !self.rs485.try_write(b) {
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
