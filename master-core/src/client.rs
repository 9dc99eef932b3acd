//! The master's side of one explicit transaction with one device, as a sans-IO state machine:
//! the request goes out (fragmented with acknowledgements when longer than 8 bytes, protocol §4.1),
//! the response comes back (reassembled and acknowledged when fragmented), and every response frame
//! is checked: identifier, header MAC (the master's), echoed XID, fragment protocol and the service
//! byte (`request | 0x80`, or `0x94` for an error response).
//!
//! Several transactions with different devices can run at once (`scan` does); a blocking driver for
//! one transaction is [`drive`], on any [`Link`]; [`run`] is it on a [`Session`].
//!
//! Calling order, as for the core's state machines: after [`Transaction::start`] and after every
//! input, drain [`Transaction::poll_transmit`], then check [`Transaction::is_done`], then wait until
//! [`Transaction::poll_at`] and call [`Transaction::handle_timeout`].

use crate::decode::hex;
use crate::error::MasterError;
pub use crate::error::RequestError;
use crate::session::{is_from_device, Session, Verdict};
use can_io::bus::Origin;
use devicenet::explicit::{split_message, BodyFormat, GeneralStatus, Header, Request, Response, ServiceCode};
use devicenet::fragment::{
    AbortReason, AckStatus, ExplicitFragment, ExplicitReassembler, ExplicitReceive, ExplicitTransmitter,
    FragmentKind, TransmitEvent,
};
use devicenet::messages::{DEVICE_HEARTBEAT, DEVICE_SHUTDOWN};
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant, MacId};
use std::collections::VecDeque;

/// Largest explicit message (header included) the master sends or reassembles.
pub const MAX_MESSAGE: usize = 1024;

/// The default explicit response timeout (`--timeout`): how long the master waits for a response,
/// or for the next fragment of one, before it gives up. Not specified publicly (protocol §9.4); 1 s
/// matches the fragment acknowledge timeout of a conformance-tested slave (JB).
pub const DEFAULT_RESPONSE_TIMEOUT: Duration = Duration::from_secs(1);

/// How long [`run`] waits, once a transaction is over, to see the master's last frames on the bus.
pub const ECHO_WAIT: Duration = Duration::from_millis(100);

/// Where a request is sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Port {
    /// The explicit connection (Group 2 message 4).
    Explicit,
    /// The Group 2 Only Unconnected Explicit Request port (Group 2 message 6): Allocate/Release.
    Group2Only,
}

/// What the device answered.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ReplyBody {
    /// Success: the service response data.
    Success(Vec<u8>),
    /// Error response.
    Error {
        /// General status.
        general: GeneralStatus,
        /// Additional code.
        additional: u8,
    },
}

/// A complete response.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    /// The response header.
    pub header: Header,
    /// The answer.
    pub body: ReplyBody,
    /// `true` when it came in fragments.
    pub fragmented: bool,
    /// Bytes of the whole message (header + body).
    pub message_len: usize,
}

impl Reply {
    /// The success data, or `None` for an error response.
    pub fn data(&self) -> Option<&[u8]> {
        match &self.body {
            ReplyBody::Success(d) => Some(d),
            ReplyBody::Error { .. } => None,
        }
    }
}

/// Why a transaction failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ClientError {
    /// The named timeout expired.
    Timeout {
        /// The timeout's name.
        name: &'static str,
        /// Its length.
        after: Duration,
    },
    /// The device refused a request fragment (ack status) or never acknowledged it.
    RequestAborted(String),
}

/// What became of a frame handed to [`Transaction::handle_frame`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Handled {
    /// Not part of this transaction.
    NotMine,
    /// Part of it, with this verdict.
    Frame(Verdict),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    /// Sending a fragmented request.
    Sending,
    /// Waiting for the response (or its next fragment) until the deadline.
    Awaiting {
        deadline: Instant,
    },
    /// The last request fragment went out and its acknowledge is overdue, but the device is one
    /// that serves a request before it acknowledges the request's last fragment
    /// ([`Transaction::with_late_last_ack`]): waiting for that acknowledge until the deadline.
    LastAck {
        deadline: Instant,
    },
    Done,
}

