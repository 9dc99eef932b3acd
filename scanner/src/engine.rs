//! The scanner engine: keeps every node of a scan list in I/O, as a DeviceNet scanner does.
//!
//! The engine ([`Scanner`]) is used by `dnet-master scanner` (its summary: [`crate::report`]) and
//! by the web console ([`crate::ui`]).
//! It is driven by its caller: [`Scanner::start`] once (network access, every node brought into
//! I/O), then [`Scanner::cycle`] over and over, [`Scanner::command`] between cycles for what the
//! console asks, [`Scanner::take_samples`] / [`Scanner::take_frames`] to drain what was seen, and
//! [`Scanner::stop`] to release every node.
//!
//! ## A node's life
//!
//! Every node not in I/O runs its bring-up as a sequence of explicit transactions, all nodes in
//! parallel (as [`crate::scan`] does, so absent nodes cost one shared response timeout, and a
//! bring-up never stops the polling of the others): Allocate explicit + the node's connection
//! through the Group 2 Only port (a set still allocated to this master is released and allocated
//! again), Identity attributes 1, 2, 3, 4, 6, 7, the connection's sizes, then the electronic key
//! and the sizes are compared with the scan list (a mismatch: the set is released, the node shows
//! 73 or 77), then (COS with `inhibit_ms`) the production inhibit time, then the EPR (attribute 9),
//! which establishes the connection. A node not in I/O is tried again every
//! [`RECONNECT_INTERVAL`].
//!
//! | `connection` | allocation | sizes read (input, output) | EPR set on |
//! |---|---|---|---|
//! | `poll` | 0x03 | Connection 2 attributes 7, 8 | Connection 2 |
//! | `strobe` | 0x05 | Connection 3 attribute 7; attribute 8 must be 8 (the strobe command), output 0 | Connection 3 |
//! | `cos`, `cyclic` | 0x11 / 0x21, + 0x40 with `ack_suppression` | Connection 4 attribute 7, Connection 2 attribute 8 (the scanner's data) | Connection 4 |
//!
//! (`docs/src/reference/io-connections.md`, protocol §II.1, §II.2; the master's side of each connection is
//! [`master_core::master::io`]'s, here run for every node at once.)
//!
//! ## One scan cycle
//!
//! - *strobe*: when any strobed node is in I/O, one bit-strobe command (8 bytes, Group 2 message
//!   0 with the scanner's MAC, `0x400 | MAC << 3`) with the bit (byte `MAC / 8`, bit `MAC % 8`) of
//!   every strobed node whose output bit is set; every strobed node answers it (Group 1 message
//!   14, at most 8 bytes, never fragmented);
//! - *poll*: every polled node in I/O gets its poll command, all back to back after the strobe;
//! - then the responses are collected (the devices' Group 1 responses win arbitration over the
//!   remaining Group 2 commands, so the bus never idles) until every polled and strobed node
//!   answered or the response window ends; then the inter-scan delay;
//! - *COS and cyclic* nodes are not polled: their productions (Group 1 message 13, reassembled
//!   when over 8 bytes) are taken whenever they come, each acknowledged at once with a zero-length
//!   frame on Group 2 message 2 (not under acknowledge suppression). The scanner's data goes to
//!   them on Group 2 message 5 (fragmented over 8 bytes) when established, then on change (COS) or
//!   every EPR (cyclic), and the node's zero-length acknowledgement on Group 1 message 15 is
//!   expected (not under suppression); data not acknowledged within max(EPR, 100 ms) is sent
//!   again (the Acknowledge Handler's way, §II.2.4), and the node's detail says so.
//!
//! A node's output image is sent only while its status is ok (otherwise zeros, or its strobe bit
//! clear).
//!
//! ## Timing: EPR and inter-scan delay (computed unless the scan list sets them)
//!
//! - *frame time* of a node = worst-case bits ([`devicenet::CanFrame::worst_case_bits`]) of its
//!   frames in a cycle, at the data rate (7 data bytes per fragment above 8 bytes, protocol §4.2):
//!   poll: its command and response; strobe: its response (the strobe command, 8 bytes, counted
//!   once for the list); COS and cyclic: one production, one output of the scanner's data and,
//!   unless suppressed, the two zero-length acknowledgements (at most one of each per cycle for
//!   the EPR's sake: a COS node changing faster adds to the bus load, which is measured);
//! - *minimum cycle* = the sum over the scan list;
//! - inter-scan delay = max(2 ms, minimum cycle / 10), in whole ms;
//! - EPR = max(100 ms, 4 × (minimum cycle + inter-scan delay)), rounded up to 10 ms — so the
//!   device's watchdog (4 × EPR, protocol §5.3) spans at least 16 cycles;
//! - response window = max(20 ms, 2 × minimum cycle), at most the EPR;
//! - a node in I/O with no complete poll response, strobe response or COS/cyclic production for
//!   4 × EPR is *timed out* (72): its connection is dead at the device too (a COS node produces at
//!   the latest every EPR, its heartbeat); if the next attempt to bring it up finds nothing it
//!   becomes *not present* (78).
//!
//! Every node gets the same EPR: for a cyclic node it is the production period, for a COS node
//! the heartbeat.
//!
//! ## Status codes
//!
//! [`crate::model::NodeStatus::code`]: Rockwell's DeviceNet node status codes (guide:
//! docs/src/plant/scanner.md).
//! Communication Faulted is seen on the bus: a duplicate MAC ID *response* at a node's MAC (an
//! on-line device keeping a newcomer with the same MAC off the bus), or two devices announcing
//! different serial numbers at one MAC. The Offline Connection Set (protocol §II.6) is not used.
//!
//! ## Scanner status
//!
//! Another node answering the scanner's duplicate MAC ID check: [`ScannerStatus::DuplicateMac`]
//! (code 70), and [`Scanner::start`] fails. While running, a controller that is not error active
//! (error warning, error passive or bus-off, where the bus reports its error state:
//! [`Bus::error_state`](can_io::bus::Bus::error_state), [`crate::health`]) shows as
//! [`ScannerStatus::BusWarning`] until it is error active again; a bus that fails (an adapter
//! error, an interface gone) is shown as [`ScannerStatus::BusOff`] (code 91) with the cycle ending
//! in the error.
//!
//! ## Limits
//!
//! A console Get or Set ([`Scanner::command`]) waits for its answer between cycles: a COS/cyclic
//! production that comes meanwhile is not taken nor acknowledged (the node sends it again after
//! its acknowledge timer, then at its next trigger).
//!
//! ## Automatic device replacement and scan-list changes
//!
//! Between cycles, every reconnect interval (and when a device ADR waits for comes on-line), the
//! ADR step runs ([`crate::adr`], in `engine/replace.rs`): nodes joined and lost, a device at MAC
//! 63, a replacement's CCV and configuration. [`Scanner::edit`] changes the scan list while the
//! scanner runs (`engine/edit.rs`). Both leave events in [`Scanner::events`].
//!
//! ## Memory
//!
//! The session keeps at most [`RECORDS_KEPT`] frames (older ones are forgotten,
//! [`master_core::session::Session::forget_records_before`]; the log file has them all); samples
//! not taken are capped at [`SAMPLES_KEPT`]; cycle statistics cover the last [`CYCLE_WINDOW`]
//! cycles.

