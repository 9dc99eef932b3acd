//! The master: network access, the bring-up of protocol §2 decided frame by frame from the device's
//! answers, explicit messaging and polling.
//!
//! ## Timing (the master's own choices, protocol §9.1 and §9.4)
//!
//! | constant | value | what |
//! |---|---|---|
//! | [`DUP_MAC_INTERVAL`] | 1 s | between the master's two duplicate MAC ID requests, and from the second to on-line (protocol §7.1) |
//! | [`DEVICE_ONLINE_GRACE`] | 1 s | after going on-line, how long the master waits for the device's own duplicate MAC ID check before taking the device as already on-line |
//! | [`UCMM_TIMEOUT`] | 500 ms | wait for a UCMM open response; the request is sent twice, then the device is taken as group-2-only |
//! | `--timeout` | 1 s | explicit response timeout ([`crate::client::DEFAULT_RESPONSE_TIMEOUT`]) |
//! | poll response timeout | the EPR, at least 100 ms | wait for a complete poll response |
//!
//! A device's duplicate MAC ID check is watched on the bus: after its first request it is on-line
//! 2 s later, after its second 1 s later (protocol §7.1).

use crate::bring_up::Step;
use crate::client::{self, ClientError, Port, Reply, ReplyBody, Transaction};
use crate::decode::{self, hex, PendingRequest};
use crate::error::{MasterError, UsageError};
use crate::session::{is_from_device, Record, Session, Verdict};
use can_io::bus::Origin;
use devicenet::explicit::{BodyFormat, GeneralStatus, Header, Request, ServiceCode};
use devicenet::fragment::io_fragments;
use devicenet::id::{Group1MessageId, Group3MessageId};
use devicenet::messages::{
    AllocationChoice, DuplicateMacCheck, GroupSelect, UcmmCloseRequest, UcmmOpenRequest, UcmmOpenResponse,
};
use devicenet::objects::class;
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant, MacId};
use std::collections::HashMap;

mod connect;
pub mod io;
mod node;
pub mod recovery;

pub use connect::{ConnectOptions, DeviceSummary};
pub use node::NodeEvent;
#[cfg(test)]
mod scripted;

/// Between the two duplicate MAC ID requests, and from the second to on-line (protocol §7.1).
pub const DUP_MAC_INTERVAL: Duration = devicenet::slave::DUP_MAC_INTERVAL;
/// How long the master waits, once on-line, for a device's duplicate MAC ID check to show.
pub const DEVICE_ONLINE_GRACE: Duration = Duration::from_secs(1);
/// How long the master waits for a UCMM open response (sent twice).
pub const UCMM_TIMEOUT: Duration = Duration::from_millis(500);
/// The shortest poll response timeout.
pub const MIN_POLL_TIMEOUT: Duration = Duration::from_millis(100);

/// The master's identity and timing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MasterConfig {
    /// The master's MAC ID (`--master-mac`).
    pub mac: MacId,
    /// Vendor ID sent in its duplicate MAC ID checks (protocol §2: 0x0001).
    pub vendor_id: u16,
    /// Serial number sent in its duplicate MAC ID checks (protocol §2: 0x01020304).
    pub serial_number: u32,
    /// Explicit response timeout (`--timeout`).
    pub response_timeout: Duration,
}

impl Default for MasterConfig {
    fn default() -> Self {
        MasterConfig {
            mac: MacId::from_low_bits(0),
            vendor_id: 0x0001,
            serial_number: 0x0102_0304,
            response_timeout: client::DEFAULT_RESPONSE_TIMEOUT,
        }
    }
}

/// What the master saw of devices' duplicate MAC ID checks.
#[derive(Clone, Debug, Default)]
pub struct OnlineTracker {
    /// Per MAC: requests seen, time of the last one, the key sent.
    seen: HashMap<u8, (u8, Instant, DuplicateMacCheck)>,
}

