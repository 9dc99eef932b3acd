//! Mutant devices: the reference converter with exactly one deliberate fault each, for
//! `dnet-master conformance --self-test` (which proves that every conformance check can fail) and
//! `dnet-soft-slave --mutant ID` (the same faults on a real bus).
//!
//! A mutant is a fault hook around the real node ([`FaultHook`]), never a second implementation
//! of the protocol. The hook sees every frame the bus delivers to the node and every frame the
//! node transmits, and may rewrite, drop, delay or add frames, or feed the node a frame nobody
//! sent. It knows the last request the node received (to tell which response a frame is) and reads
//! the node's state (the poll connection's state, the input data, the owner, the EPR resolution).
//! Everything else is the real node, so a mutant behaves exactly like the reference device but
//! for its one fault.
//!
//! [`MUTANTS`] lists them, each with the conformance check it targets; [`MutantDevice`] is a
//! mutant on the simulated bus. Response rewrites assume the 8/8 body format (the one the
//! reference device's explicit connection uses, protocol §3.1).

use crate::device::SoftSlave;
use can_io::sim::SimDevice;
use devicenet::explicit::Response;
use devicenet::fragment::{io_fragments, next_count, FragmentByte, FragmentKind};
use devicenet::id::{Group1MessageId, Group3MessageId};
use devicenet::objects::class;
use devicenet::slave::{ConnectionState, SlaveNode};
use devicenet::{CanFrame, CanId, Duration, Group2Message, Identifier, Instant, MacId};
use std::collections::VecDeque;

/// One deliberate fault of the reference device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mutant {
    /// Short stable name (`answers-ucmm`).
    pub id: &'static str,
    /// The check that must fail against it.
    pub target: &'static str,
    /// The fault, in words.
    pub fault: &'static str,
    kind: Fault,
}

impl Mutant {
    /// The reference soft slave at `mac` with this fault, for the simulated bus.
    pub fn device(&self, mac: MacId) -> MutantDevice {
        MutantDevice { inner: SoftSlave::reference(mac), hook: self.hook(), now: Instant::ZERO }
    }

    /// The fault as a hook around a node of its own (the soft slave's `--mutant`).
    pub fn hook(&self) -> FaultHook {
        FaultHook::new(self.kind)
    }
}

/// The faults, one per mutant. Response rewrites apply to the unfragmented response that answers
/// the last request the node received.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Fault {
    // ----- network access (protocol §7.1, §3.4, §8) ---------------------------------------------
    /// Its second duplicate MAC ID request is not sent.
    SkipsSecondDupMacRequest,
    /// A duplicate MAC ID request for its MAC gets no response.
    DoesNotDefendMac,
    /// Answers a UCMM open request with an open response.
    AnswersUcmm,
    /// Takes Group 2 frames for the next MAC ID as its own.
    AcceptsNextMac,
    /// Connection 2 attribute 7 (produced size) reads one byte short.
    ShortProducedSize,
    // ----- the Predefined Master/Slave Connection Set (protocol §3.4) ---------------------------
    /// Allocating poll without explicit succeeds.
    AllocatesPollWithoutExplicit,
    /// Releasing a connection that does not exist succeeds.
    ReleasesNothing,
    /// Allocation choice 0 succeeds.
    AcceptsChoiceZero,
    /// Acknowledge suppression without change of state or cyclic succeeds.
    AcceptsAckSuppression,
    /// A connection type it lacks is refused with 0x08 (service not supported) instead of 0x02/0x02.
    LackingTypeAsUnsupportedService,
    /// The explicit connection allocated through the Group 2 Only port reports body format 4.
    ReservedBodyFormat,
    /// Allocating the explicit connection a second time succeeds.
    AcceptsDoubleAllocation,
    /// A second master's Allocate succeeds while it is owned (nothing is allocated to it).
    AnswersSecondMaster,
    /// Release choice 0 succeeds.
    AcceptsReleaseChoiceZero,
    /// Releasing a type it lacks is refused with 0x0B/0x02 instead of 0x02/0x02.
    LackingReleaseAsAlreadyReleased,
    /// Another service on the Group 2 Only port is refused with 0x02 and no additional code.
    Group2OnlyWithoutAdditionalCode,
    /// Identity status bit 0 (owned) is never set.
    NeverShowsOwned,
    /// A Release through the explicit connection is answered with success and not carried out.
    KeepsReleasedConnections,
    // ----- explicit messaging (protocol §3.3, §4.1, §5.1, §6) -----------------------------------
    /// Identity attribute 6 (serial number) differs from the serial its duplicate MAC ID check announced.
    SerialDiffersFromAnnounced,
    /// Get_Attributes_All of the Identity object is one byte short.
    ShortAttributesAll,
    /// DeviceNet attribute 1 reads another MAC ID.
    WrongMacAttribute,
    /// Connection 2 attribute 5 (consumed connection ID) names another MAC ID.
    WrongPollConsumedId,
    /// Identity attribute 7 (product name) accepts a Set.
    ProductNameSettable,
    /// An unknown Identity instance is answered 0x14 (attribute not supported) instead of 0x16.
    UnknownInstanceAsUnknownAttribute,
    /// A service an object lacks is answered 0x14 instead of 0x08.
    UnsupportedServiceAsUnknownAttribute,
    /// The last fragment of a fragmented response carries the wrong count.
    WrongLastResponseFragmentCount,
    /// The acknowledgement of request fragment #1 is lost.
    LosesSecondFragmentAck,
    /// Sends the next response fragment without waiting for the acknowledgement of the previous one.
    DoesNotWaitForAck,
    /// A repeated request fragment is not acknowledged again.
    DoesNotReacknowledgeRepeat,
    /// An out-of-sequence request fragment is acknowledged with success.
    AcknowledgesOutOfSequence,
    /// The acknowledgement "too much data" (status 1) is sent as success (status 0).
    TakesAnyLength,
    // ----- connections (protocol §4.2, §5, §8, §9.12) ---------------------------------------------
    /// Answers polls while the poll connection is configuring (before the EPR is set).
    PollsWhileConfiguring,
    /// The Set EPR response carries no data instead of the EPR applied.
    SetEprWithoutValue,
    /// The inactivity watchdogs expire at 3 x EPR (the node is given 3/4 of each EPR set, and the
    /// EPR read back is the one set).
    WatchdogAt3Epr,
    /// Watchdog action 1 (auto delete) on the poll connection acts as 0 (transition to timed out).
    AutoDeleteAsTimedOut,
    /// Watchdog action 2 (auto reset) on the poll connection acts as 1 (auto delete).
    AutoResetAsAutoDelete,
    /// A Set of the poll connection's watchdog action is answered with success and ignored.
    IgnoresWatchdogAction,
    /// The explicit connection's watchdog never expires (the node is given EPR 0).
    ExplicitWatchdogNeverExpires,
    /// Watchdog action 3 (deferred delete) on the explicit connection acts as 1 (auto delete).
    DeferredAsAutoDelete,
    /// After a zero-length (idle) poll it answers no poll until the next allocation.
    StopsAfterIdlePoll,
    /// The last I/O fragment of the poll response carries the wrong count.
    WrongLastIoFragmentCount,
    /// Explicit requests from a master that does not own it are served as the owner's.
    ServesAnyMaster,
    /// Poll responses go out 150 ms late.
    SlowPollResponses,
    /// Responses on its explicit connection go out 1.2 s late.
    SlowExplicitResponses,
    // ----- issue 14: I/O connections, heartbeat, Offline Connection Set (protocol §II) -------------
    /// Allocating change of state and cyclic together (0x31) succeeds (nothing is allocated).
    AcceptsCosWithCyclic,
    /// A release naming acknowledge suppression is answered with success and not carried out.
    ReleasesAckSuppression,
    /// Bit-strobe with poll (0x07) is refused with 0x02/0x02.
    RefusesStrobeWithPoll,
    /// The bit-strobe response loses its last byte.
    ShortStrobeResponse,
    /// Connection 4 attribute 5 of an acknowledged connection reads 0x42D (the RA tables' slip)
    /// instead of the acknowledgement's identifier.
    CosConsumedIdOfPoll,
    /// Under acknowledge suppression the master's COS/cyclic data is acknowledged all the same.
    AcknowledgesUnderSuppression,
    /// A cyclic connection leaves out every second production (and takes it as acknowledged).
    SkipsCyclicProductions,
    /// An unacknowledged production is never sent again.
    NeverResends,
    /// Acknowledge Handler attribute 1 (acknowledge timer) = 0 is accepted.
    AcceptsAckTimerZero,
    /// The heartbeat carries MAC 0 in its header instead of its own.
    HeartbeatWithoutOwnMac,
    /// A duplicate MAC ID response for its MAC is not seen by the node (it does not fault).
    IgnoresDupMacResponse,
    /// Its Who answer carries another serial number.
    WhoAnswerWrongSerial,
}