use crate::model::{
    ConsoleCommand, FrameRow, NodeStatus, Sample, ScanEntry, ScanList, ScannerState, ScannerStatus,
};
use crate::monitor::InputLayout;
use can_io::bus::{Bitrate, Origin};
use devicenet::fragment::io_fragments;
use devicenet::id::Group1MessageId;
use devicenet::messages::{AllocationChoice, DuplicateMacCheck};
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant, MacId};
use harness_common::error::HarnessError;
use master_core::bring_up::BringUp;
use master_core::client::Handled;
use master_core::error::MasterError;
use master_core::master::io::IoKind;
use master_core::master::{Master, MIN_POLL_TIMEOUT};
use master_core::session::Verdict;
use std::collections::{HashMap, VecDeque};

mod edit;
mod node;
mod replace;

use crate::timing::{timing, Timing};
pub use edit::ListEditError;
use node::Node;
pub use replace::ADR_MAC;

/// How often a node that is not in I/O is tried again.
pub const RECONNECT_INTERVAL: Duration = Duration::from_secs(1);
/// Frames the session keeps (the newest).
pub const RECORDS_KEPT: usize = 20_000;
/// Samples kept until [`Scanner::take_samples`] (the newest).
pub const SAMPLES_KEPT: usize = 10_000;
/// Cycles over which the median cycle time and the bus load are computed.
pub const CYCLE_WINDOW: usize = 100;

/// The start of a node's detail while its COS/cyclic node did not acknowledge the scanner's data.
const UNACKED: &str = "the scanner's data was not acknowledged";

/// How the scanner runs.
#[derive(Clone, Debug, Default)]
pub struct ScannerOptions {
    /// Stop after this many cycles (the caller counts; `None`: until stopped).
    pub cycles: Option<u64>,
    /// The data rate (for the EPR and inter-scan delay and the bus load).
    pub bitrate: Bitrate,
    /// Per MAC: how to decode its input image into [`Sample::values`] (may be empty).
    pub layouts: HashMap<u8, InputLayout>,
}

/// The scanner. See the [module docs](self).
pub struct Scanner {
    nodes: Vec<Node>,
    state: ScannerState,
    timing: Timing,
    options: ScannerOptions,
    next_reconnect: Option<Instant>,
    samples: VecDeque<Sample>,
    /// Bus and node health ([`crate::health`]).
    health: crate::health::Health,
    frames_cursor: usize,
    /// (cycle length µs, bits on the wire) of the last cycles.
    history: VecDeque<(u64, u64)>,
    /// Automatic device replacement ([`crate::adr`]).
    adr: crate::adr::Adr,
    /// ADR steps and scan-list changes ([`crate::events`]).
    events: crate::events::EventLog,
}

