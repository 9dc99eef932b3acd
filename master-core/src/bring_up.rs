//! The per-node bring-up engine: one device brought into I/O and given back, as a sans-IO state
//! machine. The master's allocate, release, get and set run on it ([`Master::step`]), so
//! `connect`, `get`/`set` and `dnet-eds check-device` drive it, as do `scan` and the plant
//! scanner (one engine per MAC on one bus) and the soak ([`drive`]).
//!
//! [`Master::step`]: crate::master::Master::step
//!
//! The sequence is a queue of [`Step`]s — Allocate_Master/Slave_Connection_Set with the requested
//! connections, Get_Attribute_Single of what the caller reads, Set_Attribute_Single (the expected
//! packet rate that starts I/O, protocol §2 frames 22–23), Release (protocol §3.4) — run one explicit
//! [`Transaction`] at a time, so fragmented answers are reassembled and every response frame is
//! checked as the client does. The engine owns the rules every caller had written out for itself:
//!
//! - a device that answers an Allocate with 0x0B (the set is still allocated to this very master,
//!   by an earlier run that kept it) has what it holds released through the Group 2 Only port, one
//!   connection at a time, the I/O connection first, and is allocated again, once per Allocate
//!   ([`Event::Reallocated`]);
//! - 0x0C / 0x01 to an Allocate is [`NodeError::AllocationConflict`];
//! - what the device holds for this master is tracked ([`BringUp::held`]) and
//!   [`BringUp::give_back`] releases it;
//! - a step that times out, whose request is aborted, or whose error response the caller did not
//!   ask to see ([`Refusal::Stop`]) ends the sequence with a [`NodeError`] naming the MAC, the step
//!   and the timeout or the device's error response.
//!
//! It reads no clock and touches no bus: it takes the frames from the device and the time, and
//! gives frames to send, its next deadline and [`Event`]s.
//!
//! ## Calling order
//!
//! After every input ([`BringUp::push`] and the step helpers, [`BringUp::handle_frame`],
//! [`BringUp::handle_timeout`]): drain [`BringUp::poll_transmit`] onto the bus, then
//! [`BringUp::poll_event`]; then wait for a frame until [`BringUp::poll_at`] and call
//! [`BringUp::handle_timeout`] when it passes. [`BringUp::is_idle`] says when nothing is queued or
//! running. Several engines (one per device) can run at once on one bus: a frame belongs to the
//! engine whose [`BringUp::handle_frame`] does not answer [`Handled::NotMine`].
//!
//! ## Example: poll I/O with the reference device's answers
//!
//! ```
//! use devicenet::messages::AllocationChoice;
//! use devicenet::objects::class;
//! use devicenet::{CanFrame, Duration, Instant, MacId};
//! use master_core::bring_up::{BringUp, Event, Refusal};
//! use master_core::client::Port;
//!
//! let mac = MacId::new(5).unwrap();
//! let mut node = BringUp::new(mac, MacId::new(0).unwrap(), Duration::from_secs(1));
//! let now = Instant::ZERO;
//! node.allocate(now, Port::Group2Only, AllocationChoice::EXPLICIT | AllocationChoice::POLL);
//! node.get(now, class::CONNECTION, 2, 7, Refusal::Stop);
//! node.expected_packet_rate(now, 2, 100);
//! // Each request out, the device's answer in (protocol §2 frames 17, 19, 23).
//! for answer in [&[0x00, 0xCB, 0x00][..], &[0x00, 0x8E, 0x12, 0x00], &[0x00, 0x90, 0x64, 0x00]] {
//!     assert!(node.poll_transmit().is_some());
//!     node.handle_frame(&CanFrame::from_raw(0x42B, answer).unwrap(), now);
//! }
//! let events: Vec<Event> = std::iter::from_fn(|| node.poll_event()).collect();
//! assert_eq!(events.len(), 3);
//! assert!(node.is_idle());
//! assert_eq!(node.held(), AllocationChoice::EXPLICIT | AllocationChoice::POLL);
//! ```

use crate::client::{ClientError, Handled, Link, Port, ReplyBody, RequestError, Transaction};
use crate::decode;
use crate::error::MasterError;
use can_io::bus::Origin;
use devicenet::explicit::{additional, BodyFormat, GeneralStatus, Request, ServiceCode};
use devicenet::messages::{AllocateRequest, AllocationChoice, ReleaseRequest};
use devicenet::objects::class;
use devicenet::{CanFrame, Duration, Instant, MacId};
use std::collections::VecDeque;
use std::fmt;