macro_rules! mutants {
    ($($id:literal => $target:literal, $fault:literal, $kind:ident;)*) => {
        /// Every mutant, in the order of the checks they target.
        pub const MUTANTS: &[Mutant] = &[
            $(Mutant { id: $id, target: $target, fault: $fault, kind: Fault::$kind },)*
        ];
    };
}

mutants! {
    "short-produced-size" => "bring-up", "Connection 2 attribute 7 (produced size) reads one byte short", ShortProducedSize;
    "skips-second-dup-mac" => "dup-mac-startup", "its second duplicate MAC ID request is not sent", SkipsSecondDupMacRequest;
    "does-not-defend-mac" => "dup-mac-answer", "a duplicate MAC ID request for its MAC gets no response", DoesNotDefendMac;
    "answers-ucmm" => "ucmm-silent", "answers a UCMM open request with an open response", AnswersUcmm;
    "accepts-next-mac" => "other-macs-ignored", "takes Group 2 frames for the next MAC ID as its own", AcceptsNextMac;
    "poll-without-explicit" => "alloc-explicit-not-requested", "allocating poll without explicit succeeds", AllocatesPollWithoutExplicit;
    "releases-nothing" => "release-nonexistent", "releasing a connection that does not exist succeeds", ReleasesNothing;
    "accepts-choice-zero" => "alloc-choice-zero", "allocation choice 0 succeeds", AcceptsChoiceZero;
    "accepts-ack-suppression" => "alloc-ack-suppression", "acknowledge suppression without change of state or cyclic succeeds", AcceptsAckSuppression;
    "lacking-type-0x08" => "alloc-lacking-type", "a connection type it lacks is refused with 0x08 instead of 0x02/0x02", LackingTypeAsUnsupportedService;
    "reserved-body-format" => "alloc-group2-only-port", "the explicit connection allocated through the Group 2 Only port reports body format 4", ReservedBodyFormat;
    "accepts-double-allocation" => "alloc-double", "allocating the explicit connection a second time succeeds", AcceptsDoubleAllocation;
    "answers-second-master" => "alloc-conflict", "a second master's Allocate succeeds while the device is owned", AnswersSecondMaster;
    "accepts-release-choice-zero" => "release-choice-zero", "release choice 0 succeeds", AcceptsReleaseChoiceZero;
    "lacking-release-0x0b" => "release-lacking-type", "releasing a type it lacks is refused with 0x0B/0x02 instead of 0x02/0x02", LackingReleaseAsAlreadyReleased;
    "group2-only-no-additional-code" => "group2-only-invalid-service", "another service on the Group 2 Only port is refused with 0x02 and no additional code", Group2OnlyWithoutAdditionalCode;
    "never-shows-owned" => "alloc-explicit-path", "Identity status bit 0 (owned) is never set", NeverShowsOwned;
    "keeps-released-connections" => "release-reallocate", "a Release through the explicit connection is answered with success and not carried out", KeepsReleasedConnections;
    "serial-differs" => "identity-attributes", "Identity attribute 6 differs from the serial number its duplicate MAC ID check announced", SerialDiffersFromAnnounced;
    "short-attributes-all" => "identity-attributes", "Get_Attributes_All of the Identity object is one byte short", ShortAttributesAll;
    "wrong-mac-attribute" => "devicenet-attributes", "DeviceNet attribute 1 reads another MAC ID", WrongMacAttribute;
    "wrong-poll-consumed-id" => "connection-attributes", "Connection 2 attribute 5 (consumed connection ID) names another MAC ID", WrongPollConsumedId;
    "product-name-settable" => "settable-attributes", "Identity attribute 7 (product name) accepts a Set", ProductNameSettable;
    "unknown-instance-0x14" => "unknown-targets", "an unknown Identity instance is answered 0x14 instead of 0x16", UnknownInstanceAsUnknownAttribute;
    "unsupported-service-0x14" => "unsupported-service", "a service an object lacks is answered 0x14 instead of 0x08", UnsupportedServiceAsUnknownAttribute;
    "wrong-last-response-fragment" => "fragmented-response", "the last fragment of a fragmented response carries the wrong count", WrongLastResponseFragmentCount;
    "loses-fragment-ack" => "fragmented-request", "the acknowledgement of request fragment #1 is lost", LosesSecondFragmentAck;
    "does-not-wait-for-ack" => "missing-ack", "sends the next response fragment without waiting for the acknowledgement", DoesNotWaitForAck;
    "no-reack-of-repeat" => "duplicate-fragment", "a repeated request fragment is not acknowledged again", DoesNotReacknowledgeRepeat;
    "acks-out-of-sequence" => "out-of-sequence-fragment", "an out-of-sequence request fragment is acknowledged with success", AcknowledgesOutOfSequence;
    "takes-any-length" => "oversized-request", "the acknowledgement \"too much data\" (status 1) goes out as success", TakesAnyLength;
    "polls-while-configuring" => "poll-before-epr", "answers polls while the poll connection is configuring (before the EPR is set)", PollsWhileConfiguring;
    "set-epr-without-value" => "epr-round-trip", "the Set EPR response carries no data instead of the EPR applied", SetEprWithoutValue;
    "watchdog-3x-epr" => "watchdog-poll-timed-out", "the inactivity watchdogs expire at 3 x EPR instead of 4 x", WatchdogAt3Epr;
    "auto-delete-as-timed-out" => "watchdog-poll-auto-delete", "poll watchdog action 1 (auto delete) acts as 0 (timed out)", AutoDeleteAsTimedOut;
    "ignores-watchdog-action" => "watchdog-poll-auto-delete", "a Set of the poll watchdog action is answered with success and ignored", IgnoresWatchdogAction;
    "auto-reset-as-auto-delete" => "watchdog-poll-auto-reset", "poll watchdog action 2 (auto reset) acts as 1 (auto delete)", AutoResetAsAutoDelete;
    "explicit-watchdog-never-expires" => "watchdog-explicit-auto-delete", "the explicit connection's watchdog never expires", ExplicitWatchdogNeverExpires;
    "deferred-as-auto-delete" => "deferred-delete", "explicit watchdog action 3 (deferred delete) acts as 1 (auto delete)", DeferredAsAutoDelete;
    "stops-after-idle-poll" => "idle-poll", "after a zero-length (idle) poll it answers no poll until the next allocation", StopsAfterIdlePoll;
    "wrong-last-io-fragment" => "io-fragmentation", "the last I/O fragment of the poll response carries the wrong count", WrongLastIoFragmentCount;
    "serves-any-master" => "non-owner-ignored", "explicit requests from a master that does not own it are served as the owner's", ServesAnyMaster;
    "slow-poll-responses" => "poll-latency", "poll responses go out 150 ms late", SlowPollResponses;
    "slow-explicit-responses" => "explicit-latency", "responses on its explicit connection go out 1.2 s late", SlowExplicitResponses;
    "refuses-strobe-with-poll" => "alloc-io-combinations", "bit-strobe with poll (0x07) is refused with 0x02/0x02", RefusesStrobeWithPoll;
    "accepts-cos-with-cyclic" => "alloc-cos-with-cyclic", "allocating change of state and cyclic together (0x31) succeeds", AcceptsCosWithCyclic;
    "releases-ack-suppression" => "release-ack-suppression", "a release naming acknowledge suppression is answered with success", ReleasesAckSuppression;
    "short-strobe-response" => "bit-strobe", "the bit-strobe response loses its last byte", ShortStrobeResponse;
    "cos-consumed-id-of-poll" => "cos-acknowledged", "Connection 4 attribute 5 reads 0x42D instead of the acknowledgement's identifier", CosConsumedIdOfPoll;
    "acks-under-suppression" => "cos-suppressed", "under acknowledge suppression the master's data is acknowledged all the same", AcknowledgesUnderSuppression;
    "skips-cyclic-productions" => "cyclic", "a cyclic connection leaves out every second production", SkipsCyclicProductions;
    "never-resends" => "ack-handler", "an unacknowledged production is never sent again", NeverResends;
    "accepts-ack-timer-zero" => "ack-handler", "Acknowledge Handler attribute 1 (acknowledge timer) = 0 is accepted", AcceptsAckTimerZero;
    "heartbeat-without-own-mac" => "heartbeat", "the heartbeat carries MAC 0 in its header instead of its own", HeartbeatWithoutOwnMac;
    "ignores-dup-mac-response" => "offline-recovery", "a duplicate MAC ID response for its MAC does not fault it", IgnoresDupMacResponse;
    "who-answer-wrong-serial" => "offline-recovery", "its Who answer carries another serial number", WhoAnswerWrongSerial;
}

