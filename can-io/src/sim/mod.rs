//! The simulated CAN bus: simulated devices and the master on a virtual clock.
//!
//! The model, per frame:
//!
//! * **Arbitration.** Every node (the master and each device) has a transmit queue served in
//!   order. When the bus is idle, the head frames of all queues that are pending at that instant
//!   contend, and the lowest identifier wins (protocol §1.1): a frame that loses waits for the next
//!   idle bus.
//! * **Time on the wire.** A frame occupies the bus for its exact bit count at the chosen bit rate:
//!   the stuffed region (start of frame to CRC) with the stuff bits the frame's own bit pattern
//!   needs, the fixed tail, and the 3-bit intermission ([`frame_bits`]). Every other node receives
//!   the frame at its end.
//! * **Devices** are sans-IO ([`SimDevice`]): the bus calls them at the instants they ask for
//!   ([`SimDevice::poll_at`]) and when a frame completes, and queues what they transmit.
//! * **Power.** Each device powers on according to its [`PowerOn`] policy; by default when the
//!   master goes on-line, as in the source capture: 1 s after the master queued its second
//!   duplicate MAC ID check request (protocol §7.1). The bus reads that from the master's own frames;
//!   nothing simulation-specific passes through the [`Bus`] trait.
//!
//! * **Faults** (optional, [`SimBus::set_faults`]): a [`WireFaults`] model decides the fate of
//!   each transmission (delivered, destroyed by a CRC error and retransmitted, received twice,
//!   the sender driven bus-off) and of each delivery to each receiver (delivered, dropped, delayed);
//!   the model and its implementations live in [`fault`]. Without a model the bus behaves
//!   exactly as described above: the fault paths are never entered.
//! * **Fault confinement**: every node's transmit and receive error counters follow the ISO
//!   11898-1 rules under those faults (error frames counted, bus-off at TEC 256, recovery after
//!   128 × 11 bits); the master's are its [`Bus::error_state`], a device's
//!   [`SimBus::device_error_counters`] (`sim::errors`, private: its table is in the guide's health
//!   page).
//!
//! Time is virtual: a 2 s duplicate MAC ID check costs no wall time. With
//! [`SimBus::set_realtime`] the simulation waits for the wall clock to catch up with each instant
//! it reaches.

mod device;
mod errors;
pub mod fault;
#[cfg(test)]
mod scripted;

pub use device::{PowerOn, SimDevice};

use crate::bus::{Bitrate, Bus, BusError, BusEvent, Origin};
use devicenet::messages::DuplicateMacCheck;
use devicenet::slave::DUP_MAC_INTERVAL;
use devicenet::{CanFrame, Duration, Instant, MacId};
use fault::{FaultStats, RxFate, Station, TxFate, WireFaults};
use std::collections::VecDeque;

/// Sees a master go on-line from the frames it sends, as the wire shows it: a master that sent its
/// second duplicate MAC ID check request at `t` and heard no answer is on-line at `t` + 1 s (notes
/// §7.1). The simulated bus powers its [`PowerOn::WhenMasterOnline`] devices then; a test bus
/// around real equipment can do the same.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MasterOnlineWatch {
    checks: u32,
}

impl MasterOnlineWatch {
    /// The master queued `frame` at `now`; returns the instant it goes on-line when this frame was
    /// its second duplicate MAC ID check request.
    pub fn sent(&mut self, frame: &CanFrame, now: Instant) -> Option<Instant> {
        DuplicateMacCheck::request_in(frame)?;
        self.checks = self.checks.saturating_add(1);
        (self.checks == 2).then_some(now + DUP_MAC_INTERVAL)
    }
}

