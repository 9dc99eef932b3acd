//! Fault confinement on the simulated bus: every node's error counters kept by the ISO 11898-1
//! rules ([`ErrorCounters`]) as the fault model's errors and the error-free frames come, and the
//! master's error state as [`Bus::error_state`](crate::bus::Bus::error_state) reports it.
//!
//! | on the wire | transmitter | every other node on the bus |
//! |---|---|---|
//! | a frame completes without error | TEC − 1 | REC − 1 |
//! | [`TxFate::Destroy`](super::fault::TxFate::Destroy) (an error frame) | TEC + 8 | REC + 1 |
//! | [`TxFate::Duplicate`](super::fault::TxFate::Duplicate) (error in the last bit of end of frame, seen by the transmitter only) | TEC + 8 | REC − 1 (accepted) |
//! | [`TxFate::BusOff`](super::fault::TxFate::BusOff) (fault injection) | TEC set to 256 | — |
//!
//! Each error counts one error frame. A device whose TEC reaches 256 goes bus-off exactly as
//! under [`TxFate::BusOff`](super::fault::TxFate::BusOff); the master, too, leaves the bus for the
//! recovery time (its queued frames wait). Both come back error active with zero counters.
//! What the simulation leaves out: the passive error flag of an error-passive node (it destroys
//! the frame all the same here), and the suspend transmission time of an error-passive transmitter.

use crate::bus::health::{ErrorCounters, ErrorReport};
use devicenet::Instant;

/// One node's counters and, while it is bus-off, when it comes back.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Confined {
    pub(super) counters: ErrorCounters,
    pub(super) off_until: Option<Instant>,
}

impl Confined {
    /// Recovery done by `now`: zero counters, error active.
    pub(super) fn refresh(&mut self, now: Instant) {
        if self.off_until.is_some_and(|t| t <= now) {
            self.off_until = None;
            self.counters.recover();
        }
    }
}

/// The counters of the master and of every device (by attachment index), and the error frames.
#[derive(Clone, Debug, Default)]
pub(super) struct Confinement {
    pub(super) master: Confined,
    pub(super) devices: Vec<Confined>,
    pub(super) error_frames: u64,
    pub(super) master_bus_offs: u64,
}

impl Confinement {
    /// The master's report at `now`.
    pub(super) fn report(&mut self, now: Instant) -> ErrorReport {
        self.master.refresh(now);
        let c = self.master.counters;
        ErrorReport {
            state: c.state(),
            tec: Some(c.tec),
            rec: Some(c.rec),
            error_frames: self.error_frames,
            bus_offs: self.master_bus_offs,
        }
    }

    /// The counters of device `i` at `now`.
    pub(super) fn device(&mut self, i: usize, now: Instant) -> Option<ErrorCounters> {
        let d = self.devices.get_mut(i)?;
        d.refresh(now);
        Some(d.counters)
    }

    pub(super) fn device_mut(&mut self, i: usize) -> &mut Confined {
        if self.devices.len() <= i {
            self.devices.resize(i + 1, Confined::default());
        }
        &mut self.devices[i]
    }
}

use super::fault::TxFate;
use super::{Node, SimBus, BUS_OFF_RECOVERY_BITS};
use crate::bus::health::ErrorState;
use devicenet::MacId;

impl SimBus {
    /// A frame of `sender` completed at `at` without error: the transmitter's TEC and every other
    /// node's REC go down.
    pub(super) fn count_frame_ok(&mut self, sender: Node, at: Instant) {
        for i in 0..self.devices.len() {
            let on_bus = self.devices[i].on_bus(at);
            let c = self.confinement.device_mut(i);
            match sender {
                Node::Device(s) if s == i => c.counters.transmitted(),
                _ if on_bus => c.counters.received(),
                _ => {}
            }
        }
        match sender {
            Node::Master => self.confinement.master.counters.transmitted(),
            Node::Device(_) => self.confinement.master.counters.received(),
        }
    }

    /// The fault model gave `sender`'s transmission at `now` this `fate` (not
    /// [`TxFate::Deliver`]): one error frame, the counters by the module's table, and bus-off for
    /// a transmitter whose TEC reached 256.
    pub(super) fn count_error(&mut self, sender: Node, fate: TxFate, now: Instant) {
        self.confinement.error_frames += 1;
        if fate == TxFate::Destroy {
            for i in 0..self.devices.len() {
                if sender != Node::Device(i) && self.devices[i].on_bus(now) {
                    self.confinement.device_mut(i).counters.receive_error();
                }
            }
            if sender != Node::Master {
                self.confinement.master.counters.receive_error();
            }
        }
        let recovery = self.bit_time(BUS_OFF_RECOVERY_BITS);
        match sender {
            Node::Master => {
                let m = &mut self.confinement.master;
                m.refresh(now);
                if m.counters.transmit_error() {
                    m.off_until = Some(now + recovery);
                    self.confinement.master_bus_offs += 1;
                }
            }
            Node::Device(i) => {
                let d = self.confinement.device_mut(i);
                d.refresh(now);
                let off = match fate {
                    TxFate::BusOff => true,
                    _ => d.counters.transmit_error(),
                };
                if off && fate != TxFate::BusOff {
                    self.bus_off(i, now);
                }
            }
        }
    }