/// One explicit request/response exchange with one device. See the [module docs](self).
pub struct Transaction {
    target: MacId,
    master: MacId,
    port: Port,
    xid: bool,
    message: Vec<u8>,
    service: ServiceCode,
    /// The class the request addresses, to name its service ([`crate::decode::service_text`]).
    class: u16,
    timeout: Duration,
    state: State,
    tx: Box<ExplicitTransmitter<MAX_MESSAGE>>,
    rx: Box<ExplicitReassembler<MAX_MESSAGE>>,
    out: VecDeque<CanFrame>,
    outcome: Option<Result<Reply, ClientError>>,
    /// Waits for the last request fragment's acknowledge as long as for the response
    /// ([`Transaction::with_late_last_ack`]).
    late_last_ack: bool,
    /// When the last request fragment was first sent.
    last_sent: Option<Instant>,
}

impl Transaction {
    /// A transaction sending `request` (in body format `format`) from `master` to `target`.
    ///
    /// # Errors
    ///
    /// [`MasterError::Request`] as [`Transaction::build`].
    pub fn new(
        target: MacId,
        master: MacId,
        port: Port,
        xid: bool,
        request: &Request<'_>,
        format: BodyFormat,
        timeout: Duration,
    ) -> Result<Transaction, MasterError> {
        Ok(Transaction::build(target, master, port, xid, request, format, timeout)?)
    }

    /// [`Transaction::new`], with the reason a request cannot be sent as it is.
    ///
    /// # Errors
    ///
    /// [`RequestError::Build`] when `request` cannot be written in `format`,
    /// [`RequestError::TooLong`] when it is longer than [`MAX_MESSAGE`].
    pub fn build(
        target: MacId,
        master: MacId,
        port: Port,
        xid: bool,
        request: &Request<'_>,
        format: BodyFormat,
        timeout: Duration,
    ) -> Result<Transaction, RequestError> {
        let len = request.buffer_len(format).unwrap_or(0);
        let mut message = vec![0u8; 1 + len];
        message[0] = Header::new(xid, master).to_byte();
        request.emit(format, &mut message[1..]).map_err(RequestError::Build)?;
        if message.len() > MAX_MESSAGE {
            return Err(RequestError::TooLong { len: message.len(), max: MAX_MESSAGE });
        }
        Ok(Transaction {
            target,
            master,
            port,
            xid,
            message,
            service: request.service,
            class: request.class,
            timeout,
            state: State::Idle,
            tx: Box::new(ExplicitTransmitter::new()),
            rx: Box::new(ExplicitReassembler::new()),
            out: VecDeque::new(),
            outcome: None,
            late_last_ack: false,
            last_sent: None,
        })
    }

    /// For a request the device serves before it acknowledges the request's last fragment: the
    /// update object's Update, which erases the DFU sectors (about 2 s, the CPU stalled) before
    /// the adapter's transmit queue moves on (the guide's protocol §6.5,
    /// docs/src/protocol/objects.md). The last fragment is sent once, not re-sent after the 1 s
    /// fragment acknowledge timeout (a re-send would be acknowledged again after the response, a
    /// stray acknowledge by then), and its acknowledge is awaited as long as the response, the
    /// transaction's timeout from when that fragment went out. Every other fragment keeps the
    /// 1 s timeout and its one re-send.
    #[must_use]
    pub fn with_late_last_ack(mut self) -> Transaction {
        self.late_last_ack = true;
        self
    }

    /// The device.
    pub fn target(&self) -> MacId {
        self.target
    }

    /// The service requested.
    pub fn service(&self) -> ServiceCode {
        self.service
    }

    fn request_id(&self) -> devicenet::CanId {
        let message = match self.port {
            Port::Explicit => Group2Message::ExplicitRequest,
            Port::Group2Only => Group2Message::UnconnectedExplicitRequest,
        };
        Identifier::group2(self.target, message)
    }

    fn response_id(&self) -> devicenet::CanId {
        Identifier::group2(self.target, Group2Message::ExplicitResponse)
    }

    fn ack_id(&self) -> devicenet::CanId {
        Identifier::group2(self.target, Group2Message::ExplicitRequest)
    }

    fn queue(&mut self, id: devicenet::CanId, data: &[u8]) {
        if let Ok(f) = CanFrame::new(id, data) {
            self.out.push_back(f);
        }
    }