impl Scanner {
    /// A scanner for `list`, at MAC `master_mac`.
    #[must_use]
    pub fn new(list: ScanList, master_mac: u8, options: ScannerOptions) -> Scanner {
        let timing = timing(&list, options.bitrate);
        let nodes: Vec<Node> =
            list.nodes.iter().filter(|e| e.mac <= 63 && e.mac != master_mac).map(Node::new).collect();
        let state = ScannerState {
            mac: master_mac,
            status: ScannerStatus::Starting,
            cycles: 0,
            cycle_ms: 0.0,
            bus_load: 0.0,
            interscan_delay_ms: u32::try_from(timing.interscan.total_millis()).unwrap_or(u32::MAX),
            expected_packet_rate_ms: timing.epr_ms,
            nodes: nodes.iter().map(|n| n.state.clone()).collect(),
        };
        let macs: Vec<(u8, bool)> = nodes.iter().map(|n| (n.entry.mac, n.kind == IoKind::Strobe)).collect();
        let mut health = crate::health::Health::new(&macs, master_mac, options.bitrate, timing.epr_ms);
        for n in nodes.iter().filter(|n| !n.entry.enabled) {
            health.set_enabled(n.entry.mac, false);
        }
        Scanner {
            nodes,
            state,
            timing,
            options,
            next_reconnect: None,
            samples: VecDeque::new(),
            health,
            frames_cursor: 0,
            history: VecDeque::new(),
            adr: crate::adr::Adr::default(),
            events: crate::events::EventLog::default(),
        }
    }

    /// The event log: ADR steps and scan-list changes.
    #[must_use]
    pub fn events(&self) -> &crate::events::EventLog {
        &self.events
    }

    /// The timing in force.
    #[must_use]
    pub fn timing(&self) -> Timing {
        self.timing
    }

    /// The options given.
    #[must_use]
    pub fn options(&self) -> &ScannerOptions {
        &self.options
    }

    /// Network access (unless the master is on-line already, e.g. after a network scan), then
    /// every node's bring-up; returns once every bring-up has ended. A node's fault is its status,
    /// never an error; errors are the scanner's own (its MAC in use, the bus, a stop).
    pub fn start(&mut self, master: &mut Master<'_, '_>) -> Result<(), HarnessError> {
        self.state.status = ScannerStatus::Starting;
        self.frames_cursor = master.session.next_index();
        if master.online_at().is_none() {
            if let Err(e) = master.network_access() {
                return Err(self.fail(e));
            }
        }
        let macs: Vec<MacId> = self.nodes.iter().filter_map(|n| MacId::new(n.entry.mac)).collect();
        if let Err(e) = master.await_online(&macs) {
            return Err(self.fail(e));
        }
        // Duplicate MAC ID checks seen while waiting (two devices at one MAC).
        let seen: Vec<(u8, DuplicateMacCheck, Instant)> = master
            .session
            .records()
            .iter()
            .filter(|r| r.index >= self.frames_cursor && r.origin == Origin::Remote)
            .filter_map(|r| match Identifier::decode(r.frame.id()) {
                Identifier::Group2 { mac, message: Group2Message::DuplicateMacCheck } => {
                    DuplicateMacCheck::parse(r.frame.data()).ok().map(|c| (mac.as_raw(), c, r.at))
                }
                _ => None,
            })
            .collect();
        for (mac, check, at) in seen {
            if let Some(n) = self.nodes.iter_mut().find(|n| n.entry.mac == mac) {
                Self::note_check(n, &check, at);
            }
        }
        let now = master.session.now();
        for i in 0..self.nodes.len() {
            self.begin_bringup(i, master, now);
        }
        self.next_reconnect = Some(now + RECONNECT_INTERVAL);
        // Nodes already in I/O are polled while the others' bring-up goes on (an absent node
        // costs a response timeout, longer than a present node's watchdog).
        while self.nodes.iter().any(Node::busy) {
            self.scan(master, false)?;
        }
        self.state.status = ScannerStatus::Running;
        self.publish();
        Ok(())
    }

    /// Records the scanner's own failure in its status.
    fn fail(&mut self, e: MasterError) -> HarnessError {
        match &e {
            MasterError::DuplicateMac { mac, .. } if *mac == self.state.mac => {
                self.state.status = ScannerStatus::DuplicateMac
            }
            MasterError::Bus(_) => self.state.status = ScannerStatus::BusOff,
            _ => {}
        }
        self.publish();
        HarnessError::Master(e)
    }

    /// Runs the bus until `until`, or until `done` says so: bring-up transactions advanced, poll
    /// responses taken, everything else judged by the master.
    fn pump(
        &mut self,
        master: &mut Master<'_, '_>,
        until: Instant,
        done: impl Fn(&Scanner) -> bool,
    ) -> Result<(), HarnessError> {
        loop {
            let now = master.session.now();
            let epr = self.timing.epr_ms;
            for n in &mut self.nodes {
                while let Some(e) = n.engine.as_mut() {
                    while let Some(f) = e.poll_transmit() {
                        master.session.send(&f).map_err(HarnessError::Master)?;
                    }
                    let Some(event) = e.poll_event() else { break };
                    Self::take_event(n, event, now, epr);
                    if let Some(mac) = MacId::new(n.entry.mac) {
                        master.set_held(mac, n.allocated);
                    }
                }
            }
            if done(self) || now >= until {
                return Ok(());
            }
            let deadline = self
                .nodes
                .iter()
                .filter_map(|n| n.engine.as_ref().and_then(BringUp::poll_at))
                .fold(until, Instant::min);
            match master.session.next(deadline) {
                Ok(Some(i)) => self.handle_record(master, i)?,
                Ok(None) => {
                    let now = master.session.now();
                    for n in &mut self.nodes {
                        if let Some(e) = &mut n.engine {
                            e.handle_timeout(now);
                        }
                    }
                }
                Err(e) => return Err(self.fail(e)),
            }
        }
    }