/// The bits a CAN 2.0A data frame occupies on the wire, intermission included: the stuffed region
/// (SOF, identifier, RTR, IDE, r0, DLC, data, CRC) with the stuff bits this frame's bit pattern
/// needs, then CRC delimiter, ACK slot and delimiter, 7-bit end of frame and 3-bit intermission.
///
/// Never more than [`CanFrame::worst_case_bits`], never less than the unstuffed 47 + 8n.
pub fn frame_bits(frame: &CanFrame) -> u32 {
    let mut bits: Vec<bool> = Vec::with_capacity(34 + 64);
    let push = |bits: &mut Vec<bool>, value: u32, width: u32| {
        for i in (0..width).rev() {
            bits.push(value >> i & 1 == 1);
        }
    };
    push(&mut bits, 0, 1); // SOF (dominant)
    push(&mut bits, u32::from(frame.id().as_raw()), 11);
    push(&mut bits, 0, 3); // RTR, IDE, r0
    push(&mut bits, frame.dlc() as u32, 4);
    for &b in frame.data() {
        push(&mut bits, u32::from(b), 8);
    }
    // CRC-15, polynomial 0x4599, over SOF..data.
    let mut crc: u16 = 0;
    for &bit in &bits {
        let next = bit ^ (crc >> 14 & 1 == 1);
        crc = (crc << 1) & 0x7FFF;
        if next {
            crc ^= 0x4599;
        }
    }
    push(&mut bits, u32::from(crc), 15);
    // Bit stuffing: after five equal bits a complementary bit follows (and counts in the next run).
    let mut stuff = 0u32;
    let mut run = 0u32;
    let mut last: Option<bool> = None;
    for &bit in &bits {
        if Some(bit) == last {
            run += 1;
        } else {
            last = Some(bit);
            run = 1;
        }
        if run == 5 {
            stuff += 1;
            last = Some(!bit);
            run = 1;
        }
    }
    bits.len() as u32 + stuff + 10 + 3
}

/// How long `frame` occupies the bus at `bitrate` ([`frame_bits`], rounded up to the microsecond).
pub fn frame_duration(frame: &CanFrame, bitrate: Bitrate) -> Duration {
    let bits = u64::from(frame_bits(frame));
    let bps = u64::from(bitrate.bits_per_second().max(1));
    Duration::from_micros((bits * 1_000_000).div_ceil(bps))
}

/// The 3-bit intermission counted at the end of [`frame_bits`]; receivers see the frame before it.
const INTERMISSION_BITS: u64 = 3;

/// Steps the simulation may take at one instant before it reports a stalled device.
const MAX_STEPS_PER_INSTANT: u32 = 100_000;

/// Bits an error adds after the stuffed region of a destroyed frame: CRC delimiter (1), error flag
/// (6), the other nodes' superposed error flags (up to 6), error delimiter (8), intermission (3).
const ERROR_FRAME_BITS: u64 = 1 + 6 + 6 + 8 + 3;

/// Bits of the fixed tail counted in [`frame_bits`] after the stuffed region.
const TAIL_BITS: u64 = 10 + 3;

/// Bus-off recovery: 128 occurrences of 11 consecutive recessive bits (ISO 11898-1).
const BUS_OFF_RECOVERY_BITS: u64 = 128 * 11;

/// Which node sent a frame: the master, or device `i`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Node {
    Master,
    Device(usize),
}

struct Attached {
    device: Box<dyn SimDevice>,
    power: PowerOn,
    /// A power-on that is due (from the policy) and not yet done.
    power_at: Option<Instant>,
    powered: bool,
    tx: VecDeque<(Instant, CanFrame)>,
    /// Bus-off (fault injection): off the bus, neither sending nor receiving, until then.
    off_until: Option<Instant>,
}

impl Attached {
    fn on_bus(&self, now: Instant) -> bool {
        self.powered && self.off_until.is_none_or(|t| t <= now)
    }
}

struct OnWire {
    sender: Node,
    frame: CanFrame,
    /// End of frame: receivers get it now.
    end: Instant,
    /// What the fault model decided for this transmission ([`TxFate::Deliver`] without one).
    fate: TxFate,
}

/// A delivery the fault model delayed.
struct Delayed {
    at: Instant,
    to: Node,
    frame: CanFrame,
}

/// The simulated bus. See the [module docs](self) for the model.
pub struct SimBus {
    name: String,
    bitrate: Bitrate,
    now: Instant,
    devices: Vec<Attached>,
    master_tx: VecDeque<(Instant, CanFrame)>,
    on_wire: Option<OnWire>,
    /// The bus is idle from this instant (after the last frame's intermission).
    idle_at: Instant,
    outbox: VecDeque<BusEvent>,
    realtime: Option<std::time::Instant>,
    frames: u64,
    faults: Option<Box<dyn WireFaults>>,
    delayed: Vec<Delayed>,
    fault_stats: FaultStats,
    /// Sees the master go on-line from its own frames.
    master_online: MasterOnlineWatch,
    /// Every node's error counters.
    confinement: errors::Confinement,
}