/// One request of a bring-up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Step {
    /// Allocate_Master/Slave_Connection_Set for `choice` through `port` (protocol §3.4).
    Allocate {
        /// The Group 2 Only port, or the explicit connection once it is allocated.
        port: Port,
        /// The connections asked for.
        choice: AllocationChoice,
    },
    /// Get_Attribute_Single.
    Get {
        /// Class ID.
        class: u16,
        /// Instance ID.
        instance: u16,
        /// Attribute ID.
        attribute: u8,
    },
    /// Set_Attribute_Single.
    Set {
        /// Class ID.
        class: u16,
        /// Instance ID.
        instance: u16,
        /// Attribute ID.
        attribute: u8,
        /// The value, as sent.
        value: Vec<u8>,
    },
    /// Release_Master/Slave_Connection_Set for `choice` through `port`.
    Release {
        /// The Group 2 Only port (which serves Release in any state) or the explicit connection.
        port: Port,
        /// The connections given back.
        choice: AllocationChoice,
    },
}

impl Step {
    /// The request's service, class, instance and data, from `master`.
    fn request(&self, master: MacId) -> (Port, ServiceCode, u16, u16, Vec<u8>) {
        match self {
            Step::Allocate { port, choice } => (
                *port,
                ServiceCode::AllocateMasterSlave,
                class::DEVICENET,
                1,
                AllocateRequest { choice: *choice, allocator: master }.emit().to_vec(),
            ),
            Step::Get { class, instance, attribute } => {
                (Port::Explicit, ServiceCode::GetAttributeSingle, *class, *instance, vec![*attribute])
            }
            Step::Set { class, instance, attribute, value } => {
                let mut data = vec![*attribute];
                data.extend_from_slice(value);
                (Port::Explicit, ServiceCode::SetAttributeSingle, *class, *instance, data)
            }
            Step::Release { port, choice } => (
                *port,
                ServiceCode::ReleaseMasterSlave,
                class::DEVICENET,
                1,
                ReleaseRequest { choice: *choice }.emit().to_vec(),
            ),
        }
    }
}

impl fmt::Display for Step {
    /// The request as the transcript names it (`Get_Attribute_Single Identity 1 attr 7 ...`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Step::Allocate { choice, .. } = self {
            // Without the allocator: the step does not know the master's MAC.
            let service = decode::service_text(class::DEVICENET, ServiceCode::AllocateMasterSlave);
            return write!(f, "{service} {} inst 1: choice {choice}", decode::class_text(class::DEVICENET));
        }
        let (_, service, class, instance, data) = self.request(MacId::from_low_bits(0));
        let text = decode::request_text(&Request { service, class, instance, data: &data });
        f.write_str(&text)
    }
}

/// What an error response to a step does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// It ends the bring-up: [`Event::Failed`] with [`NodeError::Refused`] (or
    /// [`NodeError::AllocationConflict`]).
    Stop,
    /// It is an answer like any other: [`Event::Answered`] with the error, and the sequence goes
    /// on (a value the device may decline to give, a connection type it may lack).
    Report,
}

/// What the engine has to say.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    /// A step was answered: success, or an error response the caller asked to see
    /// ([`Refusal::Report`]).
    Answered {
        /// The step.
        step: Step,
        /// The answer.
        body: ReplyBody,
    },
    /// The set was still allocated to this master (0x0B): what it held was released through the
    /// Group 2 Only port, and `choice` is being allocated again.
    Reallocated {
        /// The allocation asked for again.
        choice: AllocationChoice,
    },
    /// The bring-up stopped; every queued step was dropped. What the device still holds for this
    /// master is [`BringUp::held`].
    Failed(NodeError),
}

/// Why a bring-up stopped: the MAC, the step, and the timeout or the device's answer.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NodeError {
    /// Nothing (or not the whole answer) arrived in time.
    #[error("MAC {mac}: {step}: no answer within {after} ({timeout})")]
    Timeout {
        /// The device.
        mac: MacId,
        /// The step.
        step: Step,
        /// The name of the timeout that expired.
        timeout: &'static str,
        /// Its length.
        after: Duration,
    },
    /// The device answered with an error response where none is allowed.
    #[error("MAC {mac}: {step}: the device answered with an error: {}", decode::error_text(*general, *additional))]
    Refused {
        /// The device.
        mac: MacId,
        /// The step.
        step: Step,
        /// General status.
        general: GeneralStatus,
        /// Additional code.
        additional: u8,
    },
    /// The device's connection set is allocated to another master (0x0C / 0x01, protocol §3.4).
    #[error("MAC {mac}: {step}: the set is allocated to another master")]
    AllocationConflict {
        /// The device.
        mac: MacId,
        /// The step.
        step: Step,
    },
    /// The device refused or never acknowledged a fragment of the request.
    #[error("MAC {mac}: {step}: request aborted: {reason}")]
    Aborted {
        /// The device.
        mac: MacId,
        /// The step.
        step: Step,
        /// What the fragment protocol said.
        reason: String,
    },
    /// The step's request could not be built (a value too long for the master).
    #[error("MAC {mac}: {step}: {source}")]
    Request {
        /// The device.
        mac: MacId,
        /// The step.
        step: Step,
        /// Why.
        source: RequestError,
    },
}