impl OnlineTracker {
    /// Notes a duplicate MAC ID request from `mac` at `at`; returns how many were seen.
    pub fn note(&mut self, mac: u8, at: Instant, check: DuplicateMacCheck) -> u8 {
        let e = self.seen.entry(mac).or_insert((0, at, check));
        e.0 = e.0.saturating_add(1);
        e.1 = at;
        e.2 = check;
        e.0
    }

    /// When `mac` is on-line, if its check was seen: 2 s after a first request, 1 s after a second.
    pub fn online_at(&self, mac: u8) -> Option<Instant> {
        self.seen.get(&mac).map(|&(n, at, _)| {
            at + if n >= 2 { DUP_MAC_INTERVAL } else { DUP_MAC_INTERVAL + DUP_MAC_INTERVAL }
        })
    }

    /// The vendor/serial `mac` announced.
    pub fn announced(&self, mac: u8) -> Option<DuplicateMacCheck> {
        self.seen.get(&mac).map(|&(_, _, c)| c)
    }

    /// MACs whose check was seen.
    pub fn macs(&self) -> Vec<u8> {
        let mut v: Vec<u8> = self.seen.keys().copied().collect();
        v.sort_unstable();
        v
    }
}

/// The master on a session. See the [module docs](self).
pub struct Master<'s, 'b> {
    /// The session (bus + transcript).
    pub session: &'s mut Session<'b>,
    /// Identity and timing.
    pub config: MasterConfig,
    /// Devices' duplicate MAC ID checks seen.
    pub tracker: OnlineTracker,
    online_at: Option<Instant>,
    /// The device under test, for judging unexpected frames.
    device: Option<MacId>,
    body_format: BodyFormat,
    xid: bool,
    last_record: Option<usize>,
    /// What this master holds allocated, per device (allocations minus releases).
    held: HashMap<u8, AllocationChoice>,
    /// What the user should know about how the command went (re-allocations).
    notices: Vec<String>,
    /// The strobe, COS or cyclic connection established ([`Master::establish_io`]).
    io: Option<io::IoConnection>,
    /// The bring-up engine of each device the master talked to ([`Master::step`]).
    nodes: HashMap<u8, crate::bring_up::BringUp>,
}

/// The outcome of an explicit request, kept with its record.
pub struct Answer {
    /// The reply.
    pub reply: Reply,
    /// The record that completed it.
    pub record: Option<usize>,
}

fn step_name(req: &Request<'_>) -> String {
    decode::request_text(req)
}

impl<'s, 'b> Master<'s, 'b> {
    /// A master on `session`.
    pub fn new(session: &'s mut Session<'b>, config: MasterConfig) -> Self {
        Master {
            session,
            config,
            tracker: OnlineTracker::default(),
            online_at: None,
            device: None,
            body_format: BodyFormat::Class8Instance8,
            xid: false,
            last_record: None,
            held: HashMap::new(),
            notices: Vec::new(),
            io: None,
            nodes: HashMap::new(),
        }
    }

    /// Sets the device under test (frames from it that nothing expects are failures).
    pub fn set_device(&mut self, mac: MacId) {
        self.device = Some(mac);
    }

    /// When the master went on-line.
    pub fn online_at(&self) -> Option<Instant> {
        self.online_at
    }

    /// The next frame from another node that `wanted` accepts, before `deadline`, with its index;
    /// every other frame meanwhile goes to [`Master::other`]. `None` when the deadline passed.
    pub fn next_wanted(
        &mut self,
        deadline: Instant,
        wanted: impl Fn(&CanFrame) -> bool,
    ) -> Result<Option<(usize, Record)>, MasterError> {
        while let Some(i) = self.session.next(deadline)? {
            let rec = self.session.record(i).clone();
            if rec.origin == Origin::Local {
                continue;
            }
            if !wanted(&rec.frame) {
                self.other(i)?;
                continue;
            }
            return Ok(Some((i, rec)));
        }
        Ok(None)
    }