impl SimBus {
    /// An empty simulated bus at `bitrate`, at time zero.
    pub fn new(bitrate: Bitrate) -> SimBus {
        SimBus {
            name: "sim".to_string(),
            bitrate,
            now: Instant::ZERO,
            devices: Vec::new(),
            master_tx: VecDeque::new(),
            on_wire: None,
            idle_at: Instant::ZERO,
            outbox: VecDeque::new(),
            realtime: None,
            frames: 0,
            faults: None,
            delayed: Vec::new(),
            fault_stats: FaultStats::default(),
            master_online: MasterOnlineWatch::default(),
            confinement: errors::Confinement::default(),
        }
    }

    /// Installs (or, with `None`, removes) the fault model consulted for every transmission and
    /// delivery from now on ([`fault`]). Deliveries it already delayed still happen.
    pub fn set_faults(&mut self, faults: Option<Box<dyn WireFaults>>) {
        self.faults = faults;
    }

    /// The faults applied so far.
    pub fn fault_stats(&self) -> FaultStats {
        self.fault_stats
    }

    /// Frames waiting anywhere in the bus: transmit queues, the master's receive queue and delayed
    /// deliveries (to watch memory in long runs).
    pub fn queued_frames(&self) -> usize {
        self.devices.iter().map(|d| d.tx.len()).sum::<usize>()
            + self.master_tx.len()
            + self.outbox.len()
            + self.delayed.len()
    }

    /// Drives the device at `mac` bus-off now (fault injection): its queued frames are lost, it is
    /// told ([`SimDevice::handle_bus_off`]) and it stays off the bus for the bus-off recovery time
    /// (128 × 11 bit times). Returns `false` when no powered device has that MAC.
    pub fn force_bus_off(&mut self, mac: MacId) -> bool {
        let now = self.now;
        match self.devices.iter().position(|d| d.powered && d.device.mac() == mac) {
            Some(i) => {
                self.bus_off(i, now);
                true
            }
            None => false,
        }
    }

    fn bus_off(&mut self, i: usize, now: Instant) {
        let recovery = self.bit_time(BUS_OFF_RECOVERY_BITS);
        self.confine_bus_off(i, now + recovery);
        let d = &mut self.devices[i];
        d.tx.clear();
        d.off_until = Some(now + recovery);
        d.device.handle_bus_off(now);
        self.fault_stats.bus_offs += 1;
        self.drain_device(i, now);
    }

    fn station(&self, node: Node) -> Station {
        match node {
            Node::Master => Station::Master,
            Node::Device(i) => Station::Device(self.devices[i].device.mac()),
        }
    }

    /// Delivers `frame` to one receiver, as the fault model (if any) decides.
    fn deliver(&mut self, sender: Node, to: Node, frame: &CanFrame, at: Instant) {
        let fate = match self.faults.as_mut() {
            None => RxFate::Deliver,
            Some(_) => {
                let (s, r) = (self.station(sender), self.station(to));
                self.faults.as_mut().map_or(RxFate::Deliver, |f| f.receive(s, r, frame, at))
            }
        };
        match fate {
            RxFate::Deliver => self.hand_over(to, frame, at),
            RxFate::Drop => self.fault_stats.dropped += 1,
            RxFate::Delay(d) => {
                self.fault_stats.delayed += 1;
                self.delayed.push(Delayed { at: at + d, to, frame: *frame });
            }
        }
    }

    fn hand_over(&mut self, to: Node, frame: &CanFrame, at: Instant) {
        match to {
            Node::Master => self.outbox.push_back(BusEvent { at, frame: *frame, origin: Origin::Remote }),
            Node::Device(i) => {
                if self.devices[i].on_bus(at) {
                    self.devices[i].device.handle_frame(frame, at);
                    self.drain_device(i, at);
                }
            }
        }
    }

    /// Attaches a device with its power-on policy.
    pub fn attach(&mut self, device: Box<dyn SimDevice>, power: PowerOn) {
        let power_at = match power {
            PowerOn::AtStart => Some(self.now),
            PowerOn::At(at) => Some(at),
            PowerOn::WhenMasterOnline | PowerOn::AfterMasterOnline(_) => None,
        };
        self.devices.push(Attached {
            device,
            power,
            power_at,
            powered: false,
            tx: VecDeque::new(),
            off_until: None,
        });
    }

    /// Builder form of [`SimBus::attach`].
    pub fn with_device(mut self, device: Box<dyn SimDevice>, power: PowerOn) -> SimBus {
        self.attach(device, power);
        self
    }