impl NodeError {
    /// The step that stopped.
    pub fn step(&self) -> &Step {
        match self {
            NodeError::Timeout { step, .. }
            | NodeError::Refused { step, .. }
            | NodeError::AllocationConflict { step, .. }
            | NodeError::Aborted { step, .. }
            | NodeError::Request { step, .. } => step,
        }
    }
}

/// A queued step and what its answer does.
#[derive(Clone, Debug)]
struct Queued {
    step: Step,
    refusal: Refusal,
    /// A release of a set kept by an earlier run: any answer is fine (the connection may be gone
    /// already, its watchdog fired), and none is reported.
    kept: bool,
    /// An Allocate asked again after 0x0B: a second 0x0B is not retried.
    retried: bool,
}

/// The per-node bring-up engine. See the [module docs](self).
pub struct BringUp {
    mac: MacId,
    master: MacId,
    timeout: Duration,
    queue: VecDeque<Queued>,
    current: Option<(Queued, Transaction)>,
    /// Frames of finished transactions not sent yet (the acknowledge of a last fragment).
    out: VecDeque<CanFrame>,
    held: AllocationChoice,
    events: VecDeque<Event>,
    /// The message body format of the explicit connection, as its Allocate answered (protocol §3.1).
    format: BodyFormat,
    answered: bool,
}

impl BringUp {
    /// An engine for the device at `mac`, from the master at `master`, waiting `response_timeout`
    /// for each answer (and each fragment of one).
    pub fn new(mac: MacId, master: MacId, response_timeout: Duration) -> BringUp {
        BringUp {
            mac,
            master,
            timeout: response_timeout,
            queue: VecDeque::new(),
            current: None,
            out: VecDeque::new(),
            held: AllocationChoice::empty(),
            events: VecDeque::new(),
            format: BodyFormat::Class8Instance8,
            answered: false,
        }
    }

    /// The device.
    pub fn mac(&self) -> MacId {
        self.mac
    }

    /// What the device holds for this master: allocations answered with success, minus releases
    /// (acknowledge suppression is a property of the allocation, never held, protocol §II.2.5).
    pub fn held(&self) -> AllocationChoice {
        self.held
    }

    /// `true` once the device answered anything (a device that never did is absent).
    pub fn answered(&self) -> bool {
        self.answered
    }

    /// Sets the response timeout of the steps started from now on.
    pub fn set_response_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The message body format requests on the explicit connection use: 8/8 until an Allocate
    /// answers another one the master can use.
    pub fn body_format(&self) -> BodyFormat {
        self.format
    }

    /// The step running, if any.
    pub fn current(&self) -> Option<&Step> {
        self.current.as_ref().map(|(q, _)| &q.step)
    }

    /// `true` when no step is running or queued.
    pub fn is_idle(&self) -> bool {
        self.current.is_none() && self.queue.is_empty()
    }

    /// Queues `step` (started at `now` when nothing runs).
    pub fn push(&mut self, now: Instant, step: Step, refusal: Refusal) {
        self.queue.push_back(Queued { step, refusal, kept: false, retried: false });
        self.advance(now);
    }

    /// Queues an Allocate of `choice` through `port`; an error response stops.
    pub fn allocate(&mut self, now: Instant, port: Port, choice: AllocationChoice) {
        self.push(now, Step::Allocate { port, choice }, Refusal::Stop);
    }

    /// Queues a Get_Attribute_Single.
    pub fn get(&mut self, now: Instant, class: u16, instance: u16, attribute: u8, refusal: Refusal) {
        self.push(now, Step::Get { class, instance, attribute }, refusal);
    }

    /// Queues a Set_Attribute_Single.
    pub fn set(
        &mut self,
        now: Instant,
        (class, instance, attribute): (u16, u16, u8),
        value: &[u8],
        refusal: Refusal,
    ) {
        self.push(now, Step::Set { class, instance, attribute, value: value.to_vec() }, refusal);
    }