    /// Device `i` went bus-off at `now` until `until`: its TEC is 256 until then.
    pub(super) fn confine_bus_off(&mut self, i: usize, until: Instant) {
        let d = self.confinement.device_mut(i);
        d.counters.force_bus_off();
        d.off_until = Some(until);
    }

    /// The master is bus-off until then (its frames wait).
    pub(super) fn master_off_until(&self) -> Option<Instant> {
        self.confinement.master.off_until
    }

    /// The master's error state ([`Bus::error_state`](crate::bus::Bus::error_state)).
    pub(super) fn master_error_report(&mut self) -> ErrorReport {
        self.confinement.report(self.now)
    }

    /// The error counters of the powered device at `mac` now (fault confinement, module docs of
    /// `sim::errors`): TEC 256 while it is bus-off. `None` when no device has that MAC.
    pub fn device_error_counters(&mut self, mac: MacId) -> Option<ErrorCounters> {
        let i = self.devices.iter().position(|d| d.device.mac() == mac)?;
        Some(self.confinement.device(i, self.now).unwrap_or_default())
    }

    /// The error state of the device at `mac` (see [`SimBus::device_error_counters`]).
    pub fn device_error_state(&mut self, mac: MacId) -> Option<ErrorState> {
        self.device_error_counters(mac).map(|c| c.state())
    }
}

#[cfg(test)]
mod tests {
    use super::super::fault::{Fault, FaultRule, PatternFaults, Station};
    use super::super::scripted::{drain, frame, scripted};
    use super::super::{PowerOn, SimBus};
    use crate::bus::health::ErrorState;
    use crate::bus::{Bitrate, Bus};
    use devicenet::{Instant, MacId};

    fn mac(m: u8) -> MacId {
        MacId::new(m).unwrap()
    }