/// The mutant named `id`.
pub fn find(id: &str) -> Option<&'static Mutant> {
    MUTANTS.iter().find(|m| m.id == id)
}

/// The mutant named `id`, or an error listing every name (for command lines).
pub fn parse(id: &str) -> Result<&'static Mutant, String> {
    find(id).ok_or_else(|| {
        let names: Vec<&str> = MUTANTS.iter().map(|m| m.id).collect();
        format!("no mutant {id:?}; the mutants are: {}", names.join(", "))
    })
}

/// Where a request came in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Port {
    /// The Group 2 Only Unconnected Explicit Request identifier (message 6).
    Group2Only,
    /// The explicit connection (message 4).
    Explicit,
}

/// The last request the node received: its header byte and its body from the service code on
/// (8/8 body format, the suite's), from the first fragment when it was fragmented.
#[derive(Clone, Debug)]
struct LastRequest {
    port: Port,
    header: u8,
    body: Vec<u8>,
}

impl LastRequest {
    fn service(&self) -> u8 {
        self.body.first().copied().unwrap_or(0)
    }

    fn class(&self) -> u16 {
        self.body.get(1).copied().map_or(0, u16::from)
    }

    fn instance(&self) -> u16 {
        self.body.get(2).copied().map_or(0, u16::from)
    }

