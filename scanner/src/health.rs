//! Bus and node health: what the scanner measures of the bus and of each node while it runs,
//! summed up as a score with findings in plain words (guide: docs/src/plant/health.md).
//!
//! [`Health`] is fed by the scanner engine: every frame of every cycle ([`Health::observe`]), the
//! bus's error state once a cycle ([`Health::bus_state`]) and each node's drop-out (its watchdog
//! of 4 × EPR ran out, [`Health::dropped_out`]). It keeps, since the start or the last
//! [`Health::clear`]:
//!
//! - the bus: the controller's error state, TEC and REC where the bus reports them
//!   ([`can_io::bus::Bus::error_state`]), error frames and bus-offs, and the bus load: every
//!   frame's exact bits on the wire, stuff bits included ([`can_io::sim::frame_bits`]), over the
//!   time;
//! - per node: the response time (from the end of the scanner's poll command or bit-strobe to the
//!   end of the node's response; for COS/cyclic nodes, from the scanner's data to the node's
//!   acknowledgement), its share of the bus traffic (bits of the frames from or to it), its
//!   drop-outs and the time of the last one;
//! - incidents: a bus-off, or drop-outs of two nodes or more within [`Health::window`]; each
//!   records the order the nodes went silent in (by the last frame heard from each), so the node
//!   that dropped first is named.
//!
//! The nodes follow the scan list while the scanner runs ([`Health::track`],
//! [`Health::untrack`], [`Health::set_enabled`]): an added node is measured from then on, a
//! removed one leaves the statistics, a disabled one (maintenance) has no drop-outs counted.
//!
//! [`Health::report`] gives all of it with the score and findings ([`report`]); the console serves
//! it as JSON and CSV (`crate::ui`'s `health_api`).
//!
//! Memory is bounded: per node a few counters, at most [`DROP_TIMES_KEPT`] drop-out times, at
//! most [`INCIDENTS_KEPT`] incidents.

pub mod report;
#[cfg(test)]
mod tests;

use can_io::bus::health::{ErrorReport, ErrorState};
use can_io::bus::{Bitrate, Origin};
use devicenet::id::Group1MessageId;
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant};
use std::collections::{BTreeMap, VecDeque};

pub use report::{merge_json, HealthReport, NodeHealthReport};

/// Drop-out times kept per node (the newest), for the interval between drop-outs.
pub const DROP_TIMES_KEPT: usize = 16;
/// Incidents kept (the newest).
pub const INCIDENTS_KEPT: usize = 32;

/// Response time statistics, in µs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Responses {
    /// Responses measured.
    pub count: u64,
    /// Shortest.
    pub min_us: u64,
    /// Longest.
    pub max_us: u64,
    /// Sum of all (for the mean).
    pub sum_us: u64,
}

impl Responses {
    fn add(&mut self, us: u64) {
        if self.count == 0 || us < self.min_us {
            self.min_us = us;
        }
        self.max_us = self.max_us.max(us);
        self.sum_us = self.sum_us.saturating_add(us);
        self.count += 1;
    }

    /// The mean, µs (`None` before the first response).
    pub fn mean_us(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum_us as f64 / self.count as f64)
    }
}

/// What is measured of one node.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeHealth {
    /// Frames from or to the node.
    pub frames: u64,
    /// Their bits on the wire.
    pub bits: u64,
    /// Response times.
    pub responses: Responses,
    /// Drop-outs (its I/O connection timed out).
    pub dropouts: u64,
    /// Bus times of the newest drop-outs, oldest first.
    pub drop_times: VecDeque<Instant>,
    /// The last frame heard from the node.
    pub last_heard: Option<Instant>,
    /// When the scanner's request went out, while the node's answer is awaited.
    awaiting_since: Option<Instant>,
    /// Strobed (answers the scanner's bit-strobe command).
    strobed: bool,
    /// Disabled in the scan list (maintenance): its drop-outs are not counted.
    pub disabled: bool,
}

/// Why an incident was recorded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Cause {
    /// The scanner's controller went bus-off.
    BusOff,
    /// Two nodes or more dropped out within the window.
    DropOuts,
}