    /// Starts the exchange at `now`.
    pub fn start(&mut self, now: Instant) {
        if self.message.len() <= 8 {
            let (id, message) = (self.request_id(), self.message.clone());
            self.queue(id, &message);
            self.state = State::Awaiting { deadline: now + self.timeout };
        } else {
            // Cannot fail: the message is longer than 8 and within MAX_MESSAGE, the transmitter idle.
            let _ = self.tx.start(&self.message, now);
            self.state = State::Sending;
            self.pump(now);
        }
    }

    fn pump(&mut self, now: Instant) {
        let id = self.request_id();
        while let Some(p) = self.tx.poll_transmit(now) {
            if self.late_last_ack && self.tx.is_last_fragment() {
                match self.last_sent {
                    // The re-send: left out (see `with_late_last_ack`).
                    Some(_) => continue,
                    None => self.last_sent = Some(now),
                }
            }
            self.queue(id, &p);
        }
        while let Some(ev) = self.tx.poll_event(now) {
            match ev {
                TransmitEvent::Completed => self.state = State::Awaiting { deadline: now + self.timeout },
                TransmitEvent::Aborted(AbortReason::AckTimeout) if self.late_last_ack && self.tx.is_last_fragment() => {
                    let sent = self.last_sent.unwrap_or(now);
                    self.state = State::LastAck { deadline: sent + self.timeout };
                }
                TransmitEvent::Aborted(AbortReason::AckTimeout) => self.finish(Err(ClientError::RequestAborted(
                    "request fragment not acknowledged, also after one re-send (fragment acknowledge timeout)".into(),
                ))),
                TransmitEvent::Aborted(AbortReason::Rejected(status)) => self.finish(Err(
                    ClientError::RequestAborted(format!("the device rejected a request fragment: ack status {status}")),
                )),
            }
        }
    }

    fn finish(&mut self, outcome: Result<Reply, ClientError>) {
        self.state = State::Done;
        self.outcome = Some(outcome);
    }