    fn handle_record(&mut self, master: &mut Master<'_, '_>, i: usize) -> Result<(), HarnessError> {
        let Some(rec) = master.session.get(i).cloned() else { return Ok(()) };
        if rec.origin == Origin::Local {
            return Ok(());
        }
        match Identifier::decode(rec.frame.id()) {
            Identifier::Group1 { message, source } => {
                let Some(n) = self.nodes.iter_mut().find(|n| n.entry.mac == source.as_raw() && n.in_io)
                else {
                    return master.other(i).map_err(|e| self.fail(e));
                };
                let data = rec.frame.data();
                let verdict = match (message, n.kind) {
                    (Group1MessageId::POLL_RESPONSE, IoKind::Poll)
                    | (Group1MessageId::BIT_STROBE_RESPONSE, IoKind::Strobe) => {
                        Self::input(n, data, rec.at, &self.options, &mut self.samples).0
                    }
                    (Group1MessageId::COS_CYCLIC, IoKind::ChangeOfState | IoKind::Cyclic) => {
                        let (v, complete) = Self::input(n, data, rec.at, &self.options, &mut self.samples);
                        if complete && !n.entry.ack_suppression {
                            let ack =
                                CanFrame::new(Identifier::group2(source, Group2Message::CosCyclicAck), &[])
                                    .map_err(|e| HarnessError::Master(MasterError::Frame(e)))?;
                            master.session.send(&ack).map_err(|e| self.fail(e))?;
                        }
                        v
                    }
                    (Group1MessageId::POLL_RESPONSE, IoKind::ChangeOfState | IoKind::Cyclic) => {
                        Self::output_acknowledged(n, data, rec.at)
                    }
                    _ => return master.other(i).map_err(|e| self.fail(e)),
                };
                master.session.set_verdict(i, verdict);
                return Ok(());
            }
            Identifier::Group2 { mac, message: Group2Message::ExplicitResponse } => {
                if let Some(e) = self
                    .nodes
                    .iter_mut()
                    .find(|n| n.entry.mac == mac.as_raw())
                    .and_then(|n| n.engine.as_mut())
                {
                    if let Handled::Frame(v) = e.handle_frame(&rec.frame, rec.at) {
                        master.session.set_verdict(i, v);
                        return Ok(());
                    }
                }
            }
            Identifier::Group2 { mac, message: Group2Message::DuplicateMacCheck } => {
                if let (Some(n), Ok(check)) = (
                    self.nodes.iter_mut().find(|n| n.entry.mac == mac.as_raw()),
                    DuplicateMacCheck::parse(rec.frame.data()),
                ) {
                    Self::note_check(n, &check, rec.at);
                }
                if let Ok(check) = DuplicateMacCheck::parse(rec.frame.data()) {
                    self.adr_note_check(mac.as_raw(), &check, rec.at);
                }
            }
            _ => {}
        }
        master.other(i).map_err(|e| self.fail(e))
    }

    /// A duplicate MAC ID check at a node's MAC: a response, or a second serial number, means two
    /// devices share the MAC (protocol §7.1: the newcomer is Communication Faulted).
    fn note_check(n: &mut Node, check: &DuplicateMacCheck, at: Instant) {
        if check.response {
            n.duplicate = Some(format!(
                "a device at MAC {} answered another's duplicate MAC ID check (vendor 0x{:04X}, serial 0x{:08X} answered): two devices share the MAC, the newcomer is Communication Faulted",
                n.entry.mac, check.vendor_id, check.serial_number
            ));
            return;
        }
        if let Some((serial, when)) = n.announced {
            if serial != check.serial_number && (at - when) < Duration::from_secs(3) {
                n.duplicate = Some(format!(
                    "two devices check MAC {} at once (serials 0x{serial:08X} and 0x{:08X}): both are Communication Faulted",
                    n.entry.mac, check.serial_number
                ));
            }
        }
        n.announced = Some((check.serial_number, at));
    }