    /// The service data after the path.
    fn data(&self) -> &[u8] {
        self.body.get(3..).unwrap_or(&[])
    }

    /// Get_Attribute_Single (0x0E) of `class` instance `instance` attribute `attr`.
    fn is_get(&self, class_id: u16, instance: u16, attr: u8) -> bool {
        self.service() == 0x0E
            && self.class() == class_id
            && self.instance() == instance
            && self.data() == [attr]
    }

    /// Set_Attribute_Single (0x10) of `class` instance `instance` attribute `attr`.
    fn is_set(&self, class_id: u16, instance: u16, attr: u8) -> bool {
        self.service() == 0x10
            && self.class() == class_id
            && self.instance() == instance
            && self.data().first() == Some(&attr)
    }

    /// The choice byte of an Allocate (0x4B) or Release (0x4C) of the DeviceNet object.
    fn choice(&self, service: u8) -> Option<u8> {
        (self.service() == service && self.class() == class::DEVICENET)
            .then(|| self.data().first().copied())?
    }
}

/// Which kind of frame a fragmented explicit frame is: `(kind, count)`.
fn fragment(data: &[u8]) -> Option<(FragmentKind, u8)> {
    match data {
        [h, f, ..] if h & 0x80 != 0 => {
            let fb = FragmentByte::from_byte(*f);
            Some((fb.kind, fb.count))
        }
        _ => None,
    }
}

fn build(id: CanId, data: &[u8]) -> Option<CanFrame> {
    CanFrame::new(id, data).ok()
}

/// One fault around a node: see the [module docs](self). Sans-IO: the caller passes each frame
/// the bus delivers through [`FaultHook::receive`] before the node sees it, each frame the node
/// sends through [`FaultHook::transmit`], feeds the node what [`FaultHook::poll_feed`] gives, and
/// puts on the bus what [`FaultHook::poll_transmit`] gives when [`FaultHook::poll_at`] says.
#[derive(Clone, Debug)]
pub struct FaultHook {
    fault: Fault,
    now: Instant,
    /// Frames to put on the bus, each with the time it may go.
    out: VecDeque<(Instant, CanFrame)>,
    /// Frames to feed the node.
    feed: VecDeque<CanFrame>,
    last: Option<LastRequest>,
    /// The last request fragment received (its bytes).
    last_fragment: Option<Vec<u8>>,
    /// Duplicate MAC ID requests sent so far.
    dup_requests: u32,
    /// Drop the next acknowledgement ([`Fault::DoesNotReacknowledgeRepeat`]).
    drop_ack: bool,
    /// An idle poll was received ([`Fault::StopsAfterIdlePoll`]).
    idle_seen: bool,
    /// Per Connection instance 1, 2: the EPR the master last set ([`Fault::WatchdogAt3Epr`],
    /// [`Fault::ExplicitWatchdogNeverExpires`]).
    epr_asked: [Option<u16>; 2],
    /// The allocation choices of the Allocates the node accepted so far, as requested (issue 14
    /// faults tell suppression and cyclic from them).
    allocated: u8,
    /// Production series seen (first fragments or whole frames), and whether the current one is
    /// dropped ([`Fault::SkipsCyclicProductions`], [`Fault::NeverResends`]).
    series: u32,
    dropping: bool,
    /// When the last production series that went out started ([`Fault::NeverResends`]).
    last_series: Option<Instant>,
}

impl FaultHook {
    fn new(fault: Fault) -> FaultHook {
        FaultHook {
            fault,
            now: Instant::ZERO,
            out: VecDeque::new(),
            feed: VecDeque::new(),
            last: None,
            last_fragment: None,
            dup_requests: 0,
            drop_ack: false,
            idle_seen: false,
            epr_asked: [None; 2],
            allocated: 0,
            series: 0,
            dropping: false,
            last_series: None,
        }
    }

    /// A frame the bus delivers at `now`, before `node` sees it: the frame the node gets (`None`:
    /// withheld). Frames the fault answers itself wait in [`FaultHook::poll_transmit`].
    pub fn receive(&mut self, frame: &CanFrame, now: Instant, node: &SlaveNode) -> Option<CanFrame> {
        self.now = now;
        self.receive_frame(frame, node)
    }

    /// A frame `node` sends at `now`: it goes out now, later or never through
    /// [`FaultHook::poll_transmit`].
    pub fn transmit(&mut self, frame: CanFrame, now: Instant, node: &SlaveNode) {
        self.now = now;
        if let Some(timed) = self.transmit_frame(frame, node) {
            self.out.push_back(timed);
        }
    }

    /// A frame to feed the node now, as if it came from the bus (nobody sent it).
    #[must_use = "the frame is handed out once: a dropped one never reaches the device"]
    pub fn poll_feed(&mut self) -> Option<CanFrame> {
        self.feed.pop_front()
    }