    /// Judges a frame nobody waits for: devices' duplicate MAC ID checks are noted (and checked),
    /// a check of the master's own MAC is answered (protocol §7.1), frames from the device under test
    /// are unexpected, everything else is other traffic.
    pub fn other(&mut self, i: usize) -> Result<(), MasterError> {
        let rec = self.session.record(i).clone();
        if rec.origin == Origin::Local {
            return Ok(());
        }
        if self.io_claims(i)? {
            return Ok(());
        }
        if let Identifier::Group2 { mac, message: Group2Message::DuplicateMacCheck } =
            Identifier::decode(rec.frame.id())
        {
            let check = match DuplicateMacCheck::parse(rec.frame.data()) {
                Ok(c) => c,
                Err(e) => {
                    self.session
                        .set_verdict(i, Verdict::fail(format!("malformed duplicate MAC ID check: {e}")));
                    return Ok(());
                }
            };
            if mac == self.config.mac {
                if check.response || self.online_at.is_none() {
                    self.session.set_verdict(i, Verdict::fail("another node uses the master's MAC ID"));
                    return Err(MasterError::DuplicateMac {
                        mac: mac.as_raw(),
                        detail: format!(
                            "a node with vendor 0x{:04X}, serial 0x{:08X} claims it",
                            check.vendor_id, check.serial_number
                        ),
                    });
                }
                // On-line: answer, to keep the newcomer off the bus (protocol §7.1 rule 3).
                let response =
                    DuplicateMacCheck::response(0, self.config.vendor_id, self.config.serial_number);
                let id = Identifier::group2(self.config.mac, Group2Message::DuplicateMacCheck);
                if let Ok(f) = CanFrame::new(id, &response.emit()) {
                    self.session.send(&f)?;
                }
                self.session
                    .set_verdict(i, Verdict::Info("a newcomer checks the master's MAC: answered".into()));
                return Ok(());
            }
            if check.response {
                let verdict = if Some(mac) == self.device {
                    Verdict::fail("duplicate MAC ID response: another node holds the device's MAC ID")
                } else {
                    Verdict::Info("duplicate MAC ID response".into())
                };
                self.session.set_verdict(i, verdict);
                return Ok(());
            }
            let n = self.tracker.note(mac.as_raw(), rec.at, check);
            let note = format!(
                "duplicate MAC ID check #{n} of MAC {mac}: vendor 0x{:04X}, serial 0x{:08X}",
                check.vendor_id, check.serial_number
            );
            let verdict =
                if n > 2 { Verdict::Ok(format!("{note} (check restarted)")) } else { Verdict::Ok(note) };
            self.session.set_verdict(i, verdict);
            return Ok(());
        }
        match self.device {
            Some(d) => client::judge_other(self.session, i, d),
            None => self.session.set_verdict(i, Verdict::Info("other traffic".into())),
        }
        Ok(())
    }

    /// Waits until `deadline`, judging what arrives.
    pub fn idle_until(&mut self, deadline: Instant) -> Result<(), MasterError> {
        while let Some(i) = self.session.next(deadline)? {
            self.other(i)?;
        }
        Ok(())
    }

    /// The master's own network access (protocol §7.1): two duplicate MAC ID requests 1 s apart,
    /// on-line 1 s after the second unless another node claims the MAC.
    pub fn network_access(&mut self) -> Result<(), MasterError> {
        let check = DuplicateMacCheck::request(0, self.config.vendor_id, self.config.serial_number);
        let id = Identifier::group2(self.config.mac, Group2Message::DuplicateMacCheck);
        let frame = CanFrame::new(id, &check.emit())?;
        for _ in 0..2 {
            let sent = self.session.now();
            self.session.send(&frame)?;
            self.idle_until(sent + DUP_MAC_INTERVAL)?;
        }
        let now = self.session.now();
        self.online_at = Some(now);
        Ok(())
    }