    /// The next frame to send.
    #[must_use = "a frame taken and not sent is lost: the device never sees the request or acknowledge"]
    pub fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.out.pop_front()
    }

    /// When [`Transaction::handle_timeout`] is due.
    pub fn poll_at(&self) -> Option<Instant> {
        match self.state {
            State::Idle | State::Done => None,
            State::Sending => self.tx.poll_at(),
            State::Awaiting { deadline } | State::LastAck { deadline, .. } => Some(deadline),
        }
    }

    /// Runs the timers due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        match self.state {
            State::Sending => self.pump(now),
            State::Awaiting { deadline } if now >= deadline => {
                let name = if self.rx.in_progress() {
                    "response fragment timeout"
                } else {
                    "explicit response timeout"
                };
                self.finish(Err(ClientError::Timeout { name, after: self.timeout }));
            }
            State::LastAck { deadline, .. } if now >= deadline => {
                self.finish(Err(ClientError::RequestAborted(format!(
                    "last request fragment not acknowledged within {} ms",
                    self.timeout.total_millis()
                ))))
            }
            _ => {}
        }
    }

    /// `true` once the outcome is known.
    pub fn is_done(&self) -> bool {
        self.state == State::Done
    }

    /// The outcome, once.
    #[must_use = "the outcome is handed out once"]
    pub fn take_outcome(&mut self) -> Option<Result<Reply, ClientError>> {
        self.outcome.take()
    }

    /// Takes a frame seen on the bus (from another node) at `now`.
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Instant) -> Handled {
        if frame.id() != self.response_id() || matches!(self.state, State::Idle | State::Done) {
            return Handled::NotMine;
        }
        let data = frame.data();
        if is_heartbeat_or_shutdown(data, self.master) {
            return Handled::NotMine;
        }
        let Some(&first) = data.first() else {
            return Handled::Frame(Verdict::fail("empty response frame (DLC 0)"));
        };
        let header = Header::from_byte(first);
        let mut failures = Vec::new();
        if header.mac != self.master {
            failures.push(format!("header MAC {}, expected the master's MAC {}", header.mac, self.master));
        }
        if header.xid != self.xid {
            failures.push(format!(
                "XID {} not echoed (request XID {})",
                u8::from(header.xid),
                u8::from(self.xid)
            ));
        }
        if header.fragmented {
            return Handled::Frame(self.fragment(frame, now, failures));
        }
        if matches!(self.state, State::Sending | State::LastAck { .. }) {
            failures.push("unfragmented response while the request is still being sent".into());
            return Handled::Frame(Verdict::Fail(failures));
        }
        let body = &data[1..];
        let (reply, mut more) = self.check_body(header, body, false, data.len());
        failures.append(&mut more);
        let note =
            format!("response to {} checked: identifier, header MAC, XID, service", self.service_name());
        self.finish(Ok(reply));
        Handled::Frame(Verdict::Ok(note).with_failures(failures))
    }

    /// The acknowledge of the last request fragment, after the 1 s fragment acknowledge timeout
    /// ([`Transaction::with_late_last_ack`]).
    fn late_ack(
        &mut self,
        data: &[u8],
        frag: &ExplicitFragment,
        now: Instant,
        mut failures: Vec<String>,
    ) -> Verdict {
        let last = self.tx.fragment_count();
        let sent = self.last_sent.unwrap_or(now);
        if frag.fragment.count != last {
            failures.push(format!(
                "acknowledge of request fragment #{}, the last one sent is #{last}",
                frag.fragment.count
            ));
            return Verdict::Fail(failures);
        }
        if data.len() != 3 {
            failures.push(format!("fragment acknowledge of DLC {}, expected 3", data.len()));
        }
        match frag.ack_status() {
            Some(AckStatus::Success) => {
                self.state = State::Awaiting { deadline: now + self.timeout };
                Verdict::Ok(format!(
                    "acknowledge of the last request fragment #{last}, {} ms after it (the device serves this request first)",
                    now.saturating_duration_since(sent).total_millis()
                ))
                .with_failures(failures)
            }
            status => {
                let text = status.map_or("none".to_string(), |s| s.to_string());
                self.finish(Err(ClientError::RequestAborted(format!(
                    "the device rejected a request fragment: ack status {text}"
                ))));
                Verdict::Ok(format!("acknowledge of the last request fragment #{last}: status {text}"))
                    .with_failures(failures)
            }
        }
    }

    fn service_name(&self) -> String {
        crate::decode::service_text(self.class, self.service)
    }

    /// Checks a whole response body and builds the reply.
    fn check_body(&self, header: Header, body: &[u8], fragmented: bool, len: usize) -> (Reply, Vec<String>) {
        let mut failures = Vec::new();
        let body_out = match Response::parse(body) {
            Ok(Response::Success { service, data }) => {
                if service != self.service {
                    failures.push(format!(
                        "service byte 0x{:02X}, expected 0x{:02X} ({} | 0x80)",
                        0x80 | service.as_raw(),
                        0x80 | self.service.as_raw(),
                        self.service_name()
                    ));
                }
                ReplyBody::Success(data.to_vec())
            }
            Ok(Response::Error { general, additional }) => {
                if body.len() != 3 {
                    failures.push(format!(
                        "error response of {} body bytes, expected 3 (94 general additional)",
                        body.len()
                    ));
                }
                ReplyBody::Error { general, additional }
            }
            Err(e) => {
                failures.push(format!("not a response ({e}): {}", hex(body)));
                ReplyBody::Success(body.get(1..).unwrap_or(&[]).to_vec())
            }
        };
        (Reply { header, body: body_out, fragmented, message_len: len }, failures)
    }

    fn fragment(&mut self, frame: &CanFrame, now: Instant, mut failures: Vec<String>) -> Verdict {
        let data = frame.data();
        let frag = match ExplicitFragment::parse(data) {
            Ok(f) => f,
            Err(e) => {
                failures.push(format!("malformed fragment: {e}"));
                return Verdict::Fail(failures);
            }
        };
        if frag.fragment.kind == FragmentKind::Ack {
            if matches!(self.state, State::LastAck { .. }) {
                return self.late_ack(data, &frag, now, failures);
            }
            if self.state != State::Sending {
                failures.push("fragment acknowledge while no request fragment is outstanding".into());
                return Verdict::Fail(failures);
            }
            if data.len() != 3 {
                failures.push(format!("fragment acknowledge of DLC {}, expected 3", data.len()));
            }
            self.tx.handle_ack(data, now);
            self.pump(now);
            return Verdict::Ok(format!("acknowledge of request fragment #{}", frag.fragment.count))
                .with_failures(failures);
        }
        if matches!(self.state, State::Sending | State::LastAck { .. }) {
            failures.push("response fragment while the request is still being sent".into());
            return Verdict::Fail(failures);
        }
        let ack_id = self.ack_id();
        match self.rx.receive(data) {
            ExplicitReceive::Ack(ack) | ExplicitReceive::Duplicate(ack) => {
                self.queue(ack_id, &ack);
                self.state = State::Awaiting { deadline: now + self.timeout };
                if frag.fragment.kind != FragmentKind::Last && data.len() != 8 {
                    failures.push(format!(
                        "{} fragment of DLC {}, expected 8",
                        frag.fragment.kind,
                        data.len()
                    ));
                }
                Verdict::Ok(format!(
                    "response fragment {} #{} acknowledged",
                    frag.fragment.kind, frag.fragment.count
                ))
                .with_failures(failures)
            }
            ExplicitReceive::Complete(ack) => {
                self.queue(ack_id, &ack);
                let whole = self.rx.message().to_vec();
                self.rx.reset();
                let (reply, mut more) = match split_message(&whole) {
                    Ok((header, body)) => self.check_body(header, body, true, whole.len()),
                    Err(e) => (
                        Reply {
                            header: frag.header,
                            body: ReplyBody::Success(Vec::new()),
                            fragmented: true,
                            message_len: 0,
                        },
                        vec![format!("reassembled response is malformed: {e}")],
                    ),
                };
                failures.append(&mut more);
                self.finish(Ok(reply));
                Verdict::Ok(format!(
                    "last response fragment #{} acknowledged; {} reassembled, checked",
                    frag.fragment.count,
                    self.service_name()
                ))
                .with_failures(failures)
            }
            ExplicitReceive::Rejected(ack) => {
                self.queue(ack_id, &ack);
                failures.push(format!("response longer than the master's {MAX_MESSAGE}-byte limit"));
                Verdict::Fail(failures)
            }
            ExplicitReceive::Ignored(e) => {
                failures.push(format!("fragment dropped: {e}"));
                Verdict::Fail(failures)
            }
        }
    }
}