    /// Devices waiting for the master to be on-line are powered on when
    /// [`MasterOnlineWatch`] sees it go on-line.
    fn watch_master(&mut self, frame: &CanFrame) {
        if let Some(online) = self.master_online.sent(frame, self.now) {
            for d in &mut self.devices {
                let delay = match d.power {
                    PowerOn::WhenMasterOnline => Duration::ZERO,
                    PowerOn::AfterMasterOnline(delay) => delay,
                    PowerOn::AtStart | PowerOn::At(_) => continue,
                };
                if !d.powered && d.power_at.is_none() {
                    d.power_at = Some(online + delay);
                }
            }
        }
    }

    /// Paces the simulation against the wall clock (`--realtime`).
    pub fn set_realtime(&mut self, on: bool) {
        self.realtime = on.then(std::time::Instant::now);
    }

    /// The bit rate.
    pub fn bitrate(&self) -> Bitrate {
        self.bitrate
    }

    /// Frames that completed on the bus so far.
    pub fn frames_completed(&self) -> u64 {
        self.frames
    }

    /// Number of attached devices.
    pub fn device_count(&self) -> usize {
        self.devices.len()
    }

    fn bit_time(&self, bits: u64) -> Duration {
        let bps = u64::from(self.bitrate.bits_per_second().max(1));
        Duration::from_micros((bits * 1_000_000).div_ceil(bps))
    }

    /// Sleeps until the wall clock reaches virtual time `t` (realtime mode only).
    fn pace(&self, t: Instant) {
        if let Some(start) = self.realtime {
            let target = start + std::time::Duration::from_micros(t.total_micros());
            let wall = std::time::Instant::now();
            if target > wall {
                std::thread::sleep(target - wall);
            }
        }
    }

    fn drain_device(&mut self, i: usize, now: Instant) {
        let attached = &mut self.devices[i];
        while let Some(frame) = attached.device.poll_transmit() {
            attached.tx.push_back((now, frame));
        }
    }

    /// The earliest instant something happens on the bus.
    fn next_instant(&self) -> Option<Instant> {
        let wire = self.on_wire.as_ref().map(|w| w.end);
        let devices = self.devices.iter().filter_map(|d| {
            let timer = if d.powered { d.device.poll_at() } else { None };
            [timer, d.power_at].into_iter().flatten().min()
        });
        let arbitration = if self.on_wire.is_none() {
            let heads = self
                .devices
                .iter()
                .filter_map(|d| d.tx.front().map(|&(at, _)| d.off_until.map_or(at, |off| at.max(off))));
            let master =
                self.master_tx.front().map(|&(at, _)| self.master_off_until().map_or(at, |off| at.max(off)));
            heads.chain(master).min().map(|ready| ready.max(self.idle_at))
        } else {
            None
        };
        let delayed = self.delayed.iter().map(|d| d.at).min();
        [wire, arbitration, delayed].into_iter().flatten().chain(devices).min()
    }

    /// Does everything due at `self.now`: completes the frame on the wire, powers devices on, runs
    /// their timers, then starts the next frame if the bus is idle (so frames queued at this
    /// instant take part in the arbitration).
    fn step(&mut self) {
        let now = self.now;
        if self.on_wire.as_ref().is_some_and(|w| w.end <= now) {
            if let Some(w) = self.on_wire.take() {
                if w.fate == TxFate::Deliver {
                    self.complete(&w);
                } else {
                    self.complete_faulty(&w);
                }
            }
        }
        if !self.delayed.is_empty() {
            self.deliver_delayed(now);
        }
        for i in 0..self.devices.len() {
            if self.devices[i].power_at.is_some_and(|at| at <= now) {
                let d = &mut self.devices[i];
                d.power_at = None;
                d.powered = true;
                d.tx.clear();
                d.off_until = None;
                d.device.power_on(now);
                self.drain_device(i, now);
            }
            if self.devices[i].powered && self.devices[i].device.poll_at().is_some_and(|at| at <= now) {
                self.devices[i].device.handle_timeout(now);
                self.drain_device(i, now);
            }
        }
        if self.on_wire.is_none() && self.idle_at <= now {
            self.arbitrate(now);
        }
    }