/// One node of an incident.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Dropped {
    /// MAC ID.
    pub mac: u8,
    /// The last frame heard from it, bus time µs (`None`: never heard).
    pub last_heard_us: Option<u64>,
    /// When its drop-out was detected, bus time µs.
    pub detected_us: u64,
}

/// A bus-off or a multi-node drop-out.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Incident {
    /// Bus time of the first event (the bus-off, or the first drop-out).
    pub at: Instant,
    /// A bus-off was part of it.
    pub bus_off: bool,
    /// The nodes that dropped out, in the order they went silent (last heard first).
    pub nodes: Vec<Dropped>,
}

impl Incident {
    /// What makes it an incident: a bus-off, or two drop-outs or more.
    pub fn cause(&self) -> Option<Cause> {
        if self.bus_off {
            Some(Cause::BusOff)
        } else if self.nodes.len() >= 2 {
            Some(Cause::DropOuts)
        } else {
            None
        }
    }
}

/// The health of the bus and of every node (module docs).
#[derive(Clone, Debug)]
pub struct Health {
    bitrate: Bitrate,
    master_mac: u8,
    window: Duration,
    /// Start of the statistics (the first frame after the start or a clear).
    since: Option<Instant>,
    /// The latest bus time seen.
    last: Instant,
    frames: u64,
    bits: u64,
    /// The bus's latest error state.
    bus: Option<ErrorReport>,
    /// Error frames and bus-offs the bus had counted at the last clear.
    base: (u64, u64),
    nodes: BTreeMap<u8, NodeHealth>,
    incidents: VecDeque<Incident>,
}

impl Health {
    /// Health for the nodes `macs` (`true`: strobed), of a scanner at `master_mac` running at
    /// `bitrate` with expected packet rate `epr_ms`.
    pub fn new(macs: &[(u8, bool)], master_mac: u8, bitrate: Bitrate, epr_ms: u16) -> Health {
        let epr = Duration::from_millis(u64::from(epr_ms));
        let window = Duration::from_micros((epr.total_micros() * 8).max(1_000_000));
        Health {
            bitrate,
            master_mac,
            window,
            since: None,
            last: Instant::ZERO,
            frames: 0,
            bits: 0,
            bus: None,
            base: (0, 0),
            nodes: macs
                .iter()
                .map(|&(m, strobed)| (m, NodeHealth { strobed, ..NodeHealth::default() }))
                .collect(),
            incidents: VecDeque::new(),
        }
    }

    /// Drop-outs this close together are one incident: 8 × EPR, at least 1 s (two watchdogs of
    /// 4 × EPR).
    pub fn window(&self) -> Duration {
        self.window
    }

    /// Takes one frame that completed on the bus at `at`.
    pub fn observe(&mut self, frame: &CanFrame, origin: Origin, at: Instant) {
        let bits = u64::from(can_io::sim::frame_bits(frame));
        self.since.get_or_insert(at);
        self.last = self.last.max(at);
        self.frames += 1;
        self.bits += bits;
        let (mac, response) = match Identifier::decode(frame.id()) {
            Identifier::Group1 { source, message } => {
                let response =
                    matches!(message, Group1MessageId::POLL_RESPONSE | Group1MessageId::BIT_STROBE_RESPONSE);
                (source.as_raw(), response)
            }
            Identifier::Group2 { mac, message: Group2Message::BitStrobeCommand }
                if origin == Origin::Local =>
            {
                for n in self.nodes.values_mut().filter(|n| n.strobed && !n.disabled) {
                    n.awaiting_since = Some(at);
                }
                (mac.as_raw(), false)
            }
            Identifier::Group2 { mac, message } => {
                if origin == Origin::Local && message == Group2Message::PollCommand {
                    if let Some(n) = self.nodes.get_mut(&mac.as_raw()) {
                        n.awaiting_since = Some(at);
                    }
                }
                (mac.as_raw(), false)
            }
            Identifier::Group3 { source, .. } => (source.as_raw(), false),
            Identifier::Group4 { .. } | Identifier::Invalid(_) => return,
        };
        if mac == self.master_mac {
            return;
        }
        let Some(n) = self.nodes.get_mut(&mac) else { return };
        n.frames += 1;
        n.bits += bits;
        if origin == Origin::Remote {
            n.last_heard = Some(at);
            if response {
                if let Some(sent) = n.awaiting_since.take() {
                    n.responses.add((at - sent).total_micros());
                }
            }
        }
    }