    /// Waits until `mac` is on-line: until 1 s after its second duplicate MAC ID request when the
    /// check shows on the bus, else for [`DEVICE_ONLINE_GRACE`].
    pub fn await_online(&mut self, macs: &[MacId]) -> Result<(), MasterError> {
        let grace = self.online_at.unwrap_or(Instant::ZERO) + DEVICE_ONLINE_GRACE;
        loop {
            // A device whose check showed is on-line at its own time; one that did not show is
            // waited for until the grace period ends.
            let deadline = macs
                .iter()
                .map(|m| self.tracker.online_at(m.as_raw()).unwrap_or(grace))
                .max()
                .unwrap_or(grace);
            if self.session.now() >= deadline {
                return Ok(());
            }
            match self.session.next(deadline)? {
                Some(i) => self.other(i)?,
                None => return Ok(()),
            }
        }
    }

    /// UCMM open explicit connection to `target`, sent up to twice (protocol §2 frames 4–5, §3.6).
    /// Returns whether the device answered (UCMM-capable); a group-2-only device stays silent.
    pub fn ucmm_probe(&mut self, target: MacId) -> Result<bool, MasterError> {
        let open = UcmmOpenRequest {
            xid: false,
            destination: target,
            body_format: BodyFormat::Class8Instance8,
            group_select: GroupSelect::Group3,
            source_message_id: 4,
        };
        let id =
            Identifier::Group3 { message: Group3MessageId::UNCONNECTED_REQUEST, source: self.config.mac }
                .encode();
        let response_id =
            Identifier::Group3 { message: Group3MessageId::UNCONNECTED_RESPONSE, source: target }.encode();
        let frame = CanFrame::new(id, &open.emit())?;
        for _ in 0..2 {
            let sent = self.session.now();
            self.session.send(&frame)?;
            let deadline = sent + UCMM_TIMEOUT;
            while let Some(i) = self.session.next(deadline)? {
                let rec = self.session.record(i).clone();
                if rec.origin == Origin::Remote && rec.frame.id() == response_id {
                    return self.ucmm_answered(i, target);
                }
                self.other(i)?;
            }
        }
        Ok(false)
    }

    fn ucmm_answered(&mut self, i: usize, target: MacId) -> Result<bool, MasterError> {
        let rec = self.session.record(i).clone();
        match UcmmOpenResponse::parse(rec.frame.data()) {
            Ok(r) if r.destination == self.config.mac => {
                self.session.set_verdict(
                    i,
                    Verdict::Ok("UCMM-capable device; closing, then the Group 2 Only port".into()),
                );
                let close = UcmmCloseRequest {
                    xid: false,
                    destination: target,
                    connection_instance: r.connection_instance,
                };
                let id = Identifier::Group3 {
                    message: Group3MessageId::UNCONNECTED_REQUEST,
                    source: self.config.mac,
                }
                .encode();
                if let Ok(f) = CanFrame::new(id, &close.emit()) {
                    self.session.send(&f)?;
                }
                let response_id =
                    Identifier::Group3 { message: Group3MessageId::UNCONNECTED_RESPONSE, source: target }
                        .encode();
                let deadline = self.session.now() + UCMM_TIMEOUT;
                while let Some(j) = self.session.next(deadline)? {
                    let rec = self.session.record(j).clone();
                    if rec.origin == Origin::Remote && rec.frame.id() == response_id {
                        self.session.set_verdict(j, Verdict::Ok("UCMM close answered".into()));
                        break;
                    }
                    self.other(j)?;
                }
            }
            Ok(r) => self.session.set_verdict(
                i,
                Verdict::fail(format!("UCMM response addressed to MAC {}, not the master", r.destination)),
            ),
            Err(_) => {
                self.session.set_verdict(i, Verdict::Ok("UCMM answered (error or unknown form)".into()))
            }
        }
        Ok(true)
    }