    /// The next frame due on the bus at `now`. Delayed frames wait; the others go in order.
    #[must_use = "the frame is handed out once: a dropped one is never sent"]
    pub fn poll_transmit(&mut self, now: Instant) -> Option<CanFrame> {
        let due = self.out.iter().position(|&(at, _)| at <= now)?;
        self.out.remove(due).map(|(_, f)| f)
    }

    /// When the next held frame falls due.
    pub fn poll_at(&self) -> Option<Instant> {
        self.out.iter().map(|&(at, _)| at).min()
    }

    /// The node's controller went bus-off: what the fault held is lost with its queue.
    pub fn bus_off(&mut self) {
        self.out.clear();
    }

    /// The EPR the node is given when the master sets `asked` on Connection `instance`.
    fn given_epr(&self, instance: u16, asked: u16) -> u16 {
        match (self.fault, instance) {
            (Fault::WatchdogAt3Epr, _) => (u32::from(asked) * 3 / 4) as u16,
            (Fault::ExplicitWatchdogNeverExpires, 1) => 0,
            _ => asked,
        }
    }

    fn id(node: &SlaveNode, message: Group2Message) -> CanId {
        Identifier::group2(node.mac_id(), message)
    }

    /// Sends `frame` now, ahead of whatever the node sends next.
    fn answer(&mut self, frame: Option<CanFrame>) {
        if let Some(f) = frame {
            self.out.push_back((self.now, f));
        }
    }

    fn receive_frame(&mut self, frame: &CanFrame, node: &SlaveNode) -> Option<CanFrame> {
        let mac = node.mac_id();
        let data = frame.data();
        let (to_mac, message) = match Identifier::decode(frame.id()) {
            Identifier::Group2 { mac: m, message } => (m, message),
            Identifier::Group3 { message, .. } if message == Group3MessageId::UNCONNECTED_REQUEST => {
                if self.fault == Fault::AnswersUcmm && data.first().map(|d| d & 0x3F) == Some(mac.as_raw()) {
                    let rsp =
                        Identifier::Group3 { message: Group3MessageId::UNCONNECTED_RESPONSE, source: mac };
                    let source = Identifier::decode(frame.id());
                    let master = match source {
                        Identifier::Group3 { source, .. } => source.as_raw(),
                        _ => 0,
                    };
                    self.answer(build(rsp.encode(), &[master, 0xCB, 0x00, 0x34, mac.as_raw(), 0x00]));
                }
                return Some(*frame);
            }
            _ => return Some(*frame),
        };
        if self.fault == Fault::AcceptsNextMac && to_mac.as_raw() == mac.as_raw() + 1 {
            return build(Identifier::group2(mac, message), data);
        }
        if to_mac != mac {
            return Some(*frame);
        }
        if self.fault == Fault::IgnoresDupMacResponse
            && message == Group2Message::DuplicateMacCheck
            && data.first().is_some_and(|b| b & 0x80 != 0)
        {
            return None;
        }
        if self.fault == Fault::AcknowledgesUnderSuppression
            && message == Group2Message::PollCommand
            && self.allocated & 0x40 != 0
            && self.allocated & 0x30 != 0
        {
            let ack = Identifier::group1(Group1MessageId::POLL_RESPONSE, mac);
            self.answer(build(ack, &[]));
        }
        match message {
            Group2Message::ExplicitRequest | Group2Message::UnconnectedExplicitRequest => {
                let port =
                    if message == Group2Message::ExplicitRequest { Port::Explicit } else { Port::Group2Only };
                self.request(port, frame, node)
            }
            Group2Message::PollCommand => self.poll_command(frame, node),
            _ => Some(*frame),
        }
    }

    /// An explicit request (or request fragment, or acknowledgement) for the node.
    fn request(&mut self, port: Port, frame: &CanFrame, node: &SlaveNode) -> Option<CanFrame> {
        let data = frame.data();
        let header = data.first().copied().unwrap_or(0);
        match fragment(data) {
            Some((FragmentKind::Ack, _)) => return Some(*frame),
            Some((kind, count)) => {
                let previous = self.last_fragment.replace(data.to_vec());
                if kind == FragmentKind::First {
                    self.last = Some(LastRequest { port, header: header & 0x7F, body: data[2..].to_vec() });
                }
                match self.fault {
                    Fault::DoesNotReacknowledgeRepeat if previous.as_deref() == Some(data) => {
                        self.drop_ack = true
                    }
                    Fault::AcknowledgesOutOfSequence if kind != FragmentKind::First => {
                        let expected = previous.as_deref().and_then(fragment).map(|(_, c)| next_count(c));
                        if expected.is_some_and(|e| e != count) {
                            let ack =
                                FragmentByte::new(FragmentKind::Ack, count).map_or(0, FragmentByte::to_byte);
                            let rsp = Self::id(node, Group2Message::ExplicitResponse);
                            self.answer(build(rsp, &[header, ack, 0]));
                        }
                    }
                    _ => {}
                }
                return Some(*frame);
            }
            None => {}
        }
        let body = data.get(1..).unwrap_or(&[]).to_vec();
        let mut req = LastRequest { port, header, body };
        if req.choice(0x4B).is_some() {
            self.idle_seen = false;
        }
        if let Some(choice) = req.choice(0x4B) {
            self.allocated |= choice;
        }
        if let Some(choice) = req.choice(0x4C) {
            if choice & 0x40 == 0 {
                self.allocated &= !choice;
                if self.allocated & 0x30 == 0 {
                    self.allocated &= !0x40;
                }
            }
        }
        let rsp = Self::id(node, Group2Message::ExplicitResponse);
        let mut deliver = Some(*frame);
        match self.fault {
            Fault::ReleasesAckSuppression if req.choice(0x4C).is_some_and(|c| c & 0x40 != 0) => {
                self.answer(build(rsp, &[header, 0xCC]));
                deliver = None;
            }
            Fault::KeepsReleasedConnections if port == Port::Explicit && req.choice(0x4C).is_some() => {
                self.answer(build(rsp, &[header, 0xCC]));
                deliver = None;
            }
            Fault::IgnoresWatchdogAction if req.is_set(class::CONNECTION, 2, 12) => {
                self.answer(build(rsp, &[header, 0x90]));
                deliver = None;
            }
            Fault::ServesAnyMaster if port == Port::Explicit => {
                if let (_, Some(owner)) = node.allocation() {
                    let h = (header & 0xC0) | owner.as_raw();
                    req.header = h;
                    let mut d = data.to_vec();
                    if let Some(first) = d.first_mut() {
                        *first = h;
                    }
                    deliver = build(frame.id(), &d);
                }
            }
            Fault::AutoDeleteAsTimedOut => {
                deliver =
                    self.rewrite_set(frame, &req, (2, 12), |v| if v == [1] { vec![0] } else { v.to_vec() })
            }
            Fault::AutoResetAsAutoDelete => {
                deliver =
                    self.rewrite_set(frame, &req, (2, 12), |v| if v == [2] { vec![1] } else { v.to_vec() })
            }
            Fault::DeferredAsAutoDelete => {
                deliver =
                    self.rewrite_set(frame, &req, (1, 12), |v| if v == [3] { vec![1] } else { v.to_vec() })
            }
            Fault::WatchdogAt3Epr | Fault::ExplicitWatchdogNeverExpires => {
                for instance in [1u16, 2] {
                    if let (true, [_, lo, hi]) = (req.is_set(class::CONNECTION, instance, 9), req.data()) {
                        let asked = u16::from_le_bytes([*lo, *hi]);
                        self.epr_asked[usize::from(instance - 1)] = Some(asked);
                        let given = self.given_epr(instance, asked).to_le_bytes();
                        deliver = self.rewrite_set(frame, &req, (instance, 9), |_| given.to_vec());
                    }
                }
            }
            _ => {}
        }
        self.last = Some(req);
        deliver
    }