/// `true` for a Device Heartbeat or Device Shutdown (protocol §3.7, §II.5): 8 bytes on a device's
/// explicit response identifier with the device's own MAC in the header (not the master's) and
/// service 0xCD or 0xCE. It answers no request.
pub fn is_heartbeat_or_shutdown(data: &[u8], master: MacId) -> bool {
    match data {
        [header, service, ..] if data.len() == 8 => {
            Header::from_byte(*header).mac != master
                && *header & 0x80 == 0
                && matches!(*service, DEVICE_HEARTBEAT | DEVICE_SHUTDOWN)
        }
        _ => false,
    }
}

/// Judges a frame that is not part of the exchange in progress: a frame from `device` is a failure
/// ("unexpected"), but for its heartbeats and shutdown messages, and but for a frame that came
/// before the session asked anything or while it winds down, which is recorded as not judged
/// ([`Session::not_judged`]); anything else is other traffic.
pub fn judge_other(session: &mut Session<'_>, index: usize, device: MacId) {
    let frame = session.record(index).frame;
    let own_response_id = Identifier::group2(device, Group2Message::ExplicitResponse);
    let announced = frame.id() == own_response_id
        && matches!(frame.data(), [h, s, ..] if frame.data().len() == 8 && h & 0x3F == device.as_raw() && matches!(*s, DEVICE_HEARTBEAT | DEVICE_SHUTDOWN));
    let verdict = if announced {
        let name = if frame.data()[1] == DEVICE_HEARTBEAT { "device heartbeat" } else { "device shutdown" };
        Verdict::Info(format!("{name} (notes II.5)"))
    } else if is_from_device(&frame, device) {
        match session.not_judged(index) {
            Some(why) => Verdict::Info(format!("not judged: {why}")),
            None => Verdict::fail("unexpected frame from the device at this point"),
        }
    } else {
        Verdict::Info("other traffic".into())
    };
    session.set_verdict(index, verdict);
}

/// Where [`drive`] runs a transaction: a clock, a way to send, and a way to wait for the next frame
/// and to hand over what the transaction made of it. A [`Session`] is one (through [`run`]); a
/// program on a bare bus, like the soak, is another.
pub trait Link {
    /// What identifies a received frame afterwards (a transcript index, or nothing).
    type Seen: Copy;

    /// The link's clock.
    fn now(&mut self) -> Instant;

    /// Queues `frame` for transmission; it comes back from [`Link::recv`] as [`Origin::Local`]
    /// once on the wire.
    fn send(&mut self, frame: &CanFrame) -> Result<(), MasterError>;