    /// Drives `tx` to its end on the session ([`client::run`]); the frames that were not part of
    /// the exchange are judged once it is over, in order ([`Master::other`]). For requests built
    /// by the caller, e.g. sent as another master would.
    pub fn run(&mut self, tx: &mut Transaction) -> Result<client::Outcome<usize>, MasterError> {
        let mut deferred: Vec<usize> = Vec::new();
        let outcome = client::run(self.session, tx, |_, i| deferred.push(i))?;
        for i in deferred {
            self.other(i)?;
        }
        Ok(outcome)
    }

    /// Sends `request` to `target` and waits for the complete answer (fragmented both ways as
    /// needed). A timeout is an error naming the request and the timeout.
    pub fn request(
        &mut self,
        target: MacId,
        port: Port,
        request: &Request<'_>,
    ) -> Result<Answer, MasterError> {
        self.request_as(target, port, request, false)
    }

    /// [`Master::request`] for a request the device serves before it acknowledges the request's
    /// last fragment (a long flash erase: the update object's Update): that acknowledge is
    /// awaited as long as the response ([`Transaction::with_late_last_ack`]).
    pub fn request_served_first(
        &mut self,
        target: MacId,
        port: Port,
        request: &Request<'_>,
    ) -> Result<Answer, MasterError> {
        self.request_as(target, port, request, true)
    }

    fn request_as(
        &mut self,
        target: MacId,
        port: Port,
        request: &Request<'_>,
        late_last_ack: bool,
    ) -> Result<Answer, MasterError> {
        let what = step_name(request);
        let format = if port == Port::Group2Only { BodyFormat::Class8Instance8 } else { self.body_format };
        let mut tx = Transaction::new(
            target,
            self.config.mac,
            port,
            self.xid,
            request,
            format,
            self.config.response_timeout,
        )?;
        if late_last_ack {
            tx = tx.with_late_last_ack();
        }
        let (outcome, record) = self.run(&mut tx)?;
        self.last_record = record;
        match outcome {
            Ok(reply) => Ok(Answer { reply, record }),
            Err(ClientError::Timeout { name, after }) => {
                Err(MasterError::Timeout { what, mac: target.as_raw(), after, timeout: name })
            }
            Err(ClientError::RequestAborted(reason)) => Err(MasterError::Protocol { what, reason }),
        }
    }

    /// [`Master::request`], with an error response turned into [`MasterError::ErrorResponse`]
    /// (and the record's verdict a failure naming it).
    pub fn request_ok(
        &mut self,
        target: MacId,
        port: Port,
        request: &Request<'_>,
    ) -> Result<(Vec<u8>, Option<usize>), MasterError> {
        let answer = self.request(target, port, request)?;
        match answer.reply.body {
            ReplyBody::Success(data) => Ok((data, answer.record)),
            ReplyBody::Error { general, additional } => {
                let text = decode::error_text(general, additional);
                if let Some(i) = answer.record {
                    let v = self.session.record(i).verdict.clone();
                    self.session.set_verdict(i, v.with_failures(vec![format!("error response: {text}")]));
                }
                Err(MasterError::ErrorResponse {
                    what: step_name(request),
                    mac: target.as_raw(),
                    general,
                    additional,
                    text,
                })
            }
        }
    }

    /// Adds payload checks to record `i`: `failures` empty keeps its verdict, with `note` added.
    pub fn judge(&mut self, i: Option<usize>, note: &str, failures: Vec<String>) {
        if let Some(i) = i {
            let v = match self.session.record(i).verdict.clone() {
                Verdict::Ok(n) if !note.is_empty() => Verdict::Ok(format!("{n}; {note}")),
                other => other,
            };
            self.session.set_verdict(i, v.with_failures(failures));
        }
    }