    /// A frame completed without a fault: every other powered node receives it.
    fn complete(&mut self, w: &OnWire) {
        self.frames += 1;
        self.count_frame_ok(w.sender, w.end);
        for i in 0..self.devices.len() {
            if w.sender != Node::Device(i) && self.devices[i].on_bus(w.end) {
                if self.faults.is_none() {
                    self.devices[i].device.handle_frame(&w.frame, w.end);
                    self.drain_device(i, w.end);
                } else {
                    self.deliver(w.sender, Node::Device(i), &w.frame, w.end);
                }
            }
        }
        if w.sender == Node::Master {
            self.outbox.push_back(BusEvent { at: w.end, frame: w.frame, origin: Origin::Local });
        } else if self.faults.is_none() {
            self.outbox.push_back(BusEvent { at: w.end, frame: w.frame, origin: Origin::Remote });
        } else {
            self.deliver(w.sender, Node::Master, &w.frame, w.end);
        }
    }

    /// The end of a transmission the fault model interfered with.
    fn complete_faulty(&mut self, w: &OnWire) {
        match w.fate {
            TxFate::Deliver => self.complete(w),
            // The receivers rejected it; the sender's controller retransmits it (it is still at
            // the head of its queue).
            TxFate::Destroy | TxFate::BusOff => {}
            TxFate::Duplicate => {
                self.complete(w);
                // The sender saw an error in the last bit of end-of-frame, after the receivers had
                // accepted the frame: it sends it again.
                let again = (w.end, w.frame);
                match w.sender {
                    Node::Master => self.master_tx.push_front(again),
                    Node::Device(i) => self.devices[i].tx.push_front(again),
                }
            }
        }
    }

    fn deliver_delayed(&mut self, now: Instant) {
        let mut due: Vec<Delayed> = Vec::new();
        let mut k = 0;
        while k < self.delayed.len() {
            if self.delayed[k].at <= now {
                due.push(self.delayed.remove(k));
            } else {
                k += 1;
            }
        }
        for d in due {
            self.hand_over(d.to, &d.frame, d.at);
        }
    }

    /// Lowest identifier among the head frames pending at `now` wins; the master wins a tie.
    fn arbitrate(&mut self, now: Instant) {
        let mut winner: Option<(u16, Node)> = None;
        let mut consider = |id: u16, node: Node| {
            if winner.is_none_or(|(best, _)| id < best) {
                winner = Some((id, node));
            }
        };
        if let Some(&(at, f)) = self.master_tx.front() {
            if at <= now && self.master_off_until().is_none_or(|t| t <= now) {
                consider(f.id().as_raw(), Node::Master);
            }
        }
        for (i, d) in self.devices.iter().enumerate() {
            if let Some(&(at, f)) = d.tx.front() {
                if at <= now && d.off_until.is_none_or(|t| t <= now) {
                    consider(f.id().as_raw(), Node::Device(i));
                }
            }
        }
        let Some((_, node)) = winner else { return };
        let fate = match self.faults.is_some() {
            false => TxFate::Deliver,
            true => self.transmit_fate(node, now),
        };
        if fate != TxFate::Deliver {
            self.start_faulty(node, fate, now);
            return;
        }
        self.put_on_wire(node, fate, now);
    }

    /// Takes `node`'s head frame off its queue and puts it on the wire at `now` with `fate`; it
    /// completes one intermission before the bus is idle again.
    fn put_on_wire(&mut self, node: Node, fate: TxFate, now: Instant) {
        let popped = match node {
            Node::Master => self.master_tx.pop_front(),
            Node::Device(i) => self.devices[i].tx.pop_front(),
        };
        if let Some((_, frame)) = popped {
            let total = frame_duration(&frame, self.bitrate);
            let intermission = self.bit_time(INTERMISSION_BITS);
            let end =
                now + Duration::from_micros(total.total_micros().saturating_sub(intermission.total_micros()));
            self.idle_at = now + total;
            self.on_wire = Some(OnWire { sender: node, frame, end, fate });
        }
    }

    /// What the fault model decides for the head frame of `node`. The master is never driven
    /// bus-off: that fate is taken as a destroyed frame.
    fn transmit_fate(&mut self, node: Node, now: Instant) -> TxFate {
        let head = match node {
            Node::Master => self.master_tx.front(),
            Node::Device(i) => self.devices[i].tx.front(),
        };
        let Some(&(_, frame)) = head else { return TxFate::Deliver };
        let station = self.station(node);
        let fate = self.faults.as_mut().map_or(TxFate::Deliver, |f| f.transmit(station, &frame, now));
        match (fate, node) {
            (TxFate::BusOff, Node::Master) => TxFate::Destroy,
            (fate, _) => fate,
        }
    }