    /// Waits until `deadline` for the next frame; `None` at the deadline.
    fn recv(&mut self, deadline: Instant) -> Result<Option<Received<Self::Seen>>, MasterError>;

    /// The transaction's verdict on `seen`, a frame that belonged to it.
    fn judged(&mut self, seen: Self::Seen, verdict: Verdict);

    /// `seen` is not part of the transaction (from another node, or unexpected).
    fn other(&mut self, seen: Self::Seen);

    /// How long to wait, once the transaction is over, to see the master's last frames come back
    /// (the final fragment acknowledge); `None`: do not wait.
    fn echo_wait(&self) -> Option<Duration> {
        Some(ECHO_WAIT)
    }
}

/// A frame a [`Link`] received.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Received<S> {
    /// Its handle (a transcript index, or nothing).
    pub seen: S,
    /// Who sent it.
    pub origin: Origin,
    /// The frame.
    pub frame: CanFrame,
    /// When it completed on the bus.
    pub at: Instant,
}

/// How a transaction ended, and the handle of the frame that completed it.
pub type Outcome<S> = (Result<Reply, ClientError>, Option<S>);

/// Drives one transaction to its end on `link`; returns the reply and the handle of the frame that
/// completed it. The one driver of a [`Transaction`]: [`run`] is it on a [`Session`].
pub fn drive<L: Link>(link: &mut L, tx: &mut Transaction) -> Result<Outcome<L::Seen>, MasterError> {
    let now = link.now();
    tx.start(now);
    let mut last = None;
    // Own frames sent and not yet seen back from the bus.
    let mut in_flight = 0usize;
    loop {
        while let Some(f) = tx.poll_transmit() {
            link.send(&f)?;
            in_flight += 1;
        }
        if tx.is_done() {
            // Record the master's last frames (the final fragment acknowledge) before returning.
            if let Some(wait) = link.echo_wait() {
                let until = link.now() + wait;
                while in_flight > 0 {
                    let Some(r) = link.recv(until)? else { break };
                    if r.origin == Origin::Local {
                        in_flight -= 1;
                    } else {
                        link.other(r.seen);
                    }
                }
            }
            let outcome = tx.take_outcome().unwrap_or(Err(ClientError::Timeout {
                name: "explicit response timeout",
                after: Duration::ZERO,
            }));
            return Ok((outcome, last));
        }
        let now = link.now();
        let deadline = tx.poll_at().unwrap_or(now);
        match link.recv(deadline)? {
            Some(r) if r.origin == Origin::Local => in_flight = in_flight.saturating_sub(1),
            Some(r) => match tx.handle_frame(&r.frame, r.at) {
                Handled::Frame(v) => {
                    link.judged(r.seen, v);
                    last = Some(r.seen);
                }
                Handled::NotMine => link.other(r.seen),
            },
            None => {
                let now = link.now();
                tx.handle_timeout(now);
            }
        }
    }
}

/// A [`Session`] as a [`Link`]: every frame recorded, verdicts set on the transcript, frames not
/// part of the transaction passed to `other`.
struct SessionLink<'s, 'b, F> {
    session: &'s mut Session<'b>,
    other: F,
}

impl<F: FnMut(&mut Session<'_>, usize)> Link for SessionLink<'_, '_, F> {
    type Seen = usize;

    fn now(&mut self) -> Instant {
        self.session.now()
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), MasterError> {
        self.session.send(frame)
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<Received<usize>>, MasterError> {
        Ok(self.session.next(deadline)?.map(|i| {
            let r = self.session.record(i);
            Received { seen: i, origin: r.origin, frame: r.frame, at: r.at }
        }))
    }

    fn judged(&mut self, seen: usize, verdict: Verdict) {
        self.session.set_verdict(seen, verdict);
    }

    fn other(&mut self, seen: usize) {
        (self.other)(self.session, seen);
    }
}

/// Runs one transaction to its end on `session` ([`drive`] on the session); returns the reply and
/// the index of the record that completed it. `other` judges every frame that is not part of it.
pub fn run(
    session: &mut Session<'_>,
    tx: &mut Transaction,
    other: impl FnMut(&mut Session<'_>, usize),
) -> Result<Outcome<usize>, MasterError> {
    drive(&mut SessionLink { session, other }, tx)
}

#[cfg(test)]
mod tests;
