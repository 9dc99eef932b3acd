//! Fault injection on the simulated bus: the model a [`SimBus`](super::SimBus) consults
//! ([`WireFaults`]), two models (random faults at given rates from a seeded generator,
//! [`RandomFaults`]; faults by pattern, [`PatternFaults`]), and [`SharedDevice`], which keeps a
//! handle on a device attached to the bus so a test can inspect it and inject faults into it (the
//! simulated breaker going silent or sending garbage: `breaker_mut().set_silent(true)`,
//! `send_garbage(..)`).
//!
//! Fault injection wraps the bus's behaviour instead of changing it: the bus asks the model at two
//! points and, without a model ([`SimBus::set_faults`](super::SimBus::set_faults) with
//! `None`, the default), never enters a fault path.
//!
//! ## What each fault means (a decision)
//!
//! CAN has no silent corruption: a receiver that sees a CRC error sends an error flag that every
//! node sees, so *nobody* accepts the frame and the transmitter's controller sends it again by
//! itself. "Corrupt" is therefore modelled as **destroyed and retransmitted**, and losing a frame
//! at *one* node is a separate fault, **drop**, which on a real bus happens in the node's receive
//! path (a full mailbox), after the frame was acknowledged by the others.
//!
//! | fault | decided at | effect on the simulated bus | on a real bus |
//! |---|---|---|---|
//! | [`TxFate::Destroy`] | a transmission | the frame runs to its CRC, an error frame follows (the bus is busy for that time), no node receives it; it stays at the head of the sender's queue and contends again at the next idle bus | CRC (or stuff, form) error seen by a receiver |
//! | [`TxFate::Duplicate`] | a transmission | every receiver gets the frame, then the sender sends it again | an error in the last bit of end-of-frame: receivers accepted, the transmitter retries (double reception) |
//! | [`TxFate::BusOff`] | a transmission by a device | the frame and everything the device had queued are lost; the device is told ([`SimDevice::handle_bus_off`]) and stays off the bus (sends and receives nothing) for the recovery time of 128 × 11 bits | transmit error counter above 255 after repeated errors; the master is never driven bus-off (taken as destroyed) |
//! | [`RxFate::Drop`] | a delivery to one receiver | that node never gets the frame; the others do | a receive overrun at that node |
//! | [`RxFate::Delay`] | a delivery to one receiver | that node gets the frame later; frames after it may overtake it | a slow receive path (interrupt latency, a busy task) |
//!
//! The master's own frames always come back to it ([`Origin::Local`](crate::bus::Origin::Local)) when
//! they complete on the wire, once per time on the wire (a duplicated frame shows twice).
//!
//! Everything is deterministic: random faults come from a seeded generator ([`Rng`]), so a run is
//! reproduced from its seed.

use super::device::SimDevice;
use devicenet::{CanFrame, Duration, Instant, MacId};
use std::cell::RefCell;
use std::ops::RangeInclusive;
use std::rc::Rc;

/// A node on the simulated bus, as the fault model sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Station {
    /// The master (this program).
    Master,
    /// The device with this MAC ID.
    Device(MacId),
}

/// What happens to one transmission, decided when the frame wins arbitration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TxFate {
    /// On the wire and received as usual.
    Deliver,
    /// Destroyed by an error (CRC error): nobody receives it; the sender retransmits it.
    Destroy,
    /// Received, then sent again by the sender: every receiver gets it twice.
    Duplicate,
    /// The sending device goes bus-off (the master: taken as [`TxFate::Destroy`]).
    BusOff,
}

/// What happens to one delivery of a completed frame to one receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RxFate {
    /// Delivered at the end of the frame.
    Deliver,
    /// Never delivered to this receiver.
    Drop,
    /// Delivered to this receiver this much later.
    Delay(Duration),
}

/// A fault model: the simulated bus asks it about every transmission and every delivery.
pub trait WireFaults {
    /// The fate of `frame` from `sender`, which won arbitration at `now`.
    fn transmit(&mut self, sender: Station, frame: &CanFrame, now: Instant) -> TxFate;
    /// The fate of the delivery of `frame` from `sender` to `receiver`, completed at `now`.
    fn receive(&mut self, sender: Station, receiver: Station, frame: &CanFrame, now: Instant) -> RxFate;
}