    /// Takes a frame of node `n`'s input (a poll or strobe response, a COS/cyclic production):
    /// the verdict, and whether the message is complete (a COS/cyclic production is then
    /// acknowledged).
    fn input(
        n: &mut Node,
        data: &[u8],
        at: Instant,
        options: &ScannerOptions,
        samples: &mut VecDeque<Sample>,
    ) -> (Verdict, bool) {
        let what = n.input_name();
        let produced = n.produced();
        // A strobe response is never fragmented (protocol §II.1.3).
        let whole: Vec<u8> = if data.is_empty() || produced <= 8 || n.kind == IoKind::Strobe {
            data.to_vec()
        } else {
            match n.rx.receive(data) {
                Ok(Some(w)) => w.to_vec(),
                Ok(None) => return (Verdict::Ok(format!("{what} fragment")), false),
                Err(e) => return (Verdict::fail(format!("{what} fragment rejected: {e}")), false),
            }
        };
        n.awaiting = false;
        n.last_exchange = Some(at);
        n.state.last_exchange_us = Some(at.total_micros());
        if whole.is_empty() {
            n.set(NodeStatus::Idle, Some(format!("zero-length {what} (idle)")));
            return (Verdict::Ok(format!("{what}: idle (no data)")), true);
        }
        if whole.len() != usize::from(produced) {
            let why = format!("{what} of {} bytes, expected {produced}", whole.len());
            n.set(NodeStatus::SizeMismatch, Some(why.clone()));
            return (Verdict::fail(why), true);
        }
        n.state.exchanges += 1;
        let detail = if n.state.status == NodeStatus::Ok { n.state.detail.take() } else { None };
        // A note on the scanner's data stays while the node is ok; a duplicate is always shown.
        let detail = n.duplicate.clone().or(detail.filter(|d| d.starts_with(UNACKED)));
        n.set(NodeStatus::Ok, detail);
        let values = options.layouts.get(&n.entry.mac).map(|l| sample_values(l, &whole)).unwrap_or_default();
        if samples.len() >= SAMPLES_KEPT {
            samples.pop_front();
        }
        samples.push_back(Sample {
            mac: n.entry.mac,
            unix_ms: crate::model::unix_ms_now(),
            bus_us: at.total_micros(),
            input: whole.clone(),
            values,
        });
        n.state.input = whole;
        (Verdict::Ok(what.into()), true)
    }

    /// The acknowledgement of the scanner's COS/cyclic data by node `n` (Group 1 message 15,
    /// zero length, protocol §II.2.5).
    fn output_acknowledged(n: &mut Node, data: &[u8], at: Instant) -> Verdict {
        let mut failures = Vec::new();
        if !data.is_empty() {
            failures.push(format!(
                "DLC {}, the acknowledgement of the scanner's data is empty (Connection 2 produced size 0)",
                data.len()
            ));
        }
        let note = if n.entry.ack_suppression {
            failures.push("an acknowledgement under acknowledge suppression (protocol §II.2.1)".into());
            "acknowledgement".to_string()
        } else if let Some(sent) = n.output_ack.take() {
            if n.state.detail.as_deref().is_some_and(|d| d.starts_with(UNACKED)) {
                n.state.detail = n.duplicate.clone();
            }
            format!(
                "acknowledgement of the scanner's data, {:.1} ms after it",
                (at - sent).total_micros() as f64 / 1000.0
            )
        } else {
            failures.push("an acknowledgement while no data of the scanner awaits one".into());
            "acknowledgement".to_string()
        };
        Verdict::Ok(note).with_failures(failures)
    }

    /// One full scan cycle and the inter-scan delay. See the [module docs](self).
    pub fn cycle(&mut self, master: &mut Master<'_, '_>) -> Result<(), HarnessError> {
        self.scan(master, true)
    }