    /// Queues the Set of the expected packet rate (attribute 9) of Connection `instance`, which
    /// takes an I/O connection from configuring to established (protocol §2 frame 22); an error
    /// response stops. The answer carries the rate the device applied.
    pub fn expected_packet_rate(&mut self, now: Instant, instance: u16, epr_ms: u16) {
        self.set(now, (class::CONNECTION, instance, 9), &epr_ms.to_le_bytes(), Refusal::Stop);
    }

    /// Queues a Release of `choice` through `port`; an error response stops.
    pub fn release(&mut self, now: Instant, port: Port, choice: AllocationChoice) {
        self.push(now, Step::Release { port, choice }, Refusal::Stop);
    }

    /// Gives the device back: the queued steps are dropped and, once the step running (if any) is
    /// over, everything [held](Self::held) is released through the Group 2 Only port (which
    /// serves Release whatever state the explicit connection is in, protocol §3.4). Nothing is sent
    /// when nothing is held. An error response to it is reported ([`Refusal::Report`]): there is
    /// nothing more to give back.
    pub fn give_back(&mut self, now: Instant) {
        self.queue.clear();
        self.queue.push_back(Queued {
            step: Step::Release { port: Port::Group2Only, choice: AllocationChoice::empty() },
            refusal: Refusal::Report,
            kept: false,
            retried: false,
        });
        self.advance(now);
    }

    /// The next frame to send.
    #[must_use = "a frame taken and not sent is lost: the device never sees the request"]
    pub fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.out.pop_front().or_else(|| self.current.as_mut().and_then(|(_, tx)| tx.poll_transmit()))
    }

    /// The next event.
    #[must_use = "an event taken is gone: an answer or a failure would be lost"]
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// When [`BringUp::handle_timeout`] is due.
    pub fn poll_at(&self) -> Option<Instant> {
        self.current.as_ref().and_then(|(_, tx)| tx.poll_at())
    }

    /// Runs the timers due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if let Some((_, tx)) = &mut self.current {
            tx.handle_timeout(now);
        }
        self.finish_if_done(now);
    }

    /// Takes a frame from another node at `now`: [`Handled::Frame`] with its verdict when it
    /// answers the step running.
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Instant) -> Handled {
        let handled = match &mut self.current {
            Some((_, tx)) => tx.handle_frame(frame, now),
            None => Handled::NotMine,
        };
        self.finish_if_done(now);
        handled
    }

    /// Starts the next queued step when nothing runs.
    fn advance(&mut self, now: Instant) {
        while self.current.is_none() {
            let Some(mut queued) = self.queue.pop_front() else { return };
            if let Step::Release { port: Port::Group2Only, choice } = &mut queued.step {
                if choice.is_empty() {
                    // give_back: what is held by the time it runs.
                    *choice = self.held;
                    if choice.is_empty() {
                        continue;
                    }
                }
            }
            let (port, service, class, instance, data) = queued.step.request(self.master);
            let request = Request { service, class, instance, data: &data };
            // The Group 2 Only port always uses 8/8 (protocol §3.1).
            let format = if port == Port::Explicit { self.format } else { BodyFormat::Class8Instance8 };
            match Transaction::build(self.mac, self.master, port, false, &request, format, self.timeout) {
                Ok(mut tx) => {
                    tx.start(now);
                    self.current = Some((queued, tx));
                }
                Err(source) => {
                    self.fail(NodeError::Request { mac: self.mac, step: queued.step, source });
                }
            }
        }
    }

    fn fail(&mut self, error: NodeError) {
        self.queue.clear();
        self.events.push_back(Event::Failed(error));
    }

    fn finish_if_done(&mut self, now: Instant) {
        let Some(outcome) =
            self.current.as_mut().filter(|(_, tx)| tx.is_done()).and_then(|(_, tx)| tx.take_outcome())
        else {
            return;
        };
        let Some((queued, mut tx)) = self.current.take() else { return };
        self.out.extend(std::iter::from_fn(|| tx.poll_transmit()));
        self.take_outcome(queued, outcome);
        self.advance(now);
    }

    /// Takes the outcome of a step: what is held, what to report, what comes next.
    fn take_outcome(&mut self, queued: Queued, outcome: Result<crate::client::Reply, ClientError>) {
        let mac = self.mac;
        let reply = match outcome {
            Ok(reply) => reply,
            Err(ClientError::Timeout { name, after }) => {
                return self.fail(NodeError::Timeout { mac, step: queued.step, timeout: name, after });
            }
            Err(ClientError::RequestAborted(reason)) => {
                return self.fail(NodeError::Aborted { mac, step: queued.step, reason });
            }
        };
        self.answered = true;
        if queued.kept {
            // Released, or already gone: either way no longer held.
            if let Step::Release { choice, .. } = queued.step {
                self.held = self.held.difference(choice);
            }
            return;
        }
        match (&queued.step, &reply.body) {
            (Step::Allocate { choice, .. }, ReplyBody::Success(data)) => {
                self.held = self.held.union(choice.difference(AllocationChoice::ACK_SUPPRESSION));
                if let [code] = data.as_slice() {
                    if let f @ (BodyFormat::Class8Instance8
                    | BodyFormat::Class8Instance16
                    | BodyFormat::Class16Instance16
                    | BodyFormat::Class16Instance8) = BodyFormat::from_code(*code)
                    {
                        self.format = f;
                    }
                }
            }
            (Step::Release { choice, .. }, ReplyBody::Success(_)) => {
                self.held = self.held.difference(*choice);
            }
            (
                Step::Allocate { choice, .. },
                ReplyBody::Error { general: GeneralStatus::AlreadyInRequestedState, .. },
            ) if !queued.retried => {
                // Still allocated to this master: release what it holds of the choice, the I/O
                // connection before the explicit one (either may be gone already), allocate again.
                let choice = *choice;
                self.queue.push_front(Queued { retried: true, ..queued });
                let held = choice.difference(AllocationChoice::ACK_SUPPRESSION);
                let io = held.difference(AllocationChoice::EXPLICIT);
                for part in [AllocationChoice::EXPLICIT, io] {
                    if held.contains(part) && !part.is_empty() {
                        self.queue.push_front(Queued {
                            step: Step::Release { port: Port::Group2Only, choice: part },
                            refusal: Refusal::Report,
                            kept: true,
                            retried: false,
                        });
                    }
                }
                self.events.push_back(Event::Reallocated { choice });
                return;
            }
            (_, ReplyBody::Error { general, additional: code }) if queued.refusal == Refusal::Stop => {
                let conflict = matches!(queued.step, Step::Allocate { .. })
                    && *general == GeneralStatus::ObjectStateConflict
                    && *code == additional::ALLOCATION_CONFLICT;
                let error = if conflict {
                    NodeError::AllocationConflict { mac, step: queued.step }
                } else {
                    NodeError::Refused { mac, step: queued.step, general: *general, additional: *code }
                };
                return self.fail(error);
            }
            _ => {}
        }
        self.events.push_back(Event::Answered { step: queued.step, body: reply.body });
    }
}