    /// `frame` with the value of a Set of Connection `(instance, attr)` replaced by `f(value)`.
    fn rewrite_set(
        &self,
        frame: &CanFrame,
        req: &LastRequest,
        (instance, attr): (u16, u8),
        f: impl FnOnce(&[u8]) -> Vec<u8>,
    ) -> Option<CanFrame> {
        if !req.is_set(class::CONNECTION, instance, attr) {
            return Some(*frame);
        }
        let data = frame.data();
        let mut d = data[..5].to_vec();
        d.extend(f(&data[5..]));
        CanFrame::new(frame.id(), &d).ok()
    }

    /// A poll command for the node.
    fn poll_command(&mut self, frame: &CanFrame, node: &SlaveNode) -> Option<CanFrame> {
        match self.fault {
            Fault::StopsAfterIdlePoll if frame.data().is_empty() => self.idle_seen = true,
            Fault::PollsWhileConfiguring if node.poll_connection().state == ConnectionState::Configuring => {
                let input = node.input().to_vec();
                let id = Identifier::group1(Group1MessageId::POLL_RESPONSE, node.mac_id());
                if input.len() > 8 {
                    for part in io_fragments(&input) {
                        self.answer(build(id, &part));
                    }
                } else {
                    self.answer(build(id, &input));
                }
            }
            _ => {}
        }
        Some(*frame)
    }

    /// A frame the node transmits: what goes on the bus (`None`: dropped), and when.
    fn transmit_frame(&mut self, f: CanFrame, node: &SlaveNode) -> Option<(Instant, CanFrame)> {
        let now = self.now;
        let id = f.id();
        let data = f.data();
        if id == Self::id(node, Group2Message::DuplicateMacCheck) {
            let is_request = data.first().is_some_and(|p| p & 0x80 == 0);
            if is_request {
                self.dup_requests += 1;
            }
            return match self.fault {
                Fault::SkipsSecondDupMacRequest if is_request && self.dup_requests == 2 => None,
                Fault::DoesNotDefendMac if !is_request => None,
                _ => Some((now, f)),
            };
        }
        if id == Identifier::group1(Group1MessageId::POLL_RESPONSE, node.mac_id()) {
            return match self.fault {
                Fault::StopsAfterIdlePoll if self.idle_seen => None,
                Fault::SlowPollResponses => Some((now + Duration::from_millis(150), f)),
                Fault::WrongLastIoFragmentCount if node.input().len() > 8 => {
                    let mut d = data.to_vec();
                    if let Some(b) = d.first_mut() {
                        let fb = FragmentByte::from_byte(*b);
                        if fb.kind == FragmentKind::Last {
                            *b = FragmentByte::new(FragmentKind::Last, next_count(fb.count))
                                .map_or(*b, FragmentByte::to_byte);
                        }
                    }
                    build(id, &d).map(|f| (now, f))
                }
                _ => Some((now, f)),
            };
        }
        let mac = node.mac_id();
        if id == Identifier::group1(Group1MessageId::BIT_STROBE_RESPONSE, mac)
            && self.fault == Fault::ShortStrobeResponse
        {
            return build(id, &data[..data.len().saturating_sub(1)]).map(|f| (now, f));
        }
        if id == Identifier::group1(Group1MessageId::COS_CYCLIC, mac) {
            return self.transmit_production(f, node);
        }
        if id
            == (Identifier::Group4 { message: devicenet::id::Group4MessageId::COMM_FAULTED_RESPONSE })
                .encode()
            && self.fault == Fault::WhoAnswerWrongSerial
            && data.len() == 7
        {
            let mut d = data.to_vec();
            d[3] ^= 0x01;
            return build(id, &d).map(|f| (now, f));
        }
        if id != Self::id(node, Group2Message::ExplicitResponse) {
            return Some((now, f));
        }
        if self.fault == Fault::HeartbeatWithoutOwnMac && data.len() == 8 && data[1] == 0xCD {
            let mut d = data.to_vec();
            d[0] &= 0xC0;
            return build(id, &d).map(|f| (now, f));
        }
        if let Some((kind, count)) = fragment(data) {
            return self.transmit_fragment(f, kind, count, node);
        }
        let last = self.last.clone();
        let Some(req) = last else { return Some((now, f)) };
        // An unfragmented response (fragments were handled above), read with the core's codec.
        let rewritten = match Response::parse(data.get(1..).unwrap_or(&[])) {
            Ok(Response::Success { data: value, .. }) => self.rewrite_success(&req, value, node),
            Ok(Response::Error { general, additional }) => {
                self.rewrite_error(&req, general.as_raw(), additional)
            }
            Err(_) => None,
        };
        let f = match rewritten {
            Some(body) => {
                let mut d = vec![data[0]];
                d.extend(body);
                build(id, &d)?
            }
            None => f,
        };
        match self.fault {
            Fault::SlowExplicitResponses if req.port == Port::Explicit => {
                Some((now + Duration::from_millis(1200), f))
            }
            _ => Some((now, f)),
        }
    }