    /// Device 5 sends `frames` frames 0x3C5; its first `destroyed` transmissions are destroyed.
    fn bus_with_errors(frames: usize, destroyed: u32) -> (SimBus, super::super::scripted::BusOffs) {
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, _, offs) = scripted(5, vec![frame(0x3C5, &[1, 2]); frames]);
        let (b, _, _) = scripted(6, vec![]);
        bus.attach(a, PowerOn::AtStart);
        bus.attach(b, PowerOn::AtStart);
        let rule =
            FaultRule::new(Fault::Destroy, 0x3C5..=0x3C5).from(Station::Device(mac(5))).times(destroyed);
        bus.set_faults(Some(Box::new(PatternFaults::new().rule(rule))));
        (bus, offs)
    }

    #[test]
    fn destroyed_frames_add_8_to_the_transmitter_and_1_to_each_receiver() {
        let (mut bus, _) = bus_with_errors(1, 3);
        let events = drain(&mut bus, Instant::from_millis(50));
        assert_eq!(events.len(), 1, "the fourth attempt goes through");
        // Transmitter: 3 × 8 − 1; the other device and the master: 3 × 1 − 1.
        let tx = bus.device_error_counters(mac(5)).unwrap();
        let rx = bus.device_error_counters(mac(6)).unwrap();
        assert_eq!((tx.tec, tx.rec), (23, 0));
        assert_eq!((rx.tec, rx.rec), (0, 2));
        let master = bus.error_state().unwrap();
        assert_eq!((master.tec, master.rec, master.error_frames), (Some(0), Some(2), 3));
        assert_eq!(master.state, ErrorState::Active);
    }

    /// The device's (TEC, state) every 100 µs until `until`.
    fn watch(bus: &mut SimBus, until: Instant) -> Vec<(Instant, u16, ErrorState)> {
        let mut seen = Vec::new();
        let mut t = Instant::ZERO;
        while t < until {
            t += devicenet::Duration::from_micros(100);
            drain(bus, t);
            let c = bus.device_error_counters(mac(5)).unwrap();
            seen.push((t, c.tec, c.state()));
        }
        seen
    }

    #[test]
    fn error_passive_at_128_and_bus_off_at_256() {
        // 16 errors: TEC 128, error passive; the frame's success then brings it to 127.
        let (mut bus, offs) = bus_with_errors(1, 16);
        let seen = watch(&mut bus, Instant::from_millis(20));
        assert!(seen.iter().any(|s| (s.1, s.2) == (128, ErrorState::Passive)), "{seen:?}");
        assert!(seen.iter().all(|s| s.1 < 128 || s.2 == ErrorState::Passive));
        assert_eq!(seen.last().map(|s| (s.1, s.2)), Some((127, ErrorState::Warning)));
        assert!(offs.borrow().is_empty());
        // 32 errors in a row: TEC 256, bus-off, told to the device; receivers at REC 32.
        let (mut bus, offs) = bus_with_errors(1, 32);
        let seen = watch(&mut bus, Instant::from_millis(40));
        assert_eq!(offs.borrow().len(), 1, "bus-off at the 32nd error");
        let off_at = offs.borrow()[0];
        let during: Vec<_> = seen
            .iter()
            .filter(|s| s.0 > off_at && s.0 < off_at + devicenet::Duration::from_micros(5_632))
            .collect();
        assert!(
            !during.is_empty() && during.iter().all(|s| (s.1, s.2) == (256, ErrorState::BusOff)),
            "{during:?}"
        );
        assert_eq!(
            bus.device_error_counters(mac(6)).unwrap().rec,
            32,
            "32 errors; the frame was lost at the bus-off"
        );
        // 128 × 11 bits at 250 kbit/s = 5.632 ms after the bus-off, back with zero counters (its
        // queue was lost: nothing more to send).
        let after: Vec<_> =
            seen.iter().filter(|s| s.0 >= off_at + devicenet::Duration::from_micros(5_632)).collect();
        assert!(
            !after.is_empty() && after.iter().all(|s| (s.1, s.2) == (0, ErrorState::Active)),
            "{after:?}"
        );
        assert_eq!(bus.error_state().unwrap().state, ErrorState::Active, "the master's REC is 32 at most");
    }

    #[test]
    fn the_master_goes_error_passive_then_bus_off_and_waits_out_the_recovery() {
        let mut bus = SimBus::new(Bitrate::K250);
        let (b, _, _) = scripted(6, vec![]);
        bus.attach(b, PowerOn::AtStart);
        let rule = FaultRule::new(Fault::Destroy, 0x407..=0x407).from(Station::Master).times(32);
        bus.set_faults(Some(Box::new(PatternFaults::new().rule(rule))));
        bus.send(&frame(0x407, &[0])).unwrap();
        let mut states = Vec::new();
        let mut events = Vec::new();
        for ms in 1..=40 {
            events.extend(drain(&mut bus, Instant::from_millis(ms)));
            states.push(bus.error_state().unwrap());
        }
        assert!(states.iter().any(|r| r.state == ErrorState::Passive && r.tec >= Some(128)));
        let off = states.iter().position(|r| r.state == ErrorState::BusOff).expect("bus-off");
        assert_eq!(states[off].tec, Some(256));
        assert_eq!(states[off].bus_offs, 1);
        assert_eq!(states[off].error_frames, 32);
        let last = states.last().unwrap();
        assert_eq!((last.state, last.tec, last.bus_offs), (ErrorState::Active, Some(0), 1));
        assert_eq!(events.len(), 1, "the frame goes out after the recovery");
    }

    #[test]
    fn a_duplicated_frame_costs_the_transmitter_8_and_counts_an_error_frame() {
        let mut bus = SimBus::new(Bitrate::K250);
        let (b, received, _) = scripted(6, vec![]);
        bus.attach(b, PowerOn::AtStart);
        let rule = FaultRule::new(Fault::Duplicate, 0x407..=0x407).times(1);
        bus.set_faults(Some(Box::new(PatternFaults::new().rule(rule))));
        bus.send(&frame(0x407, &[0])).unwrap();
        drain(&mut bus, Instant::from_millis(10));
        assert_eq!(received.borrow().len(), 2);
        let r = bus.error_state().unwrap();
        // +8 for the error, −1 for each of the two completed transmissions.
        assert_eq!((r.tec, r.rec, r.error_frames), (Some(6), Some(0), 1));
    }

    #[test]
    fn without_faults_nothing_is_counted() {
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, _, _) = scripted(5, vec![frame(0x3C5, &[1]); 10]);
        bus.attach(a, PowerOn::AtStart);
        assert_eq!(drain(&mut bus, Instant::from_millis(10)).len(), 10);
        let r = bus.error_state().unwrap();
        assert_eq!(
            (r.state, r.tec, r.rec, r.error_frames, r.bus_offs),
            (ErrorState::Active, Some(0), Some(0), 0, 0)
        );
    }
}