    /// A scan cycle; `counted`: in the cycle count and statistics (not during [`Scanner::start`]).
    fn scan(&mut self, master: &mut Master<'_, '_>, counted: bool) -> Result<(), HarnessError> {
        let t0 = master.session.now();
        let first = master.session.next_index();
        if self.next_reconnect.is_none_or(|t| t0 >= t) {
            self.adr_step(master, t0)?;
            for i in 0..self.nodes.len() {
                let deferred = self.adr_defers(self.nodes[i].entry.mac, t0);
                if !self.nodes[i].in_io && !self.nodes[i].busy() && self.nodes[i].entry.enabled && !deferred {
                    self.begin_bringup(i, master, t0);
                }
            }
            self.next_reconnect = Some(self.next_reconnect_after(t0, t0 + RECONNECT_INTERVAL));
        }
        let mut commands: Vec<CanFrame> = Vec::new();
        // One bit-strobe command for every strobed node (protocol §II.1.2).
        let mut strobe = [0u8; 8];
        let mut strobed = false;
        for n in self.nodes.iter_mut().filter(|n| n.in_io && n.kind == IoKind::Strobe) {
            let m = n.entry.mac;
            if n.output_now().first().is_some_and(|b| b & 1 == 1) {
                strobe[usize::from(m / 8)] |= 1 << (m % 8);
            }
            n.awaiting = true;
            strobed = true;
        }
        if strobed {
            commands.extend(CanFrame::new(master.strobe_id(), &strobe));
        }
        for n in self.nodes.iter_mut().filter(|n| n.in_io && n.kind == IoKind::Poll) {
            let Some(mac) = MacId::new(n.entry.mac) else { continue };
            let id = Identifier::group2(mac, Group2Message::PollCommand);
            let output = n.output_now();
            if n.consumed() > 8 {
                commands.extend(io_fragments(&output).filter_map(|p| CanFrame::new(id, &p).ok()));
            } else {
                commands.extend(CanFrame::new(id, &output));
            }
            n.awaiting = true;
        }
        // The scanner's COS/cyclic data: on change (COS), every EPR (cyclic), again when not
        // acknowledged in time.
        let epr = Duration::from_millis(u64::from(self.timing.epr_ms));
        let ack_timeout = if epr > MIN_POLL_TIMEOUT { epr } else { MIN_POLL_TIMEOUT };
        for n in self.nodes.iter_mut().filter(|n| n.in_io && n.kind.is_cos_cyclic()) {
            let Some(mac) = MacId::new(n.entry.mac) else { continue };
            let output = n.output_now();
            let late = n.output_ack.is_some_and(|sent| t0 - sent >= ack_timeout);
            if late {
                n.output_ack = None;
                if n.state.status == NodeStatus::Ok && n.duplicate.is_none() {
                    n.state.detail =
                        Some(format!("{UNACKED} within {} ms: sent again", ack_timeout.total_millis()));
                }
            }
            let due = match n.kind {
                IoKind::Cyclic => t0 >= n.next_output,
                _ => n.output_sent.as_ref() != Some(&output),
            };
            if !(due || late) {
                continue;
            }
            let id = Identifier::group2(mac, Group2Message::PollCommand);
            if n.consumed() > 8 {
                commands.extend(io_fragments(&output).filter_map(|p| CanFrame::new(id, &p).ok()));
            } else {
                commands.extend(CanFrame::new(id, &output));
            }
            if t0 >= n.next_output {
                n.next_output = t0 + epr;
            }
            n.output_sent = Some(output);
            if !n.entry.ack_suppression {
                n.output_ack = Some(t0);
            }
        }
        for f in &commands {
            if let Err(e) = master.session.send(f) {
                return Err(self.fail(e));
            }
        }
        self.pump(master, t0 + self.timing.window, |s| s.nodes.iter().all(|n| !n.awaiting))?;
        self.adr_cycle(master)?;
        let isd_end = master.session.now() + self.timing.interscan;
        self.pump(master, isd_end, |_| false)?;
        let now = master.session.now();
        for r in master.session.records().iter().filter(|r| r.index >= first) {
            self.health.observe(&r.frame, r.origin, r.at);
        }
        let controller = master.session.error_state();
        self.health.bus_state(controller, now);
        if matches!(self.state.status, ScannerStatus::Running | ScannerStatus::BusWarning) {
            let troubled = controller.is_some_and(|c| c.state != can_io::bus::health::ErrorState::Active);
            self.state.status = if troubled { ScannerStatus::BusWarning } else { ScannerStatus::Running };
        }
        // The device's watchdog is 4 x EPR (protocol §5.3): no response for that long, the
        // connection is gone at both ends.
        let watchdog = Duration::from_millis(4 * u64::from(self.timing.epr_ms));
        for n in &mut self.nodes {
            if n.in_io && now - n.last_exchange.unwrap_or(n.in_io_since) > watchdog {
                n.in_io = false;
                n.awaiting = false;
                n.output_ack = None;
                n.allocated = AllocationChoice::empty();
                if let Some(mac) = MacId::new(n.entry.mac) {
                    master.set_held(mac, n.allocated);
                }
                let what = n.input_name();
                n.set(
                    NodeStatus::TimedOut,
                    Some(format!("no {what} for {} ms (4 x EPR)", watchdog.total_millis())),
                );
                self.health.dropped_out(n.entry.mac, now);
            }
        }
        let bits: u64 = master
            .session
            .records()
            .iter()
            .filter(|r| r.index >= first)
            .map(|r| u64::from(can_io::sim::frame_bits(&r.frame)))
            .sum();
        if counted {
            if self.history.len() >= CYCLE_WINDOW {
                self.history.pop_front();
            }
            self.history.push_back(((now - t0).total_micros(), bits));
            self.state.cycles += 1;
            self.stats();
        }
        // Bounded memory: records already taken, and everything beyond the newest RECORDS_KEPT.
        let end = master.session.next_index();
        let forget = end.saturating_sub(RECORDS_KEPT).max(self.frames_cursor.min(end));
        master.session.forget_records_before(forget);
        self.frames_cursor = self.frames_cursor.max(master.session.first_kept());
        self.publish();
        Ok(())
    }

    fn stats(&mut self) {
        let mut lengths: Vec<u64> = self.history.iter().map(|h| h.0).collect();
        lengths.sort_unstable();
        let median = match lengths.len() {
            0 => 0.0,
            n if n % 2 == 1 => lengths[n / 2] as f64,
            n => (lengths[n / 2 - 1] + lengths[n / 2]) as f64 / 2.0,
        };
        self.state.cycle_ms = median / 1000.0;
        let time: u64 = self.history.iter().map(|h| h.0).sum();
        let bits: u64 = self.history.iter().map(|h| h.1).sum();
        let bps = f64::from(self.options.bitrate.bits_per_second().max(1));
        self.state.bus_load = if time == 0 { 0.0 } else { (bits as f64 / bps) / (time as f64 / 1e6) };
    }