    /// A COS/cyclic production frame from the node: whole series are dropped by the faults that
    /// leave productions out.
    fn transmit_production(&mut self, f: CanFrame, node: &SlaveNode) -> Option<(Instant, CanFrame)> {
        let now = self.now;
        let data = f.data();
        let starts = node.input().len() <= 8 || data.first().is_some_and(|b| b & 0xC0 == 0);
        if starts {
            self.series += 1;
            self.dropping = match self.fault {
                Fault::SkipsCyclicProductions => self.allocated & 0x20 != 0 && self.series % 2 == 0,
                // A series starting sooner than any trigger but the acknowledge timer can bring
                // it is a re-send (the reference device's: 16 ms after the previous).
                Fault::NeverResends => self.last_series.is_some_and(|t| now - t < Duration::from_millis(60)),
                _ => false,
            };
            if !self.dropping {
                self.last_series = Some(now);
            }
        }
        let last = node.input().len() <= 8 || data.first().is_some_and(|b| b & 0xC0 == 0x80);
        if self.dropping && last && self.fault == Fault::SkipsCyclicProductions {
            // The node hears an acknowledgement nobody sent, so it does not send the series again.
            if let Some(ack) = build(Identifier::group2(node.mac_id(), Group2Message::CosCyclicAck), &[]) {
                self.feed.push_back(ack);
            }
        }
        if self.dropping {
            None
        } else {
            Some((now, f))
        }
    }

    /// A response fragment or acknowledgement from the node.
    fn transmit_fragment(
        &mut self,
        f: CanFrame,
        kind: FragmentKind,
        count: u8,
        node: &SlaveNode,
    ) -> Option<(Instant, CanFrame)> {
        let now = self.now;
        let data = f.data();
        let is_gaa = self.last.as_ref().is_some_and(|r| r.service() == 0x01 && r.class() == class::IDENTITY);
        match (self.fault, kind) {
            (Fault::DoesNotReacknowledgeRepeat, FragmentKind::Ack) if self.drop_ack => {
                self.drop_ack = false;
                None
            }
            (Fault::LosesSecondFragmentAck, FragmentKind::Ack) if count == 1 => None,
            (Fault::TakesAnyLength, FragmentKind::Ack) if data.get(2) == Some(&1) => {
                build(f.id(), &[data[0], data[1], 0]).map(|f| (now, f))
            }
            (Fault::WrongLastResponseFragmentCount, FragmentKind::Last) => {
                let byte = FragmentByte::new(FragmentKind::Last, next_count(count))
                    .map_or(data[1], FragmentByte::to_byte);
                let mut d = data.to_vec();
                d[1] = byte;
                build(f.id(), &d).map(|f| (now, f))
            }
            (Fault::ShortAttributesAll, FragmentKind::Last) if is_gaa && data.len() > 3 => {
                build(f.id(), &data[..data.len() - 1]).map(|f| (now, f))
            }
            (Fault::DoesNotWaitForAck, FragmentKind::First | FragmentKind::Middle) => {
                // The node hears an acknowledgement nobody sent and goes on with the next fragment.
                let ack = FragmentByte::new(FragmentKind::Ack, count).map_or(0, FragmentByte::to_byte);
                if let Some(a) = build(Self::id(node, Group2Message::ExplicitRequest), &[data[0], ack, 0]) {
                    self.feed.push_back(a);
                }
                Some((now, f))
            }
            (Fault::SlowExplicitResponses, _)
                if self.last.as_ref().is_some_and(|r| r.port == Port::Explicit) =>
            {
                Some((now + Duration::from_millis(1200), f))
            }
            _ => Some((now, f)),
        }
    }