    /// Starts a transmission the fault model interferes with.
    fn start_faulty(&mut self, node: Node, fate: TxFate, now: Instant) {
        let head = match node {
            Node::Master => self.master_tx.front().copied(),
            Node::Device(i) => self.devices[i].tx.front().copied(),
        };
        let Some((_, frame)) = head else { return };
        if fate != TxFate::Deliver {
            self.count_error(node, fate, now);
        }
        match fate {
            TxFate::Deliver => {}
            TxFate::Destroy | TxFate::BusOff => {
                // The frame runs to its CRC, then an error frame: nobody receives it.
                let stuffed = u64::from(frame_bits(&frame)).saturating_sub(TAIL_BITS);
                let busy = self.bit_time(stuffed + ERROR_FRAME_BITS);
                self.idle_at = now + busy;
                self.on_wire = Some(OnWire { sender: node, frame, end: now + busy, fate });
                if fate == TxFate::BusOff {
                    if let Node::Device(i) = node {
                        self.bus_off(i, now);
                    }
                } else {
                    self.fault_stats.destroyed += 1;
                }
                return;
            }
            TxFate::Duplicate => self.fault_stats.duplicated += 1,
        }
        self.put_on_wire(node, fate, now);
    }
}

impl Bus for SimBus {
    fn name(&self) -> &str {
        &self.name
    }

    fn now(&mut self) -> Instant {
        self.now
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        self.master_tx.push_back((self.now, *frame));
        self.watch_master(frame);
        Ok(())
    }