/// The faults a simulated bus applied, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FaultStats {
    /// Transmissions destroyed (and retransmitted).
    pub destroyed: u64,
    /// Transmissions received twice.
    pub duplicated: u64,
    /// Devices driven bus-off.
    pub bus_offs: u64,
    /// Deliveries dropped at one receiver.
    pub dropped: u64,
    /// Deliveries delayed at one receiver.
    pub delayed: u64,
}

impl FaultStats {
    /// All faults together.
    pub fn total(&self) -> u64 {
        self.destroyed + self.duplicated + self.bus_offs + self.dropped + self.delayed
    }
}

impl std::ops::Add for FaultStats {
    type Output = FaultStats;
    fn add(self, o: FaultStats) -> FaultStats {
        FaultStats {
            destroyed: self.destroyed + o.destroyed,
            duplicated: self.duplicated + o.duplicated,
            bus_offs: self.bus_offs + o.bus_offs,
            dropped: self.dropped + o.dropped,
            delayed: self.delayed + o.delayed,
        }
    }
}

/// A small seeded pseudo-random generator (SplitMix64): the same seed gives the same faults.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform number in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// `true` with probability `p` (0 never, 1 always).
    pub fn chance(&mut self, p: f64) -> bool {
        p > 0.0 && self.unit() < p
    }

    /// A uniform number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            0
        } else {
            self.next_u64() % n
        }
    }
}

/// Per-frame probabilities of [`RandomFaults`]. Transmission faults are exclusive (one draw per
/// transmission); reception faults are drawn per receiver.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FaultRates {
    /// A transmission is destroyed (CRC error) and retransmitted.
    pub destroy: f64,
    /// A transmission is received twice.
    pub duplicate: f64,
    /// A device's transmission drives it bus-off.
    pub bus_off: f64,
    /// A delivery to one receiver is dropped.
    pub drop: f64,
    /// A delivery to one receiver is delayed, uniformly up to `max_delay`.
    pub delay: f64,
    /// The longest delay.
    pub max_delay: Duration,
}

/// Random faults at [`FaultRates`], from a seeded [`Rng`].
#[derive(Clone, Debug)]
pub struct RandomFaults {
    rates: FaultRates,
    rng: Rng,
}

impl RandomFaults {
    /// Faults at `rates`, drawn from a generator seeded with `seed`.
    pub fn new(rates: FaultRates, seed: u64) -> RandomFaults {
        RandomFaults { rates, rng: Rng::new(seed) }
    }
}

impl WireFaults for RandomFaults {
    fn transmit(&mut self, sender: Station, _frame: &CanFrame, _now: Instant) -> TxFate {
        let r = self.rates;
        let u = self.rng.unit();
        let bus_off = if matches!(sender, Station::Device(_)) { r.bus_off } else { 0.0 };
        if u < bus_off {
            TxFate::BusOff
        } else if u < bus_off + r.destroy {
            TxFate::Destroy
        } else if u < bus_off + r.destroy + r.duplicate {
            TxFate::Duplicate
        } else {
            TxFate::Deliver
        }
    }

    fn receive(&mut self, _sender: Station, _receiver: Station, _frame: &CanFrame, _now: Instant) -> RxFate {
        let r = self.rates;
        if self.rng.chance(r.drop) {
            RxFate::Drop
        } else if self.rng.chance(r.delay) {
            let max = r.max_delay.total_micros().max(1);
            RxFate::Delay(Duration::from_micros(1 + self.rng.below(max)))
        } else {
            RxFate::Deliver
        }
    }
}

/// One fault of a [`FaultRule`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Fault {
    /// Destroy the transmission ([`TxFate::Destroy`]).
    Destroy,
    /// Duplicate the transmission ([`TxFate::Duplicate`]).
    Duplicate,
    /// Drive the sending device bus-off ([`TxFate::BusOff`]).
    BusOff,
    /// Drop the delivery ([`RxFate::Drop`]).
    Drop,
    /// Delay the delivery ([`RxFate::Delay`]).
    Delay(Duration),
}

impl Fault {
    fn on_transmission(self) -> bool {
        matches!(self, Fault::Destroy | Fault::Duplicate | Fault::BusOff)
    }
}