    /// The new body (service code on) of a success response to `req` carrying `value`, if the
    /// fault rewrites it.
    fn rewrite_success(&mut self, req: &LastRequest, value: &[u8], node: &SlaveNode) -> Option<Vec<u8>> {
        let service = req.service() | 0x80;
        let with = |v: Vec<u8>| {
            let mut b = vec![service];
            b.extend(v);
            Some(b)
        };
        match self.fault {
            Fault::ShortProducedSize if req.is_get(class::CONNECTION, 2, 7) => {
                let v = u16::from_le_bytes(value.try_into().ok()?);
                with(v.saturating_sub(1).to_le_bytes().to_vec())
            }
            Fault::ReservedBodyFormat if req.port == Port::Group2Only && req.choice(0x4B).is_some() => {
                with(vec![4])
            }
            Fault::NeverShowsOwned if req.is_get(class::IDENTITY, 1, 5) => {
                let mut v = value.to_vec();
                *v.first_mut()? &= !1;
                with(v)
            }
            Fault::SerialDiffersFromAnnounced if req.is_get(class::IDENTITY, 1, 6) => {
                let mut v = value.to_vec();
                *v.first_mut()? ^= 1;
                with(v)
            }
            Fault::WrongMacAttribute if req.is_get(class::DEVICENET, 1, 1) => {
                with(vec![value.first()?.wrapping_add(1) & 0x3F])
            }
            Fault::WrongPollConsumedId if req.is_get(class::CONNECTION, 2, 5) => {
                let v = u16::from_le_bytes(value.try_into().ok()?) ^ 0x08;
                with(v.to_le_bytes().to_vec())
            }
            Fault::RefusesStrobeWithPoll if req.choice(0x4B) == Some(0x07) => Some(vec![0x94, 0x02, 0x02]),
            Fault::CosConsumedIdOfPoll if req.is_get(class::CONNECTION, 4, 5) && value == [0x2A, 0x04] => {
                with(vec![0x2D, 0x04])
            }
            Fault::SetEprWithoutValue
                if req.is_set(class::CONNECTION, 1, 9) || req.is_set(class::CONNECTION, 2, 9) =>
            {
                with(Vec::new())
            }
            Fault::WatchdogAt3Epr | Fault::ExplicitWatchdogNeverExpires => {
                let instance = [1u16, 2]
                    .into_iter()
                    .find(|&i| req.is_set(class::CONNECTION, i, 9) || req.is_get(class::CONNECTION, i, 9))?;
                let asked = self.epr_asked[usize::from(instance - 1)]?;
                let v = u16::from_le_bytes(value.try_into().ok()?);
                // The node's value for what it was given: shown as the EPR the master asked for,
                // rounded as the node rounds.
                (v == rounded(node, self.given_epr(instance, asked))).then_some(())?;
                with(rounded(node, asked).to_le_bytes().to_vec())
            }
            _ => None,
        }
    }

    /// The new body of an error response `general`/`additional` to `req`, if the fault rewrites it.
    fn rewrite_error(&mut self, req: &LastRequest, general: u8, additional: u8) -> Option<Vec<u8>> {
        let allocate = req.choice(0x4B);
        let release = req.choice(0x4C);
        let allocated = Some(vec![0xCB, 0x00]);
        match (self.fault, general, additional) {
            (Fault::AllocatesPollWithoutExplicit, _, _) if allocate == Some(0x02) => allocated,
            (Fault::ReleasesNothing, 0x0B, _) if release.is_some() => Some(vec![0xCC]),
            (Fault::AcceptsChoiceZero, _, _) if allocate == Some(0) => allocated,
            (Fault::AcceptsAckSuppression, _, _)
                if allocate.is_some_and(|c| c & 0x40 != 0 && c & 0x30 == 0) =>
            {
                allocated
            }
            (Fault::LackingTypeAsUnsupportedService, 0x02, 0x02) if allocate.is_some() => {
                Some(vec![0x94, 0x08, 0xFF])
            }
            (Fault::AcceptsDoubleAllocation, 0x0B, _) if allocate.is_some() => allocated,
            (Fault::AnswersSecondMaster, 0x0C, _) if allocate.is_some() => allocated,
            (Fault::AcceptsReleaseChoiceZero, _, _) if release == Some(0) => Some(vec![0xCC]),
            (Fault::LackingReleaseAsAlreadyReleased, 0x02, 0x02) if release.is_some() => {
                Some(vec![0x94, 0x0B, 0x02])
            }
            (Fault::Group2OnlyWithoutAdditionalCode, 0x02, 0x03) if req.port == Port::Group2Only => {
                Some(vec![0x94, 0x02, 0xFF])
            }
            (Fault::ProductNameSettable, 0x0E, _) if req.is_set(class::IDENTITY, 1, 7) => Some(vec![0x90]),
            (Fault::AcceptsCosWithCyclic, _, _) if allocate.is_some_and(|c| c & 0x30 == 0x30) => allocated,
            (Fault::AcceptsAckTimerZero, 0x09, _) if req.is_set(0x2B, 1, 1) => Some(vec![0x90]),
            (Fault::UnknownInstanceAsUnknownAttribute, 0x16, _)
                if req.class() == class::IDENTITY && req.instance() != 1 =>
            {
                Some(vec![0x94, 0x14, 0xFF])
            }
            (Fault::UnsupportedServiceAsUnknownAttribute, 0x08, _) if req.port == Port::Explicit => {
                Some(vec![0x94, 0x14, 0xFF])
            }
            _ => None,
        }
    }
}

/// `epr` rounded up to `node`'s timer resolution, as the node applies it (protocol §5.3).
fn rounded(node: &SlaveNode, epr: u16) -> u16 {
    let resolution = node.config().epr_resolution_ms.max(1);
    epr.div_ceil(resolution).saturating_mul(resolution)
}

/// A mutant on the simulated bus: the reference soft slave behind its [`FaultHook`].
pub struct MutantDevice {
    inner: SoftSlave,
    hook: FaultHook,
    now: Instant,
}

impl SimDevice for MutantDevice {
    fn mac(&self) -> MacId {
        self.inner.mac()
    }

    fn power_on(&mut self, now: Instant) {
        self.now = now;
        self.inner.power_on(now);
    }

    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.now = now;
        if let Some(f) = self.hook.receive(frame, now, self.inner.node()) {
            self.inner.handle_frame(&f, now);
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        if self.inner.poll_at().is_some_and(|at| at <= now) {
            self.inner.handle_timeout(now);
        }
    }

    fn poll_transmit(&mut self) -> Option<CanFrame> {
        let now = self.now;
        while let Some(f) = self.inner.poll_transmit() {
            self.hook.transmit(f, now, self.inner.node());
            while let Some(fed) = self.hook.poll_feed() {
                self.inner.handle_frame(&fed, now);
            }
        }
        self.hook.poll_transmit(now)
    }

    fn poll_at(&self) -> Option<Instant> {
        [self.inner.poll_at(), self.hook.poll_at()].into_iter().flatten().min()
    }

    fn handle_bus_off(&mut self, now: Instant) {
        self.now = now;
        self.hook.bus_off();
        self.inner.handle_bus_off(now);
    }
}

#[cfg(test)]
mod tests;