    /// Allocate_Master/Slave_Connection_Set for `choice`, through `port` (protocol §3.4). Returns the
    /// record of the response; the announced message body format is used by later requests.
    ///
    /// The request runs on the device's [bring-up engine](crate::bring_up) ([`Master::step`]): a
    /// device that answers 0x0B (already in requested state: the set is allocated to this very
    /// master, by an earlier run that kept it) is released and allocated again, as a scanner
    /// coming back to its device does; the answer's record says so and a [notice](Self::notices)
    /// is left. 0x0C / 0x01 (allocated to another master) is
    /// [`MasterError::AllocationConflict`], with that master's MAC when its traffic was seen.
    pub fn allocate(
        &mut self,
        target: MacId,
        port: Port,
        choice: AllocationChoice,
    ) -> Result<Option<usize>, MasterError> {
        // 0x0B and 0x0C / 0x01 are the engine's (Master::run_step).
        self.allocate_once(target, port, choice)
    }

    fn allocate_once(
        &mut self,
        target: MacId,
        port: Port,
        choice: AllocationChoice,
    ) -> Result<Option<usize>, MasterError> {
        let (data, i) = self.step_ok(target, Step::Allocate { port, choice })?;
        // Acknowledge suppression is a property of the allocation, not a connection to release
        // (a Release with 0x40 is refused, docs/io-connections.md).
        let held = self.held.entry(target.as_raw()).or_insert(AllocationChoice::empty());
        *held = held.union(choice.difference(AllocationChoice::ACK_SUPPRESSION));
        let mut failures = Vec::new();
        match data.as_slice() {
            [fmt] => match BodyFormat::from_code(*fmt) {
                f @ (BodyFormat::Class8Instance8
                | BodyFormat::Class8Instance16
                | BodyFormat::Class16Instance16
                | BodyFormat::Class16Instance8) => self.body_format = f,
                other => failures.push(format!(
                    "body format {} is not one the master can use",
                    decode::body_format_text(other)
                )),
            },
            other => failures
                .push(format!("allocate response data {} , expected 1 byte (body format)", hex(other))),
        }
        let note = format!("{choice} allocated");
        self.judge(i, &note, failures);
        Ok(i)
    }

    /// The last answer from `target` is an expected error: its verdict becomes `note`.
    fn mark_last_answer(&mut self, target: MacId, note: &str) {
        let last = self
            .session
            .records()
            .iter()
            .rposition(|r| r.origin == Origin::Remote && is_from_device(&r.frame, target));
        if let Some(i) = last {
            self.session.set_verdict(i, Verdict::Ok(note.to_string()));
        }
    }

    /// The MAC of another master seen talking to `target` in this session: the source MAC in the
    /// header of an explicit or Group 2 Only request to it (protocol §3.1), or the destination in the
    /// header of its responses, when it is not this master.
    fn owner_seen(&self, target: MacId) -> Option<u8> {
        self.session.records().iter().rev().find_map(|r| {
            if r.origin != Origin::Remote {
                return None;
            }
            let Identifier::Group2 { mac, message } = Identifier::decode(r.frame.id()) else { return None };
            let relevant = mac == target
                && matches!(
                    message,
                    Group2Message::ExplicitRequest
                        | Group2Message::UnconnectedExplicitRequest
                        | Group2Message::ExplicitResponse
                );
            let other = r.frame.data().first().map(|h| h & 0x3F).filter(|&m| m != self.config.mac.as_raw());
            if relevant {
                other
            } else {
                None
            }
        })
    }

    /// Release_Master/Slave_Connection_Set for `choice` through the explicit connection.
    pub fn release(&mut self, target: MacId, choice: AllocationChoice) -> Result<(), MasterError> {
        self.release_through(target, Port::Explicit, choice)
    }

    /// Release_Master/Slave_Connection_Set for `choice` through `port` (the Group 2 Only port
    /// serves Release as well as Allocate, protocol §3.4).
    pub fn release_through(
        &mut self,
        target: MacId,
        port: Port,
        choice: AllocationChoice,
    ) -> Result<(), MasterError> {
        let (data, i) = self.step_ok(target, Step::Release { port, choice })?;
        if let Some(held) = self.held.get_mut(&target.as_raw()) {
            *held = held.difference(choice);
        }
        let failures = if data.is_empty() {
            Vec::new()
        } else {
            vec![format!("release response carries data {}", hex(&data))]
        };
        self.judge(i, "released", failures);
        Ok(())
    }