/// "Apply `fault` to frames with these identifiers, from this sender, to this receiver: skip the
/// first `skip` matches, then every `every`-th, at most `times` times."
///
/// Every transmission of a matching frame counts, retransmissions included: a rule that destroys
/// every copy of a frame keeps the bus busy for ever, as a transmitter stuck on errors would.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FaultRule {
    fault: Fault,
    ids: RangeInclusive<u16>,
    sender: Option<Station>,
    receiver: Option<Station>,
    skip: u32,
    every: u32,
    times: Option<u32>,
    seen: u32,
    applied: u32,
}

impl FaultRule {
    /// `fault` on every frame whose identifier is in `ids`.
    pub fn new(fault: Fault, ids: RangeInclusive<u16>) -> FaultRule {
        FaultRule {
            fault,
            ids,
            sender: None,
            receiver: None,
            skip: 0,
            every: 1,
            times: None,
            seen: 0,
            applied: 0,
        }
    }

    /// Only frames sent by `station`.
    pub fn from(mut self, station: Station) -> FaultRule {
        self.sender = Some(station);
        self
    }

    /// Only deliveries to `station` (reception faults).
    pub fn to(mut self, station: Station) -> FaultRule {
        self.receiver = Some(station);
        self
    }

    /// Leaves the first `n` matches alone.
    pub fn skip(mut self, n: u32) -> FaultRule {
        self.skip = n;
        self
    }

    /// Applies to every `n`-th match after the skipped ones (1: each; 0 is taken as 1).
    pub fn every(mut self, n: u32) -> FaultRule {
        self.every = n.max(1);
        self
    }

    /// Applies at most `n` times.
    pub fn times(mut self, n: u32) -> FaultRule {
        self.times = Some(n);
        self
    }

    /// How many times the rule was applied.
    pub fn applied(&self) -> u32 {
        self.applied
    }

    fn matches(&self, sender: Station, receiver: Option<Station>, frame: &CanFrame) -> bool {
        self.ids.contains(&frame.id().as_raw())
            && self.sender.is_none_or(|s| s == sender)
            && match (self.receiver, receiver) {
                (Some(want), Some(r)) => want == r,
                _ => true,
            }
    }

    /// Counts a match and says whether the fault applies to it.
    fn hit(&mut self) -> bool {
        self.seen = self.seen.saturating_add(1);
        if self.seen <= self.skip || self.times.is_some_and(|t| self.applied >= t) {
            return false;
        }
        if (self.seen - self.skip - 1) % self.every != 0 {
            return false;
        }
        self.applied += 1;
        true
    }
}

/// Faults by pattern: the first rule that matches a frame and fires decides its fate.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PatternFaults {
    rules: Vec<FaultRule>,
}

impl PatternFaults {
    /// No rules (no faults).
    pub fn new() -> PatternFaults {
        PatternFaults::default()
    }

    /// Adds a rule.
    pub fn rule(mut self, rule: FaultRule) -> PatternFaults {
        self.rules.push(rule);
        self
    }

    /// The rules with their counts.
    pub fn rules(&self) -> &[FaultRule] {
        &self.rules
    }
}

impl WireFaults for PatternFaults {
    fn transmit(&mut self, sender: Station, frame: &CanFrame, _now: Instant) -> TxFate {
        for rule in self.rules.iter_mut().filter(|r| r.fault.on_transmission()) {
            if rule.matches(sender, None, frame) && rule.hit() {
                return match rule.fault {
                    Fault::Destroy => TxFate::Destroy,
                    Fault::Duplicate => TxFate::Duplicate,
                    _ => TxFate::BusOff,
                };
            }
        }
        TxFate::Deliver
    }

    fn receive(&mut self, sender: Station, receiver: Station, frame: &CanFrame, _now: Instant) -> RxFate {
        for rule in self.rules.iter_mut().filter(|r| !r.fault.on_transmission()) {
            if rule.matches(sender, Some(receiver), frame) && rule.hit() {
                return match rule.fault {
                    Fault::Delay(d) => RxFate::Delay(d),
                    _ => RxFate::Drop,
                };
            }
        }
        RxFate::Deliver
    }
}

/// A device attached to the bus while the test keeps a handle on it ([`SharedDevice::handle`]) to
/// look inside and to inject faults into it (for the soft slave: its simulated breaker).
pub struct SharedDevice<D> {
    inner: Rc<RefCell<D>>,
}