    fn publish(&mut self) {
        self.state.nodes = self.nodes.iter().map(|n| n.state.clone()).collect();
    }

    /// The scanner's state after the last cycle.
    #[must_use]
    pub fn state(&self) -> &ScannerState {
        &self.state
    }

    /// The bus and node health ([`crate::health`]).
    #[must_use]
    pub fn health(&self) -> &crate::health::Health {
        &self.health
    }

    /// The lengths of the last full cycles in µs, oldest first (their median is
    /// [`ScannerState::cycle_ms`]).
    #[must_use]
    pub fn cycle_lengths_us(&self) -> Vec<u64> {
        self.history.iter().map(|h| h.0).collect()
    }

    /// Carries out a console command and answers on its reply channel (an answer nobody waits for
    /// any more is dropped).
    pub fn command(&mut self, master: &mut Master<'_, '_>, cmd: ConsoleCommand) {
        match cmd {
            ConsoleCommand::SetOutput { mac, data, reply } => {
                let answer = match self.nodes.iter_mut().find(|n| n.entry.mac == mac) {
                    None => Err(format!("MAC {mac} is not in the scan list")),
                    Some(n) if n.state.status != NodeStatus::Ok => Err(format!(
                        "MAC {mac} is {} (code {}): outputs go only to a node that is ok",
                        n.state.status.name(),
                        n.state.code
                    )),
                    Some(n) if n.kind == IoKind::Strobe && (data.len() != 1 || data[0] > 1) => Err(format!(
                        "MAC {mac} is strobed: its output is its strobe bit, 1 byte 00 or 01 ({} bytes given)",
                        data.len()
                    )),
                    Some(n) if data.len() != n.output_len() => {
                        Err(format!("{} bytes given; MAC {mac} consumes {} bytes", data.len(), n.consumed()))
                    }
                    Some(n) => {
                        n.state.output = data;
                        Ok(Vec::new())
                    }
                };
                self.publish();
                let _ = reply.send(answer);
            }
            ConsoleCommand::Get { mac, class, instance, attribute, reply } => {
                let answer = self.explicit(master, mac, class, instance, attribute, None);
                let _ = reply.send(answer);
            }
            ConsoleCommand::Set { mac, class, instance, attribute, value, reply } => {
                let answer = self.explicit(master, mac, class, instance, attribute, Some(&value));
                let _ = reply.send(answer);
            }
            ConsoleCommand::Request { mac, service, class, instance, data, reply } => {
                let answer = self.explicit_request(master, mac, service, class, instance, &data);
                let _ = reply.send(answer);
            }
            ConsoleCommand::Events { since, reply } => {
                let _ = reply.send(self.events.since(since));
            }
            ConsoleCommand::EditList { edit, reply } => {
                let answer = self.edit(master, edit).map(|()| Vec::new()).map_err(|e| e.to_string());
                self.publish();
                let _ = reply.send(answer);
            }
            ConsoleCommand::Health { clear, reply } => {
                let now = master.session.now();
                if clear {
                    self.health.clear(now);
                }
                let _ = reply.send(self.health.report(now));
            }
        }
    }

    /// `mac` as the target of a console request: a node of the scan list with its explicit
    /// connection usable now (in I/O and not busy), or why not.
    fn explicit_target(&self, mac: u8) -> Result<MacId, String> {
        let n = self
            .nodes
            .iter()
            .find(|n| n.entry.mac == mac)
            .ok_or(format!("MAC {mac} is not in the scan list"))?;
        if !n.in_io || n.busy() {
            return Err(format!("MAC {mac} has no explicit connection now ({})", n.state.status.name()));
        }
        MacId::new(mac).ok_or(format!("MAC {mac} is out of range"))
    }

    fn explicit(
        &mut self,
        master: &mut Master<'_, '_>,
        mac: u8,
        class_id: u16,
        instance: u16,
        attribute: u8,
        value: Option<&[u8]>,
    ) -> Result<Vec<u8>, String> {
        let target = self.explicit_target(mac)?;
        let r = match value {
            Some(v) => master.set(target, class_id, instance, attribute, v),
            None => master.get(target, class_id, instance, attribute),
        };
        r.map(|(data, _)| data).map_err(|e| e.to_string())
    }

    /// [`ConsoleCommand::Request`]: `service` with `data` on `mac`'s explicit connection.
    fn explicit_request(
        &mut self,
        master: &mut Master<'_, '_>,
        mac: u8,
        service: u8,
        class: u16,
        instance: u16,
        data: &[u8],
    ) -> Result<master_core::client::ReplyBody, String> {
        let target = self.explicit_target(mac)?;
        let request = devicenet::explicit::Request {
            service: devicenet::explicit::ServiceCode::from(service),
            class,
            instance,
            data,
        };
        master
            .request(target, master_core::client::Port::Explicit, &request)
            .map(|answer| answer.reply.body)
            .map_err(|e| e.to_string())
    }

    /// The input samples received since the last call, oldest first.
    pub fn take_samples(&mut self) -> Vec<Sample> {
        self.samples.drain(..).collect()
    }