    /// Records that `target` holds `choice` for this master (allocated by frames the master sent
    /// as they were recorded, as a replay does), so that [`Master::release_held`] gives it back.
    pub fn note_held(&mut self, target: MacId, choice: AllocationChoice) {
        let held = self.held.entry(target.as_raw()).or_insert(AllocationChoice::empty());
        *held = held.union(choice);
    }

    /// Sets what `target` holds for this master, for a command that allocates through its own
    /// transactions (the overlapping `scan`).
    pub fn set_held(&mut self, target: MacId, choice: AllocationChoice) {
        self.held.insert(target.as_raw(), choice);
    }

    /// What this master holds allocated at `target` (allocations minus releases in this run).
    pub fn held(&self, target: MacId) -> AllocationChoice {
        self.held.get(&target.as_raw()).copied().unwrap_or(AllocationChoice::empty())
    }

    /// Releases everything this master holds, device by device, through the Group 2 Only port
    /// (which serves Release whatever state the explicit connection is in, protocol §3.4). A device
    /// that already dropped a connection (its watchdog fired) answers 0x0B; then each connection
    /// is released alone, and the ones it no longer has are taken as released. Returns the devices
    /// released.
    pub fn release_held(&mut self) -> Result<Vec<MacId>, MasterError> {
        let mut held: Vec<(u8, AllocationChoice)> =
            self.held.iter().filter(|(_, c)| !c.is_empty()).map(|(m, c)| (*m, *c)).collect();
        held.sort_by_key(|(m, _)| *m);
        let mut released = Vec::new();
        for (mac, choice) in held {
            let target = MacId::from_low_bits(mac);
            match self.release_through(target, Port::Group2Only, choice) {
                Ok(()) => {}
                Err(MasterError::ErrorResponse {
                    general: GeneralStatus::AlreadyInRequestedState, ..
                }) => {
                    self.mark_last_answer(target, "part of the set was already gone: released one by one");
                    for bit in (0..8).map(|b| AllocationChoice::from_bits(1 << b)) {
                        if !choice.contains(bit) || bit.is_empty() {
                            continue;
                        }
                        match self.release_through(target, Port::Group2Only, bit) {
                            Ok(()) => {}
                            Err(MasterError::ErrorResponse {
                                general: GeneralStatus::AlreadyInRequestedState,
                                ..
                            }) => {
                                self.mark_last_answer(target, &format!("{bit} was already gone"));
                                if let Some(h) = self.held.get_mut(&mac) {
                                    *h = h.difference(bit);
                                }
                            }
                            Err(e) => return Err(e),
                        }
                    }
                }
                Err(e) => return Err(e),
            }
            released.push(target);
        }
        Ok(released)
    }

    /// What the user should know about how the command went (a set released and allocated again).
    pub fn notices(&self) -> &[String] {
        &self.notices
    }

    /// Get_Attribute_Single; returns the value bytes.
    pub fn get(
        &mut self,
        target: MacId,
        class_id: u16,
        instance: u16,
        attribute: u8,
    ) -> Result<(Vec<u8>, Option<usize>), MasterError> {
        self.step_ok(target, Step::Get { class: class_id, instance, attribute })
    }

    /// Get_Attribute_Single of a UINT, checked to be 2 bytes.
    pub fn get_u16(
        &mut self,
        target: MacId,
        class_id: u16,
        instance: u16,
        attribute: u8,
    ) -> Result<Option<u16>, MasterError> {
        let (data, i) = self.get(target, class_id, instance, attribute)?;
        let value = match data.as_slice() {
            [a, b] => Some(u16::from_le_bytes([*a, *b])),
            _ => None,
        };
        let failures = match value {
            Some(_) => Vec::new(),
            None => vec![format!("value of {} bytes, a UINT has 2 (DLC 4 expected)", data.len())],
        };
        let p = PendingRequest {
            service: ServiceCode::GetAttributeSingle,
            class: class_id,
            instance,
            attribute: Some(attribute),
            choice: None,
        };
        let note = format!(
            "{} = {}",
            decode::attribute_text(p.class, p.instance, attribute),
            decode::value_text(class_id, instance, attribute, &data)
        );
        self.judge(i, &note, failures);
        Ok(value)
    }