impl<D> SharedDevice<D> {
    /// Wraps `device`.
    pub fn new(device: D) -> SharedDevice<D> {
        SharedDevice { inner: Rc::new(RefCell::new(device)) }
    }

    /// The handle the test keeps.
    pub fn handle(&self) -> Rc<RefCell<D>> {
        Rc::clone(&self.inner)
    }
}

impl<D: SimDevice> SimDevice for SharedDevice<D> {
    fn mac(&self) -> MacId {
        self.inner.borrow().mac()
    }
    fn power_on(&mut self, now: Instant) {
        self.inner.borrow_mut().power_on(now);
    }
    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.inner.borrow_mut().handle_frame(frame, now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.inner.borrow_mut().handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.inner.borrow_mut().poll_transmit()
    }
    fn poll_at(&self) -> Option<Instant> {
        self.inner.borrow().poll_at()
    }
    fn handle_bus_off(&mut self, now: Instant) {
        self.inner.borrow_mut().handle_bus_off(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::{Bitrate, Bus, Origin};
    use crate::sim::{frame_bits, PowerOn, SimBus};

    use crate::sim::scripted::{drain, frame, scripted as node};

    fn us_per_bit() -> u64 {
        4 // 250 kbit/s
    }

    #[test]
    fn a_destroyed_frame_reaches_nobody_and_is_retransmitted_after_the_error_frame() {
        let f = frame(0x42C, &[0, 0x0E, 1, 1, 1]);
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, received, _) = node(5, vec![]);
        bus.attach(a, PowerOn::AtStart);
        bus.set_faults(Some(Box::new(
            PatternFaults::new().rule(FaultRule::new(Fault::Destroy, 0x42C..=0x42C).times(1)),
        )));
        bus.send(&f).unwrap();
        let events = drain(&mut bus, Instant::from_secs(1));
        assert_eq!(events.len(), 1, "one successful transmission");
        let bits = u64::from(frame_bits(&f));
        let destroyed = (bits - 13 + 24) * us_per_bit();
        assert_eq!(events[0].at, Instant::from_micros(destroyed + (bits - 3) * us_per_bit()));
        assert_eq!(received.borrow().len(), 1);
        assert_eq!(bus.fault_stats().destroyed, 1);
    }

    #[test]
    fn a_duplicated_frame_is_received_twice_by_everyone() {
        let f = frame(0x3C5, &[1, 2, 3]);
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, _, _) = node(5, vec![f]);
        let (b, received_b, _) = node(6, vec![]);
        bus.attach(a, PowerOn::AtStart);
        bus.attach(b, PowerOn::AtStart);
        bus.set_faults(Some(Box::new(
            PatternFaults::new().rule(FaultRule::new(Fault::Duplicate, 0x3C5..=0x3C5).times(1)),
        )));
        let events = drain(&mut bus, Instant::from_secs(1));
        assert_eq!(events.len(), 2);
        assert!(events.iter().all(|e| e.frame == f && e.origin == Origin::Remote));
        assert_eq!(received_b.borrow().len(), 2);
        assert_eq!(bus.fault_stats().duplicated, 1);
    }