    fn error_state(&mut self) -> Option<crate::bus::health::ErrorReport> {
        Some(self.master_error_report())
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError> {
        // Steps taken without the clock moving; a device that keeps asking for the same instant
        // would otherwise stall the simulation.
        let mut still = 0u32;
        loop {
            if let Some(ev) = self.outbox.pop_front() {
                return Ok(Some(ev));
            }
            match self.next_instant() {
                Some(t) if t <= deadline => {
                    if t > self.now {
                        self.pace(t);
                        self.now = t;
                        still = 0;
                    } else {
                        still += 1;
                        if still > MAX_STEPS_PER_INSTANT {
                            return Err(BusError::Adapter(format!(
                                "simulation stalled at {}: a simulated device keeps asking to be called at that instant",
                                self.now
                            )));
                        }
                    }
                    self.step();
                }
                _ => {
                    if deadline > self.now {
                        self.pace(deadline);
                        self.now = deadline;
                    }
                    return Ok(None);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    use super::scripted::{drain, frame, scripted, Log as Received, Scripted};

    /// A scripted device whose bus-offs these tests do not look at.
    fn talker(mac: u8, script: Vec<CanFrame>) -> (Box<Scripted>, Received) {
        let (device, received, _) = scripted(mac, script);
        (device, received)
    }

    #[test]
    fn lowest_identifier_wins_among_frames_pending_together() {
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, _) = talker(5, vec![frame(0x42B, &[1]), frame(0x42B, &[2])]);
        let (b, _) = talker(6, vec![frame(0x3C6, &[3])]);
        bus.attach(a, PowerOn::AtStart);
        bus.attach(b, PowerOn::AtStart);
        bus.send(&frame(0x407, &[0])).unwrap();
        let ids: Vec<u16> =
            drain(&mut bus, Instant::from_secs(1)).iter().map(|e| e.frame.id().as_raw()).collect();
        // All pending at t = 0: 0x3C6 < 0x407 < 0x42B; device 5's second frame waits its turn.
        assert_eq!(ids, vec![0x3C6, 0x407, 0x42B, 0x42B]);
    }

    #[test]
    fn frames_take_their_time_on_the_wire_and_receivers_see_them_at_the_end() {
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, received) = talker(5, vec![]);
        bus.attach(a, PowerOn::AtStart);
        let f = frame(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]);
        bus.send(&f).unwrap();
        bus.send(&f).unwrap();
        let events = drain(&mut bus, Instant::from_secs(1));
        let bits = u64::from(frame_bits(&f));
        let first_end = (bits - 3) * 4; // 4 µs per bit at 250 kbit/s
        assert_eq!(events[0].at, Instant::from_micros(first_end));
        assert_eq!(events[0].origin, Origin::Local);
        assert_eq!(events[1].at, Instant::from_micros(bits * 4 + first_end));
        assert_eq!(received.borrow()[0].0, events[0].at);
        assert_eq!(bus.now(), Instant::from_secs(1));
    }

    /// The master's duplicate MAC ID check request (MAC 0, vendor 1, serial 1).
    fn master_check() -> CanFrame {
        let id = devicenet::Identifier::group2(
            MacId::new(0).unwrap(),
            devicenet::Group2Message::DuplicateMacCheck,
        );
        CanFrame::new(id, &DuplicateMacCheck::request(0, 1, 1).emit()).unwrap()
    }

    #[test]
    fn devices_power_on_one_second_after_the_masters_second_check() {
        let mut bus = SimBus::new(Bitrate::K500);
        let (a, _) = talker(5, vec![frame(0x42F, &[0; 7])]);
        bus.attach(a, PowerOn::WhenMasterOnline);
        bus.send(&master_check()).unwrap();
        let first = drain(&mut bus, Instant::from_secs(1));
        assert_eq!(first.len(), 1, "only the master's own check: the device is still off");
        bus.send(&master_check()).unwrap();
        let events = drain(&mut bus, Instant::from_secs(3));
        assert_eq!(events.len(), 2, "{events:?}");
        assert_eq!(events[0].origin, Origin::Local);
        assert_eq!(events[1].origin, Origin::Remote);
        assert!(events[1].at > Instant::from_secs(2) && events[1].at < Instant::from_millis(2001));
    }

    #[test]
    fn one_check_or_other_traffic_does_not_power_devices_on() {
        let mut bus = SimBus::new(Bitrate::K500);
        let (a, _) = talker(5, vec![frame(0x42F, &[0; 7])]);
        bus.attach(a, PowerOn::WhenMasterOnline);
        bus.send(&master_check()).unwrap();
        bus.send(&frame(0x406, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00])).unwrap();
        let events = drain(&mut bus, Instant::from_secs(5));
        assert!(events.iter().all(|e| e.origin == Origin::Local), "{events:?}");
    }

    #[test]
    fn power_on_at_a_recorded_time() {
        let mut bus = SimBus::new(Bitrate::K250);
        let (a, _) = talker(7, vec![frame(0x43F, &[0; 7])]);
        bus.attach(a, PowerOn::At(Instant::from_millis(1500)));
        let events = drain(&mut bus, Instant::from_secs(3));
        assert_eq!(events.len(), 1);
        assert!(events[0].at > Instant::from_millis(1500) && events[0].at < Instant::from_millis(1501));
    }

    #[test]
    fn known_stuffing() {
        // Identifier 0 and all-zero data stuff heavily; alternating bits not at all.
        let zeros = frame(0x000, &[0; 8]);
        assert!(frame_bits(&zeros) > 47 + 64 + 15);
        let f = frame(0x555, &[0x55; 8]);
        assert!(frame_bits(&f) <= f.worst_case_bits());
    }

    /// A device whose timer never advances.
    struct Stuck;

    impl SimDevice for Stuck {
        fn mac(&self) -> MacId {
            MacId::from_low_bits(9)
        }
        fn power_on(&mut self, _now: Instant) {}
        fn handle_frame(&mut self, _frame: &CanFrame, _now: Instant) {}
        fn handle_timeout(&mut self, _now: Instant) {}
        fn poll_transmit(&mut self) -> Option<CanFrame> {
            None
        }
        fn poll_at(&self) -> Option<Instant> {
            Some(Instant::from_millis(5))
        }
    }

    #[test]
    fn a_stalled_device_is_reported_not_looped_on() {
        let mut bus = SimBus::new(Bitrate::K250);
        bus.attach(Box::new(Stuck), PowerOn::AtStart);
        let err = bus.recv(Instant::from_secs(1)).unwrap_err();
        assert!(err.to_string().contains("simulation stalled at 0.005000s"), "{err}");
    }

    proptest! {
        #[test]
        fn bit_count_between_unstuffed_and_worst_case(id in 0u16..=0x7FF, data in proptest::collection::vec(any::<u8>(), 0..=8)) {
            let f = frame(id, &data);
            let bits = frame_bits(&f);
            prop_assert!(bits >= 47 + 8 * data.len() as u32);
            prop_assert!(bits <= f.worst_case_bits());
        }
    }
}
