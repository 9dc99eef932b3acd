//! The CAN driver interface shared by the bxCAN driver (real board) and the SLCAN driver
//! (emulated board), and the transmit queue in front of it.
//!
//! The node task hands frames to [`CanPort::send`]; the driver takes one when it can
//! ([`CanDriver::try_transmit`]), and the transmit-complete interrupt (or, for SLCAN, the host
//! opening the channel) calls [`CanPort::pump`] for the next. Receive interrupts drain
//! [`CanPort::receive`] into the converter task's input queue.

use board::hw::BusState;
use devicenet::{CanFrame, MacId};
use heapless::Deque;

/// Frames waiting for the controller.
pub const TX_QUEUE_LEN: usize = 32;

/// The controller cannot take a frame now; it will interrupt when it can.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Busy;

/// What the firmware needs from a CAN controller.
pub trait CanDriver {
    /// Starts sending `frame`, or [`Busy`]. Frames must leave in the order they are given.
    fn try_transmit(&mut self, frame: &CanFrame) -> Result<(), Busy>;
    /// The next received DeviceNet frame that passed the acceptance filter, if any.
    fn receive(&mut self) -> Option<CanFrame>;
    /// The controller's error state (also acknowledges its error interrupt).
    fn bus_state(&mut self) -> BusState;
    /// Acknowledges the transmit interrupt.
    fn clear_transmit_interrupt(&mut self);
    /// Resets the controller after bus-off (bus-off interrupt setting = 1) and rejoins the bus.
    fn restart(&mut self);
    /// Receives for MAC ID `mac` from now on (a MAC ID taken through the Offline Connection Set).
    fn set_mac(&mut self, mac: MacId);
}

/// A driver with its transmit queue.
pub struct CanPort<D> {
    driver: D,
    queue: Deque<CanFrame, TX_QUEUE_LEN>,
    dropped: u32,
}

impl<D: CanDriver> CanPort<D> {
    /// An empty queue in front of `driver`.
    pub fn new(driver: D) -> Self {
        CanPort { driver, queue: Deque::new(), dropped: 0 }
    }

    /// Queues `frame` and starts the transmitter if it is idle. A full queue drops the frame
    /// (counted in [`CanPort::dropped`]).
    pub fn send(&mut self, frame: CanFrame) {
        if self.queue.push_back(frame).is_err() {
            self.dropped = self.dropped.wrapping_add(1);
        }
        self.pump();
    }

    /// Hands queued frames to the driver until it is busy.
    pub fn pump(&mut self) {
        while let Some(frame) = self.queue.front() {
            if self.driver.try_transmit(frame).is_err() {
                break;
            }
            self.queue.pop_front();
        }
    }

    /// The transmit-complete interrupt: acknowledge it and send the next frame.
    pub fn on_transmit_interrupt(&mut self) {
        self.driver.clear_transmit_interrupt();
        self.pump();
    }

    /// The next received frame.
    pub fn receive(&mut self) -> Option<CanFrame> {
        self.driver.receive()
    }

    /// The controller's error state.
    pub fn bus_state(&mut self) -> BusState {
        self.driver.bus_state()
    }

    /// Receives for MAC ID `mac` from now on.
    pub fn set_mac(&mut self, mac: MacId) {
        self.driver.set_mac(mac);
    }

    /// Drops the queue and resets the controller (bus-off recovery).
    pub fn restart(&mut self) {
        self.queue.clear();
        self.driver.restart();
    }

    /// Frames dropped because the queue was full.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }
}