    #[test]
    fn drop_and_delay_touch_one_receiver_only() {
        let f1 = frame(0x3C5, &[1]);
        let f2 = frame(0x3C5, &[2]);
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, _, _) = node(5, vec![f1, f2]);
        let (b, received_b, _) = node(6, vec![]);
        bus.attach(a, PowerOn::AtStart);
        bus.attach(b, PowerOn::AtStart);
        let six = Station::Device(MacId::new(6).unwrap());
        bus.set_faults(Some(Box::new(
            PatternFaults::new().rule(FaultRule::new(Fault::Drop, 0x3C5..=0x3C5).to(six).times(1)).rule(
                FaultRule::new(Fault::Delay(Duration::from_millis(5)), 0x3C5..=0x3C5).to(Station::Master),
            ),
        )));
        let events = drain(&mut bus, Instant::from_secs(1));
        // The master gets both, each 5 ms late; MAC 6 only the second, on time.
        assert_eq!(events.iter().map(|e| e.frame).collect::<Vec<_>>(), vec![f1, f2]);
        let on_time = received_b.borrow()[0].0;
        assert_eq!(received_b.borrow().iter().map(|r| r.1).collect::<Vec<_>>(), vec![f2]);
        assert_eq!(events[1].at, on_time + Duration::from_millis(5));
        let s = bus.fault_stats();
        assert_eq!((s.dropped, s.delayed), (1, 2));
    }

    #[test]
    fn bus_off_loses_the_queue_tells_the_device_and_keeps_it_off_for_the_recovery_time() {
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, received, bus_offs) = node(5, vec![frame(0x42F, &[0; 7]), frame(0x42B, &[1])]);
        bus.attach(a, PowerOn::AtStart);
        bus.set_faults(Some(Box::new(
            PatternFaults::new().rule(FaultRule::new(Fault::BusOff, 0x42F..=0x42F).times(1)),
        )));
        assert!(drain(&mut bus, Instant::from_millis(1)).is_empty(), "both frames lost");
        assert_eq!(bus_offs.borrow().as_slice(), &[Instant::ZERO]);
        // Off the bus for 128 x 11 bits = 5.632 ms at 250 kbit/s: the master's frame is not received.
        bus.send(&frame(0x42C, &[0, 0x0E, 1, 1, 1])).unwrap();
        let events = drain(&mut bus, Instant::from_millis(5));
        assert_eq!(events.len(), 1);
        assert!(received.borrow().is_empty());
        // After the recovery time it is back.
        drain(&mut bus, Instant::from_millis(6));
        bus.send(&frame(0x42C, &[0, 0x0E, 1, 1, 2])).unwrap();
        drain(&mut bus, Instant::from_millis(10));
        assert_eq!(received.borrow().len(), 1);
        assert_eq!(bus.fault_stats().bus_offs, 1);
        // Forced bus-off through the bus, without a fault model.
        bus.set_faults(None);
        assert!(bus.force_bus_off(MacId::new(5).unwrap()));
        assert!(!bus.force_bus_off(MacId::new(9).unwrap()));
        assert_eq!(bus_offs.borrow().len(), 2);
    }

    #[test]
    fn random_faults_follow_their_seed_and_rates() {
        let rates = FaultRates {
            destroy: 0.1,
            duplicate: 0.1,
            bus_off: 0.0,
            drop: 0.2,
            delay: 0.1,
            max_delay: Duration::from_millis(3),
        };
        let f = frame(0x3C5, &[0]);
        let draw = |seed| {
            let mut m = RandomFaults::new(rates, seed);
            (0..2000)
                .map(|_| {
                    (
                        m.transmit(Station::Master, &f, Instant::ZERO),
                        m.receive(Station::Master, Station::Master, &f, Instant::ZERO),
                    )
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(draw(7), draw(7));
        assert_ne!(draw(7), draw(8));
        let d = draw(7);
        let destroyed = d.iter().filter(|x| x.0 == TxFate::Destroy).count();
        let dropped = d.iter().filter(|x| x.1 == RxFate::Drop).count();
        assert!((150..250).contains(&destroyed), "{destroyed}");
        assert!((330..470).contains(&dropped), "{dropped}");
        assert!(d.iter().all(|x| match x.1 {
            RxFate::Delay(d) => d <= Duration::from_millis(3),
            _ => true,
        }));
        assert!(d.iter().all(|x| x.0 != TxFate::BusOff), "never for the master");
    }

    #[test]
    fn rule_counting_skip_every_times() {
        let mut r = FaultRule::new(Fault::Drop, 0..=0x7FF).skip(2).every(3).times(2);
        let fired: Vec<bool> = (0..12).map(|_| r.hit()).collect();
        assert_eq!(fired, [false, false, true, false, false, true, false, false, false, false, false, false]);
        assert_eq!(r.applied(), 2);
    }

    #[test]
    fn without_a_model_nothing_changes() {
        // The same traffic with and without an empty pattern model: identical events.
        let run = |faults: bool| {
            let mut bus = SimBus::new(Bitrate::K500);
            let (a, _, _) = node(5, vec![frame(0x42B, &[1]), frame(0x3C5, &[2, 3])]);
            bus.attach(a, PowerOn::AtStart);
            if faults {
                bus.set_faults(Some(Box::new(PatternFaults::new())));
            }
            bus.send(&frame(0x407, &[0; 7])).unwrap();
            drain(&mut bus, Instant::from_secs(1))
        };
        assert_eq!(run(false), run(true));
    }
}