/// Runs `node` on `link` until its next event (`None`: idle with nothing to say): its frames
/// sent, the device's answers handed to it and [judged](Link::judged), every other frame passed
/// to [`Link::other`]. The engine's counterpart of [`client::drive`](crate::client::drive) for a
/// program with a bus of its own (the soak); on the master's session the driver is
/// `Master::next_event`.
///
/// # Errors
///
/// The link's.
pub fn drive<L: Link>(link: &mut L, node: &mut BringUp) -> Result<Option<Event>, MasterError> {
    // Own frames sent and not yet seen back from the bus.
    let mut in_flight = 0usize;
    loop {
        while let Some(frame) = node.poll_transmit() {
            link.send(&frame)?;
            in_flight += 1;
        }
        if let Some(event) = node.poll_event() {
            if let Some(wait) = link.echo_wait() {
                let until = link.now() + wait;
                while in_flight > 0 {
                    let Some(r) = link.recv(until)? else { break };
                    match r.origin {
                        Origin::Local => in_flight -= 1,
                        Origin::Remote => take(link, node, r),
                    }
                }
            }
            return Ok(Some(event));
        }
        let Some(deadline) = node.poll_at() else { return Ok(None) };
        match link.recv(deadline)? {
            Some(r) if r.origin == Origin::Local => in_flight = in_flight.saturating_sub(1),
            Some(r) => take(link, node, r),
            None => {
                let now = link.now();
                node.handle_timeout(now);
            }
        }
    }
}

/// Hands a frame from another node to `node`, or to the link's [`Link::other`].
fn take<L: Link>(link: &mut L, node: &mut BringUp, r: crate::client::Received<L::Seen>) {
    match node.handle_frame(&r.frame, r.at) {
        Handled::Frame(verdict) => link.judged(r.seen, verdict),
        Handled::NotMine => link.other(r.seen),
    }
}

#[cfg(test)]
mod tests;
