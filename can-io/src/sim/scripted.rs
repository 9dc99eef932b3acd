//! Test equipment of the simulated bus's own tests: a device that sends a script of frames at
//! power-on and records what it receives and its bus-offs, and the helpers around it.

use super::SimDevice;
use crate::bus::{Bus, BusEvent};
use devicenet::{CanFrame, Instant, MacId};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

/// What a scripted device received, shared with the test.
pub(crate) type Log = Rc<RefCell<Vec<(Instant, CanFrame)>>>;
/// When a scripted device was told it went bus-off.
pub(crate) type BusOffs = Rc<RefCell<Vec<Instant>>>;

/// Sends its script at power-on, records what it receives and its bus-offs.
pub(crate) struct Scripted {
    mac: MacId,
    script: Vec<CanFrame>,
    queue: VecDeque<CanFrame>,
    received: Log,
    bus_offs: BusOffs,
}

impl SimDevice for Scripted {
    fn mac(&self) -> MacId {
        self.mac
    }
    fn power_on(&mut self, _now: Instant) {
        self.queue.extend(self.script.iter().copied());
    }
    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.received.borrow_mut().push((now, *frame));
    }
    fn handle_timeout(&mut self, _now: Instant) {}
    fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.queue.pop_front()
    }
    fn poll_at(&self) -> Option<Instant> {
        None
    }
    fn handle_bus_off(&mut self, now: Instant) {
        self.bus_offs.borrow_mut().push(now);
    }
}

/// A scripted device at `mac`, with what it will record.
pub(crate) fn scripted(mac: u8, script: Vec<CanFrame>) -> (Box<Scripted>, Log, BusOffs) {
    let received = Log::default();
    let bus_offs = BusOffs::default();
    let device = Scripted {
        mac: MacId::new(mac).unwrap(),
        script,
        queue: VecDeque::new(),
        received: Rc::clone(&received),
        bus_offs: Rc::clone(&bus_offs),
    };
    (Box::new(device), received, bus_offs)
}

/// A frame from a literal.
pub(crate) fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::from_raw(id, data).unwrap()
}

/// Every event of `bus` until `until`.
pub(crate) fn drain(bus: &mut dyn Bus, until: Instant) -> Vec<BusEvent> {
    std::iter::from_fn(|| bus.recv(until).unwrap()).collect()
}