    /// The frames seen since the last call (at most the [`RECORDS_KEPT`] newest), decoded.
    pub fn take_frames(&mut self, master: &mut Master<'_, '_>) -> Vec<FrameRow> {
        let from = self.frames_cursor.max(master.session.first_kept());
        let rows: Vec<FrameRow> = master
            .session
            .records()
            .iter()
            .filter(|r| r.index >= from)
            .map(|r| {
                let (kind, mac) = frame_kind(&r.frame);
                let (meaning, message) = match r.meaning.split_once(" => ") {
                    Some((s, m)) => (s.to_string(), Some(m.to_string())),
                    None => (r.meaning.clone(), None),
                };
                FrameRow {
                    seq: r.index as u64 + 1,
                    time_us: r.at.total_micros(),
                    frame: r.frame.to_string(),
                    id: r.frame.id().as_raw(),
                    data: r.frame.data().to_vec(),
                    own: r.origin == Origin::Local,
                    mac,
                    kind: kind.into(),
                    meaning,
                    message,
                }
            })
            .collect();
        let end = master.session.next_index();
        self.frames_cursor = end;
        master.session.forget_records_before(end);
        rows
    }

    /// Releases every node this scanner holds (through the Group 2 Only port), after one response
    /// window in which no poll is sent: an answer to the last poll still on its way (a node on a
    /// slow link answering one poll behind) is taken as the node's input then, not met by the
    /// Release as a frame nothing expects.
    pub fn stop(&mut self, master: &mut Master<'_, '_>) -> Result<(), HarnessError> {
        for n in &mut self.nodes {
            n.engine = None;
            n.awaiting = false;
        }
        if self.nodes.iter().any(|n| n.in_io) {
            let drain = master.session.now() + self.timing.window;
            // A bus that fails here fails the Release below too, which says so.
            let _ = self.pump(master, drain, |_| false);
        }
        let r = master.release_held();
        for n in &mut self.nodes {
            n.in_io = false;
            n.allocated = AllocationChoice::empty();
        }
        self.state.status = ScannerStatus::Stopped;
        self.publish();
        r.map(|_| ()).map_err(|e| HarnessError::Release(Box::new(e)))
    }
}

/// The console's message kind of a frame, and the MAC it concerns.
#[must_use]
pub fn frame_kind(frame: &CanFrame) -> (&'static str, Option<u8>) {
    match Identifier::decode(frame.id()) {
        Identifier::Group1 { source, .. } => ("io", Some(source.as_raw())),
        Identifier::Group2 { mac, message } => match message {
            Group2Message::DuplicateMacCheck => ("duplicate_mac", Some(mac.as_raw())),
            Group2Message::PollCommand | Group2Message::BitStrobeCommand | Group2Message::CosCyclicAck => {
                ("io", Some(mac.as_raw()))
            }
            _ => ("explicit", Some(mac.as_raw())),
        },
        Identifier::Group3 { source, .. } => ("ucmm", Some(source.as_raw())),
        Identifier::Group4 { .. } => ("offline", None),
        Identifier::Invalid(_) => ("invalid", None),
    }
}

/// The values of an input image decoded by `layout`: one per field value, a field with several
/// values named `name[i]`.
#[must_use]
pub fn sample_values(layout: &InputLayout, input: &[u8]) -> Vec<(String, f64)> {
    let decoded = layout.decode(input);
    let mut values = Vec::new();
    for f in decoded.fields {
        match f.values.as_slice() {
            [one] => values.push((f.name, f64::from(*one))),
            many => {
                for (i, v) in many.iter().enumerate() {
                    values.push((format!("{}[{i}]", f.name), f64::from(*v)));
                }
            }
        }
    }
    values
}

/// A scan list from a network scan of MAC `from..=to` ([`crate::scan`]): each device with a poll
/// connection, keyed by what it answered (vendor, device type, product code, major revision),
/// named by its product name. Devices without a poll connection are left out; every node is
/// polled (edit `connection` for strobe, COS or cyclic).
pub fn build_scan_list(master: &mut Master<'_, '_>, from: u8, to: u8) -> Result<ScanList, HarnessError> {
    let report = crate::scan::scan(master, from, to, &mut harness_common::console::Progress::off())?;
    let nodes = report
        .devices
        .iter()
        .filter_map(|d| {
            Some(ScanEntry {
                mac: d.mac,
                connection: "poll".into(),
                ack_suppression: false,
                inhibit_ms: None,
                vendor_id: d.identity.vendor_id,
                device_type: d.identity.device_type,
                product_code: d.identity.product_code,
                major_revision: d
                    .identity
                    .revision
                    .as_deref()
                    .and_then(|r| r.split('.').next())
                    .and_then(|m| m.parse().ok()),
                minor_revision: None,
                input_size: d.produced_size?,
                output_size: d.consumed_size?,
                name: d.identity.product_name.clone(),
                adr: crate::model::AdrMode::Off,
                keying: crate::model::Keying::Exact,
                enabled: true,
            })
        })
        .collect();
    Ok(ScanList { interscan_delay_ms: None, expected_packet_rate_ms: None, nodes })
}