    /// Set_Attribute_Single; returns the response data.
    pub fn set(
        &mut self,
        target: MacId,
        class_id: u16,
        instance: u16,
        attribute: u8,
        value: &[u8],
    ) -> Result<(Vec<u8>, Option<usize>), MasterError> {
        self.step_ok(target, Step::Set { class: class_id, instance, attribute, value: value.to_vec() })
    }

    /// The poll command frames for `output` on a connection consuming `consumed` bytes.
    fn poll_frames(&self, target: MacId, output: &[u8], consumed: u16) -> Vec<CanFrame> {
        let id = Identifier::group2(target, Group2Message::PollCommand);
        if consumed > 8 {
            io_fragments(output).filter_map(|p| CanFrame::new(id, &p).ok()).collect()
        } else {
            CanFrame::new(id, output).into_iter().collect()
        }
    }

    /// One poll cycle: sends `output`, waits for the complete response (reassembled when the
    /// produced size is over 8, protocol §4.2) and checks every fragment. Returns the input data.
    pub fn poll(
        &mut self,
        target: MacId,
        output: &[u8],
        produced: u16,
        consumed: u16,
        timeout: Duration,
    ) -> Result<Vec<u8>, MasterError> {
        for f in self.poll_frames(target, output, consumed) {
            self.session.send(&f)?;
        }
        let deadline = self.session.now() + timeout;
        let response_id = Identifier::group1(Group1MessageId::POLL_RESPONSE, target);
        let mut series = io::IoSeries::new(produced);
        loop {
            let Some((i, rec)) = self.next_wanted(deadline, |f| f.id() == response_id)? else {
                return Err(MasterError::Timeout {
                    what: format!("poll of MAC {target}"),
                    mac: target.as_raw(),
                    after: timeout,
                    timeout: "poll response timeout",
                });
            };
            match series.take(rec.frame.data(), "poll response") {
                io::SeriesStep::Complete(whole, v) => {
                    self.session.set_verdict(i, v);
                    return Ok(whole);
                }
                io::SeriesStep::Fragment(v) | io::SeriesStep::Rejected(v) => self.session.set_verdict(i, v),
            }
        }
    }

    /// Gains an explicit connection to `target` for one-off requests: network access, wait for
    /// the device, Allocate explicit through the Group 2 Only port (an explicit connection still
    /// allocated to this master is released and allocated again, [`Master::allocate`]).
    pub fn open_explicit(&mut self, target: MacId) -> Result<(), MasterError> {
        self.prepare(target)?;
        self.allocate(target, Port::Group2Only, AllocationChoice::EXPLICIT)?;
        Ok(())
    }

    /// Everything before the first request to `target`: it becomes the device under test, the
    /// master goes on-line ([`Master::network_access`]) and waits for the device
    /// ([`Master::await_online`]).
    ///
    /// # Errors
    ///
    /// [`UsageError::OwnMac`] when `target` is the master's own MAC; those of the network access.
    pub fn prepare(&mut self, target: MacId) -> Result<(), MasterError> {
        if target == self.config.mac {
            return Err(UsageError::OwnMac(target).into());
        }
        self.set_device(target);
        self.network_access()?;
        self.await_online(&[target])
    }

    /// The header the master puts on its requests.
    pub fn header(&self) -> Header {
        Header::new(self.xid, self.config.mac)
    }

    /// `true` when `frame` comes from `mac`.
    pub fn is_from(frame: &CanFrame, mac: MacId) -> bool {
        is_from_device(frame, mac)
    }
}