    /// The bus's error state at `now` (once a cycle); a new bus-off starts an incident.
    pub fn bus_state(&mut self, report: Option<ErrorReport>, now: Instant) {
        self.last = self.last.max(now);
        let Some(report) = report else { return };
        let before = self.bus.map_or(self.base.1, |b| b.bus_offs);
        if report.bus_offs > before
            || (report.state == ErrorState::BusOff && self.bus.is_some_and(|b| b.state != ErrorState::BusOff))
        {
            self.incident_at(now).bus_off = true;
        }
        self.bus = Some(report);
    }

    /// Node `mac` is measured from now on (added to the scan list while running), strobed or
    /// not; a node measured already (its entry edited) keeps its figures, with the new connection.
    pub fn track(&mut self, mac: u8, strobed: bool, enabled: bool) {
        if mac == self.master_mac {
            return;
        }
        let n = self.nodes.entry(mac).or_default();
        n.strobed = strobed;
        n.disabled = !enabled;
        n.awaiting_since = None;
    }

    /// Node `mac` leaves the statistics (removed from the scan list). Incidents it was part of
    /// stay: they happened.
    pub fn untrack(&mut self, mac: u8) {
        self.nodes.remove(&mac);
    }

    /// Node `mac` enabled or disabled (maintenance): while disabled, its drop-outs are not
    /// counted (the scanner released it on purpose).
    pub fn set_enabled(&mut self, mac: u8, enabled: bool) {
        if let Some(n) = self.nodes.get_mut(&mac) {
            n.disabled = !enabled;
            n.awaiting_since = None;
        }
    }

    /// Node `mac` dropped out at `now` (its I/O connection timed out); not counted while the node
    /// is disabled or not in the scan list.
    pub fn dropped_out(&mut self, mac: u8, now: Instant) {
        let Some(n) = self.nodes.get_mut(&mac) else { return };
        if n.disabled {
            return;
        }
        n.dropouts += 1;
        n.awaiting_since = None;
        if n.drop_times.len() == DROP_TIMES_KEPT {
            n.drop_times.pop_front();
        }
        n.drop_times.push_back(now);
        let dropped = Dropped {
            mac,
            last_heard_us: n.last_heard.map(Instant::total_micros),
            detected_us: now.total_micros(),
        };
        let incident = self.incident_at(now);
        if !incident.nodes.iter().any(|d| d.mac == mac) {
            incident.nodes.push(dropped);
            incident.nodes.sort_by_key(|d| (d.last_heard_us.unwrap_or(0), d.detected_us));
        }
    }

    /// The incident open at `now` (begun less than [`Health::window`] ago), or a new one.
    fn incident_at(&mut self, now: Instant) -> &mut Incident {
        let open = self.incidents.back().is_some_and(|i| now - i.at <= self.window);
        if !open {
            // A single drop-out without a bus-off is no incident: replaced by the new one.
            if self.incidents.back().is_some_and(|i| i.cause().is_none()) {
                self.incidents.pop_back();
            }
            if self.incidents.len() == INCIDENTS_KEPT {
                self.incidents.pop_front();
            }
            self.incidents.push_back(Incident { at: now, bus_off: false, nodes: Vec::new() });
        }
        let last = self.incidents.len() - 1;
        &mut self.incidents[last]
    }

    /// Clears every statistic at `now` (the bus's current TEC, REC and state stay: they are the
    /// controller's, not counted here).
    pub fn clear(&mut self, now: Instant) {
        if let Some(b) = self.bus {
            self.base = (b.error_frames, b.bus_offs);
        }
        self.since = Some(now);
        self.last = now;
        self.frames = 0;
        self.bits = 0;
        for n in self.nodes.values_mut() {
            *n = NodeHealth { strobed: n.strobed, disabled: n.disabled, ..NodeHealth::default() };
        }
        self.incidents.clear();
    }

    /// The report at bus time `now`: figures, score and findings ([`report`]).
    pub fn report(&self, now: Instant) -> HealthReport {
        report::build(self, now)
    }

    /// The report at the last bus time seen (a scanner that stopped).
    pub fn latest_report(&self) -> HealthReport {
        report::build(self, self.last)
    }
}
